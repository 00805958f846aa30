//! Measurement logs. MCAP is the one format for simulated and measured runs (JSON messages
//! with `t` in seconds, jsonschema schemas of named numbers, log time = t in ns, an
//! `experiment` metadata record); CSV with a `t` column is accepted for reading too.
mod csv;
mod experiment;
mod reader;
mod table;
mod writer;

pub use self::csv::read_csv;
pub use experiment::{Experiment, Periodic, EXPERIMENT};
pub use reader::{read_mcap, read_mcap_bytes, Log};
pub use table::{Jitter, Table};
pub use writer::{LogWriter, TopicId, DEFAULT_FLUSH_EVERY};

/// Refuses a list of logs in which one file appears twice (by another path, a link, or as an
/// identical copy): it would count as two experiments.
pub fn refuse_repeats(files: &[std::path::PathBuf]) -> crate::Result<()> {
    let identity = |p: &std::path::Path| p.canonicalize().unwrap_or_else(|_| p.to_path_buf());
    for (i, a) in files.iter().enumerate() {
        for b in &files[..i] {
            let same = identity(a) == identity(b) || {
                let (ma, mb) = (std::fs::metadata(a), std::fs::metadata(b));
                matches!((ma, mb), (Ok(ma), Ok(mb)) if ma.len() == mb.len())
                    && std::fs::read(a).ok() == std::fs::read(b).ok()
            };
            if same {
                return Err(crate::SimError::invalid(
                    "data",
                    a.display(),
                    format!(
                        "is the same log as {}; each experiment must be given once",
                        b.display()
                    ),
                ));
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests;
