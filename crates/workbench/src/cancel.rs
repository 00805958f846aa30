//! Stopping a long run from outside it. A run (a fit, a discovery, a power study) checks its
//! [`Cancel`] between iterations and ends with [`SimError::Cancelled`] once it is set; the
//! Python binding sets it on Ctrl-C, which a run without Python calls could not otherwise see.
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use crate::{Result, SimError};

/// A flag shared by a run and whoever may stop it; clones share it. The default is never set
/// by anyone else.
#[derive(Debug, Clone, Default)]
pub struct Cancel(Arc<AtomicBool>);

impl Cancel {
    /// Asks every run that holds this flag to stop at its next check.
    pub fn cancel(&self) {
        self.0.store(true, Ordering::Relaxed);
    }

    /// Clears the flag for the next run.
    pub fn reset(&self) {
        self.0.store(false, Ordering::Relaxed);
    }

    /// Whether a stop was asked for.
    pub fn is_cancelled(&self) -> bool {
        self.0.load(Ordering::Relaxed)
    }

    /// `Err(SimError::Cancelled)` once a stop was asked for.
    pub fn check(&self) -> Result<()> {
        if self.is_cancelled() {
            Err(SimError::Cancelled)
        } else {
            Ok(())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Cancel;
    use crate::SimError;

    /// A clone sees the stop asked through another, until the flag is reset.
    #[test]
    fn clones_share_the_flag() {
        let run = Cancel::default();
        let handler = run.clone();
        assert!(run.check().is_ok());
        handler.cancel();
        assert!(matches!(run.check(), Err(SimError::Cancelled)));
        run.reset();
        assert!(!handler.is_cancelled());
    }
}
