//! The `stabilis` binary end to end: exit codes, messages, and the logs it writes.
#![allow(clippy::unwrap_used)]
mod common;

use common::{stabilis, text, Scratch};

/// A directory of the test's own, removed when dropped.
fn scratch() -> Scratch {
    Scratch::new("sim-cli-tests-")
}

#[test]
fn sim_writes_a_log_that_info_and_the_reader_understand() {
    let dir = scratch();
    let out = dir.join("run.mcap");
    let run = stabilis(&[
        "sim",
        "wheel-pendulum",
        "--duration",
        "3",
        "--out",
        out.to_str().unwrap(),
        "--seed",
        "4",
        "--json",
    ]);
    assert_eq!(run.status.code(), Some(0), "{}", text(&run.stderr));
    let json: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    assert_eq!(json["topics"]["/wheel_pendulum/state"]["messages"], 601);
    assert!(
        json["summary"]["max_tilt_last_second_deg"]
            .as_f64()
            .unwrap()
            < 0.2
    );

    let log = sim::log::read_mcap(&out).unwrap();
    assert!(log.complete);
    let state = log.topic("/wheel_pendulum/state").unwrap();
    assert_eq!(state.len(), 601);
    assert_eq!(state.t[600], 3.0);
    assert_eq!(state.column("phi").unwrap()[0], 5f64.to_radians());
    assert_eq!(log.experiment().unwrap()["sample_rate_hz"], "200");
    assert_eq!(log.experiment().unwrap()["seed"], "4");

    let info = stabilis(&["info", out.to_str().unwrap(), "--json"]);
    assert_eq!(info.status.code(), Some(0), "{}", text(&info.stderr));
    let json: serde_json::Value = serde_json::from_slice(&info.stdout).unwrap();
    assert_eq!(json["messages"], 3 * 601);
    assert_eq!(json["span"], serde_json::json!([0.0, 3.0]));
    assert_eq!(
        json["topics"]["/wheel_pendulum/input"]["fields"],
        serde_json::json!(["tau"])
    );
    assert_eq!(json["metadata"]["experiment"]["system"], "wheel-pendulum");
    assert_eq!(json["complete"], true);

    let human = stabilis(&["info", out.to_str().unwrap()]);
    let human = text(&human.stdout);
    assert!(
        human.contains("3 topics, 1803 messages, t = 0 .. 3 s"),
        "{human}"
    );
    assert!(
        human.contains("/wheel_pendulum/output: 601 messages"),
        "{human}"
    );
}

#[test]
fn same_seed_gives_the_same_run() {
    let run = |seed: &str| {
        stabilis(&[
            "sim",
            "wheel-pendulum",
            "--duration",
            "1",
            "--seed",
            seed,
            "--json",
        ])
        .stdout
    };
    let first = run("9");
    assert_eq!(
        first,
        run("9"),
        "a second run with seed 9 must reproduce the first"
    );
    assert_ne!(first, run("10"), "another seed must give other noise");
}

#[test]
fn without_control_the_pendulum_falls() {
    let run = stabilis(&[
        "sim",
        "wheel-pendulum",
        "--duration",
        "2",
        "--no-control",
        "--json",
    ]);
    assert_eq!(run.status.code(), Some(0));
    let json: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    assert!(json["summary"]["max_tilt_deg"].as_f64().unwrap() > 45.0);
}

#[test]
fn bad_input_exits_with_code_2_and_a_named_error() {
    let dir = scratch();
    let missing = dir.join("absent.mcap");
    let run = stabilis(&["info", missing.to_str().unwrap()]);
    assert_eq!(run.status.code(), Some(2));
    assert_eq!(
        text(&run.stderr).trim(),
        format!("error: file not found: {}", missing.display())
    );

    let not_mcap = dir.join("notes.mcap");
    std::fs::write(&not_mcap, "these are notes, not a log").unwrap();
    let run = stabilis(&["info", not_mcap.to_str().unwrap()]);
    assert_eq!(run.status.code(), Some(2));
    assert!(
        text(&run.stderr).contains("not an MCAP file"),
        "{}",
        text(&run.stderr)
    );

    let out = dir.join("short.mcap");
    assert_eq!(
        stabilis(&[
            "sim",
            "wheel-pendulum",
            "--duration",
            "0.1",
            "--out",
            out.to_str().unwrap()
        ])
        .status
        .code(),
        Some(0)
    );
    let run = stabilis(&[
        "info",
        out.to_str().unwrap(),
        "--topic",
        "/cubli/output",
        "--json",
    ]);
    assert_eq!(run.status.code(), Some(2));
    let stderr = text(&run.stderr);
    assert!(
        stderr.contains("missing channel \"/cubli/output\""),
        "{stderr}"
    );
    assert!(stderr.contains("/wheel_pendulum/state"), "{stderr}");
    let json: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    assert!(json["error"]
        .as_str()
        .unwrap()
        .starts_with("missing channel"));

    let run = stabilis(&["sim", "wheel-pendulum", "--duration=-1"]);
    assert_eq!(run.status.code(), Some(2));
    assert!(
        text(&run.stderr).contains("invalid duration = -1"),
        "{}",
        text(&run.stderr)
    );

    let unwritable = dir.join("no-such-dir").join("run.mcap");
    let run = stabilis(&[
        "sim",
        "wheel-pendulum",
        "--out",
        unwritable.to_str().unwrap(),
    ]);
    assert_eq!(run.status.code(), Some(2));
    assert!(
        text(&run.stderr).starts_with(&format!("error: cannot access {}: ", unwritable.display())),
        "{}",
        text(&run.stderr)
    );

    // `--json` with a log right after it would take the log as its output file.
    let before = std::fs::read(&out).unwrap();
    let run = stabilis(&[
        "info",
        "--json",
        out.to_str().unwrap(),
        out.to_str().unwrap(),
    ]);
    assert_eq!(run.status.code(), Some(2));
    assert!(
        text(&run.stderr).contains("invalid --json FILE"),
        "{}",
        text(&run.stderr)
    );
    assert_eq!(std::fs::read(&out).unwrap(), before);

    let run = stabilis(&["sim", "unicycle"]);
    assert_eq!(run.status.code(), Some(2));
    assert!(text(&run.stderr).contains("unrecognized subcommand 'unicycle'"));
}

#[test]
fn a_log_cut_off_mid_way_is_still_summarised() {
    let dir = scratch();
    let out = dir.join("long.mcap");
    let run = stabilis(&[
        "sim",
        "wheel-pendulum",
        "--duration",
        "10",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(run.status.code(), Some(0));
    // Keep the first 60 % of the bytes, as if the writer had been killed.
    let bytes = std::fs::read(&out).unwrap();
    let cut = dir.join("cut.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() * 6 / 10]).unwrap();
    let run = stabilis(&["info", cut.to_str().unwrap(), "--json"]);
    assert_eq!(run.status.code(), Some(0), "{}", text(&run.stderr));
    let json: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    assert_eq!(json["complete"], false);
    let messages = json["topics"]["/wheel_pendulum/state"]["messages"]
        .as_u64()
        .unwrap();
    // 2001 messages per topic in chunks of 512 messages across topics: most chunks survive.
    assert!((900..2001).contains(&messages), "{messages} messages read");
    assert_eq!(json["metadata"]["experiment"]["system"], "wheel-pendulum");
    let human = stabilis(&["info", cut.to_str().unwrap()]);
    assert!(text(&human.stdout).contains("warning: the log is incomplete"));
}

#[test]
fn csv_files_are_summarised_too() {
    let dir = scratch();
    let path = dir.join("measured.csv");
    std::fs::write(&path, "t,phi\n0,0.1\n0.5,0.2\n1,0.3\n").unwrap();
    let run = stabilis(&["info", path.to_str().unwrap(), "--json"]);
    assert_eq!(run.status.code(), Some(0), "{}", text(&run.stderr));
    let json: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    assert_eq!(json["messages"], 3);
    assert_eq!(json["span"], serde_json::json!([0.0, 1.0]));
}

#[test]
fn help_and_version_exit_with_0() {
    let run = stabilis(&["--help"]);
    assert_eq!(run.status.code(), Some(0));
    assert!(text(&run.stdout).contains("sim"));
    assert_eq!(stabilis(&["--version"]).status.code(), Some(0));
}
