//! Analytic Jacobians of attached points and frames, their time derivatives, and the
//! velocity-product terms `J̇θ̇` needed by inertial observation models.
//!
//! Vlasic thesis §4.4.2: a sensor at `p = F(θ)` has velocity `v = J θ̇` and acceleration
//! `a = J θ̈ + J̇ θ̇` (Eq. 4.2, accelerometers read `rot{a − g}`); a gyroscope reads the angular
//! velocity `ω = J_ω θ̇` in its own frame (Eq. 4.3, written there as `2(𝔽* 𝕁 θ̇)_vec`, which is
//! the same quantity: `J_ω` is the quaternion Jacobian mapped to angular velocity).
//!
//! **Columns.** With `uₖ`, `oₖ` the world axis and origin of DOF k (from
//! [`ForwardKinematics`]) and p a point carried by a joint whose root path contains k:
//! rotation DOF → `J_k = uₖ × (p − oₖ)`, `J_ω,k = uₖ`; translation DOF → `J_k = uₖ`,
//! `J_ω,k = 0`. DOFs off the path give zero columns.
//!
//! **Derivatives.** Let `ωₖ`, `vₖ` be the angular velocity of the frame preceding DOF k and
//! the velocity of `oₖ` (from [`JointRates`]). Then `u̇ₖ = ωₖ × uₖ`, `ȯₖ = vₖ` and
//! rotation: `J̇_k = u̇ₖ × (p − oₖ) + uₖ × (ṗ − vₖ)`, `J̇_ω,k = u̇ₖ`;
//! translation: `J̇_k = u̇ₖ`, `J̇_ω,k = 0`.
//! Since `J̇θ̇ = θ̇ᵀ (∂²F/∂θ²) θ̇` is quadratic in θ̇, `∂(J̇θ̇)/∂θ̇ = 2 J̇` — the EKF
//! measurement Jacobian `H` of Eq. 4.2 with respect to θ̇ (§4.4.3).
//!
//! **Bias accelerations.** `J̇θ̇` itself is computed in O(1) per point from a recursive
//! (Newton–Euler-style) sweep with θ̈ = 0: across a rotation DOF with rate q̇,
//! `α ← α + (ω × u) q̇`, `ω ← ω + u q̇`; across a lever r (rest offset or translation DOF
//! `r = u q`) `v ← v + ω × r (+ u q̇)`, `a ← a + α × r + ω × (ω × r) (+ 2 ω × u q̇)`. The
//! point term is then `a + α × r + ω × (ω × r)` with `r = p − o_joint`, and the frame term
//! (angular `J̇_ω θ̇`) is α.

use super::fk::{AttachedFrame, AttachedPoint, ForwardKinematics};
use super::model::Skeleton;
use super::DofKind;
use crate::math::{DQuat, DVec3};
use crate::{Error, Result};
use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};

/// The frame angular quantities (Jacobians, angular velocities and accelerations) are
/// expressed in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum AngularFrame {
    /// World coordinates.
    #[default]
    World,
    /// The attached frame's own axes (what a gyroscope reads; Vlasic Eq. 4.3 `rot{·}`).
    /// Because `d/dt(Rᵀω) = Rᵀω̇`, angular accelerations rotate the same way.
    Local,
}

/// Velocities and velocity-product (θ̈ = 0) accelerations of every joint and DOF frame at
/// (θ, θ̇); buffers reusable across calls. World coordinates, metres, seconds, radians.
#[derive(Debug, Clone, PartialEq)]
pub struct JointRates {
    pub(super) joint_angular_velocity: Vec<DVec3>,
    pub(super) joint_origin_velocity: Vec<DVec3>,
    pub(super) joint_angular_bias: Vec<DVec3>,
    pub(super) joint_origin_bias: Vec<DVec3>,
    pub(super) dof_angular_velocity: Vec<DVec3>,
    pub(super) dof_origin_velocity: Vec<DVec3>,
}

impl JointRates {
    /// Buffers sized for `skeleton`.
    pub fn new(skeleton: &Skeleton) -> Self {
        let nj = skeleton.joint_count();
        let nd = skeleton.dof_count();
        JointRates {
            joint_angular_velocity: vec![DVec3::ZERO; nj],
            joint_origin_velocity: vec![DVec3::ZERO; nj],
            joint_angular_bias: vec![DVec3::ZERO; nj],
            joint_origin_bias: vec![DVec3::ZERO; nj],
            dof_angular_velocity: vec![DVec3::ZERO; nd],
            dof_origin_velocity: vec![DVec3::ZERO; nd],
        }
    }

    /// Angular velocity of every joint frame, world, rad/s.
    pub fn joint_angular_velocities(&self) -> &[DVec3] {
        &self.joint_angular_velocity
    }

    /// Velocity of every joint origin, world, m/s.
    pub fn joint_origin_velocities(&self) -> &[DVec3] {
        &self.joint_origin_velocity
    }

    /// Angular acceleration of every joint frame when θ̈ = 0 (`J̇_ω θ̇`), world, rad/s².
    pub fn joint_angular_bias_accelerations(&self) -> &[DVec3] {
        &self.joint_angular_bias
    }

    /// Acceleration of every joint origin when θ̈ = 0 (`J̇ θ̇`), world, m/s².
    pub fn joint_origin_bias_accelerations(&self) -> &[DVec3] {
        &self.joint_origin_bias
    }

    /// Velocity of an attached point (`J θ̇`), world, m/s. `fk` must be the pass these rates
    /// were computed from.
    ///
    /// # Errors
    /// [`Error::IndexOutOfRange`] for a bad joint index.
    pub fn point_velocity(&self, fk: &ForwardKinematics, point: &AttachedPoint) -> Result<DVec3> {
        let t = fk.frame_of(point.joint, "attached point joint")?;
        let r = t.transform_point3(point.offset) - t.translation;
        let j = point.joint;
        Ok(self.joint_origin_velocity[j] + self.joint_angular_velocity[j].cross(r))
    }

    /// Angular velocity of an attached frame (`J_ω θ̇`, what a gyroscope measures), rad/s.
    ///
    /// # Errors
    /// [`Error::IndexOutOfRange`] for a bad joint index.
    pub fn frame_angular_velocity(
        &self,
        fk: &ForwardKinematics,
        frame: &AttachedFrame,
        axes: AngularFrame,
    ) -> Result<DVec3> {
        let w = self.joint_angular_velocity[check_joint(fk, frame.joint)?];
        Ok(match axes {
            AngularFrame::World => w,
            AngularFrame::Local => fk.frame_rotation(frame)?.inverse() * w,
        })
    }

    fn check_size(&self, skeleton: &Skeleton) -> Result<()> {
        if self.joint_angular_velocity.len() != skeleton.joint_count()
            || self.dof_angular_velocity.len() != skeleton.dof_count()
        {
            return Err(Error::SizeMismatch {
                what: "JointRates buffers (build them with JointRates::new(skeleton))",
                expected: skeleton.joint_count(),
                got: self.joint_angular_velocity.len(),
            });
        }
        Ok(())
    }
}

fn check_joint(fk: &ForwardKinematics, joint: usize) -> Result<usize> {
    fk.frame_of(joint, "attached joint").map(|_| joint)
}

pub(super) fn check_out(
    what: &'static str,
    out: &DMatrix<f64>,
    rows: usize,
    cols: usize,
) -> Result<()> {
    if out.nrows() != rows {
        return Err(Error::SizeMismatch {
            what,
            expected: rows,
            got: out.nrows(),
        });
    }
    if out.ncols() != cols {
        return Err(Error::SizeMismatch {
            what,
            expected: cols,
            got: out.ncols(),
        });
    }
    Ok(())
}

fn check_len(what: &'static str, expected: usize, got: usize) -> Result<()> {
    if expected != got {
        return Err(Error::SizeMismatch {
            what,
            expected,
            got,
        });
    }
    Ok(())
}

#[inline]
pub(super) fn put3(data: &mut [f64], nrows: usize, row: usize, col: usize, v: DVec3) {
    let base = col * nrows + row;
    data[base] = v.x;
    data[base + 1] = v.y;
    data[base + 2] = v.z;
}

impl Skeleton {
    /// Velocities and θ̈ = 0 accelerations of all joint and DOF frames (allocating form of
    /// [`Skeleton::rates_into`]).
    ///
    /// # Errors
    /// As [`Skeleton::rates_into`].
    pub fn rates(
        &self,
        theta: &[f64],
        theta_dot: &[f64],
        fk: &ForwardKinematics,
    ) -> Result<JointRates> {
        let mut r = JointRates::new(self);
        self.rates_into(theta, theta_dot, fk, &mut r)?;
        Ok(r)
    }

    /// One recursive sweep (see the module docs) filling `rates` for pose θ, rates θ̇ (rad/s,
    /// m/s) and `fk = forward_kinematics(θ)`. No allocation.
    ///
    /// # Errors
    /// As [`Skeleton::check_pose`] for θ and θ̇; [`Error::SizeMismatch`] for buffers built for
    /// another skeleton.
    pub fn rates_into(
        &self,
        theta: &[f64],
        theta_dot: &[f64],
        fk: &ForwardKinematics,
        rates: &mut JointRates,
    ) -> Result<()> {
        self.check_pose("theta", theta)?;
        self.check_pose("theta_dot", theta_dot)?;
        fk.check_size(self)?;
        rates.check_size(self)?;
        let mut d = 0;
        for (j, joint) in self.joints().iter().enumerate() {
            let (mut w, mut v, mut al, mut a, o_parent) = match joint.parent {
                Some(p) => (
                    rates.joint_angular_velocity[p],
                    rates.joint_origin_velocity[p],
                    rates.joint_angular_bias[p],
                    rates.joint_origin_bias[p],
                    fk.world_from_joint[p].translation,
                ),
                None => (
                    DVec3::ZERO,
                    DVec3::ZERO,
                    DVec3::ZERO,
                    DVec3::ZERO,
                    DVec3::ZERO,
                ),
            };
            // Rest-offset lever from the parent origin to this joint's origin.
            let o_first = joint.parent.map_or(joint.offset, |p| {
                fk.world_from_joint[p].transform_point3(joint.offset)
            });
            let r = o_first - o_parent;
            if joint.parent.is_some() {
                v += w.cross(r);
                a += al.cross(r) + w.cross(w.cross(r));
            }
            for dof in &joint.dofs {
                rates.dof_angular_velocity[d] = w;
                rates.dof_origin_velocity[d] = v;
                let u = fk.dof_axis_world[d];
                let qd = theta_dot[d];
                match dof.kind {
                    DofKind::Rotation => {
                        al += w.cross(u) * qd;
                        w += u * qd;
                    }
                    DofKind::Translation => {
                        let r = u * theta[d];
                        let wxu = w.cross(u);
                        v += w.cross(r) + u * qd;
                        a += al.cross(r) + w.cross(w.cross(r)) + wxu * (2.0 * qd);
                    }
                }
                d += 1;
            }
            rates.joint_angular_velocity[j] = w;
            rates.joint_origin_velocity[j] = v;
            rates.joint_angular_bias[j] = al;
            rates.joint_origin_bias[j] = a;
        }
        Ok(())
    }

    /// Positional Jacobians `J = ∂p/∂θ` of attached points, stacked: rows `3i..3i+3` belong
    /// to `points[i]`; `out` must be `3·points.len() × dof_count()`. No allocation.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] for a wrongly sized `out` or buffers of another skeleton;
    /// [`Error::IndexOutOfRange`] for a bad joint index.
    pub fn point_jacobians_into(
        &self,
        fk: &ForwardKinematics,
        points: &[AttachedPoint],
        out: &mut DMatrix<f64>,
    ) -> Result<()> {
        fk.check_size(self)?;
        check_out(
            "point Jacobian rows x columns",
            out,
            3 * points.len(),
            self.dof_count(),
        )?;
        let nrows = out.nrows();
        let data = out.as_mut_slice();
        data.fill(0.0);
        for (i, pt) in points.iter().enumerate() {
            let p = fk.point(pt)?;
            for &k in self.chain_dofs(pt.joint) {
                let u = fk.dof_axis_world[k];
                let col = if self.is_rotation(k) {
                    u.cross(p - fk.dof_origin_world[k])
                } else {
                    u
                };
                put3(data, nrows, 3 * i, k, col);
            }
        }
        Ok(())
    }

    /// Allocating form of [`Skeleton::point_jacobians_into`].
    ///
    /// # Errors
    /// As [`Skeleton::point_jacobians_into`].
    pub fn point_jacobians(
        &self,
        fk: &ForwardKinematics,
        points: &[AttachedPoint],
    ) -> Result<DMatrix<f64>> {
        let mut out = DMatrix::zeros(3 * points.len(), self.dof_count());
        self.point_jacobians_into(fk, points, &mut out)?;
        Ok(out)
    }

    /// Orientational Jacobians `J_ω` (angular velocity `ω = J_ω θ̇`) of attached frames,
    /// stacked 3 rows per frame, in world or local axes; `out` must be
    /// `3·frames.len() × dof_count()`. No allocation.
    ///
    /// # Errors
    /// As [`Skeleton::point_jacobians_into`].
    pub fn frame_jacobians_into(
        &self,
        fk: &ForwardKinematics,
        frames: &[AttachedFrame],
        axes: AngularFrame,
        out: &mut DMatrix<f64>,
    ) -> Result<()> {
        fk.check_size(self)?;
        check_out(
            "frame Jacobian rows x columns",
            out,
            3 * frames.len(),
            self.dof_count(),
        )?;
        let nrows = out.nrows();
        let data = out.as_mut_slice();
        data.fill(0.0);
        for (i, f) in frames.iter().enumerate() {
            let to_axes = frame_to_axes(fk, f, axes)?;
            for &k in self.chain_dofs(f.joint) {
                if self.is_rotation(k) {
                    put3(data, nrows, 3 * i, k, to_axes * fk.dof_axis_world[k]);
                }
            }
        }
        Ok(())
    }

    /// Allocating form of [`Skeleton::frame_jacobians_into`].
    ///
    /// # Errors
    /// As [`Skeleton::point_jacobians_into`].
    pub fn frame_jacobians(
        &self,
        fk: &ForwardKinematics,
        frames: &[AttachedFrame],
        axes: AngularFrame,
    ) -> Result<DMatrix<f64>> {
        let mut out = DMatrix::zeros(3 * frames.len(), self.dof_count());
        self.frame_jacobians_into(fk, frames, axes, &mut out)?;
        Ok(out)
    }

    /// Time derivatives `J̇` of the positional Jacobians along (θ, θ̇), stacked like
    /// [`Skeleton::point_jacobians_into`]. `J̇ θ̇` equals
    /// [`Skeleton::point_bias_accelerations_into`] and `∂(J̇θ̇)/∂θ̇ = 2 J̇`. No allocation.
    ///
    /// # Errors
    /// As [`Skeleton::point_jacobians_into`].
    pub fn point_jacobian_derivatives_into(
        &self,
        fk: &ForwardKinematics,
        rates: &JointRates,
        points: &[AttachedPoint],
        out: &mut DMatrix<f64>,
    ) -> Result<()> {
        fk.check_size(self)?;
        rates.check_size(self)?;
        check_out(
            "point Jacobian derivative rows x columns",
            out,
            3 * points.len(),
            self.dof_count(),
        )?;
        let nrows = out.nrows();
        let data = out.as_mut_slice();
        data.fill(0.0);
        for (i, pt) in points.iter().enumerate() {
            let p = fk.point(pt)?;
            let p_dot = rates.point_velocity(fk, pt)?;
            for &k in self.chain_dofs(pt.joint) {
                let u = fk.dof_axis_world[k];
                let u_dot = rates.dof_angular_velocity[k].cross(u);
                let col = if self.is_rotation(k) {
                    u_dot.cross(p - fk.dof_origin_world[k])
                        + u.cross(p_dot - rates.dof_origin_velocity[k])
                } else {
                    u_dot
                };
                put3(data, nrows, 3 * i, k, col);
            }
        }
        Ok(())
    }

    /// Time derivatives `J̇_ω` of the orientational Jacobians, stacked like
    /// [`Skeleton::frame_jacobians_into`]. In local axes this is `d/dt(Rᵀ J_ω)`, so that
    /// `J̇_ω,local θ̇ = Rᵀ J̇_ω θ̇` (the `Rᵀ ω × ...` terms cancel because they multiply ω × ω).
    ///
    /// # Errors
    /// As [`Skeleton::point_jacobians_into`].
    pub fn frame_jacobian_derivatives_into(
        &self,
        fk: &ForwardKinematics,
        rates: &JointRates,
        frames: &[AttachedFrame],
        axes: AngularFrame,
        out: &mut DMatrix<f64>,
    ) -> Result<()> {
        fk.check_size(self)?;
        rates.check_size(self)?;
        check_out(
            "frame Jacobian derivative rows x columns",
            out,
            3 * frames.len(),
            self.dof_count(),
        )?;
        let nrows = out.nrows();
        let data = out.as_mut_slice();
        data.fill(0.0);
        for (i, f) in frames.iter().enumerate() {
            let to_axes = frame_to_axes(fk, f, axes)?;
            let w = rates.joint_angular_velocity[f.joint];
            for &k in self.chain_dofs(f.joint) {
                if self.is_rotation(k) {
                    let u = fk.dof_axis_world[k];
                    let mut col = rates.dof_angular_velocity[k].cross(u);
                    if axes == AngularFrame::Local {
                        // d/dt(Rᵀu) = Rᵀ(u̇ − ω × u).
                        col -= w.cross(u);
                    }
                    put3(data, nrows, 3 * i, k, to_axes * col);
                }
            }
        }
        Ok(())
    }

    /// `J̇ θ̇` for each attached point (acceleration when θ̈ = 0), world, m/s²; the point
    /// acceleration is `J θ̈ + J̇ θ̇` (Vlasic Eq. 4.2). `out.len()` must equal `points.len()`.
    ///
    /// # Errors
    /// As [`Skeleton::point_jacobians_into`].
    pub fn point_bias_accelerations_into(
        &self,
        fk: &ForwardKinematics,
        rates: &JointRates,
        points: &[AttachedPoint],
        out: &mut [DVec3],
    ) -> Result<()> {
        fk.check_size(self)?;
        rates.check_size(self)?;
        check_len("point bias accelerations", points.len(), out.len())?;
        for (pt, o) in points.iter().zip(out.iter_mut()) {
            let t = fk.frame_of(pt.joint, "attached point joint")?;
            let r = t.transform_point3(pt.offset) - t.translation;
            let j = pt.joint;
            let w = rates.joint_angular_velocity[j];
            *o = rates.joint_origin_bias[j]
                + rates.joint_angular_bias[j].cross(r)
                + w.cross(w.cross(r));
        }
        Ok(())
    }

    /// `J̇_ω θ̇` for each attached frame (angular acceleration when θ̈ = 0), rad/s², in world
    /// or local axes (`d/dt(Rᵀω) = Rᵀω̇`). `out.len()` must equal `frames.len()`.
    ///
    /// # Errors
    /// As [`Skeleton::point_jacobians_into`].
    pub fn frame_bias_accelerations_into(
        &self,
        fk: &ForwardKinematics,
        rates: &JointRates,
        frames: &[AttachedFrame],
        axes: AngularFrame,
        out: &mut [DVec3],
    ) -> Result<()> {
        fk.check_size(self)?;
        rates.check_size(self)?;
        check_len("frame bias accelerations", frames.len(), out.len())?;
        for (f, o) in frames.iter().zip(out.iter_mut()) {
            let to_axes = frame_to_axes(fk, f, axes)?;
            *o = to_axes * rates.joint_angular_bias[f.joint];
        }
        Ok(())
    }
}

/// Rotation taking world vectors into the requested axes.
fn frame_to_axes(fk: &ForwardKinematics, f: &AttachedFrame, axes: AngularFrame) -> Result<DQuat> {
    let q = fk.frame_rotation(f)?;
    Ok(match axes {
        AngularFrame::World => DQuat::IDENTITY,
        AngularFrame::Local => q.inverse(),
    })
}

#[cfg(test)]
mod tests;
