//! # template-silhouette
//!
//! Mesh animation from multi-view silhouettes by tracking a skeleton in the visual hull and
//! molding a rigged template to the silhouettes, after D. Vlasic, *Markerless Performance
//! Capture* (MIT PhD thesis, 2010), Chapter 2 (and Vlasic, Baran, Matusik, Popović,
//! *Articulated Mesh Animation from Multi-view Silhouettes*, SIGGRAPH 2008).
//!
//! The pipeline (§2.2): per frame, fit the skeleton to the visual hull (§2.3), deform the
//! template with linear blend skinning, then adjust its surface to the silhouettes with
//! Laplacian coordinates (§2.4, Algorithm 1).
//!
//! ## Stages, in pipeline order (one private file or folder each, everything re-exported here)
//!
//! | file | stage | main items | paper |
//! | --- | --- | --- | --- |
//! | `template.rs` | the rigged template | [`Template`] | §2.2, §2.5.1 |
//! | `visual_hull.rs` | distance to the visual hull by the nearest contour ray per pixel, cone scaling, polygonal hull outside | [`ContourRayHull`], [`ConeDistance`], [`ContourRayHullParams`] | §2.3.2 |
//! | `molding.rs` | Laplacian coordinates, soft constraints with barycentric rows, one symbolic factorisation | [`Molding`], [`SoftConstraint`] | §2.4.1, Eq. 2.1–2.2 |
//! | `silhouette_constraints.rs` | contour rays every 10 px; the vertex each ray pulls (scaled metric, 5 cm, 90°) | [`contour_rays`], [`silhouette_constraints`], [`SilhouetteParams`] | §2.4.2, Figure 2-6 |
//! | `shape.rs` | Algorithm 1: Eq. 2.1 initial guess, six Eq. 2.2 iterations with rotated coordinates, bilateral temporal filter | [`ShapeEstimator`], [`ShapeParams`], [`temporal_filter`] | §2.4.2 |
//! | `pose.rs` | the objective `w_D E_D + w_T E_T + w_R E_R + w_U E_U` as √-residuals with analytic Jacobians, bounded LM with joint limits, forward pass with `2θ_{t−1} − θ_{t−2}`, reverse pass | [`PoseModel`], [`fit_pose`], [`fit_frame`], [`track`], [`PoseParams`], [`UserRay`] | §2.3.1, §2.3.3 |
//! | `pipeline.rs` | one frame's observations; the whole sequence (pose, then shape) | [`FrameObservation`], [`capture_sequence`], [`SequenceCapture`] | §2.2, Figure 2-3 |
//! | `interactive.rs` | user rays added to or removed from a frame, which is re-optimised at once | [`PoseEditor`] | §2.3.3, Figure 2-4 |
//! | `metrics.rs` | silhouette error and edge error | [`silhouette_error_pct`], [`edge_error_pct`] | §2.5.2, Table 2.1 |
//! | `editing.rs` | a template edit carried to every frame by deformation transfer | [`DeformationTransfer`] | §2.5.3, Figure 2-9 |
//! | `ellipsoid/` | `model.rs`: articulated ellipsoids (Eq. 3); `observations.rs`: attractor points, markers and silhouette rays; `params.rs`; `fit.rs`: joint least squares, LM + IRLS (Tukey), one frame or several with shared lengths and widths | [`EllipsoidModel`], [`fit_ellipsoids`], [`fit_ellipsoids_multi`], [`EllipsoidParams`] | Fua et al. §4.2, §5, Eq. 3, 7–17 |
//! | `initialise.rs` | the tracker's automatic first pose: global heading / per-joint grid search on the hull, then the ellipsoid fit | [`initialise_pose`], [`AutoInitParams`] | Fua et al. §4.2, §5 |
//! | `sizing.rs` | the performer's bone lengths and widths from the first frames: automatic first pose, pose-only tracking, one fit over the most varied frames | [`size_performer`], [`SizingParams`], [`Sizing`] | Fua et al. §5; Vlasic §2.5.1 |
//! | `error.rs` | [`Error`], [`Context`] (where in a loop an error happened) | | — |
//!
//! Errors are one [`Error`]; an error inside a loop over frames, cameras, vertices or joints
//! says where ([`Error::At`] with a [`Context`]).
//!
//! ## Quick start
//!
//! A procedural performer in fast motion, seen by the 8-camera ring at 200 × 150 px for
//! three frames: visual hulls and contour rays per frame, the pose tracked through the hulls
//! (the first frame's true pose stands in for the user's manual fit of the first frame,
//! §2.3.3), then Algorithm 1 molds the template to the silhouettes.
//!
//! ```
//! use dynamic_shapes_studio::{
//!     fast_motion, procedural_performer, studio_ring, Capture, CaptureSpec, FastMotionParams,
//!     ProceduralBodyParams,
//! };
//! use skin_core::mesh::{bone_heat_weights, rest_bones, HeatWeightsParams};
//! use template_silhouette::{
//!     capture_sequence, FrameObservation, PoseParams, ShapeParams, SilhouetteParams, Template,
//!     ContourRayHullParams,
//! };
//!
//! let performer = procedural_performer(&ProceduralBodyParams::default())?;
//! let motion = fast_motion(&performer.skeleton, &FastMotionParams::default())?;
//! let rig = studio_ring(8, 200, 150)?;
//! let cameras = rig.cameras.clone();
//! let spec = CaptureSpec::masks_only(rig).with_frame_rate_hz(1.0 / motion.frame_time_s);
//! let capture = Capture::new(&performer, &motion, spec)?;
//! let (mut observations, mut first_pose) = (Vec::new(), None);
//! for frame in capture.frames_stepped(0..3, 1) {
//!     let frame = frame?;
//!     // §2.3.2 and §2.4.2: the visual hull and the contour rays of the frame.
//!     observations.push(FrameObservation::new(
//!         &cameras,
//!         &frame.masks(),
//!         &ContourRayHullParams::default(),
//!         &SilhouetteParams::default(),
//!     )?);
//!     first_pose.get_or_insert(frame.truth.theta);
//! }
//! // §2.5.1: the template rigged by bone heat (Pinocchio), as a user's scan would be; the
//! // performer's own weights generated the studio's truth and are not used.
//! let weights = bone_heat_weights(
//!     &performer.template,
//!     &rest_bones(&performer.skeleton)?,
//!     &HeatWeightsParams::default(),
//! )?;
//! let template = Template::new(performer.template.clone(), performer.skeleton.clone(), weights)?;
//! let first_guess = first_pose.unwrap_or_default();
//!
//! // §2.3 then §2.4: forward and reverse passes with the refinement term, then Algorithm 1.
//! let result = capture_sequence(
//!     &template,
//!     &observations,
//!     &first_guess,
//!     &[], // no user rays
//!     &PoseParams::default(),
//!     &ShapeParams::default(),
//! )?;
//! assert_eq!(result.poses.poses.len(), 3);
//! assert_eq!(result.shapes.frames.len(), 3);
//! assert_eq!(result.shapes.iterations.len(), 6); // w_L = 0, 0.2, ..., 1
//! # Ok::<(), template_silhouette::Error>(())
//! ```
#![warn(missing_docs)]
#![warn(unnameable_types, unreachable_pub)]

mod editing;
mod ellipsoid;
mod error;
mod initialise;
mod interactive;
mod metrics;
mod molding;
#[cfg(feature = "validation")]
mod oracle_user;
mod pipeline;
mod pose;
mod shape;
mod silhouette_constraints;
mod sizing;
mod template;
mod visual_hull;

pub use editing::DeformationTransfer;
#[cfg(feature = "validation")]
pub use ellipsoid::{
    ellipsoid_scenario, score_ellipsoids, EllipsoidScenario, EllipsoidScenarioParams,
    EllipsoidScores, ScenarioFrame, ScenarioMotion,
};
pub use ellipsoid::{
    fit_ellipsoids, fit_ellipsoids_multi, fit_half_width, Ellipsoid, EllipsoidBone, EllipsoidFit,
    EllipsoidModel, EllipsoidMultiFit, EllipsoidObservations, EllipsoidParams, EllipsoidState,
    MarkerObservation,
};
pub use error::{Context, Error, Result, ResultExt};
pub use initialise::{
    initial_pose_score, initialise_pose, pose_error, rest_pose_start, AutoInit, AutoInitParams,
};
pub use interactive::PoseEditor;
pub use metrics::{edge_error_pct, silhouette_error_pct};
pub use molding::{Molding, SoftConstraint};
#[cfg(feature = "validation")]
pub use oracle_user::OracleUser;
pub use pipeline::{
    capture_sequence, capture_sequence_corrected, FrameObservation, SequenceCapture,
};
pub use pose::{
    fit_frame, fit_pose, track, track_corrected, Effector, EffectorTargets, FrameCorrector,
    FrameFit, JointTarget, PoseFit, PoseFrame, PoseModel, PoseParams, PoseTerms, PoseTrack,
    Temporal, UserRay, MAX_CORRECTION_ROUNDS,
};
pub use shape::{
    temporal_filter, ShapeEstimator, ShapeFrame, ShapeIteration, ShapeParams, ShapeSequence,
};
pub use silhouette_constraints::{
    contour_rays, silhouette_constraints, ContourRay, RayCase, SilhouetteConstraint,
    SilhouetteParams,
};
pub use sizing::{
    reference_sizes, size_from_poses, size_performer, Sizing, SizingParams, SizingTracker,
};
pub use template::Template;
pub use visual_hull::{
    ConeDistance, ConeSample, ContourRayHull, ContourRayHullParams, HullDistance, HullRegion,
};
