//! # multilinear-face
//!
//! Multilinear face models after D. Vlasic, *Markerless Performance Capture* (MIT PhD thesis,
//! 2010), Chapter 5 (and Vlasic, Brand, Pfister, Popović, *Face Transfer with Multilinear
//! Models*, SIGGRAPH 2005).
#![warn(missing_docs)]
#![warn(unnameable_types, unreachable_pub)]

mod correspondence;
mod error;
mod face_data;
mod impute;
mod model;
#[cfg(feature = "validation")]
pub mod validation;

pub use correspondence::{
    fit_template, procrustes, CorrespondenceParams, Similarity, TemplateFit,
};
pub use error::{Context, Error, Result, ResultExt};
pub use face_data::{FaceTensor, KnownFaces};
pub use impute::{impute, impute_by_averaging, ImputeParams, Imputation};
pub use model::{Dials, ModelFit, ModelParams, MultilinearModel};
