//! `stabilis info FILE`: what a log holds (topics, message counts, time span, fields, metadata).
//! Reads MCAP, or CSV when the file name ends in `.csv`.
use std::collections::BTreeMap;
use std::path::PathBuf;

use serde_json::json;

use super::Output;
use crate::error::Result;
use crate::log::{read_csv, read_mcap, Log, Table};

/// Options of `stabilis info`.
#[derive(Debug, Clone, PartialEq, clap::Args)]
pub struct Args {
    /// The MCAP (or .csv) file.
    pub file: PathBuf,
    /// Fail (exit code 2) unless the log has this topic; may be repeated.
    #[arg(long)]
    pub topic: Vec<String>,
}

impl Args {
    /// Reads the file and summarises it.
    pub fn run(&self) -> Result<Output> {
        let is_csv = self
            .file
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("csv"));
        let log = if is_csv {
            let table = read_csv(&self.file)?;
            Log {
                path: self.file.clone(),
                topics: BTreeMap::from([(table.name.clone(), table)]),
                metadata: BTreeMap::new(),
                complete: true,
                problem: None,
                stamped_by_log_time: Vec::new(),
                reordered: Vec::new(),
            }
        } else {
            read_mcap(&self.file)?
        };
        for topic in &self.topic {
            log.topic(topic)?;
        }
        Ok(summarize(&log))
    }
}

fn span(table: &Table) -> serde_json::Value {
    table
        .span()
        .map_or(serde_json::Value::Null, |(a, b)| json!([a, b]))
}

fn summarize(log: &Log) -> Output {
    let messages: usize = log.topics.values().map(Table::len).sum();
    let start = log
        .topics
        .values()
        .filter_map(Table::span)
        .map(|s| s.0)
        .fold(f64::INFINITY, f64::min);
    let end = log
        .topics
        .values()
        .filter_map(Table::span)
        .map(|s| s.1)
        .fold(f64::NEG_INFINITY, f64::max);
    let mut human = format!(
        "{}: {} topics, {} messages",
        log.path.display(),
        log.topics.len(),
        messages
    );
    if start.is_finite() {
        human.push_str(&format!(", t = {start} .. {end} s"));
    }
    if let Some(problem) = &log.problem {
        human.push_str(&format!(
            "\nwarning: the log is incomplete ({problem}); showing what was read"
        ));
    }
    for (name, table) in &log.topics {
        human.push_str(&format!("\n  {name}: {} messages", table.len()));
        if let Some((a, b)) = table.span() {
            human.push_str(&format!(", t = {a} .. {b} s"));
        }
        human.push_str(&format!(", fields: {}", table.fields.join(" ")));
        if log.stamped_by_log_time.contains(name) {
            human.push_str(" (no t field: times are the messages' log_time)");
        }
        if log.reordered.contains(name) {
            human.push_str(" (out of time order in the file; read in time order)");
        }
    }
    for (name, record) in &log.metadata {
        human.push_str(&format!("\n  metadata {name}:"));
        for (key, value) in record {
            human.push_str(&format!("\n    {key} = {value}"));
        }
    }
    let topics: serde_json::Map<String, serde_json::Value> = log
        .topics
        .iter()
        .map(|(name, table)| {
            (
                name.clone(),
                json!({
                    "messages": table.len(),
                    "span": span(table),
                    "fields": table.fields,
                    "stamped_by_log_time": log.stamped_by_log_time.contains(name),
                    "reordered": log.reordered.contains(name),
                }),
            )
        })
        .collect();
    let json = json!({
        "file": log.path.display().to_string(),
        "complete": log.complete,
        "problem": log.problem,
        "messages": messages,
        "span": if start.is_finite() { json!([start, end]) } else { serde_json::Value::Null },
        "topics": topics,
        "metadata": log.metadata,
    });
    Output { human, json }
}
