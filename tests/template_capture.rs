//! Small end-to-end validation of template-silhouette on the studio (the CI-sized version of
//! the coming `examples/template_capture`): the MakeHuman performer (body only, no skirt) in
//! the exercise motion, seen by an 8-camera ring; pose tracking in the visual hulls (§2.3)
//! then Algorithm 1 (§2.4),
//! scored against the performer's true posed mesh and against linear blend skinning driven by
//! the same estimated poses and by the true poses. The template is rigged by the library's
//! bone-heat weights, as a user's would be; the performer's own weights (which generated the
//! truth) are the oracle.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)] // not library code

use std::time::Instant;

use dynamic_shapes::core::camera::{Camera, Intrinsics, Rig};
use dynamic_shapes::core::image::Mask;
use dynamic_shapes::core::math::DVec3;
use dynamic_shapes::core::mesh::{bone_heat_weights, rest_bones, HeatWeightsParams};
use dynamic_shapes::core::skeleton::Motion;
use dynamic_shapes::core::stats::{mean, rms};
use dynamic_shapes::template::{
    capture_sequence, edge_error_pct, silhouette_error_pct, ContourRayHullParams, FrameObservation,
    PoseParams, ShapeEstimator, ShapeFrame, ShapeParams, SilhouetteParams, Template,
};
use dynamic_shapes_studio::{
    exercise_motion, makehuman_performer, Capture, CaptureSpec, DeformationParams, ExerciseParams,
    Performer,
};

/// RMS distance between corresponding vertices, mm.
fn rms_mm(a: &[DVec3], b: &[DVec3]) -> f64 {
    let d: Vec<f64> = a.iter().zip(b).map(|(x, y)| x.distance(*y)).collect();
    1e3 * rms(&d)
}

/// The MakeHuman body (no skirt) in the exercise motion and the ring of §2.5.1 around it (the
/// MakeHuman template is centred on its pelvis, not standing on y = 0): 8 cameras at
/// 480 × 360, 3.5 m away, slightly above the pelvis.
fn body_exercise_studio() -> (Performer, Motion, Vec<Camera>, CaptureSpec) {
    let performer = makehuman_performer(
        example_kit::data_path("makehuman").unwrap(),
        &DeformationParams::default(),
    )
    .unwrap();
    let motion = exercise_motion(&performer.skeleton, &ExerciseParams::default()).unwrap();
    let (cameras, spec) = ring_around(&performer, &motion);
    (performer, motion, cameras, spec)
}

/// The ring of §2.5.1 around `performer`'s pelvis at the first frame of `motion`: 8 cameras
/// at 480 × 360, 3.5 m away, 0.15 m above the pelvis; masks only, at the motion's rate.
fn ring_around(performer: &Performer, motion: &Motion) -> (Vec<Camera>, CaptureSpec) {
    let root = performer
        .skeleton
        .forward_kinematics(motion.frame(0))
        .unwrap()
        .joint_positions()[0];
    let k = Intrinsics::from_horizontal_fov(55f64.to_radians(), 480, 360).unwrap();
    let rig = Rig::ring(8, 3.5, root.y + 0.15, root, DVec3::Y, k).unwrap();
    let cameras = rig.cameras.clone();
    let spec = CaptureSpec::masks_only(rig).with_frame_rate_hz(1.0 / motion.frame_time_s);
    (cameras, spec)
}

/// One frame's observations (hull and contour rays) with the default parameters.
fn observe(cameras: &[Camera], masks: &[Mask]) -> FrameObservation {
    FrameObservation::new(
        cameras,
        masks,
        &ContourRayHullParams::default(),
        &SilhouetteParams::default(),
    )
    .unwrap()
}

#[test]
fn tracked_and_molded_template_fits_the_silhouettes_of_an_exercise() {
    let (performer, motion, cameras, spec) = body_exercise_studio();
    let capture = Capture::new(&performer, &motion, spec).unwrap();
    let frames: Vec<_> = capture
        .frames_stepped(40..56, 2)
        .map(|f| f.unwrap())
        .collect();
    // Rigged as a user's template would be (§2.5.1: Pinocchio's bone heat); the performer's
    // own weights generated the truth and are the oracle.
    let weights = bone_heat_weights(
        &performer.template,
        &rest_bones(&performer.skeleton).unwrap(),
        &HeatWeightsParams::default(),
    )
    .unwrap();
    let template = Template::new(
        performer.template.clone(),
        performer.skeleton.clone(),
        weights,
    )
    .unwrap();
    let oracle = Template::new(
        performer.template.clone(),
        performer.skeleton.clone(),
        performer.weights.clone(),
    )
    .unwrap();
    let sk = template.skeleton();

    let start = Instant::now();
    let masks: Vec<_> = frames.iter().map(|f| f.masks()).collect();
    let observations: Vec<FrameObservation> = masks.iter().map(|m| observe(&cameras, m)).collect();
    let observe_s = start.elapsed().as_secs_f64();

    // §2.3 then §2.4; the first frame's true pose stands in for the user's fit of frame 0.
    let result = capture_sequence(
        &template,
        &observations,
        &frames[0].truth.theta,
        &[],
        &PoseParams::default(),
        &ShapeParams::default(),
    )
    .unwrap();
    let (poses, seq) = (&result.poses, &result.shapes);
    let (pose_s, shape_s) = (result.pose_seconds, result.shape_seconds);

    let n = frames.len() as f64;
    let (mut joint_mm, mut method_mm, mut lbs_mm, mut lbs_true_mm, mut oracle_mm) =
        (0.0, 0.0, 0.0, 0.0, 0.0);
    let (mut sil_method, mut sil_lbs, mut edge, mut lbs_edge, mut true_edge) =
        (0.0, 0.0, 0.0, 0.0, 0.0);
    for (t, f) in frames.iter().enumerate() {
        let truth = &f.truth.posed.true_vertices;
        let est = sk.forward_kinematics(&poses.poses[t]).unwrap();
        let tru = sk.forward_kinematics(&f.truth.theta).unwrap();
        joint_mm += 1e3
            * est
                .joint_positions()
                .iter()
                .zip(tru.joint_positions())
                .map(|(a, b)| (*a - b).length())
                .sum::<f64>()
            / sk.joint_count() as f64;
        let lbs = template.skin(&poses.poses[t]).unwrap();
        method_mm += rms_mm(&seq.frames[t], truth);
        lbs_mm += rms_mm(&lbs, truth);
        lbs_true_mm += rms_mm(&template.skin(&f.truth.theta).unwrap(), truth);
        oracle_mm += rms_mm(&oracle.skin(&f.truth.theta).unwrap(), truth);
        let mesh = template.mesh_with(seq.frames[t].clone());
        sil_method += mean(&silhouette_error_pct(&mesh, &cameras, &masks[t]).unwrap());
        sil_lbs +=
            mean(&silhouette_error_pct(&template.mesh_with(lbs), &cameras, &masks[t]).unwrap());
        edge += edge_error_pct(template.mesh(), &seq.frames[t]).unwrap();
        lbs_edge +=
            edge_error_pct(template.mesh(), &template.skin(&poses.poses[t]).unwrap()).unwrap();
        true_edge += edge_error_pct(template.mesh(), truth).unwrap();
    }
    let figures = [
        ("joint_error_mm", joint_mm / n),
        ("vertex_rms_mm", method_mm / n),
        ("lbs_vertex_rms_mm", lbs_mm / n),
        ("lbs_true_pose_vertex_rms_mm", lbs_true_mm / n),
        ("lbs_oracle_pose_vertex_rms_mm", oracle_mm / n),
        ("silhouette_error_pct", sil_method / n),
        ("lbs_silhouette_error_pct", sil_lbs / n),
        ("edge_error_pct", edge / n),
        ("lbs_edge_error_pct", lbs_edge / n),
        ("true_edge_error_pct", true_edge / n),
        ("observe_s_per_frame", observe_s / n),
        ("pose_s_per_frame", pose_s / n),
        ("shape_s_per_frame", shape_s / n),
    ];
    for (k, v) in figures {
        println!("{k}: {v:.3}");
    }
    let get = |k: &str| figures.iter().find(|f| f.0 == k).unwrap().1;
    // Measured (8 frames, 480 × 360, the library's weights): joints 14.4 mm; silhouettes
    // 7.9 % against 11.4 % for skinning with the same poses; vertices 88 mm against 25 mm for
    // that skinning — the thesis' Eq. 2.1 collapses the head and torso, where bone heat
    // leaves few nearly-rigid vertices (below) — and skinning with the true poses 9.8 mm
    // (1.1 mm with the performer's own weights, the oracle that generated the truth).
    assert!(get("joint_error_mm") < 20.0);
    assert!(get("silhouette_error_pct") < 0.85 * get("lbs_silhouette_error_pct"));
    assert!(get("lbs_oracle_pose_vertex_rms_mm") < 2.0);
    assert!(get("lbs_true_pose_vertex_rms_mm") > 3.0 * get("lbs_oracle_pose_vertex_rms_mm"));

    // Algorithm 1 on the true poses separates the molding from the tracker. With automatic
    // weights the thesis' molding ends far from the truth — farther than skinning with the
    // same (true) poses — while the anchor to the skinned surface (ShapeParams::w_anchor,
    // ours) brings it back to skinning's level without beating it (docs: the full run).
    let shape_frames: Vec<ShapeFrame> = frames
        .iter()
        .zip(&observations)
        .map(|(f, o)| ShapeFrame {
            theta: &f.truth.theta,
            rays: &o.rays,
        })
        .collect();
    let molded_true_pose_mm = |params: ShapeParams| {
        let shapes = ShapeEstimator::new(template.clone(), params)
            .unwrap()
            .estimate(&shape_frames)
            .unwrap();
        frames
            .iter()
            .zip(&shapes.frames)
            .map(|(f, v)| rms_mm(v, &f.truth.posed.true_vertices))
            .sum::<f64>()
            / n
    };
    let thesis = molded_true_pose_mm(ShapeParams::default());
    let anchored = molded_true_pose_mm(ShapeParams {
        w_anchor: 1.0,
        ..ShapeParams::default()
    });
    let lbs_true = get("lbs_true_pose_vertex_rms_mm");
    println!("molded_true_pose_vertex_rms_mm: {thesis:.3} (anchored {anchored:.3})");
    assert!(
        thesis > 2.0 * lbs_true,
        "thesis {thesis} mm vs skinning {lbs_true} mm"
    );
    assert!(
        anchored < 1.15 * lbs_true && anchored < 0.5 * thesis,
        "anchored {anchored} mm vs skinning {lbs_true} mm, thesis {thesis} mm"
    );
}

/// The pieces a user strings together around a capture (§2.5): the MakeHuman template with
/// its skirt decimated to ≈ 10k vertices (weights and texture coordinates carried over, the
/// vertices a fixed embedding in the rest mesh), and a template edit carried to a posed frame
/// by deformation transfer.
#[test]
fn a_decimated_textured_template_takes_an_edit_to_a_posed_frame() {
    use dynamic_shapes::core::mesh::{decimate, SkinWeights};
    use dynamic_shapes::template::DeformationTransfer;
    use dynamic_shapes_studio::{GarmentParams, SkirtParams};

    let performer = makehuman_performer(
        example_kit::data_path("makehuman").unwrap(),
        &DeformationParams::default()
            .with_flap(None)
            .with_garment(Some(GarmentParams::Skirt(SkirtParams::default()))),
    )
    .unwrap();
    let full = &performer.template;
    let d = decimate(full, 10_000).unwrap();
    let n = d.mesh.vertex_count();
    assert!((9_000..=11_000).contains(&n), "{n} vertices");
    let lists: Vec<Vec<(u32, f64)>> = d
        .original_index
        .iter()
        .map(|&o| performer.weights.influences(o as usize).collect())
        .collect();
    let weights = SkinWeights::from_lists(&lists, performer.weights.bone_count()).unwrap();
    let template = Template::new(d.mesh.clone(), performer.skeleton.clone(), weights).unwrap();
    // The skirt survives decimation (its hem is a locked border).
    let garment = performer.garment_vertices();
    let skirt = d
        .original_index
        .iter()
        .filter(|&&o| garment.contains(&(o as usize)))
        .count();
    assert!(skirt > 500, "{skirt} skirt vertices kept");
    // Texture coordinates on the kept vertices, split at the atlas' seams.
    let uvs = performer
        .uvs
        .as_ref()
        .unwrap()
        .for_vertex_subset(full, &d.mesh, &d.original_index)
        .unwrap();
    let split = uvs.split_seams(&d.mesh).unwrap();
    assert!(split.vertex.len() >= n && split.vertex.len() < 2 * n);
    // A posed frame: the skinned template in the exercise's frame 60.
    let motion = exercise_motion(&performer.skeleton, &ExerciseParams::default()).unwrap();
    let posed = template.skin(motion.frame(60)).unwrap();
    // The edit: the belly pushed out 3 cm in front of the pelvis, smoothly.
    let root = performer
        .skeleton
        .forward_kinematics(&vec![0.0; performer.skeleton.dof_count()])
        .unwrap()
        .joint_positions()[0];
    let edited: Vec<DVec3> = d
        .mesh
        .vertices
        .iter()
        .map(|v| {
            let r = (*v - (root + DVec3::new(0.0, 0.1, 0.12))).length();
            let s = (1.0 - r / 0.12).clamp(0.0, 1.0);
            *v + DVec3::Z * 0.03 * s * s
        })
        .collect();
    let transfer = DeformationTransfer::new(&d.mesh, &edited).unwrap();
    let out = transfer.transfer(&posed).unwrap();
    // The vertices the edit left alone stay where the frame has them; the edited ones move
    // by about the edit's size.
    let (mut still, mut moved) = (vec![], vec![]);
    for v in 0..n {
        let shift = out[v].distance(posed[v]);
        if edited[v] == d.mesh.vertices[v] {
            still.push(shift);
        } else if edited[v].distance(d.mesh.vertices[v]) > 0.02 {
            moved.push(shift);
        }
    }
    assert!(!moved.is_empty());
    assert!(
        rms(&still) < 1e-3,
        "unedited vertices moved {} m",
        rms(&still)
    );
    let m = mean(&moved);
    assert!((0.015..0.04).contains(&m), "edited vertices moved {m} m");
}

/// Automatic first-frame initialisation: `initialise_pose` from one frame's visual hull and contour
/// rays only (no markers, no stereo points, no user constraint), scored against the true pose and
/// against the baseline that could have won (the rest pose moved to the hull's centroid, then the
/// same robust ellipsoid fit).
#[test]
fn automatic_first_pose_beats_the_rest_pose_start() {
    use dynamic_shapes::template::{
        initial_pose_score, initialise_pose, pose_error, rest_pose_start, AutoInitParams,
        EllipsoidModel,
    };
    let (performer, motion, cameras, spec) = body_exercise_studio();
    let capture = Capture::new(&performer, &motion, spec).unwrap();
    let sk = &performer.skeleton;
    let model = EllipsoidModel::with_end_sites(sk.clone(), 0.1).unwrap();
    let params = AutoInitParams::default();
    for f in [40usize, 60] {
        let frame = capture.frames_stepped(f..f + 1, 1).next().unwrap().unwrap();
        let truth = &frame.truth.theta;
        let obs = observe(&cameras, &frame.masks());
        let t = Instant::now();
        let auto = initialise_pose(&model, &obs.hull, &obs.rays, &params).unwrap();
        let auto_s = t.elapsed().as_secs_f64();
        let rest_fit = rest_pose_start(&model, &obs.hull, &obs.rays, &params).unwrap();
        let err = |theta: &[f64]| {
            let (m, rad) = pose_error(sk, theta, truth).unwrap();
            (1e3 * m, rad.to_degrees())
        };
        let (a_mm, a_deg) = err(auto.theta());
        let (g_mm, g_deg) = err(&auto.global.theta);
        let (r_mm, r_deg) = err(&rest_fit.state.theta);
        println!(
            "frame {f}: automatic {a_mm:.0} mm {a_deg:.1} deg (global step {g_mm:.0} mm \
             {g_deg:.1} deg, {} candidates, {auto_s:.2} s); rest start {r_mm:.0} mm {r_deg:.1} deg",
            auto.evaluations
        );
        println!(
            "  headings {:?}; fit kept {}; true pose scores {:.3}",
            auto.headings,
            auto.fit_kept,
            initial_pose_score(&model, &obs.hull, truth, &params).unwrap()
        );
        assert!(a_deg < r_deg && a_mm < r_mm);
    }
}

/// Automatic sizing and its use by the tracker, with no user constraint: a performer whose bone
/// lengths differ from the default by up to 10 % (the `ellipsoid_fit` scenario's, procedural body),
/// the first half second of a swinging motion (the fast motion at 0.5–1 Hz, 30 frames at 60 Hz), 8
/// cameras at 400 × 300; only hulls and contour rays.
///
/// 1. The automatic first pose (`size_performer` runs `initialise_pose` on frame 0), the
///    template tracker at default proportions from it, then `size_from_poses`: 8 frames spread
///    over the half second fitted together. Baseline that could have won: default proportions
///    (5 cm widths) at the same poses. Also `size_performer`'s own tracking (the pose-only
///    ellipsoid fit frame to frame): printed.
/// 2. The template re-rigged to the sized skeleton (`Template::resized`), tracked again from
///    the same first pose; against the default-proportion track and the true skeleton's.
#[test]
fn sizing_from_the_tracked_first_frames_beats_default_proportions() {
    use dynamic_shapes::template::{
        ellipsoid_scenario, score_ellipsoids, size_from_poses, size_performer, track,
        EllipsoidScenarioParams, EllipsoidScores, PoseFrame, PoseModel, ScenarioMotion,
        SizingParams,
    };
    use dynamic_shapes_studio::{procedural_performer, FastMotionParams, ProceduralBodyParams};
    let t = Instant::now();
    let scenario = ellipsoid_scenario(&EllipsoidScenarioParams {
        cameras: 8,
        end_sites: true,
        frames: (0..30).collect(),
        motion: ScenarioMotion::Fast(FastMotionParams {
            frequency_hz: (0.5, 1.0),
            ..FastMotionParams::default()
        }),
        points: 100, // unused here: the tracker's inputs are the hulls and the rays
        markers: 0,
        ..EllipsoidScenarioParams::default()
    })
    .unwrap();
    let model = &scenario.model;
    let obs: Vec<FrameObservation> = scenario
        .frames
        .iter()
        .map(|f| observe(&scenario.cameras, &f.masks))
        .collect();
    let scenario_s = t.elapsed().as_secs_f64();
    let params = SizingParams::default();
    let t = Instant::now();
    let own = size_performer(model, &obs, &params).unwrap();
    let own_s = t.elapsed().as_secs_f64();
    let first = own.init.as_ref().unwrap().theta().to_vec();

    // The template tracker (no shape refinement) at default proportions.
    let performer = procedural_performer(&ProceduralBodyParams {
        grid_spacing_m: 0.02, // the scenario's
        ..ProceduralBodyParams::default()
    })
    .unwrap();
    let default_template = Template::new(
        performer.template.clone(),
        performer.skeleton.clone(),
        performer.weights.clone(),
    )
    .unwrap();
    let frames: Vec<PoseFrame<'_>> = obs.iter().map(|o| o.pose_frame(&[])).collect();
    let run = |template: &Template| {
        let m = PoseModel::new(template, &PoseParams::default()).unwrap();
        track(&m, &frames, &first, None, &PoseParams::default())
            .unwrap()
            .poses
    };
    let t = Instant::now();
    let default_poses = run(&default_template);
    let track_s = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let sizing = size_from_poses(model, &obs, &default_poses, &params).unwrap();
    let size_s = t.elapsed().as_secs_f64();

    let mean_of = |s: &[EllipsoidScores]| {
        let m = |g: fn(&EllipsoidScores) -> f64| mean(&s.iter().map(g).collect::<Vec<_>>());
        (
            m(|s| s.bone_length_error_mm),
            m(|s| s.width_error_mm),
            m(|s| s.joint_angle_error_deg),
        )
    };
    let scores = |states: &[dynamic_shapes::template::EllipsoidState], chosen: &[usize]| {
        let s: Vec<EllipsoidScores> = states
            .iter()
            .zip(chosen)
            .map(|(s, &f)| score_ellipsoids(model, s, &scenario.frames[f].truth).unwrap())
            .collect();
        mean_of(&s)
    };
    let baseline: Vec<_> = sizing
        .chosen
        .iter()
        .map(|&f| sizing.tracked[f].clone())
        .collect();
    let (sl, sw, sd) = scores(&sizing.fit.states, &sizing.chosen);
    let (bl, bw, bd) = scores(&baseline, &sizing.chosen);
    let (ol, ow, od) = scores(&own.fit.states, &own.chosen);
    let own_base: Vec<_> = own.chosen.iter().map(|&f| own.tracked[f].clone()).collect();
    let (_, _, obd) = scores(&own_base, &own.chosen);
    println!(
        "scenario {scenario_s:.1} s; sizing from the template tracker's poses (frames {:?}): \
         lengths {sl:.1} mm widths {sw:.1} mm directions {sd:.1} deg; default proportions \
         {bl:.1} / {bw:.1} / {bd:.1} (track {track_s:.1} s, fit {size_s:.1} s)",
        sizing.chosen
    );
    println!(
        "size_performer (ellipsoid tracking): {ol:.1} / {ow:.1} / {od:.1}, its tracked poses \
         {obd:.1} deg ({own_s:.1} s)"
    );

    // 2. The tracker with the sized template, against default proportions and the truth.
    let sized_template = default_template
        .resized(sizing.skeleton(model).unwrap())
        .unwrap();
    let true_template = default_template
        .resized(model.scaled_skeleton(&scenario.frames[0].truth).unwrap())
        .unwrap();
    let true_sk = true_template.skeleton().clone();
    let figures = |template: &Template, poses: &[Vec<f64>]| {
        let (mut joint, mut vertex, mut sil) = (0.0, 0.0, 0.0);
        for (f, (p, fr)) in poses.iter().zip(&scenario.frames).enumerate() {
            let est = template.skeleton().forward_kinematics(p).unwrap();
            let tru = true_sk.forward_kinematics(&fr.truth.theta).unwrap();
            joint += 1e3
                * mean(
                    &est.joint_positions()
                        .iter()
                        .zip(tru.joint_positions())
                        .map(|(a, b)| a.distance(b))
                        .collect::<Vec<_>>(),
                );
            let skinned = template.skin(p).unwrap();
            vertex += rms_mm(&skinned, &fr.mesh.vertices);
            if f % 5 == 0 {
                sil += mean(
                    &silhouette_error_pct(
                        &template.mesh_with(skinned),
                        &scenario.cameras,
                        &fr.masks,
                    )
                    .unwrap(),
                );
            }
        }
        let n = poses.len() as f64;
        (joint / n, sil / (n / 5.0).ceil(), vertex / n)
    };
    let t = Instant::now();
    let sized_poses = run(&sized_template);
    let true_poses = run(&true_template);
    let rerun_s = t.elapsed().as_secs_f64();
    let (dj, ds, dv) = figures(&default_template, &default_poses);
    let (zj, zs, zv) = figures(&sized_template, &sized_poses);
    let (tj, ts, tv) = figures(&true_template, &true_poses);
    println!(
        "tracker (joint mm / silhouette % / vertex mm): default proportions {dj:.1} / {ds:.2} / \
         {dv:.1}; sized {zj:.1} / {zs:.2} / {zv:.1}; true skeleton {tj:.1} / {ts:.2} / {tv:.1} \
         ({rerun_s:.1} s)"
    );
    assert!(sw < 0.6 * bw, "widths {sw} vs {bw}");
    assert!(sd < bd, "directions {sd} vs {bd}");
}

/// The sizing studio: the body exercise (`body_exercise_studio`) with every modelled
/// bone of the end-site model scaled by a seeded factor in [0.9, 1.1]
/// (`Performer::with_bone_scales`), frames 40–62 (every second) captured and observed.
struct ResizedStudio {
    default: Performer,
    model: dynamic_shapes::template::EllipsoidModel,
    performer: Performer,
    frames: Vec<dynamic_shapes_studio::CaptureFrame>,
    obs: Vec<FrameObservation>,
}

fn resized_body_exercise() -> ResizedStudio {
    let (default, motion, cameras, spec) = body_exercise_studio();
    let model =
        dynamic_shapes::template::EllipsoidModel::with_end_sites(default.skeleton.clone(), 0.1)
            .unwrap();
    let rng = dynamic_shapes::core::random::SplitMix64::new(12);
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
        .map(|f| observe(&cameras, &f.masks()))
        .collect();
    ResizedStudio {
        default,
        model,
        performer,
        frames,
        obs,
    }
}

/// Automatic sizing on a studio performer with other bone lengths, the template tracker's figures
/// with this sizing and initialisation and no user constraint at all: the MakeHuman body with every
/// modelled bone scaled by a seeded factor in [0.9, 1.1] (`Performer::with_bone_scales`), the
/// exercise motion (frames 40–62, every second), observed through the studio's `Capture` by 8
/// cameras at 480 × 360. The tracker's template has the default proportions; the automatic first
/// pose, the pose tracker at default proportions, `size_from_poses` on its poses, then the tracker
/// again with the template re-rigged to the sized skeleton and to the true one. Baseline that could
/// have won: the default proportions (5 cm half-widths). Scored against `reference_sizes` of the
/// true template (Eq. 3 fitted to its nearly-rigid limb vertices).
#[test]
fn a_performer_with_other_bone_lengths_is_sized_from_the_tracked_first_frames() {
    use dynamic_shapes::template::{
        initialise_pose, reference_sizes, score_ellipsoids, size_from_poses, track, AutoInitParams,
        EllipsoidState, PoseFrame, PoseModel, SizingParams,
    };
    let t = Instant::now();
    let ResizedStudio {
        default,
        model,
        performer,
        frames,
        obs,
    } = resized_body_exercise();
    let studio_s = t.elapsed().as_secs_f64();
    let true_template = Template::new(
        performer.template.clone(),
        performer.skeleton.clone(),
        performer.weights.clone(),
    )
    .unwrap();
    let default_template = true_template.resized(default.skeleton.clone()).unwrap();
    let t = Instant::now();
    let first = initialise_pose(
        &model,
        &obs[0].hull,
        &obs[0].rays,
        &AutoInitParams::default(),
    )
    .unwrap()
    .theta()
    .to_vec();
    let init_s = t.elapsed().as_secs_f64();
    let pose_frames: Vec<PoseFrame<'_>> = obs.iter().map(|o| o.pose_frame(&[])).collect();
    let run = |template: &Template| {
        let m = PoseModel::new(template, &PoseParams::default()).unwrap();
        track(&m, &pose_frames, &first, None, &PoseParams::default())
            .unwrap()
            .poses
    };
    let t = Instant::now();
    let default_poses = run(&default_template);
    let sizing = size_from_poses(&model, &obs, &default_poses, &SizingParams::default()).unwrap();
    let size_s = t.elapsed().as_secs_f64();

    // Sizes against the true template's reference, at the rest pose.
    let reference = reference_sizes(&model, &true_template, 0.05).unwrap();
    let rest = |s: &EllipsoidState| EllipsoidState {
        theta: default.skeleton.rest_pose(),
        ..s.clone()
    };
    let sizes = |s: &EllipsoidState| {
        let e = score_ellipsoids(&model, &rest(s), &rest(&reference)).unwrap();
        (e.bone_length_error_mm, e.width_error_mm)
    };
    let (sl, sw) = sizes(sizing.state().unwrap());
    let (dl, dw) = sizes(&model.initial_state(&first, 0.05).unwrap());

    // The tracker with the three templates.
    let sized_template = default_template
        .resized(sizing.skeleton(&model).unwrap())
        .unwrap();
    let t = Instant::now();
    let sized_poses = run(&sized_template);
    let true_poses = run(&true_template);
    let rerun_s = t.elapsed().as_secs_f64();
    let joint_mm = |template: &Template, poses: &[Vec<f64>]| {
        let per_frame: Vec<f64> = poses
            .iter()
            .zip(&frames)
            .map(|(p, f)| {
                let est = template.skeleton().forward_kinematics(p).unwrap();
                let tru = performer
                    .skeleton
                    .forward_kinematics(&f.truth.theta)
                    .unwrap();
                1e3 * mean(
                    &est.joint_positions()
                        .iter()
                        .zip(tru.joint_positions())
                        .map(|(a, b)| a.distance(b))
                        .collect::<Vec<_>>(),
                )
            })
            .collect();
        mean(&per_frame)
    };
    let (dj, zj, tj) = (
        joint_mm(&default_template, &default_poses),
        joint_mm(&sized_template, &sized_poses),
        joint_mm(&true_template, &true_poses),
    );
    println!(
        "studio {studio_s:.1} s, first pose {init_s:.1} s, track + size {size_s:.1} s, two \
         more tracks {rerun_s:.1} s; sizes (frames {:?}): lengths {sl:.1} mm widths {sw:.1} mm; \
         default proportions {dl:.1} / {dw:.1}",
        sizing.chosen
    );
    println!(
        "tracker joint error: default proportions {dj:.1} mm, sized {zj:.1} mm, true skeleton \
         {tj:.1} mm"
    );
    // Diagnostic: the same sizing from the true poses, which separates the fit's own error
    // from the tracked poses'.
    let truth_poses: Vec<Vec<f64>> = frames.iter().map(|f| f.truth.theta.clone()).collect();
    let oracle = size_from_poses(&model, &obs, &truth_poses, &SizingParams::default()).unwrap();
    let (ol, ow) = sizes(oracle.state().unwrap());
    println!("the sizing from the true poses: lengths {ol:.1} mm widths {ow:.1} mm");
    assert!(sw < 0.9 * dw, "widths {sw} vs default {dw}");
    // Lengths within 10 % of the default proportions' error from the tracked poses and 20 %
    // from the true ones (measured 15.4 and 17.1 against 16.0; with the root's position free
    // in the joint fit, `EllipsoidParams::sigma_translation_prior_m` None, 21.1 and 26.5: the
    // pelvis rose 6 cm and the thighs lengthened, docs/template-silhouette.md).
    assert!(sl < 1.1 * dl, "lengths {sl} vs default {dl}");
    assert!(
        ol < 1.2 * dl,
        "lengths from the true poses {ol} vs default {dl}"
    );
}

/// Trace (diagnostic, `--ignored`): why `size_from_poses` makes the legs too long on the MakeHuman
/// performer with other bone lengths. Per limb bone, from the true poses: the hull samples each
/// ellipsoid holds near its ends (within 3 cm beyond a joint along the true bone) and their
/// distance to the true surface (phantom hull), then the per-bone length errors with the default
/// fit, with free end-site scales and with one-sided hull samples.
#[test]
#[ignore = "diagnostic trace, ~1 min"]
fn trace_leg_lengths() {
    use dynamic_shapes::template::{
        initialise_pose, reference_sizes, score_ellipsoids, size_from_poses, track, AutoInitParams,
        EllipsoidParams, EllipsoidState, PoseFrame, PoseModel, SizingParams,
    };
    let ResizedStudio {
        default,
        model,
        performer,
        frames,
        obs,
    } = resized_body_exercise();
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
    let pose_frames: Vec<PoseFrame<'_>> = obs.iter().map(|o| o.pose_frame(&[])).collect();
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

/// The thesis' protocol on the performer in the skirt walking (CMU 131_01), where the tracker
/// loses the limbs: the template as a scanner gives it (`scan_outer_surface`: one closed outer
/// surface, decimated to 10,000 vertices and relaxed, bone-heat weights) and the user of
/// §2.3.3 who fixes hard frames during the forward pass, emulated by an oracle that sees the
/// true pose (`OracleUser`). The user's rays cut the joint error against the tracker alone
/// (the frames it fixed are counted from the rays the tracker reports); then,
/// beyond the thesis, the molding started from the previous frame's surface
/// (`ShapeStart::PreviousFrame`) against the thesis' start on the same poses, scored by the
/// two-way distance between the skirt and the true skirt.
#[test]
fn the_emulated_user_and_the_previous_frame_start_beat_their_baselines_on_the_skirt_walk() {
    use dynamic_shapes::core::mesh::{points_to_surface, DistanceStats, MeshQuery};
    use dynamic_shapes::core::skeleton::{BvhParams, CMU_METRES_PER_UNIT};
    use dynamic_shapes::template::{capture_sequence_corrected, OracleUser, ShapeStart};
    use dynamic_shapes_studio::{
        play_bvh, scan_outer_surface, GarmentParams, RetargetParams, ScanParams, SkirtParams,
    };

    let performer = makehuman_performer(
        example_kit::data_path("makehuman").unwrap(),
        &DeformationParams::default()
            .with_flap(None)
            .with_garment(Some(GarmentParams::Skirt(SkirtParams::default()))),
    )
    .unwrap();
    let motion = play_bvh(
        example_kit::data_path("mocap-cmu/131_01.bvh").unwrap(),
        &BvhParams {
            metres_per_unit: CMU_METRES_PER_UNIT,
        },
        &performer.skeleton,
        1.0 / 60.0,
        &RetargetParams::default(),
    )
    .unwrap()
    .motion;
    let (cameras, spec) = ring_around(&performer, &motion);
    let capture = Capture::new(&performer, &motion, spec).unwrap();
    let frames: Vec<_> = capture
        .frames_stepped(0..24, 2)
        .map(|f| f.unwrap())
        .collect();
    let masks: Vec<Vec<Mask>> = frames.iter().map(|f| f.masks()).collect();
    let observations: Vec<FrameObservation> = masks.iter().map(|m| observe(&cameras, m)).collect();
    let scan = scan_outer_surface(&performer, &ScanParams::default()).unwrap();
    let weights = bone_heat_weights(
        &scan.mesh,
        &rest_bones(&performer.skeleton).unwrap(),
        &HeatWeightsParams::default(),
    )
    .unwrap();
    let template = Template::new(scan.mesh.clone(), performer.skeleton.clone(), weights).unwrap();
    let sk = template.skeleton();
    let true_poses: Vec<Vec<f64>> = frames.iter().map(|f| f.truth.theta.clone()).collect();
    let joint_error_mm = |poses: &[Vec<f64>]| {
        let per_frame: Vec<f64> = poses
            .iter()
            .zip(&true_poses)
            .map(|(a, b)| {
                let (pa, pb) = (
                    sk.forward_kinematics(a).unwrap().joint_positions(),
                    sk.forward_kinematics(b).unwrap().joint_positions(),
                );
                1e3 * mean(
                    &pa.iter()
                        .zip(&pb)
                        .map(|(x, y)| x.distance(*y))
                        .collect::<Vec<_>>(),
                )
            })
            .collect();
        mean(&per_frame)
    };
    let silhouette_pct = |shapes: &[Vec<DVec3>]| {
        let per_frame: Vec<f64> = shapes
            .iter()
            .zip(&masks)
            .map(|(v, m)| {
                mean(&silhouette_error_pct(&template.mesh_with(v.clone()), &cameras, m).unwrap())
            })
            .collect();
        mean(&per_frame)
    };
    let mut user = OracleUser::new(
        sk,
        &performer.skeleton,
        true_poses.clone(),
        [cameras[0].clone(), cameras[2].clone()],
        0.05,
    )
    .unwrap();
    let mut accept = |_: usize, _: &[f64]| Vec::new();
    let run = |corrector: &mut dyn dynamic_shapes::template::FrameCorrector| {
        capture_sequence_corrected(
            &template,
            &observations,
            &true_poses[0],
            &[],
            corrector,
            &PoseParams::default(),
            &ShapeParams::default(),
        )
        .unwrap()
    };
    let (plain, fixed) = (run(&mut accept), run(&mut user));
    let (plain_mm, fixed_mm) = (
        joint_error_mm(&plain.poses.poses),
        joint_error_mm(&fixed.poses.poses),
    );
    let (plain_sil, fixed_sil) = (
        silhouette_pct(&plain.shapes.frames),
        silhouette_pct(&fixed.shapes.frames),
    );
    let fixed_frames = fixed
        .poses
        .added_user_rays
        .iter()
        .filter(|r| !r.is_empty())
        .count();
    // Beyond the thesis: the same poses, each frame's molding from the previous frame's.
    let carried = ShapeEstimator::new(
        template.clone(),
        ShapeParams::default().with_start(ShapeStart::PreviousFrame),
    )
    .unwrap()
    .estimate(
        &fixed
            .poses
            .poses
            .iter()
            .zip(&observations)
            .map(|(theta, o)| ShapeFrame {
                theta,
                rays: &o.rays,
            })
            .collect::<Vec<_>>(),
    )
    .unwrap();
    // The two-way distance between the template's skirt and the true skirt, mm (mean over
    // frames of the pooled mean).
    let skirt: Vec<usize> = (0..scan.mesh.vertex_count())
        .filter(|&v| scan.on_garment[v])
        .collect();
    let skirt_mm = |shapes: &[Vec<DVec3>]| {
        let per_frame: Vec<f64> = shapes
            .iter()
            .zip(&frames)
            .map(|(v, f)| {
                let true_mesh = f.truth.true_mesh(&performer);
                let true_query = MeshQuery::new(&true_mesh).unwrap();
                let query = MeshQuery::new(&template.mesh_with(v.clone())).unwrap();
                let ours: Vec<DVec3> = skirt.iter().map(|&i| v[i]).collect();
                let theirs: Vec<DVec3> = performer
                    .garment_vertices()
                    .map(|i| true_mesh.vertices[i])
                    .collect();
                let pooled: Vec<f64> = points_to_surface(&ours, &true_query)
                    .unwrap()
                    .per_vertex
                    .into_iter()
                    .chain(points_to_surface(&theirs, &query).unwrap().per_vertex)
                    .collect();
                1e3 * DistanceStats::from_distances(&pooled).unwrap().mean
            })
            .collect();
        mean(&per_frame)
    };
    let (thesis_skirt, carried_skirt) = (skirt_mm(&fixed.shapes.frames), skirt_mm(&carried.frames));
    println!(
        "skirt walk, {} frames, scanned template: joint error {plain_mm:.1} mm, with the \
         emulated user {fixed_mm:.1} mm ({fixed_frames} frames fixed); silhouette error \
         {plain_sil:.1} %, with the user {fixed_sil:.1} %; skirt surface distance from the \
         thesis' start {thesis_skirt:.1} mm, from the previous frame's {carried_skirt:.1} mm",
        frames.len()
    );
    assert!(plain.poses.added_user_rays.iter().all(Vec::is_empty));
    assert!(fixed_frames > 0);
    assert!(
        fixed_mm < 0.7 * plain_mm,
        "with the user {fixed_mm} mm, without {plain_mm} mm"
    );
    // The user mends poses, not silhouettes: the molding fits the silhouettes from either
    // track (6.8 % both, measured), so the silhouette error is printed, not asserted.
    assert!(fixed_sil.is_finite() && plain_sil.is_finite());
    assert!(
        carried_skirt < 0.9 * thesis_skirt,
        "from the previous frame {carried_skirt} mm, from skinning {thesis_skirt} mm"
    );
}
