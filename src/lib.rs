//! # dynamic-shapes
//!
//! Capture and re-animation of moving human bodies and faces. This facade re-exports each
//! crate of the workspace as a module, so users can depend on one crate.
#![warn(missing_docs)]

#[doc(inline)]
pub use skin_core as core;

#[doc(inline)]
pub use needle_model as needle;

#[doc(inline)]
pub use template_silhouette as template;

#[doc(inline)]
pub use photometric_normals as photometric;

#[doc(inline)]
pub use inertial_acoustic as inertial;

#[doc(inline)]
pub use multilinear_face as face;

/// The synthetic capture studio (feature `studio`): performers, motions, garments, lighting
/// and the capture builder that renders ground truth for the methods' validation.
#[cfg(feature = "studio")]
#[doc(inline)]
pub use dynamic_shapes_studio as studio;

/// The code in README.md, compiled and run as a doctest so the snippet stays true.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctests;
