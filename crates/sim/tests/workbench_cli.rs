//! `stabilis discover | fit` end to end on MCAP logs: the embedded flying-platform dataset is
//! written as 18 MCAP files (DESIGN.md topics and metadata) and read back by the binary.
#![allow(clippy::unwrap_used)]
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use sim::log::LogWriter;
use sim::workbench::flying_platform::embedded_dataset;

fn stabilis(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_stabilis"))
        .args(args)
        .output()
        .unwrap()
}

fn temp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("sim-workbench-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

/// Writes the embedded dataset as MCAP files into `dir`, leaving out the output `drop`.
fn write_logs(dir: &Path, drop: Option<&str>) {
    std::fs::create_dir_all(dir).unwrap();
    let data = embedded_dataset().unwrap();
    for (k, e) in data.experiments.iter().enumerate() {
        let mut w = LogWriter::create(dir.join(format!("exp{:02}.mcap", k + 1))).unwrap();
        let outputs: Vec<&String> = data
            .outputs
            .iter()
            .filter(|o| Some(o.as_str()) != drop)
            .collect();
        let ti = w.add_topic("/flying_platform/input", &data.inputs).unwrap();
        let to = w.add_topic("/flying_platform/output", &outputs).unwrap();
        let tr = w
            .add_topic("/flying_platform/excitation", &data.inputs)
            .unwrap();
        let p = e.periodic.unwrap();
        let excited: Vec<&str> = data
            .inputs
            .iter()
            .enumerate()
            .filter(|(j, _)| e.r.as_ref().unwrap().column(*j).iter().any(|v| *v != 0.0))
            .map(|(_, n)| n.as_str())
            .collect();
        w.write_metadata(
            "experiment",
            BTreeMap::from([
                (
                    "sample_rate_hz".to_string(),
                    data.sample_rate_hz.to_string(),
                ),
                ("period_samples".to_string(), p.period.to_string()),
                ("periods".to_string(), p.periods.to_string()),
                ("transient_samples".to_string(), p.transient.to_string()),
                ("excited".to_string(), excited.join(",")),
            ]),
        )
        .unwrap();
        for i in 0..e.u.nrows() {
            let t = i as f64 / data.sample_rate_hz;
            let u: Vec<f64> = e.u.row(i).iter().cloned().collect();
            let y: Vec<f64> = data
                .outputs
                .iter()
                .enumerate()
                .filter(|(_, o)| Some(o.as_str()) != drop)
                .map(|(j, _)| e.y[(i, j)])
                .collect();
            let r: Vec<f64> = e.r.as_ref().unwrap().row(i).iter().cloned().collect();
            w.write(ti, t, &u).unwrap();
            w.write(to, t, &y).unwrap();
            w.write(tr, t, &r).unwrap();
        }
        w.finish().unwrap();
    }
}

#[test]
fn discover_on_mcap_logs_writes_json_and_report() {
    let logs = temp("logs");
    write_logs(&logs, None);
    let json = temp("discover.json");
    let report = temp("report");
    let run = stabilis(&[
        "discover",
        "--data",
        logs.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
        "--json",
        json.to_str().unwrap(),
    ]);
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert_eq!(
        run.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    assert!(
        stdout.contains("found: [momentum_drag, fan_gyroscopic]"),
        "{stdout}"
    );
    let doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(
        doc["found"],
        serde_json::json!(["momentum_drag", "fan_gyroscopic"])
    );
    assert_eq!(doc["unexplained"], false);
    assert_eq!(doc["estimator"], "instrumental_variable");
    let steps = doc["steps"].as_array().unwrap();
    assert_eq!(steps.len(), 3);
    assert!(steps[0]["added"].is_null());
    assert_eq!(steps[1]["added"], "momentum_drag");
    let (c0, c2) = (
        steps[0]["cost"].as_f64().unwrap(),
        steps[2]["cost"].as_f64().unwrap(),
    );
    assert!(c2 < 0.05 * c0, "costs {c0} -> {c2}");
    assert!((steps[2]["params"]["c_alpha1"].as_f64().unwrap() - 2.388).abs() < 0.24);
    let html = std::fs::read_to_string(report.join("index.html")).unwrap();
    assert!(html.contains("<svg") && html.contains("momentum_drag") && !html.contains("<script"));
}

#[test]
fn fit_with_effects_reports_parameters_with_standard_errors() {
    let logs = temp("logs-fit");
    write_logs(&logs, None);
    let run = stabilis(&[
        "fit",
        "--with",
        "momentum_drag,fan_gyroscopic",
        "--data",
        logs.to_str().unwrap(),
        "--json",
    ]);
    assert_eq!(
        run.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let doc: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    let step = &doc["steps"][0];
    assert_eq!(
        step["effects"],
        serde_json::json!(["momentum_drag", "fan_gyroscopic"])
    );
    let c = step["params"]["c_omega_t0"].as_f64().unwrap();
    let s = step["std"]["c_omega_t0"].as_f64().unwrap();
    assert!(
        s > 0.0 && (c - 0.018).abs() < 4.0 * s + 0.002,
        "c_omega_t0 = {c} +- {s}"
    );
}

#[test]
fn missing_channel_is_named_and_no_report_is_left() {
    let logs = temp("logs-missing");
    write_logs(&logs, Some("wz"));
    let report = temp("report-missing");
    let run = stabilis(&[
        "discover",
        "--data",
        logs.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
    ]);
    assert_eq!(run.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(
        stderr.contains("\"wz\"") && stderr.contains("missing field"),
        "{stderr}"
    );
    assert!(!report.exists());
}

#[test]
fn unknown_effect_is_named() {
    let logs = temp("logs-unknown");
    write_logs(&logs, None);
    let run = stabilis(&[
        "fit",
        "--with",
        "ground_effect",
        "--data",
        logs.to_str().unwrap(),
    ]);
    assert_eq!(run.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(
        stderr.contains("ground_effect") && stderr.contains("momentum_drag"),
        "{stderr}"
    );
}
