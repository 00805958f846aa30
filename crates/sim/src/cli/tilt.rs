//! `stabilis tilt --data log.mcap`: accelerometer-only estimation of tilt, angular velocity and
//! angular acceleration (crate `tilt`) from the readings logged on `/imu/accel`.
//!
//! Log format: topic `/imu/accel` with fields `a{i}x a{i}y a{i}z` for sensors `i = 1..N`
//! (body-frame specific force, m/s^2), and a metadata record `imu` with `sensors` = N and
//! `p{i}` = `"x,y,z"` (position of sensor i relative to the pivot, body frame, m); optionally
//! `bias{i}` = `"x,y,z"` (calibrated bias, subtracted), and `q`, `r` (step sizes). When the log
//! also has `/imu/truth` with `gx gy gz` (and optionally `wx wy wz`, `wdx wdy wdz`) at the same
//! times, the errors of the estimator and of the least-squares baseline are reported.
use std::collections::BTreeMap;
use std::path::PathBuf;

use nalgebra::Vector3;
use serde_json::json;

use super::Output;
use crate::error::{Result, SimError};
use crate::log::{read_mcap, Log, LogWriter, Table};
use crate::progress::Progress;

/// Topic of the accelerometer readings.
pub const ACCEL_TOPIC: &str = "/imu/accel";
/// Optional topic of the true gravity (and rates) for error statistics.
pub const TRUTH_TOPIC: &str = "/imu/truth";
/// Metadata record describing the sensor layout.
pub const IMU_METADATA: &str = "imu";
/// Topic written by `--out`.
pub const ESTIMATE_TOPIC: &str = "/tilt/estimate";

/// Options of `stabilis tilt`.
#[derive(Debug, Clone, PartialEq, clap::Args)]
pub struct Args {
    /// MCAP log with `/imu/accel` and the `imu` metadata record (see the README).
    #[arg(long)]
    pub data: PathBuf,
    /// Also write the estimates to this MCAP file (topic `/tilt/estimate`).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

impl Args {
    /// Reads the log, estimates every sample and summarises.
    pub fn run(&self) -> Result<Output> {
        let inputs = std::slice::from_ref(&self.data);
        if let Some(path) = &self.out {
            // Refused before the work, not after it.
            crate::output::check_file(path, crate::output::Kind::Mcap, inputs)?;
        }
        let log = read_mcap(&self.data)?;
        if let Some(problem) = &log.problem {
            eprintln!(
                "warning: {} is incomplete ({problem}); estimating what was read",
                self.data.display()
            );
        }
        let estimator = estimator_from_metadata(&log)?;
        let accel = log.topic(ACCEL_TOPIC)?;
        let samples = samples(accel, estimator.layout().len())?;
        let mut progress = Progress::new(samples.len() as u64, "estimating");
        let mut estimates = Vec::with_capacity(samples.len());
        let mut baseline = Vec::with_capacity(samples.len());
        for (k, m) in samples.iter().enumerate() {
            let context = || format!("{ACCEL_TOPIC} at t = {} s", accel.t[k]);
            estimates.push(
                estimator
                    .estimate(m)
                    .map_err(|e| SimError::domain(context(), e))?,
            );
            baseline.push(
                tilt::least_squares(estimator.layout(), m)
                    .map_err(|e| SimError::domain(context(), e))?,
            );
            progress.set(k as u64 + 1);
        }
        progress.finish();
        let truth = match log.topics.get(TRUTH_TOPIC) {
            Some(table) => Some(errors(table, &accel.t, &estimates, &baseline)?),
            None => None,
        };
        if let Some(path) = &self.out {
            write_estimates(path, inputs, &accel.t, &estimates)?;
        }
        Ok(summary(self, &estimator, &estimates, truth))
    }
}

/// A metadata value parsed as `f64`.
fn number(record: &BTreeMap<String, String>, key: &str) -> Result<Option<f64>> {
    record
        .get(key)
        .map(|text| {
            text.trim().parse::<f64>().map_err(|_| {
                SimError::invalid(
                    format!("metadata {IMU_METADATA}.{key}"),
                    text,
                    "not a number",
                )
            })
        })
        .transpose()
}

/// A metadata value `"x,y,z"` parsed as a vector.
fn triple(record: &BTreeMap<String, String>, key: &str) -> Result<Option<Vector3<f64>>> {
    let Some(text) = record.get(key) else {
        return Ok(None);
    };
    let parts: Vec<f64> = text
        .split(',')
        .map(|s| s.trim().parse::<f64>())
        .collect::<std::result::Result<_, _>>()
        .map_err(|_| {
            SimError::invalid(
                format!("metadata {IMU_METADATA}.{key}"),
                text,
                "expected three comma-separated numbers \"x,y,z\"",
            )
        })?;
    match parts.as_slice() {
        [x, y, z] => Ok(Some(Vector3::new(*x, *y, *z))),
        _ => Err(SimError::invalid(
            format!("metadata {IMU_METADATA}.{key}"),
            text,
            "expected three comma-separated numbers \"x,y,z\"",
        )),
    }
}

/// The estimator described by the `imu` metadata record.
fn estimator_from_metadata(log: &Log) -> Result<tilt::Estimator> {
    let record = log
        .metadata
        .get(IMU_METADATA)
        .ok_or_else(|| SimError::MissingField {
            context: format!("metadata of {}", log.path.display()),
            field: IMU_METADATA.to_string(),
            available: log.metadata.keys().cloned().collect(),
        })?;
    let missing = |field: String| SimError::MissingField {
        context: format!("metadata record {IMU_METADATA}"),
        field,
        available: record.keys().cloned().collect(),
    };
    let count = number(record, "sensors")?.ok_or_else(|| missing("sensors".into()))?;
    if !(count >= 1.0 && count.fract() == 0.0 && count <= tilt::MAX_SENSORS as f64) {
        return Err(SimError::invalid(
            format!("metadata {IMU_METADATA}.sensors"),
            count,
            format!("must be a whole number from 1 to {}", tilt::MAX_SENSORS),
        ));
    }
    let n = count as usize;
    let mut positions = Vec::with_capacity(n);
    let mut biases = Vec::with_capacity(n);
    for i in 1..=n {
        positions.push(triple(record, &format!("p{i}"))?.ok_or_else(|| missing(format!("p{i}")))?);
        biases.push(triple(record, &format!("bias{i}"))?.unwrap_or_else(Vector3::zeros));
    }
    let layout = tilt::Layout::new(&positions)
        .and_then(|l| l.with_biases(&biases))
        .map_err(|e| SimError::domain(format!("sensor layout in metadata {IMU_METADATA}"), e))?;
    let mut options = tilt::Options::for_layout(&layout);
    match (number(record, "q")?, number(record, "r")?) {
        (None, None) => {}
        (Some(q), Some(r)) => options = options.with_step_sizes(&layout, q, r),
        _ => {
            return Err(SimError::invalid(
                format!("metadata {IMU_METADATA}.q/r"),
                "one of them",
                "give both step sizes q and r, or neither",
            ))
        }
    }
    tilt::Estimator::with_options(layout, options)
        .map_err(|e| SimError::domain(format!("step sizes in metadata {IMU_METADATA}"), e))
}

/// The readings of every message as one vector per sensor.
fn samples(accel: &Table, sensors: usize) -> Result<Vec<Vec<Vector3<f64>>>> {
    let mut columns = Vec::with_capacity(sensors);
    for i in 1..=sensors {
        columns.push([
            accel.column(&format!("a{i}x"))?,
            accel.column(&format!("a{i}y"))?,
            accel.column(&format!("a{i}z"))?,
        ]);
    }
    Ok((0..accel.len())
        .map(|k| {
            columns
                .iter()
                .map(|[x, y, z]| Vector3::new(x[k], y[k], z[k]))
                .collect()
        })
        .collect())
}

/// Error statistics against `/imu/truth`.
#[derive(Debug, Clone, PartialEq)]
struct Errors {
    tilt_ml: f64,
    tilt_ls: f64,
    omega_abs: Option<f64>,
    omega_dot: Option<f64>,
}

fn errors(
    truth: &Table,
    t: &[f64],
    estimates: &[tilt::Estimate],
    baseline: &[tilt::LeastSquaresEstimate],
) -> Result<Errors> {
    if truth.t.len() != t.len() || truth.t.iter().zip(t).any(|(a, b)| (a - b).abs() > 1e-9) {
        return Err(SimError::invalid(
            TRUTH_TOPIC,
            format!("{} messages", truth.len()),
            format!(
                "must have the same times as {ACCEL_TOPIC} ({} messages)",
                t.len()
            ),
        ));
    }
    let vectors = |names: [&str; 3]| -> Result<Vec<Vector3<f64>>> {
        let [x, y, z] = [
            truth.column(names[0])?,
            truth.column(names[1])?,
            truth.column(names[2])?,
        ];
        Ok((0..t.len())
            .map(|k| Vector3::new(x[k], y[k], z[k]))
            .collect())
    };
    let has = |names: [&str; 3]| names.iter().all(|n| truth.fields.iter().any(|f| f == n));
    let g = vectors(["gx", "gy", "gz"])?;
    let n = t.len().max(1) as f64;
    let mean = |values: &mut dyn Iterator<Item = f64>| values.sum::<f64>() / n;
    let tilt_ml = mean(&mut estimates.iter().zip(&g).map(|(e, g)| (e.g - g).norm()));
    let tilt_ls = mean(
        &mut baseline
            .iter()
            .zip(&g)
            .map(|(b, g)| b.g.map_or(f64::NAN, |gl| (gl - g).norm())),
    );
    let omega_abs = if has(["wx", "wy", "wz"]) {
        let w = vectors(["wx", "wy", "wz"])?;
        Some(mean(
            &mut estimates
                .iter()
                .zip(&w)
                .map(|(e, w)| (e.omega.abs() - w.abs()).norm()),
        ))
    } else {
        None
    };
    let omega_dot = if has(["wdx", "wdy", "wdz"]) {
        let wd = vectors(["wdx", "wdy", "wdz"])?;
        Some(mean(
            &mut estimates
                .iter()
                .zip(&wd)
                .map(|(e, wd)| (e.omega_dot - wd).norm()),
        ))
    } else {
        None
    };
    Ok(Errors {
        tilt_ml,
        tilt_ls,
        omega_abs,
        omega_dot,
    })
}

/// Writes `/tilt/estimate` with `gx gy gz wx wy wz wdx wdy wdz iterations converged`.
fn write_estimates(
    path: &PathBuf,
    inputs: &[PathBuf],
    t: &[f64],
    estimates: &[tilt::Estimate],
) -> Result<()> {
    let mut writer = LogWriter::create_for(path, inputs)?;
    let fields = [
        "gx",
        "gy",
        "gz",
        "wx",
        "wy",
        "wz",
        "wdx",
        "wdy",
        "wdz",
        "iterations",
        "converged",
    ];
    let topic = writer.add_topic(ESTIMATE_TOPIC, &fields)?;
    for (time, e) in t.iter().zip(estimates) {
        let values = [
            e.g.x,
            e.g.y,
            e.g.z,
            e.omega.x,
            e.omega.y,
            e.omega.z,
            e.omega_dot.x,
            e.omega_dot.y,
            e.omega_dot.z,
            e.iterations as f64,
            f64::from(u8::from(e.flags.converged)),
        ];
        writer.write(topic, *time, &values)?;
    }
    writer.finish()
}

fn summary(
    args: &Args,
    estimator: &tilt::Estimator,
    estimates: &[tilt::Estimate],
    truth: Option<Errors>,
) -> Output {
    let tuning = estimator.options().tuning;
    let count = estimates.len();
    let converged = estimates.iter().filter(|e| e.flags.converged).count();
    let flagged = estimates
        .iter()
        .filter(|e| e.flags.omega_along_plane_normal)
        .count();
    let iterations: Vec<f64> = estimates.iter().map(|e| e.iterations as f64).collect();
    let mean_iterations = iterations.iter().sum::<f64>() / count.max(1) as f64;
    let max_iterations = iterations.iter().copied().fold(0.0, f64::max);
    let mut human = format!(
        "{}: {} samples from {} accelerometers\nstep sizes q = {:.4}, r = {:.4}; spectral radius of A_s = {:.4} ({})\nconverged {converged} of {count}; iterations mean {mean_iterations:.1}, max {max_iterations}",
        args.data.display(),
        count,
        estimator.layout().len(),
        tuning.q,
        tuning.r,
        tuning.spectral_radius(),
        if tuning.certified() { "local convergence certified" } else { "no certificate" },
    );
    if flagged > 0 {
        human.push_str(&format!(
            "\nwarning: {flagged} samples with omega along the normal of the sensor plane (not identifiable)"
        ));
    }
    if let Some(last) = estimates.last() {
        human.push_str(&format!(
            "\nlast sample: g = ({:.4}, {:.4}, {:.4}) m/s^2, |omega| = {:.4} rad/s, omega_dot = ({:.4}, {:.4}, {:.4}) rad/s^2",
            last.g.x, last.g.y, last.g.z, last.omega_norm, last.omega_dot.x, last.omega_dot.y, last.omega_dot.z
        ));
    }
    if let Some(e) = &truth {
        human.push_str(&format!(
            "\nmean tilt error |g_hat - g|: {:.3e} m/s^2 (least squares {:.3e}, reduction {:.1} %)",
            e.tilt_ml,
            e.tilt_ls,
            100.0 * (1.0 - e.tilt_ml / e.tilt_ls)
        ));
    }
    if let Some(out) = &args.out {
        human.push_str(&format!("\nwrote {}", out.display()));
    }
    let json = json!({
        "data": args.data.display().to_string(),
        "samples": count,
        "sensors": estimator.layout().len(),
        "tuning": {
            "q": tuning.q,
            "r": tuning.r,
            "eigenvalues": tuning.eigenvalues,
            "certified": tuning.certified(),
        },
        "converged": converged,
        "omega_along_plane_normal": flagged,
        "iterations": { "mean": mean_iterations, "max": max_iterations },
        "last": estimates.last().map(|e| json!({
            "g": [e.g.x, e.g.y, e.g.z],
            "omega_norm": e.omega_norm,
            "omega_dot": [e.omega_dot.x, e.omega_dot.y, e.omega_dot.z],
        })),
        "errors": truth.map(|e| json!({
            "tilt_ml": e.tilt_ml,
            "tilt_least_squares": e.tilt_ls,
            "omega_abs": e.omega_abs,
            "omega_dot": e.omega_dot,
        })),
        "out": args.out.as_ref().map(|p| p.display().to_string()),
    });
    Output { human, json }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::rngs::StdRng;
    use rand::SeedableRng;
    use tilt::simulation::{measure, simulate_trajectory, TrajectoryConfig};

    fn positions() -> [Vector3<f64>; 4] {
        [
            Vector3::new(1.0, 0.0, 0.0),
            Vector3::new(0.0, 1.0, 0.0),
            Vector3::new(0.0, 0.0, 1.0),
            Vector3::new(0.2, 0.2, 0.2) / 3f64.sqrt(),
        ]
    }

    /// Writes a simulated 2 s log in the documented format; `metadata` edits the record.
    fn write_log(path: &std::path::Path, edit: impl FnOnce(&mut BTreeMap<String, String>)) {
        let p = positions();
        let mut rng = StdRng::seed_from_u64(9);
        let states = simulate_trajectory(&mut rng, &TrajectoryConfig::default());
        let mut writer = LogWriter::create(path).unwrap();
        let fields: Vec<String> = (1..=4)
            .flat_map(|i| ["x", "y", "z"].map(|c| format!("a{i}{c}")))
            .collect();
        let accel = writer.add_topic(ACCEL_TOPIC, &fields).unwrap();
        let truth_fields = ["gx", "gy", "gz", "wx", "wy", "wz", "wdx", "wdy", "wdz"];
        let truth = writer.add_topic(TRUTH_TOPIC, &truth_fields).unwrap();
        let mut m = [Vector3::zeros(); 4];
        for (k, s) in states.iter().enumerate() {
            let t = 0.02 * k as f64;
            measure(&mut rng, &p, s, 7.7e-4, &[], &mut m);
            let values: Vec<f64> = m.iter().flat_map(|v| v.iter().copied()).collect();
            writer.write(accel, t, &values).unwrap();
            let truth_values: Vec<f64> = [s.g, s.omega, s.omega_dot]
                .iter()
                .flat_map(|v| v.iter().copied())
                .collect();
            writer.write(truth, t, &truth_values).unwrap();
        }
        let mut record = BTreeMap::from([("sensors".to_string(), "4".to_string())]);
        for (i, v) in p.iter().enumerate() {
            record.insert(format!("p{}", i + 1), format!("{},{},{}", v.x, v.y, v.z));
        }
        edit(&mut record);
        writer.write_metadata(IMU_METADATA, record).unwrap();
        writer.finish().unwrap();
    }

    /// A directory of the test's own, removed when dropped.
    fn scratch() -> tempfile::TempDir {
        tempfile::Builder::new()
            .prefix("stabilis-tilt-")
            .tempdir()
            .unwrap()
    }

    #[test]
    fn estimates_a_simulated_log_better_than_least_squares() {
        let dir = scratch();
        let path = dir.path().join("ok.mcap");
        write_log(&path, |_| {});
        let out = dir.path().join("estimates.mcap");
        let args = Args {
            data: path,
            out: Some(out.clone()),
        };
        let output = args.run().unwrap();
        assert_eq!(output.json["samples"], 100);
        assert_eq!(output.json["converged"], 100);
        let ml = output.json["errors"]["tilt_ml"].as_f64().unwrap();
        let ls = output.json["errors"]["tilt_least_squares"]
            .as_f64()
            .unwrap();
        // The 2 s trajectory of the paper: about 0.8e-3 vs 1.5e-3 (spec section 8).
        assert!(ml < 0.75 * ls && ml < 1.5e-3, "{ml} vs {ls}");
        let written = read_mcap(&out).unwrap();
        let table = written.topic(ESTIMATE_TOPIC).unwrap();
        assert_eq!(table.len(), 100);
        let [gx, gy, gz] = ["gx", "gy", "gz"].map(|f| table.column(f).unwrap());
        for k in 0..100 {
            let norm = Vector3::new(gx[k], gy[k], gz[k]).norm();
            assert!((norm - tilt::G0).abs() < 1e-9 * tilt::G0);
        }
        assert!(table.column("converged").unwrap().iter().all(|&c| c == 1.0));
        assert!(output.human.contains("reduction"));
    }

    /// An edit of the `imu` metadata record.
    type Edit = fn(&mut BTreeMap<String, String>);

    #[test]
    fn bad_metadata_is_named() {
        let dir = scratch();
        let cases: [(&str, Edit); 4] = [
            ("p3", |r| {
                r.remove("p3");
            }),
            ("p2", |r| {
                r.insert("p2".into(), "1,2".into());
            }),
            ("coplanar with the pivot", |r| {
                for i in 1..=4 {
                    r.insert(format!("p{i}"), format!("{i},1,0"));
                }
            }),
            ("q/r", |r| {
                r.insert("q".into(), "0.25".into());
            }),
        ];
        for (k, (needle, edit)) in cases.into_iter().enumerate() {
            let path = dir.path().join(format!("bad{k}.mcap"));
            write_log(&path, edit);
            let error = Args {
                data: path,
                out: None,
            }
            .run()
            .unwrap_err();
            let text = format!("{error}: {:?}", std::error::Error::source(&error));
            assert!(text.contains(needle), "{needle}: {text}");
            assert_eq!(error.exit_code(), 2);
        }
    }
}
