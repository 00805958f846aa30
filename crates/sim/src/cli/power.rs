//! `stabilis power`: Monte-Carlo detection power and false discoveries of the workbench for a
//! planned experiment ([`workbench::power`]).
//!
//! Campaigns run on threads of this process by default. With `--scheduler ADDRESS` they run on
//! a Dask cluster through the Python package: the study is prepared here, sent as JSON to
//! `python3 -m stabilis.dask_runner --scheduler ADDRESS` (the interpreter from the environment
//! variable `STABILIS_PYTHON`, default `python3`; it must import `stabilis` and
//! `dask.distributed`), whose tasks each run a batch of campaigns; the outcomes come back on
//! its standard output and are aggregated here, as in-process.
use std::io::{IsTerminal, Write};
use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::sync::Mutex;
use std::time::Instant;

use super::workbench::{CriterionArg, EstimatorArg};
use super::Output;
use crate::error::{Result, SimError};
use crate::progress::Progress;
use workbench::load;
use workbench::model::ModelStructure;
use workbench::model_file::ModelFile;
use workbench::power::{self, Outcome, Study, StudyOptions, StudySpec};
use workbench::Cancel;

/// Environment variable naming the Python interpreter of `--scheduler`.
pub const PYTHON_VAR: &str = "STABILIS_PYTHON";

/// Options of `stabilis power`.
#[derive(Debug, Clone, PartialEq, clap::Args)]
pub struct Args {
    /// The model file (TOML) with the experimenter's `[controller]`.
    #[arg(long, value_name = "FILE")]
    pub model: PathBuf,
    /// The logs whose excitation, length and noise the campaigns replay (MCAP or CSV files,
    /// or directories of them).
    #[arg(long, num_args = 1.., required = true)]
    pub data: Vec<PathBuf>,
    /// The effect whose power is studied (declared in the file, or actuator_lag, input_delay).
    #[arg(long)]
    pub effect: String,
    /// Values of the effect's parameter, increasing, comma-separated (include 0 for the
    /// false-discovery rate).
    #[arg(long, value_delimiter = ',', num_args = 1.., required = true, allow_negative_numbers = true)]
    pub values: Vec<f64>,
    /// Simulated campaigns per value.
    #[arg(long, default_value_t = 100)]
    pub campaigns: usize,
    /// Seed of the campaigns' random numbers (same seed, same results, however run).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Run the campaigns on this Dask scheduler (tcp://host:8786) through the Python package.
    #[arg(long, value_name = "ADDRESS")]
    pub scheduler: Option<String>,
    /// Threads of an in-process run (default: the machine's cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Non-parametric estimator of each campaign's discovery.
    #[arg(long, value_enum, default_value = "auto")]
    pub estimator: EstimatorArg,
    /// Criterion of the nominal fit and of each campaign's discovery: frf or time; default:
    /// time for a nonlinear model file, frf otherwise (as `discover`).
    #[arg(long, value_enum)]
    pub criterion: Option<CriterionArg>,
    /// Write an HTML report (power against the value with its bands) into this directory.
    #[arg(long)]
    pub report: Option<PathBuf>,
}

impl Args {
    /// The files the verb reads.
    pub fn inputs(&self) -> Vec<PathBuf> {
        self.data
            .iter()
            .chain(std::iter::once(&self.model))
            .cloned()
            .collect()
    }

    /// Runs the study.
    pub fn run(&self) -> Result<Output> {
        let text =
            std::fs::read_to_string(&self.model).map_err(|e| SimError::io(&self.model, e))?;
        let file = ModelFile::parse(&text, &self.model)?;
        let data = load::load(file.system(), &file.inputs(), &file.outputs(), &self.data)?;
        let estimator = match self.estimator {
            EstimatorArg::Auto => "auto",
            EstimatorArg::Ls => "ls",
            EstimatorArg::Iv => "iv",
        };
        eprintln!("power: fitting the nominal model and estimating the noise");
        let spec = power::prepare(
            &text,
            &self.model,
            data,
            &StudyOptions {
                effect: self.effect.clone(),
                values: self.values.clone(),
                campaigns: self.campaigns,
                seed: self.seed,
                estimator: estimator.into(),
                band_hz: None,
                criterion: self.criterion.map(Into::into),
                // Ctrl-C ends the process; its outputs are written by rename.
                cancel: Cancel::default(),
            },
        )?;
        let outcomes = match &self.scheduler {
            Some(address) => on_dask(&spec, address)?,
            None => in_process(&spec, self.threads)?,
        };
        let result = power::aggregate(&spec, &outcomes)?;
        let mut human = result.table();
        if let Some(dir) = &self.report {
            result.write_report(dir, &self.inputs())?;
            human.push_str(&format!("wrote {}\n", dir.join("index.html").display()));
        }
        let json = serde_json::to_value(&result)
            .map_err(|e| SimError::invalid("json", "serialisation", e.to_string()))?;
        Ok(Output { human, json })
    }
}

/// Progress on stderr: a bar on a terminal, otherwise a line every twentieth of the study.
struct Reporter {
    total: usize,
    started: Instant,
    bar: Option<Progress>,
}

impl Reporter {
    fn new(total: usize) -> Self {
        Self {
            total,
            started: Instant::now(),
            bar: std::io::stderr()
                .is_terminal()
                .then(|| Progress::new(total as u64, "power campaigns")),
        }
    }

    fn done(&mut self, done: usize) {
        let rate = done as f64 / self.started.elapsed().as_secs_f64().max(1e-9);
        match &mut self.bar {
            Some(bar) => {
                bar.set(done as u64);
                bar.set_message(&format!(
                    "power: {done}/{} campaigns, {rate:.2}/s",
                    self.total
                ));
            }
            None => {
                let every = (self.total / 20).max(1);
                if done % every == 0 || done == self.total {
                    eprintln!("power: {done}/{} campaigns, {rate:.2}/s", self.total);
                }
            }
        }
    }

    fn finish(&self) {
        if let Some(bar) = &self.bar {
            bar.finish();
        }
    }
}

fn in_process(spec: &StudySpec, threads: Option<usize>) -> Result<Vec<Outcome>> {
    let study = Study::new(spec.clone())?;
    let jobs = study.jobs();
    let threads = threads
        .or_else(|| std::thread::available_parallelism().ok().map(|n| n.get()))
        .unwrap_or(1);
    let reporter = Mutex::new(Reporter::new(jobs.len()));
    let outcomes = power::run(
        &study,
        &jobs,
        threads,
        &|done| {
            if let Ok(mut r) = reporter.lock() {
                r.done(done);
            }
        },
        &Cancel::default(),
    )?;
    if let Ok(r) = reporter.lock() {
        r.finish();
    }
    Ok(outcomes)
}

/// Runs the campaigns on the Dask scheduler at `address` through the Python package.
fn on_dask(spec: &StudySpec, address: &str) -> Result<Vec<Outcome>> {
    let python = std::env::var(PYTHON_VAR).unwrap_or_else(|_| "python3".into());
    let needs = format!(
        "--scheduler runs the campaigns through the Python package: `{python}` must import \
         stabilis and dask.distributed (pip install 'dask[distributed]' and the stabilis \
         wheel into that environment, or set {PYTHON_VAR} to an interpreter that has them)"
    );
    let check = Command::new(&python)
        .args(["-c", "import stabilis.dask_runner, dask.distributed"])
        .output()
        .map_err(|e| SimError::invalid("--scheduler", address, format!("{needs}; {e}")))?;
    if !check.status.success() {
        let why = String::from_utf8_lossy(&check.stderr);
        return Err(SimError::invalid(
            "--scheduler",
            address,
            format!(
                "{needs}; it says: {}",
                why.trim().lines().last().unwrap_or("")
            ),
        ));
    }
    let text = serde_json::to_string(spec)
        .map_err(|e| SimError::invalid("json", "serialisation", e.to_string()))?;
    let mut child = Command::new(&python)
        .args(["-m", "stabilis.dask_runner", "--scheduler", address])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .map_err(|e| SimError::invalid("--scheduler", address, format!("{needs}; {e}")))?;
    if let Some(mut stdin) = child.stdin.take() {
        stdin
            .write_all(text.as_bytes())
            .map_err(|e| SimError::invalid("--scheduler", address, e.to_string()))?;
    }
    let out = child
        .wait_with_output()
        .map_err(|e| SimError::invalid("--scheduler", address, e.to_string()))?;
    if !out.status.success() {
        return Err(SimError::invalid(
            "--scheduler",
            address,
            format!(
                "`{python} -m stabilis.dask_runner` failed ({}); its messages are above",
                out.status
            ),
        ));
    }
    serde_json::from_slice(&out.stdout).map_err(|e| {
        SimError::invalid(
            "--scheduler",
            address,
            format!("the Dask run returned no readable outcomes: {e}"),
        )
    })
}
