//! # needle-model
//!
//! Skin deformation captured from moving silhouettes, after P. Sand, *Reconstruction of
//! Deforming Surfaces from Moving Silhouettes* (MIT MS thesis, 2003) and Sand, McMillan and
//! Popović, *Continuous Capture of Skin Deformation* (SIGGRAPH 2003).
//!
//! The body is a set of deformable primitives, one per bone: needles in rings around the bone
//! axis (§3.1–3.2). Each frame, each needle is projected into each camera and walked outward
//! until it leaves the silhouette; the resulting length is an observation tied to the pose of
//! the bones the primitive depends on (§3.3, §4.3). A normalised radial basis function over
//! prototype poses then predicts every needle's length for any new pose (§5).
#![warn(missing_docs)]

pub mod error;

pub use error::{Error, Result};
pub mod nrbf;
pub mod params;
pub mod prototypes;

pub use nrbf::{Nrbf, NrbfFit};
pub use params::ReconstructionParams;
pub use prototypes::{NeedleObservations, PrototypeLocations, PrototypeShapes};
