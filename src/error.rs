//! Errors a library caller can act on: the onboard API ([`crate::onboard`]) and model files
//! ([`crate::io::model`]). An [`Error`] is a kind to match on and today's one-line message
//! (naming the file, tensor or field) for people; the `rnerf` commands print the message.

use std::fmt;

/// What went wrong, as a caller can act on it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum ErrorKind {
    /// An argument is not usable: a buffer of the wrong size, intrinsics that are not a
    /// camera, a non-finite pose, a thread count of 0, non-finite weights to save.
    BadInput,
    /// A file this build does not read: another format version, another format, another
    /// model kind or mixing rule.
    Unsupported,
    /// The operating system refused: a file missing, unreadable, too large or not writable,
    /// threads that cannot start.
    Io,
    /// A model file that is truncated or holds bad tensors or metadata.
    CorruptModel,
    /// A residual model file whose residual and frozen background do not belong together
    /// (different scene boxes).
    MismatchedBackground,
}

/// An error: its kind and a one-line message.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Error {
    kind: ErrorKind,
    message: String,
}

impl Error {
    /// An error of `kind` saying `message`.
    pub fn new(kind: ErrorKind, message: impl Into<String>) -> Error {
        Error { kind, message: message.into() }
    }

    /// A [`ErrorKind::CorruptModel`] error (for `map_err` over the readers' messages).
    pub fn corrupt(message: String) -> Error {
        Error::new(ErrorKind::CorruptModel, message)
    }

    /// A [`ErrorKind::BadInput`] error.
    pub fn bad_input(message: impl Into<String>) -> Error {
        Error::new(ErrorKind::BadInput, message)
    }

    /// What went wrong.
    pub fn kind(&self) -> ErrorKind {
        self.kind
    }

    /// The one-line message.
    pub fn message(&self) -> &str {
        &self.message
    }

    /// The same error with `prefix: ` before its message (a file's name).
    pub fn context(self, prefix: impl fmt::Display) -> Error {
        Error { kind: self.kind, message: format!("{prefix}: {}", self.message) }
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for Error {}

/// The message alone: code that reports errors as lines of text (the `rnerf` commands,
/// checkpoints) takes a library error with `?`.
impl From<Error> for String {
    fn from(e: Error) -> String {
        e.message
    }
}
