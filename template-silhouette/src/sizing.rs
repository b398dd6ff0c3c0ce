//! Automatic sizing of the template tracker's performer: bone lengths and
//! limb widths estimated from the first frames of the sequence, from what the tracker has —
//! each frame's visual hull (surface samples as attractors) and silhouette contour rays; no
//! markers, no stereo points. The thesis sized its skeletons by hand (Vlasic 2010 §2.5.1);
//! here the articulated ellipsoid model of Fua et al. (§4.2) is fitted over several frames
//! at once with shared lengths and widths (§5, [`fit_ellipsoids_multi`]).
//!
//! The frames are consecutive, so the poses come from temporal continuity rather than from a
//! global search per frame (which flipped the heading on fast-motion frames 20 and 40 of the
//! studio):
//! 1. frame 0: [`initialise_pose`] (global search + robust fit);
//! 2. every next frame, from the previous pose extrapolated at constant velocity
//!    (`2θ_{t−1} − θ_{t−2}`, as the tracker's forward pass, Vlasic §2.3.3), default
//!    proportions: the coordinate descent of [`initialise_pose`]'s score
//!    ([`SizingTracker::Descent`]) or the pose-only robust fit to the hull samples and rays
//!    ([`SizingTracker::Fit`], [`EllipsoidParams::pose_only`]; a bone without observations
//!    keeps its predicted pose); optionally ([`SizingParams::reinitialise`]) the global search
//!    again at the sized frames with the tracked heading as its hint;
//! 3. [`size_from_poses`]: [`SizingParams::frames`] frames spread evenly over the sequence,
//!    fitted together with shared length scales and widths, from their poses and default
//!    proportions, each frame's root position held near its given pose's
//!    ([`SizingParams::fit`]).
//!
//! [`size_from_poses`] takes poses tracked by other means instead — the template tracker's
//! ([`crate::track`]) at default proportions from the automatic first pose, which is what
//! measured best (`tests/template_capture.rs`, docs/template-silhouette.md: the ellipsoid
//! model's own tracking drifts within a few frames; its score, without a torso ellipsoid,
//! ranks wrong poses below the true one).
//!
//! [`Template::resized`](crate::Template::resized) applies the result to the tracker's
//! template.

use skin_core::check;
use skin_core::skeleton::Skeleton;

use crate::ellipsoid::{
    fit_ellipsoids, fit_ellipsoids_multi, fit_half_width, EllipsoidModel, EllipsoidMultiFit,
    EllipsoidObservations, EllipsoidParams, EllipsoidState,
};
use crate::error::{Context, Error, Result, ResultExt};
use crate::initialise::{
    descend_pose, hull_samples, initial_pose_score, initialise_pose, yaw_dof, AutoInit,
    AutoInitParams,
};
use crate::pipeline::FrameObservation;

/// Parameters of [`size_performer`]. Neither paper gives numbers; ours, per field.
#[derive(Debug, Clone, PartialEq)]
pub struct SizingParams {
    /// The first frame's automatic initialisation; its `points` (hull samples per frame) and
    /// `half_width_m` (starting widths) serve every frame. Default [`AutoInitParams::default`].
    pub init: AutoInitParams,
    /// Frames fitted together for the sizes, spread evenly over the sequence (frame 0 and the
    /// last among them). Default 8 (the `ellipsoid_fit` scenario's 8-frame fit).
    pub frames: usize,
    /// Predict each frame's start at constant velocity (`2θ_{t−1} − θ_{t−2}`); else the
    /// previous pose. Default true.
    pub extrapolate: bool,
    /// At each chosen frame, run [`initialise_pose`] again with the tracked heading as its
    /// hint ([`AutoInitParams::heading_hint_rad`]) and keep its pose when it scores lower than
    /// the tracked one (the tracking then continues from it). Default false (measured on the
    /// studio, fast motion: kept on 1 of 7 frames, 3× the time).
    pub reinitialise: bool,
    /// How each frame after the first is tracked. Default [`SizingTracker::Descent`].
    pub tracker: SizingTracker,
    /// The joint fit over the chosen frames. Default `init.fit` (hull samples at σ 2 cm) with
    /// the root's position held to the given poses'
    /// ([`EllipsoidParams::sigma_translation_prior_m`] 3 mm; the rotations stay free at
    /// `sigma_theta_prior` 1 rad). Traced on the MakeHuman performer with bone lengths up to
    /// 10 % off, sizing from the true poses: with the root free the fit lifts the pelvis by
    /// 59 mm on average (the model has no pelvis ellipsoid; the torso's hull samples pull the
    /// spine's ellipsoid up) and the thighs lengthen to reach the knees (+37 / +67 mm); held,
    /// length error 26.5 → 17.1 mm from the true poses, 21.1 → 15.4 mm from the template
    /// tracker's (docs/template-silhouette.md, "Options and their measured trade-offs"). Its
    /// IRLS scale is the default's choice ([`EllipsoidParams::kept_scale_min_rejected`]): the
    /// hull samples lose 5–9 % per round, so the scale is taken over all of them.
    pub fit: EllipsoidParams,
}

impl Default for SizingParams {
    fn default() -> Self {
        let init = AutoInitParams::default();
        SizingParams {
            fit: EllipsoidParams {
                sigma_translation_prior_m: Some(0.003),
                ..init.fit.clone()
            },
            init,
            frames: 8,
            extrapolate: true,
            reinitialise: false,
            tracker: SizingTracker::default(),
        }
    }
}

/// How [`size_performer`] tracks the frames after the first, from the previous pose.
#[derive(Debug, Clone, PartialEq)]
pub enum SizingTracker {
    /// The pose-only robust ellipsoid fit to the hull samples and contour rays
    /// ([`fit_ellipsoids`] with [`EllipsoidParams::pose_only`]).
    Fit,
    /// The coordinate descent of [`initialise_pose`]'s global score (truncated chamfer to
    /// the hull) with these steps, degrees.
    Descent(Vec<f64>),
}

impl Default for SizingTracker {
    fn default() -> Self {
        SizingTracker::Descent(vec![8.0, 4.0, 2.0])
    }
}

/// Result of [`size_performer`].
#[derive(Debug, Clone)]
pub struct Sizing {
    /// The first frame's automatic initialisation ([`size_performer`]; `None` from
    /// [`size_from_poses`]).
    pub init: Option<AutoInit>,
    /// Every frame's tracked state (default proportions).
    pub tracked: Vec<EllipsoidState>,
    /// Indices of the frames fitted together.
    pub chosen: Vec<usize>,
    /// The chosen frames whose pose came from the hinted global search
    /// ([`SizingParams::reinitialise`]) rather than from tracking.
    pub reinitialised: Vec<usize>,
    /// The joint fit over [`Sizing::chosen`] (its states are in that order).
    pub fit: EllipsoidMultiFit,
}

impl Sizing {
    /// The fitted shared unknowns (length scales, half-widths, half-lengths) with the first
    /// chosen frame's pose.
    ///
    /// # Errors
    /// [`Error::Empty`] if the fit holds no frame (not produced by [`size_performer`]).
    pub fn state(&self) -> Result<&EllipsoidState> {
        self.fit.states.first().ok_or(Error::Empty {
            what: "sized frames",
        })
    }

    /// The performer's skeleton: the model's default skeleton with every bone scaled by its
    /// fitted length scale ([`EllipsoidModel::scaled_skeleton`]).
    ///
    /// # Errors
    /// A model other than the one sized (wrong sizes).
    pub fn skeleton(&self, model: &EllipsoidModel) -> Result<Skeleton> {
        model.scaled_skeleton(self.state()?)
    }
}

/// Estimates the performer's bone lengths and limb widths from the first frames of a sequence
/// (the module docs give the steps), from the tracker's own inputs: `frames` are consecutive
/// frames' visual hulls and contour rays, frame 0 first.
///
/// # Errors
/// Invalid parameters, no frame, errors of [`initialise_pose`] (frame 0), of the per-frame fits
/// and of the joint fit (each wrapped in [`Error::At`] with [`Context::Frame`]).
pub fn size_performer(
    model: &EllipsoidModel,
    frames: &[FrameObservation],
    params: &SizingParams,
) -> Result<Sizing> {
    check::nonzero("frames", frames.len())?;
    check::nonzero("sized frames", params.frames)?;
    let first = frames.first().ok_or(Error::Empty {
        what: "sizing frames",
    })?;
    let init =
        initialise_pose(model, &first.hull, &first.rays, &params.init).at(Context::Frame(0))?;
    let observations = frames
        .iter()
        .enumerate()
        .map(|(f, o)| {
            Ok(EllipsoidObservations {
                points: hull_samples(&o.hull, params.init.points).at(Context::Frame(f))?,
                markers: Vec::new(),
                rays: o.rays.clone(),
            })
        })
        .collect::<Result<Vec<_>>>()?;
    // Tracking: default proportions, the first fit's widths, pose-only rounds.
    let widths = if init.fit_kept {
        init.fit.state.half_width.clone()
    } else {
        init.global.half_width.clone()
    };
    // A bone briefly hidden in the hull (an arm against the torso) keeps its predicted pose
    // rather than stopping the track.
    let track = EllipsoidParams {
        pose_only: true,
        min_observations_per_bone: 0,
        ..params.init.fit.clone()
    };
    let chosen = spread(frames.len(), params.frames);
    let sk = model.skeleton();
    let yaw = yaw_dof(sk, params.init.up.normalize());
    let mut tracked = vec![EllipsoidState {
        half_width: widths.clone(),
        ..model.initial_state(init.theta(), params.init.half_width_m)?
    }];
    let mut reinitialised = Vec::new();
    for (f, obs) in observations.iter().enumerate().skip(1) {
        let prev = &tracked[f - 1].theta;
        let theta: Vec<f64> = match (params.extrapolate, f.checked_sub(2)) {
            (true, Some(pp)) => prev
                .iter()
                .zip(&tracked[pp].theta)
                .map(|(a, b)| 2.0 * a - b)
                .collect(),
            _ => prev.clone(),
        };
        let theta: Vec<f64> = theta
            .iter()
            .enumerate()
            .map(|(d, &t)| sk.dof(d).limits.map_or(t, |l| t.clamp(l.min, l.max)))
            .collect();
        let start = EllipsoidState {
            half_width: widths.clone(),
            ..model.initial_state(&theta, params.init.half_width_m)?
        };
        let mut state = match &params.tracker {
            SizingTracker::Fit => {
                fit_ellipsoids(model, &start, obs, &track)
                    .at(Context::Frame(f))?
                    .state
            }
            SizingTracker::Descent(steps) => {
                let (theta, _) = descend_pose(model, &frames[f].hull, &theta, &params.init, steps)
                    .at(Context::Frame(f))?;
                EllipsoidState { theta, ..start }
            }
        };
        if params.reinitialise && chosen.contains(&f) {
            // The global search again, its heading near the tracked one; kept when it scores
            // lower than the tracked pose.
            let hinted = AutoInitParams {
                heading_hint_rad: yaw.map(|d| state.theta[d]),
                ..params.init.clone()
            };
            let hull = &frames[f].hull;
            match initialise_pose(model, hull, &frames[f].rays, &hinted) {
                Ok(again) => {
                    let cost = |t: &[f64]| initial_pose_score(model, hull, t, &params.init);
                    if cost(again.theta())? < cost(&state.theta)? {
                        state.theta = again.theta().to_vec();
                        reinitialised.push(f);
                    }
                }
                // Its local fit failed (a collapsed or empty ellipsoid): the tracked pose stays.
                Err(e) => {
                    log::warn!("frame {f}: re-initialisation failed ({e}); tracked pose kept")
                }
            }
        }
        tracked.push(state);
    }
    let poses: Vec<Vec<f64>> = tracked.iter().map(|s| s.theta.clone()).collect();
    let sized = size_from_poses(model, frames, &poses, params)?;
    Ok(Sizing {
        init: Some(init),
        tracked,
        reinitialised,
        ..sized
    })
}

/// [`SizingParams::frames`] frames spread evenly over `n` (frame 0 and the last among them).
fn spread(n: usize, k: usize) -> Vec<usize> {
    let k = k.min(n);
    if k <= 1 {
        return vec![0];
    }
    let mut c: Vec<usize> = (0..k)
        .map(|i| (i * (n - 1) + (k - 1) / 2) / (k - 1))
        .collect();
    c.dedup();
    c
}

/// The sizing step alone, from poses tracked by other means (the template tracker's
/// [`crate::track`] at default proportions, for one): [`SizingParams::frames`] frames spread
/// evenly over the sequence, fitted together ([`fit_ellipsoids_multi`], shared length scales
/// and widths) from their poses, default proportions and
/// [`AutoInitParams::half_width_m`], to the hull samples and contour rays of `frames`.
///
/// # Errors
/// Invalid parameters; `frames` and `poses` of different lengths or empty; errors of
/// [`fit_ellipsoids_multi`].
pub fn size_from_poses(
    model: &EllipsoidModel,
    frames: &[FrameObservation],
    poses: &[Vec<f64>],
    params: &SizingParams,
) -> Result<Sizing> {
    check::nonzero("frames", frames.len())?;
    check::nonzero("sized frames", params.frames)?;
    check::same_size("poses vs frames", frames.len(), poses.len())?;
    let chosen = spread(frames.len(), params.frames);
    let tracked = poses
        .iter()
        .map(|t| model.initial_state(t, params.init.half_width_m))
        .collect::<Result<Vec<_>>>()?;
    let obs = chosen
        .iter()
        .map(|&f| {
            Ok(EllipsoidObservations {
                points: hull_samples(&frames[f].hull, params.init.points).at(Context::Frame(f))?,
                markers: Vec::new(),
                rays: frames[f].rays.clone(),
            })
        })
        .collect::<Result<Vec<_>>>()?;
    let starts: Vec<EllipsoidState> = chosen.iter().map(|&f| tracked[f].clone()).collect();
    let fit = fit_ellipsoids_multi(model, &starts, &obs, &params.fit)?;
    Ok(Sizing {
        init: None,
        tracked,
        chosen,
        reinitialised: Vec::new(),
        fit,
    })
}

/// Reference sizes of a rigged template for scoring a sizing (Fua et al. Eq. 3 on the
/// template's own limbs): per bone of `model`, the length scale that makes the model's bone
/// the template skeleton's (`|offset| / L_b`; an end-site segment's from the end site), the
/// half-length `½ s_b L_b`, and the half-width of Eq. 3 fitted ([`fit_half_width`]) to the
/// template's nearly-rigid vertices ([`crate::Template::nearly_rigid`], weight ≥ 0.95) on the bone's
/// parent joint — each assigned to the nearest of that joint's bones — at the rest pose. A
/// bone without such vertices keeps `default_half_width_m`.
///
/// # Errors
/// A template whose skeleton has another joint tree than the model's
/// ([`Error::InvalidParam`]); errors of [`fit_half_width`].
pub fn reference_sizes(
    model: &EllipsoidModel,
    template: &crate::Template,
    default_half_width_m: f64,
) -> Result<EllipsoidState> {
    check::positive("default_half_width_m", default_half_width_m)?;
    let (sk, default) = (template.skeleton(), model.skeleton());
    let same_tree = sk.joint_count() == default.joint_count()
        && sk
            .joints()
            .iter()
            .zip(default.joints())
            .all(|(a, b)| a.parent == b.parent);
    if !same_tree {
        return Err(Error::InvalidParam {
            name: "template",
            reason: "the template's skeleton must have the model's joint tree; build the model \
                     from the template's skeleton"
                .into(),
        });
    }
    let bones = model.bones();
    let length_scale: Vec<f64> = bones
        .iter()
        .zip(model.default_lengths())
        .map(|(bone, &l)| {
            let j = &sk.joints()[bone.parent];
            let v = match bone.child {
                Some(c) => sk.joints()[c].offset,
                None => j.end_site.unwrap_or_default(),
            };
            v.length() / l
        })
        .collect();
    let mut state = EllipsoidState {
        half_length: model
            .default_lengths()
            .iter()
            .zip(&length_scale)
            .map(|(l, s)| 0.5 * l * s)
            .collect(),
        length_scale,
        half_width: vec![default_half_width_m; bones.len()],
        ..model.initial_state(&sk.rest_pose(), default_half_width_m)?
    };
    let ellipsoids = model.ellipsoids(&state)?;
    let mut points = vec![Vec::new(); bones.len()];
    let vertices = &template.mesh().vertices;
    for (v, joint) in template.nearly_rigid(0.95) {
        let x = vertices[v];
        let nearest = (0..bones.len())
            .filter(|&b| bones[b].parent == joint)
            .map(|b| {
                let e = &ellipsoids[b];
                let t = (x - e.centre).dot(e.axis).clamp(-e.half_bone, e.half_bone);
                (b, x.distance(e.centre + e.axis * t))
            })
            .min_by(|a, b| a.1.total_cmp(&b.1));
        if let Some((b, _)) = nearest {
            points[b].push(x);
        }
    }
    for (b, p) in points.iter().enumerate() {
        if !p.is_empty() {
            state.half_width[b] =
                fit_half_width(model, &state, b, p).at(Context::Joint(bones[b].joint()))?;
        }
    }
    Ok(state)
}

#[cfg(test)]
mod tests {
    use super::*;
    use skin_core::skeleton::{human_skeleton, HumanParams};

    #[test]
    fn reference_sizes_follow_the_template_skeleton() {
        let t = crate::template::tests::bendy();
        let model = EllipsoidModel::limbs(t.skeleton().clone(), 0.1).unwrap();
        assert_eq!(model.bones().len(), 1);
        let mut joints = t.skeleton().joints().to_vec();
        joints[1].offset *= 1.2;
        let longer = t.resized(Skeleton::new(joints).unwrap()).unwrap();
        let r = reference_sizes(&model, &longer, 0.05).unwrap();
        assert!((r.length_scale[0] - 1.2).abs() < 1e-12);
        assert!((r.half_length[0] - 0.3).abs() < 1e-12);
        // The root's rigid part is the lower half of an ellipsoid 0.15 m in radius.
        assert!(
            (0.05..0.16).contains(&r.half_width[0]),
            "{}",
            r.half_width[0]
        );
        let other =
            EllipsoidModel::limbs(human_skeleton(&HumanParams::default()).unwrap(), 0.1).unwrap();
        assert!(reference_sizes(&other, &longer, 0.05).is_err());
        assert!(reference_sizes(&model, &longer, f64::NAN).is_err());
    }

    #[test]
    fn bad_input_is_reported() {
        let sk = human_skeleton(&HumanParams::default()).unwrap();
        let model = EllipsoidModel::with_end_sites(sk, 0.1).unwrap();
        assert!(size_performer(&model, &[], &SizingParams::default()).is_err());
    }
}
