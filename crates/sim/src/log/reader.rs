//! Reads an MCAP log into one [`Table`] per topic plus its metadata records. The file is read
//! front to back, so a log whose writer was killed before the summary still yields every
//! complete chunk; [`Log::complete`] says whether the data section ended properly.
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
}

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
    let records = mcap::read::ChunkFlattener::new_with_options(
        bytes,
        mcap::read::Options::IgnoreEndMagic.into(),
    )
    .map_err(|source| SimError::Mcap {
        path: path.to_path_buf(),
        source,
    })?;

    let mut schemas: HashMap<u16, Option<Vec<String>>> = HashMap::new();
    let mut channels: HashMap<u16, Channel> = HashMap::new();
    let mut log = Log {
        path: path.to_path_buf(),
        topics: BTreeMap::new(),
        metadata: BTreeMap::new(),
        complete: false,
        problem: None,
    };
    for record in records {
        let record = match record {
            Ok(record) => record,
            Err(e) => {
                log.problem = Some(e.to_string());
                break;
            }
        };
        match record {
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
                add_message(&mut log.topics, channel, &data)?;
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
        log.topics
            .entry(channel.topic.clone())
            .or_insert_with(|| Table::new(channel.topic, channel.fields.unwrap_or_default()));
    }
    Ok(log)
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

fn add_message(
    topics: &mut BTreeMap<String, Table>,
    channel: &mut Channel,
    data: &[u8],
) -> Result<()> {
    let index = topics.get(&channel.topic).map_or(0, Table::len);
    let context = || format!("{} message {index}", channel.topic);
    let object: Entries = serde_json::from_slice(data).map_err(|e| SimError::BadMessage {
        context: context(),
        reason: format!("not a JSON object: {e}"),
    })?;
    let t = match object.get("t") {
        Some(value) => number(value, context, "t")?,
        None => {
            return Err(SimError::MissingField {
                context: context(),
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
