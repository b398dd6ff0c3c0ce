//! The whole pipeline of Vlasic 2010 §2.2 (Figure 2-3): per frame the observations (visual
//! hull §2.3.2, contour rays §2.4.2), then pose tracking (§2.3) and shape estimation (§2.4,
//! Algorithm 1) over the sequence.

use std::time::Instant;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use skin_core::camera::Camera;
use skin_core::image::Mask;

use crate::error::{Context, Error, Result, ResultExt};
use crate::pose::{
    track_corrected, FrameCorrector, PoseFrame, PoseModel, PoseParams, PoseTrack, UserRay,
};
use crate::shape::{ShapeEstimator, ShapeFrame, ShapeParams, ShapeSequence};
use crate::silhouette_constraints::{contour_rays, ContourRay, SilhouetteParams};
use crate::template::Template;
use crate::visual_hull::{check_views, ContourRayHull, ContourRayHullParams};

/// What one frame's silhouettes give the method: the visual hull (pose, §2.3.2) and the
/// contour rays of every camera (shape, §2.4.2).
#[derive(Debug)]
pub struct FrameObservation {
    /// The frame's visual hull.
    pub hull: ContourRayHull,
    /// Contour rays of all cameras, sampled every `sample_step_px`.
    pub rays: Vec<ContourRay>,
}

impl FrameObservation {
    /// Builds the hull and the contour rays of one frame (cameras in parallel).
    ///
    /// # Errors
    /// As [`ContourRayHull::new`] and [`contour_rays`], wrapped with the camera.
    pub fn new(
        cameras: &[Camera],
        masks: &[Mask],
        hull: &ContourRayHullParams,
        silhouette: &SilhouetteParams,
    ) -> Result<Self> {
        check_views(cameras, masks)?;
        let hull = ContourRayHull::new(cameras, masks, hull)?;
        let per_camera = cameras
            .par_iter()
            .zip(masks)
            .enumerate()
            .map(|(c, (camera, mask))| {
                contour_rays(camera, mask, silhouette).at(Context::Camera(c))
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(FrameObservation {
            hull,
            rays: per_camera.concat(),
        })
    }

    /// The frame as the pose tracker takes it, with `user` rays (§2.3.3; `&[]` for none).
    pub fn pose_frame<'a>(&'a self, user: &'a [UserRay]) -> PoseFrame<'a> {
        PoseFrame {
            hull: &self.hull,
            rays: &self.rays,
            user,
        }
    }
}

/// Poses and shapes of a captured sequence, with the time each stage took.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SequenceCapture {
    /// Poses after the forward and reverse passes (§2.3.3).
    pub poses: PoseTrack,
    /// Shapes after Algorithm 1 (§2.4.2).
    pub shapes: ShapeSequence,
    /// Wall-clock time of pose estimation (both passes, refinement included), s.
    pub pose_seconds: f64,
    /// Wall-clock time of shape estimation, s.
    pub shape_seconds: f64,
}

/// Captures a sequence (§2.2): pose tracking through the hulls from `first_guess` (the
/// user's fit of the first frame, §2.3.3) with the refinement term, then Algorithm 1 on the
/// tracked poses. `user` holds each frame's user rays, or is empty for none.
///
/// # Errors
/// [`Error::Empty`] for no frame; [`Error::SizeMismatch`] when `user` is neither empty nor one
/// list per frame; errors of [`PoseModel::new`], [`ShapeEstimator::new`], [`crate::track`] and
/// [`ShapeEstimator::estimate`].
pub fn capture_sequence(
    template: &Template,
    observations: &[FrameObservation],
    first_guess: &[f64],
    user: &[Vec<UserRay>],
    pose: &PoseParams,
    shape: &ShapeParams,
) -> Result<SequenceCapture> {
    let mut accept = |_: usize, _: &[f64]| Vec::new();
    capture_sequence_corrected(
        template,
        observations,
        first_guess,
        user,
        &mut accept,
        pose,
        shape,
    )
}

/// [`capture_sequence`] with a user who fixes frames during the forward pass
/// ([`track_corrected`], §2.3.3); the rays it added are in
/// [`SequenceCapture::poses`]`.added_user_rays`.
///
/// # Errors
/// As [`capture_sequence`], and those of [`track_corrected`].
pub fn capture_sequence_corrected(
    template: &Template,
    observations: &[FrameObservation],
    first_guess: &[f64],
    user: &[Vec<UserRay>],
    corrector: &mut dyn FrameCorrector,
    pose: &PoseParams,
    shape: &ShapeParams,
) -> Result<SequenceCapture> {
    if observations.is_empty() {
        return Err(Error::Empty {
            what: "frames (one observation each)",
        });
    }
    if !user.is_empty() && user.len() != observations.len() {
        return Err(Error::SizeMismatch {
            what: "user-ray lists vs frames (give one list per frame, or none at all)",
            expected: observations.len(),
            got: user.len(),
        });
    }
    let model = PoseModel::new(template, pose)?;
    let mut estimator = ShapeEstimator::new(template.clone(), shape.clone())?;
    let frames: Vec<PoseFrame<'_>> = observations
        .iter()
        .enumerate()
        .map(|(t, o)| o.pose_frame(user.get(t).map_or(&[], Vec::as_slice)))
        .collect();
    let start = Instant::now();
    let poses = track_corrected(
        &model,
        &frames,
        first_guess,
        Some(&mut estimator),
        pose,
        corrector,
    )?;
    let pose_seconds = start.elapsed().as_secs_f64();
    let shape_frames: Vec<ShapeFrame<'_>> = poses
        .poses
        .iter()
        .zip(observations)
        .map(|(theta, o)| ShapeFrame {
            theta,
            rays: &o.rays,
        })
        .collect();
    let start = Instant::now();
    let shapes = estimator.estimate(&shape_frames)?;
    let shape_seconds = start.elapsed().as_secs_f64();
    Ok(SequenceCapture {
        poses,
        shapes,
        pose_seconds,
        shape_seconds,
    })
}
