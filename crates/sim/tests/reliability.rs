//! The guarantees of the README end to end: no command overwrites or deletes an input or a
//! file it did not write, a killed run leaves the previous output as it was, sizes beyond the
//! machine are refused before anything is allocated, damaged logs are named errors, and a
//! closed pipe is not a crash.
#![allow(clippy::unwrap_used)]
mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

use common::{stabilis, stabilis_in, text, Scratch};

/// An empty directory `name` of the test's own, alone in its parent (which some tests look
/// at); both are removed when it is dropped.
fn scratch(name: &str) -> Scratch {
    Scratch::nested("sim-reliability-", name)
}

/// A short wheel-pendulum log at `path`.
fn log_at(path: &Path) {
    let run = stabilis(&[
        "sim",
        "wheel-pendulum",
        "--duration",
        "1",
        "--out",
        path.to_str().unwrap(),
    ]);
    assert_eq!(run.status.code(), Some(0), "{}", text(&run.stderr));
}

/// Every file under `dir` with its bytes, sorted.
fn snapshot(dir: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    let mut out: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .map(|p| {
            let bytes = if p.is_file() {
                std::fs::read(&p).unwrap()
            } else {
                Vec::new()
            };
            (p, bytes)
        })
        .collect();
    out.sort();
    out
}

fn assert_refused(run: &Output, path_part: &str) {
    let stderr = text(&run.stderr);
    assert_eq!(run.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("refusing to write") && stderr.contains(path_part),
        "{stderr}"
    );
}

#[test]
fn report_into_the_data_directory_is_refused_and_deletes_nothing() {
    let dir = scratch("report-data");
    log_at(&dir.join("run.mcap"));
    std::fs::write(dir.join("notes.txt"), "mine").unwrap();
    let before = snapshot(&dir);
    let d = dir.to_str().unwrap();
    assert_refused(&stabilis(&["discover", "--data", d, "--report", d]), d);
    assert_eq!(snapshot(&dir), before);
}

#[test]
fn report_onto_a_file_or_a_non_empty_current_directory_is_refused() {
    let dir = scratch("report-file");
    log_at(&dir.join("run.mcap"));
    let notes = dir.join("notes.txt");
    std::fs::write(&notes, "mine").unwrap();
    let before = snapshot(&dir);
    let run = stabilis(&["discover", "--report", notes.to_str().unwrap()]);
    assert_refused(&run, "notes.txt");
    let run = stabilis_in(&dir, &["discover", "--report", "."]);
    assert_eq!(run.status.code(), Some(2), "{}", text(&run.stderr));
    // Nothing added, nothing hidden, nothing left beside it.
    assert_eq!(snapshot(&dir), before);
    let parent = snapshot(dir.parent().unwrap());
    let name = dir.file_name().unwrap().to_string_lossy().into_owned();
    assert!(
        !parent.iter().any(|(p, _)| p
            .file_name()
            .unwrap()
            .to_string_lossy()
            .starts_with(&format!(".{name}"))),
        "a temporary was left beside {name}"
    );
}

/// Two outputs of one run on the same path (or one inside the other) are refused before any
/// work: nothing is written, and the message names both options.
#[test]
fn outputs_that_clash_with_each_other_are_refused_before_the_work() {
    let dir = scratch("clash");
    let same = dir.join("rr2");
    let s = same.to_str().unwrap();
    let run = stabilis(&["discover", "--report", s, "--json", s]);
    assert_refused(&run, "rr2");
    let stderr = text(&run.stderr);
    assert!(
        stderr.contains(&format!("--json {s} and --report {s} name the same path")),
        "{stderr}"
    );
    // Refused before the discovery: no report was written.
    assert!(text(&run.stdout).is_empty(), "{}", text(&run.stdout));
    let inside = same.join("result.json");
    let run = stabilis(&["compare", "--report", s, "--json", inside.to_str().unwrap()]);
    assert_refused(&run, "result.json");
    assert!(text(&run.stderr).contains("lies inside --report"));
    // A simulated log and its JSON on one path.
    let log = dir.join("run.json");
    let l = log.to_str().unwrap();
    let run = stabilis(&[
        "sim",
        "wheel-pendulum",
        "--duration",
        "1",
        "--out",
        l,
        "--json",
        l,
    ]);
    assert_refused(&run, "run.json");
    assert!(text(&run.stderr).contains("name the same path"));
    assert_eq!(snapshot(&dir), Vec::new());
}

#[test]
fn tilt_out_onto_its_input_is_refused() {
    let dir = scratch("tilt");
    let log = dir.join("imu.mcap");
    log_at(&log);
    let before = std::fs::read(&log).unwrap();
    let l = log.to_str().unwrap();
    assert_refused(&stabilis(&["tilt", "--data", l, "--out", l]), "imu.mcap");
    // Also by another spelling of the same path.
    let other = dir.join(".").join("imu.mcap");
    let run = stabilis(&["tilt", "--data", l, "--out", other.to_str().unwrap()]);
    assert_refused(&run, "imu.mcap");
    assert_eq!(std::fs::read(&log).unwrap(), before);
}

#[test]
fn outputs_never_replace_a_file_of_another_kind() {
    let dir = scratch("kinds");
    let csv = dir.join("data.csv");
    std::fs::write(&csv, "t,x\n0,1\n").unwrap();
    let c = csv.to_str().unwrap();
    let run = stabilis(&["sim", "wheel-pendulum", "--duration", "1", "--out", c]);
    assert_refused(&run, "data.csv");
    let run = stabilis(&["sim", "wheel-pendulum", "--duration", "1", "--json", c]);
    assert_eq!(run.status.code(), Some(2), "{}", text(&run.stderr));
    let json = dir.join("notes.json");
    std::fs::write(&json, "not json").unwrap();
    let j = json.to_str().unwrap();
    let run = stabilis(&["sim", "wheel-pendulum", "--duration", "1", "--json", j]);
    assert_refused(&run, "notes.json");
    assert_eq!(std::fs::read_to_string(&csv).unwrap(), "t,x\n0,1\n");
    assert_eq!(std::fs::read_to_string(&json).unwrap(), "not json");
    // A log replaces a log, and JSON replaces JSON.
    let log = dir.join("run.mcap");
    log_at(&log);
    log_at(&log);
    let out = dir.join("out.json");
    let o = out.to_str().unwrap();
    for _ in 0..2 {
        let run = stabilis(&["sim", "wheel-pendulum", "--duration", "1", "--json", o]);
        assert_eq!(run.status.code(), Some(0), "{}", text(&run.stderr));
    }
    assert!(serde_json::from_slice::<serde_json::Value>(&std::fs::read(&out).unwrap()).is_ok());
    // ...but only its own: a user's JSON and a log another program wrote are kept.
    let config = dir.join("config.json");
    std::fs::write(&config, "{\"gain\": 3}\n").unwrap();
    let sim_to = |flag: &str, path: &std::path::Path| {
        stabilis(&[
            "sim",
            "wheel-pendulum",
            "--duration",
            "1",
            flag,
            path.to_str().unwrap(),
        ])
    };
    assert_refused(&sim_to("--json", &config), "config.json");
    assert_eq!(std::fs::read_to_string(&config).unwrap(), "{\"gain\": 3}\n");
    let rig = dir.join("rig.mcap");
    let mut header = b"\x89MCAP0\r\n\x01".to_vec();
    let library = b"mcap-python 1.1";
    header.extend_from_slice(&(8 + library.len() as u64).to_le_bytes());
    header.extend_from_slice(&0u32.to_le_bytes());
    header.extend_from_slice(&(library.len() as u32).to_le_bytes());
    header.extend_from_slice(library);
    std::fs::write(&rig, &header).unwrap();
    assert_refused(&sim_to("--out", &rig), "rig.mcap");
    assert_eq!(std::fs::read(&rig).unwrap(), header);
}

/// Starts `args`, waits `seconds`, kills it and waits for it.
fn kill_after(args: &[&str], seconds: f64) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_stabilis"))
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    std::thread::sleep(std::time::Duration::from_secs_f64(seconds));
    child.kill().unwrap();
    child.wait().unwrap();
}

#[test]
fn a_killed_run_leaves_the_previous_log_as_it_was() {
    let dir = scratch("killed");
    let log = dir.join("run.mcap");
    log_at(&log);
    let before = std::fs::read(&log).unwrap();
    let l = log.to_str().unwrap();
    kill_after(&["sim", "cubli", "--duration", "20000", "--out", l], 1.5);
    assert_eq!(std::fs::read(&log).unwrap(), before);
    // What the killed run wrote is beside it, readable up to its last flushed chunk.
    let partial: Vec<_> = snapshot(&dir)
        .into_iter()
        .filter(|(p, _)| {
            p.file_name()
                .unwrap()
                .to_string_lossy()
                .starts_with(".run.mcap.tmp-")
        })
        .collect();
    assert_eq!(partial.len(), 1);
    let read = sim::log::read_mcap(&partial[0].0).unwrap();
    assert!(!read.complete && read.problem.is_some());
    // A platoon killed during its synthesis leaves no file at the target at all.
    let platoon = dir.join("platoon.mcap");
    let p = platoon.to_str().unwrap();
    kill_after(&["sim", "platoon", "--vehicles", "10", "--out", p], 0.5);
    assert!(!platoon.exists());
}

#[test]
fn sizes_beyond_the_machine_are_refused_by_name() {
    for (args, name) in [
        (&["sim", "cubli", "--duration", "1e9"][..], "duration"),
        (&["sim", "platoon", "--vehicles", "100000"][..], "vehicles"),
        (&["sim", "platoon", "--vehicles", "5000"][..], "vehicles"),
        (
            &["sim", "wheel-pendulum", "--duration", "1e12"][..],
            "duration",
        ),
        (
            &[
                "sim",
                "flying-platform",
                "--scenario",
                "sysid",
                "--periods",
                "100000000",
            ][..],
            "periods",
        ),
        (
            &["sim", "flying-platform", "--duration", "1e10"][..],
            "duration",
        ),
    ] {
        let started = std::time::Instant::now();
        let run = stabilis(args);
        let stderr = text(&run.stderr);
        assert_eq!(run.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(
            stderr.contains(&format!("invalid {name} = ")) && stderr.contains("bytes"),
            "{args:?}: {stderr}"
        );
        assert!(started.elapsed().as_secs_f64() < 5.0, "{args:?} took long");
    }
}

#[test]
fn bad_numbers_are_named() {
    for (args, expect) in [
        (
            &["sim", "cubli", "--duration", "-1"][..],
            "invalid duration = -1",
        ),
        (
            &["sim", "cubli", "--excitation-rms=-1"][..],
            "invalid excitation-rms = -1",
        ),
        (
            &["sim", "cubli", "--excitation-rms", "-1"][..],
            "invalid excitation-rms = -1",
        ),
        (
            &[
                "sim",
                "flying-platform",
                "--duration",
                "2",
                "--log-delay-samples",
                "1000000",
            ][..],
            "log_delay_samples",
        ),
        (&["sim", "platoon", "--condition", "cor99"][..], "\"cor99\""),
        (&["sim", "platoon", "--solver", "magic"][..], "\"magic\""),
    ] {
        let run = stabilis(args);
        let stderr = text(&run.stderr);
        assert_eq!(run.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(stderr.contains(expect), "{args:?}: {stderr}");
        assert!(!stderr.contains("NaN"), "{args:?}: {stderr}");
    }
}

#[test]
fn a_closed_pipe_ends_the_program_quietly() {
    let dir = scratch("pipe");
    let log = dir.join("run.mcap");
    log_at(&log);
    for args in [
        &["info", log.to_str().unwrap()][..],
        &["info", "--json", "-", log.to_str().unwrap()][..],
    ] {
        let mut child = Command::new(env!("CARGO_BIN_EXE_stabilis"))
            .args(args)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        drop(child.stdout.take());
        let out = child.wait_with_output().unwrap();
        let stderr = text(&out.stderr);
        assert_eq!(out.status.code(), Some(0), "{args:?}: {stderr}");
        assert!(!stderr.contains("panicked"), "{stderr}");
    }
}

/// Rewrites `log` with `edit` applied to each `(t, values)` of every topic and the experiment
/// record changed by `meta`.
fn rewrite(
    log: &Path,
    out: &Path,
    edit: impl Fn(usize, f64) -> f64,
    meta: impl Fn(&mut std::collections::BTreeMap<String, String>),
) {
    let read = sim::log::read_mcap(log).unwrap();
    let mut w = sim::log::LogWriter::create(out).unwrap();
    for (name, record) in &read.metadata {
        let mut record = record.clone();
        if name == "experiment" {
            meta(&mut record);
        }
        w.write_metadata(name, record).unwrap();
    }
    for (name, table) in &read.topics {
        let id = w.add_topic(name, &table.fields).unwrap();
        for k in 0..table.len() {
            let values: Vec<f64> = table.columns.iter().map(|c| c[k]).collect();
            w.write(id, edit(k, table.t[k]), &values).unwrap();
        }
    }
    w.finish().unwrap();
}

/// A flying-platform hover log of `duration` seconds written into `dir`.
fn hover_log(dir: &Path, duration: f64) -> PathBuf {
    let run = stabilis(&[
        "sim",
        "flying-platform",
        "--duration",
        &duration.to_string(),
        "--out",
        dir.to_str().unwrap(),
    ]);
    assert_eq!(run.status.code(), Some(0), "{}", text(&run.stderr));
    dir.join("flying_platform_hover.mcap")
}

#[test]
fn workbench_logs_with_uneven_time_or_a_wrong_rate_or_given_twice_are_refused() {
    let dir = scratch("time");
    let fp = dir.join("fp");
    let good = hover_log(&fp, 20.0);
    let g = good.to_str().unwrap();
    // The same log twice, by two spellings.
    let again = fp.join(".").join("flying_platform_hover.mcap");
    let run = stabilis(&["compare", "--data", g, again.to_str().unwrap()]);
    let stderr = text(&run.stderr);
    assert_eq!(run.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("is the same log as"), "{stderr}");
    // sample_rate_hz = 1000 on a 50 Hz log.
    let wrong_rate = dir.join("rate.mcap");
    rewrite(
        &good,
        &wrong_rate,
        |_, t| t,
        |m| {
            m.insert("sample_rate_hz".into(), "1000".into());
        },
    );
    let run = stabilis(&["compare", "--data", wrong_rate.to_str().unwrap()]);
    let stderr = text(&run.stderr);
    assert_eq!(run.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("sample_rate_hz") && stderr.contains("50"),
        "{stderr}"
    );
    // One sample time moved by half a step.
    let uneven = dir.join("uneven.mcap");
    rewrite(
        &good,
        &uneven,
        |k, t| if k == 100 { t + 0.01 } else { t },
        |_| {},
    );
    let run = stabilis(&["compare", "--data", uneven.to_str().unwrap()]);
    let stderr = text(&run.stderr);
    assert_eq!(run.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("uneven sampling"), "{stderr}");
}

#[test]
fn a_cut_off_log_is_read_with_a_warning() {
    let dir = scratch("cut");
    let bytes = std::fs::read(hover_log(&dir.join("fp"), 30.0)).unwrap();
    let cut = dir.join("cut.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() * 3 / 4]).unwrap();
    let run = stabilis(&["compare", "--data", cut.to_str().unwrap()]);
    let stderr = text(&run.stderr);
    assert!(
        stderr.contains("warning:") && stderr.contains("incomplete"),
        "{stderr}"
    );
}
