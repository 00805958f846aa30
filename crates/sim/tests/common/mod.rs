//! Running the `stabilis` binary from the end-to-end tests: one definition for every test file
//! (each file uses the part it needs).
#![allow(dead_code, clippy::unwrap_used)]
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// A directory of one test's own under the system's temporary directory, removed with
/// everything in it when dropped: keep it alive until every file in it (and every run of the
/// binary on them) is done. Derefs to the directory's path.
#[derive(Debug)]
pub struct Scratch {
    _root: tempfile::TempDir,
    path: PathBuf,
}

impl Scratch {
    /// A new empty directory `<prefix>XXXXXX`.
    pub fn new(prefix: &str) -> Self {
        let root = tempfile::Builder::new().prefix(prefix).tempdir().unwrap();
        let path = root.path().to_path_buf();
        Self { _root: root, path }
    }

    /// A new empty directory `name` alone in a new `<prefix>XXXXXX`, for tests that look at
    /// what is beside their directory.
    pub fn nested(prefix: &str, name: &str) -> Self {
        let root = tempfile::Builder::new().prefix(prefix).tempdir().unwrap();
        let path = root.path().join(name);
        std::fs::create_dir(&path).unwrap();
        Self { _root: root, path }
    }
}

impl std::ops::Deref for Scratch {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.path
    }
}

impl AsRef<Path> for Scratch {
    fn as_ref(&self) -> &Path {
        &self.path
    }
}

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
