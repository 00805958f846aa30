//! The shipped systems adapted to the [`workbench`] (which knows no system), the one registry
//! of systems it knows by name, used by the command line and Python alike, and the way to
//! bring any other system: a model file.
use std::path::Path;
use std::sync::Arc;

use workbench::model::ModelStructure;
use workbench::model_file::ModelFile;
use workbench::{Result, SimError};

pub mod cubli;
pub mod flying_platform;

use self::flying_platform::FlyingPlatform;

/// Names of the shipped systems.
pub const SHIPPED: [&str; 2] = ["flying_platform", "cubli"];

/// Where a workbench's model comes from.
#[derive(Debug, Clone)]
pub enum Source {
    /// A linear structure compared through the FRF (a shipped system or a model file).
    Structure(Arc<dyn ModelStructure>),
    /// The Cubli, whose full-state logs are compared by time-domain regression.
    Cubli,
}

/// The shipped system of that name.
pub fn shipped(name: &str) -> Result<Source> {
    match name {
        "flying_platform" => Ok(Source::Structure(Arc::new(FlyingPlatform::default()))),
        "cubli" => Ok(Source::Cubli),
        other => Err(SimError::invalid(
            "system",
            other,
            format!(
                "not a shipped system ({}); bring your own with a model file: --model FILE \
                 (README, \"Your own system\")",
                SHIPPED.join(", ")
            ),
        )),
    }
}

/// The structure of a model file.
pub fn from_model_file(path: &Path) -> Result<Source> {
    Ok(Source::Structure(Arc::new(ModelFile::from_path(path)?)))
}
