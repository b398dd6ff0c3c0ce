//! Pose derivatives of the inertial observation terms: `∂(J̇θ̇)/∂θ`, `∂(J̇θ̇)/∂θ̇`,
//! `∂(J y)/∂θ` for a fixed vector y (the `J θ̈` part of an acceleration) and
//! `∂(J_ω θ̇)/∂θ` (gyroscopes) — the state Jacobians `H` the skeletal EKF needs for
//! accelerometers (Vlasic Eq. 4.2) and gyroscopes (Eq. 4.3), §4.4.3.
//!
//! **Derivation.** Along the chain of a point p (DOFs in root → leaf order) let `gₖ = uₖ`
//! for a rotation DOF and `gₖ = 0` for a translation (the DOF's rotation generator), `Jₖ`
//! the positional column and `Wₖ = Σ_{c<k} θ̇_c g_c` the angular velocity of the frame
//! preceding DOF k. Perturbing θ_m rotates everything downstream of DOF m about `g_m`, so
//! `∂J_b/∂θ_m = g_{min(b,m)} × J_{max(b,m)}` (symmetric second derivative of p). Hence
//!
//! * `J̇θ̇ = Σ_b θ̇_b A_b × J_b` with `A_b = 2W_b + θ̇_b g_b`;
//! * `∂(J̇θ̇)/∂θ̇_m = 2(W_m × J_m + g_m × Σ_{b≥m} θ̇_b J_b)` (= 2 J̇, column m);
//! * `∂(J̇θ̇)/∂θ_m = g_m × Σ_{b>m} θ̇_b A_b × J_b − 2(g_m × W_m) × Σ_{b>m} θ̇_b J_b
//!   + Σ_{b≤m} θ̇_b A_b × (g_b × J_m)`;
//! * `∂(J y)/∂θ_m = (Σ_{b<m} y_b g_b) × J_m + g_m × Σ_{b≥m} y_b J_b`;
//! * `∂(J_ω θ̇)/∂θ_m = g_m × (ω − W_m)` in world axes and `−Rᵀ(g_m × W_m)` in the frame's
//!   own axes (the frame rotation's derivative cancels the rest).
//!
//! Each is one prefix and one suffix sweep over the chain: O(chain length) per point, no
//! allocation. Columns of DOFs off the chain are zero.

use super::fk::{AttachedFrame, AttachedPoint, ForwardKinematics};
use super::jacobian::{check_out, put3, AngularFrame};
use super::model::Skeleton;
use crate::math::{DMat3, DVec3};
use crate::Result;
use nalgebra::DMatrix;

/// Longest chain handled without heap allocation (longer chains allocate scratch).
const STACK_CHAIN: usize = 48;

/// Checks `out` is `rows × dof_count`, zeroes it and returns its row count and column-major
/// data.
fn zeroed<'a>(
    skeleton: &Skeleton,
    what: &'static str,
    out: &'a mut DMatrix<f64>,
    rows: usize,
) -> Result<(usize, &'a mut [f64])> {
    check_out(what, out, rows, skeleton.dof_count())?;
    let data = out.as_mut_slice();
    data.fill(0.0);
    Ok((rows, data))
}

/// Per-chain-DOF generator g and positional column J of a point p.
#[inline]
fn generator_and_column(
    skeleton: &Skeleton,
    fk: &ForwardKinematics,
    k: usize,
    p: DVec3,
) -> (DVec3, DVec3) {
    let u = fk.dof_axis_world[k];
    if skeleton.is_rotation(k) {
        (u, u.cross(p - fk.dof_origin_world[k]))
    } else {
        (DVec3::ZERO, u)
    }
}

impl Skeleton {
    fn check_rates(&self, fk: &ForwardKinematics, theta_dot: &[f64]) -> Result<()> {
        fk.check_size(self)?;
        self.check_pose("theta_dot", theta_dot)
    }

    /// `∂(J̇θ̇)/∂θ` and `∂(J̇θ̇)/∂θ̇` of attached points (world, m/s² per rad or per rad/s),
    /// stacked 3 rows per point like [`Skeleton::point_jacobians_into`]; both outputs must be
    /// `3·points.len() × dof_count()`. `fk` is the forward kinematics at θ. No allocation for
    /// chains of up to 48 DOFs.
    ///
    /// # Errors
    /// [`crate::Error::SizeMismatch`] for wrongly sized outputs or `fk`; as [`Skeleton::check_pose`]
    /// for θ̇; [`crate::Error::IndexOutOfRange`] for a bad joint index.
    pub fn point_bias_acceleration_jacobians_into(
        &self,
        fk: &ForwardKinematics,
        theta_dot: &[f64],
        points: &[AttachedPoint],
        d_theta: &mut DMatrix<f64>,
        d_theta_dot: &mut DMatrix<f64>,
    ) -> Result<()> {
        self.check_rates(fk, theta_dot)?;
        let rows = 3 * points.len();
        let what = "d(Jdot thetadot)/dtheta rows x columns";
        let (nrows, dt) = zeroed(self, what, d_theta, rows)?;
        let what = "d(Jdot thetadot)/dthetadot rows x columns";
        let (_, dd) = zeroed(self, what, d_theta_dot, rows)?;
        let mut heap: Vec<[DVec3; 4]> = Vec::new();
        let mut stack = [[DVec3::ZERO; 4]; STACK_CHAIN];
        for (i, pt) in points.iter().enumerate() {
            let p = fk.point(pt)?;
            let chain = self.chain_dofs(pt.joint);
            // scratch[c] = [g, J, W (prefix, exclusive), A]
            let scratch: &mut [[DVec3; 4]] = if chain.len() <= STACK_CHAIN {
                &mut stack[..chain.len()]
            } else {
                heap.resize(chain.len(), [DVec3::ZERO; 4]);
                &mut heap[..]
            };
            let mut w = DVec3::ZERO;
            for (c, &k) in chain.iter().enumerate() {
                let (g, j) = generator_and_column(self, fk, k, p);
                let a = 2.0 * w + theta_dot[k] * g;
                scratch[c] = [g, j, w, a];
                w += theta_dot[k] * g;
            }
            // Suffix sums over b > m, accumulated from the leaf; prefix matrix over b ≤ m
            // from the root (second pass).
            let mut s_gt = DVec3::ZERO;
            let mut v_gt = DVec3::ZERO;
            for (c, &k) in chain.iter().enumerate().rev() {
                let [g, j, w, a] = scratch[c];
                let qd = theta_dot[k];
                // ∂/∂θ̇ (uses Σ_{b≥m} = θ̇_m J_m + v_gt).
                put3(
                    dd,
                    nrows,
                    3 * i,
                    k,
                    2.0 * (w.cross(j) + g.cross(qd * j + v_gt)),
                );
                // ∂/∂θ, first two terms (the third is added below).
                put3(
                    dt,
                    nrows,
                    3 * i,
                    k,
                    g.cross(s_gt) - 2.0 * g.cross(w).cross(v_gt),
                );
                s_gt += qd * a.cross(j);
                v_gt += qd * j;
            }
            let mut m = DMat3::ZERO;
            for (c, &k) in chain.iter().enumerate() {
                let [g, j, _, a] = scratch[c];
                let qd = theta_dot[k];
                m += qd
                    * (DMat3::from_cols(g * a.x, g * a.y, g * a.z)
                        - DMat3::from_diagonal(DVec3::splat(a.dot(g))));
                let base = k * nrows + 3 * i;
                let add = m * j;
                dt[base] += add.x;
                dt[base + 1] += add.y;
                dt[base + 2] += add.z;
            }
        }
        Ok(())
    }

    /// `∂(J y)/∂θ` of attached points for a fixed vector y (e.g. θ̈, giving the `J θ̈` part
    /// of an acceleration's pose derivative), stacked 3 rows per point; `out` must be
    /// `3·points.len() × dof_count()`. No allocation.
    ///
    /// # Errors
    /// As [`Skeleton::point_bias_acceleration_jacobians_into`] (with y in place of θ̇).
    pub fn point_jacobian_product_jacobians_into(
        &self,
        fk: &ForwardKinematics,
        y: &[f64],
        points: &[AttachedPoint],
        out: &mut DMatrix<f64>,
    ) -> Result<()> {
        self.check_rates(fk, y)?;
        let (nrows, data) = zeroed(self, "d(J y)/dtheta rows x columns", out, 3 * points.len())?;
        for (i, pt) in points.iter().enumerate() {
            let p = fk.point(pt)?;
            let chain = self.chain_dofs(pt.joint);
            // First pass (leaf → root): suffix Σ_{b≥m} y_b J_b times g_m.
            let mut v_ge = DVec3::ZERO;
            for &k in chain.iter().rev() {
                let (g, j) = generator_and_column(self, fk, k, p);
                v_ge += y[k] * j;
                put3(data, nrows, 3 * i, k, g.cross(v_ge));
            }
            // Second pass (root → leaf): prefix Σ_{b<m} y_b g_b crossed with J_m.
            let mut w = DVec3::ZERO;
            for &k in chain {
                let (g, j) = generator_and_column(self, fk, k, p);
                let add = w.cross(j);
                let base = k * nrows + 3 * i;
                data[base] += add.x;
                data[base + 1] += add.y;
                data[base + 2] += add.z;
                w += y[k] * g;
            }
        }
        Ok(())
    }

    /// `∂(J_ω θ̇)/∂θ` of attached frames — the pose derivative of a gyroscope reading — in
    /// world axes or the frame's own axes ([`AngularFrame::Local`], what Eq. 4.3 observes),
    /// stacked 3 rows per frame; `out` must be `3·frames.len() × dof_count()`. No allocation.
    ///
    /// # Errors
    /// As [`Skeleton::point_bias_acceleration_jacobians_into`].
    pub fn frame_angular_velocity_jacobians_into(
        &self,
        fk: &ForwardKinematics,
        theta_dot: &[f64],
        frames: &[AttachedFrame],
        axes: AngularFrame,
        out: &mut DMatrix<f64>,
    ) -> Result<()> {
        self.check_rates(fk, theta_dot)?;
        let what = "d(J_w thetadot)/dtheta rows x columns";
        let (nrows, data) = zeroed(self, what, out, 3 * frames.len())?;
        for (i, f) in frames.iter().enumerate() {
            let to_local = fk.frame_rotation(f)?.inverse();
            let chain = self.chain_dofs(f.joint);
            let omega: DVec3 = chain
                .iter()
                .filter(|&&k| self.is_rotation(k))
                .map(|&k| theta_dot[k] * fk.dof_axis_world[k])
                .sum();
            let mut w = DVec3::ZERO;
            for &k in chain {
                if self.is_rotation(k) {
                    let g = fk.dof_axis_world[k];
                    let col = match axes {
                        AngularFrame::World => g.cross(omega - w),
                        AngularFrame::Local => -(to_local * g.cross(w)),
                    };
                    put3(data, nrows, 3 * i, k, col);
                    w += theta_dot[k] * g;
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests;
