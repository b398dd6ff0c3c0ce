//! The tracking scenario the validation scores (and the Python bindings' fixtures reuse): the
//! thesis's 6 × 9 model of the bilinear set, a person it never saw and the tracked vertices.

use super::{bilinear_face_set, feature_vertices, render_face_video, FaceSet, FaceSetParams};
use super::{FaceVideo, FaceVideoParams, IctBasis};
use crate::model::{ModelParams, MultilinearModel};
use crate::Result;

/// The bilinear set of [`FaceSetParams::default`], its model at the thesis's truncation
/// ([`ModelParams::thesis_bilinear`]), a novel person (one identity of seed 99) and the
/// tracked vertices of the neutral face.
#[derive(Debug, Clone)]
pub struct TrackingScenario {
    /// The ICT basis everything is made from.
    pub basis: IctBasis,
    /// The training set (15 people × 10 expressions).
    pub training: FaceSet,
    /// The model fitted to `training`.
    pub model: MultilinearModel,
    /// A person the model never saw, in every expression.
    pub novel: FaceSet,
    /// The tracked vertices ([`feature_vertices`] of the neutral face).
    pub tracked: Vec<usize>,
}

impl TrackingScenario {
    /// The scenario with `tracked` tracked vertices.
    ///
    /// # Errors
    /// Errors of the face sets, the model fit and [`feature_vertices`].
    pub fn new(basis: IctBasis, tracked: usize) -> Result<Self> {
        let training = bilinear_face_set(&basis, &FaceSetParams::default())?;
        let (model, _) = MultilinearModel::fit(&training.faces, &ModelParams::thesis_bilinear())?;
        let novel = bilinear_face_set(
            &basis,
            &FaceSetParams::default().with_identities(1).with_seed(99),
        )?;
        let tracked = feature_vertices(basis.neutral(), tracked)?;
        Ok(Self {
            basis,
            training,
            model,
            novel,
            tracked,
        })
    }

    /// The novel person's rendered video ([`render_face_video`] with the default
    /// [`FaceVideoParams`]): `frames` frames through the `expressions` keyframes, with
    /// `features` feature points.
    ///
    /// # Errors
    /// As [`feature_vertices`] and [`render_face_video`].
    pub fn video(
        &self,
        expressions: &[usize],
        frames: usize,
        features: usize,
    ) -> Result<FaceVideo> {
        let features = feature_vertices(self.basis.neutral(), features)?;
        render_face_video(
            &self.novel.faces,
            expressions,
            frames,
            &self.training.triangles,
            &self.basis.neutral().vertices,
            &features,
            &FaceVideoParams::default(),
        )
    }
}
