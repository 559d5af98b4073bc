//! Progress of long work on stderr: a bar redrawn in place on a terminal, plain lines (every
//! tenth of the work) otherwise, so logs stay readable.

use std::io::{IsTerminal, Write};
use std::time::Instant;

/// A progress reporter for `total` units of work.
pub struct Progress {
    label: String,
    total: u64,
    start: Instant,
    tty: bool,
    next_line: u64,
}

impl Progress {
    /// Starts reporting `total` units under `label`.
    pub fn new(label: &str, total: u64) -> Progress {
        Progress {
            label: label.into(),
            total: total.max(1),
            start: Instant::now(),
            tty: std::io::stderr().is_terminal(),
            next_line: 0,
        }
    }

    /// Seconds since the start.
    pub fn seconds(&self) -> f64 {
        self.start.elapsed().as_secs_f64()
    }

    /// Reports `done` units finished, with `detail` (e.g. loss and PSNR).
    pub fn update(&mut self, done: u64, detail: &str) {
        let secs = self.seconds();
        let eta = if done > 0 { secs * (self.total - done.min(self.total)) as f64 / done as f64 } else { f64::NAN };
        let eta = if eta.is_finite() { format!("{}m{:02}s", (eta / 60.0) as u64, eta as u64 % 60) } else { "?".into() };
        if self.tty {
            let width = 24;
            let filled = (width as u64 * done / self.total) as usize;
            let bar: String = (0..width).map(|i| if i < filled { '#' } else { '.' }).collect();
            eprint!("\r\x1b[2K{} [{bar}] {done}/{}  {detail}  ETA {eta}", self.label, self.total);
            let _ = std::io::stderr().flush();
            if done >= self.total {
                eprintln!();
            }
        } else if done >= self.next_line || done >= self.total {
            eprintln!("{} {done}/{}  {detail}  {secs:.1} s  ETA {eta}", self.label, self.total);
            self.next_line = done + self.total.div_ceil(10);
        }
    }
}
