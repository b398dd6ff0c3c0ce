#![doc = include_str!("../README.md")]
//!
//! ## Stages, in pipeline order
//!
//! | Stage | Thesis | Public items |
//! |---|---|---|
//! | the rigged template | §2.2, §2.5.1 | [`Template`] |
//! | visual-hull distance by the nearest contour ray | §2.3.2 | [`ContourRayHull`], [`ConeDistance`], [`ContourRayHullParams`] |
//! | one frame's observations | §2.2, Figure 2-3 | [`FrameObservation`] |
//! | pose: `w_D E_D + w_T E_T + w_R E_R + w_U E_U`, forward and reverse passes | §2.3.1, §2.3.3 | [`track`], [`fit_frame`], [`fit_pose`], [`PoseModel`], [`PoseParams`], [`UserRay`] |
//! | interactive correction | §2.3.3, Figure 2-4 | [`PoseEditor`] |
//! | the user who fixes hard frames during the forward pass | §2.3.3 | [`FrameCorrector`], [`track_corrected`], [`capture_sequence_corrected`] |
//! | Laplacian coordinates, soft constraints | §2.4.1, Eq. 2.1–2.2 | [`Molding`], [`SoftConstraint`] |
//! | silhouette constraints | §2.4.2, Figure 2-6 | [`contour_rays`], [`silhouette_constraints`], [`SilhouetteParams`] |
//! | shape: Algorithm 1 | §2.4.2 | [`ShapeEstimator`], [`ShapeParams`], [`temporal_filter`] |
//! | the whole sequence (pose, then shape) | §2.2 | [`capture_sequence`] → [`SequenceCapture`] |
//! | Table 2.1 metrics | §2.5.2 | [`silhouette_error_pct`], [`edge_error_pct`] |
//! | template edits carried to every frame | §2.5.3, Figure 2-9 | [`DeformationTransfer`] |
//! | a dynamic shape model learned from molded sequences, driven by poses (beyond: Ch. 6, Dyna) | Ch. 6, Figure 6-1 | [`shape_model::ShapeModel`], [`shape_model::ShapeDriver`], [`shape_model::ShapeModelParams`] |
//! | articulated ellipsoids, robust fit | Fua et al. §4.2, §5 | [`EllipsoidModel`], [`fit_ellipsoids`], [`fit_ellipsoids_multi`], [`EllipsoidParams`] |
//! | automatic first pose | Fua et al. §4.2, §5 | [`initialise_pose`], [`AutoInitParams`] |
//! | bone lengths and widths from the first frames | Fua et al. §5; Vlasic §2.5.1 | [`size_performer`], [`size_from_poses`], [`SizingParams`], [`Template::resized`] |
//!
//! With the cargo feature `validation`: the ellipsoid fit's studio scenario and its scores
//! (`ellipsoid_scenario`, `score_ellipsoids`, `EllipsoidScenarioParams`) and `OracleUser`, which
//! emulates the frame-fixing user from the true poses.
//!
//! Errors are one [`Error`]; an error inside a loop over frames, cameras, vertices or joints
//! says where ([`Error::At`] with a [`Context`]).
#![cfg_attr(docsrs, feature(doc_cfg))]
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
pub mod shape_model;
mod silhouette_constraints;
mod sizing;
mod template;
mod visual_hull;

pub use editing::DeformationTransfer;
#[cfg(feature = "validation")]
#[cfg_attr(docsrs, doc(cfg(feature = "validation")))]
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
#[cfg_attr(docsrs, doc(cfg(feature = "validation")))]
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
    ShapeStart,
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
