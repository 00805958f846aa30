//! The one error type of the workbench and of the simulator above it: every message names the
//! file, topic, field or parameter at fault, so that a user can fix the input without reading
//! the source.
use std::path::PathBuf;

/// Everything that can go wrong while simulating, logging or reading logs.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    /// The file to read does not exist.
    #[error("file not found: {}", path.display())]
    FileNotFound {
        /// The path as given.
        path: PathBuf,
    },
    /// Reading or writing a file failed for a reason other than its absence.
    #[error("cannot access {}: {source}", path.display())]
    Io {
        /// The path as given.
        path: PathBuf,
        /// The operating system's reason.
        #[source]
        source: std::io::Error,
    },
    /// The file exists but is not an MCAP file (wrong magic bytes or unreadable header).
    #[error("not an MCAP file: {}: {reason}", path.display())]
    NotMcap {
        /// The path as given.
        path: PathBuf,
        /// What was found instead.
        reason: String,
    },
    /// The MCAP library refused a record while writing or reading.
    #[error("MCAP error in {}: {source}", path.display())]
    Mcap {
        /// The file being written or read.
        path: PathBuf,
        /// The library's error.
        #[source]
        source: mcap::McapError,
    },
    /// A CSV file could not be parsed.
    #[error("bad CSV file {}: {reason}", path.display())]
    Csv {
        /// The file being read.
        path: PathBuf,
        /// What is wrong, with the line number where known.
        reason: String,
    },
    /// A requested topic (MCAP channel) is not in the log.
    #[error("missing channel {topic:?} in {}; available: {}", path.display(), available.join(", "))]
    MissingTopic {
        /// The file being read.
        path: PathBuf,
        /// The topic that was asked for.
        topic: String,
        /// The topics that the file does have.
        available: Vec<String>,
    },
    /// A field is missing from a table, a schema or a message.
    #[error("missing field {field:?} in {context}; available: {}", available.join(", "))]
    MissingField {
        /// Where the field was looked for (topic, message number, file).
        context: String,
        /// The field that was asked for.
        field: String,
        /// The fields that are there.
        available: Vec<String>,
    },
    /// A value is NaN, infinite or not a number at all.
    #[error("field {field:?} in {context} is not a finite number: {value}")]
    NotFinite {
        /// Where the value is (topic and time, or file and line).
        context: String,
        /// The field name.
        field: String,
        /// The offending value as text.
        value: String,
    },
    /// A message is not a JSON object of numbers, or has no `t`.
    #[error("bad message in {context}: {reason}")]
    BadMessage {
        /// Topic and message number.
        context: String,
        /// What is wrong with it.
        reason: String,
    },
    /// Two things that must have the same length do not.
    #[error("length mismatch for {what}: expected {expected}, found {found}")]
    LengthMismatch {
        /// What was measured (e.g. "initial state of wheel-pendulum", "column w1").
        what: String,
        /// The required length.
        expected: usize,
        /// The length that was given.
        found: usize,
    },
    /// A parameter of a run or model is out of its valid range.
    #[error("invalid {name} = {value}: {reason}")]
    InvalidParameter {
        /// The parameter's name as the user spells it.
        name: String,
        /// Its value as text.
        value: String,
        /// The valid range or the rule it breaks.
        reason: String,
    },
    /// A model file is malformed: `key` is the dotted TOML key (`linear.A[1][0]`,
    /// `effects.joint_friction.parameters.b`), `reason` names the problem (with the expression
    /// and the position of a bad name, or the sizes of mismatched matrices).
    #[error("{}: {key}: {reason}", path.display())]
    ModelFile {
        /// The model file.
        path: PathBuf,
        /// Where in the file.
        key: String,
        /// What is wrong.
        reason: String,
    },
    /// An output path that would overwrite or delete an input or something this program did
    /// not write (see [`crate::output`]).
    #[error("refusing to write {}: {reason}", path.display())]
    UnsafeOutput {
        /// The output path as given.
        path: PathBuf,
        /// Why it is refused.
        reason: String,
    },
    /// A state-space model whose matrices do not fit together, or that cannot be evaluated
    /// (a pole on an evaluated frequency, a bad sample period or delay).
    #[error("state-space model: {0}")]
    StateSpace(#[from] rigid_body::Error),
    /// A domain crate (cubli, tilt, ...) reported an error; `context` says what was being done.
    #[error("{context}: {source}")]
    Domain {
        /// What the simulator was doing.
        context: String,
        /// The domain crate's error.
        #[source]
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    /// The run was stopped from outside before its end ([`crate::Cancel`]): it has no result.
    #[error("the run was cancelled before its end")]
    Cancelled,
}

impl SimError {
    /// Wraps a domain crate's error with what was being done.
    pub fn domain(
        context: impl Into<String>,
        source: impl std::error::Error + Send + Sync + 'static,
    ) -> Self {
        Self::Domain {
            context: context.into(),
            source: Box::new(source),
        }
    }

    /// Builds an [`SimError::InvalidParameter`].
    pub fn invalid(
        name: impl Into<String>,
        value: impl ToString,
        reason: impl Into<String>,
    ) -> Self {
        Self::InvalidParameter {
            name: name.into(),
            value: value.to_string(),
            reason: reason.into(),
        }
    }

    /// Maps an I/O error on `path`, turning "not found" into [`SimError::FileNotFound`].
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        let path = path.into();
        if source.kind() == std::io::ErrorKind::NotFound {
            Self::FileNotFound { path }
        } else {
            Self::Io { path, source }
        }
    }

    /// The process exit code for this error: 2 for bad input (the user can fix it: a missing
    /// directory, a file without permission), 1 when the machine failed us (a full disk), 130
    /// (as for SIGINT) for a cancelled run.
    pub fn exit_code(&self) -> i32 {
        match self {
            Self::Io { source, .. }
                if !matches!(
                    source.kind(),
                    std::io::ErrorKind::NotFound | std::io::ErrorKind::PermissionDenied
                ) =>
            {
                1
            }
            Self::Cancelled => 130,
            _ => 2,
        }
    }
}

/// Result type of the workbench and the simulator.
pub type Result<T, E = SimError> = std::result::Result<T, E>;
