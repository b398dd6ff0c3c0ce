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
//! ## Stages, in pipeline order (one private file each, everything re-exported here)
//!
//! | file | stage | main items | paper |
//! | --- | --- | --- | --- |
//! | `template.rs` | the rigged template | [`Template`] | §2.2, §2.5.1 |
//! | `visual_hull.rs` | distance to the visual hull: nearest contour ray per pixel, cone scaling, polygonal hull outside | [`VisualHull`], [`ConeDistance`], [`VisualHullParams`] | §2.3.2 |
//! | `molding.rs` | Laplacian coordinates, soft constraints with barycentric rows, one symbolic factorisation | [`Molding`], [`SoftConstraint`] | §2.4.1, Eq. 2.1–2.2 |
//! | `silhouette_constraints.rs` | contour rays every 10 px; the vertex each ray pulls (scaled metric, 5 cm, 90°) | [`contour_rays`], [`silhouette_constraints`], [`SilhouetteParams`] | §2.4.2, Figure 2-6 |
//! | `shape.rs` | Algorithm 1: Eq. 2.1 initial guess, six Eq. 2.2 iterations with rotated coordinates, bilateral temporal filter | [`ShapeEstimator`], [`ShapeParams`], [`temporal_filter`] | §2.4.2 |
//! | `pose.rs` | the objective `w_D E_D + w_T E_T + w_R E_R + w_U E_U` as √-residuals with analytic Jacobians, bounded LM with joint limits, forward pass with `2θ_{t−1} − θ_{t−2}`, reverse pass | [`PoseModel`], [`fit_pose`], [`fit_frame`], [`track`], [`PoseParams`], [`UserRay`] | §2.3.1, §2.3.3 |
//! | `error.rs` | [`Error`], [`Context`] (where in a loop an error happened) | | — |
//!
//! Errors are one [`Error`]; an error inside a loop over frames, cameras, vertices or joints
//! says where ([`Error::At`] with a [`Context`]).
#![warn(missing_docs)]
#![warn(unnameable_types, unreachable_pub)]

mod error;
mod molding;
mod pose;
mod shape;
mod silhouette_constraints;
mod template;
mod visual_hull;

pub use error::{Context, Error, Result, ResultExt};
pub use molding::{Molding, SoftConstraint};
pub use pose::{
    fit_frame, fit_pose, track, JointTarget, PoseFit, PoseFrame, PoseModel, PoseParams, PoseTerms,
    PoseTrack, Temporal, UserRay, DEFAULT_EFFECTOR_MIN_WEIGHT, DEFAULT_GAMMA_WIDTH_M,
    DEFAULT_REFINEMENT_ROUNDS, DEFAULT_SAMPLES_PER_BONE, DEFAULT_W_D, DEFAULT_W_R, DEFAULT_W_T,
    DEFAULT_W_U,
};
pub use shape::{
    temporal_filter, ShapeEstimator, ShapeFrame, ShapeIteration, ShapeParams, ShapeSequence,
    DEFAULT_FILTER_PASSES, DEFAULT_FILTER_SIGMA_M, DEFAULT_RIGID_MIN_WEIGHT, DEFAULT_W_C,
    DEFAULT_W_L_STEP,
};
pub use silhouette_constraints::{
    contour_rays, silhouette_constraints, ContourRay, RayCase, SilhouetteConstraint,
    SilhouetteParams, DEFAULT_DEPTH_SAMPLES, DEFAULT_MAX_DISTANCE_M, DEFAULT_MAX_NORMAL_ANGLE_DEG,
    DEFAULT_NORMAL_SCALE,
};
pub use template::Template;
pub use visual_hull::{
    ConeDistance, ConeSample, HullDistance, HullRegion, VisualHull, VisualHullParams,
    DEFAULT_COARSE_SPACING_M, DEFAULT_MARGIN_PX, DEFAULT_POLYGON_SPACING_M,
};
