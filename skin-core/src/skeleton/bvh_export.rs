//! BVH export of a [`Skeleton`] and [`Motion`] (inverse of [`parse_bvh`](super::parse_bvh)).
//!
//! Each DOF becomes one channel; a DOF axis may be `±X`, `±Y` or `±Z` (a negative axis is
//! written as the positive channel with the value negated, so forward kinematics is
//! unchanged). Translations must precede rotations within each joint, because BVH applies
//! position channels in the parent frame. Joints are written depth-first from each root,
//! children in index order; numbers use Rust's shortest round-trip formatting, so
//! import → export → import reproduces the skeleton and frames up to the degree ↔ radian
//! and unit-scale roundings (≈ 1 ulp). DOF limits and DOF names are not representable in BVH
//! and are lost.

use super::bvh::BvhParams;
use super::dof::DofKind;
use super::model::Skeleton;
use super::motion::Motion;
use crate::math::DVec3;
use crate::{Error, Result};
use std::fmt::Write as _;
use std::path::Path;

fn invalid(reason: String) -> Error {
    Error::InvalidParam {
        name: "skeleton (BVH export)",
        reason,
    }
}

/// Channel axis index and sign of an axis-aligned unit vector.
fn axis_channel(axis: DVec3) -> Option<(usize, f64)> {
    const TOL: f64 = 1e-12;
    (0..3).find_map(|i| {
        let a = axis[i];
        let rest = (0..3).filter(|&k| k != i).all(|k| axis[k].abs() < TOL);
        (rest && (a.abs() - 1.0).abs() < TOL).then_some((i, a.signum()))
    })
}

fn valid_name(name: &str) -> bool {
    !name.is_empty()
        && !name.contains(['{', '}'])
        && name.split_whitespace().collect::<Vec<_>>().join(" ") == name
}

/// Writes a skeleton and motion as BVH text.
///
/// # Errors
/// As [`Motion::check_for`]; [`Error::InvalidParam`] naming the joint or DOF for a DOF axis
/// that is not `±X/±Y/±Z`, a translation DOF after a rotation DOF, or a joint name that is
/// empty or contains braces, line breaks or repeated/outer whitespace; bad `params`.
pub fn to_bvh_string(skeleton: &Skeleton, motion: &Motion, params: &BvhParams) -> Result<String> {
    params.check()?;
    motion.check_for(skeleton)?;
    let scale = params.metres_per_unit;
    let joints = skeleton.joints();
    let mut channel_of_dof: Vec<(usize, f64)> = Vec::with_capacity(skeleton.dof_count());
    for j in joints {
        if !valid_name(&j.name) {
            return Err(invalid(format!(
                "joint name '{}' cannot be written to BVH",
                j.name
            )));
        }
        let mut seen_rotation = false;
        for d in &j.dofs {
            let (axis, sign) = axis_channel(d.axis).ok_or_else(|| {
                invalid(format!(
                    "DOF '{}' of joint '{}' has axis {} (BVH needs ±X, ±Y or ±Z)",
                    d.name, j.name, d.axis
                ))
            })?;
            match d.kind {
                DofKind::Rotation => seen_rotation = true,
                DofKind::Translation if seen_rotation => {
                    return Err(invalid(format!(
                        "joint '{}': translation DOF '{}' follows a rotation (BVH applies positions first)",
                        j.name, d.name
                    )))
                }
                DofKind::Translation => {}
            }
            channel_of_dof.push((axis, sign));
        }
    }

    // Depth-first order of joints (iterative), children in index order.
    let mut children: Vec<Vec<usize>> = vec![Vec::new(); joints.len()];
    let mut roots = Vec::new();
    for (i, j) in joints.iter().enumerate() {
        match j.parent {
            Some(p) => children[p].push(i),
            None => roots.push(i),
        }
    }
    let mut out = String::from("HIERARCHY\n");
    let mut order = Vec::with_capacity(joints.len());
    // Stack items: (joint, depth, closing?)
    let mut stack: Vec<(usize, usize, bool)> = roots.iter().rev().map(|&r| (r, 0, false)).collect();
    while let Some((j, depth, closing)) = stack.pop() {
        let ind = "\t".repeat(depth);
        if closing {
            let _ = writeln!(out, "{ind}}}");
            continue;
        }
        order.push(j);
        let joint = &joints[j];
        let kw = if joint.parent.is_none() {
            "ROOT"
        } else {
            "JOINT"
        };
        let o = joint.offset / scale;
        let _ = writeln!(
            out,
            "{ind}{kw} {}\n{ind}{{\n{ind}\tOFFSET {} {} {}",
            joint.name, o.x, o.y, o.z
        );
        let _ = write!(out, "{ind}\tCHANNELS {}", joint.dofs.len());
        for (k, d) in skeleton.joint_dofs(j).zip(&joint.dofs) {
            let axis = ["X", "Y", "Z"][channel_of_dof[k].0];
            let kind = if d.kind == DofKind::Rotation {
                "rotation"
            } else {
                "position"
            };
            let _ = write!(out, " {axis}{kind}");
        }
        out.push('\n');
        if let Some(e) = joint.end_site {
            let e = e / scale;
            let _ = writeln!(
                out,
                "{ind}\tEnd Site\n{ind}\t{{\n{ind}\t\tOFFSET {} {} {}\n{ind}\t}}",
                e.x, e.y, e.z
            );
        }
        stack.push((j, depth, true));
        for &c in children[j].iter().rev() {
            stack.push((c, depth + 1, false));
        }
    }
    let _ = writeln!(
        out,
        "MOTION\nFrames: {}\nFrame Time: {}",
        motion.frame_count(),
        motion.frame_time_s
    );
    for k in 0..motion.frame_count() {
        let theta = motion.frame(k);
        let mut first = true;
        for &j in &order {
            for d in skeleton.joint_dofs(j) {
                let (_, sign) = channel_of_dof[d];
                let v = if skeleton.is_rotation(d) {
                    (sign * theta[d]).to_degrees()
                } else {
                    sign * theta[d] / scale
                };
                if !first {
                    out.push(' ');
                }
                first = false;
                let _ = write!(out, "{v}");
            }
        }
        out.push('\n');
    }
    Ok(out)
}

/// Writes a skeleton and motion to a BVH file.
///
/// # Errors
/// As [`to_bvh_string`]; [`Error::Io`] if the file cannot be written.
pub fn write_bvh(
    path: impl AsRef<Path>,
    skeleton: &Skeleton,
    motion: &Motion,
    params: &BvhParams,
) -> Result<()> {
    let path = path.as_ref();
    let text = to_bvh_string(skeleton, motion, params)?;
    std::fs::write(path, text).map_err(|e| Error::io(path, e))
}
