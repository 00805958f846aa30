//! no_std core of stabilis: the geometry and numerics every domain crate builds on.
#![no_std]
#![cfg_attr(docsrs, feature(doc_cfg))]

#[cfg(feature = "std")]
extern crate std;

mod error;
pub use error::Error;

/// Result type of this crate.
pub type Result<T> = core::result::Result<T, Error>;

pub mod laguerre;
#[cfg(feature = "std")]
pub mod lti;
pub mod matrix_set;
pub mod s2;
pub mod siqp;
pub mod so3;
