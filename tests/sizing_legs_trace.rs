//! Issue 12 trace (diagnostic, `--ignored`): why `size_from_poses` makes the legs too long on
//! the MakeHuman performer with other bone lengths. Per limb bone, from the true poses: the
//! hull samples each ellipsoid holds near its ends (within 3 cm beyond a joint along the true
//! bone) and their distance to the true surface (phantom hull), then the per-bone length
//! errors with the default fit, with free end-site scales and with one-sided hull samples.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)]

use dynamic_shapes::core::camera::{Camera, Intrinsics, Rig};
use dynamic_shapes::core::math::DVec3;
use dynamic_shapes::core::random::SplitMix64;
use dynamic_shapes::core::skeleton::Motion;
use dynamic_shapes::core::studio::{
    exercise_motion, makehuman_performer, Capture, CaptureSpec, DeformationParams, ExerciseParams,
    Performer,
};
use dynamic_shapes::template::{
    initialise_pose, reference_sizes, score_ellipsoids, size_from_poses, track, AutoInitParams,
    EllipsoidModel, EllipsoidParams, EllipsoidState, FrameObservation, PoseFrame, PoseModel,
    PoseParams, SilhouetteParams, SizingParams, Template, VisualHullParams,
};

fn studio() -> (Performer, Motion, Vec<Camera>, CaptureSpec) {
    let performer = makehuman_performer(
        example_kit::data_path("makehuman").unwrap(),
        &DeformationParams::default(),
    )
    .unwrap();
    let motion = exercise_motion(&performer.skeleton, &ExerciseParams::default()).unwrap();
    let root = performer
        .skeleton
        .forward_kinematics(motion.frame(0))
        .unwrap()
        .joint_positions()[0];
    let k = Intrinsics::from_horizontal_fov(55f64.to_radians(), 480, 360).unwrap();
    let rig = Rig::ring(8, 3.5, root.y + 0.15, root, DVec3::Y, k).unwrap();
    let cameras = rig.cameras.clone();
    let spec = CaptureSpec::masks_only(rig).with_frame_rate_hz(1.0 / motion.frame_time_s);
    (performer, motion, cameras, spec)
}

#[test]
#[ignore = "diagnostic trace, ~1 min"]
fn trace_leg_lengths() {
    let (default, motion, cameras, spec) = studio();
    let model = EllipsoidModel::with_end_sites(default.skeleton.clone(), 0.1).unwrap();
    let rng = SplitMix64::new(12);
    let mut factors = vec![1.0; default.skeleton.joint_count()];
    for (k, bone) in model.bones().iter().enumerate() {
        if let Some(c) = bone.child {
            factors[c] = 0.9 + 0.2 * rng.uniform_at(k as u64);
        }
    }
    let performer = default
        .with_bone_scales(&factors, &DeformationParams::default())
        .unwrap();
    let capture = Capture::new(&performer, &motion, spec).unwrap();
    let frames: Vec<_> = capture
        .frames_stepped(40..64, 2)
        .map(|f| f.unwrap())
        .collect();
    let obs: Vec<FrameObservation> = frames
        .iter()
        .map(|f| {
            FrameObservation::new(
                &cameras,
                &f.masks(),
                &VisualHullParams::default(),
                &SilhouetteParams::default(),
            )
            .unwrap()
        })
        .collect();
    let true_template = Template::new(
        performer.template.clone(),
        performer.skeleton.clone(),
        performer.weights.clone(),
    )
    .unwrap();
    let reference = reference_sizes(&model, &true_template, 0.05).unwrap();
    let ref_len = model.bone_lengths(&reference);
    let truth: Vec<Vec<f64>> = frames.iter().map(|f| f.truth.theta.clone()).collect();
    let sk = performer.skeleton.clone();
    let name = |j: usize| sk.joints()[j].name.clone();
    let rest = |s: &EllipsoidState| EllipsoidState {
        theta: default.skeleton.rest_pose(),
        ..s.clone()
    };
    let run = |label: &str, poses: &[Vec<f64>], params: &SizingParams, trace: bool| {
        let sizing = size_from_poses(&model, &obs, poses, params).unwrap();
        let st = sizing.state().unwrap();
        let e = score_ellipsoids(&model, &rest(st), &rest(&reference)).unwrap();
        let len = model.bone_lengths(st);
        let mut per = String::new();
        for (b, bone) in model.bones().iter().enumerate() {
            if let Some(c) = bone.child {
                per += &format!(
                    " {}→{} {:+.0}",
                    name(bone.parent),
                    name(c),
                    1e3 * (len[b] - ref_len[b])
                );
            }
        }
        println!(
            "[{label}] lengths {:.1} mm widths {:.1} mm; per bone (mm):{per}",
            e.bone_length_error_mm, e.width_error_mm
        );
        // Fitted joints (scaled skeleton, fitted θ) against the true joints, mean over frames.
        let fitted_sk = sizing.skeleton(&model).unwrap();
        let mut jerr = vec![DVec3::ZERO; sk.joint_count()];
        for (k, &f) in sizing.chosen.iter().enumerate() {
            let a = fitted_sk
                .forward_kinematics(&sizing.fit.states[k].theta)
                .unwrap();
            let b = sk.forward_kinematics(&truth[f]).unwrap();
            for (j, (x, y)) in a
                .joint_positions()
                .iter()
                .zip(b.joint_positions())
                .enumerate()
            {
                jerr[j] += (*x - y) / sizing.chosen.len() as f64;
            }
        }
        let mut js = String::new();
        for (j, e) in jerr.iter().enumerate() {
            if name(j).contains("hip")
                || name(j).contains("knee")
                || name(j).contains("ankle")
                || j == 0
            {
                js += &format!(
                    " {} ({:+.0},{:+.0},{:+.0})",
                    name(j),
                    1e3 * e.x,
                    1e3 * e.y,
                    1e3 * e.z
                );
            }
        }
        println!("  mean fitted − true joint (mm, x y z):{js}");
        if !trace {
            return;
        }
        // Samples near the ends of each limb bone, distance to the true surface.
        let n = model.bones().len();
        // per bone: [beyond parent, middle, beyond child] counts and mean distance; phantom (>2 cm)
        let mut cnt = vec![[0usize; 3]; n];
        let mut dist = vec![[0.0f64; 3]; n];
        let mut phantom = vec![[0usize; 3]; n];
        let mut tq: Vec<Vec<f64>> = vec![Vec::new(); n];
        for (k, &f) in sizing.chosen.iter().enumerate() {
            let verts = &obs[f].hull.polygon().vertices;
            let step = verts.len().div_ceil(600).max(1);
            let pts: Vec<DVec3> = verts.iter().step_by(step).copied().collect();
            assert_eq!(pts.len(), sizing.fit.point_bones[k].len());
            let fk = sk.forward_kinematics(&truth[f]).unwrap();
            let jp = fk.joint_positions();
            let surf = &frames[f].truth.posed.true_vertices;
            for (i, p) in pts.iter().enumerate() {
                let Some(b) = sizing.fit.point_bones[k][i] else {
                    continue;
                };
                let bone = &model.bones()[b];
                let Some(c) = bone.child else { continue };
                let (a, z) = (jp[bone.parent], jp[c]);
                let l = a.distance(z);
                let t = (*p - a).dot((z - a) / l);
                let region = if (-0.03..0.0).contains(&t) {
                    0
                } else if (0.0..=l).contains(&t) {
                    1
                } else if t > l && t <= l + 0.03 {
                    2
                } else {
                    continue;
                };
                let d = surf
                    .iter()
                    .map(|v| v.distance(*p))
                    .fold(f64::INFINITY, f64::min);
                cnt[b][region] += 1;
                dist[b][region] += d;
                if d > 0.02 {
                    phantom[b][region] += 1;
                    if region == 1 && name(bone.parent).contains("hip") {
                        tq[b].push(t / l);
                    }
                }
            }
        }
        for (b, q) in tq.iter_mut().enumerate() {
            if q.is_empty() {
                continue;
            }
            q.sort_by(f64::total_cmp);
            let at = |p: f64| q[((q.len() - 1) as f64 * p) as usize];
            println!(
                "  bone {b} phantom samples along the thigh (0 hip, 1 knee): quartiles {:.2} {:.2} {:.2}",
                at(0.25),
                at(0.5),
                at(0.75)
            );
        }
        for (b, bone) in model.bones().iter().enumerate() {
            let Some(c) = bone.child else { continue };
            let m = |r: usize| 1e3 * dist[b][r] / cnt[b][r].max(1) as f64;
            println!(
                "  {}→{}: samples beyond parent {} ({:.0} mm to surface, {} > 2 cm), middle {} \
                 ({:.0} mm, {}), beyond child {} ({:.0} mm, {})",
                name(bone.parent),
                name(c),
                cnt[b][0],
                m(0),
                phantom[b][0],
                cnt[b][1],
                m(1),
                phantom[b][1],
                cnt[b][2],
                m(2),
                phantom[b][2]
            );
        }
    };
    let base = SizingParams::default();
    let base = SizingParams {
        fit: EllipsoidParams {
            sigma_translation_prior_m: None,
            ..base.fit.clone()
        },
        ..base
    };
    run("default fit", &truth, &base, true);
    let free_ends = SizingParams {
        fit: EllipsoidParams {
            sigma_end_site_scale_prior: 0.2,
            ..base.fit.clone()
        },
        ..base.clone()
    };
    run("end sites free (σ 0.2)", &truth, &free_ends, false);
    // The tracker's poses at default proportions from the automatic first pose (as the
    // integration test).
    let default_template = true_template.resized(default.skeleton.clone()).unwrap();
    let first = initialise_pose(
        &model,
        &obs[0].hull,
        &obs[0].rays,
        &AutoInitParams::default(),
    )
    .unwrap()
    .theta()
    .to_vec();
    let pose_frames: Vec<PoseFrame<'_>> = obs
        .iter()
        .map(|o| PoseFrame {
            hull: &o.hull,
            rays: &o.rays,
            user: &[],
        })
        .collect();
    let pm = PoseModel::new(&default_template, &PoseParams::default()).unwrap();
    let tracked = track(&pm, &pose_frames, &first, None, &PoseParams::default())
        .unwrap()
        .poses;
    for (sigma, tr) in [(1.0, 0.01), (1.0, 0.003), (1.0, 0.001), (0.3, 0.003)] {
        {
            let p = SizingParams {
                fit: EllipsoidParams {
                    sigma_theta_prior: sigma,
                    sigma_translation_prior_m: Some(tr),
                    ..base.fit.clone()
                },
                ..base.clone()
            };
            run(
                &format!("true poses, σθ {sigma} σt {tr}"),
                &truth,
                &p,
                false,
            );
            run(
                &format!("TRACKED poses, σθ {sigma} σt {tr}"),
                &tracked,
                &p,
                false,
            );
        }
    }
}
