//! # dynamic-shapes
//!
//! Capture and re-animation of moving human bodies and faces. This facade re-exports each
//! crate of the workspace as a module, so users can depend on one crate; each crate can also
//! be used alone.
//!
//! | module | crate | what it does | reference page |
//! |---|---|---|---|
//! | [`core`] | `skin-core` | cameras, skeletons, meshes, images, sparse least squares, tensors | `docs/skin-core.md` |
//! | [`needle`] | `needle-model` | skin deformation from silhouettes (Sand 2003) | `docs/needle-model.md` |
//! | [`template`] | `template-silhouette` | pose tracking in visual hulls, template molding (thesis Ch. 2) | `docs/template-silhouette.md` |
//! | [`photometric`] | `photometric-normals` | normals from spherical lighting to merged surfaces (Ch. 3) | `docs/photometric-normals.md` |
//! | [`inertial`] | `inertial-acoustic` | wearable inertial and ultrasonic capture, skeletal EKF (Ch. 4) | `docs/inertial-acoustic.md` |
//! | [`face`] | `multilinear-face` | multilinear face models, tracking and transfer (Ch. 5) | `docs/multilinear-face.md` |
//! | `studio` (feature `studio`) | `dynamic-shapes-studio` | the synthetic capture studio that renders ground truth | `docs/studio.md` |
//!
//! The reference pages (in the repository's `docs/` folder) give each crate's pipeline,
//! parameters, formats, validation and limitations; `docs/results.md` holds every measured
//! figure, generated from the recorded runs of the examples.
//!
//! Features: `gltf` (default; glTF 2.0 export of mesh sequences), `decimate` (default; mesh
//! decimation), `studio` (the studio and the methods' validation equipment).
#![warn(missing_docs)]
#![cfg_attr(docsrs, feature(doc_cfg))]

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
#[cfg_attr(docsrs, doc(cfg(feature = "studio")))]
#[doc(inline)]
pub use dynamic_shapes_studio as studio;

/// The code in README.md, compiled and run as a doctest so the snippet stays true.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctests;
