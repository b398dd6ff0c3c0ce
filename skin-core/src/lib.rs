//! # skin-core
//!
//! Shared foundations of `dynamic-shapes`: the types and algorithms every method crate stands
//! on. Geometry is `glam` f64 (re-exported as [`math`]); linear algebra is `nalgebra` f64;
//! public sparse matrices are `nalgebra_sparse::CscMatrix<f64>`; `faer` is used internally for
//! sparse Cholesky with symbolic reuse and large dense decompositions.
//!
//! | module | holds | paper |
//! | --- | --- | --- |
//! | [`camera`] | pinhole intrinsics, radial distortion with its own centre, extrinsics, rigs, calibration (DLT + Levenberg–Marquardt, Nelder–Mead; bar calibration by bundle adjustment), time-offset estimation, OpenCV import/export | Sand 2003 thesis §4.1; Fua et al. §2.2 |
//! | [`skeleton`] | joint tree, DOFs and limits, forward kinematics, Jacobians and J̇θ̇, BVH import/export | Vlasic thesis Eq. 4.2–4.3 |
//! | [`mesh`] | triangle meshes, OBJ/PLY IO, normals, adjacency, Laplacians, closest point and ray queries, skinning, distance metrics | Vlasic §2.4.1, §2.5.1 |
//! | [`image`] | masks, background subtraction, contours with normals, distance transforms, PNG IO | Sand §4.2 |
//! | [`markers`] | retro-reflective markers: detection, forward intersection | Fua et al. §2 |
//! | [`lsq`] | sparse least squares with several right-hand sides and symbolic reuse | Vlasic Eq. 2.1, 2.2, 3.3, 3.4 |
//! | [`raster`] | CPU rasteriser: silhouette masks, depth along the ray, camera-space normals, triangle ids and barycentrics, exact under radial distortion | Sand §6.2 (silhouette error) |
//! | [`stats`] | mean, median, percentiles (NumPy's interpolation), RMS of samples | |
//! | [`tensor`] | dense N-mode tensors, unfolding, mode-n products, truncated HOSVD and HOOI (Tucker) | Vlasic Eq. 5.1–5.4 |
//! | [`check`] | input checks: finite, positive, in range, index in bounds | |
//! | [`optim`] | small dense optimisers: Levenberg–Marquardt, Nelder–Mead downhill simplex | Sand §4.1 |
#![warn(missing_docs)]

pub mod camera;
pub mod check;
pub mod image;
pub mod lsq;
pub mod markers;
pub mod math;
pub mod mesh;
pub mod optim;
#[doc(hidden)]
pub mod random;
pub mod raster;
pub mod skeleton;
pub mod stats;
pub mod tensor;

mod error;
mod faer_bridge;
mod method_error;

pub use error::{Context, Error, Result, ResultExt};
