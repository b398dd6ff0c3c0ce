//! Tests of the performers and their non-skinning deformation.

use super::texture::Material;
use super::*;
use nalgebra::DMatrix;
use skin_core::math::DVec3;
use skin_core::mesh::SkinWeights;
use skin_core::skeleton::Motion;
use skin_core::Error;
use std::path::PathBuf;
use std::sync::OnceLock;

/// A file of the repository's `data/` folder. The tests need it: a missing file fails them
/// with a message naming the path rather than skipping silently.
pub(crate) fn data(rel: &str) -> PathBuf {
    example_kit::data_path(rel).unwrap()
}

fn procedural() -> &'static Performer {
    static P: OnceLock<Performer> = OnceLock::new();
    P.get_or_init(|| {
        procedural_performer(&ProceduralBodyParams {
            grid_spacing_m: 0.03,
            ..Default::default()
        })
        .unwrap()
    })
}

/// The MakeHuman performer with the default deformation, built once for all the studio's
/// tests.
pub(crate) fn makehuman() -> &'static Performer {
    static P: OnceLock<Performer> = OnceLock::new();
    P.get_or_init(|| makehuman_performer(data("makehuman"), &DeformationParams::default()).unwrap())
}

fn with_dof(p: &Performer, dof: &str, v: f64) -> Vec<f64> {
    let mut t = p.skeleton.rest_pose();
    t[p.skeleton.dof_index(dof).unwrap()] = v;
    t
}

fn nonskinning_at(p: &Performer, dof: &str, v: f64) -> f64 {
    p.pose(&with_dof(p, dof, v), &mut DeformationState::default(), 0.0)
        .unwrap()
        .max_nonskinning_m()
}

/// The pose-driven shapes of the elbow and knee: zero at rest and under extension, growing
/// with flexion to their reference angle, then held (the activation saturates), tens of
/// millimetres in size.
fn check_pose_shapes(p: &Performer) {
    for dof in ["l_elbow.flexion", "r_knee.flexion"] {
        assert_eq!(nonskinning_at(p, dof, 0.0), 0.0, "{dof}: zero at rest");
        let mut last = 0.0;
        for v in [0.3, 0.8, 1.5] {
            let d = nonskinning_at(p, dof, v);
            assert!(
                d > last,
                "{dof}: shapes grow with flexion ({v} rad: {d} m after {last} m)"
            );
            last = d;
        }
        let full = nonskinning_at(p, dof, 2.3);
        assert!(full >= 0.9 * last, "{dof}: held past the reference angle");
        assert!((0.01..0.08).contains(&full), "{dof}: {full} m at 2.3 rad");
        // Extension (negative flexion, if allowed) does not activate them.
        assert_eq!(nonskinning_at(p, dof, -0.2), 0.0);
    }
}

#[test]
fn procedural_pose_shapes_zero_at_rest_and_grow_with_flexion() {
    check_pose_shapes(procedural());
}

#[test]
fn makehuman_performer_matches_template_and_deforms() {
    let p = makehuman();
    assert_eq!(p.vertex_count(), 13380);
    assert_eq!(p.skeleton.dof_count(), 42);
    let f = p
        .pose(
            &p.skeleton.rest_pose(),
            &mut DeformationState::default(),
            0.0,
        )
        .unwrap();
    for (a, b) in f.true_vertices.iter().zip(&p.template.vertices) {
        assert!(a.distance(*b) < 1e-12, "rest pose equals template");
    }
    let top = p
        .template
        .vertices
        .iter()
        .map(|v| v.y)
        .fold(f64::MIN, f64::max);
    let bottom = p
        .template
        .vertices
        .iter()
        .map(|v| v.y)
        .fold(f64::MAX, f64::min);
    assert!(
        (top - bottom - 1.67).abs() < 0.03,
        "metres, 1.67 m tall: {}",
        top - bottom
    );
    // Joints sit inside the body: hips below the pelvis, knees below hips, left is +X.
    let pos = |n: &str| f.joint_positions[p.skeleton.joint_index(n).unwrap()];
    assert!(pos("l_hip").x > 0.05 && pos("r_hip").x < -0.05);
    assert!(pos("l_knee").y < pos("l_hip").y - 0.3 && pos("head").y > pos("neck").y);
    check_pose_shapes(p);
    assert!(p.deformation.flap_mass_count() >= 2);
    // DOF axes follow the A-pose: rest inside the limits, elbow flexion about the arm plane's
    // normal, and its limit at the anatomical 150° bend from the straight arm.
    assert!(p
        .skeleton
        .limit_violations(&p.skeleton.rest_pose())
        .unwrap()
        .is_empty());
    let d = p.skeleton.dof_index("l_elbow.flexion").unwrap();
    let max = p.skeleton.dof(d).limits.unwrap().max;
    let mut theta = p.skeleton.rest_pose();
    theta[d] = max;
    let q = p
        .skeleton
        .forward_kinematics(&theta)
        .unwrap()
        .joint_positions();
    let at = |n: &str| q[p.skeleton.joint_index(n).unwrap()];
    let upper = at("l_elbow") - at("l_shoulder");
    let fore = at("l_wrist") - at("l_elbow");
    let bend = upper.angle_between(fore).to_degrees();
    assert!(
        (bend - 150.0).abs() < 1.0,
        "full elbow flexion bends {bend}°"
    );
    let axis = p.skeleton.dof(d).axis;
    assert!(axis.dot(upper.normalize()).abs() < 1e-9);
}

fn root_sway(p: &Performer, frames: usize, dt: f64, stop_after: usize) -> Motion {
    let tx = p.skeleton.dof_index("pelvis.tx").unwrap();
    let m = DMatrix::from_fn(p.skeleton.dof_count(), frames, |d, k| {
        let t = k.min(stop_after) as f64 * dt;
        if d == tx {
            0.15 * (std::f64::consts::TAU * 1.5 * t).sin()
        } else {
            0.0
        }
    });
    Motion::new(dt, m).unwrap()
}

#[test]
fn flap_lags_motion_then_settles_deterministically() {
    let p = procedural();
    assert!(p.deformation.flap_mass_count() >= 2);
    let dt = 1.0 / 60.0;
    let m = root_sway(p, 240, dt, 60);
    let mut trace = Vec::new();
    p.perform(&m, |_, f| {
        trace.push(f.max_nonskinning_m());
        // A root translation is rigid: no pose-driven shape, all of the difference is the
        // flap, recorded as dynamic, and the truth is exactly the sum of its parts.
        assert!(f.pose_displacement.iter().all(|d| *d == DVec3::ZERO));
        for (((t, l), p), d) in f
            .true_vertices
            .iter()
            .zip(&f.lbs_vertices)
            .zip(&f.pose_displacement)
            .zip(&f.dynamic_displacement)
        {
            assert_eq!(*t, *l + *p + *d);
        }
        Ok(())
    })
    .unwrap();
    assert_eq!(trace[0], 0.0, "first frame starts at rest");
    let peak = trace[..70].iter().copied().fold(0.0, f64::max);
    assert!(
        peak > 0.005,
        "a 1.5 Hz, 15 cm sway drags the flap: {peak} m"
    );
    assert!(
        trace[239] < 0.1 * peak,
        "settles after the body stops: {} vs {peak}",
        trace[239]
    );
    // Pure translation is rigid for LBS: all of that difference is the flap.
    let mut again = Vec::new();
    p.perform(&m, |_, f| {
        again.push(f.max_nonskinning_m());
        Ok(())
    })
    .unwrap();
    assert_eq!(trace, again, "deterministic");
    // Holding the rest pose never moves the flap.
    let rest = Motion::new(dt, DMatrix::zeros(p.skeleton.dof_count(), 30)).unwrap();
    assert_eq!(p.max_nonskinning_m(&rest).unwrap(), 0.0);
}

#[test]
fn fast_motion_gives_tens_of_mm() {
    let p = procedural();
    let m = fast_motion(
        &p.skeleton,
        &FastMotionParams {
            duration_s: 1.5,
            ..Default::default()
        },
    )
    .unwrap();
    let d = p.max_nonskinning_m(&m).unwrap();
    assert!((0.01..0.15).contains(&d), "{d}");
}

#[test]
fn pose_rejects_bad_input() {
    let p = procedural();
    let mut st = DeformationState::default();
    let rest = p.skeleton.rest_pose();
    assert!(matches!(
        p.pose(&rest[1..], &mut st, 0.1),
        Err(Error::SizeMismatch { .. })
    ));
    let mut nan = rest.clone();
    nan[7] = f64::NAN;
    assert!(p.pose(&nan, &mut st, 0.1).is_err());
    p.pose(&rest, &mut st, 0.0).unwrap();
    assert!(matches!(
        p.pose(&rest, &mut st, 0.0),
        Err(Error::InvalidParam { name: "dt_s", .. })
    ));
    assert!(p.pose(&rest, &mut st, f64::NAN).is_err());
    let mut wrong = st.clone();
    wrong.positions.pop();
    assert!(matches!(
        p.pose(&rest, &mut wrong, 0.1),
        Err(Error::SizeMismatch { .. })
    ));
    // Performer construction checks sizes and names.
    let w = SkinWeights::from_lists(&vec![vec![(0, 1.0)]; 3], p.skeleton.joint_count()).unwrap();
    let r = Performer::new(
        "x",
        p.template.clone(),
        p.skeleton.clone(),
        w,
        &DeformationParams::none(),
    );
    assert!(matches!(r, Err(Error::SizeMismatch { .. })));
    let mut params = DeformationParams::default();
    if let Some(f) = params.flap.as_mut() {
        f.joints[0] = "l_humerus".into();
    }
    let r = Performer::new(
        "x",
        p.template.clone(),
        p.skeleton.clone(),
        p.weights.clone(),
        &params,
    );
    assert!(r.unwrap_err().to_string().contains("l_humerus"));
    let mut params = DeformationParams::default();
    if let Some(f) = params.flap.as_mut() {
        f.stiffness_n_per_m = -1.0;
    }
    assert!(Performer::new(
        "x",
        p.template.clone(),
        p.skeleton.clone(),
        p.weights.clone(),
        &params
    )
    .is_err());
    // Without deformation, truth equals LBS.
    let plain = Performer::new(
        "x",
        p.template.clone(),
        p.skeleton.clone(),
        p.weights.clone(),
        &DeformationParams::none(),
    )
    .unwrap();
    assert_eq!(nonskinning_at(&plain, "l_elbow.flexion", 2.0), 0.0);
}

/// The MakeHuman performer with the default pose-driven shapes and the default skirt instead of
/// the hip flap (the flap is the skin-tight stand-in for loose clothing; under a skirt it
/// only distorts the thighs the skirt collides with).
fn skirted() -> &'static Performer {
    static P: OnceLock<Performer> = OnceLock::new();
    P.get_or_init(|| {
        makehuman_performer(
            data("makehuman"),
            &DeformationParams::default()
                .with_flap(None)
                .with_garment(Some(GarmentParams::Skirt(SkirtParams::default()))),
        )
        .unwrap()
    })
}

#[test]
fn the_template_carries_texture_coordinates_for_the_body_and_the_skirt() {
    let p = skirted();
    let uvs = p.uvs.as_ref().expect("MakeHuman's base mesh has vt lines");
    uvs.validate(&p.template).unwrap();
    let split = uvs.split_seams(&p.template).unwrap();
    // Every vertex keeps at least one coordinate; seams add fewer vertices than there are.
    assert!(split.vertex.len() >= p.vertex_count());
    assert!(split.vertex.len() < 2 * p.vertex_count());
    assert!(split.uvs.iter().all(|c| (-1e-9..=2.0).contains(&c.x)));
    // A layout for another mesh is refused.
    let wrong = uvs.clone();
    let mut other = p.clone();
    other.uvs = None;
    assert!(other.with_body_uvs(wrong).is_err());
}

#[test]
fn skirt_is_part_of_the_template_and_its_truth_is_dynamic() {
    let p = skirted();
    let body = &makehuman_performer(
        data("makehuman"),
        &DeformationParams::default().with_flap(None),
    )
    .unwrap();
    let garment = p.garment_vertices();
    assert_eq!(garment.start, body.vertex_count());
    assert_eq!(garment.len(), p.garment().unwrap().vertex_count());
    assert!(garment.len() <= MAX_GARMENT_VERTICES);
    p.template.validate().unwrap();
    let skirt_faces = p
        .face_materials()
        .iter()
        .filter(|m| **m == Material::Garment)
        .count();
    assert_eq!(
        skirt_faces,
        p.template.face_count() - body.template.face_count()
    );
    // Over a second of the fast motion: the truth is exactly the sum of its parts; the body's
    // truth is that of the performer without the skirt (switching the garment off removes
    // exactly the garment); the garment's departure from the skinned garment is dynamic;
    // no skirt vertex that is not pinned enters the true body (arms excepted, they are no
    // colliders) by more than 5 mm.
    let m = fast_motion(
        &p.skeleton,
        &FastMotionParams {
            duration_s: 1.0,
            ..Default::default()
        },
    )
    .unwrap();
    let (faces, seam) = super::garment::tests::body_faces_without_arms(p);
    let g = p.garment().unwrap();
    let mut plain = Vec::new();
    body.perform(&m, |_, f| {
        plain.push(f.true_vertices.clone());
        Ok(())
    })
    .unwrap();
    let (mut lag, mut depth): (f64, f64) = (0.0, 0.0);
    p.perform(&m, |k, f| {
        for (((t, l), q), d) in f
            .true_vertices
            .iter()
            .zip(&f.lbs_vertices)
            .zip(&f.pose_displacement)
            .zip(&f.dynamic_displacement)
        {
            assert_eq!(*t, *l + *q + *d);
        }
        // (The joined skin weights are renormalised rows: equal to rounding.)
        for (a, b) in f.true_vertices[..garment.start].iter().zip(&plain[k]) {
            assert!(
                a.distance(*b) < 1e-12,
                "frame {k}: body {a} vs {b} without the skirt"
            );
        }
        assert!(f.pose_displacement[garment.clone()]
            .iter()
            .all(|d| *d == DVec3::ZERO));
        if k == 0 {
            assert!(f.dynamic_displacement[garment.clone()]
                .iter()
                .all(|d| *d == DVec3::ZERO));
        }
        lag = f.dynamic_displacement[garment.clone()]
            .iter()
            .map(|d| d.length())
            .fold(lag, f64::max);
        if k % 3 == 0 {
            let q = skin_core::mesh::MeshQuery::new(&skin_core::mesh::TriMesh {
                vertices: f.true_vertices[..garment.start].to_vec(),
                faces: faces.clone(),
            })
            .unwrap();
            for (i, v) in f.true_vertices[garment.clone()].iter().enumerate() {
                let cp = q.closest_point(*v).unwrap();
                if !g.is_pinned(i) && !seam[cp.point.face as usize] {
                    depth = depth.max(-cp.signed_distance);
                }
            }
        }
        Ok(())
    })
    .unwrap();
    assert!(lag >= 0.10, "the hem swings {lag} m from the skinned skirt");
    assert!(depth <= 0.005, "skirt {depth} m inside the true body");
}
