//! Local parameterisation of the skeleton's 3-DOF joints for the EKF (§4.4).
//!
//! The skeleton's shoulders, hips and spine are Euler triples `R = R_a0(θ0) R_a1(θ1) R_a2(θ2)`,
//! singular when the middle angle reaches ±90° — where the exercise motion's shoulders often
//! go. The filter keeps such a joint's angles near zero instead: when one of them exceeds a
//! threshold, the current rotation `R_c` is folded into the filter's own copy of the skeleton
//! (the multiplicative / error-state idea, with the Euler triple at zero as the local chart,
//! which is non-singular there) and the angles restart at zero:
//!
//! * `T(o) R_c R_a(ε) = T(o) R_{R_c a}(ε) R_c`, so the joint's axes become `R_c a`, and the
//!   trailing `R_c` passes into its subtree: every descendant's offset, end site and axes, and
//!   every sensor attached there, are rotated by `R_c` (their world frames gain a constant
//!   right factor, recorded per joint as `G`, so the true frame is the filter's frame times
//!   `G`). Descendants' angles are unchanged.
//! * The joint's rate maps through `M = (R_c A)⁻¹ E(θ)`, with `A` the axes and `E(θ)` the
//!   Euler-rate matrix (the angular velocity `ω = E θ̇` is the same physical vector in both
//!   charts); its acceleration so that `ω̇ = E θ̈ + Ė θ̇` is kept too (the velocity-product
//!   terms differ between the charts and are not small at a few rad/s). The covariance is
//!   transported with `M` on the joint's three rows and columns of each block (θ, θ̇, θ̈),
//!   to first order. (The full 9 × 9 Jacobian of the change of chart — the new rates depend
//!   on the angles too — was tried and tracked worse on the exercise motion, four seeds:
//!   right shoulder 9.7° → 13.6° with the suit rigid at q = 0.04, 9.5° → 22.4° on the
//!   garment at q = 20.)
//! * The pose reported in the original skeleton's angles is recovered by composing the
//!   filter's joint rotation with `G` and decomposing it on the original axes (the branch
//!   nearest the previous output).

use skin_core::math::{DMat3, DVec3};
use skin_core::skeleton::{Joint, Skeleton};

/// The three axes of joint `j` if it is a 3-DOF rotational joint with mutually orthogonal axes.
pub(crate) fn orthogonal_triple(skeleton: &Skeleton, j: usize) -> Option<[DVec3; 3]> {
    let joint = &skeleton.joints()[j];
    if joint.dofs.len() != 3 || skeleton.joint_dofs(j).any(|d| !skeleton.is_rotation(d)) {
        return None;
    }
    let a = [joint.dofs[0].axis, joint.dofs[1].axis, joint.dofs[2].axis];
    let orthogonal =
        a[0].dot(a[1]).abs() < 1e-9 && a[0].dot(a[2]).abs() < 1e-9 && a[1].dot(a[2]).abs() < 1e-9;
    orthogonal.then_some(a)
}

/// `R_a0(θ0) R_a1(θ1) R_a2(θ2)`.
pub(crate) fn triple_rotation(axes: [DVec3; 3], angles: [f64; 3]) -> DMat3 {
    DMat3::from_axis_angle(axes[0], angles[0])
        * DMat3::from_axis_angle(axes[1], angles[1])
        * DMat3::from_axis_angle(axes[2], angles[2])
}

/// The Euler-rate matrix `E`: `ω = E θ̇` in the joint's pre-rotation frame.
pub(crate) fn rate_matrix(axes: [DVec3; 3], angles: [f64; 3]) -> DMat3 {
    let r0 = DMat3::from_axis_angle(axes[0], angles[0]);
    let r01 = r0 * DMat3::from_axis_angle(axes[1], angles[1]);
    DMat3::from_cols(axes[0], r0 * axes[1], r01 * axes[2])
}

/// The velocity-product term `Ė θ̇ = Σ_{k<i} θ̇_k θ̇_i (e_k × e_i)` of `ω̇ = E θ̈ + Ė θ̇`, for
/// the columns `e` of an Euler-rate matrix and the rates.
pub(crate) fn velocity_product(e: DMat3, rates: DVec3) -> DVec3 {
    let (c, r) = ([e.x_axis, e.y_axis, e.z_axis], rates.to_array());
    c[0].cross(c[1]) * (r[0] * r[1])
        + c[0].cross(c[2]) * (r[0] * r[2])
        + c[1].cross(c[2]) * (r[1] * r[2])
}

/// Wraps `v` by whole turns to lie within π of `near`.
fn unwrap_near(v: f64, near: f64) -> f64 {
    let tau = std::f64::consts::TAU;
    v - tau * ((v - near) / tau).round()
}

/// Angles `θ` on the orthogonal `axes` with `triple_rotation(axes, θ) = r`, on the branch
/// (and turn) nearest `previous`.
pub(crate) fn decompose(axes: [DVec3; 3], r: DMat3, previous: [f64; 3]) -> [f64; 3] {
    let s = axes[2].dot(axes[0].cross(axes[1])).signum();
    let b = DMat3::from_cols(axes[0], axes[1], axes[2] * s);
    let m = b.transpose() * r * b;
    // m = Rx(α) Ry(β) Rz(γ̃): m02 = sin β, m12 = −sin α cos β, m01 = −cos β sin γ̃.
    let beta = m.z_axis.x.clamp(-1.0, 1.0).asin();
    let alpha = (-m.z_axis.y).atan2(m.z_axis.z);
    let gamma = (-m.y_axis.x).atan2(m.x_axis.x);
    let pi = std::f64::consts::PI;
    let branches = [
        [alpha, beta, s * gamma],
        [alpha + pi, pi - beta, s * (gamma + pi)],
    ];
    let mut best = [0.0; 3];
    let mut best_cost = f64::INFINITY;
    for br in branches {
        let v = [
            unwrap_near(br[0], previous[0]),
            unwrap_near(br[1], previous[1]),
            unwrap_near(br[2], previous[2]),
        ];
        let cost: f64 = v.iter().zip(&previous).map(|(a, b)| (a - b).abs()).sum();
        if cost < best_cost {
            best_cost = cost;
            best = v;
        }
    }
    best
}

/// Which joints are `j` or below it.
pub(crate) fn subtree(joints: &[Joint], j: usize) -> Vec<bool> {
    let mut inside = vec![false; joints.len()];
    for (k, joint) in joints.iter().enumerate() {
        inside[k] = k == j || joint.parent.is_some_and(|p| inside[p]);
    }
    inside
}

/// Folds the rotation `r` of joint `j` into `joints` (see the module docs): `j`'s axes and
/// everything in its subtree turn by `r`, except `j`'s own offset (in its parent's frame).
pub(crate) fn fold_rotation(joints: &mut [Joint], inside: &[bool], j: usize, r: DMat3) {
    for (k, joint) in joints.iter_mut().enumerate() {
        if !inside[k] {
            continue;
        }
        for dof in &mut joint.dofs {
            dof.axis = (r * dof.axis).normalize();
        }
        if k != j {
            joint.offset = r * joint.offset;
        }
        if let Some(e) = joint.end_site.as_mut() {
            *e = r * *e;
        }
    }
}

/// The joint's state `(θ, θ̇, θ̈)` in the chart re-centred at the rotation `r_c` (new axes
/// `a_new`, see the module docs), from its state `(δ, θ̇, θ̈)` on `axes`.
pub(crate) fn to_recentred(
    axes: [DVec3; 3],
    a_new: [DVec3; 3],
    r_c: DMat3,
    state: [f64; 9],
) -> [f64; 9] {
    let delta = [state[0], state[1], state[2]];
    let (rate, acc) = (
        DVec3::new(state[3], state[4], state[5]),
        DVec3::new(state[6], state[7], state[8]),
    );
    let eps = decompose(
        a_new,
        triple_rotation(axes, delta) * r_c.transpose(),
        [0.0; 3],
    );
    let e = rate_matrix(axes, delta);
    let e_new = rate_matrix(a_new, eps);
    let inv = e_new.inverse();
    let new_rate = inv * (e * rate);
    let new_acc = inv * (e * acc + velocity_product(e, rate) - velocity_product(e_new, new_rate));
    [
        eps[0], eps[1], eps[2], new_rate.x, new_rate.y, new_rate.z, new_acc.x, new_acc.y, new_acc.z,
    ]
}

/// `P ← T P Tᵀ` for `T` the identity except `t` on the rows and columns `idx` (P full and
/// symmetric, column-major, `n × n`).
pub(crate) fn transport<const K: usize>(
    p: &mut [f64],
    n: usize,
    idx: [usize; K],
    t: [[f64; K]; K],
) {
    let apply = |v: [f64; K]| -> [f64; K] {
        std::array::from_fn(|i| t[i].iter().zip(&v).map(|(a, b)| a * b).sum())
    };
    // Rows: for every column c, P[idx, c] ← t P[idx, c].
    for c in 0..n {
        let col = &mut p[c * n..(c + 1) * n];
        let w = apply(idx.map(|r| col[r]));
        for (i, &r) in idx.iter().enumerate() {
            col[r] = w[i];
        }
    }
    // Columns: for every row r, P[r, idx] ← t P[r, idx].
    for r in 0..n {
        let w = apply(idx.map(|c| p[c * n + r]));
        for (i, &c) in idx.iter().enumerate() {
            p[c * n + r] = w[i];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn decomposition_round_trips_on_both_handednesses() {
        for axes in [
            [DVec3::X, DVec3::Y, DVec3::Z],
            [DVec3::Z, DVec3::X, -DVec3::Y],
            [-DVec3::Y, DVec3::Z, DVec3::X],
        ] {
            for angles in [[0.3, -1.2, 2.0], [-2.5, 1.5, -0.4], [0.1, 0.0, -0.1]] {
                let r = triple_rotation(axes, angles);
                let back = decompose(axes, r, angles);
                for (a, b) in back.iter().zip(&angles) {
                    assert!((a - b).abs() < 1e-9, "{axes:?} {angles:?} → {back:?}");
                }
                // From far away, the other branch still gives the same rotation.
                let other = decompose(axes, r, [3.0, 3.0, 3.0]);
                let r2 = triple_rotation(axes, other);
                assert!((r2 - r).abs().to_cols_array().iter().all(|v| *v < 1e-9));
            }
        }
    }

    #[test]
    fn rate_matrix_matches_finite_differences() {
        let axes = [DVec3::Z, DVec3::X, -DVec3::Y];
        let (th, rate) = ([0.4, 1.3, -0.7], DVec3::new(0.5, -1.0, 2.0));
        let h = 1e-6;
        let plus = triple_rotation(
            axes,
            [th[0] + h * rate.x, th[1] + h * rate.y, th[2] + h * rate.z],
        );
        let minus = triple_rotation(
            axes,
            [th[0] - h * rate.x, th[1] - h * rate.y, th[2] - h * rate.z],
        );
        let r = triple_rotation(axes, th);
        let w = (plus - minus) * (0.5 / h) * r.transpose();
        let omega = DVec3::new(w.y_axis.z, w.z_axis.x, w.x_axis.y);
        let e = rate_matrix(axes, th) * rate;
        assert!((omega - e).length() < 1e-6, "{omega} vs {e}");
    }

    #[test]
    fn velocity_product_matches_finite_differences_of_omega() {
        let axes = [DVec3::Y, -DVec3::Z, DVec3::X];
        let (th, rate, acc) = (
            [0.4, 1.3, -0.7],
            DVec3::new(0.5, -1.0, 2.0),
            DVec3::new(0.3, 0.2, -0.6),
        );
        let h = 1e-6;
        let omega = |t: f64| {
            let a = [
                th[0] + t * rate.x + 0.5 * t * t * acc.x,
                th[1] + t * rate.y + 0.5 * t * t * acc.y,
                th[2] + t * rate.z + 0.5 * t * t * acc.z,
            ];
            rate_matrix(axes, a) * (rate + acc * t)
        };
        let fd = (omega(h) - omega(-h)) / (2.0 * h);
        let e = rate_matrix(axes, th);
        let analytic = e * acc + velocity_product(e, rate);
        assert!((fd - analytic).length() < 1e-6, "{fd} vs {analytic}");
    }

    #[test]
    fn recentred_state_is_zero_angles_with_the_same_angular_velocity() {
        let axes = [DVec3::Z, DVec3::X, -DVec3::Y];
        let state = [0.4, 1.3, -0.7, 0.5, -1.0, 2.0, 0.3, 0.2, -0.6];
        let delta = [state[0], state[1], state[2]];
        let r_c = triple_rotation(axes, delta);
        let a_new = axes.map(|a| r_c * a);
        let out = to_recentred(axes, a_new, r_c, state);
        assert!(out[..3].iter().all(|v| v.abs() < 1e-12), "{out:?}");
        let w_old = rate_matrix(axes, delta) * DVec3::new(state[3], state[4], state[5]);
        let w_new = rate_matrix(a_new, [0.0; 3]) * DVec3::new(out[3], out[4], out[5]);
        assert!((w_old - w_new).length() < 1e-12);
        // Angles: to first order a change dδ becomes (R_c A)⁻¹ E dδ.
        let m = DMat3::from_cols(a_new[0], a_new[1], a_new[2]).inverse() * rate_matrix(axes, delta);
        let h = 1e-6;
        let mut moved = state;
        moved[1] += h;
        let d = to_recentred(axes, a_new, r_c, moved);
        let expected = m.col(1) * h;
        assert!((DVec3::new(d[0], d[1], d[2]) - expected).length() < 1e-11);
    }

    #[test]
    fn transport_is_t_p_t_transposed() {
        let n = 5;
        let mut p = vec![0.0; n * n];
        for r in 0..n {
            for c in 0..n {
                p[c * n + r] = if r == c {
                    2.0 + r as f64
                } else {
                    0.1 * (r + c) as f64
                };
            }
        }
        let m = [[1.0, -0.3, 0.0], [0.2, 1.1, 0.5], [0.0, 0.4, 0.9]];
        let idx = [1, 2, 4];
        let mut t = nalgebra::DMatrix::<f64>::identity(n, n);
        for i in 0..3 {
            for k in 0..3 {
                t[(idx[i], idx[k])] = m[i][k];
            }
        }
        let expected = &t * nalgebra::DMatrix::from_column_slice(n, n, &p) * t.transpose();
        transport(&mut p, n, idx, m);
        for (a, b) in p.iter().zip(expected.as_slice()) {
            assert!((a - b).abs() < 1e-12);
        }
    }
}
