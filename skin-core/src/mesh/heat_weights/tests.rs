use super::*;
use crate::math::{DAffine3, DQuat};
use crate::mesh::{shapes, skin};

fn two_bone_arm() -> (TriMesh, [Bone; 2]) {
    let arm = shapes::cylinder(0.1, 2.0, 16, 40).unwrap();
    let bones = [
        Bone::segment(DVec3::ZERO, DVec3::Z),
        Bone::segment(DVec3::Z, 2.0 * DVec3::Z),
    ];
    (arm, bones)
}

#[test]
fn partition_of_unity_and_bone_middles() {
    let (arm, bones) = two_bone_arm();
    let dense = bone_heat_weights_dense(&arm, &bones, &HeatWeightsParams::default()).unwrap();
    for i in 0..arm.vertices.len() {
        assert!((dense.row(i).sum() - 1.0).abs() < 1e-9, "row {i}");
    }
    let w = bone_heat_weights(&arm, &bones, &HeatWeightsParams::default()).unwrap();
    let d = w.to_dense();
    for (i, p) in arm.vertices.iter().enumerate() {
        assert!((d.row(i).sum() - 1.0).abs() < 1e-12);
        // Middle of each bone: rigidly attached.
        if (p.z - 0.5).abs() < 0.06 {
            assert!(d[(i, 0)] > 0.97, "z {} w {}", p.z, d[(i, 0)]);
        }
        if (p.z - 1.5).abs() < 0.06 {
            assert!(d[(i, 1)] > 0.97, "z {} w {}", p.z, d[(i, 1)]);
        }
        // At the joint: shared about equally, and monotone along the arm.
        if (p.z - 1.0).abs() < 1e-9 {
            assert!((d[(i, 0)] - 0.5).abs() < 0.1, "joint w {}", d[(i, 0)]);
        }
    }
    // Monotone transition from bone 0 to bone 1 along z (one ring per 0.05).
    let ring_w0: Vec<f64> = (0..=40).map(|r| d[(r * 16, 0)]).collect();
    assert!(ring_w0.windows(2).all(|p| p[1] <= p[0] + 1e-9));
}

#[test]
fn skinning_with_heat_weights_bends_the_arm() {
    let (arm, bones) = two_bone_arm();
    let w = bone_heat_weights(&arm, &bones, &HeatWeightsParams::default()).unwrap();
    // Identity pose reproduces the rest mesh.
    let rest = skin(&arm.vertices, &w, &[DAffine3::IDENTITY; 2]).unwrap();
    for (a, b) in rest.iter().zip(&arm.vertices) {
        assert!((*a - *b).length() < 1e-14);
    }
    // Bend the forearm 90° about the elbow (x axis through z = 1).
    let elbow = DVec3::Z;
    let bend = DAffine3::from_translation(elbow)
        * DAffine3::from_quat(DQuat::from_rotation_x(std::f64::consts::FRAC_PI_2))
        * DAffine3::from_translation(-elbow);
    let posed = skin(&arm.vertices, &w, &[DAffine3::IDENTITY, bend]).unwrap();
    for (p, q) in arm.vertices.iter().zip(&posed) {
        if (p.z - 1.75).abs() < 0.06 {
            assert!((*q - bend.transform_point3(*p)).length() < 1e-2);
        }
        if (p.z - 0.25).abs() < 0.06 {
            assert!((*q - *p).length() < 1e-2);
        }
    }
}

/// A torso (radius 0.15) with an arm (radius 0.04) hanging 1 cm from its side, both open
/// tubes along z, one bone each on its axis: the torso's side facing the arm is nearer the
/// arm's bone (5 cm) than its own (15 cm).
fn arm_against_torso() -> (TriMesh, [Bone; 2], Vec<usize>) {
    let torso = shapes::cylinder(0.15, 1.0, 48, 40).unwrap();
    let mut arm = shapes::cylinder(0.04, 1.0, 16, 40).unwrap();
    let offset = DVec3::new(0.2, 0.0, 0.0);
    for v in &mut arm.vertices {
        *v += offset;
    }
    let n0 = torso.vertices.len() as u32;
    let mut mesh = torso.clone();
    mesh.vertices.extend(arm.vertices);
    mesh.faces
        .extend(arm.faces.iter().map(|f| [f[0] + n0, f[1] + n0, f[2] + n0]));
    let bones = [
        Bone::segment(DVec3::ZERO, DVec3::Z),
        Bone::segment(offset, offset + DVec3::Z),
    ];
    // Torso vertices in the middle third facing the arm.
    let facing: Vec<usize> = (0..n0 as usize)
        .filter(|&i| {
            let p = torso.vertices[i];
            p.x > 0.149 && (0.3..0.7).contains(&p.z)
        })
        .collect();
    assert!(!facing.is_empty());
    (mesh, bones, facing)
}

#[test]
fn visibility_keeps_a_torso_from_taking_the_arm_beside_it() {
    let (mesh, bones, facing) = arm_against_torso();
    let torso_weight = |params: &HeatWeightsParams| {
        let d = bone_heat_weights_dense(&mesh, &bones, params).unwrap();
        facing.iter().map(|&i| d[(i, 0)]).fold(1.0, f64::min)
    };
    // Nearest bone only (the behaviour without the test): the arm's bone wins.
    let blind = torso_weight(&HeatWeightsParams::default().without_visibility());
    assert!(blind < 0.5, "without visibility: torso weight {blind}");
    // Pinocchio's test (the default): the torso keeps its side.
    let seen = torso_weight(&HeatWeightsParams::default());
    assert!(seen > 0.95, "with visibility: torso weight {seen}");
    // The volume test alone (no normal cone) already rejects the segment across the gap.
    let volume_only = HeatWeightsParams {
        visibility: Some(VisibilityParams {
            normal_cone_cos: -1.0,
            ..VisibilityParams::default()
        }),
        ..HeatWeightsParams::default()
    };
    let volume = torso_weight(&volume_only);
    assert!(volume > 0.95, "volume test alone: torso weight {volume}");
    // The arm itself still takes its own bone.
    let d = bone_heat_weights_dense(&mesh, &bones, &HeatWeightsParams::default()).unwrap();
    let n0 = 48 * 41;
    for i in n0..mesh.vertices.len() {
        if (0.2..0.8).contains(&mesh.vertices[i].z) {
            assert!(d[(i, 1)] > 0.95, "arm vertex {i}: {}", d[(i, 1)]);
        }
    }
}

#[test]
fn a_component_that_sees_no_bone_is_heated_by_its_nearest() {
    // A detached ring floating around the arm (a loose sleeve) whose segments to the bone
    // all leave the volume... made of outward faces but with the bone outside it.
    let (arm, bones) = two_bone_arm();
    let mut ring = shapes::cylinder(0.05, 0.2, 12, 4).unwrap();
    for v in &mut ring.vertices {
        *v += DVec3::new(0.5, 0.0, 0.4);
    }
    let n0 = arm.vertices.len() as u32;
    let mut mesh = arm.clone();
    mesh.vertices.extend(ring.vertices);
    mesh.faces
        .extend(ring.faces.iter().map(|f| [f[0] + n0, f[1] + n0, f[2] + n0]));
    let d = bone_heat_weights_dense(&mesh, &bones, &HeatWeightsParams::default()).unwrap();
    for i in n0 as usize..mesh.vertices.len() {
        assert!((d.row(i).sum() - 1.0).abs() < 1e-9);
        assert!(d[(i, 0)] > 0.99, "ring vertex {i}: {}", d[(i, 0)]);
    }
    // Joined to the arm only by a degenerate face (its first vertex collinear with two
    // of the arm's at z = 0.4), the ring is still its own component of the heat system,
    // whose Laplacian skips that face.
    mesh.faces.push([n0, 8 * 16, 8 * 16 + 8]);
    let d = bone_heat_weights_dense(&mesh, &bones, &HeatWeightsParams::default()).unwrap();
    for i in n0 as usize..mesh.vertices.len() {
        assert!(d[(i, 0)] > 0.99, "bridged ring vertex {i}: {}", d[(i, 0)]);
    }
}

#[test]
fn rest_bones_run_from_each_joint_to_its_children_and_end_site() {
    use crate::skeleton::{human_skeleton, HumanParams};
    let sk = human_skeleton(&HumanParams::default()).unwrap();
    let bones = rest_bones(&sk).unwrap();
    let fk = sk.forward_kinematics(&sk.rest_pose()).unwrap();
    let at = fk.world_from_joint();
    assert_eq!(bones.len(), sk.joint_count());
    let mut branched = 0;
    for (j, joint) in sk.joints().iter().enumerate() {
        let mut ends: Vec<DVec3> = (0..sk.joint_count())
            .filter(|&c| sk.joints()[c].parent == Some(j))
            .map(|c| at[c].translation)
            .collect();
        ends.extend(joint.end_site.map(|e| at[j].transform_point3(e)));
        if ends.is_empty() {
            ends.push(at[j].translation);
        }
        branched += usize::from(ends.len() > 1);
        assert_eq!(bones[j].segments.len(), ends.len(), "{}", joint.name);
        for (s, e) in bones[j].segments.iter().zip(&ends) {
            assert!((s.start - at[j].translation).length() < 1e-12);
            assert!((s.end - *e).length() < 1e-12, "{}", joint.name);
        }
    }
    // The pelvis (spine and both hips) and the chest (neck and clavicles) branch.
    assert!(branched >= 2);
    // Distance to a branched bone is to its nearest segment.
    let pelvis = &bones[0];
    let hip_end = pelvis.segments[1].end;
    assert!(pelvis.distance(hip_end) < 1e-12);
    assert!((pelvis.closest_point(hip_end) - hip_end).length() < 1e-12);
}

#[test]
fn errors() {
    let (arm, bones) = two_bone_arm();
    let p = HeatWeightsParams::default();
    assert!(matches!(
        bone_heat_weights(&arm, &[], &p),
        Err(Error::Empty { .. })
    ));
    let nan = [Bone::segment(DVec3::NAN, DVec3::Z)];
    assert!(matches!(
        bone_heat_weights(&arm, &nan, &p),
        Err(Error::NonFinite { .. })
    ));
    let hollow = [Bone { segments: vec![] }];
    assert!(matches!(
        bone_heat_weights(&arm, &hollow, &p),
        Err(Error::Empty { .. })
    ));
    let bad = HeatWeightsParams {
        heat_constant: 0.0,
        ..p
    };
    for vis in [
        VisibilityParams {
            tolerance_rel: 0.0,
            ..VisibilityParams::default()
        },
        VisibilityParams {
            step_rel: f64::NAN,
            ..VisibilityParams::default()
        },
        VisibilityParams {
            normal_cone_cos: 1.5,
            ..VisibilityParams::default()
        },
    ] {
        let bad_vis = HeatWeightsParams {
            visibility: Some(vis),
            ..p
        };
        assert!(matches!(
            bone_heat_weights(&arm, &bones, &bad_vis),
            Err(Error::InvalidParam { .. })
        ));
    }
    assert!(matches!(
        bone_heat_weights(&arm, &bones, &bad),
        Err(Error::InvalidParam { .. })
    ));
    assert!(matches!(
        bone_heat_weights(&TriMesh::default(), &bones, &p),
        Err(Error::Empty { .. })
    ));
    // A vertex lying on a bone and an unreferenced vertex still get valid weights.
    let mut m = arm.clone();
    m.vertices.push(DVec3::new(0.0, 0.0, 0.5));
    let w = bone_heat_weights(&m, &bones, &p).unwrap();
    let last: Vec<_> = w.influences(m.vertices.len() - 1).collect();
    assert_eq!(last, vec![(0, 1.0)]);
}
