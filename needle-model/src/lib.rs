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
//! prototype poses then predicts every needle's length for any new pose (§5).
//!
//! Stages, one module each: [`primitive`] (needles in rings, Table 3.1 layout), [`config`]
//! (configuration spaces, §3.3), [`sync`] (video/mocap time offset, §4.2), [`observe`]
//! (silhouette walks, §4.3), [`store`] (compact observation storage), [`params`]
//! (reconstruction parameters, §6.3), [`prototypes`] (prototype locations and robust-minimum
//! shapes, §5.2–5.3), [`nrbf`] (the normalised RBF, §5.1), [`reconstruct`] (the whole body,
//! §5.3–5.4), [`animate`](mod@animate) (posed needle endpoints, §5.4), [`surface`] (primitive meshes and the
//! watertight union body, §3.2), [`silhouette_error`] (§6.2) and [`select`] (automatic
//! parameter selection, §6.3).
//!
//! ```no_run
//! use needle_model::{BodyLayout, FrameInput, NeedleBody, ObserveParams, Observer};
//! # fn run(skeleton: skin_core::skeleton::Skeleton, cameras: Vec<skin_core::camera::Camera>,
//! #        theta: Vec<f64>, masks: Vec<skin_core::image::Mask>) -> needle_model::Result<()> {
//! let body = NeedleBody::new(&skeleton, &BodyLayout::table_3_1())?; // 6 600 needles
//! let observer = Observer::new(body, skeleton, cameras, ObserveParams::default())?;
//! let acc = observer.accumulate(&[FrameInput { theta: &theta, masks: &masks }])?;
//! println!("{} observations", acc.store.total_observations());
//! # Ok(()) }
//! ```
#![warn(missing_docs)]

pub mod animate;
#[cfg(feature = "validation")]
pub mod baseline;
pub mod config;
pub mod device;
pub mod error;
pub mod nrbf;
pub mod observe;
pub mod params;
pub mod primitive;
pub mod prototypes;
pub mod reconstruct;
pub mod select;
pub mod silhouette_error;
pub mod store;
pub mod surface;
pub mod sync;
#[cfg(feature = "validation")]
pub mod truth;

pub use animate::{animate, AnimatedBody, AnimatedPrimitive};
#[cfg(feature = "validation")]
pub use baseline::SkinnedShape;
pub use config::ConfigSpace;
pub use device::{calibrate_device, DeviceCalibration, DeviceParams, DeviceTrack, DeviceVideo};
pub use error::{Error, Result};
pub use nrbf::{Nrbf, NrbfFit};
pub use observe::{Accumulation, FrameInput, ObserveParams, ObserveStats, Observer, Walk};
pub use params::ReconstructionParams;
pub use primitive::{BodyLayout, NeedleBody, Primitive, PrimitiveSpec};
pub use prototypes::{PrototypeLocations, PrototypeShapes};
pub use reconstruct::{NeedleModel, Reconstruction};
pub use select::{
    select_params, validation_error, Parameter, ParameterCurve, Selection, SelectionParams,
    ValidationFrame,
};
pub use silhouette_error::{
    FrameSilhouetteError, SilhouetteError, SilhouetteErrorParams, SilhouetteScorer,
};
pub use store::{NeedleObservations, Observation, ObservationStore, PrimitiveShape};
pub use surface::{
    merged_mesh, primitive_implicit, primitive_mesh, primitive_meshes, union_mesh, SurfaceParams,
};
pub use sync::{estimate_sync_offset, SyncParams, SyncResult, VideoFrame};
