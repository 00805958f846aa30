//! `stabilis discover | fit` end to end on MCAP logs: the embedded flying-platform dataset is
//! written as 18 MCAP files (DESIGN.md topics and metadata) and read back by the binary.
#![allow(clippy::unwrap_used)]
use std::collections::BTreeMap;
use std::path::Path;

mod common;

use common::{ok, refused, Scratch};
use sim::log::LogWriter;
use sim::systems::flying_platform::embedded_dataset;

/// A directory of the test's own, removed when dropped.
fn scratch() -> Scratch {
    Scratch::new("sim-workbench-cli-")
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
    let dir = scratch();
    let logs = dir.join("logs");
    write_logs(&logs, None);
    let json = dir.join("discover.json");
    let report = dir.join("report");
    let stdout = ok(&[
        "discover",
        "--data",
        logs.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
        "--json",
        json.to_str().unwrap(),
    ]);
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
    let dir = scratch();
    let logs = dir.join("logs-fit");
    write_logs(&logs, None);
    let stdout = ok(&[
        "fit",
        "--with",
        "momentum_drag,fan_gyroscopic",
        "--data",
        logs.to_str().unwrap(),
        "--json",
    ]);
    let doc: serde_json::Value = serde_json::from_str(&stdout).unwrap();
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
    // The summary does not read as if the effects given had been rejected.
    let summary = ok(&[
        "fit",
        "--with",
        "momentum_drag,fan_gyroscopic",
        "--data",
        logs.to_str().unwrap(),
    ]);
    assert!(
        summary.contains("found: nothing searched") && !summary.contains("found: []"),
        "{summary}"
    );
}

#[test]
fn missing_channel_is_named_and_no_report_is_left() {
    let dir = scratch();
    let logs = dir.join("logs-missing");
    write_logs(&logs, Some("wz"));
    let report = dir.join("report-missing");
    let stderr = refused(&[
        "discover",
        "--data",
        logs.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
    ]);
    // Read as the default system's logs, which a user of another system may not know.
    assert!(
        stderr.contains("\"wz\"")
            && stderr.contains("missing field")
            && stderr.contains("neither --model nor --system was given"),
        "{stderr}"
    );
    assert!(!report.exists());
}

#[test]
fn unknown_or_repeated_effect_is_named() {
    let dir = scratch();
    let logs = dir.join("logs-unknown");
    write_logs(&logs, None);
    let stderr = refused(&[
        "fit",
        "--with",
        "ground_effect",
        "--data",
        logs.to_str().unwrap(),
    ]);
    assert!(
        stderr.contains("ground_effect") && stderr.contains("momentum_drag"),
        "{stderr}"
    );
    let stderr = refused(&[
        "fit",
        "--with",
        "momentum_drag, fan_gyroscopic,momentum_drag",
        "--data",
        logs.to_str().unwrap(),
    ]);
    assert!(stderr.contains("names momentum_drag twice"), "{stderr}");
}

/// Simulates four 40 s Cubli balancing runs with `stabilis sim cubli` (0.01 N m multisine on
/// the commanded torques, default sensor noise) into `dir`, with `extra` options.
fn cubli_logs(dir: &Path, extra: &[&str]) {
    std::fs::create_dir_all(dir).unwrap();
    for (seed, tilt) in [(21, "5"), (22, "-4"), (23, "3"), (24, "-4.5")] {
        let out = dir.join(format!("run{seed}.mcap"));
        let mut args = vec![
            "sim".to_string(),
            "cubli".into(),
            "--duration=40".into(),
            "--excitation-rms=0.01".into(),
            format!("--seed={seed}"),
            format!("--tilt-deg={tilt}"),
            format!("--out={}", out.display()),
        ];
        args.extend(extra.iter().map(|s| s.to_string()));
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        ok(&args);
    }
}

#[test]
fn cubli_compare_fit_discover_and_report() {
    let dir = scratch();
    let c = 2e-5;
    let logs = dir.join("cubli-viscous");
    cubli_logs(&logs, &["--viscous=2e-5,2e-5,2e-5"]);
    let data = logs.to_str().unwrap();
    let json = |args: &[&str]| -> serde_json::Value {
        serde_json::from_str(&ok(&[
            args,
            &["--system", "cubli", "--data", data, "--json"],
        ]
        .concat()))
        .unwrap()
    };
    let nominal = json(&["compare"]);
    // `diagnose` is `compare` under the name the workbench's steps go by.
    assert_eq!(json(&["diagnose"]), nominal);
    let fitted = json(&["fit", "--with", "wheel_viscous_friction"]);
    let (s0, s1) = (&nominal["steps"][0], &fitted["steps"][0]);
    assert_eq!(s1["effects"], serde_json::json!(["wheel_viscous_friction"]));
    let est = s1["params"]["wheel_viscous_friction"].as_f64().unwrap();
    let std = s1["std"]["wheel_viscous_friction"].as_f64().unwrap();
    assert!((est - c).abs() < 0.15 * c && std > 0.0, "{est} +- {std}");
    assert!(s1["cost"].as_f64() < s0["cost"].as_f64(), "{s0} vs {s1}");
    // The fitted model explains the logs; the nominal one leaves the wheels' misfit.
    assert_eq!(fitted["unexplained"], false, "{}", fitted["verdict"]);
    assert_eq!(nominal["unexplained"], true, "{}", nominal["verdict"]);
    let report = dir.join("cubli-report");
    let stdout = ok(&[
        "discover",
        "--system",
        "cubli",
        "--data",
        data,
        "--report",
        report.to_str().unwrap(),
    ]);
    assert!(
        stdout.contains("found: [wheel_viscous_friction]"),
        "{stdout}"
    );
    let html = std::fs::read_to_string(report.join("index.html")).unwrap();
    for part in [
        "<svg",
        "Parameters",
        "Error per step",
        "Residuals",
        "explained to the noise level",
    ] {
        assert!(html.contains(part), "report lacks {part}");
    }
    assert!(!html.contains("<script"));
    let doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(report.join("report.json")).unwrap())
            .unwrap();
    assert_eq!(doc["found"], serde_json::json!(["wheel_viscous_friction"]));
    let stderr = refused(&[
        "fit",
        "--system",
        "cubli",
        "--with",
        "ground_effect",
        "--data",
        data,
    ]);
    assert!(
        stderr.contains("ground_effect") && stderr.contains("wheel_coulomb_friction"),
        "{stderr}"
    );
    let stderr = refused(&[
        "compare",
        "--system",
        "cubli",
        "--estimator",
        "iv",
        "--data",
        data,
    ]);
    assert!(stderr.contains("no FRF estimator"), "{stderr}");
}

/// Writes one Cubli run as CSV with `t`, the inputs and the outputs, changed by `edit`.
fn cubli_csv(path: &Path, source: &Path, edit: impl Fn(&mut Vec<String>, &mut Vec<Vec<String>>)) {
    let data = sim::systems::cubli::load_cubli(&[source.to_path_buf()]).unwrap();
    let e = &data.experiments[0];
    let mut header: Vec<String> = ["t"]
        .iter()
        .map(|s| s.to_string())
        .chain(data.inputs.iter().cloned())
        .chain(data.outputs.iter().cloned())
        .collect();
    let mut rows: Vec<Vec<String>> = (0..e.u.nrows())
        .map(|k| {
            std::iter::once(k as f64 / data.sample_rate_hz)
                .chain(e.u.row(k).iter().copied())
                .chain(e.y.row(k).iter().copied())
                .map(|v| v.to_string())
                .collect()
        })
        .collect();
    edit(&mut header, &mut rows);
    let text: Vec<String> = std::iter::once(header.join(","))
        .chain(rows.iter().map(|r| r.join(",")))
        .collect();
    std::fs::write(path, text.join("\n")).unwrap();
}

#[test]
fn cubli_bad_data_is_named_and_no_report_is_left() {
    let dir = scratch();
    let logs = dir.join("cubli-bad-source");
    cubli_logs(&logs, &[]);
    let source = logs.join("run21.mcap");
    let report = dir.join("cubli-bad-report");
    let run = |file: &Path| {
        refused(&[
            "discover",
            "--system",
            "cubli",
            "--data",
            file.to_str().unwrap(),
            "--report",
            report.to_str().unwrap(),
        ])
    };
    // A missing channel.
    let missing = dir.join("cubli-missing.csv");
    cubli_csv(&missing, &source, |h, rows| {
        h.pop();
        for r in rows.iter_mut() {
            r.pop();
        }
    });
    let stderr = run(&missing);
    assert!(stderr.contains("\"gz\""), "{stderr}");
    // A NaN sample.
    let nan = dir.join("cubli-nan.csv");
    cubli_csv(&nan, &source, |_, rows| rows[500][5] = "NaN".into());
    let stderr = run(&nan);
    assert!(
        stderr.contains("\"wy\"") && stderr.contains("line 502"),
        "{stderr}"
    );
    // Output and input logs of different lengths.
    let short = dir.join("cubli-short.mcap");
    let data = sim::systems::cubli::load_cubli(std::slice::from_ref(&source)).unwrap();
    let e = &data.experiments[0];
    let mut w = LogWriter::create(&short).unwrap();
    let ti = w.add_topic("/cubli/input", &data.inputs).unwrap();
    let to = w.add_topic("/cubli/output", &data.outputs).unwrap();
    for k in 0..e.u.nrows() {
        let t = k as f64 / data.sample_rate_hz;
        w.write(
            ti,
            t,
            e.u.row(k).iter().copied().collect::<Vec<_>>().as_slice(),
        )
        .unwrap();
        if k + 10 < e.u.nrows() {
            w.write(
                to,
                t,
                e.y.row(k).iter().copied().collect::<Vec<_>>().as_slice(),
            )
            .unwrap();
        }
    }
    w.finish().unwrap();
    let stderr = run(&short);
    assert!(stderr.contains("/cubli/output"), "{stderr}");
    // One file of three with its time in milliseconds: the message lists each rate with its
    // files, the odd one first, rounded (the mean step of a time column is not exact).
    let rates = dir.join("cubli-rates");
    std::fs::create_dir_all(&rates).unwrap();
    for (name, rows) in [("a", 0), ("b", 1)] {
        // b one row shorter: the same log twice is refused as such.
        cubli_csv(&rates.join(format!("{name}.csv")), &source, |_, r| {
            r.truncate(r.len() - rows)
        });
    }
    cubli_csv(&rates.join("ms.csv"), &source, |_, rows| {
        for r in rows.iter_mut() {
            r[0] = (1e3 * r[0].parse::<f64>().unwrap()).to_string();
        }
    });
    let stderr = run(&rates);
    let fs = data.sample_rate_hz;
    let (slow, fast) = (
        format!("{} Hz in {}", fs / 1e3, rates.join("ms.csv").display()),
        format!(
            "{fs} Hz in {}, {}",
            rates.join("a.csv").display(),
            rates.join("b.csv").display()
        ),
    );
    assert!(
        stderr.contains(&format!("{slow}; {fast}")) && stderr.contains("other units"),
        "{stderr}"
    );
    assert!(!report.exists());
}
