//! What the model sees of a pose and of the recent motion: the pose features of its
//! pose-dependent part and the motion inputs of its dynamic part.

use serde::{Deserialize, Serialize};
use skin_core::math::{DMat3, DQuat, DVec3};
use skin_core::skeleton::ForwardKinematics;

use crate::template::Template;

/// Smallest skin weight with which a bone counts as carrying a loose vertex (a drive joint).
const DRIVE_MIN_WEIGHT: f64 = 0.2;

/// Which joints feed the model, and their rest rotations.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(crate) struct FeatureLayout {
    /// Joints whose local rotation is a pose feature: every joint but the root.
    pose_joints: Vec<usize>,
    /// Joints whose local angular velocity is a motion input: the bones that carry the
    /// template's loose vertices (the root's children when it marks none).
    drive_joints: Vec<usize>,
    /// Each joint's local rotation at rest (θ = 0), parent frame from joint frame.
    rest_local: Vec<DQuat>,
}

/// The kinematic state of one frame the motion inputs are differences of.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Kinematics {
    root_position: DVec3,
    root_rotation: DQuat,
    /// Local rotations of the drive joints.
    drive: Vec<DQuat>,
}

fn local_rotation(fk: &ForwardKinematics, parent: Option<usize>, j: usize) -> DQuat {
    let w = fk.world_from_joint();
    let local = match parent {
        Some(p) => w[p].inverse() * w[j],
        None => w[j],
    };
    DQuat::from_mat3(&local.matrix3).normalize()
}

/// The rotation vector (axis × angle, radians) of the shortest rotation `q`.
fn log(q: DQuat) -> DVec3 {
    if q.w < 0.0 { -q } else { q }.to_scaled_axis()
}

impl FeatureLayout {
    pub(crate) fn new(template: &Template) -> crate::Result<Self> {
        let skeleton = template.skeleton();
        let joints = skeleton.joints();
        let fk = skeleton.forward_kinematics(&skeleton.rest_pose())?;
        let rest_local = (0..joints.len())
            .map(|j| local_rotation(&fk, joints[j].parent, j))
            .collect();
        let pose_joints: Vec<usize> = (0..joints.len())
            .filter(|&j| joints[j].parent.is_some())
            .collect();
        let mut carries = vec![false; joints.len()];
        for v in (0..template.vertex_count()).filter(|&v| template.is_loose(v)) {
            for (b, w) in template.weights().influences(v) {
                if w >= DRIVE_MIN_WEIGHT {
                    carries[b as usize] = true;
                }
            }
        }
        carries[0] = false;
        let mut drive_joints: Vec<usize> = (0..joints.len()).filter(|&j| carries[j]).collect();
        if drive_joints.is_empty() {
            drive_joints = skeleton.children(0).collect();
        }
        Ok(FeatureLayout {
            pose_joints,
            drive_joints,
            rest_local,
        })
    }

    /// Number of pose features: nine per pose joint, three for gravity.
    pub(crate) fn pose_len(&self) -> usize {
        9 * self.pose_joints.len() + 3
    }

    /// Number of motion inputs: the root's velocity, acceleration, angular velocity and
    /// angular acceleration in its own frame, and each drive joint's local angular velocity.
    pub(crate) fn motion_len(&self) -> usize {
        12 + 3 * self.drive_joints.len()
    }

    /// The pose features of a posed skeleton: per pose joint, its local rotation relative to
    /// rest minus the identity (the nine entries of `R_rest⁻¹ R − I`, SMPL's pose-corrective
    /// features: zero at rest, linear in small rotations, no angle wrap), then gravity's
    /// direction in the root's frame (how the body leans, which decides where cloth hangs).
    pub(crate) fn pose(
        &self,
        fk: &ForwardKinematics,
        skeleton_parents: &[Option<usize>],
    ) -> Vec<f64> {
        let mut f = Vec::with_capacity(self.pose_len());
        for &j in &self.pose_joints {
            let q = self.rest_local[j].inverse() * local_rotation(fk, skeleton_parents[j], j);
            let m = DMat3::from_quat(q) - DMat3::IDENTITY;
            f.extend_from_slice(&m.to_cols_array());
        }
        let root = DQuat::from_mat3(&fk.world_from_joint()[0].matrix3).normalize();
        f.extend_from_slice(&(root.inverse() * DVec3::NEG_Y).to_array());
        f
    }

    /// The state the motion inputs difference.
    pub(crate) fn kinematics(
        &self,
        fk: &ForwardKinematics,
        skeleton_parents: &[Option<usize>],
    ) -> Kinematics {
        let w0 = fk.world_from_joint()[0];
        Kinematics {
            root_position: w0.translation,
            root_rotation: DQuat::from_mat3(&w0.matrix3).normalize(),
            drive: self
                .drive_joints
                .iter()
                .map(|&j| local_rotation(fk, skeleton_parents[j], j))
                .collect(),
        }
    }

    /// The motion inputs at frame `t` from the states of frames `t − 2`, `t − 1`, `t`
    /// (backward differences over `dt_s`; at a sequence's start the missing states repeat the
    /// first, so the body starts at rest). Vectors are in the root's frame at `t`: what a
    /// garment hanging from the hips feels, whichever way the performer faces.
    pub(crate) fn motion(&self, [k2, k1, k0]: [&Kinematics; 3], dt_s: f64) -> Vec<f64> {
        let to_root = k0.root_rotation.inverse();
        let velocity = to_root * (k0.root_position - k1.root_position) / dt_s;
        let acceleration = to_root * (k0.root_position - 2.0 * k1.root_position + k2.root_position)
            / (dt_s * dt_s);
        let omega = log(k1.root_rotation.inverse() * k0.root_rotation) / dt_s;
        let omega_before = log(k2.root_rotation.inverse() * k1.root_rotation) / dt_s;
        let alpha = (omega - omega_before) / dt_s;
        let mut u = Vec::with_capacity(self.motion_len());
        for v in [velocity, acceleration, omega, alpha] {
            u.extend_from_slice(&v.to_array());
        }
        for (a, b) in k1.drive.iter().zip(&k0.drive) {
            u.extend_from_slice(&(log(a.inverse() * *b) / dt_s).to_array());
        }
        u
    }
}
