//! # multilinear-face
//!
//! Multilinear face models after D. Vlasic, *Reconstruction and Analysis of Dynamic Shapes* (MIT PhD thesis,
//! 2010), Chapter 5 (and Vlasic, Brand, Pfister, Popović, *Face Transfer with Multilinear
//! Models*, SIGGRAPH 2005): faces in full correspondence arranged into a data tensor by
//! attribute (expression × identity, or viseme × expression × identity), decomposed by the
//! N-mode SVD without factoring the vertex mode; faces from attribute weights; dials tuned to
//! named attributes; missing faces imputed from all modes jointly; template correspondence;
//! attributes tracked from video (symmetric KLT tied to the model) and faces transferred
//! between videos with the target's lifted texture.
//! The tensor algebra itself (HOSVD, HOOI, mode products) is `skin_core::tensor`.
//!
//! **Use it when** you have (or can put into correspondence) face meshes of several people ×
//! several expressions, possibly with some combinations missing, and want a compact model to
//! synthesise, edit, complete or track faces. Tracking from video needs a textured face, a few
//! 2D feature points in the first frame, and a face the model's knobs span. Faces in which
//! expression and identity simply add gain nothing over the additive model, which [`impute`]
//! detects on the known faces. The reference page, docs/multilinear-face.md in the repository,
//! has every parameter with its default and source, the validation protocol with its figures,
//! and the limitations with the tests that show them.
//!
//! ## Stages, in pipeline order (one private file each, everything re-exported here)
//!
//! | file | stage | main items | paper |
//! | --- | --- | --- | --- |
//! | `correspondence.rs` | Procrustes from feature points, then the minimal deformation (smoothness, features, closest points; features weighted first) | [`fit_template`], [`CorrespondenceParams`] (the alignment: `skin_core::math::fit_similarity`) | §5.3.2 |
//! | `face_data.rs` | the data tensor (vertices × attributes) and which faces are known | [`FaceTensor`], [`KnownFaces`] | Figure 5-3, §5.3.4 |
//! | `impute/` | the thesis's per-mode PPCA, constraints of all modes solved jointly, iterated (EM) (`ppca.rs`); the averaging baseline (`averaging.rs`); the default that chooses between them by cross-validation on the known faces (`model_choice.rs`, ours); fills as affine maps of the known faces, scored from their moments (`moments.rs`); block SPD inverse (`spd.rs`) | [`impute`], [`ImputeParams`], [`impute_ppca`], [`PpcaParams`], [`impute_by_averaging`] | §5.3.4 |
//! | `model.rs` | the multilinear model, faces from weights, the linear basis of one attribute, dial tuning | [`MultilinearModel`], [`ModelParams`], [`Dials`] | §5.3.3, Eq. 5.4, 5.5, 5.9, §5.4 |
//! | `klt.rs` (private) | symmetric pyramidal KLT per point: `Z d = e` with both images' mean gradient, forward–backward check | used by [`track_video`] | §5.4.1, Eq. 5.6 |
//! | `tracking.rs` | weak-perspective camera, coordinate descent over attributes through 2D point tracks, constant attributes accumulated over all frames, passes | [`track_points`], [`WeakPerspective`], [`TrackParams`] | §5.4.1, Eq. 5.7–5.9 |
//! | `transfer.rs` | texture lifted from a frame onto tracked geometry; new geometry rendered with it into the frame | [`lift_texture`], [`render_textured`], [`FaceTexture`] | §5.4, Figures 5-1, 5-7 |
//! | `video.rs` | tracking from video: KLT systems weighted into the model solves (Eq. 5.7), multi-scale, passes, initialisation from feature points, lost-face detection | [`track_video`], [`VideoTrackParams`], [`FeaturePoints`], [`VideoTrack`] | §5.4.1–5.4.2 |
//! | `error.rs` | [`Error`], [`Context`] | | — |
//! | `validation/` (feature `validation`) | data sets from the ICT face basis with a measured interaction, hold-out masks, the imputation metric, re-meshed scans, rendered textured face videos | `validation` | §5.3.1, §5.4 |
//!
//! Errors are one [`Error`]; an error inside a loop says where ([`Error::At`] with a
//! [`Context`]: `Frame(i)` is the `i`-th face of a list, or the attribute mode of an
//! all-missing slice); tracking that loses the face is [`Error::FaceLost`] at its frame.
//!
//! ## Quick start
//!
//! Six small "faces" that vary bilinearly with two expressions and three people: the model
//! at full rank reproduces each face from its weights (Eq. 5.5), and a held-out face is
//! imputed from the others.
//!
//! ```
//! use multilinear_face::{impute, FaceTensor, ImputeParams, KnownFaces, ModelParams, MultilinearModel};
//! use skin_core::math::DVec3;
//!
//! let face = |e: f64, i: f64| -> Vec<DVec3> {
//!     (0..20)
//!         .map(|k| {
//!             let k = k as f64;
//!             DVec3::new(k, (0.3 * k).sin() * (1.0 + 0.5 * i), e * (0.2 * k).cos() * (1.0 + 0.3 * i))
//!         })
//!         .collect()
//! };
//! let faces: Vec<Vec<DVec3>> = (0..6).map(|f| face((f / 3) as f64, (f % 3) as f64)).collect();
//! let data = FaceTensor::from_faces(&[2, 3], &faces)?; // 2 expressions × 3 people
//! let (model, fit) = MultilinearModel::fit(&data, &ModelParams::new(&[2, 3]))?;
//! assert!(fit.hooi_rel_error < 1e-6);
//! let w = [model.training_weights(0, 1)?, model.training_weights(1, 2)?];
//! let f = model.face(&w)?; // expression 1 of person 2
//! assert!(f[7].distance(faces[5][7]) < 1e-9);
//!
//! // Hold out expression 1 of person 0 and impute it from the other five faces.
//! let known = KnownFaces::new(&[2, 3], vec![true, true, true, false, true, true])?;
//! let filled = impute(&data, &known, &ImputeParams::default())?;
//! assert_eq!(filled.faces.face(3)?.len(), 20);
//! # Ok::<(), multilinear_face::Error>(())
//! ```
//!
//! [`track_points`] and [`fit_template`] have runnable examples too.
#![cfg_attr(docsrs, feature(doc_cfg))]
#![warn(missing_docs)]
#![warn(unnameable_types, unreachable_pub)]

mod correspondence;
mod error;
mod face_data;
mod impute;
mod klt;
mod model;
mod tracking;
mod transfer;
#[cfg(feature = "validation")]
#[cfg_attr(docsrs, doc(cfg(feature = "validation")))]
pub mod validation;
mod video;

pub use correspondence::{fit_template, CorrespondenceParams, TemplateFit};
pub use error::{Context, Error, Result, ResultExt};
pub use face_data::{FaceTensor, KnownFaces};
pub use impute::{
    impute, impute_by_averaging, impute_ppca, Imputation, ImputeModel, ImputeParams,
    PpcaImputation, PpcaParams,
};
pub use model::{Dials, ModelFit, ModelParams, MultilinearModel};
pub use tracking::{mean_weights, track_points, PointTrack, TrackParams, WeakPerspective};
pub use transfer::{lift_texture, render_textured, FaceTexture};
pub use video::{track_video, FeaturePoints, VideoTrack, VideoTrackParams};
