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
        let fs = sample_rate(&table, None, file)?;
        // The channels first: a log without an input names the input, not its excitation.
        let (u, y) = (columns(&table, inputs, "")?, columns(&table, outputs, "")?);
        let r = if table.fields.iter().any(|f| f.starts_with("r_")) {
            let missing: Vec<String> = inputs
                .iter()
                .map(|i| format!("r_{i}"))
                .filter(|c| !table.fields.contains(c))
                .collect();
            if !missing.is_empty() {
                return Err(SimError::invalid(
                    "excitation",
                    &name,
                    format!(
                        "has no column {} beside {}: the instrumental variable needs the excitation of every input; log it for each (zeros for an input not excited) or drop every r_ column",
                        missing.join(", "),
                        table
                            .fields
                            .iter()
                            .filter(|f| f.starts_with("r_"))
                            .cloned()
                            .collect::<Vec<_>>()
                            .join(", ")
                    ),
                ));
            }
            Some(columns(&table, inputs, "r_")?)
        } else {
            None
        };
        let e = Experiment {
            name,
            u,
            y,
            r,
            periodic: None,
        };
        (e, fs)
    } else {
        let log = read_mcap(file)?;
        if let Some(problem) = &log.problem {
            eprintln!("warning: {name} is incomplete ({problem}); using what was read");
        }
        if !log.stamped_by_log_time.is_empty() {
            eprintln!(
                "warning: {name}: the messages of {} carry no t; their log_time (the recorder's \
                 stamp) is taken as the sample time",
                log.stamped_by_log_time.join(", ")
            );
        }
        if !log.reordered.is_empty() {
            eprintln!(
                "warning: {name}: the file holds the messages of {} out of time order (chunks \
                 written out of order); they are read in time order",
                log.reordered.join(", ")
            );
        }
        let input = log.topic(&format!("/{system}/input"))?;
        let output = log.topic(&format!("/{system}/output"))?;
        let meta = log.experiment().map(Meta::from_metadata).transpose()?;
        let fs = sample_rate(input, meta.as_ref().map(|m| m.sample_rate_hz), file)?;
        let paired = |topic: &str, other: &Table| -> Result<()> {
            if other.len() == input.len() {
                return Ok(());
            }
            Err(SimError::LengthMismatch {
                what: format!(
                    "messages of /{system}/{topic} in {name} (one per input sample; {})",
                    unpaired(&input.t, &other.t, fs)
                ),
                expected: input.len(),
                found: other.len(),
            })
        };
        paired("output", output)?;
        let excitation = log.topics.get(&format!("/{system}/excitation"));
        let r = match excitation {
            Some(t) => {
                paired("excitation", t)?;
                Some(columns(t, inputs, "")?)
            }
            None => None,
        };
        if let Some(p) = meta.as_ref().and_then(|m| m.periodic.as_ref()) {
            if let Some(x) = p.excited.iter().find(|x| !inputs.contains(x)) {
                return Err(SimError::invalid(
                    format!("experiment metadata `excited` of {name}"),
                    x,
                    format!("names no input of the model (inputs {})", inputs.join(", ")),
                ));
            }
        }
        for (topic, t) in [("output", Some(output)), ("excitation", excitation)]
            .into_iter()
            .filter_map(|(topic, t)| Some((topic, t?)))
        {
            aligned(&name, &format!("/{system}/{topic}"), &input.t, &t.t, fs)?;
        }
        let excited = meta
            .as_ref()
            .and_then(|m| m.periodic.as_ref())
            .map(|p| p.excited.clone());
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
        for note in metadata_notes(&e, inputs, excited.as_deref().unwrap_or_default()) {
            eprintln!("warning: {}: {note}", e.name);
        }
        (e, fs)
    })
}

/// Where an experiment's periodic metadata and its record disagree in ways the workbench can
/// go on with: samples after the declared periods (a transient declared too short puts the
/// start of the record into the first period, where the plant has not settled), and inputs
/// the `excited` list names or leaves out against what the logged excitation moves (the
/// excitation is what the estimate uses).
fn metadata_notes(e: &Experiment, inputs: &[String], excited: &[String]) -> Vec<String> {
    let mut notes = Vec::new();
    if let Some(p) = e.periodic {
        let (used, n) = (p.transient + p.periods * p.period, e.u.nrows());
        if n > used {
            notes.push(format!(
                "its metadata lays out {used} of its {n} samples (transient_samples {} + {} \
                 periods of {}): the last {} are not used; if the plant settles later than \
                 sample {}, transient_samples should say so",
                p.transient,
                p.periods,
                p.period,
                n - used,
                p.transient
            ));
        }
    }
    if let (Some(r), false) = (&e.r, excited.is_empty()) {
        let moved: Vec<&str> = inputs
            .iter()
            .enumerate()
            .filter(|&(i, _)| r.column(i).iter().any(|v| *v != 0.0))
            .map(|(_, x)| x.as_str())
            .collect();
        let listed: Vec<&str> = inputs
            .iter()
            .filter(|x| excited.contains(x))
            .map(String::as_str)
            .collect();
        if moved != listed {
            notes.push(format!(
                "its metadata lists `excited` = {} where the logged excitation moves {}: the \
                 excitation is used",
                listed.join(","),
                if moved.is_empty() {
                    "no input".to_string()
                } else {
                    moved.join(",")
                }
            ));
        }
    }
    notes
}

/// The sample rate of `table` (see [`Table::sample_rate`]), with a warning on standard error
/// when its stamps scatter around a regular grid: the samples are then taken as evenly spaced.
fn sample_rate(table: &Table, declared: Option<f64>, file: &Path) -> Result<f64> {
    let (fs, jitter) = table.sample_rate(declared, file)?;
    if let Some(j) = jitter {
        eprintln!("warning: {}: {j}", file.display());
    }
    Ok(fs)
}

/// Where a topic's messages stop pairing with the input samples `input` (stamps `other`, rate
/// `fs`): the first message more than half a sample from its input sample's time, or the
/// samples at the end that one of them lacks.
fn unpaired(input: &[f64], other: &[f64], fs: f64) -> String {
    match first_apart(input, other, fs) {
        Some(k) => format!(
            "the first unpaired is input sample {k} at t = {} s, where the message is at t = {} \
             s: a message is missing or extra there",
            input[k], other[k]
        ),
        None if other.len() < input.len() => format!(
            "the input samples from t = {} s on have none: the topic ends early",
            input[other.len()]
        ),
        None => format!(
            "the messages from t = {} s on have no input sample: the input ends early",
            other[input.len()]
        ),
    }
}

/// Relative difference below which two logs' sample rates are one: loggers' clocks differ by
/// tens of parts per million, and a time column's mean step carries its jitter, while a rate
/// read 0.1 % off moves an FRF line by a thousandth of its frequency.
pub const SAME_RATE: f64 = 1e-3;

/// Refuses a topic whose messages are not stamped with their input samples' times (within
/// half a sample period): messages are paired by their order, so an output log that starts
/// late would pair every input with a later output.
fn aligned(file: &str, topic: &str, input: &[f64], other: &[f64], fs: f64) -> Result<()> {
    if let Some(k) = first_apart(input, other, fs) {
        let (a, b, half) = (input[k], other[k], 0.5 / fs);
        return Err(SimError::invalid(
            format!("{topic} in {file}"),
            format!("message {k} at t = {b} s"),
            format!(
                "its input sample is at t = {a} s: one message per input sample at the same time (within half a sample period, {half:e} s) is needed; the topics were logged with an offset or at other instants"
            ),
        ));
    }
    Ok(())
}

/// The first message of stamps `other` more than half a sample period (rate `fs`) from the
/// input sample it is paired with by order, over the samples both have.
fn first_apart(input: &[f64], other: &[f64], fs: f64) -> Option<usize> {
    let half = 0.5 / fs;
    input
        .iter()
        .zip(other)
        .position(|(a, b)| (a - b).abs() > half)
}

/// The sample rate the experiments share (within [`SAME_RATE`], their mean); when they do not,
/// an error that lists each rate with the experiments recorded at it (the largest group last,
/// so a file in other units stands out first).
fn one_rate(experiments: &[Experiment], rates: &[f64]) -> Result<f64> {
    let mut groups: Vec<(f64, Vec<&str>)> = Vec::new();
    for (e, &fs) in experiments.iter().zip(rates) {
        match groups
            .iter_mut()
            .find(|(r, _)| (*r - fs).abs() <= SAME_RATE * r.abs())
        {
            Some((_, names)) => names.push(&e.name),
            None => groups.push((fs, vec![&e.name])),
        }
    }
    if groups.len() <= 1 {
        return Ok(if rates.is_empty() {
            0.0
        } else {
            rates.iter().sum::<f64>() / rates.len() as f64
        });
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
    let rounded = format!("{v:.9e}").parse::<f64>().unwrap_or(v);
    if positional(rounded) {
        rounded.to_string()
    } else {
        format!("{rounded:e}")
    }
}

/// Whether a number reads best in positional notation: all but the extremes (Rust prints
/// every f64 positionally, and 1e-300 would take 300 digits).
fn positional(v: f64) -> bool {
    v == 0.0 || (1e-4..1e9).contains(&v.abs())
}

/// `v` with `digits` decimals, in exponent notation at the extremes (see [`hz`]).
pub fn readable(v: f64, digits: usize) -> String {
    if positional(v) {
        format!("{v:.digits$}")
    } else {
        format!("{v:.digits$e}")
    }
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

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::DMatrix;

    fn experiment(name: &str) -> Experiment {
        Experiment {
            name: name.into(),
            u: DMatrix::zeros(1, 1),
            y: DMatrix::zeros(1, 1),
            r: None,
            periodic: None,
        }
    }

    /// Samples after the declared periods and an `excited` list the excitation contradicts are
    /// named; a layout that covers the record and a list that agrees are not.
    #[test]
    fn metadata_the_record_contradicts_is_named() {
        let inputs = vec!["T1".to_string(), "T2".to_string()];
        let record = |n: usize| Experiment {
            name: "x.mcap".into(),
            u: DMatrix::zeros(n, 2),
            y: DMatrix::zeros(n, 1),
            r: Some(DMatrix::from_fn(n, 2, |k, j| {
                if j == 0 {
                    (k % 10) as f64
                } else {
                    0.0
                }
            })),
            periodic: Some(Periodic {
                period: 10,
                periods: 4,
                transient: 0,
            }),
        };
        assert!(metadata_notes(&record(40), &inputs, &["T1".into()]).is_empty());
        assert!(metadata_notes(&record(40), &inputs, &[]).is_empty());
        let notes = metadata_notes(&record(45), &inputs, &["T2".into()]);
        assert_eq!(notes.len(), 2, "{notes:?}");
        assert!(
            notes[0].starts_with("its metadata lays out 40 of its 45 samples (transient_samples 0 + 4 periods of 10): the last 5 are not used"),
            "{notes:?}"
        );
        assert_eq!(
            notes[1],
            "its metadata lists `excited` = T2 where the logged excitation moves T1: the excitation is used"
        );
    }

    /// Rates read as a person writes them: ten significant digits, positional but for
    /// extremes (1e-300 Hz printed 300 digits).
    #[test]
    fn rates_print_short() {
        assert_eq!(hz(200.00000000000003), "200");
        assert_eq!(hz(0.5), "0.5");
        assert_eq!(hz(1e-300), "1e-300");
        assert_eq!(hz(2.5e12), "2.5e12");
        assert_eq!(hz(0.0), "0");
    }

    /// A directory of the test's own, removed with its files when dropped.
    fn scratch(prefix: &str) -> tempfile::TempDir {
        tempfile::Builder::new().prefix(prefix).tempdir().unwrap()
    }

    /// A log `name` in `dir` of the pendulum's topics, 40 samples at 100 Hz, the output
    /// stamped `offset` s after its input and missing at the samples `dropped`, with `excited`
    /// in the metadata when given.
    fn pendulum_log(
        dir: &Path,
        name: &str,
        offset: f64,
        excited: Option<&str>,
        dropped: &[usize],
    ) -> PathBuf {
        let path = dir.join(name);
        let mut log = crate::log::LogWriter::create(&path).unwrap();
        let mut meta = Meta::new(100.0);
        meta.periodic = excited.map(|x| crate::log::Periodic {
            period_samples: 10,
            periods: 4,
            transient_samples: 0,
            excited: vec![x.to_string()],
        });
        log.write_metadata(crate::log::EXPERIMENT, meta.to_metadata())
            .unwrap();
        let input = log.add_topic("/pend/input", &["T"]).unwrap();
        let output = log.add_topic("/pend/output", &["theta"]).unwrap();
        for k in 0..40 {
            let t = k as f64 / 100.0;
            let r = ((k % 10) as f64).sin();
            log.write(input, t, &[r]).unwrap();
            if !dropped.contains(&k) {
                log.write(output, t + offset, &[0.1 * r]).unwrap();
            }
        }
        log.finish().unwrap();
        path
    }

    /// Topics are paired message by message, so an output stamped later than its input (by
    /// more than half a sample) is refused, naming the topic; an `excited` input the model
    /// does not have is named.
    #[test]
    fn misaligned_topics_and_unknown_excited_inputs_are_named() {
        let (inputs, outputs) = (vec!["T".to_string()], vec!["theta".to_string()]);
        let dir = scratch("workbench-load-tests-");
        let ok = pendulum_log(dir.path(), "ok.mcap", 0.004, Some("T"), &[]);
        assert!(load("pend", &inputs, &outputs, &[ok]).is_ok());
        let late = pendulum_log(dir.path(), "late.mcap", 0.25, None, &[]);
        let err = load("pend", &inputs, &outputs, &[late])
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("/pend/output in") && err.contains("message 0 at t = 0.25 s"),
            "{err}"
        );
        let unknown = pendulum_log(dir.path(), "x.mcap", 0.0, Some("X"), &[]);
        let err = load("pend", &inputs, &outputs, &[unknown])
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("`excited`")
                && err.contains("= X: names no input of the model (inputs T)"),
            "{err}"
        );
    }

    /// An output message dropped by the logger is named at its input sample, and a topic that
    /// ends early at the first sample it lacks (it used to give the two counts only).
    #[test]
    fn a_dropped_message_is_named_where_it_is() {
        let (inputs, outputs) = (vec!["T".to_string()], vec!["theta".to_string()]);
        let dir = scratch("workbench-load-dropped-");
        let cases = [
            (
                &[17][..],
                "input sample 17 at t = 0.17 s, where the message is at t = 0.18 s",
            ),
            (
                &[37, 38, 39][..],
                "input samples from t = 0.37 s on have none",
            ),
        ];
        for (k, (dropped, named)) in cases.into_iter().enumerate() {
            let log = pendulum_log(dir.path(), &format!("d{k}.mcap"), 0.0, None, dropped);
            let err = load("pend", &inputs, &outputs, &[log])
                .unwrap_err()
                .to_string();
            assert!(
                err.contains("/pend/output") && err.contains(named) && err.contains("found"),
                "{err}"
            );
        }
    }

    /// A CSV without an input and its excitation column names the input, the channel the
    /// model needs, not the excitation; one with the excitation of only some inputs names the
    /// missing columns and the remedy.
    #[test]
    fn a_missing_input_is_named_before_its_excitation() {
        let dir = scratch("workbench-load-csv-");
        let path = dir.path().join("one_input.csv");
        let rows: String = (0..20)
            .map(|k| format!("{},{},{},{}\n", k as f64 * 0.01, k, 2 * k, k % 3))
            .collect();
        std::fs::write(&path, format!("t,uL,y,r_uL\n{rows}")).unwrap();
        let inputs = vec!["uL".to_string(), "uR".to_string()];
        let err = load("robot", &inputs, &["y".to_string()], &[path])
            .unwrap_err()
            .to_string();
        assert!(err.starts_with("missing field \"uR\""), "{err}");
        // Both inputs logged, the excitation of one: named, with what to do.
        let both = dir.path().join("one_excitation.csv");
        let rows: String = (0..20)
            .map(|k| format!("{},{},{},{},{}\n", k as f64 * 0.01, k, k % 5, 2 * k, k % 3))
            .collect();
        std::fs::write(&both, format!("t,uL,uR,y,r_uL\n{rows}")).unwrap();
        let err = load("robot", &inputs, &["y".to_string()], &[both])
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("has no column r_uR beside r_uL")
                && err.contains("zeros for an input not excited"),
            "{err}"
        );
    }

    /// Logs whose clocks differ by parts per million share their mean rate; a file in
    /// milliseconds among files in seconds is refused, listed first.
    #[test]
    fn rates_within_a_thousandth_are_one() {
        let e = [experiment("a"), experiment("b"), experiment("c")];
        let fs = one_rate(&e, &[100.0, 100.001, 99.9995]).unwrap();
        assert!((fs - 100.000_166_666_7).abs() < 1e-9, "{fs}");
        let err = one_rate(&e, &[100.0, 0.1, 100.0]).unwrap_err().to_string();
        assert!(err.contains("0.1 Hz in b; 100 Hz in a, c"), "{err}");
    }
}
