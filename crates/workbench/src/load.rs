//! Measurements from logs: MCAP files (or directories of them) with the DESIGN.md topics
//! `/<system>/input`, `/<system>/output` and, when logged, `/<system>/excitation`, plus the
//! `experiment` metadata record; or CSV files with a `t` column and the channel names
//! (excitation columns prefixed `r_`).
use std::path::{Path, PathBuf};

use nalgebra::DMatrix;

use super::dataset::{Dataset, Experiment, Periodic};
use super::discover::in_parallel;
use crate::error::{Result, SimError};
use crate::log::{read_csv, read_mcap, Experiment as Meta, Table};

/// Expands directories into their `.mcap` and `.csv` files (sorted), keeps files as given.
pub fn expand(paths: &[PathBuf]) -> Result<Vec<PathBuf>> {
    let mut out = Vec::new();
    for p in paths {
        if p.is_dir() {
            let mut files: Vec<PathBuf> = std::fs::read_dir(p)
                .map_err(|e| SimError::io(p, e))?
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|f| {
                    f.extension().is_some_and(|x| {
                        x.eq_ignore_ascii_case("mcap") || x.eq_ignore_ascii_case("csv")
                    })
                })
                .collect();
            files.sort();
            if files.is_empty() {
                return Err(SimError::invalid(
                    "data",
                    p.display(),
                    "the directory holds no .mcap or .csv file",
                ));
            }
            out.extend(files);
        } else if p.exists() {
            out.push(p.clone());
        } else {
            return Err(SimError::FileNotFound { path: p.clone() });
        }
    }
    if out.is_empty() {
        return Err(SimError::invalid(
            "data",
            "no path",
            "give at least one file or directory",
        ));
    }
    crate::log::refuse_repeats(&out)?;
    Ok(out)
}

/// The system a set of MCAP logs was recorded from: the `<system>` of the first log's single
/// `/<system>/input` topic (for a model that does not name its system).
pub fn system_of(paths: &[PathBuf]) -> Result<String> {
    let files = expand(paths)?;
    let first = &files[0];
    if first
        .extension()
        .is_some_and(|x| x.eq_ignore_ascii_case("csv"))
    {
        return Err(SimError::invalid(
            "system name",
            first.display(),
            "a CSV log does not name its system: give the model a name",
        ));
    }
    let log = read_mcap(first)?;
    let systems: Vec<&str> = log
        .topics
        .keys()
        .filter_map(|t| t.strip_prefix('/')?.strip_suffix("/input"))
        .collect();
    match systems.as_slice() {
        [one] => Ok(one.to_string()),
        _ => Err(SimError::invalid(
            "system name",
            first.display(),
            format!(
                "cannot tell the system from the topics ({}): give the model a name",
                log.topics.keys().cloned().collect::<Vec<_>>().join(", ")
            ),
        )),
    }
}

/// Selects `names` from `table` as columns of a matrix, naming a missing channel.
fn columns(table: &Table, names: &[String], prefix: &str) -> Result<DMatrix<f64>> {
    let cols: Vec<&[f64]> = names
        .iter()
        .map(|n| table.column(&format!("{prefix}{n}")))
        .collect::<Result<_>>()?;
    Ok(DMatrix::from_fn(table.t.len(), names.len(), |i, j| {
        cols[j][i]
    }))
}

/// One experiment and its sample rate from the log `file`.
fn experiment(
    system: &str,
    inputs: &[String],
    outputs: &[String],
    file: &Path,
) -> Result<(Experiment, f64)> {
    let name = file.display().to_string();
    let is_csv = file
        .extension()
        .is_some_and(|x| x.eq_ignore_ascii_case("csv"));
    Ok(if is_csv {
        let table = read_csv(file)?;
        let fs = table.sample_rate(None, file)?;
        let r = if table.fields.iter().any(|f| f.starts_with("r_")) {
            Some(columns(&table, inputs, "r_")?)
        } else {
            None
        };
        let e = Experiment {
            name,
            u: columns(&table, inputs, "")?,
            y: columns(&table, outputs, "")?,
            r,
            periodic: None,
        };
        (e, fs)
    } else {
        let log = read_mcap(file)?;
        if let Some(problem) = &log.problem {
            eprintln!("warning: {name} is incomplete ({problem}); using what was read");
        }
        let input = log.topic(&format!("/{system}/input"))?;
        let output = log.topic(&format!("/{system}/output"))?;
        if input.len() != output.len() {
            return Err(SimError::LengthMismatch {
                what: format!(
                    "messages of /{system}/output in {name} (one output per input sample)"
                ),
                expected: input.len(),
                found: output.len(),
            });
        }
        let r = match log.topics.get(&format!("/{system}/excitation")) {
            Some(t) if t.len() == input.len() => Some(columns(t, inputs, "")?),
            Some(t) => {
                return Err(SimError::LengthMismatch {
                    what: format!("messages of /{system}/excitation in {name}"),
                    expected: input.len(),
                    found: t.len(),
                })
            }
            None => None,
        };
        let meta = log.experiment().map(Meta::from_metadata).transpose()?;
        let fs = input.sample_rate(meta.as_ref().map(|m| m.sample_rate_hz), file)?;
        let periodic = meta.and_then(|m| m.periodic).map(|p| Periodic {
            period: p.period_samples,
            periods: p.periods,
            transient: p.transient_samples,
        });
        let e = Experiment {
            name,
            u: columns(input, inputs, "")?,
            y: columns(output, outputs, "")?,
            r,
            periodic,
        };
        (e, fs)
    })
}

/// The sample rate the experiments share; when they do not, an error that lists each rate with
/// the experiments recorded at it (the largest group last, so a file in other units stands
/// out first).
fn one_rate(experiments: &[Experiment], rates: &[f64]) -> Result<f64> {
    let mut groups: Vec<(f64, Vec<&str>)> = Vec::new();
    for (e, &fs) in experiments.iter().zip(rates) {
        match groups
            .iter_mut()
            .find(|(r, _)| (r - fs).abs() <= 1e-6 * r.abs())
        {
            Some((_, names)) => names.push(&e.name),
            None => groups.push((fs, vec![&e.name])),
        }
    }
    if groups.len() <= 1 {
        return Ok(groups.first().map_or(0.0, |g| g.0));
    }
    groups.sort_by_key(|(_, names)| names.len());
    let listed: Vec<String> = groups
        .iter()
        .map(|(r, names)| format!("{} Hz in {}", hz(*r), names.join(", ")))
        .collect();
    Err(SimError::invalid(
        "sample rate",
        listed.join("; "),
        "all experiments must share one sample rate (is one file's time column in other units?)",
    ))
}

/// A rate for a message: ten significant digits, so that 200.00000000000003 (the mean step
/// of a log's time column) reads 200.
pub fn hz(v: f64) -> String {
    format!("{v:.9e}").parse::<f64>().unwrap_or(v).to_string()
}

/// Loads experiments of `system` with the given channel names from `paths`.
pub fn load(
    system: &str,
    inputs: &[String],
    outputs: &[String],
    paths: &[PathBuf],
) -> Result<Dataset> {
    let files = expand(paths)?;
    // Files are read in parallel: parsing their messages is most of the loading time.
    let jobs: Vec<_> = files
        .iter()
        .map(|file| move || experiment(system, inputs, outputs, file))
        .collect();
    let (experiments, rates): (Vec<Experiment>, Vec<f64>) =
        in_parallel(true, jobs, "reading a log")?
            .into_iter()
            .unzip();
    let rate = one_rate(&experiments, &rates)?;
    let data = Dataset {
        sample_rate_hz: rate,
        inputs: inputs.to_vec(),
        outputs: outputs.to_vec(),
        experiments,
    };
    data.validate()?;
    Ok(data)
}
