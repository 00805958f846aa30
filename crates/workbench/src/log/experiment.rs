//! The `experiment` metadata record that describes a run: sample rate and, for periodic
//! excitation, the period layout that frequency-domain identification needs.
use std::collections::BTreeMap;

use crate::error::{Result, SimError};

/// Name of the metadata record.
pub const EXPERIMENT: &str = "experiment";

/// Layout of a periodic excitation.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Periodic {
    /// Samples per period.
    pub period_samples: usize,
    /// Number of periods logged after the transient.
    pub periods: usize,
    /// Samples before the first logged period.
    pub transient_samples: usize,
    /// Names of the excited inputs.
    pub excited: Vec<String>,
}

/// What a log's `experiment` record says.
///
/// ```
/// use workbench::log::Experiment;
/// let mut experiment = Experiment::new(100.0);
/// experiment.extra.insert("system".into(), "wheel-pendulum".into());
/// let record = experiment.to_metadata();
/// assert_eq!(record["sample_rate_hz"], "100");
/// assert_eq!(Experiment::from_metadata(&record).unwrap(), experiment);
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct Experiment {
    /// Controller and logging rate.
    pub sample_rate_hz: f64,
    /// Periodic excitation, if any.
    pub periodic: Option<Periodic>,
    /// Any further keys (system, seed, duration...), kept as strings.
    pub extra: BTreeMap<String, String>,
}

const PERIODIC_KEYS: [&str; 4] = ["period_samples", "periods", "transient_samples", "excited"];

impl Experiment {
    /// An experiment record with only the sample rate.
    pub fn new(sample_rate_hz: f64) -> Self {
        Self {
            sample_rate_hz,
            periodic: None,
            extra: BTreeMap::new(),
        }
    }

    /// The record as MCAP metadata (string values).
    pub fn to_metadata(&self) -> BTreeMap<String, String> {
        let mut map = self.extra.clone();
        map.insert("sample_rate_hz".into(), self.sample_rate_hz.to_string());
        if let Some(p) = &self.periodic {
            map.insert("period_samples".into(), p.period_samples.to_string());
            map.insert("periods".into(), p.periods.to_string());
            map.insert("transient_samples".into(), p.transient_samples.to_string());
            map.insert("excited".into(), p.excited.join(","));
        }
        map
    }

    /// Parses a metadata record; the periodic keys must be all present or all absent.
    pub fn from_metadata(map: &BTreeMap<String, String>) -> Result<Self> {
        let sample_rate_hz = parse::<f64>(map, "sample_rate_hz")?;
        if !(sample_rate_hz.is_finite() && sample_rate_hz > 0.0) {
            return Err(SimError::invalid(
                "experiment.sample_rate_hz",
                sample_rate_hz,
                "must be a positive number",
            ));
        }
        let present = PERIODIC_KEYS
            .iter()
            .filter(|k| map.contains_key(**k))
            .count();
        let periodic = match present {
            0 => None,
            4 => Some(Periodic {
                period_samples: parse(map, "period_samples")?,
                periods: parse(map, "periods")?,
                transient_samples: parse(map, "transient_samples")?,
                excited: map["excited"]
                    .split(',')
                    .map(str::trim)
                    .filter(|s| !s.is_empty())
                    .map(String::from)
                    .collect(),
            }),
            _ => {
                let missing = PERIODIC_KEYS
                    .iter()
                    .find(|k| !map.contains_key(**k))
                    .map_or("", |k| k);
                return Err(SimError::MissingField {
                    context: "experiment metadata (periodic keys come together)".into(),
                    field: missing.into(),
                    available: map.keys().cloned().collect(),
                });
            }
        };
        let extra = map
            .iter()
            .filter(|(k, _)| *k != "sample_rate_hz" && !PERIODIC_KEYS.contains(&k.as_str()))
            .map(|(k, v)| (k.clone(), v.clone()))
            .collect();
        Ok(Self {
            sample_rate_hz,
            periodic,
            extra,
        })
    }
}

fn parse<T: std::str::FromStr>(map: &BTreeMap<String, String>, key: &str) -> Result<T> {
    let text = map.get(key).ok_or_else(|| SimError::MissingField {
        context: "experiment metadata".into(),
        field: key.into(),
        available: map.keys().cloned().collect(),
    })?;
    text.trim()
        .parse()
        .map_err(|_| SimError::invalid(format!("experiment.{key}"), text, "not a number"))
}
