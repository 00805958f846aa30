//! MCAP writer for runs: JSON messages with a `t` field, jsonschema schemas, `experiment`
//! metadata. Messages go out in chunks that are closed every few hundred messages, so a process
//! that is killed leaves a file whose completed chunks can still be read. The file is written
//! beside its target (see [`crate::output`]) and renamed onto it by [`LogWriter::finish`]: a run
//! that fails or is dropped unfinished removes its temporary file and leaves the target as it was,
//! a killed run leaves the temporary `.NAME.tmp-PID` with its completed chunks.
use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use crate::error::{Result, SimError};
use crate::output::{Kind, Pending};

/// How often the writer closes its chunk and flushes it to disk, in messages.
pub const DEFAULT_FLUSH_EVERY: usize = 512;

/// A topic added to a [`LogWriter`]; pass it back to [`LogWriter::write`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TopicId(usize);

#[derive(Debug)]
struct Topic {
    name: String,
    channel: u16,
    fields: Vec<String>,
    /// Field names already JSON-quoted, with the separator: `,"x":`.
    keys: Vec<String>,
    sequence: u32,
}

/// Writes one run to an MCAP file.
///
/// ```
/// use workbench::log::{LogWriter, read_mcap};
/// let path = std::env::temp_dir().join(format!("sim_doc_writer_{}.mcap", std::process::id()));
/// let mut log = LogWriter::create(&path).unwrap();
/// let output = log.add_topic("/demo/output", &["x"]).unwrap();
/// log.write(output, 0.0, &[1.0]).unwrap();
/// log.write(output, 0.5, &[2.0]).unwrap();
/// log.finish().unwrap();
/// let read = read_mcap(&path).unwrap();
/// std::fs::remove_file(&path).unwrap();
/// assert_eq!(read.topic("/demo/output").unwrap().column("x").unwrap(), &[1.0, 2.0]);
/// ```
pub struct LogWriter {
    path: PathBuf,
    inner: mcap::Writer<BufWriter<File>>,
    topics: Vec<Topic>,
    flush_every: usize,
    since_flush: usize,
    buffer: Vec<u8>,
    /// Dropped after `inner`, which finishes the file on drop.
    pending: Pending,
}

impl std::fmt::Debug for LogWriter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LogWriter")
            .field("path", &self.path)
            .field("topics", &self.topics)
            .finish_non_exhaustive()
    }
}

impl LogWriter {
    /// Starts a log that will replace `path` when finished (an existing MCAP log there is kept
    /// until then; anything else there is refused, see [`crate::output`]).
    pub fn create(path: impl AsRef<Path>) -> Result<Self> {
        Self::create_for(path, &[])
    }

    /// Like [`LogWriter::create`], refusing a `path` that is one of `inputs` or inside one.
    pub fn create_for(path: impl AsRef<Path>, inputs: &[PathBuf]) -> Result<Self> {
        Self::with_flush_every(path, inputs, DEFAULT_FLUSH_EVERY)
    }

    /// Like [`LogWriter::create_for`], closing a chunk every `flush_every` messages (at least 1).
    pub fn with_flush_every(
        path: impl AsRef<Path>,
        inputs: &[PathBuf],
        flush_every: usize,
    ) -> Result<Self> {
        let path = path.as_ref().to_path_buf();
        let pending = Pending::file(&path, Kind::Mcap, inputs)?;
        // The temporary file is the one `Pending` just created. Not `SimError::io`: a missing
        // directory is not a missing input file.
        let file = File::create(pending.path()).map_err(|source| SimError::Io {
            path: path.clone(),
            source,
        })?;
        let inner = mcap::WriteOptions::new()
            .profile("")
            .library(crate::output::WRITTEN_AS)
            .create(BufWriter::new(file))
            .map_err(|source| mcap_error(&path, source))?;
        Ok(Self {
            path,
            inner,
            topics: Vec::new(),
            flush_every: flush_every.max(1),
            since_flush: 0,
            buffer: Vec::new(),
            pending,
        })
    }

    /// Adds a topic whose messages carry `t` and the given number fields.
    pub fn add_topic<S: AsRef<str>>(&mut self, topic: &str, fields: &[S]) -> Result<TopicId> {
        if self.topics.iter().any(|t| t.name == topic) {
            return Err(SimError::invalid(
                "topic",
                topic,
                "added twice to the same log",
            ));
        }
        let mut seen = std::collections::BTreeSet::new();
        for field in fields {
            let field = field.as_ref();
            if field == "t" || !seen.insert(field) {
                return Err(SimError::invalid(
                    format!("field of {topic}"),
                    field,
                    "field names must be unique and must not be `t`",
                ));
            }
        }
        let schema = json_schema(topic, fields);
        let schema_name = topic.trim_start_matches('/').replace('/', ".");
        let schema_id = self
            .inner
            .add_schema(&schema_name, "jsonschema", schema.as_bytes())
            .map_err(|source| mcap_error(&self.path, source))?;
        let channel = self
            .inner
            .add_channel(schema_id, topic, "json", &BTreeMap::new())
            .map_err(|source| mcap_error(&self.path, source))?;
        let keys = fields
            .iter()
            .map(|f| format!(",{}:", serde_json::Value::from(f.as_ref())))
            .collect();
        self.topics.push(Topic {
            name: topic.to_string(),
            channel,
            fields: fields.iter().map(|f| f.as_ref().to_string()).collect(),
            keys,
            sequence: 0,
        });
        Ok(TopicId(self.topics.len() - 1))
    }

    /// Writes one message: `t` in seconds (finite, not negative) and one finite value per field.
    pub fn write(&mut self, topic: TopicId, t: f64, values: &[f64]) -> Result<()> {
        let entry = self
            .topics
            .get_mut(topic.0)
            .ok_or_else(|| SimError::invalid("topic id", topic.0, "not added to this log"))?;
        if values.len() != entry.keys.len() {
            return Err(SimError::LengthMismatch {
                what: format!("message on {} at t = {t}", entry.name),
                expected: entry.keys.len(),
                found: values.len(),
            });
        }
        if !t.is_finite() || t < 0.0 {
            return Err(SimError::NotFinite {
                context: entry.name.clone(),
                field: "t".into(),
                value: format!("{t} (must be finite and not negative)"),
            });
        }
        self.buffer.clear();
        self.buffer.extend_from_slice(b"{\"t\":");
        push_number(&mut self.buffer, t);
        for ((key, field), &value) in entry.keys.iter().zip(&entry.fields).zip(values) {
            if !value.is_finite() {
                return Err(SimError::NotFinite {
                    context: format!("{} at t = {t}", entry.name),
                    field: field.clone(),
                    value: value.to_string(),
                });
            }
            self.buffer.extend_from_slice(key.as_bytes());
            push_number(&mut self.buffer, value);
        }
        self.buffer.push(b'}');
        let log_time = (t * 1e9).round() as u64;
        let header = mcap::records::MessageHeader {
            channel_id: entry.channel,
            sequence: entry.sequence,
            log_time,
            publish_time: log_time,
        };
        entry.sequence = entry.sequence.wrapping_add(1);
        self.inner
            .write_to_known_channel(&header, &self.buffer)
            .map_err(|source| mcap_error(&self.path, source))?;
        self.since_flush += 1;
        if self.since_flush >= self.flush_every {
            self.flush()?;
        }
        Ok(())
    }

    /// Writes a metadata record; MCAP metadata values are strings.
    pub fn write_metadata(&mut self, name: &str, values: BTreeMap<String, String>) -> Result<()> {
        self.inner
            .write_metadata(&mcap::records::Metadata {
                name: name.to_string(),
                metadata: values,
            })
            .map_err(|source| mcap_error(&self.path, source))
    }

    /// Closes the current chunk and pushes everything written so far to the file.
    pub fn flush(&mut self) -> Result<()> {
        self.since_flush = 0;
        self.inner
            .flush()
            .map_err(|source| mcap_error(&self.path, source))
    }

    /// Writes the summary and footer, closes the file and renames it onto its target. Dropping
    /// the writer instead removes the unfinished file.
    pub fn finish(mut self) -> Result<()> {
        self.inner
            .finish()
            .map_err(|source| mcap_error(&self.path, source))?;
        let file = self
            .inner
            .into_inner()
            .into_inner()
            .map_err(|e| SimError::io(&self.path, e.into_error()))?;
        file.sync_all().map_err(|e| SimError::io(&self.path, e))?;
        drop(file);
        self.pending.commit()
    }

    /// The file being written.
    pub fn path(&self) -> &Path {
        &self.path
    }
}

fn mcap_error(path: &Path, source: mcap::McapError) -> SimError {
    match source {
        mcap::McapError::Io(e) => SimError::io(path, e),
        source => SimError::Mcap {
            path: path.to_path_buf(),
            source,
        },
    }
}

fn push_number(buffer: &mut Vec<u8>, value: f64) {
    // serde_json prints the shortest representation that reads back to the same f64.
    buffer.extend_from_slice(serde_json::Value::from(value).to_string().as_bytes());
}

/// The jsonschema of a topic: an object of named numbers, `t` first; `required` keeps the order.
fn json_schema<S: AsRef<str>>(topic: &str, fields: &[S]) -> String {
    let mut properties = serde_json::Map::new();
    properties.insert(
        "t".into(),
        serde_json::json!({"type": "number", "description": "time, s"}),
    );
    let mut required = vec![serde_json::Value::from("t")];
    for field in fields {
        properties.insert(field.as_ref().into(), serde_json::json!({"type": "number"}));
        required.push(field.as_ref().into());
    }
    serde_json::json!({
        "title": topic,
        "type": "object",
        "properties": properties,
        "required": required,
    })
    .to_string()
}
