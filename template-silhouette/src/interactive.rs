//! Interactive pose correction (Vlasic 2010 §2.3.3, Figure 2-4): the user drags a joint to
//! its place in a camera view, which adds a ray the joint must lie on (`E_U`, §2.3.1), and
//! the frame is re-optimised at once ("the skeleton is reoptimized several times per
//! second"); constraints can be removed again.

use crate::error::{Error, Result};
use crate::pipeline::FrameObservation;
use crate::pose::{
    checked_user_ray, fit_pose, PoseFit, PoseModel, PoseParams, PoseTerms, Temporal, UserRay,
};

/// The poses of a tracked sequence with each frame's user rays, re-optimised one frame at a
/// time (§2.3.3).
#[derive(Debug)]
pub struct PoseEditor<'a> {
    model: &'a PoseModel,
    observations: &'a [FrameObservation],
    params: PoseParams,
    poses: Vec<Vec<f64>>,
    user: Vec<Vec<UserRay>>,
}

impl<'a> PoseEditor<'a> {
    /// An editor over `poses` (one per observation, e.g. [`crate::PoseTrack::poses`]), with
    /// no user ray yet.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] for a pose count other than the frame count; errors of
    /// [`skin_core::skeleton::Skeleton::check_pose`] for a pose of another skeleton.
    pub fn new(
        model: &'a PoseModel,
        observations: &'a [FrameObservation],
        poses: Vec<Vec<f64>>,
        params: PoseParams,
    ) -> Result<Self> {
        if poses.len() != observations.len() {
            return Err(Error::SizeMismatch {
                what: "poses vs frames (give one pose per frame)",
                expected: observations.len(),
                got: poses.len(),
            });
        }
        for p in &poses {
            model.skeleton().check_pose("pose", p)?;
        }
        let user = vec![Vec::new(); poses.len()];
        Ok(PoseEditor {
            model,
            observations,
            params,
            poses,
            user,
        })
    }

    /// The current poses.
    pub fn poses(&self) -> &[Vec<f64>] {
        &self.poses
    }

    /// The user rays of frame `t`.
    ///
    /// # Errors
    /// [`Error::IndexOutOfRange`] for a frame past the end.
    pub fn user_rays(&self, t: usize) -> Result<&[UserRay]> {
        skin_core::check::index("frame", t, self.poses.len())?;
        Ok(&self.user[t])
    }

    /// Adds a user ray to frame `t` and re-optimises the frame; returns the fit.
    ///
    /// # Errors
    /// [`Error::IndexOutOfRange`] for a frame past the end or a joint the skeleton does not
    /// have; [`Error::NonFinite`] for a ray with NaN or infinite values or a zero direction;
    /// errors of [`Self::reoptimise`].
    pub fn add_user_ray(&mut self, t: usize, ray: UserRay) -> Result<PoseFit> {
        skin_core::check::index("frame", t, self.poses.len())?;
        let ray = checked_user_ray(self.model.skeleton(), ray)?;
        self.user[t].push(ray);
        self.reoptimise(t)
    }

    /// Removes user ray `index` of frame `t` and re-optimises the frame; returns the fit.
    ///
    /// # Errors
    /// [`Error::IndexOutOfRange`] for a frame or ray past the end; errors of
    /// [`Self::reoptimise`].
    pub fn remove_user_ray(&mut self, t: usize, index: usize) -> Result<PoseFit> {
        skin_core::check::index("frame", t, self.poses.len())?;
        skin_core::check::index("user ray", index, self.user[t].len())?;
        self.user[t].remove(index);
        self.reoptimise(t)
    }

    /// Re-optimises frame `t` from its current pose with its user rays and both temporal
    /// neighbours (the reverse pass's objective, §2.3.1), and stores the result.
    ///
    /// # Errors
    /// [`Error::IndexOutOfRange`] for a frame past the end; errors of [`fit_pose`].
    pub fn reoptimise(&mut self, t: usize) -> Result<PoseFit> {
        skin_core::check::index("frame", t, self.poses.len())?;
        let terms = PoseTerms {
            hull: &self.observations[t].hull,
            temporal: Temporal {
                previous: t.checked_sub(1).map(|p| self.poses[p].as_slice()),
                next: self.poses.get(t + 1).map(Vec::as_slice),
            },
            refinement: &[],
            user: &self.user[t],
        };
        let fit = fit_pose(self.model, &terms, &self.poses[t], &self.params)?;
        self.poses[t].clone_from(&fit.theta);
        Ok(fit)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pose::tests::studio;
    use crate::silhouette_constraints::SilhouetteParams;
    use crate::visual_hull::ContourRayHullParams;
    use skin_core::math::{DVec3, Ray};

    #[test]
    fn a_dragged_joint_follows_its_ray_and_returns_when_the_ray_is_removed() {
        // Frame 1 of three with the same silhouettes: its neighbours hold the hull's pose, so
        // the temporal term brings the wrist back once the ray is removed.
        let st = studio(20);
        let observe = || {
            FrameObservation::new(
                &st.cameras,
                &st.masks,
                &ContourRayHullParams::default(),
                &SilhouetteParams::default(),
            )
            .unwrap()
        };
        let obs = [observe(), observe(), observe()];
        let params = PoseParams::default();
        let model = PoseModel::new(&st.template, &params).unwrap();
        let sk = st.template.skeleton();
        let mut editor = PoseEditor::new(&model, &obs, vec![st.truth.clone(); 3], params).unwrap();
        let before = editor.reoptimise(1).unwrap().theta;
        // The user drags the left wrist 10 cm up in camera 0's view.
        let wrist = sk.joint_index("l_wrist").unwrap();
        let at = |theta: &[f64]| sk.forward_kinematics(theta).unwrap().joint_positions()[wrist];
        let target = at(&before) + DVec3::new(0.0, 0.1, 0.0);
        let origin = st.cameras[0].centre();
        let ray = UserRay {
            joint: wrist,
            ray: Ray::new(origin, 2.0 * (target - origin)), // not unit: normalised on entry
        };
        let fit = editor.add_user_ray(1, ray).unwrap();
        let dir = (target - origin).normalize();
        let off = |theta: &[f64]| (at(theta) - origin).cross(dir).length();
        assert!(off(&fit.theta) < 0.01, "{} m off the ray", off(&fit.theta));
        assert_eq!(editor.user_rays(1).unwrap().len(), 1);
        assert_eq!(editor.poses()[1], fit.theta);
        // Removing it lets the wrist go back to where the hull puts it.
        let back = editor.remove_user_ray(1, 0).unwrap();
        assert!(off(&back.theta) > 0.05);
        let (dragged, returned) = (
            (at(&fit.theta) - at(&before)).length(),
            (at(&back.theta) - at(&before)).length(),
        );
        eprintln!("wrist moved {dragged} m by the ray, {returned} m from its place after removal");
        assert!(returned < 0.3 * dragged, "{returned} m vs {dragged} m");
        // Bad requests are clear errors and change nothing.
        assert!(editor.remove_user_ray(1, 0).is_err());
        assert!(editor.reoptimise(3).is_err());
        let bad_joint = UserRay { joint: 999, ..ray };
        assert!(editor.add_user_ray(0, bad_joint).is_err());
        let nan = UserRay {
            ray: Ray::new(DVec3::NAN, dir),
            ..ray
        };
        assert!(matches!(
            editor.add_user_ray(0, nan),
            Err(Error::NonFinite { .. })
        ));
        assert!(editor.user_rays(1).unwrap().is_empty());
        assert!(PoseEditor::new(&model, &obs, vec![], PoseParams::default()).is_err());
    }
}
