//! Retro-reflective markers (Fua et al., "Human body modeling and motion analysis from video
//! sequences", §2): detection in grey images, multi-view forward intersection, tracking.
//!
//! | file | holds | paper |
//! | --- | --- | --- |
//! | `bar_calibration.rs` | [`calibrate_with_bar`]: self-calibrating bundle adjustment of the cameras from a bar of known length with a marker at each end | §2.2 |
//! | `detect.rs` | [`detect_markers`]: high-pass filter, threshold, connected components, intensity-weighted centroids | §2.3 |
//! | `triangulate.rs` | [`triangulate`]: linear ray intersection + Gauss–Newton on the reprojection error, per-view residuals | §2.3 (forward intersection) |
//! | `triangulate.rs` | [`reconstruct_markers`]: correspondence of unlabelled detections across cameras (pair hypotheses completed in the other views) | §2.3 |
//! | `track.rs` | [`track_markers`]: the three-frame rule (velocity volume, reduced acceleration volume, smallest acceleration), broken and restarted trajectories; [`TrackParams::human`]: the volumes from published human speed and acceleration limits | §2.4 |
//!
//! ## Example
//! ```
//! use skin_core::camera::{Intrinsics, Rig};
//! use skin_core::markers::{triangulate, MarkerView};
//! use skin_core::math::DVec3;
//! let k = Intrinsics::from_horizontal_fov(0.9, 640, 480)?;
//! let rig = Rig::ring(3, 3.0, 1.5, DVec3::new(0.0, 1.0, 0.0), DVec3::Y, k)?;
//! let marker = DVec3::new(0.1, 1.2, -0.05);
//! let views = rig
//!     .cameras
//!     .iter()
//!     .map(|c| Ok(MarkerView { camera: c, pixel: c.project(marker)? }))
//!     .collect::<skin_core::Result<Vec<_>>>()?;
//! let t = triangulate(&views)?;
//! assert!((t.point - marker).length() < 1e-9 && t.rms_px < 1e-6);
//! # Ok::<(), skin_core::Error>(())
//! ```

mod bar_calibration;
mod detect;
mod track;
mod triangulate;

/// Default marker sphere radius, m (the 5–10 mm retro-reflective balls of optical capture).
pub const DEFAULT_MARKER_RADIUS_M: f64 = 0.008;
/// Default distance of a marker's sphere centre from the skin along the normal, m (the radius
/// plus a 2 mm base): what a fit to marker centres subtracts to reach the skin.
pub const DEFAULT_MARKER_OFFSET_M: f64 = 0.010;

pub use bar_calibration::{
    bar_length_rms_m, calibrate_with_bar, synthetic_bar_calibration, BarCalibration,
    BarCalibrationParams, SyntheticBarCalibration,
};
pub use detect::{detect_markers, MarkerBlob, MarkerDetectParams};
pub use track::{
    id_switches, track_markers, TrackParams, Trajectory, HUMAN_MAX_ACCELERATION_M_PER_S2,
    HUMAN_MAX_SPEED_M_PER_S,
};
pub use triangulate::{
    reconstruct_markers, triangulate, MarkerView, ReconstructedMarker, Triangulation,
};
