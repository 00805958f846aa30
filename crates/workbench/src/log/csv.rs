//! CSV measurements: a header row, a `t` column in seconds, and the same field names as the
//! MCAP topics. Read into the same [`Table`] as an MCAP topic. Fields are separated by commas,
//! or by the semicolons or tabs of the header row; lines starting with `#` are comments.
use std::path::Path;

use super::Table;
use crate::error::{Result, SimError};

/// Reads the CSV file at `path` into a table named after the file.
///
/// ```
/// let path = std::env::temp_dir().join(format!("sim_doc_read_{}.csv", std::process::id()));
/// std::fs::write(&path, "t,x\n0,1.5\n0.1,2.5\n").unwrap();
/// let table = workbench::log::read_csv(&path).unwrap();
/// std::fs::remove_file(&path).unwrap();
/// assert_eq!(table.column("x").unwrap(), &[1.5, 2.5]);
/// ```
pub fn read_csv(path: impl AsRef<Path>) -> Result<Table> {
    let path = path.as_ref();
    let text = std::fs::read(path).map_err(|e| SimError::io(path, e))?;
    let csv_error = |reason: String| SimError::Csv {
        path: path.to_path_buf(),
        reason,
    };
    if text.iter().all(u8::is_ascii_whitespace) {
        return Err(csv_error(
            "the file is empty: a CSV needs a header row (t and the channel names) and one row per sample".into(),
        ));
    }
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(true)
        .trim(csv::Trim::All)
        .comment(Some(b'#'))
        .delimiter(delimiter(&text))
        .from_reader(text.as_slice());
    let header: Vec<String> = reader
        .headers()
        .map_err(|e| csv_error(format!("cannot read the header row: {e}")))?
        .iter()
        .map(String::from)
        .collect();
    for (i, name) in header.iter().enumerate() {
        if let Some(first) = header[..i].iter().position(|h| h == name) {
            return Err(csv_error(format!(
                "column {name:?} appears twice in the header row (columns {} and {})",
                first + 1,
                i + 1
            )));
        }
    }
    let t_index = header
        .iter()
        .position(|h| h == "t")
        .ok_or_else(|| SimError::MissingField {
            context: format!("header row of {}", path.display()),
            field: "t".into(),
            available: header.clone(),
        })?;
    let fields: Vec<String> = header
        .iter()
        .enumerate()
        .filter(|&(i, _)| i != t_index)
        .map(|(_, h)| h.clone())
        .collect();
    let mut table = Table::new(path.display().to_string(), fields);
    let mut values = Vec::with_capacity(header.len());
    // The last row's time and byte offset: a time that does not increase is named by its line
    // here, where the file's lines are known (the table names samples). Lines are counted
    // only for a message: counting them at every row made reading quadratic in the rows.
    let mut before: Option<(f64, Option<u64>)> = None;
    for record in reader.records() {
        let record = record.map_err(|e| csv_error(e.to_string()))?;
        let byte = record.position().map(|p| p.byte());
        values.clear();
        let mut t = 0.0;
        for (i, (cell, name)) in record.iter().zip(&header).enumerate() {
            let value: f64 = cell.parse().map_err(|_| {
                let hint = if cell.contains(',') {
                    " (a decimal comma? numbers need a decimal point)"
                } else {
                    ""
                };
                csv_error(format!(
                    "line {}, column {name:?}: {cell:?} is not a number{hint}",
                    line_at(&text, byte)
                ))
            })?;
            if !value.is_finite() {
                return Err(SimError::NotFinite {
                    context: format!("{} line {}", path.display(), line_at(&text, byte)),
                    field: name.clone(),
                    value: cell.to_string(),
                });
            }
            if i == t_index {
                t = value;
            } else {
                values.push(value);
            }
        }
        if let Some((t0, byte0)) = before.filter(|&(t0, _)| t <= t0) {
            return Err(csv_error(format!(
                "line {}: t = {t} s does not increase (line {} is at t = {t0} s): rows must be in time order, each sample once",
                line_at(&text, byte),
                line_at(&text, byte0)
            )));
        }
        before = Some((t, byte));
        table.push(t, &values)?;
    }
    Ok(table)
}

/// The line of the record the reader places at byte `byte` of `text` (0 when the reader gives
/// no position). The reader may place a record on the line end before it (after a Windows
/// `\r\n`) or on a comment line before it, and counts lines the same way, so such a file named
/// an earlier line than the bad one: line ends and comment lines are skipped here.
fn line_at(text: &[u8], byte: Option<u64>) -> usize {
    let Some(byte) = byte else {
        return 0;
    };
    let mut at = (byte as usize).min(text.len());
    while at < text.len() {
        if matches!(text[at], b'\n' | b'\r') {
            at += 1;
        } else if text[at] == b'#' {
            at += text[at..]
                .iter()
                .position(|&b| b == b'\n')
                .unwrap_or(text.len() - at);
        } else {
            break;
        }
    }
    1 + text[..at].iter().filter(|&&b| b == b'\n').count()
}

/// The field delimiter: a comma, or else the semicolon or tab that separates the header row's
/// fields (spreadsheets in many locales write `;`, and some loggers tab-separated values), so
/// that such a file reads instead of failing with its whole header taken as one field. Lines
/// before the header that start with `#` are comments.
fn delimiter(text: &[u8]) -> u8 {
    let header = text
        .split(|&b| b == b'\n')
        .find(|line| !line.trim_ascii().is_empty() && !line.starts_with(b"#"))
        .unwrap_or_default();
    let count = |d: u8| header.iter().filter(|&&b| b == d).count();
    [b',', b';', b'\t']
        .into_iter()
        .find(|&d| count(d) > 0)
        .unwrap_or(b',')
}
