//! Progress bars for long jobs: drawn on stderr only when it is a terminal, and only once the job
//! has run for a second, so short commands and pipes stay clean.
use std::io::IsTerminal;
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

const SHOW_AFTER: Duration = Duration::from_secs(1);

/// A progress bar that appears after one second on an interactive stderr.
#[derive(Debug)]
pub struct Progress {
    bar: ProgressBar,
    started: Instant,
    interactive: bool,
    shown: bool,
}

impl Progress {
    /// A bar for `len` units of work, labelled `message`.
    pub fn new(len: u64, message: &str) -> Self {
        let bar = ProgressBar::with_draw_target(Some(len), ProgressDrawTarget::hidden());
        if let Ok(style) = ProgressStyle::with_template("{msg} [{bar:40}] {percent}% (eta {eta})") {
            bar.set_style(style.progress_chars("=> "));
        }
        bar.set_message(message.to_string());
        Self {
            bar,
            started: Instant::now(),
            interactive: std::io::stderr().is_terminal(),
            shown: false,
        }
    }

    /// A bar that never draws (library and Python use).
    pub fn hidden() -> Self {
        let mut progress = Self::new(0, "");
        progress.interactive = false;
        progress
    }

    /// Sets the position to `done` units.
    pub fn set(&mut self, done: u64) {
        if self.interactive && !self.shown && self.started.elapsed() >= SHOW_AFTER {
            self.bar.set_draw_target(ProgressDrawTarget::stderr());
            self.shown = true;
        }
        self.bar.set_position(done);
    }

    /// Replaces the label (a rate, a count).
    pub fn set_message(&self, message: &str) {
        self.bar.set_message(message.to_string());
    }

    /// Removes the bar from the terminal.
    pub fn finish(&self) {
        self.bar.finish_and_clear();
    }
}
