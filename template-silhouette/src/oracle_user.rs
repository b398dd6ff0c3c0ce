//! The user who fixes hard frames (§2.3.3; Table 2.1 counts the "fixed frames"), emulated for
//! validation (feature `validation`). It sees the true poses, so it is an oracle: it stands
//! for a person who looks at each tracked frame, sees a joint off its limb and drags it to
//! its place in two camera views.

use skin_core::camera::Camera;
use skin_core::math::Ray;
use skin_core::skeleton::Skeleton;

use crate::error::{Error, Result};
use crate::pose::{FrameCorrector, UserRay};

/// An emulated user (an oracle: it sees the truth) for [`crate::track_corrected`] and
/// [`crate::capture_sequence_corrected`]: after each forward-pass fit, every joint farther
/// than `threshold_m` from its true position gets one [`UserRay`] through its true position
/// from each of two cameras, as a person dragging the joint in two views would place.
///
/// A threshold of 5 cm is where a joint visibly leaves its limb in a camera view of the
/// studio; the user's own placement is exact (the rays pass through the true joint).
#[derive(Debug, Clone)]
#[cfg_attr(docsrs, doc(cfg(feature = "validation")))]
pub struct OracleUser {
    skeleton: Skeleton,
    truth: Skeleton,
    true_poses: Vec<Vec<f64>>,
    cameras: [Camera; 2],
    threshold_m: f64,
}

impl OracleUser {
    /// A user who compares the tracked `skeleton`'s joints with those of the `truth`
    /// skeleton at `true_poses` (one per frame), and places rays from the centres of
    /// `cameras`.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] when the skeletons' joint counts differ; errors of
    /// [`Skeleton::check_pose`] for a true pose of another skeleton;
    /// [`Error::InvalidParam`] for a threshold that is not positive and finite.
    pub fn new(
        skeleton: &Skeleton,
        truth: &Skeleton,
        true_poses: Vec<Vec<f64>>,
        cameras: [Camera; 2],
        threshold_m: f64,
    ) -> Result<Self> {
        if skeleton.joint_count() != truth.joint_count() {
            return Err(Error::SizeMismatch {
                what: "joints of the tracked vs the true skeleton (the user compares joint \
                       by joint)",
                expected: truth.joint_count(),
                got: skeleton.joint_count(),
            });
        }
        for theta in &true_poses {
            truth.check_pose("true pose", theta)?;
        }
        if !(threshold_m.is_finite() && threshold_m > 0.0) {
            return Err(Error::InvalidParam {
                name: "threshold_m",
                reason: format!("give a positive distance in m, got {threshold_m}"),
            });
        }
        Ok(OracleUser {
            skeleton: skeleton.clone(),
            truth: truth.clone(),
            true_poses,
            cameras,
            threshold_m,
        })
    }
}

impl FrameCorrector for OracleUser {
    /// Rays for every joint of `theta` farther than the threshold from the truth; none for a
    /// frame without a true pose or a pose the skeletons cannot pose.
    fn correct(&mut self, t: usize, theta: &[f64]) -> Vec<UserRay> {
        let Some(true_theta) = self.true_poses.get(t) else {
            return Vec::new();
        };
        let (Ok(tracked), Ok(truth)) = (
            self.skeleton.forward_kinematics(theta),
            self.truth.forward_kinematics(true_theta),
        ) else {
            return Vec::new();
        };
        let (tracked, truth) = (tracked.joint_positions(), truth.joint_positions());
        let mut rays = Vec::new();
        for (joint, (a, b)) in tracked.iter().zip(&truth).enumerate() {
            if a.distance(*b) > self.threshold_m {
                for camera in &self.cameras {
                    let origin = camera.centre();
                    rays.push(UserRay {
                        joint,
                        ray: Ray::new(origin, *b - origin),
                    });
                }
            }
        }
        rays
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pose::tests::studio;

    /// Joints off by more than the threshold get two rays each, through their true places;
    /// a frame at the truth gets none; bad construction is an error.
    #[test]
    fn rays_go_through_the_true_joints_that_are_off() {
        let st = studio(20);
        let sk = st.template.skeleton();
        let cameras = [st.cameras[0].clone(), st.cameras[2].clone()];
        let mut user =
            OracleUser::new(sk, sk, vec![st.truth.clone()], cameras.clone(), 0.05).unwrap();
        assert!(user.correct(0, &st.truth).is_empty());
        assert!(
            user.correct(1, &st.truth).is_empty(),
            "no truth for frame 1"
        );
        let mut off = st.truth.clone();
        let elbow = sk.joint_dofs(sk.joint_index("l_elbow").unwrap()).start;
        off[elbow] += 1.0;
        let rays = user.correct(0, &off);
        assert!(!rays.is_empty() && rays.len().is_multiple_of(2));
        let truth = sk.forward_kinematics(&st.truth).unwrap().joint_positions();
        for r in &rays {
            let d = (truth[r.joint] - r.ray.origin)
                .cross(r.ray.direction.normalize())
                .length();
            assert!(d < 1e-9, "ray {d} m from the true joint");
        }
        assert!(OracleUser::new(sk, sk, vec![], cameras.clone(), f64::NAN).is_err());
        assert!(OracleUser::new(sk, sk, vec![], cameras.clone(), 0.0).is_err());
        assert!(OracleUser::new(sk, sk, vec![vec![0.0; 2]], cameras, 0.05).is_err());
    }
}
