//! A 42-DOF, 19-joint human skeleton for a 1.75 m adult (the synthetic studio's performer and
//! the EKF's default body model, Vlasic thesis §4.4.1).
//!
//! **Frames.** World and every joint frame at rest: +Y up, +Z forward (the way the body
//! faces), +X to the body's left (right-handed). θ = 0 is standing upright, arms hanging at
//! the sides, palms facing the thighs. All DOFs are rotations about the joint's current local
//! axes (intrinsic order as listed), except the root's three translations.
//!
//! **Sign convention.** Axes carry signs so that positive values mean flexion (limb forward,
//! knee and elbow bending), abduction (limb away from the midline), internal rotation, and
//! left lateral bend / left twist for the trunk, neck and head.
//!
//! **Dimensions** follow the segment-length ratios of Winter, *Biomechanics and Motor Control
//! of Human Movement* (4th ed., Fig. 4.1) scaled to `height_m`: e.g. thigh 0.245 H, shank
//! 0.246 H, upper arm 0.186 H, forearm 0.146 H, shoulder height 0.818 H.
//!
//! **Limits** are active ranges of motion from the AAOS tables (Greene & Heckman, *The
//! Clinical Measurement of Joint Motion*, 1994), rounded to 5°.

use super::dof::{Dof, DofLimits};
use super::model::{Joint, Skeleton};
use crate::math::DVec3;
use crate::Result;
use serde::{Deserialize, Serialize};

impl HumanParams {
    /// Default stature of [`human_skeleton`], metres (a typical adult).
    pub const DEFAULT_HEIGHT_M: f64 = 1.75;
}

/// Parameters of [`human_skeleton`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct HumanParams {
    /// Standing height (floor to top of head) at θ = 0, metres; all segment lengths scale with
    /// it. Default: 1.75 (an adult).
    pub height_m: f64,
}

impl Default for HumanParams {
    fn default() -> Self {
        HumanParams {
            height_m: HumanParams::DEFAULT_HEIGHT_M,
        }
    }
}

fn rot(joint: &str, dof: &str, axis: DVec3, min_deg: f64, max_deg: f64) -> Dof {
    Dof::rotation(
        format!("{joint}.{dof}"),
        axis,
        Some(DofLimits::degrees(min_deg, max_deg)),
    )
}

/// The 42-DOF human skeleton (19 joints; leaves carry end sites at head top, hands and toes).
///
/// | joint | DOFs |
/// | --- | --- |
/// | `pelvis` (root) | `tx ty tz` (m), `yaw` (Y), `pitch` (X), `roll` (Z) — unlimited |
/// | `spine` (lumbar), `chest` (thoracic) | `flexion`, `lateral`, `twist` |
/// | `neck` | `flexion`, `lateral` |
/// | `head` | `flexion`, `twist` |
/// | `l_/r_clavicle` | none (rigid shoulder girdle) |
/// | `l_/r_shoulder` | `flexion`, `abduction`, `rotation` |
/// | `l_/r_elbow` | `flexion`, `pronation` |
/// | `l_/r_wrist` | `flexion`, `deviation` (radial) |
/// | `l_/r_hip` | `flexion`, `abduction`, `rotation` |
/// | `l_/r_knee` | `flexion` |
/// | `l_/r_ankle` | `dorsiflexion`, `inversion` |
///
/// DOF names are `"<joint>.<dof>"`, e.g. `"l_knee.flexion"`.
///
/// # Errors
/// [`Error::InvalidParam`](crate::Error::InvalidParam) unless `height_m` is finite and positive.
///
/// # Example
/// ```
/// use skin_core::skeleton::{human_skeleton, HumanParams};
/// let s = human_skeleton(&HumanParams::default())?;
/// assert_eq!(s.dof_count(), 42);
/// # Ok::<(), skin_core::Error>(())
/// ```
pub fn human_skeleton(params: &HumanParams) -> Result<Skeleton> {
    let h = params.height_m;
    crate::check::positive("height_m", h)?;
    let v = |x: f64, y: f64, z: f64| DVec3::new(x, y, z) * h;
    let (x, y, z) = (DVec3::X, DVec3::Y, DVec3::Z);
    let mut j: Vec<Joint> = Vec::with_capacity(19);
    // Root at the pelvis centre, 0.554 H above the floor (hip centres 0.530 H, Winter).
    j.push(Joint::new(
        "pelvis",
        None,
        v(0.0, 0.554, 0.0),
        vec![
            Dof::translation("pelvis.tx", x, None),
            Dof::translation("pelvis.ty", y, None),
            Dof::translation("pelvis.tz", z, None),
            Dof::rotation("pelvis.yaw", y, None),
            Dof::rotation("pelvis.pitch", x, None),
            Dof::rotation("pelvis.roll", z, None),
        ],
    ));
    let trunk = |name: &str, parent: usize, off: DVec3, fl: (f64, f64), lat: f64, tw: f64| {
        Joint::new(
            name,
            Some(parent),
            off,
            vec![
                rot(name, "flexion", x, fl.0, fl.1),
                rot(name, "lateral", -z, -lat, lat),
                rot(name, "twist", y, -tw, tw),
            ],
        )
    };
    j.push(trunk(
        "spine",
        0,
        v(0.0, 0.046, -0.006),
        (-25.0, 50.0),
        25.0,
        20.0,
    )); // 1
    j.push(trunk(
        "chest",
        1,
        v(0.0, 0.114, 0.0),
        (-15.0, 30.0),
        15.0,
        25.0,
    )); // 2
    j.push(Joint::new(
        "neck",
        Some(2),
        v(0.0, 0.131, 0.0),
        vec![
            rot("neck", "flexion", x, -40.0, 45.0),
            rot("neck", "lateral", -z, -45.0, 45.0),
        ],
    )); // 3 (C7, 0.845 H)
    j.push(
        Joint::new(
            "head",
            Some(3),
            v(0.0, 0.055, 0.0),
            vec![
                rot("head", "flexion", x, -30.0, 20.0),
                rot("head", "twist", y, -80.0, 80.0),
            ],
        )
        .with_end_site(v(0.0, 0.100, 0.0)), // top of head at 1.000 H
    ); // 4
    for (side, s) in [("l", 1.0), ("r", -1.0)] {
        let chest = 2;
        let clav = j.len();
        j.push(Joint::new(
            format!("{side}_clavicle"),
            Some(chest),
            v(s * 0.015, 0.103, 0.01),
            vec![],
        ));
        let sh = j.len();
        let n = format!("{side}_shoulder");
        j.push(Joint::new(
            n.clone(),
            Some(clav),
            v(s * 0.095, 0.0, -0.01),
            vec![
                rot(&n, "flexion", -x, -60.0, 180.0),
                rot(&n, "abduction", z * s, -30.0, 180.0),
                rot(&n, "rotation", y * -s, -90.0, 70.0),
            ],
        ));
        let el = j.len();
        let n = format!("{side}_elbow");
        j.push(Joint::new(
            n.clone(),
            Some(sh),
            v(0.0, -0.186, 0.0),
            vec![
                rot(&n, "flexion", -x, 0.0, 150.0),
                rot(&n, "pronation", y * -s, -80.0, 80.0),
            ],
        ));
        let n = format!("{side}_wrist");
        j.push(
            Joint::new(
                n.clone(),
                Some(el),
                v(0.0, -0.146, 0.0),
                vec![
                    rot(&n, "flexion", z * -s, -70.0, 80.0),
                    rot(&n, "deviation", -x, -30.0, 20.0),
                ],
            )
            .with_end_site(v(0.0, -0.108, 0.0)),
        );
    }
    for (side, s) in [("l", 1.0), ("r", -1.0)] {
        let hip = j.len();
        let n = format!("{side}_hip");
        j.push(Joint::new(
            n.clone(),
            Some(0),
            v(s * 0.051, -0.024, 0.0),
            vec![
                rot(&n, "flexion", -x, -30.0, 120.0),
                rot(&n, "abduction", z * s, -30.0, 45.0),
                rot(&n, "rotation", y * -s, -45.0, 45.0),
            ],
        ));
        let knee = j.len();
        let n = format!("{side}_knee");
        j.push(Joint::new(
            n.clone(),
            Some(hip),
            v(0.0, -0.245, 0.0),
            vec![rot(&n, "flexion", x, 0.0, 135.0)],
        ));
        let n = format!("{side}_ankle");
        j.push(
            Joint::new(
                n.clone(),
                Some(knee),
                v(0.0, -0.246, 0.0),
                vec![
                    rot(&n, "dorsiflexion", -x, -50.0, 20.0),
                    rot(&n, "inversion", z * -s, -20.0, 35.0),
                ],
            )
            .with_end_site(v(0.0, -0.039, 0.117)), // toe tip on the floor
        );
    }
    Skeleton::new(j)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_names_and_dimensions() {
        let s = human_skeleton(&HumanParams::default()).unwrap();
        assert_eq!(s.dof_count(), 42);
        assert_eq!(s.joint_count(), 19);
        let names: std::collections::HashSet<_> = s.dofs().map(|d| d.name.clone()).collect();
        assert_eq!(names.len(), 42, "DOF names unique");
        let fk = s.forward_kinematics(&s.rest_pose()).unwrap();
        let p = |n: &str| fk.world_from_joint()[s.joint_index(n).unwrap()].translation;
        let head = s.joint_index("head").unwrap();
        let top = fk.world_from_joint()[head].transform_point3(s.joints()[head].end_site.unwrap());
        assert!((top.y - 1.75).abs() < 0.01, "head top {top}");
        let ankle = s.joint_index("l_ankle").unwrap();
        let toe =
            fk.world_from_joint()[ankle].transform_point3(s.joints()[ankle].end_site.unwrap());
        assert!(
            toe.y.abs() < 0.01 && toe.z > 0.1,
            "toe tip on the floor, forward: {toe}"
        );
        assert!(
            p("l_hip").x > 0.05 && p("r_hip").x < -0.05,
            "+X is the body's left"
        );
        assert!((p("l_shoulder").y - 0.818 * 1.75).abs() < 0.03);
        assert!(
            (p("l_shoulder").x - p("r_shoulder").x - 0.38).abs() < 0.04,
            "biacromial width"
        );
        // All limits contain the rest pose.
        assert!(s.limit_violations(&s.rest_pose()).unwrap().is_empty());
        assert!(human_skeleton(&HumanParams { height_m: f64::NAN }).is_err());
        assert!(human_skeleton(&HumanParams { height_m: -1.0 }).is_err());
    }

    #[test]
    fn positive_flexion_moves_limbs_forward() {
        let s = human_skeleton(&HumanParams::default()).unwrap();
        let rest = s.forward_kinematics(&s.rest_pose()).unwrap();
        for (dof, child) in [
            ("l_hip.flexion", "l_knee"),
            ("r_hip.flexion", "r_knee"),
            ("l_shoulder.flexion", "l_elbow"),
            ("r_elbow.flexion", "r_wrist"),
            ("spine.flexion", "neck"),
        ] {
            let mut theta = s.rest_pose();
            theta[s.dof_index(dof).unwrap()] = 0.5;
            let fk = s.forward_kinematics(&theta).unwrap();
            let c = s.joint_index(child).unwrap();
            let dz =
                fk.world_from_joint()[c].translation.z - rest.world_from_joint()[c].translation.z;
            assert!(dz > 0.05, "{dof} should move {child} forward, dz = {dz}");
        }
        for (dof, child, sign) in [
            ("l_hip.abduction", "l_knee", 1.0),
            ("r_shoulder.abduction", "r_elbow", -1.0),
        ] {
            let mut theta = s.rest_pose();
            theta[s.dof_index(dof).unwrap()] = 0.5;
            let fk = s.forward_kinematics(&theta).unwrap();
            let c = s.joint_index(child).unwrap();
            let dx =
                fk.world_from_joint()[c].translation.x - rest.world_from_joint()[c].translation.x;
            assert!(
                dx * sign > 0.05,
                "{dof} should move {child} outward, dx = {dx}"
            );
        }
        // Knee flexion moves the ankle backward.
        let mut theta = s.rest_pose();
        theta[s.dof_index("l_knee.flexion").unwrap()] = 0.5;
        let fk = s.forward_kinematics(&theta).unwrap();
        let a = s.joint_index("l_ankle").unwrap();
        assert!(fk.world_from_joint()[a].translation.z < -0.05);
    }
}
