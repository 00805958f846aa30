//! Every file or directory the program writes goes through this module, so that no output can
//! destroy a user's data:
//!
//! - an output may not be one of the inputs, lie inside an input directory, or (for a directory)
//!   contain an input; two outputs of one run may not name the same path or lie one inside the
//!   other ([`check_outputs`], before any work);
//! - an existing file is replaced only when it is empty or this program wrote it (an MCAP log
//!   whose header names it as the library, a JSON object whose `written_by` names it: see
//!   [`stamped`]); anything else (a user's own log or JSON, a directory, a CSV, a device) is
//!   refused;
//! - an existing directory is replaced only when it is empty or was written by this module (it
//!   holds the [`MARKER`] file listing its contents, and nothing else was added);
//! - the output is written to a temporary path beside the target (`.NAME.tmp-PID`) and renamed
//!   into place when complete, so the target is either the old version or the complete new one.
//!   A run killed midway leaves only that temporary path.
//!
//! Refusals are [`SimError::UnsafeOutput`] (exit code 2) naming the path.
//!
//! ```
//! use workbench::output::{write_atomically, Kind};
//! let path = std::env::temp_dir().join(format!("sim_doc_output_{}.json", std::process::id()));
//! write_atomically(&path, Kind::Json, &[], |tmp| {
//!     std::fs::write(tmp, "{}").map_err(|e| workbench::SimError::io(tmp, e))
//! })
//! .unwrap();
//! // The output can never be an input.
//! let err = write_atomically(&path, Kind::Json, &[path.clone()], |_| Ok(())).unwrap_err();
//! assert!(err.to_string().contains("is an input"));
//! std::fs::remove_file(&path).unwrap();
//! ```
use std::io::Read;
use std::path::{Component, Path, PathBuf};

use crate::error::{Result, SimError};

/// Name of the file that marks a directory as written by this program; it lists the entries
/// written, one per line.
pub const MARKER: &str = ".stabilis-output";

/// What a file output holds; an existing file at the target must be of the same kind.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// An MCAP log (starts with the MCAP magic).
    Mcap,
    /// A JSON document (starts with `{` or `[` after white space).
    Json,
}

impl Kind {
    fn name(self) -> &'static str {
        match self {
            Self::Mcap => "an MCAP log",
            Self::Json => "a JSON file",
        }
    }

    /// Whether `head`, the first bytes of an existing file, is of this kind.
    fn matches(self, head: &[u8]) -> bool {
        match self {
            Self::Mcap => head.starts_with(b"\x89MCAP"),
            Self::Json => head
                .iter()
                .find(|b| !b.is_ascii_whitespace())
                .is_some_and(|b| matches!(b, b'{' | b'[')),
        }
    }

    /// Whether the existing file at `path` (of this kind) is one this program wrote: an MCAP
    /// log whose header names [`WRITER`] as its library, a JSON object whose `written_by`
    /// does. A user's own log or JSON of the same kind is not replaced.
    fn written_here(self, path: &Path) -> Result<bool> {
        match self {
            Self::Mcap => {
                let mut head = Vec::with_capacity(512);
                std::fs::File::open(path)
                    .and_then(|f| f.take(512).read_to_end(&mut head))
                    .map_err(|e| SimError::io(path, e))?;
                Ok(mcap_library(&head).is_some_and(|l| l.starts_with(WRITER)))
            }
            Self::Json => {
                let text = std::fs::read(path).map_err(|e| SimError::io(path, e))?;
                let doc: Option<serde_json::Value> = serde_json::from_slice(&text).ok();
                Ok(doc
                    .as_ref()
                    .and_then(|d| d.get(WRITTEN_BY))
                    .and_then(|w| w.as_str())
                    .is_some_and(|w| w.starts_with(WRITER)))
            }
        }
    }
}

/// The name this program writes into its outputs (MCAP header library, JSON `written_by`),
/// by which it knows a file it may replace (of any version).
pub const WRITER: &str = "stabilis";

/// What it writes there: [`WRITER`] and its version.
pub const WRITTEN_AS: &str = concat!("stabilis ", env!("CARGO_PKG_VERSION"));

/// The key of a JSON output's writer.
pub const WRITTEN_BY: &str = "written_by";

/// The library named in the header record of an MCAP log (`head`, its first bytes): magic,
/// opcode 0x01, length (u64), profile and library (each a u32 length and UTF-8).
fn mcap_library(head: &[u8]) -> Option<String> {
    let rest = head.strip_prefix(b"\x89MCAP0\r\n")?;
    let (&opcode, rest) = rest.split_first()?;
    if opcode != 0x01 {
        return None;
    }
    let rest = rest.get(8..)?;
    let string = |b: &[u8]| -> Option<(String, usize)> {
        let n = u32::from_le_bytes(b.get(..4)?.try_into().ok()?) as usize;
        let s = std::str::from_utf8(b.get(4..4 + n)?).ok()?;
        Some((s.to_string(), 4 + n))
    };
    let (_, used) = string(rest)?;
    string(rest.get(used..)?).map(|(library, _)| library)
}

/// `value` with [`WRITTEN_BY`] naming this program when it is an object (the JSON outputs are).
pub fn stamped(value: &serde_json::Value) -> serde_json::Value {
    let mut v = value.clone();
    if let Some(map) = v.as_object_mut() {
        map.insert(
            WRITTEN_BY.to_string(),
            serde_json::Value::String(WRITTEN_AS.to_string()),
        );
    }
    v
}

fn refuse(path: &Path, reason: impl Into<String>) -> SimError {
    SimError::UnsafeOutput {
        path: path.to_path_buf(),
        reason: reason.into(),
    }
}

/// `path` made absolute and free of `.`, `..` and symbolic links as far as it exists.
fn resolve(path: &Path) -> PathBuf {
    if let Ok(p) = path.canonicalize() {
        return p;
    }
    let absolute = if path.is_absolute() {
        path.to_path_buf()
    } else {
        std::env::current_dir().unwrap_or_default().join(path)
    };
    let mut clean = PathBuf::new();
    for c in absolute.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => {
                clean.pop();
            }
            c => clean.push(c),
        }
    }
    match (clean.parent(), clean.file_name()) {
        (Some(parent), Some(name)) => resolve_parent(parent).join(name),
        _ => clean,
    }
}

fn resolve_parent(parent: &Path) -> PathBuf {
    parent
        .canonicalize()
        .unwrap_or_else(|_| match (parent.parent(), parent.file_name()) {
            (Some(p), Some(n)) => resolve_parent(p).join(n),
            _ => parent.to_path_buf(),
        })
}

#[cfg(unix)]
fn same_file(a: &Path, b: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    match (std::fs::metadata(a), std::fs::metadata(b)) {
        (Ok(a), Ok(b)) => a.dev() == b.dev() && a.ino() == b.ino(),
        _ => false,
    }
}

#[cfg(not(unix))]
fn same_file(_: &Path, _: &Path) -> bool {
    false
}

/// Refuses `target` when it is an input, lies inside an input directory or contains an input.
fn check_inputs(target: &Path, inputs: &[PathBuf]) -> Result<()> {
    let out = resolve(target);
    for input in inputs {
        let input_path = resolve(input);
        if out == input_path || same_file(target, input) {
            return Err(refuse(target, format!("is an input ({})", input.display())));
        }
        if out.starts_with(&input_path) {
            return Err(refuse(
                target,
                format!("is inside the input directory {}", input.display()),
            ));
        }
        if input_path.starts_with(&out) {
            return Err(refuse(
                target,
                format!("contains the input {}", input.display()),
            ));
        }
    }
    Ok(())
}

/// A temporary path beside `target` that nothing occupies (`.NAME.tag-PID`, or with `-N`
/// appended when that exists), and `target` made absolute, so that `.` and `dir/..` have a
/// name to rename onto. `create` claims the path (an empty file or directory, created only if
/// absent), so that what is later removed there is always what this program made.
fn temporary(
    target: &Path,
    tag: &str,
    create: impl Fn(&Path) -> std::io::Result<()>,
) -> Result<(PathBuf, PathBuf)> {
    let target = resolve(target);
    let name = target
        .file_name()
        .ok_or_else(|| refuse(&target, "has no file name"))?
        .to_string_lossy()
        .into_owned();
    let base = format!(".{name}.{tag}-{}", std::process::id());
    for n in 0..1000 {
        let tmp = target.with_file_name(if n == 0 {
            base.clone()
        } else {
            format!("{base}-{n}")
        });
        match create(&tmp) {
            Ok(()) => return Ok((target, tmp)),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => continue,
            // Named after the output: a missing directory is not a missing input file.
            Err(source) => {
                return Err(SimError::Io {
                    path: target,
                    source,
                })
            }
        }
    }
    Err(refuse(&target, "has no free temporary name beside it"))
}

/// Claims a file path: creates it empty, failing if anything is there.
fn new_file(path: &Path) -> std::io::Result<()> {
    std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(path)
        .map(drop)
}

/// Checks that a file of `kind` may be written at `target` given the `inputs` of the run.
pub fn check_file(target: &Path, kind: Kind, inputs: &[PathBuf]) -> Result<()> {
    check_inputs(target, inputs)?;
    let meta = match std::fs::symlink_metadata(target) {
        Ok(meta) => meta,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(e) => return Err(SimError::io(target, e)),
    };
    if meta.is_dir() {
        return Err(refuse(target, "is a directory"));
    }
    if !meta.is_file() {
        return Err(refuse(
            target,
            format!(
                "exists and is not a regular file (expected {})",
                kind.name()
            ),
        ));
    }
    let mut head = [0u8; 64];
    let mut file = std::fs::File::open(target).map_err(|e| SimError::io(target, e))?;
    let n = file.read(&mut head).map_err(|e| SimError::io(target, e))?;
    if n > 0 && !kind.matches(&head[..n]) {
        return Err(refuse(
            target,
            format!("exists and is not {}; not overwriting it", kind.name()),
        ));
    }
    if n > 0 && !kind.written_here(target)? {
        return Err(refuse(
            target,
            format!(
                "exists and is {} this program did not write; not overwriting it",
                kind.name()
            ),
        ));
    }
    Ok(())
}

/// What an output of a run is: a file of a kind, or a directory.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Target {
    /// A file of this kind (see [`check_file`]).
    File(Kind),
    /// A directory (see [`check_dir`]).
    Dir,
    /// A directory the run writes files into beside what it holds (each file checked when it
    /// is written): here only kept apart from the other outputs.
    Into,
}

/// An output a run is going to write: the option that names it (`--json`), its path and what
/// it is.
#[derive(Debug, Clone, Copy)]
pub struct Planned<'a> {
    /// The option or argument that names it, for the message.
    pub option: &'a str,
    /// Where it goes.
    pub path: &'a Path,
    /// File or directory.
    pub target: Target,
}

/// Checks every output of a run before any work is done: no two name the same path or lie one
/// inside the other (`--json out/r and --report out/r name the same path`), and each may be
/// written given the `inputs` ([`check_file`], [`check_dir`]).
pub fn check_outputs(outputs: &[Planned<'_>], inputs: &[PathBuf]) -> Result<()> {
    let resolved: Vec<PathBuf> = outputs.iter().map(|o| resolve(o.path)).collect();
    for (i, a) in outputs.iter().enumerate() {
        for (j, b) in outputs.iter().enumerate().skip(i + 1) {
            let (ra, rb) = (&resolved[i], &resolved[j]);
            let named = |o: &Planned<'_>| format!("{} {}", o.option, o.path.display());
            if ra == rb || same_file(a.path, b.path) {
                return Err(refuse(
                    b.path,
                    format!("{} and {} name the same path", named(b), named(a)),
                ));
            }
            for (inner, r_inner, outer, r_outer) in [(a, ra, b, rb), (b, rb, a, ra)] {
                if r_inner.starts_with(r_outer) {
                    return Err(refuse(
                        inner.path,
                        format!("{} lies inside {}", named(inner), named(outer)),
                    ));
                }
            }
        }
    }
    for o in outputs {
        match o.target {
            Target::File(kind) => check_file(o.path, kind, inputs)?,
            Target::Dir => check_dir(o.path, inputs)?,
            Target::Into => check_inputs(o.path, inputs)?,
        }
    }
    Ok(())
}

/// A file being written beside its target; [`Pending::commit`] renames it into place, dropping
/// it uncommitted removes it.
#[derive(Debug)]
pub struct Pending {
    target: PathBuf,
    tmp: PathBuf,
    committed: bool,
}

impl Pending {
    /// Checks `target` (see [`check_file`]) and reserves its temporary path.
    pub fn file(target: &Path, kind: Kind, inputs: &[PathBuf]) -> Result<Self> {
        check_file(target, kind, inputs)?;
        let (target, tmp) = temporary(target, "tmp", new_file)?;
        Ok(Self {
            target,
            tmp,
            committed: false,
        })
    }

    /// The temporary path to write to.
    pub fn path(&self) -> &Path {
        &self.tmp
    }

    /// The final path.
    pub fn target(&self) -> &Path {
        &self.target
    }

    /// Renames the finished temporary file onto the target.
    pub fn commit(mut self) -> Result<()> {
        std::fs::rename(&self.tmp, &self.target).map_err(|e| SimError::io(&self.target, e))?;
        self.committed = true;
        Ok(())
    }
}

impl Drop for Pending {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_file(&self.tmp);
        }
    }
}

/// Writes a file of `kind` at `path`: `write` fills the temporary path it is given, which is
/// renamed onto `path` when `write` succeeds and removed when it fails.
pub fn write_atomically(
    path: &Path,
    kind: Kind,
    inputs: &[PathBuf],
    write: impl FnOnce(&Path) -> Result<()>,
) -> Result<()> {
    let pending = Pending::file(path, kind, inputs)?;
    write(pending.path())?;
    pending.commit()
}

/// The names listed in the marker of `dir`, if it is a directory this module wrote.
fn marked_entries(dir: &Path) -> Option<Vec<String>> {
    let text = std::fs::read_to_string(dir.join(MARKER)).ok()?;
    // Only plain names of entries of `dir` count: a line that is empty, `.`, `..` or holds a
    // separator (a marker edited by hand or damaged) would name `dir` itself or something
    // outside it, which removing the old output must never touch.
    let plain = |name: &&str| {
        let mut parts = Path::new(name).components();
        matches!(
            (parts.next(), parts.next()),
            (Some(std::path::Component::Normal(n)), None) if n == std::ffi::OsStr::new(name)
        )
    };
    Some(text.lines().filter(plain).map(String::from).collect())
}

/// Checks that a directory may be written at `target`: not an input, not containing one, and
/// either absent, empty, or written by this module with nothing added since.
pub fn check_dir(target: &Path, inputs: &[PathBuf]) -> Result<()> {
    check_inputs(target, inputs)?;
    let meta = match std::fs::symlink_metadata(target) {
        Ok(meta) => meta,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(e) => return Err(SimError::io(target, e)),
    };
    if !meta.is_dir() {
        return Err(refuse(target, "exists and is not a directory"));
    }
    let entries: Vec<String> = std::fs::read_dir(target)
        .map_err(|e| SimError::io(target, e))?
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    if entries.is_empty() {
        return Ok(());
    }
    let Some(listed) = marked_entries(target) else {
        return Err(refuse(
            target,
            "is a non-empty directory this program did not write; give a new or empty one",
        ));
    };
    if let Some(extra) = entries
        .iter()
        .find(|e| e.as_str() != MARKER && !listed.contains(e))
    {
        return Err(refuse(
            target,
            format!("holds {extra:?}, which this program did not write; not replacing it"),
        ));
    }
    Ok(())
}

/// Writes a directory at `dir`: `write` fills the empty temporary directory it is given; when it
/// succeeds the directory is marked (see [`MARKER`]) and renamed onto `dir`. An old `dir` that
/// this module wrote is moved aside and deleted only after the new one is in place.
pub fn write_dir_atomically(
    dir: &Path,
    inputs: &[PathBuf],
    write: impl FnOnce(&Path) -> Result<()>,
) -> Result<()> {
    check_dir(dir, inputs)?;
    // The directory it goes in must exist, as for a file: a typo in a parent's name is not a
    // request to create a tree (nor is a path under `/` run as root).
    if let Some(parent) = resolve(dir).parent().filter(|p| !p.as_os_str().is_empty()) {
        if !parent.is_dir() {
            return Err(SimError::invalid(
                format!("output {}", dir.display()),
                parent.display(),
                "the directory it goes in does not exist (nothing is created but the output itself)",
            ));
        }
    }
    let (target, tmp) = temporary(dir, "tmp", |p| std::fs::create_dir(p))?;
    let built = write(&tmp).and_then(|()| mark(&tmp));
    if let Err(e) = built {
        let _ = std::fs::remove_dir_all(&tmp);
        return Err(e);
    }
    // The old directory is moved aside (onto a name it alone can take: a fresh empty
    // directory is claimed and replaced) and emptied only after the new one is in place.
    let old = if target.exists() {
        let (_, old) = temporary(&target, "old", |p| std::fs::create_dir(p))?;
        std::fs::rename(&target, &old).map_err(|e| SimError::io(&target, e))?;
        Some(old)
    } else {
        None
    };
    if let Err(e) = std::fs::rename(&tmp, &target) {
        if let Some(old) = &old {
            let _ = std::fs::rename(old, &target);
        }
        let _ = std::fs::remove_dir_all(&tmp);
        return Err(SimError::io(&target, e));
    }
    if let Some(old) = old {
        remove_marked(&old)?;
    }
    Ok(())
}

/// Removes from `dir` (an output this module wrote, moved aside) the files its marker lists,
/// then the marker and `dir`. Anything else (added while the run lasted) stays, with `dir`,
/// and is named on stderr. The writers put only files in an output, so a listed name that is
/// now a directory was put there by someone else, and stays too.
fn remove_marked(dir: &Path) -> Result<()> {
    let listed = marked_entries(dir).unwrap_or_default();
    for name in &listed {
        let entry = dir.join(name);
        let removed = match std::fs::symlink_metadata(&entry) {
            Ok(meta) if meta.is_dir() => Ok(()),
            Ok(_) => std::fs::remove_file(&entry),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(()),
            Err(e) => Err(e),
        };
        removed.map_err(|e| SimError::io(&entry, e))?;
    }
    let marker = dir.join(MARKER);
    let _ = std::fs::remove_file(&marker);
    if std::fs::remove_dir(dir).is_err() {
        eprintln!(
            "warning: {} holds files this program did not write (added during the run); kept there",
            dir.display()
        );
    }
    Ok(())
}

fn mark(dir: &Path) -> Result<()> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .map_err(|e| SimError::io(dir, e))?
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    let marker = dir.join(MARKER);
    std::fs::write(&marker, names.join("\n") + "\n").map_err(|e| SimError::io(&marker, e))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An empty directory `sim_output_{name}_XXXXXX` of the test's own, removed when dropped.
    fn scratch(name: &str) -> tempfile::TempDir {
        tempfile::Builder::new()
            .prefix(&format!("sim_output_{name}_"))
            .tempdir()
            .unwrap()
    }

    /// The entries of `root` other than `known` (an old output moved aside, say).
    fn others(root: &Path, known: &[&PathBuf]) -> Vec<PathBuf> {
        std::fs::read_dir(root)
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| !known.contains(&p))
            .collect()
    }

    fn write_text(text: &'static str) -> impl FnOnce(&Path) -> Result<()> {
        move |p: &Path| std::fs::write(p, text).map_err(|e| SimError::io(p, e))
    }

    #[test]
    fn a_directory_holding_the_inputs_is_never_replaced() {
        let tmp = scratch("inputs_dir");
        let dir = tmp.path().to_path_buf();
        let input = dir.join("run.mcap");
        std::fs::write(&input, b"\x89MCAP0\r\n").unwrap();
        let err = write_dir_atomically(&dir, std::slice::from_ref(&dir), |d| {
            write_text("x")(&d.join("index.html"))
        })
        .unwrap_err();
        assert!(err.to_string().contains("is an input"), "{err}");
        assert_eq!(err.exit_code(), 2);
        // Even when the inputs are not named, a directory this program did not make is kept.
        let err = write_dir_atomically(&dir, &[], |d| write_text("x")(&d.join("index.html")))
            .unwrap_err();
        assert!(err.to_string().contains("did not write"), "{err}");
        assert!(input.exists());
        let names: Vec<_> = std::fs::read_dir(&dir).unwrap().collect();
        assert_eq!(names.len(), 1, "no temporary left behind");
    }

    #[test]
    fn a_missing_parent_is_refused_and_nothing_is_created() {
        let tmp = scratch("no_parent");
        let root = tmp.path().to_path_buf();
        let dir = root.join("typo").join("sub").join("report");
        let err = write_dir_atomically(&dir, &[], |d| write_text("x")(&d.join("index.html")))
            .unwrap_err();
        assert!(err.to_string().contains("does not exist"), "{err}");
        assert_eq!(err.exit_code(), 2);
        assert!(!root.join("typo").exists());
    }

    #[test]
    fn a_directory_it_wrote_is_replaced_unless_something_was_added() {
        let tmp = scratch("own_dir");
        let root = tmp.path().to_path_buf();
        let dir = root.join("report");
        write_dir_atomically(&dir, &[], |d| write_text("1")(&d.join("index.html"))).unwrap();
        write_dir_atomically(&dir, &[], |d| write_text("2")(&d.join("index.html"))).unwrap();
        assert_eq!(
            std::fs::read_to_string(dir.join("index.html")).unwrap(),
            "2"
        );
        std::fs::write(dir.join("notes.txt"), "mine").unwrap();
        let err = write_dir_atomically(&dir, &[], |d| write_text("3")(&d.join("index.html")))
            .unwrap_err();
        assert!(err.to_string().contains("notes.txt"), "{err}");
        assert_eq!(
            std::fs::read_to_string(dir.join("notes.txt")).unwrap(),
            "mine"
        );
        // Only the report itself is left in the parent (no temporaries, no old copies).
        assert_eq!(std::fs::read_dir(&root).unwrap().count(), 1);
    }

    /// A file a user adds to an old report while the new one is being written is kept (in the
    /// moved-aside directory), and a user's file that happens to have the temporary name is
    /// neither written over nor removed.
    #[test]
    fn nothing_added_during_the_run_or_named_like_a_temporary_is_deleted() {
        let tmp = scratch("during");
        let root = tmp.path().to_path_buf();
        let dir = root.join("report");
        write_dir_atomically(&dir, &[], |d| write_text("1")(&d.join("index.html"))).unwrap();
        write_dir_atomically(&dir, &[], |d| {
            std::fs::write(dir.join("added.txt"), "mine").unwrap();
            write_text("2")(&d.join("index.html"))
        })
        .unwrap();
        assert_eq!(
            std::fs::read_to_string(dir.join("index.html")).unwrap(),
            "2"
        );
        let kept = others(&root, &[&dir]);
        assert_eq!(kept.len(), 1, "{kept:?}");
        assert_eq!(
            std::fs::read_to_string(kept[0].join("added.txt")).unwrap(),
            "mine"
        );

        let target = root.join("out.json");
        let squatter = root.join(format!(".out.json.tmp-{}", std::process::id()));
        std::fs::write(&squatter, "user data").unwrap();
        let err = write_atomically(&target, Kind::Json, &[], |_| {
            Err(SimError::invalid("write", "x", "failed on purpose"))
        })
        .unwrap_err();
        assert!(err.to_string().contains("on purpose"), "{err}");
        write_atomically(&target, Kind::Json, &[], write_text("{}")).unwrap();
        assert_eq!(std::fs::read_to_string(&squatter).unwrap(), "user data");
        assert_eq!(std::fs::read_to_string(&target).unwrap(), "{}");
    }

    /// A marker that names something outside the old output, or the old output itself (an
    /// empty line, `.`), removes neither: only the listed entries of the old output go.
    #[test]
    fn a_damaged_marker_removes_nothing_outside_the_listed_entries() {
        let tmp = scratch("damaged_marker");
        let root = tmp.path().to_path_buf();
        let dir = root.join("report");
        write_dir_atomically(&dir, &[], |d| write_text("1")(&d.join("index.html"))).unwrap();
        let outside = root.join("mine.txt");
        std::fs::write(&outside, "user data").unwrap();
        let marker = dir.join(MARKER);
        let listed = std::fs::read_to_string(&marker).unwrap();
        std::fs::write(
            &marker,
            format!("{listed}\n../mine.txt\n\n.\nsub/../../mine.txt\n"),
        )
        .unwrap();
        write_dir_atomically(&dir, &[], |d| {
            // Added to the old output while the new one is written: it must survive.
            std::fs::write(dir.join("added.txt"), "also mine").unwrap();
            write_text("2")(&d.join("index.html"))
        })
        .unwrap();
        assert_eq!(std::fs::read_to_string(&outside).unwrap(), "user data");
        assert_eq!(
            std::fs::read_to_string(dir.join("index.html")).unwrap(),
            "2"
        );
        let kept = others(&root, &[&dir, &outside]);
        assert_eq!(kept.len(), 1, "{kept:?}");
        assert_eq!(
            std::fs::read_to_string(kept[0].join("added.txt")).unwrap(),
            "also mine"
        );
    }

    /// A listed file that a user replaced by a directory of their own is not removed with the
    /// old output: the writers put only files there, so the directory and what it holds are
    /// the user's, and they stay in the moved-aside directory.
    #[test]
    fn a_directory_under_a_listed_name_is_kept() {
        let tmp = scratch("listed_dir");
        let root = tmp.path().to_path_buf();
        let dir = root.join("report");
        write_dir_atomically(&dir, &[], |d| write_text("1")(&d.join("index.html"))).unwrap();
        std::fs::remove_file(dir.join("index.html")).unwrap();
        std::fs::create_dir(dir.join("index.html")).unwrap();
        std::fs::write(dir.join("index.html").join("notes.txt"), "mine").unwrap();
        write_dir_atomically(&dir, &[], |d| write_text("2")(&d.join("index.html"))).unwrap();
        assert_eq!(
            std::fs::read_to_string(dir.join("index.html")).unwrap(),
            "2"
        );
        let kept = others(&root, &[&dir]);
        assert_eq!(kept.len(), 1, "{kept:?}");
        assert_eq!(
            std::fs::read_to_string(kept[0].join("index.html").join("notes.txt")).unwrap(),
            "mine"
        );
    }

    #[test]
    fn the_current_directory_is_refused_when_not_empty() {
        let tmp = scratch("dot");
        let dir = tmp.path().to_path_buf();
        std::fs::write(dir.join("keep.txt"), "x").unwrap();
        let dot = dir.join(".");
        let err = write_dir_atomically(&dot, &[], |d| write_text("x")(&d.join("a"))).unwrap_err();
        assert_eq!(err.exit_code(), 2);
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1);
        let leftovers = std::fs::read_dir(dir.parent().unwrap())
            .unwrap()
            .filter(|e| {
                let name = e.as_ref().unwrap().file_name();
                let name = name.to_string_lossy();
                name.starts_with(".sim_output_dot_") || name.starts_with(".out.tmp-")
            })
            .count();
        assert_eq!(leftovers, 0);
    }

    /// A user's own JSON or MCAP log of the kind being written is kept: only a file this
    /// program wrote (its `written_by`, its MCAP header's library) is replaced.
    #[test]
    fn a_users_own_file_of_the_same_kind_is_refused() {
        let tmp = scratch("own_kind");
        let dir = tmp.path().to_path_buf();
        let config = dir.join("config.json");
        std::fs::write(&config, "{\"gain\": 3}").unwrap();
        let err = write_atomically(&config, Kind::Json, &[], write_text("{}")).unwrap_err();
        assert!(err.to_string().contains("did not write"), "{err}");
        assert_eq!(std::fs::read_to_string(&config).unwrap(), "{\"gain\": 3}");
        let ours = serde_json::to_string(&stamped(&serde_json::json!({"steps": []}))).unwrap();
        let write_ours = || {
            let text = ours.clone();
            move |p: &Path| std::fs::write(p, text).map_err(|e| SimError::io(p, e))
        };
        write_atomically(&config, Kind::Json, &[], write_ours()).unwrap_err();
        let out = dir.join("out.json");
        write_atomically(&out, Kind::Json, &[], write_ours()).unwrap();
        write_atomically(&out, Kind::Json, &[], write_ours()).unwrap();
        // An MCAP header: magic, opcode 1, length, profile "", library.
        let header = |library: &str| {
            let mut b = b"\x89MCAP0\r\n\x01".to_vec();
            b.extend_from_slice(&(8 + library.len() as u64).to_le_bytes());
            b.extend_from_slice(&0u32.to_le_bytes());
            b.extend_from_slice(&(library.len() as u32).to_le_bytes());
            b.extend_from_slice(library.as_bytes());
            b
        };
        let rig = dir.join("rig.mcap");
        std::fs::write(&rig, header("mcap-python 1.1")).unwrap();
        let err = write_atomically(&rig, Kind::Mcap, &[], write_text("x")).unwrap_err();
        assert!(err.to_string().contains("did not write"), "{err}");
        assert_eq!(std::fs::read(&rig).unwrap(), header("mcap-python 1.1"));
        assert_eq!(
            mcap_library(&header("stabilis 0.1.0")).as_deref(),
            Some("stabilis 0.1.0")
        );
        let own = dir.join("own.mcap");
        std::fs::write(&own, header("stabilis 0.1.0")).unwrap();
        write_atomically(&own, Kind::Mcap, &[], write_text("x")).unwrap();
    }

    #[test]
    fn files_of_another_kind_and_inputs_are_refused() {
        let tmp = scratch("kinds");
        let dir = tmp.path().to_path_buf();
        let csv = dir.join("data.csv");
        std::fs::write(&csv, "t,x\n0,1\n").unwrap();
        for kind in [Kind::Mcap, Kind::Json] {
            let err = write_atomically(&csv, kind, &[], write_text("{}")).unwrap_err();
            assert!(err.to_string().contains("not overwriting"), "{err}");
        }
        let err = write_atomically(&dir, Kind::Json, &[], write_text("{}")).unwrap_err();
        assert!(err.to_string().contains("is a directory"), "{err}");
        let log = dir.join("run.mcap");
        std::fs::write(&log, b"\x89MCAP0\r\nrest").unwrap();
        let via_dots = dir.join("sub").join("..").join("run.mcap");
        let err = write_atomically(
            &via_dots,
            Kind::Mcap,
            std::slice::from_ref(&log),
            write_text("x"),
        )
        .unwrap_err();
        assert!(err.to_string().contains("is an input"), "{err}");
        assert_eq!(std::fs::read(&log).unwrap(), b"\x89MCAP0\r\nrest");
        assert_eq!(std::fs::read_to_string(&csv).unwrap(), "t,x\n0,1\n");
    }

    #[test]
    fn outputs_that_name_the_same_path_or_lie_one_inside_the_other_are_refused() {
        let tmp = scratch("clash");
        let dir = tmp.path().to_path_buf();
        let report = dir.join("r");
        let json = dir.join("r");
        fn planned<'a>(report: &'a Path, json: &'a Path) -> [Planned<'a>; 2] {
            [
                Planned {
                    option: "--report",
                    path: report,
                    target: Target::Dir,
                },
                Planned {
                    option: "--json",
                    path: json,
                    target: Target::File(Kind::Json),
                },
            ]
        }
        let err = check_outputs(&planned(&report, &json), &[]).unwrap_err();
        assert_eq!(err.exit_code(), 2);
        let text = err.to_string();
        assert!(
            text.contains("--json") && text.contains("--report"),
            "{text}"
        );
        assert!(text.contains("name the same path"), "{text}");
        // Another spelling of the same path, and a file inside the report directory.
        let dotted = dir.join(".").join("r");
        let err = check_outputs(&planned(&report, &dotted), &[]).unwrap_err();
        assert!(err.to_string().contains("name the same path"), "{err}");
        let inside = report.join("x.json");
        let err = check_outputs(&planned(&report, &inside), &[]).unwrap_err();
        assert!(err.to_string().contains("lies inside --report"), "{err}");
        check_outputs(&planned(&report, &dir.join("r.json")), &[]).unwrap();
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 0);
    }

    #[test]
    fn a_failed_write_keeps_the_old_file_and_leaves_no_temporary() {
        let tmp = scratch("failed");
        let dir = tmp.path().to_path_buf();
        let path = dir.join("out.json");
        let (one, three) = (
            r#"{"written_by": "stabilis", "n": 1}"#,
            r#"{"written_by": "stabilis", "n": 3}"#,
        );
        std::fs::write(&path, one).unwrap();
        let err = write_atomically(&path, Kind::Json, &[], |tmp| {
            std::fs::write(tmp, "[2").unwrap();
            Err(SimError::invalid("x", 1, "failed on purpose"))
        })
        .unwrap_err();
        assert!(err.to_string().contains("on purpose"), "{err}");
        assert_eq!(std::fs::read_to_string(&path).unwrap(), one);
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1);
        write_atomically(&path, Kind::Json, &[], write_text(three)).unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), three);
    }
}
