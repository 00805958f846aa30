//! Runnable scenarios, one file per system (`stabilis sim <system>`). Each scenario has clap
//! `Args` that flatten [`Common`] and implement [`Scenario`]; it is registered with one variant
//! of [`crate::cli::SimSystem`]. A scenario writes its log through a [`Recorder`] while it runs,
//! so the MCAP file is usable even if the run is cut off.
use std::collections::BTreeMap;
use std::path::PathBuf;

use crate::error::Result;
use crate::log::{Experiment, LogWriter, Table, TopicId, EXPERIMENT};
use crate::progress::Progress;

pub mod cubli;
pub mod flying_platform;
pub mod platoon;
pub mod quad_integrator;
pub mod wheel_pendulum;

/// Options every scenario takes.
#[derive(Debug, Clone, PartialEq, clap::Args)]
pub struct Common {
    /// Simulated time, s.
    #[arg(long, default_value_t = 10.0, allow_negative_numbers = true)]
    pub duration: f64,
    /// MCAP file to write.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Seed of the measurement noise.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
}

/// The number of samples of a run of `duration` seconds at `rate_hz`: a named error unless the
/// duration is positive and the run fits in memory (see [`crate::limits`]), checked before
/// anything is allocated.
pub fn samples(duration: f64, rate_hz: f64) -> Result<usize> {
    if !(duration.is_finite() && duration > 0.0) {
        return Err(crate::error::SimError::invalid(
            "duration",
            duration,
            "must be a positive number of seconds",
        ));
    }
    crate::limits::check(
        "duration",
        duration,
        duration * rate_hz,
        crate::limits::BYTES_PER_SAMPLE,
    )
}

/// A simulated system that can be run from the command line or from Python.
pub trait Scenario {
    /// The options shared by all scenarios.
    fn common(&self) -> &Common;
    /// Runs the scenario, recording into `recorder` as it goes.
    fn run(&self, recorder: &mut Recorder, progress: &mut Progress) -> Result<()>;
}

/// What a scenario produced.
#[derive(Debug, Clone, PartialEq)]
pub struct Recording {
    /// One table per topic.
    pub topics: BTreeMap<String, Table>,
    /// The `experiment` metadata record.
    pub experiment: BTreeMap<String, String>,
    /// Headline numbers of the run (final tilt, peak torque...), for the terminal and `--json`.
    pub summary: serde_json::Map<String, serde_json::Value>,
    /// The MCAP file written, if any.
    pub out: Option<PathBuf>,
}

/// Collects topics in memory and, if asked, streams them to an MCAP file.
#[derive(Debug)]
pub struct Recorder {
    writer: Option<LogWriter>,
    topics: Vec<(Table, Option<TopicId>)>,
    experiment: BTreeMap<String, String>,
    summary: serde_json::Map<String, serde_json::Value>,
}

/// A topic added to a [`Recorder`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RecorderTopic(usize);

impl Recorder {
    /// A recorder that also writes `out` when given.
    pub fn new(out: Option<&std::path::Path>) -> Result<Self> {
        Ok(Self {
            writer: out.map(LogWriter::create).transpose()?,
            topics: Vec::new(),
            experiment: BTreeMap::new(),
            summary: serde_json::Map::new(),
        })
    }

    /// Records the `experiment` metadata.
    pub fn experiment(&mut self, experiment: &Experiment) -> Result<()> {
        self.experiment = experiment.to_metadata();
        if let Some(writer) = &mut self.writer {
            writer.write_metadata(EXPERIMENT, self.experiment.clone())?;
        }
        Ok(())
    }

    /// Adds a topic with the given fields.
    pub fn add_topic<S: AsRef<str>>(&mut self, topic: &str, fields: &[S]) -> Result<RecorderTopic> {
        let id = match &mut self.writer {
            Some(writer) => Some(writer.add_topic(topic, fields)?),
            None => None,
        };
        let names = fields.iter().map(|f| f.as_ref().to_string());
        self.topics.push((Table::new(topic, names), id));
        Ok(RecorderTopic(self.topics.len() - 1))
    }

    /// Records one sample of a topic.
    pub fn record(&mut self, topic: RecorderTopic, t: f64, values: &[f64]) -> Result<()> {
        let (table, id) = &mut self.topics[topic.0];
        table.push(t, values)?;
        if let (Some(writer), Some(id)) = (&mut self.writer, id) {
            writer.write(*id, t, values)?;
        }
        Ok(())
    }

    /// Adds a headline number to the summary.
    pub fn summarize(&mut self, key: &str, value: impl Into<serde_json::Value>) {
        self.summary.insert(key.to_string(), value.into());
    }

    /// Closes the log and returns what was recorded.
    pub fn finish(self) -> Result<Recording> {
        let out = match self.writer {
            Some(writer) => {
                let path = writer.path().to_path_buf();
                writer.finish()?;
                Some(path)
            }
            None => None,
        };
        Ok(Recording {
            topics: self
                .topics
                .into_iter()
                .map(|(table, _)| (table.name.clone(), table))
                .collect(),
            experiment: self.experiment,
            summary: self.summary,
            out,
        })
    }
}

/// Runs a scenario with a fresh recorder (writing `common().out` if set).
pub fn run(scenario: &dyn Scenario, progress: &mut Progress) -> Result<Recording> {
    let mut recorder = Recorder::new(scenario.common().out.as_deref())?;
    scenario.run(&mut recorder, progress)?;
    progress.finish();
    recorder.finish()
}
