//! BVH import/export tests: hand-written files with known answers, malformed input, round
//! trips, and the real files in `data/` (CMU 131_01, MakeHuman walk1/dance1).

use crate::math::{DMat3, DVec3};
use crate::skeleton::*;
use crate::Error;
use std::path::PathBuf;

const SMALL: &str = "HIERARCHY
ROOT hips
{
\tOFFSET 0 1 0
\tCHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation
\tJOINT left leg
\t{
\t\tOFFSET 0.1 -0.1 0
\t\tCHANNELS 3 Xrotation Zrotation Yrotation
\t\tEnd Site
\t\t{
\t\t\tOFFSET 0 -0.5 0
\t\t}
\t}
\tJOINT spine {
\t\tOFFSET 0 0.2 0
\t\tCHANNELS 2 Yrotation Xposition
\t}
}
MOTION
Frames: 2
Frame Time: .0083333
1 2 3 10 20 30 40 50 60 70 0.5
-1 -2 -3 0 0 0 0 0 0 0 0

";

/// A data file of the repository's `data/` folder; the tests fail, rather than skip, without it.
fn data_file(rel: &str) -> PathBuf {
    example_kit::data_path(rel).unwrap()
}

fn parse(text: &str) -> crate::Result<Bvh> {
    parse_bvh(text, &BvhParams::default())
}

fn err_line(text: &str) -> (usize, String) {
    match parse(text) {
        Err(Error::Parse { line, message, .. }) => (line, message),
        other => panic!("expected a parse error, got {other:?}"),
    }
}

#[test]
fn small_file_structure_and_values() {
    let b = parse(SMALL).unwrap();
    let s = &b.skeleton;
    assert_eq!(s.joint_count(), 3);
    assert_eq!(s.joints()[1].name, "left leg");
    assert_eq!(s.joints()[1].end_site, Some(DVec3::new(0.0, -0.5, 0.0)));
    assert_eq!(s.joints()[2].parent, Some(0));
    assert_eq!(s.dof_count(), 11);
    // The spine lists Yrotation before Xposition: the translation moves first in the skeleton.
    assert_eq!(s.dof(9).name, "spine.Xposition");
    assert_eq!(s.dof(10).name, "spine.Yrotation");
    assert_eq!(b.motion.frame_count(), 2);
    assert!((b.motion.frame_time_s - 0.0083333).abs() < 1e-15);
    let f = b.motion.frame(0);
    assert_eq!(&f[..3], &[1.0, 2.0, 3.0]);
    assert!((f[3] - 10f64.to_radians()).abs() < 1e-15);
    assert_eq!(f[9], 0.5);
    assert!((f[10] - 70f64.to_radians()).abs() < 1e-15);
}

#[test]
fn euler_order_is_intrinsic_in_listed_order() {
    let b = parse(SMALL).unwrap();
    let s = &b.skeleton;
    let theta = b.motion.frame(0);
    let fk = s.forward_kinematics(theta).unwrap();
    let (z, y, x) = (10f64.to_radians(), 20f64.to_radians(), 30f64.to_radians());
    let r_root = DMat3::from_rotation_z(z) * DMat3::from_rotation_y(y) * DMat3::from_rotation_x(x);
    let t_root = DVec3::new(1.0, 3.0, 3.0); // OFFSET (0,1,0) + position (1,2,3)
    let w0 = fk.world_from_joint()[0];
    assert!((w0.translation - t_root).length() < 1e-14);
    assert!((w0.matrix3 - r_root)
        .abs()
        .to_cols_array()
        .iter()
        .all(|v| *v < 1e-14));
    let (a, b2, c) = (40f64.to_radians(), 50f64.to_radians(), 60f64.to_radians());
    let r_leg =
        r_root * DMat3::from_rotation_x(a) * DMat3::from_rotation_z(b2) * DMat3::from_rotation_y(c);
    let w1 = fk.world_from_joint()[1];
    assert!((w1.translation - (t_root + r_root * DVec3::new(0.1, -0.1, 0.0))).length() < 1e-14);
    assert!((w1.matrix3 - r_leg)
        .abs()
        .to_cols_array()
        .iter()
        .all(|v| *v < 1e-14));
    // Spine: translation along the parent-rotated X *before* its own Y rotation.
    let w2 = fk.world_from_joint()[2];
    let expect = t_root + r_root * (DVec3::new(0.0, 0.2, 0.0) + DVec3::X * 0.5);
    assert!((w2.translation - expect).length() < 1e-14);
}

#[test]
fn units_are_scaled() {
    let b = parse_bvh(
        SMALL,
        &BvhParams {
            metres_per_unit: 0.1,
        },
    )
    .unwrap();
    assert!((b.skeleton.joints()[0].offset.y - 0.1).abs() < 1e-15);
    assert!((b.motion.frame(0)[0] - 0.1).abs() < 1e-15);
    assert!(
        (b.motion.frame(0)[3] - 10f64.to_radians()).abs() < 1e-15,
        "angles not scaled"
    );
    assert!(parse_bvh(
        SMALL,
        &BvhParams {
            metres_per_unit: 0.0
        }
    )
    .is_err());
    assert!(parse_bvh(
        SMALL,
        &BvhParams {
            metres_per_unit: f64::NAN
        }
    )
    .is_err());
}

fn assert_same(a: &Bvh, b: &Bvh, tol: f64) {
    assert_eq!(a.skeleton.joint_count(), b.skeleton.joint_count());
    for (ja, jb) in a.skeleton.joints().iter().zip(b.skeleton.joints()) {
        assert_eq!(ja.name, jb.name);
        assert_eq!(ja.parent, jb.parent);
        assert!((ja.offset - jb.offset).length() <= tol * (1.0 + ja.offset.length()));
        assert_eq!(ja.end_site.is_some(), jb.end_site.is_some());
        assert_eq!(ja.dofs.len(), jb.dofs.len());
        for (da, db) in ja.dofs.iter().zip(&jb.dofs) {
            assert_eq!((da.kind, da.axis), (db.kind, db.axis));
        }
    }
    assert_eq!(a.motion.frames.shape(), b.motion.frames.shape());
    assert!((a.motion.frame_time_s - b.motion.frame_time_s).abs() <= 1e-15);
    let diff = (&a.motion.frames - &b.motion.frames).abs().max();
    assert!(
        diff <= tol * (1.0 + a.motion.frames.abs().max()),
        "frames differ by {diff}"
    );
    for k in 0..a.motion.frame_count() {
        let fa = a.skeleton.forward_kinematics(a.motion.frame(k)).unwrap();
        let fb = b.skeleton.forward_kinematics(b.motion.frame(k)).unwrap();
        for (pa, pb) in fa.joint_positions().iter().zip(fb.joint_positions()) {
            assert!(
                (*pa - pb).length() <= tol * (1.0 + pa.length()),
                "frame {k}: {pa} vs {pb}"
            );
        }
    }
}

fn round_trip(b: &Bvh, params: &BvhParams) -> Bvh {
    let text = to_bvh_string(&b.skeleton, &b.motion, params).unwrap();
    parse_bvh(&text, params).unwrap()
}

#[test]
fn export_round_trip_small() {
    let b = parse(SMALL).unwrap();
    let again = round_trip(&b, &BvhParams::default());
    assert_eq!(
        again.skeleton, b.skeleton,
        "offsets in metres survive exactly"
    );
    assert_same(&b, &again, 1e-14);
}

#[test]
fn export_human_skeleton_keeps_fk() {
    let s = human_skeleton(&HumanParams::default()).unwrap();
    let n = s.dof_count();
    let frames = nalgebra::DMatrix::from_fn(n, 3, |d, k| 0.1 * ((d * 7 + k * 3) % 11) as f64 - 0.5);
    let motion = Motion::new(1.0 / 60.0, frames).unwrap();
    let path = std::env::temp_dir().join(format!("skin_core_human_{}.bvh", std::process::id()));
    write_bvh(
        &path,
        &s,
        &motion,
        &BvhParams {
            metres_per_unit: 0.01,
        },
    )
    .unwrap();
    let b = read_bvh(
        &path,
        &BvhParams {
            metres_per_unit: 0.01,
        },
    )
    .unwrap();
    let _ = std::fs::remove_file(&path);
    assert_eq!(b.skeleton.dof_count(), n);
    for k in 0..3 {
        let fa = s.forward_kinematics(motion.frame(k)).unwrap();
        let fb = b.skeleton.forward_kinematics(b.motion.frame(k)).unwrap();
        for (j, (pa, pb)) in fa
            .joint_positions()
            .iter()
            .zip(fb.joint_positions())
            .enumerate()
        {
            assert!((*pa - pb).length() < 1e-12, "joint {j}: {pa} vs {pb}");
        }
    }
}

#[test]
fn export_rejects_unrepresentable_skeletons() {
    let oblique = Skeleton::new(vec![Joint::new(
        "a",
        None,
        DVec3::ZERO,
        vec![Dof::rotation("a.r", DVec3::new(1.0, 1.0, 0.0), None)],
    )])
    .unwrap();
    let m = Motion::new(0.1, nalgebra::DMatrix::zeros(1, 1)).unwrap();
    let e = to_bvh_string(&oblique, &m, &BvhParams::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("a.r"), "{e}");
    let late = Skeleton::new(vec![Joint::new(
        "a",
        None,
        DVec3::ZERO,
        vec![
            Dof::rotation("r", DVec3::X, None),
            Dof::translation("t", DVec3::X, None),
        ],
    )])
    .unwrap();
    let m2 = Motion::new(0.1, nalgebra::DMatrix::zeros(2, 1)).unwrap();
    assert!(to_bvh_string(&late, &m2, &BvhParams::default()).is_err());
    let braces = Skeleton::new(vec![Joint::new("a{", None, DVec3::ZERO, vec![])]).unwrap();
    let m0 = Motion::new(0.1, nalgebra::DMatrix::zeros(0, 1)).unwrap();
    assert!(to_bvh_string(&braces, &m0, &BvhParams::default()).is_err());
    // Motion of the wrong size.
    assert!(matches!(
        to_bvh_string(&oblique, &m2, &BvhParams::default()),
        Err(Error::SizeMismatch { .. })
    ));
}

#[test]
fn malformed_files_name_the_line() {
    // Missing closing brace of the spine: MOTION arrives while it is open.
    let t = SMALL.replacen("\t}\n}\nMOTION", "}\nMOTION", 1);
    let (line, msg) = err_line(&t);
    assert_eq!(line, 19, "{msg}");
    assert!(
        msg.contains("'hips'"),
        "the spine's brace closes the root's block: {msg}"
    );
    // Missing opening brace.
    let (line, msg) = err_line(&SMALL.replacen("ROOT hips\n{", "ROOT hips\n", 1));
    assert_eq!(line, 4, "{msg}");
    // Truncated in the hierarchy.
    let (_, msg) = err_line(&SMALL[..SMALL.find("JOINT spine").unwrap()]);
    assert!(msg.contains("end of file"), "{msg}");
    // Wrong channel count per frame (10 instead of 11), naming the missing joint.
    let (line, msg) = err_line(&SMALL.replace("70 0.5", "70"));
    assert_eq!(line, 23);
    assert!(msg.contains("10 values") && msg.contains("spine"), "{msg}");
    // Too many values.
    let (line, msg) = err_line(&SMALL.replace("70 0.5", "70 0.5 1"));
    assert_eq!(line, 23, "{msg}");
    // Non-numeric and non-finite values, naming joint and channel.
    let (line, msg) = err_line(&SMALL.replace(" 40 50", " 4o 50"));
    assert_eq!(line, 23);
    assert!(
        msg.contains("left leg") && msg.contains("Xrotation") && msg.contains("4o"),
        "{msg}"
    );
    let (_, msg) = err_line(&SMALL.replace(" 40 50", " NaN 50"));
    assert!(msg.contains("NaN"), "{msg}");
    let (_, msg) = err_line(&SMALL.replace("OFFSET 0.1", "OFFSET inf"));
    assert!(msg.contains("inf"), "{msg}");
    // Frames count mismatch, both ways.
    let (_, msg) = err_line(&SMALL.replace("Frames: 2", "Frames: 3"));
    assert!(
        msg.contains("Frames: 3") && msg.contains("2 frame lines"),
        "{msg}"
    );
    let (line, _) = err_line(&SMALL.replace("Frames: 2", "Frames: 1"));
    assert_eq!(line, 24);
    // Header problems.
    let (line, _) = err_line(&SMALL.replace("Frame Time: .0083333", "Frame Time: 0"));
    assert_eq!(line, 22);
    let (line, _) = err_line(&SMALL.replace("Frames: 2", "Frames two"));
    assert_eq!(line, 21);
    let (_, msg) = err_line(&SMALL.replace("CHANNELS 3 Xrotation", "CHANNELS 3 Wrotation"));
    assert!(msg.contains("Wrotation"));
    let (_, msg) = err_line(&SMALL.replace("JOINT spine", "JOINT left leg"));
    assert!(msg.contains("duplicate"), "{msg}");
    let (_, msg) = err_line(&SMALL.replace("\t\tOFFSET 0 0.2 0\n", ""));
    assert!(msg.contains("no OFFSET"), "{msg}");
    let (line, _) = err_line(&SMALL.replace("HIERARCHY", "HIERARCHI"));
    assert_eq!(line, 1);
    assert!(err_line("").1.contains("end of file"));
    let (_, msg) = err_line(&SMALL.replace("MOTION\n", "").replace("Frames: 2\n", ""));
    assert!(!msg.is_empty());
    assert!(matches!(
        read_bvh("/nonexistent/x.bvh", &BvhParams::default()),
        Err(Error::Io { .. })
    ));
}

#[test]
fn odd_but_valid_layouts() {
    // Frame Time with space before the colon, no channels, zero frames, CRLF endings.
    let t = "HIERARCHY\r\nROOT a\r\n{\r\nOFFSET 0 0 0\r\n}\r\nMOTION\r\nFrames: 0\r\nFrame Time : 0.5\r\n";
    let b = parse(t).unwrap();
    assert_eq!(b.motion.frame_count(), 0);
    assert_eq!(b.skeleton.dof_count(), 0);
    let t2 = "HIERARCHY\nROOT a\n{\nOFFSET 0 0 0\n}\nROOT b\n{\nOFFSET 1 0 0\nCHANNELS 1 yrotation\n}\nMOTION\nFrames: 1\nFrame Time: 0.5\n45\n";
    let b = parse(t2).unwrap();
    assert_eq!(b.skeleton.joints()[1].parent, None);
    assert_eq!(b.skeleton.dof(0).axis, DVec3::Y);
}

#[test]
fn cmu_131_01() {
    let path = data_file("mocap-cmu/131_01.bvh");
    let b = read_bvh(
        &path,
        &BvhParams {
            metres_per_unit: CMU_METRES_PER_UNIT,
        },
    )
    .unwrap();
    let s = &b.skeleton;
    // SOURCE.md: 994 frames at 120 Hz, 31 joints, root Hips.
    assert_eq!(b.motion.frame_count(), 994);
    assert!((b.motion.frame_time_s - 0.0083333).abs() < 1e-9);
    assert_eq!(s.joint_count(), 31);
    assert_eq!(s.joints()[0].name, "Hips");
    assert_eq!(s.dof_count(), 6 + 30 * 3);
    // Thigh and shank lengths of an adult, 0.35–0.5 m.
    for (a, c) in [
        ("LeftHip", "LeftKnee"),
        ("LeftKnee", "LeftAnkle"),
        ("RightHip", "RightKnee"),
    ] {
        let len = s.joints()[s.joint_index(c).unwrap()].offset.length();
        assert!((0.35..0.5).contains(&len), "{a}-{c}: {len} m");
        let _ = a;
    }
    // Standing height in the first frame: head end site above the lowest toe, 1.5–1.9 m.
    let fk = s.forward_kinematics(b.motion.frame(0)).unwrap();
    let head = s.joint_index("Head").unwrap();
    let top = fk
        .point(&AttachedPoint {
            joint: head,
            offset: s.joints()[head].end_site.unwrap(),
        })
        .unwrap();
    let feet = fk
        .joint_positions()
        .iter()
        .map(|p| p.y)
        .fold(f64::INFINITY, f64::min);
    let h = top.y - feet;
    let rest = s.forward_kinematics(&s.rest_pose()).unwrap();
    let top_rest = rest
        .point(&AttachedPoint {
            joint: head,
            offset: s.joints()[head].end_site.unwrap(),
        })
        .unwrap();
    let feet_rest = rest
        .joint_positions()
        .iter()
        .map(|p| p.y)
        .fold(f64::INFINITY, f64::min);
    eprintln!(
        "CMU 131_01 height: frame 0 {h:.3} m, rest {:.3} m",
        top_rest.y - feet_rest
    );
    // The 3ds Max conversion merges CMU's upper-back segment and ends the head at its centre,
    // so this skeleton stands about 1.4 m from toe to head end site.
    assert!((1.3..1.95).contains(&h), "height {h} m");
    // Round trip in file units.
    let p = BvhParams {
        metres_per_unit: CMU_METRES_PER_UNIT,
    };
    assert_same(&b, &round_trip(&b, &p), 1e-12);
    // Resampling to 30 Hz keeps the span.
    let r = b.motion.resample(s, 1.0 / 30.0).unwrap();
    assert_eq!(
        r.frame_count(),
        (993.0 * 0.0083333 * 30.0f64).floor() as usize + 1
    );
}

#[test]
fn makehuman_walk_and_dance() {
    for (file, frames) in [("makehuman/walk1.bvh", 14), ("makehuman/dance1.bvh", 1)] {
        let path = data_file(file);
        let p = BvhParams {
            metres_per_unit: 0.1,
        }; // MakeHuman works in decimetres.
        let b = read_bvh(&path, &p).unwrap();
        let s = &b.skeleton;
        assert_eq!(b.motion.frame_count(), frames, "{file}");
        // ROOT + 74 JOINTs (the MakeHuman "game" rig with fingers, eyes, tongue).
        assert_eq!(s.joint_count(), 75, "{file}");
        b.motion.check_for(s).unwrap();
        for name in ["UpLeg_L", "LoLeg_L", "UpLeg_R", "LoLeg_R"] {
            let len = s.bone_length(s.joint_index(name).unwrap());
            eprintln!("{file} {name}: {len:.3} m");
            assert!((0.2..0.55).contains(&len), "{file} {name}: {len} m");
        }
        assert_same(&b, &round_trip(&b, &p), 1e-12);
    }
}
