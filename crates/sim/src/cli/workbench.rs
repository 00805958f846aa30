//! `stabilis discover | compare | fit`: the model workbench on measured or embedded data.
//!
//! Without `--data` the embedded flying-platform identification dataset is generated
//! (deterministically, with hidden effects) and used.
use std::path::PathBuf;

use super::Output;
use crate::error::{Result, SimError};
use crate::progress::Progress;
use crate::systems::cubli::{write_cubli_report, CubliBench, CubliDiscovery};
use crate::systems::flying_platform::embedded_dataset;
use crate::systems::{self, Source};
use workbench::report::{json, table, write_report};
use workbench::{load, Criterion, DataOptions, Discovery, EstimatorChoice, Workbench};

/// Non-parametric estimator.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum EstimatorArg {
    /// Instrumental variable when the excitation topic is logged, least squares otherwise.
    Auto,
    /// Least squares Y U^+ (biased in closed loop).
    Ls,
    /// Instrumental variable (Y R^H)(U R^H)^-1.
    Iv,
}

/// Options shared by the workbench verbs.
#[derive(Debug, Clone, PartialEq, clap::Args)]
pub struct Common {
    /// A shipped system: flying_platform or cubli (for any other system, --model).
    #[arg(long, default_value = "flying_platform", conflicts_with = "model")]
    pub system: String,
    /// A model file (TOML) describing your own system; its `name` sets the MCAP topics.
    #[arg(long, value_name = "FILE")]
    pub model: Option<PathBuf>,
    /// MCAP or CSV files, or directories of them (default: the embedded dataset).
    #[arg(long, num_args = 1..)]
    pub data: Vec<PathBuf>,
    /// Non-parametric estimator.
    #[arg(long, value_enum, default_value = "auto")]
    pub estimator: EstimatorArg,
    /// Band in Hz, LOW,HIGH, for an excitation designed for it: a Welch estimate covers it, a
    /// periodic one keeps its excited lines within it (default: the band the data excite).
    #[arg(long, value_name = "LOW,HIGH", value_delimiter = ',', num_args = 1)]
    pub band_hz: Vec<f64>,
    /// Criterion: frf (variance-weighted FRF misfit) or time (prediction error of the
    /// extended Kalman predictor, for a model file with [nonlinear]); default: time for a
    /// nonlinear model file, frf otherwise.
    #[arg(long, value_enum)]
    pub criterion: Option<CriterionArg>,
    /// Write an HTML report with plots into this directory.
    #[arg(long)]
    pub report: Option<PathBuf>,
}

/// `--criterion`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum CriterionArg {
    /// The variance-weighted FRF misfit (nonlinear models linearized).
    Frf,
    /// The one-step prediction error, absolute units (nonlinear models).
    Time,
}

impl From<CriterionArg> for Criterion {
    fn from(arg: CriterionArg) -> Self {
        match arg {
            CriterionArg::Frf => Criterion::Frf,
            CriterionArg::Time => Criterion::Time,
        }
    }
}

/// Options of `stabilis discover`.
#[derive(Debug, Clone, PartialEq, clap::Args)]
pub struct DiscoverArgs {
    /// Data, system and outputs.
    #[command(flatten)]
    pub common: Common,
}

/// Options of `stabilis compare` and `stabilis fit`.
#[derive(Debug, Clone, PartialEq, clap::Args)]
pub struct FitArgs {
    /// Data, system and outputs.
    #[command(flatten)]
    pub common: Common,
    /// Effects to enable, comma-separated (e.g. momentum_drag,fan_gyroscopic).
    #[arg(long = "with", value_delimiter = ',')]
    pub with: Vec<String>,
}

impl Common {
    /// The system named by `--system` or described by `--model`.
    fn source(&self) -> Result<Source> {
        match &self.model {
            Some(path) => systems::from_model_file(path),
            None => systems::shipped(&self.system),
        }
    }

    fn workbench(&self) -> Result<Workbench> {
        let structure = match self.source()? {
            Source::Structure(s) => s,
            Source::Cubli => {
                return Err(SimError::invalid(
                    "system",
                    "cubli",
                    "the Cubli has no FRF model structure",
                ))
            }
        };
        let data = if self.data.is_empty() {
            if self.model.is_some() || self.system != "flying_platform" {
                return Err(SimError::invalid(
                    "data",
                    "(none)",
                    format!(
                        "{} needs logs: --data run1.mcap run2.mcap ... (only the flying platform \
                         has an embedded dataset)",
                        structure.system()
                    ),
                ));
            }
            embedded_dataset()?
        } else {
            load::load(
                structure.system(),
                &structure.inputs(),
                &structure.outputs(),
                &self.data,
            )
            .map_err(|e| {
                if self.model.is_some() || self.system != "flying_platform" {
                    return e;
                }
                SimError::invalid(
                    "data",
                    self.data[0].display(),
                    format!(
                        "{e}; neither --model nor --system was given, so the logs were read as \
                         the shipped flying platform's: for your own system give --model FILE"
                    ),
                )
            })?
        };
        let choice = match self.estimator {
            EstimatorArg::Auto => EstimatorChoice::Auto,
            EstimatorArg::Ls => EstimatorChoice::LeastSquares,
            EstimatorArg::Iv => EstimatorChoice::InstrumentalVariable,
        };
        let band_hz = match self.band_hz.as_slice() {
            [] => None,
            [lo, hi] => Some((*lo, *hi)),
            other => {
                return Err(SimError::invalid(
                    "--band-hz",
                    format!("{other:?}"),
                    "give two frequencies, LOW,HIGH",
                ))
            }
        };
        let criterion = self.criterion.map(Criterion::from);
        Workbench::with_options(structure, data, choice, DataOptions { band_hz, criterion })
    }

    /// The outputs of a record: the summary (steps, the final model's parameters, verdict),
    /// the JSON and the report.
    fn finish(&self, wb: &Workbench, d: &Discovery) -> Result<Output> {
        let mut human = table(wb, d);
        if let Some(dir) = &self.report {
            write_report(dir, wb, d)?;
            human.push_str(&format!("wrote {}\n", dir.join("index.html").display()));
        }
        Ok(Output {
            human,
            json: json(wb, d),
        })
    }
}

impl Common {
    /// The Cubli workbench on `--data` (required: there is no embedded Cubli dataset).
    fn cubli(&self) -> Result<CubliBench> {
        if self.estimator != EstimatorArg::Auto {
            return Err(SimError::invalid(
                "estimator",
                format!("{:?}", self.estimator).to_lowercase(),
                "the Cubli workbench fits in the time domain and has no FRF estimator",
            ));
        }
        if self.data.is_empty() {
            return Err(SimError::invalid(
                "data",
                "(none)",
                "--system cubli needs logs: --data run1.mcap run2.mcap ...",
            ));
        }
        CubliBench::load(&self.data)
    }

    fn finish_cubli(&self, d: &CubliDiscovery) -> Result<Output> {
        let mut human = d.table();
        if let Some(dir) = &self.report {
            write_cubli_report(dir, d)?;
            human.push_str(&format!("wrote {}\n", dir.join("index.html").display()));
        }
        Ok(Output {
            human,
            json: d.json(),
        })
    }
}

impl DiscoverArgs {
    /// Finds the missing effects step by step.
    pub fn run(&self) -> Result<Output> {
        if matches!(self.common.source()?, Source::Cubli) {
            let d = self.common.cubli()?.discover()?;
            return self.common.finish_cubli(&d);
        }
        let wb = self.common.workbench()?;
        let candidates = wb.model().candidates().len() as u64;
        // One unit per candidate fit of the at most `candidates` steps.
        let mut progress = Progress::new(candidates * (candidates + 1) / 2 + 1, "discovering");
        let mut done = 0;
        let d = wb.discover_with(&mut |_: &str| {
            done += 1;
            progress.set(done);
        })?;
        progress.finish();
        self.common.finish(&wb, &d)
    }
}

impl FitArgs {
    /// `stabilis fit`: as `compare`, but an effect to fit is required.
    pub fn run_fit(&self) -> Result<Output> {
        if self.effects()?.is_empty() {
            return Err(SimError::invalid(
                "--with",
                "(none)",
                "fit needs --with EFFECT[,EFFECT]; to fit the model as it is, use compare",
            ));
        }
        self.run()
    }

    /// The effects of `--with`, trimmed, empty entries (a trailing comma) left out; an effect
    /// named twice is refused, since it may be a typo for another.
    fn effects(&self) -> Result<Vec<&str>> {
        let mut names: Vec<&str> = Vec::new();
        for e in self.with.iter().map(|e| e.trim()).filter(|e| !e.is_empty()) {
            if names.contains(&e) {
                return Err(SimError::invalid(
                    "--with",
                    self.with.join(","),
                    format!("names {e} twice; each effect is enabled once"),
                ));
            }
            names.push(e);
        }
        Ok(names)
    }

    /// Fits the model with the given effects and reports it (a one-step discovery record).
    pub fn run(&self) -> Result<Output> {
        let effects = self.effects()?;
        if matches!(self.common.source()?, Source::Cubli) {
            let mut bench = self.common.cubli()?;
            for e in &effects {
                bench.add(e)?;
            }
            return self.common.finish_cubli(&bench.fit()?);
        }
        let mut wb = self.common.workbench()?;
        for e in &effects {
            wb.add(e)?;
        }
        let d = wb.compared()?;
        self.common.finish(&wb, &d)
    }
}
