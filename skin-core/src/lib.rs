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
//!
//! Cargo features: `gltf` (glTF 2.0 export of mesh sequences, `mesh::write_gltf_animation`)
//! and `decimate` (mesh decimation by edge collapses, `mesh::decimate`); both off by default.
//!
//! **Use it when** you build a capture method on calibrated cameras, an articulated skeleton
//! and triangle meshes, or want one of its pieces alone: camera calibration from 2D–3D points
//! or a waved bar, marker detection and tracking, forward kinematics with the Jacobians an
//! EKF needs, Laplacian editing through sparse least squares, bone-heat skinning weights, or
//! Tucker decompositions. The reference page, docs/skin-core.md in the repository, maps every
//! module to its paper section, lists the parameters with their defaults and sources, and
//! gives the validation figures and limitations.
//!
//! ## Quick start
//!
//! A posed skeleton seen by a camera, then a Laplacian edit (Vlasic §2.4.1) solved by sparse
//! least squares: keep a sphere's Laplacian coordinates, pull one vertex out by 0.2, pin another.
//!
//! ```
//! use nalgebra::DMatrix;
//! use nalgebra_sparse::{CooMatrix, CscMatrix};
//! use skin_core::camera::{Camera, Intrinsics};
//! use skin_core::lsq::{LsqParams, LsqProblem};
//! use skin_core::math::DVec3;
//! use skin_core::mesh::{cotangent_laplacian, shapes, LaplacianParams};
//! use skin_core::skeleton::{human_skeleton, AttachedPoint, HumanParams};
//!
//! // Forward kinematics of the human skeleton with the left elbow flexed, seen from 3 m.
//! let s = human_skeleton(&HumanParams::default())?;
//! let mut theta = s.rest_pose();
//! theta[s.dof_index("l_elbow.flexion").unwrap()] = 1.2;
//! let fk = s.forward_kinematics(&theta)?;
//! let wrist = AttachedPoint { joint: s.joint_index("l_wrist").unwrap(), offset: DVec3::ZERO };
//! let k = Intrinsics::new(800.0, 800.0, 320.0, 240.0, 640, 480)?;
//! let eye = DVec3::new(0.0, 1.0, 3.0);
//! let cam = Camera::look_at(k, eye, DVec3::new(0.0, 1.0, 0.0), DVec3::Y)?;
//! let px = cam.project(fk.point(&wrist)?)?;
//! assert!((0.0..640.0).contains(&px.x) && (0.0..480.0).contains(&px.y));
//!
//! // Laplacian editing: min ‖L X − L X₀‖² + 1000 ‖C X − D‖², one solve for x, y, z.
//! let mesh = shapes::icosphere(2)?;
//! let n = mesh.vertices.len();
//! let l = cotangent_laplacian(&mesh, &LaplacianParams::default())?;
//! let x0 = DMatrix::from_fn(n, 3, |i, c| mesh.vertices[i][c]);
//! let mut c = CooMatrix::new(2, n);
//! c.push(0, 0, 1.0); // vertex 0 moves
//! c.push(1, n - 1, 1.0); // vertex n − 1 stays
//! let mut d = DMatrix::zeros(2, 3);
//! for k in 0..3 {
//!     d[(0, k)] = 1.2 * x0[(0, k)];
//!     d[(1, k)] = x0[(n - 1, k)];
//! }
//! let solver = LsqProblem::new(l.clone())
//!     .with_term(CscMatrix::from(&c), 1000.0)
//!     .factor(&LsqParams::default())?;
//! let x = solver.solve(&(&l * &x0), &[d])?;
//! let moved = DVec3::new(x[(0, 0)], x[(0, 1)], x[(0, 2)]);
//! assert!((moved.length() - 1.2).abs() < 0.01);
//! # Ok::<(), skin_core::Error>(())
//! ```
#![cfg_attr(docsrs, feature(doc_cfg))]
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
