//! Forward kinematics: one sweep over the joints computing every joint frame, plus the world
//! axis and origin of every DOF (the ingredients of the Jacobian columns).
//!
//! This is `F(θ)` of Vlasic thesis §4.4.1–4.4.2 (positions `p = F(θ)` and orientations
//! `q = 𝔽(θ)` of sensors attached to bones).

use super::model::Skeleton;
use super::DofKind;
use crate::math::{DAffine3, DMat3, DQuat, DVec3};
use crate::{Error, Result};
use serde::{Deserialize, Serialize};

/// A point rigidly attached to a bone (marker, sensor position, ultrasonic source...).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct AttachedPoint {
    /// Index of the joint whose frame carries the point.
    pub joint: usize,
    /// Position in that joint's frame, metres.
    pub offset: DVec3,
}

/// A frame rigidly attached to a bone (e.g. an IMU's axes).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct AttachedFrame {
    /// Index of the joint whose frame carries this frame.
    pub joint: usize,
    /// Orientation of the attached frame relative to the joint frame (`joint_from_frame`).
    pub joint_from_frame: DQuat,
}

/// Output buffers of one forward-kinematics pass; reuse across calls to avoid allocation.
#[derive(Debug, Clone, PartialEq)]
pub struct ForwardKinematics {
    pub(super) world_from_joint: Vec<DAffine3>,
    pub(super) dof_axis_world: Vec<DVec3>,
    pub(super) dof_origin_world: Vec<DVec3>,
}

impl ForwardKinematics {
    /// Buffers sized for `skeleton` (filled with identity/zero until the first pass).
    pub fn new(skeleton: &Skeleton) -> Self {
        ForwardKinematics {
            world_from_joint: vec![DAffine3::IDENTITY; skeleton.joint_count()],
            dof_axis_world: vec![DVec3::ZERO; skeleton.dof_count()],
            dof_origin_world: vec![DVec3::ZERO; skeleton.dof_count()],
        }
    }

    /// World frame of every joint (`world_from_joint`, metres).
    pub fn world_from_joint(&self) -> &[DAffine3] {
        &self.world_from_joint
    }

    /// World position of every joint origin, metres.
    pub fn joint_positions(&self) -> Vec<DVec3> {
        self.world_from_joint
            .iter()
            .map(|t| t.translation)
            .collect()
    }

    /// World direction (unit) of every DOF axis, in θ order.
    pub fn dof_axes_world(&self) -> &[DVec3] {
        &self.dof_axis_world
    }

    /// World point each DOF axis passes through (origin of the frame preceding the DOF).
    pub fn dof_origins_world(&self) -> &[DVec3] {
        &self.dof_origin_world
    }

    /// World position of an attached point, metres.
    ///
    /// # Errors
    /// [`Error::IndexOutOfRange`] for a bad joint index.
    pub fn point(&self, point: &AttachedPoint) -> Result<DVec3> {
        Ok(self
            .frame_of(point.joint, "attached point joint")?
            .transform_point3(point.offset))
    }

    /// World orientation of an attached frame (`world_from_frame`).
    ///
    /// # Errors
    /// [`Error::IndexOutOfRange`] for a bad joint index.
    pub fn frame_rotation(&self, frame: &AttachedFrame) -> Result<DQuat> {
        let m = self.frame_of(frame.joint, "attached frame joint")?.matrix3;
        Ok(DQuat::from_mat3(&m) * frame.joint_from_frame)
    }

    pub(super) fn frame_of(&self, joint: usize, what: &'static str) -> Result<&DAffine3> {
        self.world_from_joint
            .get(joint)
            .ok_or(Error::IndexOutOfRange {
                what,
                index: joint,
                len: self.world_from_joint.len(),
            })
    }

    pub(super) fn check_size(&self, skeleton: &Skeleton) -> Result<()> {
        if self.world_from_joint.len() != skeleton.joint_count()
            || self.dof_axis_world.len() != skeleton.dof_count()
        {
            return Err(Error::SizeMismatch {
                what:
                    "ForwardKinematics buffers (build them with ForwardKinematics::new(skeleton))",
                expected: skeleton.joint_count(),
                got: self.world_from_joint.len(),
            });
        }
        Ok(())
    }
}

/// `rot ← rot · R_{eᵢ}(angle)`, touching only the two columns the rotation mixes.
#[inline]
fn rotate_about_basis_axis(rot: &mut DMat3, i: usize, angle: f64) {
    let (s, c) = angle.sin_cos();
    let (x, y, z) = (rot.x_axis, rot.y_axis, rot.z_axis);
    match i {
        0 => {
            rot.y_axis = y * c + z * s;
            rot.z_axis = z * c - y * s;
        }
        1 => {
            rot.z_axis = z * c + x * s;
            rot.x_axis = x * c - z * s;
        }
        _ => {
            rot.x_axis = x * c + y * s;
            rot.y_axis = y * c - x * s;
        }
    }
}

impl Skeleton {
    /// Forward kinematics of all joints at pose θ (allocating form of
    /// [`Skeleton::forward_kinematics_into`]).
    ///
    /// # Errors
    /// As [`Skeleton::check_pose`].
    pub fn forward_kinematics(&self, theta: &[f64]) -> Result<ForwardKinematics> {
        let mut fk = ForwardKinematics::new(self);
        self.forward_kinematics_into(theta, &mut fk)?;
        Ok(fk)
    }

    /// Forward kinematics into preallocated buffers: for each joint
    /// `world_from_joint = world_from_parent · T(offset) · M₀(θ₀) · M₁(θ₁) · …`, recording each
    /// DOF's world axis and origin on the way. No allocation.
    ///
    /// # Errors
    /// As [`Skeleton::check_pose`]; [`Error::SizeMismatch`] if `fk` was built for another
    /// skeleton.
    pub fn forward_kinematics_into(&self, theta: &[f64], fk: &mut ForwardKinematics) -> Result<()> {
        self.check_pose("theta", theta)?;
        fk.check_size(self)?;
        let mut d = 0;
        for (j, joint) in self.joints().iter().enumerate() {
            let parent = joint
                .parent
                .map_or(DAffine3::IDENTITY, |p| fk.world_from_joint[p]);
            let mut rot: DMat3 = parent.matrix3;
            let mut origin = parent.transform_point3(joint.offset);
            for dof in &joint.dofs {
                let axis_world = rot * dof.axis;
                fk.dof_axis_world[d] = axis_world;
                fk.dof_origin_world[d] = origin;
                match dof.kind {
                    DofKind::Rotation => match self.fast_axis(d) {
                        Some((i, sign)) => rotate_about_basis_axis(&mut rot, i, sign * theta[d]),
                        None => rot *= DMat3::from_axis_angle(dof.axis, theta[d]),
                    },
                    DofKind::Translation => origin += axis_world * theta[d],
                }
                d += 1;
            }
            fk.world_from_joint[j] = DAffine3::from_mat3_translation(rot, origin);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn basis_axis_fast_path_matches_general_rotation() {
        let base = DMat3::from_axis_angle(DVec3::new(0.3, -0.5, 0.8).normalize(), 0.7);
        for i in 0..3 {
            for sign in [1.0, -1.0] {
                let axis = DVec3::AXES[i] * sign;
                let mut fast = base;
                rotate_about_basis_axis(&mut fast, i, sign * 1.1);
                let general = base * DMat3::from_axis_angle(axis, 1.1);
                assert!(
                    (fast - general)
                        .abs()
                        .to_cols_array()
                        .iter()
                        .all(|v| *v < 1e-15),
                    "axis {axis}"
                );
            }
        }
    }
}
