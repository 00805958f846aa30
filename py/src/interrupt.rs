//! Ctrl-C and a user's exception during a long call: both stop the run through its
//! [`Cancel`], which the engine checks at every fit iteration.
//!
//! A run that calls no Python (a model file's) runs on a thread of its own without the GIL
//! while the caller's thread runs Python's signal handlers every [`POLL`]: it holds no Python
//! call at which the signal could be seen. A run that calls Python (a Python model, an effect's
//! callable) stays on the caller's thread, where the interpreter raises `KeyboardInterrupt` in
//! the user's code like any exception of its own, and keeping that exception ([`Raised`])
//! cancels the run. (Polling beside such a run made a cart-pole's discovery 1.5 times slower:
//! each poll waits for the GIL the run takes at every call.)
use std::sync::Mutex;
use std::time::Duration;

use pyo3::prelude::*;
use workbench::Cancel;

/// How often the caller's thread looks at Python's pending signals.
const POLL: Duration = Duration::from_millis(50);

/// The run thread's stack: a main thread's size (a spawned thread's default is 2 MiB).
const STACK: usize = 8 << 20;

/// The first exception a user's callable raised during the running call, for the caller.
/// Keeping one cancels the run: the exception replaces its result anyway.
#[derive(Debug, Default)]
pub struct Raised {
    first: Mutex<Option<PyErr>>,
    cancel: Cancel,
}

impl Raised {
    /// Keeps `err` unless an earlier one is kept, cancels the run, and returns the error the
    /// run sees in its place: `name`'s `value` failed with the exception's message.
    pub fn keep_as(&self, err: PyErr, name: impl Into<String>, value: &str) -> sim::SimError {
        let message = err.to_string();
        if let Ok(mut slot) = self.first.lock() {
            slot.get_or_insert(err);
        }
        self.cancel.cancel();
        sim::SimError::invalid(name, value, message)
    }

    /// The kept exception, leaving none.
    pub fn take(&self) -> Option<PyErr> {
        self.first.lock().ok().and_then(|mut slot| slot.take())
    }

    /// The flag the runs of this slot's workbench check.
    pub fn cancel(&self) -> &Cancel {
        &self.cancel
    }
}

/// Runs `f` without the GIL with `cancel` cleared: on a thread of its own, while a Python
/// signal handler's exception raised meanwhile sets `cancel` and is returned once `f` has
/// ended; on this thread when `calls_python` (see the module's text). A panic in `f` becomes
/// a `stabilis.Error` naming it as a bug, not a `PanicException` that `except Exception`
/// misses.
pub fn interruptible<R: Send>(
    py: Python<'_>,
    cancel: &Cancel,
    calls_python: bool,
    f: impl FnOnce() -> R + Send,
) -> PyResult<R> {
    cancel.reset();
    if calls_python {
        let result = py.detach(|| std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)));
        return result.map_err(bug);
    }
    std::thread::scope(|scope| {
        let caller = std::thread::current();
        let worker = std::thread::Builder::new()
            .name("stabilis-run".into())
            .stack_size(STACK)
            .spawn_scoped(scope, move || {
                // Should the run call Python after all, the thread keeps one Python thread
                // state for the whole run, released but not destroyed: each call would
                // otherwise create and destroy one (a Python model's discovery run here was
                // 60 times slower).
                let result = Python::attach(|py| {
                    py.detach(|| std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)))
                });
                caller.unpark();
                result
            })
            .map_err(|e| {
                crate::errors::Error::new_err(format!("cannot start the run's thread: {e}"))
            })?;
        let mut interrupt = None;
        while !worker.is_finished() {
            py.detach(|| std::thread::park_timeout(POLL));
            if interrupt.is_none() && !worker.is_finished() {
                if let Err(e) = py.check_signals() {
                    cancel.cancel();
                    interrupt = Some(e);
                }
            }
        }
        let result = worker.join().unwrap_or_else(Err);
        match interrupt {
            Some(e) => Err(e),
            None => result.map_err(bug),
        }
    })
}

/// A panic's payload as a `stabilis.Error` that names it as a bug.
fn bug(panic: Box<dyn std::any::Any + Send>) -> PyErr {
    let what = panic
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| panic.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "no message".into());
    crate::errors::Error::new_err(format!(
        "internal error (a bug in stabilis; please report it with the model and logs): {what}"
    ))
}
