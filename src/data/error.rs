//! Errors of dataset loading: each names the file, and where it applies the frame and field.
//! A [`DataReport`] collects every problem found in one dataset and prints on one line.

use std::fmt;
use std::path::{Path, PathBuf};

/// One problem with an input file.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DataError {
    /// The file (or directory) at fault.
    pub file: PathBuf,
    /// Index of the frame in the json's `frames` array, when the problem is in one frame.
    pub frame: Option<usize>,
    /// The json field (or image property) at fault.
    pub field: Option<String>,
    /// What is wrong.
    pub message: String,
}

impl DataError {
    /// A problem with `file` as a whole.
    pub fn file(file: &Path, message: impl Into<String>) -> DataError {
        DataError { file: file.to_path_buf(), frame: None, field: None, message: message.into() }
    }

    /// A problem with one field of one frame (`frame: None` for a top-level field).
    pub fn field(file: &Path, frame: Option<usize>, field: &str, message: impl Into<String>) -> DataError {
        DataError { file: file.to_path_buf(), frame, field: Some(field.to_string()), message: message.into() }
    }
}

impl fmt::Display for DataError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file.display())?;
        if let Some(i) = self.frame {
            write!(f, ": frame {i}")?;
        }
        if let Some(field) = &self.field {
            write!(f, ": field '{field}'")?;
        }
        // One line, whatever a decoder's message held.
        write!(f, ": {}", self.message.replace(['\n', '\r'], " "))
    }
}

impl std::error::Error for DataError {}

/// Every problem found in a dataset (never empty), shown on one line: the first few problems
/// and how many more there were.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DataReport(pub Vec<DataError>);

/// Problems spelled out in a report's one line; the rest are counted.
const SHOWN: usize = 3;

impl fmt::Display for DataReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, e) in self.0.iter().take(SHOWN).enumerate() {
            if i > 0 {
                f.write_str("; ")?;
            }
            write!(f, "{e}")?;
        }
        if self.0.len() > SHOWN {
            write!(f, "; and {} more problems", self.0.len() - SHOWN)?;
        }
        Ok(())
    }
}

impl std::error::Error for DataReport {}

impl From<DataError> for DataReport {
    fn from(e: DataError) -> Self {
        DataReport(vec![e])
    }
}
