//! Tests of the pose-driven deformation on the MakeHuman performer.

use super::*;
use crate::{DeformationParams, DeformationState, Performer, PosedFrame};
use std::sync::OnceLock;

/// The MakeHuman performer with the default deformation (every pose-driven effect on).
fn base() -> &'static Performer {
    crate::tests::makehuman()
}

/// The same body with only the pose-driven deformation `pose`.
fn with_pose(pose: PoseDeformParams) -> Performer {
    let p = base();
    Performer::new(
        "makehuman",
        p.template.clone(),
        p.skeleton.clone(),
        p.weights.clone(),
        &DeformationParams::none().with_pose(Some(pose)),
    )
    .unwrap()
}

/// The MakeHuman performer with only the default pose-driven deformation.
fn full() -> &'static Performer {
    static P: OnceLock<Performer> = OnceLock::new();
    P.get_or_init(|| with_pose(PoseDeformParams::default()))
}

fn pose(p: &Performer, theta: &[f64]) -> PosedFrame {
    p.pose(theta, &mut DeformationState::default(), 0.0)
        .unwrap()
}

fn set(p: &Performer, dofs: &[(&str, f64)]) -> Vec<f64> {
    let mut t = p.skeleton.rest_pose();
    for (n, v) in dofs {
        t[p.skeleton.dof_index(n).unwrap()] = v.to_radians();
    }
    t
}

/// A pose activating every default effect partly.
fn mixed(p: &Performer) -> Vec<f64> {
    set(
        p,
        &[
            ("l_elbow.flexion", 60.0),
            ("r_elbow.flexion", 95.0),
            ("l_shoulder.abduction", 40.0),
            ("r_shoulder.abduction", 70.0),
            ("l_knee.flexion", 70.0),
            ("r_knee.flexion", 30.0),
            ("l_ankle.dorsiflexion", -20.0),
            ("r_ankle.dorsiflexion", -35.0),
            ("spine.flexion", 20.0),
            ("chest.flexion", 10.0),
            ("l_shoulder.flexion", 30.0),
            ("pelvis.yaw", 40.0),
        ],
    )
}

fn max_len(v: &[DVec3]) -> f64 {
    v.iter().map(|d| d.length()).fold(0.0, f64::max)
}

#[test]
fn profiles_and_activation() {
    assert_eq!(activation_ramp(0.0), 0.0);
    assert_eq!(activation_ramp(-3.0), 0.0);
    assert_eq!(activation_ramp(1.0), 1.0);
    assert_eq!(activation_ramp(7.0), 1.0);
    assert!((activation_ramp(0.5) - 0.5).abs() < 1e-15);
    let biceps = PoseDeformParams::default();
    let b = biceps.effect("l_biceps").unwrap().along;
    assert_eq!(b.value(0.6), 1.0);
    let near_elbow = b.value(0.95);
    assert!((0.25..0.35).contains(&near_elbow), "{near_elbow}");
    assert_eq!(b.value(-0.1), 0.0);
    assert_eq!(b.value(1.2), 0.0);
    assert!(b.value(0.0) < 1e-20 && b.value(1.15) < 1e-20);
    // C¹ at the peak and the ends: one-sided slopes agree.
    let h = 1e-6;
    for s in [0.6, 0.0, 1.15] {
        let l = (b.value(s) - b.value(s - h)) / h;
        let r = (b.value(s + h) - b.value(s)) / h;
        assert!((l - r).abs() < 1e-4, "slope jump at {s}: {l} vs {r}");
    }
}

#[test]
fn zero_at_rest_and_on_by_default() {
    let p = full();
    let f = pose(p, &p.skeleton.rest_pose());
    assert!(f.pose_displacement.iter().all(|d| *d == DVec3::ZERO));
    assert_eq!(f.true_vertices, f.lbs_vertices);
    // Inactive sign: extension-side angles give nothing.
    let t = set(
        p,
        &[
            ("l_ankle.dorsiflexion", 15.0),
            ("spine.flexion", -20.0),
            ("l_shoulder.abduction", -20.0),
        ],
    );
    assert!(pose(p, &t)
        .pose_displacement
        .iter()
        .all(|d| *d == DVec3::ZERO));
    // The default performer has every effect on, and switching them off changes the truth
    // by exactly the recorded displacement and nothing else.
    let on = base();
    assert_eq!(on.deformation.pose_effect_count(), 20);
    assert_eq!(
        DeformationParams::default().pose,
        Some(PoseDeformParams::default())
    );
    let b = &Performer::new(
        "x",
        on.template.clone(),
        on.skeleton.clone(),
        on.weights.clone(),
        &DeformationParams::default().with_pose(None),
    )
    .unwrap();
    assert_eq!(b.deformation.pose_effect_count(), 0);
    let theta = mixed(b);
    let off = pose(b, &theta);
    assert_eq!(off.pose_displacement.len(), b.vertex_count());
    assert!(off.pose_displacement.iter().all(|d| *d == DVec3::ZERO));
    let f = pose(on, &theta);
    assert_eq!(f.lbs_vertices, off.lbs_vertices);
    for ((a, b), d) in f
        .true_vertices
        .iter()
        .zip(&off.true_vertices)
        .zip(&f.pose_displacement)
    {
        assert!((*a - *d - *b).length() < 1e-12);
        if *d == DVec3::ZERO {
            assert_eq!(a, b);
        }
    }
}

/// Per effect at its reference pose: max displacement, vertices moving > 2, 5, 10 mm.
#[test]
fn each_effect_reaches_its_amplitude_in_its_region() {
    let params = PoseDeformParams::default();
    assert_eq!(params.effects.len(), 20);
    let b = base();
    let rest = &b.template.vertices;
    eprintln!("effect | reference pose | max mm | > 2 mm | > 5 mm | > 10 mm");
    for e in &params.effects {
        let p = with_pose(params.clone().only(&e.name));
        assert_eq!(p.deformation.pose_effect_count(), 1);
        let theta = e.reference_pose(&p.skeleton).unwrap();
        let f = pose(&p, &theta);
        let d = &f.pose_displacement;
        let max = max_len(d);
        let count = |mm: f64| d.iter().filter(|v| v.length() > mm * 1e-3).count();
        eprintln!(
            "{} | {} = {:.0}° | {:.1} | {} | {} | {}",
            e.name,
            e.dofs.join(" + "),
            e.reference_rad.to_degrees(),
            max * 1e3,
            count(2.0),
            count(5.0),
            count(10.0)
        );
        assert!(
            (0.8 * e.amplitude_m..=1.2 * e.amplitude_m).contains(&max),
            "{}: {max} m vs {} m",
            e.name,
            e.amplitude_m
        );
        assert!(count(2.0) > 20, "{}: a region, not a spike", e.name);
        // Only vertices of the region move, and only on the effect's own side of the body.
        let region: Vec<usize> = e
            .region
            .iter()
            .map(|j| p.skeleton.joint_index(j).unwrap())
            .collect();
        for (v, dv) in d.iter().enumerate() {
            if *dv == DVec3::ZERO {
                continue;
            }
            assert!(
                p.weights
                    .influences(v)
                    .any(|(j, _)| region.contains(&(j as usize))),
                "{}: vertex {v} outside its region moves",
                e.name
            );
            // Across the midline (+X is the body's left) only through MakeHuman's stray
            // weights (e.g. 0.5 % on the left knee for a right-knee vertex): < 0.1 mm.
            let x = rest[v].x;
            let wrong =
                (e.name.starts_with("l_") && x < 0.0) || (e.name.starts_with("r_") && x > 0.0);
            assert!(
                !wrong || dv.length() < 1e-4,
                "{}: vertex {v} at x = {x} moves {} m",
                e.name,
                dv.length()
            );
        }
        // Halfway to the reference: half the amplitude (smoothstep(1/2) = 1/2).
        let half: Vec<f64> = theta.iter().map(|t| 0.5 * t).collect();
        let h = max_len(&pose(&p, &half).pose_displacement);
        assert!(
            (h - 0.5 * max).abs() < 0.2 * max,
            "{}: {h} vs {max}",
            e.name
        );
    }
}

/// The biceps profile on the mesh: peak about 60 % down the upper arm, still about 30 % of it
/// near the elbow.
#[test]
fn biceps_profile_along_the_upper_arm() {
    let params = PoseDeformParams::default();
    let e = params.effect("l_biceps").unwrap();
    let p = with_pose(params.clone().only("l_biceps"));
    let f = pose(&p, &e.reference_pose(&p.skeleton).unwrap());
    let fk = p
        .skeleton
        .forward_kinematics(&p.skeleton.rest_pose())
        .unwrap();
    let at = |n: &str| fk.world_from_joint()[p.skeleton.joint_index(n).unwrap()].translation;
    let (a, b) = (at("l_shoulder"), at("l_elbow"));
    let band = |lo: f64, hi: f64| {
        p.template
            .vertices
            .iter()
            .zip(&f.pose_displacement)
            .filter(|(x, _)| (lo..hi).contains(&((**x - a).dot(b - a) / (b - a).length_squared())))
            .map(|(_, d)| d.length())
            .fold(0.0, f64::max)
    };
    let bands: Vec<f64> = (0..12)
        .map(|k| band(k as f64 * 0.1, k as f64 * 0.1 + 0.1))
        .collect();
    eprintln!(
        "l_biceps max mm per tenth of the upper arm: {:.1?}",
        bands.iter().map(|d| d * 1e3).collect::<Vec<_>>()
    );
    let peak = stats_max(&bands);
    let k = bands.iter().position(|d| *d == peak).unwrap();
    assert!((4..=6).contains(&k), "peak in tenth {k}");
    let near_elbow = bands[9] / peak;
    assert!(
        (0.2..0.5).contains(&near_elbow),
        "{near_elbow} of peak at 90–100 %"
    );
}

fn stats_max(v: &[f64]) -> f64 {
    skin_core::stats::max(v)
}

#[test]
fn directions_follow_the_anatomy() {
    let params = PoseDeformParams::default();
    let rest = &base().template.vertices;
    // Mean rest-space displacement direction of the vertices an effect moves at rest-space
    // scale (tiny activation: rotations negligible).
    let mean_dir = |name: &str| {
        let e = params.effect(name).unwrap();
        let p = with_pose(params.clone().only(name));
        let f = pose(&p, &e.reference_pose(&p.skeleton).unwrap());
        let moved: Vec<usize> = (0..rest.len())
            .filter(|&v| f.pose_displacement[v] != DVec3::ZERO)
            .collect();
        let centre = moved.iter().map(|&v| rest[v]).sum::<DVec3>() / moved.len() as f64;
        (centre, f)
    };
    // Calf, hamstrings and back sit behind the leg/trunk axis, abdomen in front.
    for (name, joint, behind) in [
        ("l_calf", "l_knee", true),
        ("r_hamstrings", "r_hip", true),
        ("back", "spine", true),
        ("abdomen", "spine", false),
        ("l_knee_crease", "l_knee", true),
        ("l_knee_round", "l_knee", false),
    ] {
        let (c, _) = mean_dir(name);
        let b = base();
        let fk = b
            .skeleton
            .forward_kinematics(&b.skeleton.rest_pose())
            .unwrap();
        let z = fk.world_from_joint()[b.skeleton.joint_index(joint).unwrap()]
            .translation
            .z;
        assert_eq!(c.z < z, behind, "{name}: centre z {} vs joint z {z}", c.z);
    }
    // The back creases inward (towards the spine: forward at the back), the abdomen swells
    // outward (forward), at a small forward bend.
    let small = |name: &str| {
        let p = with_pose(params.clone().only(name));
        let f = pose(&p, &set(&p, &[("spine.flexion", 1.0)]));
        f.pose_displacement.iter().sum::<DVec3>()
    };
    assert!(small("abdomen").z > 0.0 && small("back").z > 0.0);
}

#[test]
fn effects_add_up_and_switch_off_exactly() {
    let params = PoseDeformParams::default();
    let p = full();
    let theta = mixed(p);
    let all = pose(p, &theta).pose_displacement;
    let mut sum = vec![DVec3::ZERO; all.len()];
    for e in &params.effects {
        let part = pose(&with_pose(params.clone().only(&e.name)), &theta).pose_displacement;
        let rest = pose(&with_pose(params.clone().without(&e.name)), &theta).pose_displacement;
        for v in 0..all.len() {
            assert!((all[v] - rest[v] - part[v]).length() < 1e-12, "{}", e.name);
            sum[v] += part[v];
        }
    }
    for (a, s) in all.iter().zip(&sum) {
        assert!((*a - *s).length() < 1e-12);
    }
    assert!(max_len(&all) > 0.01);
    // No effect at all: zero.
    let none = with_pose(PoseDeformParams::none());
    assert!(pose(&none, &theta)
        .pose_displacement
        .iter()
        .all(|d| *d == DVec3::ZERO));
}

#[test]
fn deterministic_for_any_thread_count() {
    let p = full();
    let theta = mixed(p);
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| pose(p, &theta))
    };
    let one = run(1);
    for n in [2, 4] {
        let f = run(n);
        assert_eq!(f.pose_displacement, one.pose_displacement);
        assert_eq!(f.true_vertices, one.true_vertices);
    }
}

#[test]
fn pose_time_is_reported() {
    let p = full();
    let theta = mixed(p);
    pose(p, &theta);
    let t0 = std::time::Instant::now();
    let n = 100;
    for _ in 0..n {
        pose(p, &theta);
    }
    let ms = t0.elapsed().as_secs_f64() * 1e3 / n as f64;
    let plain = base();
    let t0 = std::time::Instant::now();
    for _ in 0..n {
        pose(plain, &theta);
    }
    let base_ms = t0.elapsed().as_secs_f64() * 1e3 / n as f64;
    eprintln!("pose with effects: {ms:.2} ms/frame, without: {base_ms:.2} ms/frame");
}

#[test]
fn bad_input_is_named() {
    let b = base();
    let build = |pose: PoseDeformParams| {
        Performer::new(
            "x",
            b.template.clone(),
            b.skeleton.clone(),
            b.weights.clone(),
            &DeformationParams::none().with_pose(Some(pose)),
        )
        .map(|_| ())
        .unwrap_err()
        .to_string()
    };
    let edit = |f: &dyn Fn(&mut PoseEffect)| {
        let mut p = PoseDeformParams::default();
        f(&mut p.effects[0]);
        build(p)
    };
    let e = edit(&|e| e.dofs = vec!["l_elbow.bend".into()]);
    assert!(e.contains("l_elbow.bend") && e.contains("l_biceps"), "{e}");
    let e = edit(&|e| e.dofs.push("pelvis.tx".into()));
    assert!(e.contains("not a rotation"), "{e}");
    let e = edit(&|e| e.bone = "l_humerus".into());
    assert!(e.contains("l_humerus"), "{e}");
    let e = edit(&|e| e.region = vec!["l_biceps_brachii".into()]);
    assert!(e.contains("l_biceps_brachii"), "{e}");
    let e = edit(&|e| e.side = EffectSide::AwayFrom("elbow".into()));
    assert!(e.contains("'elbow'"), "{e}");
    let e = edit(&|e| e.amplitude_m = -0.01);
    assert_eq!(
        e,
        "invalid parameter pose.effects: effect 'l_biceps': amplitude_m must be finite and ≥ 0, \
         got -0.01; set pose.effects within its documented range"
    );
    let e = edit(&|e| e.amplitude_m = f64::NAN);
    assert!(e.contains("amplitude_m"), "{e}");
    let e = edit(&|e| e.reference_rad = 0.0);
    assert!(e.contains("reference_rad"), "{e}");
    let e = edit(&|e| e.along.before = 0.0);
    assert!(e.contains("along.before"), "{e}");
    let e = edit(&|e| e.dofs.clear());
    assert!(e.contains("dofs"), "{e}");
    let e = edit(&|e| e.name = "r_biceps".into());
    assert!(e.contains("duplicate"), "{e}");
    let e = edit(&|e| {
        e.axis = EffectAxis::Joint;
        e.bone = "chest".into();
    });
    assert!(e.contains("one child"), "{e}");
    let r = PoseEffect::reference_pose(
        &PoseEffect {
            dofs: vec!["nope".into()],
            ..PoseDeformParams::default().effects[0].clone()
        },
        &b.skeleton,
    );
    assert!(r.unwrap_err().to_string().contains("nope"));
    // A zero amplitude is allowed and moves nothing.
    let mut p = PoseDeformParams::default().only("l_biceps");
    p.effects[0].amplitude_m = 0.0;
    let z = with_pose(p);
    let f = pose(&z, &set(&z, &[("l_elbow.flexion", 90.0)]));
    assert!(f.pose_displacement.iter().all(|d| *d == DVec3::ZERO));
}

#[test]
fn procedural_performer_takes_the_defaults() {
    let p = crate::procedural_performer(&crate::ProceduralBodyParams {
        grid_spacing_m: 0.03,
        deformation: DeformationParams::none()
            .with_pose(Some(PoseDeformParams::default().only("l_biceps"))),
        ..Default::default()
    })
    .unwrap();
    let e = PoseDeformParams::default();
    let e = e.effect("l_biceps").unwrap();
    let f = pose(&p, &e.reference_pose(&p.skeleton).unwrap());
    let max = max_len(&f.pose_displacement);
    assert!(
        (0.7 * e.amplitude_m..=1.2 * e.amplitude_m).contains(&max),
        "{max}"
    );
    // Every default effect resolves on the procedural skeleton too.
    let all = crate::procedural_performer(&crate::ProceduralBodyParams {
        grid_spacing_m: 0.03,
        deformation: DeformationParams::none().with_pose(Some(PoseDeformParams::default())),
        ..Default::default()
    })
    .unwrap();
    assert_eq!(all.deformation.pose_effect_count(), 20);
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(24))]
    /// A pure function of θ: the same θ gives bit-identical displacement whatever was posed
    /// before; a small change of θ gives a small change of displacement.
    #[test]
    fn pure_and_continuous_in_theta(
        angles in proptest::collection::vec(-1.0f64..1.0, 8),
        step in proptest::collection::vec(-1e-4f64..1e-4, 8),
    ) {
        let p = full();
        let names = [
            "l_elbow.flexion", "r_knee.flexion", "l_shoulder.abduction", "l_ankle.dorsiflexion",
            "spine.flexion", "chest.flexion", "r_elbow.flexion", "l_knee.flexion",
        ];
        let mut theta = p.skeleton.rest_pose();
        let mut near = theta.clone();
        for (k, n) in names.iter().enumerate() {
            let d = p.skeleton.dof_index(n).unwrap();
            theta[d] = angles[k];
            near[d] = angles[k] + step[k];
        }
        let first = pose(p, &theta).pose_displacement;
        pose(p, &mixed(p));
        let other = pose(p, &near).pose_displacement;
        let again = pose(p, &theta).pose_displacement;
        proptest::prop_assert_eq!(&first, &again);
        let dtheta: f64 = step.iter().map(|s| s.abs()).sum();
        let change = first
            .iter()
            .zip(&other)
            .map(|(a, b)| a.distance(*b))
            .fold(0.0, f64::max);
        // Lipschitz bound: activation slope ≤ 1.5 / 30°, amplitudes ≤ 20 mm (summed over a
        // few overlapping effects), plus the rotation of the offsets.
        proptest::prop_assert!(change <= 0.5 * dtheta + 1e-12, "{} for {}", change, dtheta);
    }
}
