//! Tests of the garments on the MakeHuman performer (built without the performer's own
//! non-skinning deformation: the garment is measured against the skinned body).

use super::*;
use crate::tests::data;
use crate::{
    fast_motion, makehuman_performer, DeformationParams, DeformationState, FastMotionParams,
    Performer, PosedFrame,
};
use skin_core::mesh::skin;
use skin_core::skeleton::Motion;
use std::sync::OnceLock;
use std::time::Instant;

fn performer() -> &'static Performer {
    static P: OnceLock<Performer> = OnceLock::new();
    P.get_or_init(|| makehuman_performer(data("makehuman"), &DeformationParams::none()).unwrap())
}

fn build(params: &GarmentParams) -> Result<Garment> {
    let p = performer();
    Garment::new(params, &p.skeleton, &p.template, &p.weights)
}

fn skirt() -> &'static Garment {
    static G: OnceLock<Garment> = OnceLock::new();
    G.get_or_init(|| build(&GarmentParams::Skirt(SkirtParams::default())).unwrap())
}

fn sheet() -> &'static Garment {
    static G: OnceLock<Garment> = OnceLock::new();
    G.get_or_init(|| build(&GarmentParams::Sheet(SheetParams::default())).unwrap())
}

/// Plays `motion`, calling `each(frame, posed body, skinned garment, simulated garment,
/// seconds spent in `step`)`.
fn play(
    g: &Garment,
    motion: &Motion,
    mut each: impl FnMut(usize, &PosedFrame, &[DVec3], &[DVec3], f64),
) {
    let p = performer();
    let mut st = GarmentState::default();
    let mut ds = DeformationState::default();
    for k in 0..motion.frame_count() {
        let f = p
            .pose(motion.frame(k), &mut ds, motion.frame_time_s)
            .unwrap();
        let wfr = p.world_from_rest(&f.world_from_joint);
        let sk = skin(&g.rest_mesh().vertices, g.weights(), &wfr).unwrap();
        let t = Instant::now();
        let sim = g
            .step(
                &mut st,
                &sk,
                &f.world_from_joint,
                &f.lbs_vertices,
                motion.frame_time_s,
            )
            .unwrap();
        let secs = t.elapsed().as_secs_f64();
        each(k, &f, &sk, &sim, secs);
    }
}

fn fast(seconds: f64, frame_time_s: f64) -> Motion {
    fast_motion(
        &performer().skeleton,
        &FastMotionParams {
            duration_s: seconds,
            frame_time_s,
            ..Default::default()
        },
    )
    .unwrap()
}

/// The body's faces except those mainly weighted to the arms and hands (mean over the corners
/// of the weight on shoulder, elbow and wrist ≥ ½), each with whether it lies on the seam where
/// the arms are cut off (a corner whose largest weight is an arm joint's). Arms are no
/// colliders of the skirt and a hand may pass through it: a skirt vertex whose closest point
/// is on the seam is inside an arm (or next to the hole the arm leaves), not the trunk.
fn faces_without_arms() -> (Vec<[u32; 3]>, Vec<bool>) {
    body_faces_without_arms(performer())
}

/// [`faces_without_arms`] of the body of any performer with the human skeleton's arm joints
/// (its first [`Performer::garment_vertices`]`.start` vertices).
pub(crate) fn body_faces_without_arms(p: &Performer) -> (Vec<[u32; 3]>, Vec<bool>) {
    let body = p.garment_vertices().start as u32;
    let arms: Vec<u32> = [
        "l_shoulder",
        "l_elbow",
        "l_wrist",
        "r_shoulder",
        "r_elbow",
        "r_wrist",
    ]
    .iter()
    .map(|n| p.skeleton.joint_index(n).unwrap() as u32)
    .collect();
    let arm = |v: u32| -> f64 {
        p.weights
            .influences(v as usize)
            .filter(|(j, _)| arms.contains(j))
            .map(|(_, w)| w)
            .sum()
    };
    let main_is_arm = |v: u32| {
        let main = p
            .weights
            .influences(v as usize)
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .unwrap()
            .0;
        arms.contains(&main)
    };
    p.template
        .faces
        .iter()
        .filter(|f| f.iter().all(|&v| v < body))
        .filter(|f| f.iter().map(|&v| arm(v)).sum::<f64>() / 3.0 < 0.5)
        .map(|f| (*f, f.iter().any(|&v| main_is_arm(v))))
        .unzip()
}

/// Hem ring of the default skirt.
fn hem(g: &Garment) -> std::ops::Range<usize> {
    let s = SkirtParams::default().segments;
    g.vertex_count() - s..g.vertex_count()
}

#[test]
fn skirt_is_coarse_valid_and_drapes_outside_the_body() {
    let g = skirt();
    let d = SkirtParams::default();
    assert_eq!(g.vertex_count(), d.rings * d.segments);
    assert!(g.vertex_count() <= MAX_GARMENT_VERTICES);
    let m = g.rest_mesh();
    m.validate().unwrap();
    assert_eq!(g.weights().vertex_count(), g.vertex_count());
    assert_eq!(g.weights().bone_count(), performer().skeleton.joint_count());
    // Skinned as a rigger would skin a skirt: pelvis, spine and thighs only.
    let sk = &performer().skeleton;
    let allowed: Vec<u32> = ["pelvis", "spine", "l_hip", "r_hip"]
        .iter()
        .map(|n| sk.joint_index(n).unwrap() as u32)
        .collect();
    for i in 0..g.vertex_count() {
        for (j, w) in g.weights().influences(i) {
            assert!(
                allowed.contains(&j),
                "vertex {i} weight {w} on {}",
                sk.joints()[j as usize].name
            );
        }
    }
    let pinned = (0..g.vertex_count()).filter(|&i| g.is_pinned(i)).count();
    assert_eq!(pinned, d.segments, "the waistband is pinned");
    // Outward normals: the hem's faces point away from the axis.
    let n = skin_core::mesh::face_normals(m).unwrap();
    let c = m.bounding_box().unwrap().center();
    let f = m.face_count() - 1;
    let out = m.triangle(f)[0] - c;
    assert!(n[f].dot(DVec3::new(out.x, 0.0, out.z)) > 0.0);
    // The drape hangs from the waist to below the knees, outside the body.
    let p = performer();
    let rest = p
        .skeleton
        .forward_kinematics(&p.skeleton.rest_pose())
        .unwrap();
    let knee = rest.joint_positions()[p.skeleton.joint_index("l_knee").unwrap()];
    let lowest = m.vertices.iter().map(|v| v.y).fold(f64::INFINITY, f64::min);
    assert!(lowest < knee.y - 0.05, "hem {lowest} below knee {}", knee.y);
    let q = MeshQuery::new(&p.template).unwrap();
    let closest = m
        .vertices
        .iter()
        .map(|v| q.closest_point(*v).unwrap().signed_distance)
        .fold(f64::INFINITY, f64::min);
    assert!(closest > 0.0, "rest drape clears the body: {closest} m");
    // Barely stretched by its own weight.
    let strain = g
        .cloth
        .stretch
        .iter()
        .map(|e| m.vertices[e.i as usize].distance(m.vertices[e.j as usize]) / e.rest_m - 1.0)
        .fold(0.0, f64::max);
    eprintln!(
        "skirt: {} vertices, {} faces, rest clearance {closest:.4} m, max rest strain {strain:.3}",
        g.vertex_count(),
        m.face_count()
    );
}

/// Over 2 s of the fast motion no free skirt vertex is more than 5 mm inside the posed
/// (skinned) body — all of it but the arms and hands, see [`faces_without_arms`] — and the
/// hem swings at least 10 cm away from the skinned skirt.
#[test]
fn skirt_keeps_out_of_the_body_and_swings_in_fast_motion() {
    let g = skirt();
    let (faces, seam) = faces_without_arms();
    let motion = fast(2.0, 1.0 / 60.0);
    let (mut pen, mut pen_pinned, mut hem_lag): (f64, f64, f64) = (0.0, 0.0, 0.0);
    let mut in_arms = 0usize;
    let mut per_frame = Vec::new();
    let hem = hem(g);
    play(g, &motion, |k, f, sk, sim, _| {
        let lag = hem
            .clone()
            .map(|i| sk[i].distance(sim[i]))
            .fold(0.0, f64::max);
        hem_lag = hem_lag.max(lag);
        per_frame.push(lag);
        if k % 2 == 0 {
            let body = TriMesh {
                vertices: f.lbs_vertices.clone(),
                faces: faces.clone(),
            };
            let q = MeshQuery::new(&body).unwrap();
            for (i, v) in sim.iter().enumerate() {
                let cp = q.closest_point(*v).unwrap();
                let d = -cp.signed_distance;
                if seam[cp.point.face as usize] {
                    in_arms += usize::from(d > 0.0);
                } else if g.is_pinned(i) {
                    pen_pinned = pen_pinned.max(d);
                } else {
                    pen = pen.max(d);
                }
            }
        }
    });
    eprintln!(
        "skirt, fast motion 2 s at 60 fps: max penetration {:.1} mm (free), {:.1} mm (pinned \
         waistband, i.e. skinned), max hem displacement from the skinned skirt {:.3} m \
         (median over frames of the largest {:.3} m); {in_arms} vertex-frames inside an arm \
         (not counted)",
        1e3 * pen,
        1e3 * pen_pinned,
        hem_lag,
        skin_core::stats::median(&per_frame)
    );
    assert!(pen <= 0.005, "penetration {pen} m");
    assert!(hem_lag >= 0.10, "hem displacement {hem_lag} m");
}

/// A walk-like motion (legs swinging, body moving forward) that stops: the hem lags and
/// swings, keeps moving after the body stops, then settles.
#[test]
fn skirt_hem_lags_swings_and_settles_after_a_walk() {
    let g = skirt();
    let p = performer();
    let s = &p.skeleton;
    let dt = 1.0 / 30.0;
    let (walk, hold) = (45, 75);
    let dof = |n: &str| s.dof_index(n).unwrap();
    let (lh, rh, lk, rk, tz) = (
        dof("l_hip.flexion"),
        dof("r_hip.flexion"),
        dof("l_knee.flexion"),
        dof("r_knee.flexion"),
        dof("pelvis.tz"),
    );
    let frames = nalgebra::DMatrix::from_fn(s.dof_count(), walk + hold, |d, k| {
        let t = k.min(walk) as f64 * dt;
        let ramp = (t / 0.3).min(1.0);
        let ph = std::f64::consts::TAU * 1.0 * t;
        match d {
            _ if d == lh => ramp * 0.45 * ph.sin(),
            _ if d == rh => -ramp * 0.45 * ph.sin(),
            _ if d == lk => ramp * 0.5 * (ph - 1.0).sin().max(0.0),
            _ if d == rk => ramp * 0.5 * (-ph + 1.0).sin().max(0.0),
            _ if d == tz => 1.2 * t * t / (t + 0.3),
            _ => 0.0,
        }
    });
    let motion = Motion::new(dt, frames).unwrap();
    let hem = hem(g);
    let mut lag = Vec::new();
    let mut speed = Vec::new();
    let mut last: Option<Vec<DVec3>> = None;
    play(g, &motion, |_, _, sk, sim, _| {
        lag.push(
            hem.clone()
                .map(|i| sk[i].distance(sim[i]))
                .fold(0.0, f64::max),
        );
        let v = last.as_ref().map_or(0.0, |l| {
            hem.clone()
                .map(|i| l[i].distance(sim[i]))
                .fold(0.0, f64::max)
                / dt
        });
        speed.push(v);
        last = Some(sim.to_vec());
    });
    let during = lag[10..walk].iter().copied().fold(0.0, f64::max);
    let after = speed[walk + 3..walk + 15]
        .iter()
        .copied()
        .fold(0.0, f64::max);
    let end = speed[walk + hold - 10..]
        .iter()
        .copied()
        .fold(0.0, f64::max);
    eprintln!(
        "skirt walk: max hem lag while walking {during:.3} m, hem speed 0.1–0.5 s after the stop \
         {after:.3} m/s, in the last 1/3 s {end:.4} m/s"
    );
    assert!(during > 0.03, "visible lag while walking: {during} m");
    assert!(
        after > 0.05,
        "the hem keeps swinging after the stop: {after} m/s"
    );
    assert!(end < 0.3 * after, "and settles: {end} vs {after} m/s");
}

#[test]
fn step_is_deterministic_for_any_thread_count_and_starts_at_skinned() {
    let g = skirt();
    let motion = fast(0.3, 1.0 / 60.0);
    let run = || {
        let mut out = Vec::new();
        play(g, &motion, |k, _, sk, sim, _| {
            if k == 0 {
                assert_eq!(sk, sim, "first call starts at the skinned garment");
            }
            out.push(sim.to_vec());
        });
        out
    };
    let a = run();
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let b = one.install(run);
    assert_eq!(a, b, "bit-identical");
    assert!(a.iter().flatten().all(|v| v.is_finite()));
}

#[test]
fn step_rejects_bad_input() {
    let g = skirt();
    let p = performer();
    let rest = p
        .skeleton
        .forward_kinematics(&p.skeleton.rest_pose())
        .unwrap();
    let frames = rest.world_from_joint();
    let sk = g.rest_mesh().vertices.clone();
    let body = &p.template.vertices[..];
    let mut st = GarmentState::default();
    assert!(matches!(
        g.step(&mut st, &sk[1..], frames, body, 0.1),
        Err(Error::SizeMismatch { .. })
    ));
    assert!(matches!(
        g.step(&mut st, &sk, &frames[1..], body, 0.1),
        Err(Error::SizeMismatch { .. })
    ));
    let mut nan = sk.clone();
    nan[3].x = f64::NAN;
    assert!(matches!(
        g.step(&mut st, &nan, frames, body, 0.1),
        Err(Error::NonFinite { .. })
    ));
    assert!(matches!(
        g.step(&mut st, &sk, frames, &body[1..], 0.1),
        Err(Error::SizeMismatch { .. })
    ));
    let mut nan_body = body.to_vec();
    nan_body[7].y = f64::NAN;
    assert!(matches!(
        g.step(&mut st, &sk, frames, &nan_body, 0.1),
        Err(Error::NonFinite { .. })
    ));
    assert_eq!(g.step(&mut st, &sk, frames, body, f64::NAN).unwrap(), sk);
    for bad in [0.0, -0.1, f64::INFINITY] {
        assert!(matches!(
            g.step(&mut st, &sk, frames, body, bad),
            Err(Error::InvalidParam { name: "dt_s", .. })
        ));
    }
    let mut wrong = st.clone();
    wrong.velocities.pop();
    assert!(matches!(
        g.step(&mut wrong, &sk, frames, body, 0.1),
        Err(Error::SizeMismatch { .. })
    ));
}

/// Holding the rest pose keeps the settled drape nearly still.
#[test]
fn skirt_rest_drape_is_settled() {
    let g = skirt();
    let p = performer();
    let rest = p
        .skeleton
        .forward_kinematics(&p.skeleton.rest_pose())
        .unwrap();
    let frames = rest.world_from_joint();
    let sk = g.rest_mesh().vertices.clone();
    let body = &p.template.vertices;
    let mut st = GarmentState::default();
    g.step(&mut st, &sk, frames, body, 0.0).unwrap();
    let x = g.step(&mut st, &sk, frames, body, 1.0 / 30.0).unwrap();
    let moved = x
        .iter()
        .zip(&sk)
        .map(|(a, b)| a.distance(*b))
        .fold(0.0, f64::max);
    eprintln!("skirt held at rest: largest vertex motion in the first frame {moved:.5} m");
    assert!(moved < 0.01, "rest drape drifts {moved} m in a frame");
}

#[test]
fn bad_params_are_rejected_with_their_names() {
    let skirt_err = |p: SkirtParams| build(&GarmentParams::Skirt(p)).unwrap_err().to_string();
    let cloth = ClothParams {
        density_kg_per_m2: -1.0,
        ..Default::default()
    };
    let e = skirt_err(SkirtParams::default().with_cloth(cloth));
    assert!(e.contains("density_kg_per_m2"), "{e}");
    let cloth = ClothParams {
        damping_per_s: f64::NAN,
        ..Default::default()
    };
    assert!(skirt_err(SkirtParams::default().with_cloth(cloth)).contains("damping_per_s"));
    let cloth = ClothParams {
        iterations: 0,
        ..Default::default()
    };
    assert!(skirt_err(SkirtParams::default().with_cloth(cloth)).contains("iterations"));
    let cloth = ClothParams {
        max_speed_m_per_s: Some(f64::NAN),
        ..Default::default()
    };
    assert!(skirt_err(SkirtParams::default().with_cloth(cloth)).contains("max_speed_m_per_s"));
    let mut p = SkirtParams::default();
    p.knee_joints[0] = "l_kneecap".into();
    assert!(skirt_err(p).contains("l_kneecap"));
    let mut p = SkirtParams::default();
    p.collider_joints.push("tail".into());
    assert!(skirt_err(p).contains("tail"));
    assert!(skirt_err(SkirtParams::default().with_flare_m(-0.1)).contains("flare_m"));
    // Waist smaller than the body's waist.
    let e = skirt_err(SkirtParams::default().with_waist_radius_m(0.05));
    assert!(e.contains("smaller than the body's waist"), "{e}");
    // Hem above the crotch.
    let e = skirt_err(SkirtParams::default().with_hem_below_knee_m(-0.5));
    assert!(e.contains("above the crotch"), "{e}");
    // Leg colliders outside the hem ring.
    let e = skirt_err(SkirtParams::default().with_hem_radius_m(0.1));
    assert!(e.contains("outside the hem ring"), "{e}");
    // Too many vertices.
    let e = skirt_err(SkirtParams::default().with_resolution(100, 100));
    assert!(e.contains("5000"), "{e}");
    let sp = SheetParams {
        size_m: -2.0,
        ..Default::default()
    };
    assert!(build(&GarmentParams::Sheet(sp))
        .unwrap_err()
        .to_string()
        .contains("size_m"));
    let sp = SheetParams {
        pin_joints: vec!["hat".into()],
        ..Default::default()
    };
    assert!(build(&GarmentParams::Sheet(sp))
        .unwrap_err()
        .to_string()
        .contains("hat"));
    assert!(build(&GarmentParams::Sheet(
        SheetParams::default().with_resolution(80)
    ))
    .unwrap_err()
    .to_string()
    .contains("5000"));
    // The body's weights must match the body.
    let p = performer();
    let small = TriMesh::new(p.template.vertices[..10].to_vec(), vec![]).unwrap();
    assert!(matches!(
        Garment::new(
            &GarmentParams::Skirt(SkirtParams::default()),
            &p.skeleton,
            &small,
            &p.weights
        ),
        Err(Error::SizeMismatch { .. })
    ));
}

#[test]
fn sheet_drapes_over_head_and_shoulders_and_follows_the_body() {
    let g = sheet();
    let d = SheetParams::default();
    assert_eq!(g.vertex_count(), d.resolution * d.resolution);
    let m = g.rest_mesh();
    m.validate().unwrap();
    let p = performer();
    let top = p
        .template
        .vertices
        .iter()
        .map(|v| v.y)
        .fold(f64::MIN, f64::max);
    let rest = p
        .skeleton
        .forward_kinematics(&p.skeleton.rest_pose())
        .unwrap();
    let shoulder = rest.joint_positions()[p.skeleton.joint_index("l_shoulder").unwrap()];
    let bb = m.bounding_box().unwrap();
    let pinned = (0..g.vertex_count()).filter(|&i| g.is_pinned(i)).count();
    eprintln!(
        "sheet: {} vertices, {pinned} pinned, spans y {:.3}..{:.3} (body top {top:.3}, \
         shoulder {:.3})",
        g.vertex_count(),
        bb.min.y,
        bb.max.y,
        shoulder.y
    );
    assert!(pinned > 0);
    // The head's round capsule (fitted to cover jaw and face) reaches ≈ 12 cm above the crown.
    assert!(bb.max.y > top && bb.max.y < top + 0.15, "rests on the head");
    assert!(
        bb.min.y < shoulder.y - 0.3,
        "hangs well below the shoulders"
    );
    let q = MeshQuery::new(&p.template).unwrap();
    let closest = m
        .vertices
        .iter()
        .map(|v| q.closest_point(*v).unwrap().signed_distance)
        .fold(f64::INFINITY, f64::min);
    assert!(closest > -0.005, "rest drape clears the body: {closest} m");
    let motion = fast(0.5, 1.0 / 30.0);
    let mut ms = Vec::new();
    play(g, &motion, |_, _, sk, sim, secs| {
        ms.push(1e3 * secs);
        for (i, (a, b)) in sk.iter().zip(sim).enumerate() {
            assert!(b.is_finite());
            if g.is_pinned(i) {
                assert!(a.distance(*b) < 1e-9, "pinned vertices follow the body");
            }
        }
    });
    eprintln!(
        "sheet step at 30 fps: median {:.2} ms",
        skin_core::stats::median(&ms)
    );
}

/// Speed figure for the report (printed, not asserted): ms per `step` of the skirt at 30 fps.
#[test]
fn skirt_step_cost_at_30_fps() {
    let g = skirt();
    let motion = fast(1.0, 1.0 / 30.0);
    let mut ms = Vec::new();
    play(g, &motion, |k, _, _, _, secs| {
        if k > 0 {
            ms.push(1e3 * secs);
        }
    });
    eprintln!(
        "skirt step at 30 fps ({} vertices): median {:.2} ms, max {:.2} ms",
        g.vertex_count(),
        skin_core::stats::median(&ms),
        ms.iter().copied().fold(0.0, f64::max)
    );
}

/// The Ghost under the exercise motion the photometric studio plays (the default
/// [`crate::ExerciseParams`], whose frame 0 is not the rest pose): over its first 60
/// frames every sheet vertex stays finite and within 3 m of the root.
#[test]
fn sheet_stays_on_the_body_under_the_exercise_motion() {
    let g = sheet();
    let p = performer();
    let motion = crate::exercise_motion(&p.skeleton, &crate::ExerciseParams::default()).unwrap();
    let first = Motion::new(
        motion.frame_time_s,
        motion.frames.columns(0, 60).into_owned(),
    )
    .unwrap();
    let mut worst = 0.0f64;
    play(g, &first, |k, f, _, sim, _| {
        let root = f.world_from_joint[0].translation;
        let far = sim.iter().map(|v| v.distance(root)).fold(0.0, f64::max);
        eprintln!("frame {k}: farthest sheet vertex {far:.3} m from the root");
        assert!(sim.iter().all(|v| v.is_finite()), "frame {k}: non-finite");
        assert!(far < 3.0, "frame {k}: a sheet vertex {far} m from the root");
        worst = worst.max(far);
    });
    eprintln!("sheet under the exercise motion: farthest vertex {worst:.3} m from the root");
}
