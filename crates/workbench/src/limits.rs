//! Sizes a user asks for (a duration, a number of periods or vehicles) checked against the
//! memory the machine has before anything is allocated: a named error giving the size asked
//! and the limit, instead of an allocation that aborts the process.
use crate::error::{Result, SimError};

/// Bytes of memory available (`MemAvailable` of /proc/meminfo; 4 GiB where that is unknown).
pub fn available_memory() -> usize {
    std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|text| {
            let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
            let kib: usize = line.split_whitespace().nth(1)?.parse().ok()?;
            Some(kib.saturating_mul(1024))
        })
        .unwrap_or(4 << 30)
}

/// A generous bound on the bytes one sample of a simulated run holds: the trajectory of the
/// domain crate plus the recorded topics (the widest scenario records under 60 numbers).
pub const BYTES_PER_SAMPLE: f64 = 1024.0;

/// The budget of one run: half the memory available.
pub fn budget() -> f64 {
    available_memory() as f64 / 2.0
}

/// Checks that `count` items (samples, matrix entries) of `bytes_per_item` bytes each fit in
/// [`budget`]; `name = value` is the option as the user spelled it. Returns `count` rounded.
///
/// ```
/// let err = workbench::limits::check("duration", 1e9, 1e11, 200.0).unwrap_err();
/// assert!(err.to_string().starts_with("invalid duration = 1000000000:"), "{err}");
/// assert_eq!(workbench::limits::check("duration", 10.0, 1000.0, 200.0).unwrap(), 1000);
/// ```
pub fn check(name: &str, value: impl ToString, count: f64, bytes_per_item: f64) -> Result<usize> {
    if !(count.is_finite() && count >= 0.0) {
        return Err(SimError::invalid(
            name,
            value.to_string(),
            "must be a finite size, not negative",
        ));
    }
    let need = count * bytes_per_item;
    let budget = budget();
    if need > budget {
        return Err(SimError::invalid(
            name,
            value.to_string(),
            format!(
                "needs about {need:.3e} bytes ({count:.3e} x {bytes_per_item} B), more than the \
                 {budget:.3e} bytes (half the memory available) a run may use"
            ),
        ));
    }
    Ok(count.round() as usize)
}
