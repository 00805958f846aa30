//! Round trips through the writer and readers, logs cut off in three ways, and the named errors.
use std::collections::BTreeMap;
use std::path::PathBuf;

use proptest::prelude::*;

use super::*;
use crate::error::SimError;

/// A directory of the test's own, removed with its files when dropped.
fn scratch() -> tempfile::TempDir {
    tempfile::Builder::new()
        .prefix("workbench-log-tests-")
        .tempdir()
        .unwrap()
}

/// Writes `n` messages of a ramp on one topic (x = 2 t, v = -t) and returns the writer unfinished.
fn ramp(path: &std::path::Path, n: usize, flush_every: usize) -> LogWriter {
    let mut log = LogWriter::with_flush_every(path, &[], flush_every).unwrap();
    log.write_metadata(EXPERIMENT, Experiment::new(100.0).to_metadata())
        .unwrap();
    let topic = log.add_topic("/demo/output", &["x", "v"]).unwrap();
    for k in 0..n {
        let t = k as f64 / 100.0;
        log.write(topic, t, &[2.0 * t, -t]).unwrap();
    }
    log
}

fn check_ramp(log: &Log, n: usize) {
    let table = log.topic("/demo/output").unwrap();
    assert_eq!(table.len(), n);
    for (k, ((t, x), v)) in table
        .t
        .iter()
        .zip(table.column("x").unwrap())
        .zip(table.column("v").unwrap())
        .enumerate()
    {
        assert_eq!(*t, k as f64 / 100.0);
        assert_eq!((*x, *v), (2.0 * t, -t));
    }
}

#[test]
fn finished_log_reads_back_with_metadata() {
    let dir = scratch();
    let path = dir.path().join("finished.mcap");
    ramp(&path, 300, DEFAULT_FLUSH_EVERY).finish().unwrap();
    let log = read_mcap(&path).unwrap();
    assert!(log.complete && log.problem.is_none());
    check_ramp(&log, 300);
    assert_eq!(log.experiment().unwrap()["sample_rate_hz"], "100");
    assert_eq!(log.topic("/demo/output").unwrap().fields, ["x", "v"]);
}

/// The temporary file a writer of `path` fills before renaming it onto `path`.
fn temporary(path: &std::path::Path) -> PathBuf {
    let name = path.file_name().unwrap().to_string_lossy();
    path.with_file_name(format!(".{name}.tmp-{}", std::process::id()))
}

#[test]
fn dropped_writer_keeps_the_previous_log_and_leaves_no_temporary() {
    let dir = scratch();
    let path = dir.path().join("dropped.mcap");
    ramp(&path, 5, DEFAULT_FLUSH_EVERY).finish().unwrap();
    drop(ramp(&path, 250, DEFAULT_FLUSH_EVERY));
    check_ramp(&read_mcap(&path).unwrap(), 5);
    assert!(!temporary(&path).exists());
}

#[test]
fn panic_while_writing_keeps_the_previous_log() {
    let dir = scratch();
    let path = dir.path().join("panicked.mcap");
    ramp(&path, 7, DEFAULT_FLUSH_EVERY).finish().unwrap();
    let moved = path.clone();
    let result = std::panic::catch_unwind(move || {
        let _log = ramp(&moved, 120, DEFAULT_FLUSH_EVERY);
        panic!("simulated failure in the middle of a run");
    });
    assert!(result.is_err());
    let log = read_mcap(&path).unwrap();
    assert!(log.complete);
    check_ramp(&log, 7);
    assert!(!temporary(&path).exists());
}

#[test]
fn killed_writer_keeps_the_previous_log_and_leaves_every_flushed_chunk_beside_it() {
    // Forgetting the writer skips every destructor, as a killed process would: buffered bytes
    // are lost, chunks already flushed must still read from the temporary file, and the log
    // at the target is the previous one.
    let dir = scratch();
    let path = dir.path().join("killed.mcap");
    ramp(&path, 3, DEFAULT_FLUSH_EVERY).finish().unwrap();
    std::mem::forget(ramp(&path, 1050, 100));
    check_ramp(&read_mcap(&path).unwrap(), 3);
    let partial = temporary(&path);
    let log = read_mcap(&partial).unwrap();
    assert!(!log.complete);
    assert!(log.problem.is_some());
    let n = log.topic("/demo/output").unwrap().len();
    assert!((1000..=1050).contains(&n), "read {n} messages");
    check_ramp(&log, n);
    assert_eq!(log.experiment().unwrap()["sample_rate_hz"], "100");
    std::fs::remove_file(partial).unwrap();
}

#[test]
fn writer_refuses_to_replace_a_file_that_is_not_a_log() {
    let dir = scratch();
    let path = dir.path().join("notes.mcap");
    std::fs::write(&path, "my notes").unwrap();
    let err = LogWriter::create(&path).unwrap_err();
    assert!(matches!(err, SimError::UnsafeOutput { .. }), "{err}");
    assert_eq!(err.exit_code(), 2);
    assert_eq!(std::fs::read_to_string(&path).unwrap(), "my notes");
    let log = dir.path().join("input.mcap");
    ramp(&log, 2, DEFAULT_FLUSH_EVERY).finish().unwrap();
    let err = LogWriter::create_for(&log, std::slice::from_ref(&log)).unwrap_err();
    assert!(err.to_string().contains("is an input"), "{err}");
    check_ramp(&read_mcap(&log).unwrap(), 2);
}

#[test]
fn missing_file_wrong_format_and_missing_topic_are_named() {
    let dir = scratch();
    let err = read_mcap(dir.path().join("absent.mcap")).unwrap_err();
    assert!(matches!(err, SimError::FileNotFound { .. }));
    assert!(err.to_string().starts_with("file not found: "), "{err}");

    let text = dir.path().join("text.mcap");
    std::fs::write(&text, "t,x\n0,1\n").unwrap();
    let err = read_mcap(&text).unwrap_err();
    assert!(err.to_string().contains("not an MCAP file"), "{err}");
    std::fs::write(&text, "").unwrap();
    assert!(matches!(
        read_mcap(&text).unwrap_err(),
        SimError::NotMcap { .. }
    ));

    let path = dir.path().join("topics.mcap");
    ramp(&path, 3, DEFAULT_FLUSH_EVERY).finish().unwrap();
    let err = read_mcap(&path).unwrap().topic("/demo/input").unwrap_err();
    assert!(
        err.to_string()
            .starts_with("missing channel \"/demo/input\"")
            && err.to_string().ends_with("available: /demo/output"),
        "{err}"
    );
    let log = read_mcap(&path).unwrap();
    let err = log.topic("/demo/output").unwrap().column("a").unwrap_err();
    assert_eq!(
        err.to_string(),
        "missing field \"a\" in /demo/output; available: x, v"
    );
}

#[test]
fn writer_refuses_bad_messages() {
    let dir = scratch();
    let mut log = LogWriter::create(dir.path().join("refused.mcap")).unwrap();
    let topic = log.add_topic("/demo/output", &["x", "v"]).unwrap();
    let err = log.write(topic, 0.0, &[1.0, f64::NAN]).unwrap_err();
    assert!(err.to_string().contains("field \"v\""), "{err}");
    let err = log.write(topic, 0.0, &[1.0]).unwrap_err();
    assert!(matches!(
        err,
        SimError::LengthMismatch {
            expected: 2,
            found: 1,
            ..
        }
    ));
    assert!(log.write(topic, -1.0, &[1.0, 2.0]).is_err());
    assert!(log.add_topic("/demo/output", &["y"]).is_err());
    assert!(log.add_topic("/demo/other", &["t"]).is_err());
    assert!(log.add_topic("/demo/other", &["y", "y"]).is_err());
}

/// Writes raw JSON messages with the mcap crate, as another tool might, to `name` in `dir`.
fn raw_log(dir: &std::path::Path, name: &str, schema: &str, messages: &[&str]) -> PathBuf {
    let path = dir.join(name);
    let mut writer = mcap::Writer::new(std::io::BufWriter::new(
        std::fs::File::create(&path).unwrap(),
    ))
    .unwrap();
    let schema = writer
        .add_schema("demo", "jsonschema", schema.as_bytes())
        .unwrap();
    let channel = writer
        .add_channel(schema, "/raw", "json", &BTreeMap::new())
        .unwrap();
    for (k, message) in messages.iter().enumerate() {
        let header = mcap::records::MessageHeader {
            channel_id: channel,
            sequence: k as u32,
            log_time: k as u64,
            publish_time: k as u64,
        };
        writer
            .write_to_known_channel(&header, message.as_bytes())
            .unwrap();
    }
    writer.finish().unwrap();
    path
}

/// An MCAP file written with the MCAP library directly: one schemaless JSON channel `topic`,
/// `messages` as `(log_time, JSON)`, the header naming `library`.
fn stamped_log(path: &std::path::Path, library: &str, topic: &str, messages: &[(u64, String)]) {
    let file = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    let mut w = mcap::WriteOptions::new()
        .library(library)
        .create(file)
        .unwrap();
    let channel = w.add_channel(0, topic, "json", &BTreeMap::new()).unwrap();
    for (k, (log_time, data)) in messages.iter().enumerate() {
        let header = mcap::records::MessageHeader {
            channel_id: channel,
            sequence: k as u32,
            log_time: *log_time,
            publish_time: *log_time,
        };
        w.write_to_known_channel(&header, data.as_bytes()).unwrap();
    }
    w.finish().unwrap();
}

const SCHEMA: &str = r#"{"type":"object","properties":{"t":{"type":"number"},"b":{"type":"number"},"a":{"type":"number"},"label":{"type":"string"}}}"#;

#[test]
fn foreign_logs_read_by_schema_and_bad_values_are_named() {
    let dir = scratch();
    let path = raw_log(
        dir.path(),
        "foreign.mcap",
        SCHEMA,
        &[
            r#"{"t":0,"a":1,"b":2,"label":"x"}"#,
            r#"{"t":0.5,"a":3,"b":4,"label":"y"}"#,
        ],
    );
    let log = read_mcap(&path).unwrap();
    let table = log.topic("/raw").unwrap();
    // Without `required`, number properties come in name order; strings are skipped.
    assert_eq!(table.fields, ["a", "b"]);
    assert_eq!(table.column("b").unwrap(), &[2.0, 4.0]);
    assert_eq!(table.t, [0.0, 0.5]);

    let path = raw_log(
        dir.path(),
        "missing-field.mcap",
        SCHEMA,
        &[r#"{"t":0,"a":1}"#],
    );
    let err = read_mcap(&path).unwrap_err();
    assert!(
        err.to_string()
            .starts_with("missing field \"b\" in /raw at t = 0"),
        "{err}"
    );

    let path = raw_log(
        dir.path(),
        "null.mcap",
        SCHEMA,
        &[r#"{"t":0,"a":null,"b":1}"#],
    );
    let err = read_mcap(&path).unwrap_err();
    assert_eq!(
        err.to_string(),
        "field \"a\" in /raw at t = 0 is not a finite number: null"
    );

    // A topic whose first message has `t` needs it in every message.
    let path = raw_log(
        dir.path(),
        "no-t-later.mcap",
        SCHEMA,
        &[r#"{"t":0,"a":1,"b":1}"#, r#"{"a":1,"b":1}"#],
    );
    let err = read_mcap(&path).unwrap_err();
    assert!(
        err.to_string().starts_with(
            "missing field \"t\" in /raw message 1 (the topic's first message has one)"
        ),
        "{err}"
    );

    let path = raw_log(dir.path(), "not-json.mcap", SCHEMA, &["[1, 2]"]);
    let err = read_mcap(&path).unwrap_err();
    assert!(
        err.to_string()
            .starts_with("bad message in /raw message 0: not a JSON object"),
        "{err}"
    );

    // No usable schema: the fields are the numbers of the first message.
    let path = raw_log(
        dir.path(),
        "schemaless.mcap",
        "{}",
        &[r#"{"t":1,"z":5,"y":6}"#],
    );
    let table = read_mcap(&path).unwrap().topic("/raw").unwrap().clone();
    assert_eq!(table.fields, ["y", "z"]);
}

#[test]
fn csv_reads_into_the_same_table() {
    let dir = scratch();
    let path = dir.path().join("good.csv");
    std::fs::write(&path, "x, t ,v\n1,0,2\n3,0.5,4\n").unwrap();
    let table = read_csv(&path).unwrap();
    assert_eq!(table.fields, ["x", "v"]);
    assert_eq!(table.t, [0.0, 0.5]);
    assert_eq!(table.column("v").unwrap(), &[2.0, 4.0]);
}

/// Semicolon- and tab-separated files, comment lines before the header and Windows line ends
/// read as the comma-separated file does.
#[test]
fn csv_delimiters_comments_and_line_ends_read_alike() {
    let dir = scratch();
    let comma = dir.path().join("comma.csv");
    std::fs::write(&comma, "t,x,v\n0,1.5,2\n0.5,-3,4e-3\n").unwrap();
    let want = read_csv(&comma).unwrap();
    for (name, text) in [
        ("semicolon.csv", "t;x;v\n0;1.5;2\n0.5;-3;4e-3\n"),
        ("tab.csv", "t\tx\tv\n0\t1.5\t2\n0.5\t-3\t4e-3\n"),
        (
            "comment.csv",
            "# rig 3, 2026-12-04\nt,x,v\n0,1.5,2\n# pause\n0.5,-3,4e-3\n",
        ),
        ("crlf.csv", "t,x,v\r\n0,1.5,2\r\n0.5,-3,4e-3\r\n"),
    ] {
        let path = dir.path().join(name);
        std::fs::write(&path, text).unwrap();
        let table = read_csv(&path).unwrap();
        assert_eq!(table.fields, want.fields, "{name}");
        assert_eq!(table.t, want.t, "{name}");
        assert_eq!(
            table.column("v").unwrap(),
            want.column("v").unwrap(),
            "{name}"
        );
    }
}

#[test]
fn csv_errors_are_named() {
    let dir = scratch();
    let cases = [
        (
            "no-t.csv",
            "x,v\n1,2\n",
            "missing field \"t\" in header row of",
        ),
        ("nan.csv", "t,x\n0,1\n1,nan\n", "field \"x\" in"),
        (
            "word.csv",
            "t,x\n0,one\n",
            "line 2, column \"x\": \"one\" is not a number",
        ),
        // Windows line ends and a comment: the line is still the file's (it read "line 3").
        (
            "word-crlf.csv",
            "# rig 3\r\nt,x\r\n0,1\r\n0.1,one\r\n",
            "line 4, column \"x\": \"one\" is not a number",
        ),
        // A comment line before the bad row: the row's own line (it read "line 3").
        (
            "word-after-comment.csv",
            "t,x\n0,1\n# note\n0.1,one\n",
            "line 4, column \"x\": \"one\" is not a number",
        ),
        (
            "nan-crlf.csv",
            "t,x\r\n0,1\r\n1,nan\r\n",
            "nan-crlf.csv line 3",
        ),
        ("ragged.csv", "t,x\n0,1\n1\n", "bad CSV file"),
        // A time that does not increase is named by its line, past comments (sample 2 of 4).
        (
            "unordered.csv",
            "# rig 3\nt,x\n0,1\n# pause\n0.2,2\n0.1,3\n0.3,4\n",
            "line 6: t = 0.1 s does not increase (line 5 is at t = 0.2 s)",
        ),
        (
            "repeated-crlf.csv",
            "t,x\r\n0,1\r\n0.1,2\r\n0.1,2\r\n",
            "line 4: t = 0.1 s does not increase (line 3 is at t = 0.1 s)",
        ),
        ("empty.csv", " \n", "the file is empty"),
        (
            "decimal-comma.csv",
            "t;x\n0;1,5\n",
            "\"1,5\" is not a number (a decimal comma?",
        ),
    ];
    for (name, text, expected) in cases {
        let path = dir.path().join(name);
        std::fs::write(&path, text).unwrap();
        let err = read_csv(&path).unwrap_err();
        assert!(err.to_string().contains(expected), "{name}: {err}");
    }
    assert!(matches!(
        read_csv(dir.path().join("absent.csv")).unwrap_err(),
        SimError::FileNotFound { .. }
    ));
}

#[test]
fn experiment_periodic_keys_round_trip() {
    let experiment = Experiment {
        sample_rate_hz: 250.0,
        periodic: Some(Periodic {
            period_samples: 1024,
            periods: 8,
            transient_samples: 2048,
            excited: vec!["F1x".into(), "F2z".into()],
        }),
        extra: BTreeMap::from([("system".to_string(), "flying_platform".to_string())]),
    };
    let map = experiment.to_metadata();
    assert_eq!(map["excited"], "F1x,F2z");
    assert_eq!(Experiment::from_metadata(&map).unwrap(), experiment);
    let mut partial = map.clone();
    partial.remove("periods");
    let err = Experiment::from_metadata(&partial).unwrap_err();
    assert!(
        err.to_string().contains("missing field \"periods\""),
        "{err}"
    );
}

proptest! {
    /// Every finite f64 survives the JSON text of a message bit for bit.
    #[test]
    fn values_round_trip_exactly(values in proptest::collection::vec(proptest::num::f64::NORMAL | proptest::num::f64::SUBNORMAL | proptest::num::f64::ZERO, 1..40)) {
        let dir = scratch();
        let path = dir.path().join("prop.mcap");
        let mut log = LogWriter::create(&path).unwrap();
        let topic = log.add_topic("/p/q", &["value"]).unwrap();
        for (k, v) in values.iter().enumerate() {
            log.write(topic, k as f64 * 0.001, &[*v]).unwrap();
        }
        log.finish().unwrap();
        let read = read_mcap(&path).unwrap();
        let column = read.topic("/p/q").unwrap().column("value").unwrap().to_vec();
        prop_assert_eq!(column.iter().map(|v| v.to_bits()).collect::<Vec<_>>(), values.iter().map(|v| v.to_bits()).collect::<Vec<_>>());
    }

    /// Whatever order a file holds a topic's samples in (written over several chunks), they are
    /// read in time order, each time with its own values.
    #[test]
    fn samples_in_any_order_read_in_time_order(order in Just((0..40).collect::<Vec<usize>>()).prop_shuffle()) {
        let dir = scratch();
        let path = dir.path().join("shuffled.mcap");
        let mut log = LogWriter::with_flush_every(&path, &[], 7).unwrap();
        let topic = log.add_topic("/p/q", &["k", "x"]).unwrap();
        for &k in &order {
            log.write(topic, k as f64 * 0.001, &[k as f64, (k as f64).sin()]).unwrap();
        }
        log.finish().unwrap();
        let read = read_mcap(&path).unwrap();
        let table = read.topic("/p/q").unwrap();
        prop_assert_eq!(table.column("k").unwrap(), &(0..40).map(|k| k as f64).collect::<Vec<_>>()[..]);
        prop_assert_eq!(table.column("x").unwrap(), &(0..40).map(|k| (k as f64).sin()).collect::<Vec<_>>()[..]);
        prop_assert!(table.t.windows(2).all(|w| w[0] < w[1]));
        let sorted = order.windows(2).all(|w| w[0] < w[1]);
        prop_assert_eq!(read.reordered.is_empty(), sorted);
    }
}

#[test]
fn tables_check_their_lengths() {
    let err = Table::from_columns("/demo/x", vec![0.0, 1.0], vec!["a".into()], vec![vec![1.0]])
        .unwrap_err();
    assert_eq!(
        err.to_string(),
        "length mismatch for column \"a\" of /demo/x: expected 2, found 1"
    );
    let err = Table::from_columns(
        "/demo/x",
        vec![0.0],
        vec!["a".into(), "b".into()],
        vec![vec![1.0]],
    )
    .unwrap_err();
    assert!(matches!(
        err,
        SimError::LengthMismatch {
            expected: 2,
            found: 1,
            ..
        }
    ));
    let mut table = Table::new("/demo/x", ["a"]);
    assert!(table.push(0.0, &[1.0, 2.0]).is_err());
    assert!(table.is_empty() && table.span().is_none());
}

/// Offsets of the chunk records of an MCAP file (after the magic, top-level records only).
fn chunk_offsets(bytes: &[u8]) -> Vec<usize> {
    let mut out = Vec::new();
    let mut at = 8;
    while at + 9 <= bytes.len() && bytes[at] != 0x0F {
        if bytes[at] == 0x06 {
            out.push(at);
        }
        at += 9 + u64::from_le_bytes(bytes[at + 1..at + 9].try_into().unwrap()) as usize;
    }
    out
}

#[test]
fn a_flipped_bit_in_compressed_data_fails_the_chunk_crc() {
    let dir = scratch();
    let path = dir.path().join("crc.mcap");
    ramp(&path, 1200, 200).finish().unwrap();
    let bytes = std::fs::read(&path).unwrap();
    let chunk = chunk_offsets(&bytes)[2];
    let compression_len =
        u32::from_le_bytes(bytes[chunk + 37..chunk + 41].try_into().unwrap()) as usize;
    let compressed_size = u64::from_le_bytes(
        bytes[chunk + 41 + compression_len..chunk + 49 + compression_len]
            .try_into()
            .unwrap(),
    ) as usize;
    let data = chunk + 49 + compression_len;
    // Every bit of the compressed records: refused by the chunk CRC (or zstd's own check), or,
    // for the few bits the decompressor ignores, read as exactly the log that was written.
    let original = read_mcap_bytes(&path, &bytes).unwrap();
    let (mut crc_errors, mut other_errors, mut unchanged) = (0, 0, 0);
    for at in data..data + compressed_size {
        for bit in 0..8 {
            let mut flipped = bytes.clone();
            flipped[at] ^= 1 << bit;
            match read_mcap_bytes(&path, &flipped) {
                Err(err @ SimError::Mcap { .. }) if err.to_string().contains("CRC") => {
                    crc_errors += 1
                }
                Err(SimError::Mcap { .. }) => other_errors += 1,
                Err(err) => panic!("byte {at} bit {bit}: {err}"),
                Ok(log) => {
                    assert!(log == original, "byte {at} bit {bit}: different numbers");
                    unchanged += 1;
                }
            }
        }
    }
    assert!(
        crc_errors > 0 && unchanged < crc_errors + other_errors,
        "{crc_errors} CRC errors, {other_errors} other errors, {unchanged} unchanged"
    );
}

#[test]
fn a_corrupt_chunk_size_is_an_error_before_any_allocation() {
    let dir = scratch();
    let path = dir.path().join("size.mcap");
    ramp(&path, 1200, 200).finish().unwrap();
    let bytes = std::fs::read(&path).unwrap();
    let chunk = chunk_offsets(&bytes)[1];
    // uncompressed_size: 3.7e18 bytes, the size that aborted the process.
    let mut huge = bytes.clone();
    huge[chunk + 25..chunk + 33].copy_from_slice(&3_700_000_000_000_000_000u64.to_le_bytes());
    let err = read_mcap_bytes(&path, &huge).unwrap_err();
    assert!(matches!(err, SimError::Mcap { .. }), "{err}");
    // A record length beyond the file: refused, or read as a file cut off there.
    let mut long = bytes.clone();
    long[chunk + 1..chunk + 9].copy_from_slice(&(u64::MAX / 2).to_le_bytes());
    match read_mcap_bytes(&path, &long) {
        Err(err) => assert!(matches!(err, SimError::Mcap { .. }), "{err}"),
        Ok(log) => assert!(log.problem.is_some() && !log.complete),
    }
}

/// Writes one topic's messages at `times` in that order, x = 10 t.
fn written_in_order(path: &std::path::Path, times: &[f64]) -> crate::error::Result<Log> {
    let mut log = LogWriter::create(path).unwrap();
    let topic = log.add_topic("/demo/output", &["x"]).unwrap();
    for &t in times {
        log.write(topic, t, &[10.0 * t]).unwrap();
    }
    log.finish().unwrap();
    read_mcap(path)
}

/// Messages out of time order (chunks written out of order) are read in time order and the
/// topic is named; two messages at one time are an error naming both.
#[test]
fn messages_out_of_time_order_are_put_back_or_named() {
    let dir = scratch();
    let path = dir.path().join("order.mcap");
    for times in [
        &[0.03, 0.04, 0.0, 0.01, 0.02, 0.05][..],
        &[0.0, 0.02, 0.01, 0.03, 0.04, 0.05],
        &[0.05, 0.04, 0.03, 0.02, 0.01, 0.0],
    ] {
        let log = written_in_order(&path, times).unwrap();
        let table = log.topic("/demo/output").unwrap();
        assert_eq!(table.t, [0.0, 0.01, 0.02, 0.03, 0.04, 0.05]);
        assert_eq!(table.column("x").unwrap(), &[0.0, 0.1, 0.2, 0.3, 0.4, 0.5]);
        assert_eq!(log.reordered, ["/demo/output"]);
    }
    let log = written_in_order(&path, &[0.0, 0.01, 0.02]).unwrap();
    assert!(log.reordered.is_empty());
    for (times, named) in [
        (
            &[0.0, 0.01, 0.01][..],
            "messages 1 and 2 are both at t = 0.01 s",
        ),
        (
            &[0.02, 0.0, 0.01, 0.02],
            "messages 0 and 3 are both at t = 0.02 s",
        ),
    ] {
        let err = written_in_order(&path, times).unwrap_err().to_string();
        assert!(
            err.contains("/demo/output") && err.contains(named),
            "{times:?}: {err}"
        );
    }
}

#[test]
fn times_off_their_log_time_are_named_errors() {
    let dir = scratch();

    // t against log_time in a log that says stabilis wrote it, written with the MCAP library
    // directly: a constant offset (a rebased log) is fine, a message whose t disagrees is not.
    let write = |path: &std::path::Path, stamps: &[(f64, u64)]| {
        let messages: Vec<(u64, String)> = stamps
            .iter()
            .map(|(t, log_time)| (*log_time, format!("{{\"t\":{t},\"x\":1}}")))
            .collect();
        stamped_log(path, "stabilis (test)", "/demo/output", &messages);
    };
    let epoch = 1_700_000_000_000_000_000u64;
    let wall = dir.path().join("wall.mcap");
    write(&wall, &[(0.0, epoch), (0.5, epoch + 500_000_000)]);
    assert_eq!(
        read_mcap(&wall)
            .unwrap()
            .topic("/demo/output")
            .unwrap()
            .len(),
        2
    );
    let off = dir.path().join("off.mcap");
    write(&off, &[(0.0, epoch), (0.5, epoch + 900_000_000)]);
    let err = read_mcap(&off).unwrap_err().to_string();
    assert!(err.contains("log_time"), "{err}");
}

#[test]
fn a_csv_with_a_repeated_column_is_refused() {
    let dir = scratch();
    let path = dir.path().join("twice.csv");
    std::fs::write(&path, "t,x,x\n0,1,2\n").unwrap();
    let err = read_csv(&path).unwrap_err().to_string();
    assert!(err.contains("\"x\" appears twice"), "{err}");
}

#[test]
fn uneven_or_mislabelled_sampling_is_named() {
    let mut table = Table::new("/demo/x", ["a"]);
    for t in [0.0, 0.01, 0.02, 0.03] {
        table.push(t, &[1.0]).unwrap();
    }
    let file = std::path::Path::new("run.mcap");
    assert!((table.sample_rate(None, file).unwrap().0 - 100.0).abs() < 1e-9);
    assert_eq!(table.sample_rate(Some(100.0), file).unwrap(), (100.0, None));
    let err = table
        .sample_rate(Some(1000.0), file)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("sample_rate_hz") && err.contains("100.000000 Hz"),
        "{err}"
    );
    table.t[2] = 0.025;
    let err = table.sample_rate(None, file).unwrap_err().to_string();
    assert!(
        err.contains("uneven sampling") && err.contains("run.mcap"),
        "{err}"
    );
}

/// A 100 Hz clock whose samples were stamped late by up to 15 % of a period (uniform, three
/// seeds): the rate is the clock's to 1e-6 relative, the stamps are reported as jitter, and a
/// sample dropped or inserted anywhere in such a record is still refused as uneven sampling,
/// as is a clock that changes rate by 3 % halfway (each step within the jitter's reach, the
/// stamps 0.75 s off the grid at the end).
#[test]
fn jittered_stamps_of_a_regular_clock_are_read_and_dropped_samples_are_not() {
    use rand::{Rng, SeedableRng};
    let file = std::path::Path::new("run.csv");
    for seed in 1..=3 {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let stamps: Vec<f64> = (0..5000)
            .map(|k| 12.0 + k as f64 * 0.01 + rng.random_range(0.0..0.0015))
            .collect();
        let table = |keep: &dyn Fn(usize) -> bool, insert: Option<usize>| {
            let mut table = Table::new("/demo/x", ["a"]);
            for (k, &t) in stamps.iter().enumerate().filter(|(k, _)| keep(*k)) {
                table.push(t, &[1.0]).unwrap();
                if insert == Some(k) {
                    table.push(0.5 * (t + stamps[k + 1]), &[1.0]).unwrap();
                }
            }
            table
        };
        let (rate, jitter) = table(&|_| true, None).sample_rate(None, file).unwrap();
        assert!((rate - 100.0).abs() < 1e-4, "seed {seed}: {rate}");
        let mut drifting = Table::new("/demo/x", ["a"]);
        for (k, &t) in stamps.iter().enumerate() {
            let late = 0.03 * 0.01 * k.saturating_sub(2500) as f64;
            drifting.push(t + late, &[1.0]).unwrap();
        }
        let err = drifting.sample_rate(None, file).unwrap_err().to_string();
        assert!(
            err.contains("uneven sampling") && err.contains("from the regular grid"),
            "seed {seed}: {err}"
        );
        let jitter = jitter.expect("the stamps scatter by more than 1 % of a step");
        assert!(
            jitter.deviation > 5e-4 && jitter.deviation < 1.5e-3,
            "seed {seed}: {jitter:?}"
        );
        assert!(
            jitter.to_string().contains("taken as evenly spaced at"),
            "{jitter}"
        );
        for at in [1, 2500, 4998] {
            let err = table(&|k| k != at, None)
                .sample_rate(None, file)
                .unwrap_err()
                .to_string();
            assert!(
                err.contains("uneven sampling"),
                "seed {seed}, dropped {at}: {err}"
            );
            let err = table(&|_| true, Some(at))
                .sample_rate(None, file)
                .unwrap_err()
                .to_string();
            assert!(
                err.contains("uneven sampling"),
                "seed {seed}, inserted {at}: {err}"
            );
        }
    }
}

/// 100 samples missing in the middle of a 100 Hz record: the gap is named at its own sample
/// (judged against the mean step, which the gap raises, sample 1 was named).
#[test]
fn a_gap_is_named_where_it_is() {
    let mut table = Table::new("/demo/x", ["a"]);
    for k in (0..4000).chain(4100..9000) {
        table.push(k as f64 * 0.01, &[1.0]).unwrap();
    }
    let err = table
        .sample_rate(None, std::path::Path::new("run.csv"))
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("at sample 4000")
            && err.contains("step of 1.010000 s where the typical (median) step is 0.010000 s"),
        "{err}"
    );
}

#[test]
fn the_same_log_twice_is_refused() {
    let dir = scratch();
    let a = dir.path().join("once.mcap");
    ramp(&a, 3, DEFAULT_FLUSH_EVERY).finish().unwrap();
    let copy = dir.path().join("copy.mcap");
    std::fs::copy(&a, &copy).unwrap();
    let other = dir.path().join("other.mcap");
    ramp(&other, 4, DEFAULT_FLUSH_EVERY).finish().unwrap();
    assert!(refuse_repeats(&[a.clone(), other.clone()]).is_ok());
    for repeat in [
        a.clone(),
        a.parent().unwrap().join(".").join("once.mcap"),
        copy,
    ] {
        let err = refuse_repeats(&[a.clone(), other.clone(), repeat]).unwrap_err();
        assert!(err.to_string().contains("is the same log as"), "{err}");
    }
}

/// A recorder that stamps its messages but writes no `t` field: the topic's times are the
/// messages' `log_time` (wall clock, ns), the log lists the topic as such, and a stamp that
/// does not increase is named as a `log_time`.
#[test]
fn a_topic_without_t_takes_its_log_time() {
    let dir = scratch();
    let write = |name: &str, stamps: &[u64]| -> PathBuf {
        let path = dir.path().join(name);
        let messages: Vec<(u64, String)> = stamps
            .iter()
            .enumerate()
            .map(|(k, &log_time)| (log_time, format!("{{\"x\":{k}}}")))
            .collect();
        stamped_log(&path, "a recorder", "/rig/output", &messages);
        path
    };
    let epoch = 1_700_000_000_000_000_000u64;
    let stamps: Vec<u64> = (0..5).map(|k| epoch + k * 1_000_000).collect();
    let log = read_mcap(write("stamped.mcap", &stamps)).unwrap();
    assert_eq!(log.stamped_by_log_time, ["/rig/output"]);
    let table = log.topic("/rig/output").unwrap();
    assert_eq!(table.fields, ["x"]);
    for (t, &stamp) in table.t.iter().zip(&stamps) {
        assert_eq!(*t, (stamp - epoch) as f64 * 1e-9);
    }
    assert_eq!(table.column("x").unwrap(), &[0.0, 1.0, 2.0, 3.0, 4.0]);
    let (rate, jitter) = table
        .sample_rate(None, &dir.path().join("stamped.mcap"))
        .unwrap();
    assert!((rate - 1000.0).abs() < 1e-9, "{rate}");
    assert!(jitter.is_none());

    // Stamps in two runs that follow one another: in time order, counted from the earliest.
    let mut later_first = stamps[3..].to_vec();
    later_first.extend_from_slice(&stamps[..3]);
    let log = read_mcap(write("later_first.mcap", &later_first)).unwrap();
    let table = log.topic("/rig/output").unwrap();
    assert_eq!(log.reordered, ["/rig/output"]);
    for (t, &stamp) in table.t.iter().zip(&stamps) {
        assert!((*t - (stamp - epoch) as f64 * 1e-9).abs() < 1e-15, "{t}");
    }
    assert_eq!(table.column("x").unwrap(), &[2.0, 3.0, 4.0, 0.0, 1.0]);

    let mut again = stamps.clone();
    again[4] = again[2];
    let err = read_mcap(write("again.mcap", &again))
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("/rig/output")
            && err.contains("messages 2 and 4 are both at log_time = 0.002 s"),
        "{err}"
    );
}
