//! Damaged logs of every kind the simulator writes (truncated, bits flipped, chunks duplicated)
//! give the data or a named error: never a panic or an abort, never numbers that differ from
//! the log as written. Chunks written out of order, which MCAP allows, read as the original.
//! Fixed seed and a bounded number of mutations, so it runs in CI in a few seconds.
#![allow(clippy::unwrap_used)]
use std::path::Path;

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use sim::cli::SimSystem;
use sim::log::{read_mcap_bytes, Log};

const TRUNCATIONS: usize = 40;
const FLIPS: usize = 150;

/// One log per scenario of `stabilis sim`, short runs.
fn logs() -> Vec<(String, Vec<u8>)> {
    let dir = tempfile::Builder::new()
        .prefix("sim-mutations-")
        .tempdir()
        .unwrap();
    let runs: [(&str, &[&str]); 5] = [
        ("wheel-pendulum", &["--duration", "3"]),
        ("cubli", &["--duration", "5", "--excitation-rms", "0.01"]),
        ("quad-integrator", &["--duration", "100"]),
        ("platoon", &["--duration", "10"]),
        ("flying-platform", &["--duration", "12"]),
    ];
    runs.iter()
        .map(|(system, options)| {
            let out = dir.path().join(system);
            let out_arg = out.display().to_string();
            let mut args: Vec<&str> = options.to_vec();
            let file = if *system == "flying-platform" {
                args.extend(["--out", &out_arg]);
                out.join("flying_platform_hover.mcap")
            } else {
                args.extend(["--out", &out_arg]);
                out.clone()
            };
            SimSystem::parse_args(system, args).unwrap().run().unwrap();
            (system.to_string(), std::fs::read(file).unwrap())
        })
        .collect()
}

/// Top-level records after the magic: (offset, opcode, total length with opcode and length).
fn records(bytes: &[u8]) -> Vec<(usize, u8, usize)> {
    let mut out = Vec::new();
    let mut at = 8;
    while at + 9 <= bytes.len() {
        let opcode = bytes[at];
        let len = u64::from_le_bytes(bytes[at + 1..at + 9].try_into().unwrap()) as usize;
        out.push((at, opcode, 9 + len));
        if opcode == 0x0F {
            break; // data end
        }
        at += 9 + len;
    }
    out
}

const CHUNK: u8 = 0x06;

/// Reads `bytes` catching any panic, with `what` in the failure message.
fn read(bytes: &[u8], what: &str) -> sim::Result<Log> {
    std::panic::catch_unwind(|| read_mcap_bytes(Path::new("mutated.mcap"), bytes))
        .unwrap_or_else(|_| panic!("reader panicked on {what}"))
}

/// A log read from damaged bytes holds, per topic, a prefix of the original's samples (and
/// says why it stopped when it is shorter): the numbers are never altered.
fn assert_prefix(original: &Log, read: &Log, what: &str) {
    let mut shorter = false;
    for (name, table) in &read.topics {
        let full = original
            .topics
            .get(name)
            .unwrap_or_else(|| panic!("{what}: topic {name} was not in the log"));
        assert_eq!(table.fields, full.fields, "{what}: fields of {name}");
        let n = table.len();
        assert!(n <= full.len(), "{what}: {name} grew");
        shorter |= n < full.len();
        assert_eq!(table.t, full.t[..n], "{what}: t of {name} changed");
        for (column, full_column) in table.columns.iter().zip(&full.columns) {
            assert_eq!(column[..], full_column[..n], "{what}: values of {name}");
        }
    }
    shorter |= read.topics.len() < original.topics.len();
    if shorter {
        assert!(
            read.problem.is_some(),
            "{what}: shorter log without a warning"
        );
    }
}

#[test]
fn damaged_logs_give_their_data_or_a_named_error() {
    let mut rng = StdRng::seed_from_u64(13);
    let mut counts = [0usize; 2]; // read with the data, refused by name
    let mut swaps = [0usize; 2]; // read as the original, of all swaps
    for (system, bytes) in logs() {
        let original = read(&bytes, &system).unwrap();
        assert!(original.complete && original.problem.is_none(), "{system}");
        let mut check = |mutated: &[u8], what: String, must_fail: bool| match read(mutated, &what) {
            Ok(log) => {
                assert!(!must_fail, "{what}: accepted");
                assert_prefix(&original, &log, &what);
                counts[0] += 1;
            }
            Err(e) => {
                assert!(!e.to_string().is_empty());
                counts[1] += 1;
            }
        };
        for _ in 0..TRUNCATIONS {
            let n = rng.random_range(0..bytes.len());
            check(&bytes[..n], format!("{system} cut at {n}"), false);
        }
        for _ in 0..FLIPS {
            let mut mutated = bytes.clone();
            let at = rng.random_range(0..bytes.len());
            let bit = rng.random_range(0..8);
            mutated[at] ^= 1 << bit;
            check(&mutated, format!("{system} bit {bit} of byte {at}"), false);
        }
        let chunks: Vec<_> = records(&bytes)
            .into_iter()
            .filter(|r| r.1 == CHUNK)
            .collect();
        assert!(chunks.len() >= 3, "{system}: {} chunks", chunks.len());
        // A chunk with the index records after it, up to the next chunk.
        let starts: Vec<usize> = chunks.iter().map(|c| c.0).collect();
        // A repeated chunk repeats its times and is refused. A swapped pair is a file written
        // out of order: the original, unless the first chunk (declaring the channels) moves.
        let swaps_before = swaps[0];
        for k in 1..starts.len() {
            let (a, b) = (starts[k - 1], starts[k]);
            let mut repeated = bytes[..b].to_vec();
            repeated.extend_from_slice(&bytes[a..]);
            check(
                &repeated,
                format!("{system} chunk {} repeated", k - 1),
                true,
            );
            if let Some(&c) = starts.get(k + 1) {
                let mut swapped = bytes[..a].to_vec();
                swapped.extend_from_slice(&bytes[b..c]);
                swapped.extend_from_slice(&bytes[a..b]);
                swapped.extend_from_slice(&bytes[c..]);
                let what = format!("{system} chunks {} and {k} swapped", k - 1);
                swaps[1] += 1;
                match read(&swapped, &what) {
                    Ok(log) => {
                        assert_eq!(log.topics, original.topics, "{what}");
                        assert!(log.complete && !log.reordered.is_empty(), "{what}");
                        swaps[0] += 1;
                    }
                    Err(e) => {
                        assert!(k == 1, "{what}: {e}");
                        assert!(e.to_string().contains("never declared"), "{what}: {e}");
                    }
                }
            }
        }
        let swaps_read = swaps[0] - swaps_before;
        assert!(
            swaps_read >= 1 && swaps_read + 3 >= starts.len(),
            "{system}: {swaps_read} swaps read"
        );
    }
    println!(
        "mutated logs: {} read with their data, {} refused by name; {} of {} chunk swaps read \
         as the original",
        counts[0], counts[1], swaps[0], swaps[1]
    );
    assert!(counts[1] > 0 && counts[0] > 0);
}
