//! Running the `stabilis` binary from the end-to-end tests: one definition for every test file
//! (each file uses the part it needs).
#![allow(dead_code, clippy::unwrap_used)]
use std::path::Path;
use std::process::{Command, Output};

/// Runs the binary in the current directory.
pub fn stabilis(args: &[&str]) -> Output {
    stabilis_in(Path::new("."), args)
}

/// Runs the binary in `dir`.
pub fn stabilis_in(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_stabilis"))
        .args(args)
        .current_dir(dir)
        .output()
        .unwrap()
}

/// Bytes of stdout or stderr as text.
pub fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// Runs the binary, asserts exit code 0 and returns its stdout.
pub fn ok(args: &[&str]) -> String {
    let run = stabilis(args);
    assert_eq!(run.status.code(), Some(0), "{}", text(&run.stderr));
    text(&run.stdout)
}

/// Runs the binary, asserts exit code 2 (bad input) and returns its stderr.
pub fn refused(args: &[&str]) -> String {
    let run = stabilis(args);
    assert_eq!(run.status.code(), Some(2), "{run:?}");
    text(&run.stderr)
}
