//! `stabilis sim cubli --scenario jump-up --jump edge`: the face → edge jump learns its wheel
//! speed, writes the DESIGN.md topics and ends balanced on the edge.
#![allow(clippy::unwrap_used)]
use std::process::Command;

use sim::scenarios::cubli::{INPUT_FIELDS, OUTPUT_FIELDS, STATE_FIELDS};

fn run_edge(name: &str, extra: &[&str]) -> (serde_json::Value, sim::log::Log) {
    // Removed when dropped, after the binary has written the log and it has been read.
    let dir = tempfile::Builder::new()
        .prefix("cubli-jump-")
        .tempdir()
        .unwrap();
    let out = dir.path().join(name);
    let mut args = vec![
        "sim",
        "cubli",
        "--scenario",
        "jump-up",
        "--jump",
        "edge",
        "--duration",
        "4",
        "--seed",
        "5",
        "--json",
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let run = Command::new(env!("CARGO_BIN_EXE_stabilis"))
        .args(&args)
        .output()
        .unwrap();
    assert_eq!(
        run.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let json: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    let log = sim::log::read_mcap(&out).unwrap();
    (json, log)
}

#[test]
fn edge_jump_log_has_the_design_topics_and_ends_balanced() {
    let (json, log) = run_edge("edge.mcap", &[]);
    assert!(log.complete);
    let input = log.topic("/cubli/input").unwrap();
    let output = log.topic("/cubli/output").unwrap();
    let state = log.topic("/cubli/state").unwrap();
    assert_eq!(input.fields, INPUT_FIELDS);
    assert_eq!(output.fields, OUTPUT_FIELDS);
    assert_eq!(state.fields, STATE_FIELDS);
    assert_eq!(state.len(), 400);
    let exp = log.experiment().unwrap();
    assert_eq!(exp["jump"], "edge");
    // Only wheel 1 (parallel to the edge) spins and gets torque; the housing turns about e1 only.
    for f in ["T2", "T3"] {
        assert!(input.column(f).unwrap().iter().all(|v| *v == 0.0));
    }
    for f in ["wy", "wz", "w2", "w3"] {
        assert!(state.column(f).unwrap().iter().all(|v| *v == 0.0), "{f}");
    }
    // Starts just after braking at rest on the face (44.46 degrees for the true plant, whose
    // centre of mass is shifted by (2, -2, 0) g m), ends upright on the edge.
    let phi = state.column("inclination").unwrap();
    assert!((phi[0].to_degrees() - 44.46).abs() < 0.01, "{}", phi[0]);
    let last = phi[phi.len() - 100..]
        .iter()
        .fold(0.0f64, |m, v| m.max(v.abs()));
    assert!(last.to_degrees() < 0.5, "{}", last.to_degrees());
    // The unit gravity of the state has no component along the edge.
    assert!(state.column("gx").unwrap().iter().all(|v| v.abs() < 1e-12));
    let summary = &json["summary"];
    assert!(summary["final_inclination_deg"].as_f64().unwrap() < 0.5);
    let first = summary["first_successful_trial"].as_u64().unwrap();
    assert!(first <= 5, "{first}");
    let learned = summary["learned_wheel_speeds_rad_s"][0].as_f64().unwrap();
    // Closed form of the true plant (crates/cubli/tests/edge.rs): 521.73 rad/s.
    assert!((learned - 521.7).abs() < 2.0, "{learned}");
}

#[test]
fn edge_jump_with_random_brake_efficiency_still_balances() {
    let (json, log) = run_edge(
        "edge-random.mcap",
        &["--brake-spread", "0.01", "--trials", "8"],
    );
    let brakes: Vec<String> = json["summary"]["learning"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| t["brake"].as_str().unwrap().to_string())
        .collect();
    assert_eq!(brakes.len(), 8);
    assert!(brakes.windows(2).all(|w| w[0] != w[1]), "{brakes:?}");
    assert_eq!(log.experiment().unwrap()["brake_spread"], "0.01");
    assert!(json["summary"]["final_inclination_deg"].as_f64().unwrap() < 0.5);
}

#[test]
fn bad_jump_options_are_named() {
    for (args, name) in [
        (&["--jump", "face"][..], "face"),
        (&["--brake-spread", "1.5"][..], "brake-spread"),
        (&["--start-scale", "0"][..], "start-scale"),
    ] {
        let mut all = vec!["sim", "cubli", "--scenario", "jump-up", "--duration", "1"];
        all.extend_from_slice(args);
        let run = Command::new(env!("CARGO_BIN_EXE_stabilis"))
            .args(&all)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(stderr.contains(name), "{args:?}: {stderr}");
    }
}
