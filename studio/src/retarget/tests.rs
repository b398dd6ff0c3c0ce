//! Tests of BVH retargeting.

use super::*;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use skin_core::skeleton::{
    human_skeleton, read_bvh, BvhParams, Dof, HumanParams, Joint, CMU_METRES_PER_UNIT,
};

/// A BVH-like copy of `s`: names prefixed `src_`, offsets `r0 · k · offset`, every joint with
/// Z, Y, X rotation channels, the root also with X, Y, Z translations.
fn bvh_like(s: &Skeleton, r0: DMat3, k: f64) -> Skeleton {
    let joints = s
        .joints()
        .iter()
        .map(|j| {
            let mut dofs = Vec::new();
            if j.parent.is_none() {
                dofs.extend(
                    ["Xposition", "Yposition", "Zposition"]
                        .iter()
                        .zip([DVec3::X, DVec3::Y, DVec3::Z])
                        .map(|(n, a)| Dof::translation(*n, a, None)),
                );
            }
            dofs.extend(
                ["Zrotation", "Yrotation", "Xrotation"]
                    .iter()
                    .zip([DVec3::Z, DVec3::Y, DVec3::X])
                    .map(|(n, a)| Dof::rotation(*n, a, None)),
            );
            let mut out = Joint::new(format!("src_{}", j.name), j.parent, r0 * j.offset * k, dofs);
            out.end_site = j.end_site.map(|e| r0 * e * k);
            out
        })
        .collect();
    Skeleton::new(joints).unwrap()
}

fn identity_map(s: &Skeleton) -> JointMap {
    JointMap {
        name: "test".into(),
        pairs: s
            .joints()
            .iter()
            .map(|j| JointPair {
                source: format!("src_{}", j.name),
                target: j.name.clone(),
            })
            .collect(),
    }
}

#[test]
fn retargeted_positions_match_source_within_scale() {
    let target = human_skeleton(&HumanParams::default()).unwrap();
    // Source: Z-up (rotated 90° about X), half size.
    let r0 = DMat3::from_rotation_x(std::f64::consts::FRAC_PI_2);
    let k = 0.5;
    let source = bvh_like(&target, r0, k);
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let n = 12;
    let mut truth = Vec::new();
    let mut src_frames = DMatrix::zeros(source.dof_count(), n);
    for f in 0..n {
        let mut theta = target.rest_pose();
        for (d, v) in theta.iter_mut().enumerate() {
            let dof = target.dof(d);
            *v = match (dof.kind, dof.limits) {
                (_, Some(l)) => {
                    let (lo, hi) = (l.min.max(-1.2), l.max.min(1.2));
                    lo + (hi - lo) * rng.random::<f64>()
                }
                (DofKind::Rotation, None) => rng.random::<f64>() - 0.5,
                (DofKind::Translation, None) => 2.0 * rng.random::<f64>() - 1.0,
            };
        }
        let fk = target.forward_kinematics(&theta).unwrap();
        // Source pose with the same world rotations (conjugated by r0) and positions.
        let mut src_theta = source.rest_pose();
        for j in 0..target.joint_count() {
            let q = |i: usize| r0 * fk.world_from_joint()[i].matrix3 * r0.transpose();
            let parent = target.joints()[j].parent.map_or(DMat3::IDENTITY, q);
            let angles =
                decompose(parent.transpose() * q(j), &[DVec3::Z, DVec3::Y, DVec3::X]).unwrap();
            let dofs: Vec<usize> = source.joint_dofs(j).collect();
            let rot = &dofs[dofs.len() - 3..];
            for (d, a) in rot.iter().zip(angles) {
                src_theta[*d] = a;
            }
        }
        let root = r0 * fk.world_from_joint()[0].translation * k - source.joints()[0].offset;
        src_theta[0..3].copy_from_slice(&root.to_array());
        src_frames.column_mut(f).copy_from_slice(&src_theta);
        truth.push(fk.joint_positions());
    }
    let motion = Motion::new(0.01, src_frames).unwrap();
    let out = retarget(
        &source,
        &motion,
        &target,
        &identity_map(&target),
        &RetargetParams::default(),
    )
    .unwrap();
    assert!((out.scale - 1.0 / k).abs() < 1e-12);
    let g = DMat3::from_quat(out.performer_from_source);
    assert!((g * r0 - DMat3::IDENTITY).abs_diff_eq(DMat3::ZERO, 1e-12));
    for (f, truth_f) in truth.iter().enumerate() {
        let got = target
            .forward_kinematics(out.motion.frame(f))
            .unwrap()
            .joint_positions();
        let src = source
            .forward_kinematics(motion.frame(f))
            .unwrap()
            .joint_positions();
        for j in 0..target.joint_count() {
            let want = g * src[j] * out.scale;
            assert!(
                got[j].distance(want) < 1e-9,
                "frame {f} joint {}: {} vs {want}",
                target.joints()[j].name,
                got[j]
            );
            assert!(got[j].distance(truth_f[j]) < 1e-9);
        }
    }
}

use super::super::tests::data;

/// Angle between the performer's and the (G-rotated) source bone directions, radians.
fn bone_angles(
    src: &Skeleton,
    m: &Motion,
    tgt: &Skeleton,
    out: &Retargeted,
    bones: [(&str, &str, &str, &str); 1],
) -> Vec<f64> {
    let g = DMat3::from_quat(out.performer_from_source);
    let mut res = Vec::new();
    for f in 0..m.frame_count() {
        let sp = src
            .forward_kinematics(m.frame(f))
            .unwrap()
            .joint_positions();
        let tp = tgt
            .forward_kinematics(out.motion.frame(f))
            .unwrap()
            .joint_positions();
        for (sa, sb, ta, tb) in bones {
            let ds = g * (sp[src.joint_index(sb).unwrap()] - sp[src.joint_index(sa).unwrap()]);
            let dt = tp[tgt.joint_index(tb).unwrap()] - tp[tgt.joint_index(ta).unwrap()];
            res.push(ds.angle_between(dt));
        }
    }
    res
}

#[test]
fn cmu_walk_retargets_with_matching_limb_directions() {
    let path = data("mocap-cmu/131_01.bvh");
    let bvh = read_bvh(
        path,
        &BvhParams {
            metres_per_unit: CMU_METRES_PER_UNIT,
        },
    )
    .unwrap();
    let map = JointMap::detect(&bvh.skeleton).unwrap();
    assert_eq!(map.name, "cmu");
    let target = human_skeleton(&HumanParams::default()).unwrap();
    let out = retarget(
        &bvh.skeleton,
        &bvh.motion,
        &target,
        &map,
        &RetargetParams::default(),
    )
    .unwrap();
    assert!((0.5..2.0).contains(&out.scale), "scale {}", out.scale);
    // Joints with three DOFs reproduce the source bone direction exactly.
    for bones in [
        [("LeftHip", "LeftKnee", "l_hip", "l_knee")],
        [("RightShoulder", "RightElbow", "r_shoulder", "r_elbow")],
    ] {
        let worst = bone_angles(&bvh.skeleton, &bvh.motion, &target, &out, bones)
            .into_iter()
            .fold(0.0, f64::max);
        assert!(worst < 1e-6, "{bones:?}: {worst} rad");
    }
    // The 1-DOF knee follows the shin closely (swing–twist projection).
    let shin = bone_angles(
        &bvh.skeleton,
        &bvh.motion,
        &target,
        &out,
        [("LeftKnee", "LeftAnkle", "l_knee", "l_ankle")],
    );
    let mean = shin.iter().sum::<f64>() / shin.len() as f64;
    assert!(mean < 0.15, "mean shin direction error {mean} rad");
    // The pelvis height is the source's scaled (131_01 dips to 0.65 m) and the motion
    // resamples to 30 Hz.
    let pelvis = target.joint_index("pelvis").unwrap();
    for f in 0..out.motion.frame_count() {
        let y = target
            .forward_kinematics(out.motion.frame(f))
            .unwrap()
            .joint_positions()[pelvis]
            .y;
        let src_y = bvh.motion.frame(f)[1];
        assert!(
            (y - out.scale * src_y).abs() < 1e-9,
            "pelvis height {y} at frame {f}, source {src_y}"
        );
        assert!((0.5..1.3).contains(&y), "pelvis height {y} at frame {f}");
    }
    let r = out.motion.resample(&target, 1.0 / 30.0).unwrap();
    assert!((r.frame_count() as f64 - bvh.motion.duration_s() * 30.0).abs() < 2.0);
    let played = play_bvh(
        data("mocap-cmu/131_01.bvh"),
        &BvhParams {
            metres_per_unit: CMU_METRES_PER_UNIT,
        },
        &target,
        1.0 / 30.0,
        &RetargetParams::default(),
    )
    .unwrap();
    assert_eq!(played.motion, r);
    assert!(play_bvh(
        "/nonexistent.bvh",
        &BvhParams::default(),
        &target,
        0.1,
        &RetargetParams::default()
    )
    .is_err());
}

#[test]
fn makehuman_bvhs_retarget_and_bad_maps_are_named() {
    let (walk, dance) = (data("makehuman/walk1.bvh"), data("makehuman/dance1.bvh"));
    let target = human_skeleton(&HumanParams::default()).unwrap();
    for path in [walk, dance] {
        let bvh = read_bvh(
            &path,
            &BvhParams {
                metres_per_unit: 0.1,
            },
        )
        .unwrap();
        let map = JointMap::detect(&bvh.skeleton).unwrap();
        assert_eq!(map.name, "makehuman_bvh");
        let out = retarget(
            &bvh.skeleton,
            &bvh.motion,
            &target,
            &map,
            &RetargetParams::default(),
        )
        .unwrap();
        let worst = bone_angles(
            &bvh.skeleton,
            &bvh.motion,
            &target,
            &out,
            [("UpLeg_L", "LoLeg_L", "l_hip", "l_knee")],
        )
        .into_iter()
        .fold(0.0, f64::max);
        assert!(worst < 1e-6, "{path:?}: thigh {worst} rad");
        // The wrong map: a clear error naming the joints that do not map.
        let err = retarget(
            &bvh.skeleton,
            &bvh.motion,
            &target,
            &JointMap::cmu(),
            &RetargetParams::default(),
        )
        .unwrap_err();
        let msg = err.to_string();
        assert!(
            msg.contains("LeftHip") && msg.contains("lowerback"),
            "{msg}"
        );
    }
}

#[test]
fn unmappable_skeletons_are_rejected_with_names() {
    let target = human_skeleton(&HumanParams::default()).unwrap();
    let odd = Skeleton::new(vec![
        Joint::new(
            "torso",
            None,
            DVec3::ZERO,
            vec![Dof::rotation("r", DVec3::Y, None)],
        ),
        Joint::new("tail", Some(0), DVec3::Y, vec![]),
    ])
    .unwrap();
    let err = JointMap::detect(&odd).unwrap_err().to_string();
    assert!(err.contains("lacks source joints"), "{err}");
    let motion = Motion::new(0.1, DMatrix::zeros(1, 2)).unwrap();
    let err = retarget(
        &odd,
        &motion,
        &target,
        &JointMap::cmu(),
        &RetargetParams::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("Hips"), "{err}");
    // A map naming a joint the performer lacks.
    let mut map = identity_map(&target);
    map.pairs[3].target = "collarbone".into();
    let src = bvh_like(&target, DMat3::IDENTITY, 1.0);
    let m = Motion::new(0.1, DMatrix::zeros(src.dof_count(), 1)).unwrap();
    let err = retarget(&src, &m, &target, &map, &RetargetParams::default())
        .unwrap_err()
        .to_string();
    assert!(err.contains("collarbone"), "{err}");
    // Wrong motion size.
    let bad = Motion::new(0.1, DMatrix::zeros(3, 1)).unwrap();
    assert!(retarget(
        &src,
        &bad,
        &target,
        &identity_map(&target),
        &RetargetParams::default()
    )
    .is_err());
    // Clamping keeps every frame inside the limits.
    let wild = Motion::new(0.1, DMatrix::from_element(src.dof_count(), 2, 2.5)).unwrap();
    let out = retarget(
        &src,
        &wild,
        &target,
        &identity_map(&target),
        &RetargetParams {
            clamp_to_limits: true,
            ..RetargetParams::default()
        },
    )
    .unwrap();
    for f in 0..2 {
        assert!(target
            .limit_violations(out.motion.frame(f))
            .unwrap()
            .is_empty());
    }
}

#[test]
fn decompose_inverts_composition() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let axes = [-DVec3::X, DVec3::Z, -DVec3::Y];
    for _ in 0..50 {
        let a: Vec<f64> = (0..3).map(|_| 2.0 * rng.random::<f64>() - 1.0).collect();
        let l = DMat3::from_axis_angle(axes[0], a[0])
            * DMat3::from_axis_angle(axes[1], a[1])
            * DMat3::from_axis_angle(axes[2], a[2]);
        let got = decompose(l, &axes).unwrap();
        for (x, y) in got.iter().zip(&a) {
            assert!((x - y).abs() < 1e-12);
        }
        let one = decompose(DMat3::from_axis_angle(axes[1], a[1]), &axes[1..2]).unwrap();
        assert!((one[0] - a[1]).abs() < 1e-12);
    }
    assert!(decompose(
        DMat3::IDENTITY,
        &[DVec3::X, DVec3::new(1.0, 1.0, 0.0).normalize()]
    )
    .is_none());
}

proptest::proptest! {
    /// Euler decomposition onto signed orthonormal axes inverts composition (|middle| < π/2).
    #[test]
    fn decompose_round_trip(a in -3.0f64..3.0, b in -1.5f64..1.5, c in -3.0f64..3.0, perm in 0usize..6, flip in 0usize..8) {
        let base = [DVec3::X, DVec3::Y, DVec3::Z];
        let order = [[0, 1, 2], [0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]][perm];
        let axes: Vec<DVec3> = (0..3).map(|i| base[order[i]] * if flip >> i & 1 == 1 { -1.0 } else { 1.0 }).collect();
        let l = DMat3::from_axis_angle(axes[0], a) * DMat3::from_axis_angle(axes[1], b) * DMat3::from_axis_angle(axes[2], c);
        let got = decompose(l, &axes).unwrap();
        let back = DMat3::from_axis_angle(axes[0], got[0]) * DMat3::from_axis_angle(axes[1], got[1]) * DMat3::from_axis_angle(axes[2], got[2]);
        proptest::prop_assert!((back - l).abs_diff_eq(DMat3::ZERO, 1e-9));
        proptest::prop_assert!((got[1] - b).abs() < 1e-9);
    }
}

/// World-frame angular speeds (rad/s) of joint `j`'s frame between consecutive frames.
fn world_speeds(s: &Skeleton, m: &Motion, j: usize) -> Vec<f64> {
    let rots: Vec<DQuat> = (0..m.frame_count())
        .map(|f| {
            let fk = s.forward_kinematics(m.frame(f)).unwrap();
            DQuat::from_mat3(&fk.world_from_joint()[j].matrix3)
        })
        .collect();
    rots.windows(2)
        .map(|w| w[1].angle_between(w[0]) / m.frame_time_s)
        .collect()
}

fn cmu_walk() -> skin_core::skeleton::Bvh {
    read_bvh(
        data("mocap-cmu/131_01.bvh"),
        &BvhParams {
            metres_per_unit: CMU_METRES_PER_UNIT,
        },
    )
    .unwrap()
}

/// The CMU walk retargeted onto `target` with the given twist rate limit.
fn retarget_walk(
    bvh: &skin_core::skeleton::Bvh,
    target: &Skeleton,
    twist: Option<f64>,
) -> Result<Retargeted> {
    retarget(
        &bvh.skeleton,
        &bvh.motion,
        target,
        &JointMap::cmu(),
        &RetargetParams {
            twist_rate_limit_rad_per_s: twist,
            ..RetargetParams::default()
        },
    )
}

const BONES: [(&str, &str); 8] = [
    ("LeftShoulder", "l_shoulder"),
    ("RightShoulder", "r_shoulder"),
    ("LeftElbow", "l_elbow"),
    ("RightElbow", "r_elbow"),
    ("LeftHip", "l_hip"),
    ("RightKnee", "r_knee"),
    ("Chest", "chest"),
    ("Head", "head"),
];

/// The retargeted walk spins the right upper arm at 35 rad/s because the SOURCE does — the retarget
/// adds no spin. 3-DOF joints reproduce the source bone's world angular velocity exactly (the world
/// rotation is `G R_src Gᵀ C`, C constant); 1- and 2-DOF joints (knee, elbow, head) stay within a
/// small margin of it.
#[test]
fn retarget_adds_no_angular_velocity_on_the_cmu_walk() {
    let bvh = cmu_walk();
    let target = human_skeleton(&HumanParams::default()).unwrap();
    let out = retarget_walk(&bvh, &target, None).unwrap();
    let max = |v: &[f64]| v.iter().copied().fold(0.0, f64::max);
    for (sn, tn) in BONES {
        let a = world_speeds(
            &bvh.skeleton,
            &bvh.motion,
            bvh.skeleton.joint_index(sn).unwrap(),
        );
        let t = target.joint_index(tn).unwrap();
        let b = world_speeds(&target, &out.motion, t);
        if target.joint_dofs(t).len() == 3 {
            let worst = a
                .iter()
                .zip(&b)
                .map(|(x, y)| (x - y).abs())
                .fold(0.0, f64::max);
            assert!(worst < 1e-6, "{tn}: speeds differ by {worst} rad/s");
        } else {
            assert!(
                max(&b) <= 1.1 * max(&a) + 1.0,
                "{tn}: {} vs source {}",
                max(&b),
                max(&a)
            );
        }
    }
    // The source's right humerus: 34.9 rad/s at frame 235 (1.96 s), almost all of it twist
    // about the bone while the elbow extends; the left stays under 9 rad/s.
    let r = world_speeds(
        &bvh.skeleton,
        &bvh.motion,
        bvh.skeleton.joint_index("RightShoulder").unwrap(),
    );
    let l = world_speeds(
        &bvh.skeleton,
        &bvh.motion,
        bvh.skeleton.joint_index("LeftShoulder").unwrap(),
    );
    assert!(
        max(&r) > 30.0 && max(&l) < 9.0,
        "right {} left {}",
        max(&r),
        max(&l)
    );
}

/// The opt-in twist rate limit removes the right humerus' twist spike (swing kept exactly:
/// the upper-arm direction is the source's in every frame) and changes nothing where the
/// twist is slower than the limit.
#[test]
fn twist_rate_limit_caps_the_humerus_spin_and_keeps_the_swing() {
    let bvh = cmu_walk();
    let target = human_skeleton(&HumanParams::default()).unwrap();
    let limit = 10.0;
    let run = |twist| retarget_walk(&bvh, &target, twist).unwrap();
    let (plain, limited) = (run(None), run(Some(limit)));
    let max = |v: &[f64]| v.iter().copied().fold(0.0, f64::max);
    let r = target.joint_index("r_shoulder").unwrap();
    let before = max(&world_speeds(&target, &plain.motion, r));
    let after = max(&world_speeds(&target, &limited.motion, r));
    // Swing (≤ 6.6 rad/s in the source) plus the limited twist.
    assert!(
        before > 30.0 && after < limit + 7.0,
        "{before} → {after} rad/s"
    );
    // The forearm turns with the limited humerus (34.7 rad/s in the source).
    let e = target.joint_index("r_elbow").unwrap();
    let (fore_before, fore_after) = (
        max(&world_speeds(&target, &plain.motion, e)),
        max(&world_speeds(&target, &limited.motion, e)),
    );
    assert!(
        fore_before > 30.0 && fore_after < 20.0,
        "forearm {fore_before} → {fore_after} rad/s"
    );
    // The humerus direction is the source's exactly, in every frame.
    let arm = bone_angles(
        &bvh.skeleton,
        &bvh.motion,
        &target,
        &limited,
        [("RightShoulder", "RightElbow", "r_shoulder", "r_elbow")],
    );
    assert!(
        max(&arm) < 1e-6,
        "upper-arm direction off by {} rad",
        max(&arm)
    );
    // The left arm never twists faster than the limit: bit-identical to the plain retarget.
    let l = target.joint_index("l_shoulder").unwrap();
    for d in target.joint_dofs(l) {
        for f in 0..plain.motion.frame_count() {
            assert_eq!(plain.motion.frames[(d, f)], limited.motion.frames[(d, f)]);
        }
    }
    // No limit below zero or NaN.
    for bad in [0.0, -1.0, f64::NAN] {
        assert!(retarget_walk(&bvh, &target, Some(bad)).is_err());
    }
}

/// Trace (run with `--ignored --nocapture`): the fastest DOF rates of the twist-limited walk.
#[test]
#[ignore]
fn trace_dof_rates_of_the_limited_walk() {
    let bvh = cmu_walk();
    let target = human_skeleton(&HumanParams::default()).unwrap();
    let out = retarget_walk(&bvh, &target, Some(10.0)).unwrap();
    let m = &out.motion;
    let mut rates: Vec<(f64, usize, usize)> = (0..target.dof_count())
        .filter(|&d| target.is_rotation(d))
        .map(|d| {
            (1..m.frame_count())
                .map(|f| {
                    let step = m.frames[(d, f)] - m.frames[(d, f - 1)];
                    let step =
                        step - std::f64::consts::TAU * (step / std::f64::consts::TAU).round();
                    (step.abs() / m.frame_time_s, d, f)
                })
                .fold((0.0, d, 0), |a, b| if b.0 > a.0 { b } else { a })
        })
        .collect();
    rates.sort_by(|a, b| b.0.total_cmp(&a.0));
    for (r, d, f) in rates.iter().take(10) {
        println!("{}: {r:.1} rad/s at frame {f}", target.dof(*d).name);
    }
}

/// World angular velocities (rad/s) of joint `j`'s frame between consecutive frames.
fn world_rates(s: &Skeleton, m: &Motion, j: usize) -> Vec<DVec3> {
    let rots: Vec<DQuat> = (0..m.frame_count())
        .map(|f| {
            let fk = s.forward_kinematics(m.frame(f)).unwrap();
            DQuat::from_mat3(&fk.world_from_joint()[j].matrix3)
        })
        .collect();
    rots.windows(2)
        .map(|w| {
            let d = w[1] * w[0].inverse();
            // The shorter of the two quaternions of the step.
            let d = if d.w < 0.0 { -d } else { d };
            d.to_scaled_axis() / m.frame_time_s
        })
        .collect()
}

/// The CMU rig's wrist is a zero-length joint (`LeftWrist → lhand` at offset 0, the hand's length
/// in `lhand → LFingers`), so a rest correction from the wrist's own bone is the identity. On the
/// MakeHuman performer (A-pose hand ≈ 45° off the source's hanging one) the retargeted wrist then
/// sits at the Euler singularity: flexion flipping across ±176°, the hand spinning at 364 rad/s
/// against the source's 19. With the correction from the hand's real bone, the 2-DOF wrist (its
/// dropped third angle is the twist about the hand) reproduces the source hand's direction exactly
/// and turns no faster than the source's hand.
#[test]
fn cmu_wrists_follow_the_source_hands_on_the_makehuman_performer() {
    let bvh = cmu_walk();
    let target = super::super::tests::makehuman().skeleton.clone();
    let out = retarget_walk(&bvh, &target, None).unwrap();
    let g = DMat3::from_quat(out.performer_from_source);
    let max = |v: &[f64]| v.iter().copied().fold(0.0, f64::max);
    for (side, sw, sf) in [
        ("l", "LeftWrist", "LFingers"),
        ("r", "RightWrist", "RFingers"),
    ] {
        let tw = target.joint_index(&format!("{side}_wrist")).unwrap();
        let tip = target.joints()[tw].end_site.unwrap();
        let (sw, sf) = (
            bvh.skeleton.joint_index(sw).unwrap(),
            bvh.skeleton.joint_index(sf).unwrap(),
        );
        let mut worst: f64 = 0.0;
        let mut flexion = (f64::MAX, f64::MIN);
        let d = target.joint_dofs(tw).next().unwrap();
        for f in 0..bvh.motion.frame_count() {
            let sp = bvh
                .skeleton
                .forward_kinematics(bvh.motion.frame(f))
                .unwrap()
                .joint_positions();
            let fk = target.forward_kinematics(out.motion.frame(f)).unwrap();
            let hand = fk.world_from_joint()[tw].matrix3 * tip;
            worst = worst.max(hand.angle_between(g * (sp[sf] - sp[sw])));
            let a = out.motion.frames[(d, f)];
            flexion = (flexion.0.min(a), flexion.1.max(a));
        }
        assert!(worst < 1e-6, "{side} hand direction off by {worst} rad");
        // Away from the ±π flip: the source's hands bend at most 67° off the forearm.
        assert!(
            flexion.0 > -2.0 && flexion.1 < 2.0,
            "{side} wrist flexion {flexion:?} rad"
        );
        let src = world_rates(&bvh.skeleton, &bvh.motion, sw);
        let got = world_rates(&target, &out.motion, tw);
        let speed = |v: &[DVec3]| max(&v.iter().map(|w| w.length()).collect::<Vec<_>>());
        assert!(
            speed(&got) <= 1.1 * speed(&src) + 1.0,
            "{side} hand {} rad/s, source {}",
            speed(&got),
            speed(&src)
        );
    }
}

/// Trace (run with `--ignored --nocapture`): the retargeted CMU walk's wrists on the human
/// and the MakeHuman skeletons — angle ranges, the hand's world angular rate and
/// acceleration.
#[test]
#[ignore]
fn trace_cmu_wrists() {
    let bvh = cmu_walk();
    for sn in ["LeftElbow", "LeftWrist", "RightWrist"] {
        let w = world_rates(
            &bvh.skeleton,
            &bvh.motion,
            bvh.skeleton.joint_index(sn).unwrap(),
        );
        let mut acc: Vec<f64> = w
            .windows(2)
            .map(|p| (p[1] - p[0]).length() / bvh.motion.frame_time_s)
            .collect();
        acc.sort_by(f64::total_cmp);
        let peak = w.iter().map(|v| v.length()).fold(0.0, f64::max);
        println!(
            "source {sn}: peak world rate {peak:.1} rad/s, angular acceleration median {:.0}, 99th pct {:.0} rad/s²",
            acc[acc.len() / 2],
            acc[acc.len() * 99 / 100]
        );
    }
    // The hand's bend off the forearm's line, source and performers.
    let bend = |s: &Skeleton, m: &Motion, [a, b, c, tip]: [&str; 4]| {
        let (mut lo, mut hi) = (f64::MAX, f64::MIN);
        for f in 0..m.frame_count() {
            let fk = s.forward_kinematics(m.frame(f)).unwrap();
            let p = fk.joint_positions();
            let [a, b, c] = [a, b, c].map(|n| p[s.joint_index(n).unwrap()]);
            let t = if tip.is_empty() {
                let w = fk.world_from_joint()[s.joint_index("l_wrist").unwrap()];
                w.transform_point3(
                    s.joints()[s.joint_index("l_wrist").unwrap()]
                        .end_site
                        .unwrap(),
                )
            } else {
                p[s.joint_index(tip).unwrap()]
            };
            let ang = (b - a).angle_between(t - c).to_degrees();
            lo = lo.min(ang);
            hi = hi.max(ang);
        }
        (lo, hi)
    };
    println!(
        "source left hand bend off the forearm: {:.1?} deg",
        bend(
            &bvh.skeleton,
            &bvh.motion,
            ["LeftElbow", "LeftWrist", "LeftWrist", "LFingers"]
        )
    );
    for (name, target) in [
        ("human", human_skeleton(&HumanParams::default()).unwrap()),
        (
            "makehuman",
            super::super::tests::makehuman().skeleton.clone(),
        ),
    ] {
        let out = retarget_walk(&bvh, &target, Some(10.0)).unwrap();
        let m = &out.motion;
        println!(
            "{name} left hand bend off the forearm: {:.1?} deg",
            bend(&target, m, ["l_elbow", "l_wrist", "l_wrist", ""])
        );
        for j in ["l_elbow", "l_wrist", "r_wrist"] {
            let ji = target.joint_index(j).unwrap();
            for d in target.joint_dofs(ji) {
                let v: Vec<f64> = (0..m.frame_count()).map(|f| m.frames[(d, f)]).collect();
                let (lo, hi) = v
                    .iter()
                    .fold((f64::MAX, f64::MIN), |a, &x| (a.0.min(x), a.1.max(x)));
                println!(
                    "{name} {}: {:.1}..{:.1} deg",
                    target.dof(d).name,
                    lo.to_degrees(),
                    hi.to_degrees()
                );
            }
            let w = world_rates(&target, m, ji);
            let mut acc: Vec<f64> = w
                .windows(2)
                .map(|p| (p[1] - p[0]).length() / m.frame_time_s)
                .collect();
            acc.sort_by(f64::total_cmp);
            let peak = w.iter().map(|v| v.length()).fold(0.0, f64::max);
            println!(
                "{name} {j}: peak world rate {peak:.1} rad/s, angular acceleration median {:.0}, 99th pct {:.0} rad/s²",
                acc[acc.len() / 2],
                acc[acc.len() * 99 / 100]
            );
        }
    }
}
