//! Cameras: the image-formation model and calibration of Sand 2003 (MS thesis §4.1; SIGGRAPH
//! paper §4), plus the tools around it.
//!
//! Sand relates motion-capture (world) points `wᵢ` to image points `pᵢ` by
//! `pᵢ = D_{c,r}(P_{q,f,a} wᵢ)`: a perspective projection with pose `q`, focal length `f` and
//! aspect ratio `a`, followed by first-order radial distortion with its own centre `c` and
//! coefficient `r`. The parameters are found by minimising image-space error over several
//! hundred correspondences with the downhill simplex method; video and motion data are first
//! synchronised by correlating a vertical image coordinate with the vertical world coordinate.
//!
//! | file | holds |
//! | --- | --- |
//! | `intrinsics.rs` | [`Intrinsics`]: focal lengths, principal point, image size |
//! | `distortion.rs` | [`RadialDistortion`]: Sand's `D_{c,r}` and its inverse |
//! | `model.rs` | [`Camera`]: pose, [`Camera::project`], [`Camera::ray`], [`Camera::unproject`], visibility |
//! | `rig.rs` | [`Rig`]: rings of cameras around a volume plus a top camera |
//! | `dlt.rs` | normalised DLT and RQ decomposition of `P = K[R|t]` |
//! | `calibrate.rs` | [`calibrate`]: DLT + Levenberg–Marquardt or Nelder–Mead refinement |
//! | `time_offset.rs` | [`estimate_time_offset`]: synchronisation of two sampled signals |
//! | `opencv.rs` | OpenCV calibration import/export (FileStorage YAML) |
//! | `synthetic.rs` | synthetic calibration problems with ground truth |
//!
//! Conventions: world and camera frames in metres; camera frame x right, y down, z forward;
//! pixels with integer coordinates at pixel centres (OpenCV).

mod calibrate;
mod distortion;
mod dlt;
mod intrinsics;
mod model;
mod opencv;
mod opencv_yaml;
mod rig;
mod synthetic;
mod time_offset;

pub use calibrate::{
    calibrate, CalibrationMethod, CalibrationParams, CalibrationReport, SimplexObjective,
};
pub use distortion::RadialDistortion;
pub use dlt::{
    decompose_projection, dlt, reprojection_rms, validate_correspondences, DltEstimate,
    ProjectionDecomposition, MIN_CORRESPONDENCES,
};
pub use intrinsics::Intrinsics;
pub use model::{Camera, Projection, ProjectionJacobian, MIN_DEPTH_M};
pub use opencv::{OpenCvCalibration, OpenCvExport, OpenCvImport, OpenCvParams};
pub use rig::Rig;
pub use synthetic::{synthetic_calibration, SyntheticCalibration, SyntheticCalibrationParams};
pub use time_offset::{estimate_time_offset, SampledSignal, TimeOffset, TimeOffsetParams};
