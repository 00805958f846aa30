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
pub use table::Table;
pub use writer::{LogWriter, TopicId, DEFAULT_FLUSH_EVERY};

#[cfg(test)]
mod tests;
