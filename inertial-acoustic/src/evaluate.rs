//! Evaluation (§4.5, Table 4.1): the orientation difference of a joint between two poses —
//! the angle of `R_a R_bᵀ` for the joint's rotation relative to its parent — and its mean and
//! standard deviation over a sequence.

use crate::{Error, Result};
use serde::{Deserialize, Serialize};
use skin_core::math::{DQuat, DVec3};
use skin_core::skeleton::{ForwardKinematics, Skeleton};

/// Mean and standard deviation of an error, degrees.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ErrorStats {
    /// Mean, degrees.
    pub mean_deg: f64,
    /// Standard deviation (population), degrees.
    pub sd_deg: f64,
}

impl ErrorStats {
    /// Stats of `values` (degrees).
    ///
    /// # Errors
    /// [`Error::Empty`] without values; [`Error::NonFinite`] for NaN.
    pub fn of(values: &[f64]) -> Result<Self> {
        if values.is_empty() {
            return Err(Error::Empty { what: "errors" });
        }
        if values.iter().any(|v| !v.is_finite()) {
            return Err(Error::NonFinite { what: "errors" });
        }
        let n = values.len() as f64;
        let mean = values.iter().sum::<f64>() / n;
        let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n;
        Ok(ErrorStats {
            mean_deg: mean,
            sd_deg: var.sqrt(),
        })
    }
}

fn local_rotation(fk: &ForwardKinematics, skeleton: &Skeleton, j: usize) -> DQuat {
    let w = fk.world_from_joint();
    let child = DQuat::from_mat3(&w[j].matrix3);
    match skeleton.joints()[j].parent {
        Some(p) => DQuat::from_mat3(&w[p].matrix3).inverse() * child,
        None => child,
    }
}

/// Orientation difference, degrees, of each joint in `joints` (its rotation relative to its
/// parent) between poses `a` and `b`.
///
/// # Errors
/// As [`Skeleton::forward_kinematics`]; [`Error::Core`] index error for a bad joint.
pub fn joint_orientation_errors_deg(
    skeleton: &Skeleton,
    a: &[f64],
    b: &[f64],
    joints: &[usize],
) -> Result<Vec<f64>> {
    Ok(local_rotation_pairs(skeleton, a, b, joints)?
        .into_iter()
        .map(|(qa, qb)| qa.angle_between(qb).to_degrees())
        .collect())
}

/// Per joint in `joints`: its rotation relative to its parent in poses `a` and `b`.
fn local_rotation_pairs(
    skeleton: &Skeleton,
    a: &[f64],
    b: &[f64],
    joints: &[usize],
) -> Result<Vec<(DQuat, DQuat)>> {
    let fa = skeleton.forward_kinematics(a)?;
    let fb = skeleton.forward_kinematics(b)?;
    joints
        .iter()
        .map(|&j| {
            skin_core::check::index("joint", j, skeleton.joint_count())?;
            Ok((
                local_rotation(&fa, skeleton, j),
                local_rotation(&fb, skeleton, j),
            ))
        })
        .collect()
}

/// The orientation difference of each joint in `joints` between poses `a` (estimate) and
/// `b` (truth) split into twist about the bone and swing of the bone (degrees): the error
/// rotation `E = R_bᵀ R_a` of the joint relative to its parent, in the joint's frame, is
/// decomposed as `E = swing · twist` with `twist` about the bone's axis (the direction to its
/// first child, else its end site; a joint without either has all of `E` as swing). Tells
/// whether a joint's error is a rotation it has a DOF for — e.g. the 2-DOF neck cannot
/// twist, so its twist error is what a board's twist against the bone leaves.
///
/// # Errors
/// As [`joint_orientation_errors_deg`].
pub fn joint_swing_twist_errors_deg(
    skeleton: &Skeleton,
    a: &[f64],
    b: &[f64],
    joints: &[usize],
) -> Result<Vec<[f64; 2]>> {
    let pairs = local_rotation_pairs(skeleton, a, b, joints)?;
    joints
        .iter()
        .zip(pairs)
        .map(|(&j, (qa, qb))| {
            let mut e = qb.inverse() * qa;
            if e.w < 0.0 {
                e = -e;
            }
            let bone = skeleton
                .children(j)
                .next()
                .map(|c| skeleton.joints()[c].offset)
                .or(skeleton.joints()[j].end_site)
                .map(|v| v.normalize_or_zero())
                .unwrap_or_default();
            let v = DVec3::new(e.x, e.y, e.z);
            let twist = 2.0 * f64::atan2(v.dot(bone), e.w);
            let swing_angle = if bone == DVec3::ZERO {
                e.angle_between(DQuat::IDENTITY)
            } else {
                (e * DQuat::from_axis_angle(bone, -twist)).angle_between(DQuat::IDENTITY)
            };
            Ok([swing_angle.to_degrees(), twist.abs().to_degrees()])
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use skin_core::skeleton::{human_skeleton, HumanParams};

    /// A flexion of the neck is all swing, a twist of the head (about its bone) all twist.
    #[test]
    fn swing_twist_split_separates_bending_from_twisting() {
        let s = human_skeleton(&HumanParams::default()).unwrap();
        let rest = s.rest_pose();
        let (neck, head) = (
            s.joint_index("neck").unwrap(),
            s.joint_index("head").unwrap(),
        );
        let dof = |j: usize, k: usize| s.joint_dofs(j).nth(k).unwrap();
        let mut bent = rest.clone();
        bent[dof(neck, 0)] += 0.3;
        let mut twisted = rest.clone();
        twisted[dof(head, 1)] += 0.4;
        let e = joint_swing_twist_errors_deg(&s, &bent, &rest, &[neck, head]).unwrap();
        assert!(
            (e[0][0] - 0.3f64.to_degrees()).abs() < 1e-9 && e[0][1] < 1e-9,
            "{e:?}"
        );
        let e = joint_swing_twist_errors_deg(&s, &twisted, &rest, &[head]).unwrap();
        assert!(
            e[0][0] < 1e-6 && (e[0][1] - 0.4f64.to_degrees()).abs() < 1e-6,
            "{e:?}"
        );
        let total = joint_orientation_errors_deg(&s, &twisted, &rest, &[head]).unwrap();
        assert!((total[0] - e[0][1]).abs() < 1e-6);
        assert!(joint_swing_twist_errors_deg(&s, &rest, &rest, &[99]).is_err());
    }
}
