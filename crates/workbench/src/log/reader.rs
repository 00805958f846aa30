//! Reads an MCAP log into one [`Table`] per topic plus its metadata records. The file is read
//! front to back, so a log whose writer was killed before the summary still yields every
//! complete chunk; [`Log::complete`] says whether the data section ended properly.
//!
//! Damage is an error, never numbers: every chunk's CRC is checked before any of its messages
//! is used, every record length is bounded before anything is allocated for it (see
//! [`record_limit`]), and within a topic no two messages may share a time. MCAP does not ask a
//! writer to keep its messages in time order (chunks may be flushed out of order), so a topic
//! whose messages are not is read in time order and listed in [`Log::reordered`]. In logs
//! this program wrote, whose `log_time` is `t` in nanoseconds by construction, the two must
//! agree (other recorders stamp `log_time` at reception, so there it is not compared). A
//! topic whose first message has no `t` takes every message's `log_time` as its sample time
//! instead (a recorder that stamps messages but writes no time field), listed in
//! [`Log::stamped_by_log_time`]. A file that merely stops early (a killed run) is read up to
//! its last complete chunk, with [`Log::problem`] saying so.
use std::borrow::Cow;
use std::collections::{BTreeMap, HashMap};
use std::fmt;
use std::path::{Path, PathBuf};

use serde::de::{self, Deserialize, Deserializer, MapAccess, Visitor};
use serde_json::Value;

use super::Table;
use crate::error::{Result, SimError};

const MAGIC: &[u8] = b"\x89MCAP0\r\n";

/// A whole log: per-topic tables and metadata records by name.
#[derive(Debug, Clone, PartialEq)]
pub struct Log {
    /// The file it was read from.
    pub path: PathBuf,
    /// One table per topic, by topic name.
    pub topics: BTreeMap<String, Table>,
    /// Metadata records by name (e.g. `experiment`).
    pub metadata: BTreeMap<String, BTreeMap<String, String>>,
    /// False when the file stops before its data-end record (a run that was cut off).
    pub complete: bool,
    /// Why reading stopped early, when it did.
    pub problem: Option<String>,
    /// Topics whose messages carry no `t`: their sample times are the messages' `log_time`,
    /// in seconds from the file's earliest message (a wall clock's nanoseconds near 1.7e18
    /// would keep only 0.24 µs in an f64, 0.02 % of a 1 ms step).
    pub stamped_by_log_time: Vec<String>,
    /// Topics whose messages the file holds out of time order, put back in order.
    pub reordered: Vec<String>,
}

impl Log {
    /// The table of `topic`, or [`SimError::MissingTopic`] listing the topics there are.
    pub fn topic(&self, topic: &str) -> Result<&Table> {
        self.topics
            .get(topic)
            .ok_or_else(|| SimError::MissingTopic {
                path: self.path.clone(),
                topic: topic.to_string(),
                available: self.topics.keys().cloned().collect(),
            })
    }

    /// The `experiment` metadata record, if the log has one.
    pub fn experiment(&self) -> Option<&BTreeMap<String, String>> {
        self.metadata.get("experiment")
    }
}

struct Channel {
    topic: String,
    /// Fields from the schema; `None` until the first message when the schema names none.
    fields: Option<Vec<String>>,
    /// `log_time` minus `t` of the first message, s (zero in logs this program wrote; kept
    /// general so that a rebased log still reads).
    offset: Option<f64>,
    /// Set by the first message: whether the topic's times are its messages' `log_time`
    /// (the first message has no `t`).
    by_log_time: Option<bool>,
}

/// The longest record, compressed or not, that a file of `file_len` bytes may hold: a thousand
/// times the file (zstd and lz4 chunks of numeric logs compress by far less) and at most half
/// the memory available, so that a corrupt length is a named error rather than an allocation
/// that aborts the process.
pub fn record_limit(file_len: usize) -> usize {
    let by_file = file_len.saturating_mul(1000).max(1 << 20);
    by_file.min(crate::limits::available_memory() / 2)
}

/// How far `t` may stray from `log_time` (after the first message's offset), s: the writer
/// rounds `t` to whole nanoseconds, and a wall-clock `log_time` near 1.7e9 s holds about 0.2 µs
/// in an f64.
const LOG_TIME_TOLERANCE_S: f64 = 1e-6;

/// Reads the MCAP file at `path`.
pub fn read_mcap(path: impl AsRef<Path>) -> Result<Log> {
    let path = path.as_ref();
    let bytes = std::fs::read(path).map_err(|e| SimError::io(path, e))?;
    read_mcap_bytes(path, &bytes)
}

/// Reads an MCAP file already in memory; `path` is used in messages only.
pub fn read_mcap_bytes(path: &Path, bytes: &[u8]) -> Result<Log> {
    if !bytes.starts_with(MAGIC) {
        let reason = if bytes.len() < MAGIC.len() {
            format!("{} bytes long, shorter than the MCAP magic", bytes.len())
        } else {
            "does not start with the MCAP magic bytes".to_string()
        };
        return Err(SimError::NotMcap {
            path: path.to_path_buf(),
            reason,
        });
    }
    let options = mcap::sans_io::LinearReaderOptions::default()
        .with_skip_end_magic(true)
        .with_prevalidate_chunk_crcs(true)
        .with_record_length_limit(record_limit(bytes.len()));
    let mut reader = mcap::sans_io::LinearReader::new_with_options(options);
    let mut rest = bytes;
    let mut schemas: HashMap<u16, Option<Vec<String>>> = HashMap::new();
    let mut channels: HashMap<u16, Channel> = HashMap::new();
    let mut log = Log {
        path: path.to_path_buf(),
        topics: BTreeMap::new(),
        metadata: BTreeMap::new(),
        complete: false,
        problem: None,
        stamped_by_log_time: Vec::new(),
        reordered: Vec::new(),
    };
    // Whether `log_time` is `t` in nanoseconds by construction (logs this program wrote).
    let mut ours = false;
    // The first message's `log_time`, from which topics without `t` count their times until
    // the earliest is known.
    let mut first_log_time: Option<u64> = None;
    let mut earliest_log_time = u64::MAX;
    let damaged = |source| SimError::Mcap {
        path: path.to_path_buf(),
        source,
    };
    while let Some(event) = reader.next_event() {
        let (opcode, data) = match event {
            Ok(mcap::sans_io::LinearReadEvent::ReadRequest(need)) => {
                // Never more than the file holds, whatever length a record claims.
                let n = need.min(rest.len());
                reader.insert(n).copy_from_slice(&rest[..n]);
                reader.notify_read(n);
                rest = &rest[n..];
                continue;
            }
            Ok(mcap::sans_io::LinearReadEvent::Record { opcode, data }) => (opcode, data),
            // The whole file was read and a record (or the chunk holding it) is incomplete:
            // a run cut off while writing.
            Err(
                e @ (mcap::McapError::UnexpectedEof
                | mcap::McapError::UnexpectedEoc
                | mcap::McapError::DecompressionError(_)),
            ) if rest.is_empty() => {
                log.problem = Some(format!("the file ends inside a record ({e})"));
                break;
            }
            Err(source) => return Err(damaged(source)),
        };
        match mcap::parse_record(opcode, data).map_err(damaged)? {
            mcap::records::Record::Header(header) => {
                ours = header.library.starts_with("stabilis");
            }
            mcap::records::Record::Schema { header, data } => {
                let fields = (header.encoding == "jsonschema")
                    .then(|| schema_fields(&data))
                    .flatten();
                schemas.insert(header.id, fields);
            }
            mcap::records::Record::Channel(channel) => {
                if channel.message_encoding != "json" {
                    return Err(SimError::BadMessage {
                        context: format!("channel {}", channel.topic),
                        reason: format!(
                            "message encoding is {:?}; stabilis reads json",
                            channel.message_encoding
                        ),
                    });
                }
                let fields = schemas.get(&channel.schema_id).cloned().flatten();
                channels.insert(
                    channel.id,
                    Channel {
                        topic: channel.topic,
                        fields,
                        offset: None,
                        by_log_time: None,
                    },
                );
            }
            mcap::records::Record::Message { header, data } => {
                let channel =
                    channels
                        .get_mut(&header.channel_id)
                        .ok_or_else(|| SimError::BadMessage {
                            context: format!(
                                "message {} of channel id {}",
                                header.sequence, header.channel_id
                            ),
                            reason: "its channel was never declared".into(),
                        })?;
                let base = *first_log_time.get_or_insert(header.log_time);
                earliest_log_time = earliest_log_time.min(header.log_time);
                let since_first = (i128::from(header.log_time) - i128::from(base)) as f64 * 1e-9;
                let stamp = Stamp {
                    log_time: header.log_time,
                    since_first,
                    ours,
                };
                add_message(&mut log.topics, channel, stamp, &data)?;
            }
            mcap::records::Record::Metadata(metadata) => {
                log.metadata.insert(metadata.name, metadata.metadata);
            }
            mcap::records::Record::DataEnd(_) => {
                log.complete = true;
                break;
            }
            _ => {}
        }
    }
    if !log.complete && log.problem.is_none() {
        log.problem = Some("the file ends before its data-end record".into());
    }
    // Declared topics without messages still appear, as empty tables.
    for channel in channels.into_values() {
        if channel.by_log_time == Some(true) {
            log.stamped_by_log_time.push(channel.topic.clone());
        }
        log.topics
            .entry(channel.topic.clone())
            .or_insert_with(|| Table::new(channel.topic, channel.fields.unwrap_or_default()));
    }
    // Channels come from a hash map: name the topics in a stable order.
    log.stamped_by_log_time.sort();
    log.stamped_by_log_time.dedup();
    // Count the stamped times from the earliest message rather than the first in the file.
    let rebase = first_log_time.map_or(0.0, |first| (first - earliest_log_time) as f64 * 1e-9);
    for (name, table) in &mut log.topics {
        let by_log_time = log.stamped_by_log_time.contains(name);
        if by_log_time && rebase > 0.0 {
            table.t.iter_mut().for_each(|t| *t += rebase);
        }
        if put_in_time_order(table, if by_log_time { "log_time" } else { "t" })? {
            log.reordered.push(name.clone());
        }
    }
    Ok(log)
}

/// Puts a topic's messages in time order; true if they had to move. Two messages at the same
/// time cannot both be samples (a repeated chunk, two recordings on one topic): an error
/// naming both.
fn put_in_time_order(table: &mut Table, clock: &str) -> Result<bool> {
    let t = &table.t;
    if t.windows(2).all(|w| w[0] < w[1]) {
        return Ok(false);
    }
    // Stable: messages at one time keep their file order, so the first of a pair is earlier.
    let mut order: Vec<usize> = (0..t.len()).collect();
    order.sort_by(|&a, &b| t[a].total_cmp(&t[b]));
    if let Some(pair) = order.windows(2).find(|p| t[p[0]] == t[p[1]]) {
        return Err(SimError::BadMessage {
            context: table.name.clone(),
            reason: format!(
                "messages {} and {} are both at {clock} = {} s (repeated, or two recordings on \
                 one topic?)",
                pair[0], pair[1], t[pair[0]]
            ),
        });
    }
    table.t = order.iter().map(|&k| t[k]).collect();
    for column in &mut table.columns {
        *column = order.iter().map(|&k| column[k]).collect();
    }
    Ok(true)
}

/// Number fields of a jsonschema object, `required` order first, then the rest by name.
fn schema_fields(data: &[u8]) -> Option<Vec<String>> {
    let schema: Value = serde_json::from_slice(data).ok()?;
    let properties = schema.get("properties")?.as_object()?;
    let is_number = |name: &str| {
        properties
            .get(name)
            .and_then(|p| p.get("type"))
            .and_then(Value::as_str)
            .is_some_and(|ty| ty == "number" || ty == "integer")
    };
    let mut fields: Vec<String> = schema
        .get("required")
        .and_then(Value::as_array)
        .into_iter()
        .flatten()
        .filter_map(Value::as_str)
        .filter(|&name| name != "t" && is_number(name))
        .map(String::from)
        .collect();
    for name in properties.keys() {
        if name != "t" && is_number(name) && !fields.contains(name) {
            fields.push(name.clone());
        }
    }
    Some(fields)
}

/// A field name of a message, borrowed from the message bytes unless it holds escapes.
struct Key<'a>(Cow<'a, str>);

impl<'de> Deserialize<'de> for Key<'de> {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> std::result::Result<Self, D::Error> {
        struct KeyVisitor;
        impl<'de> Visitor<'de> for KeyVisitor {
            type Value = Key<'de>;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a field name")
            }
            fn visit_borrowed_str<E: de::Error>(
                self,
                v: &'de str,
            ) -> std::result::Result<Key<'de>, E> {
                Ok(Key(Cow::Borrowed(v)))
            }
            fn visit_str<E: de::Error>(self, v: &str) -> std::result::Result<Key<'de>, E> {
                Ok(Key(Cow::Owned(v.to_owned())))
            }
        }
        deserializer.deserialize_str(KeyVisitor)
    }
}

/// The entries of a message's JSON object in message order. Read without building a map
/// (logs hold one message per sample and topic, so this is most of the loading time).
struct Entries<'a>(Vec<(Cow<'a, str>, Value)>);

impl<'de> Deserialize<'de> for Entries<'de> {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> std::result::Result<Self, D::Error> {
        struct EntriesVisitor;
        impl<'de> Visitor<'de> for EntriesVisitor {
            type Value = Entries<'de>;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a JSON object")
            }
            fn visit_map<A: MapAccess<'de>>(
                self,
                mut map: A,
            ) -> std::result::Result<Entries<'de>, A::Error> {
                let mut entries = Vec::with_capacity(map.size_hint().unwrap_or(16));
                while let Some((Key(k), v)) = map.next_entry::<Key, Value>()? {
                    entries.push((k, v));
                }
                Ok(Entries(entries))
            }
        }
        deserializer.deserialize_map(EntriesVisitor)
    }
}

impl Entries<'_> {
    /// The value of `name` (the last one when a name repeats, as a JSON map keeps it).
    fn get(&self, name: &str) -> Option<&Value> {
        self.0.iter().rev().find(|(k, _)| k == name).map(|(_, v)| v)
    }

    /// The entries by name, sorted, a repeated name holding its last value.
    fn by_name(&self) -> BTreeMap<&str, &Value> {
        self.0.iter().map(|(k, v)| (k.as_ref(), v)).collect()
    }

    /// The field names, sorted.
    fn names(&self) -> Vec<String> {
        self.by_name().into_keys().map(String::from).collect()
    }
}

/// A message's `log_time` as the reader uses it.
struct Stamp {
    /// As recorded, ns.
    log_time: u64,
    /// From the file's first message, s: the sample time of a topic without `t`.
    since_first: f64,
    /// The file says this program wrote it, so `log_time` is `t` in nanoseconds and the two
    /// are compared.
    ours: bool,
}

/// Adds one message to its topic's table.
fn add_message(
    topics: &mut BTreeMap<String, Table>,
    channel: &mut Channel,
    stamp: Stamp,
    data: &[u8],
) -> Result<()> {
    let index = topics.get(&channel.topic).map_or(0, Table::len);
    let context = || format!("{} message {index}", channel.topic);
    let object: Entries = serde_json::from_slice(data).map_err(|e| SimError::BadMessage {
        context: context(),
        reason: format!("not a JSON object: {e}"),
    })?;
    let by_log_time = *channel
        .by_log_time
        .get_or_insert_with(|| object.get("t").is_none());
    let t = match object.get("t") {
        _ if by_log_time => stamp.since_first,
        Some(value) => number(value, context, "t")?,
        None => {
            return Err(SimError::MissingField {
                context: format!("{} (the topic's first message has one)", context()),
                field: "t".into(),
                available: object.names(),
            })
        }
    };
    let fields = channel.fields.get_or_insert_with(|| {
        object
            .by_name()
            .into_iter()
            .filter(|(name, value)| *name != "t" && value.is_number())
            .map(|(name, _)| name.to_string())
            .collect()
    });
    if stamp.ours && !by_log_time {
        let (log_time, stamped) = (stamp.log_time, stamp.log_time as f64 * 1e-9);
        let offset = *channel.offset.get_or_insert(stamped - t);
        if (stamped - t - offset).abs() > LOG_TIME_TOLERANCE_S {
            return Err(SimError::BadMessage {
                context: context(),
                reason: format!(
                    "t = {t} s disagrees with its log_time {log_time} ns (expected {:.0} ns)",
                    (t + offset) * 1e9
                ),
            });
        }
    }
    let context = || format!("{} at t = {t}", channel.topic);
    let mut values = Vec::with_capacity(fields.len());
    for field in fields.iter() {
        let value = object.get(field).ok_or_else(|| SimError::MissingField {
            context: context(),
            field: field.clone(),
            available: object.names(),
        })?;
        values.push(number(value, context, field)?);
    }
    match topics.get_mut(&channel.topic) {
        Some(table) => table.push(t, &values),
        None => {
            let mut table = Table::new(channel.topic.clone(), fields.clone());
            table.push(t, &values)?;
            topics.insert(channel.topic.clone(), table);
            Ok(())
        }
    }
}

/// A finite number, or a named error (JSON writers turn NaN into `null`).
/// `context` is only formatted on error.
fn number(value: &Value, context: impl Fn() -> String, field: &str) -> Result<f64> {
    match value.as_f64() {
        Some(x) if x.is_finite() => Ok(x),
        _ => Err(SimError::NotFinite {
            context: context(),
            field: field.to_string(),
            value: value.to_string(),
        }),
    }
}
