//! # needle-model
//!
//! Skin deformation captured from moving silhouettes, after P. Sand, *Reconstruction of
//! Deforming Surfaces from Moving Silhouettes* (MIT MS thesis, 2003) and Sand, McMillan and
//! Popović, *Continuous Capture of Skin Deformation* (SIGGRAPH 2003).
//!
//! The body is a set of deformable primitives, one per bone: needles in rings around the bone
//! axis (§3.1–3.2). Each frame, each needle is projected into each camera and walked outward
//! until it leaves the silhouette; the resulting length is an observation tied to the pose of
//! the bones the primitive depends on (§3.3, §4.3). A normalised radial basis function over
//! prototype poses then predicts every needle's length for any new pose (§5):
//!
//! ```text
//! l_j(x) = Σ_k v_jk K(x, p_k) / Σ_k K(x, p_k),   K(x, p) = exp(−W ‖x − p‖² / s²)   (§5.1)
//! ```
//!
//! with prototype locations `p_k` chosen by farthest-point selection (§5.2) and prototype
//! shapes `v_jk` the `F_min` percentile of the `F_near` nearest observations (§5.3).
//!
//! **Use it when** you have calibrated, synchronised video silhouettes and motion-capture
//! joint angles of a performer and want a pose-driven skin model (needle lengths or a mesh for
//! any pose) without a template mesh. Outward shape changes (muscles) are followed best;
//! concavities and the bending of skin inside a joint are not, and head, hands and neck have
//! no primitives. The reference page, docs/needle-model.md in the repository, has every
//! parameter with its default and source, the validation protocol with its figures, and the
//! limitations with the tests that show them.
//!
//! ## Stages, in pipeline order (one private file each, everything re-exported here)
//!
//! | file | stage | paper |
//! | --- | --- | --- |
//! | `primitive.rs` | [`NeedleBody`], [`BodyLayout`]: needles in rings, the Table 3.1 layout | §3.1–3.2 |
//! | `config.rs` | [`ConfigSpace`]: marker coordinates in the carrier frame | §3.3 |
//! | `device.rs` | [`calibrate_device`]: camera calibration with the calibration device | §4.1 |
//! | `sync.rs` | [`estimate_sync_offset`]: video/mocap time offset from silhouettes | §4.2 |
//! | `observe.rs` | [`Observer`]: silhouette walks of every needle | §4.3 |
//! | `store.rs` | [`ObservationStore`], [`NeedleObservations`]: 3-byte observations, tagged by frame | §4.3 |
//! | `params.rs` | [`ReconstructionParams`]: `F_near`, `F_min`, `W`, `N` | §6.3 |
//! | `prototype_locations.rs` | [`farthest_point_prototypes`] | §5.2 |
//! | `prototype_shapes.rs` | [`prototype_shapes`]: robust minimum, hole filling | §5.3 |
//! | `nrbf.rs` | [`Nrbf`]: the normalised RBF and its fit | §5.1 (fit §5.2–5.3) |
//! | `reconstruct.rs` | [`NeedleModel`]: every primitive of the body | §5.3 (outer loop) |
//! | `animate.rs` | [`animate()`]: posed needle endpoints | §5.4 |
//! | `surface.rs` | [`primitive_meshes`], [`union_mesh`]: meshes, the union body | §3.2, §5.4 |
//! | `pose_space.rs` | [`PoseSpaceModel`], [`SkinnedNeedles`]: the model as a residual over skinning | ours (pose-space deformation) |
//! | `silhouette_error.rs` | [`SilhouetteScorer`]: the silhouette error | §6.2 |
//! | `select.rs` | [`select_params`]: automatic parameter selection | §6.3 |
//! | `error.rs` | [`Error`], [`Context`] (where in a loop an error happened) | — |
//!
//! Validation equipment sits behind the cargo feature `validation` (see
//! [Validation](#validation)): `truth` (ground-truth scoring on the studio) and `baseline`
//! (the linear-blend-skinning baseline).
//!
//! Errors are one [`Error`]; an error inside a loop over primitives, needles, cameras or frames
//! says where ([`Error::At`] with a [`Context`]).
//!
//! ## Quick start
//!
//! A synthetic performer seen by two low-resolution cameras for a few frames: accumulate the
//! needle observations, reconstruct, and predict the needle lengths of one primitive.
//!
//! ```
//! use needle_model::{
//!     BodyLayout, FrameInput, NeedleBody, NeedleModel, ObserveParams, Observer,
//!     ReconstructionParams,
//! };
//! use dynamic_shapes_studio::{
//!     fast_motion, procedural_performer, studio_ring, Capture, CaptureSpec, FastMotionParams,
//!     ProceduralBodyParams,
//! };
//!
//! // The studio: a procedural performer in fast motion, two cameras at 160 × 120 px.
//! let performer = procedural_performer(&ProceduralBodyParams::default())?;
//! let skeleton = performer.skeleton.clone();
//! let motion = fast_motion(&skeleton, &FastMotionParams::default())?;
//! let rig = studio_ring(2, 160, 120)?;
//! let cameras = rig.cameras.clone();
//!
//! // Silhouettes of six frames, every tenth of the motion at its own frame rate.
//! let spec = CaptureSpec::masks_only(rig).with_frame_rate_hz(1.0 / motion.frame_time_s);
//! let capture = Capture::new(&performer, &motion, spec)?;
//! let (mut thetas, mut masks) = (Vec::new(), Vec::new());
//! for frame in capture.frames_stepped(0..60, 10) {
//!     let frame = frame?;
//!     masks.push(frame.masks());
//!     thetas.push(frame.truth.theta);
//! }
//!
//! // §4.3: walk every needle through every silhouette (a quarter of Table 3.1's density).
//! let body = NeedleBody::new(&skeleton, &BodyLayout::table_3_1().with_density(0.25))?;
//! let observer = Observer::new(body, skeleton.clone(), cameras, ObserveParams::default())?;
//! let frames: Vec<FrameInput<'_>> = thetas
//!     .iter()
//!     .zip(&masks)
//!     .map(|(theta, masks)| FrameInput { theta, masks })
//!     .collect();
//! let acc = observer.accumulate(&frames)?;
//! assert!(acc.store.total_observations() > 0);
//!
//! // §5.2–5.3: prototypes and their shapes, per primitive.
//! let params = ReconstructionParams::default().with_prototype_count_n(4);
//! let rec = NeedleModel::reconstruct(&acc.store, observer.body(), &params)?;
//!
//! // §5.4: the needle lengths of the first primitive in the first frame's pose.
//! let fk = skeleton.forward_kinematics(&thetas[0])?;
//! let primitive = &observer.body().primitives[0];
//! let x = primitive.config.point_f32(&fk)?;
//! let lengths_m = rec.model.needle_lengths(0, &x)?;
//! assert_eq!(lengths_m.len(), primitive.needle_count());
//! assert!(lengths_m.iter().all(|&l| l >= 0.0 && f64::from(l) <= primitive.max_length_m));
//! # Ok::<(), needle_model::Error>(())
//! ```
//!
//! ## Validation
//!
//! With the cargo feature `validation`, the public modules `truth` (ground truth of the
//! studio: test sets, per-vertex errors) and `baseline` (linear blend skinning with bone-heat
//! weights fitted to the same silhouettes) are compiled too. Their items are reached through
//! the module, by that one path (`needle_model::baseline::SkinnedShape`).
#![cfg_attr(docsrs, feature(doc_cfg))]
#![warn(missing_docs)]
#![warn(unnameable_types, unreachable_pub)]

mod animate;
#[cfg(feature = "validation")]
#[cfg_attr(docsrs, doc(cfg(feature = "validation")))]
pub mod baseline;
mod config;
mod device;
mod error;
mod nrbf;
mod observe;
mod params;
mod pose_space;
mod primitive;
mod prototype_locations;
mod prototype_shapes;
mod reconstruct;
mod select;
mod silhouette_error;
mod store;
mod surface;
mod sync;
#[cfg(feature = "validation")]
#[cfg_attr(docsrs, doc(cfg(feature = "validation")))]
pub mod truth;

pub use animate::{animate, AnimatedBody, AnimatedPrimitive};
pub use config::{resolve_marker, ConfigSpace, MAX_CONFIG_DIM};
pub use device::{calibrate_device, DeviceCalibration, DeviceParams, DeviceTrack, DeviceVideo};
pub use error::{Context, Error, Result, ResultExt};
pub use nrbf::{Nrbf, NrbfFit};
pub use observe::{Accumulation, Discard, FrameInput, ObserveParams, ObserveStats, Observer, Walk};
pub use params::{Neighbourhood, ReconstructionParams};
pub use pose_space::{PoseSpaceModel, PoseSpaceReconstruction, SkinnedNeedles};
pub use primitive::{BodyLayout, NeedleBody, Primitive, PrimitiveSpec};
pub use prototype_locations::{farthest_point_prototypes, PrototypeLocations};
pub use prototype_shapes::{grid_adjacency, prototype_shapes, NeighbourhoodStats, PrototypeShapes};
pub use reconstruct::{NeedleModel, PrimitiveFitReport, Reconstruction};
pub use select::{
    select_params, validation_error, Parameter, ParameterCurve, Selection, SelectionParams,
    ValidationFrame,
};
pub use silhouette_error::{
    FrameSilhouetteError, SilhouetteError, SilhouetteErrorParams, SilhouetteScorer,
};
pub use store::{
    NeedleObservations, Observation, ObservationStore, PrimitiveShape, MAX_NEEDLES_PER_PRIMITIVE,
};
pub use surface::{
    merged_mesh, primitive_implicit, primitive_mesh, primitive_meshes, union_mesh, SurfaceParams,
};
pub use sync::{estimate_sync_offset, sample_motion, SyncParams, SyncResult, VideoFrame};
