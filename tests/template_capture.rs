//! Small end-to-end validation of template-silhouette on the studio (the CI-sized version of
//! the coming `examples/template_capture`): the MakeHuman performer (body only, no skirt) in
//! the exercise motion, seen by an 8-camera ring; pose tracking in the visual hulls (§2.3)
//! then Algorithm 1 (§2.4),
//! scored against the performer's true posed mesh and against linear blend skinning driven by
//! the same estimated poses and by the true poses.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)] // not library code

use std::time::Instant;

use dynamic_shapes::core::camera::{Camera, Intrinsics, Rig};
use dynamic_shapes::core::math::DVec3;
use dynamic_shapes::core::skeleton::Motion;
use dynamic_shapes::core::stats::{mean, rms};
use dynamic_shapes::core::studio::{
    exercise_motion, makehuman_performer, Capture, CaptureSpec, DeformationParams, ExerciseParams,
    Performer,
};
use dynamic_shapes::template::{
    capture_sequence, edge_error_pct, silhouette_error_pct, FrameObservation, PoseParams,
    ShapeParams, SilhouetteParams, Template, VisualHullParams,
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
fn tracked_and_molded_template_fits_the_silhouettes_of_an_exercise() {
    let (performer, motion, cameras, spec) = body_exercise_studio();
    let capture = Capture::new(&performer, &motion, spec).unwrap();
    let frames: Vec<_> = capture
        .frames_stepped(40..56, 2)
        .map(|f| f.unwrap())
        .collect();
    let template = Template::new(
        performer.template.clone(),
        performer.skeleton.clone(),
        performer.weights.clone(),
    )
    .unwrap();
    let sk = template.skeleton();

    let start = Instant::now();
    let masks: Vec<_> = frames.iter().map(|f| f.masks()).collect();
    let observations: Vec<FrameObservation> = masks
        .iter()
        .map(|m| {
            FrameObservation::new(
                &cameras,
                m,
                &VisualHullParams::default(),
                &SilhouetteParams::default(),
            )
            .unwrap()
        })
        .collect();
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
    let (mut joint_mm, mut method_mm, mut lbs_mm, mut lbs_true_mm) = (0.0, 0.0, 0.0, 0.0);
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
    // Measured (8 frames, 480 × 360; hands' and feet's frames in E_R): joints 15.1 mm (11.9
    // with the thesis' tip rule: on 8 frames the rules differ by noise; see EffectorTargets
    // for means over independent tracks); silhouettes 3.9 % against 11.3 % for skinning with
    // the same poses; vertices 24.0 mm against 23.8 mm for that skinning (the pose dominates:
    // skinning with the true poses is 1.1 mm from this body-only truth); edges 15.4 %
    // against 3 % for skinning (the thesis: 8.7–13.3 %).
    assert!(get("joint_error_mm") < 20.0);
    assert!(get("silhouette_error_pct") < 0.5 * get("lbs_silhouette_error_pct"));
    assert!(get("vertex_rms_mm") < 35.0);
    assert!(get("vertex_rms_mm") < 1.25 * get("lbs_vertex_rms_mm"));
    assert!(get("edge_error_pct") < 20.0);
}

/// The pieces a user strings together around a capture (§2.5): the MakeHuman template with
/// its skirt decimated to ≈ 10k vertices (weights and texture coordinates carried over, the
/// vertices a fixed embedding in the rest mesh), and a template edit carried to a posed frame
/// by deformation transfer.
#[test]
fn a_decimated_textured_template_takes_an_edit_to_a_posed_frame() {
    use dynamic_shapes::core::mesh::{decimate, SkinWeights};
    use dynamic_shapes::core::studio::{GarmentParams, SkirtParams};
    use dynamic_shapes::template::DeformationTransfer;

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

/// Automatic first-frame initialisation (issue 12, "use it"): `initialise_pose` from one
/// frame's visual hull and contour rays only (no markers, no stereo points, no user
/// constraint), scored against the true pose and against the baseline that could have won
/// (the rest pose moved to the hull's centroid, then the same robust ellipsoid fit).
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
        let obs = FrameObservation::new(
            &cameras,
            &frame.masks(),
            &VisualHullParams::default(),
            &SilhouetteParams::default(),
        )
        .unwrap();
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

/// Automatic sizing (issue 12, "use it"): bone lengths and limb widths from the first second
/// of a performer whose proportions differ from the default by up to 10 % (the
/// `ellipsoid_fit` scenario's performer, fast motion frames 0…59 at 60 Hz, 8 cameras), from
/// what the tracker has (hull samples, contour rays): `size_performer` initialises frame 0,
/// tracks the next frames from the previous pose, and fits the 8 most varied frames together.
/// Against the baseline that could have won: no sizing (default proportions, 5 cm widths) at
/// the same tracked poses.
#[test]
fn sizing_from_the_first_second_beats_default_proportions() {
    use dynamic_shapes::template::{
        ellipsoid_scenario, pose_error, score_ellipsoids, size_performer,
        EllipsoidScenarioParams, EllipsoidScores, SizingParams,
    };
    let scenario = ellipsoid_scenario(&EllipsoidScenarioParams {
        cameras: 8,
        end_sites: true,
        frames: (0..60).collect(),
        points: 100,
        markers: 0,
        ..EllipsoidScenarioParams::default()
    })
    .unwrap();
    let model = &scenario.model;
    let obs: Vec<FrameObservation> = scenario
        .frames
        .iter()
        .map(|f| {
            FrameObservation::new(
                &scenario.cameras,
                &f.masks,
                &VisualHullParams::default(),
                &SilhouetteParams::default(),
            )
            .unwrap()
        })
        .collect();
    let mut params = SizingParams::default();
    if let Ok(m) = std::env::var("SIZING_TRACKER") {
        if m == "fit" {
            params.tracker = dynamic_shapes::template::SizingTracker::Fit;
        }
    }
    if std::env::var("SIZING_NOREINIT").is_ok() {
        params.reinitialise = false;
    }
    if std::env::var("SIZING_NOEXTRAP").is_ok() {
        params.extrapolate = false;
    }
    let t = Instant::now();
    let sizing = size_performer(model, &obs, &params).unwrap();
    let sizing_s = t.elapsed().as_secs_f64();
    // Tracking: every frame's bone direction error against the truth.
    let tracked_deg: Vec<f64> = sizing
        .tracked
        .iter()
        .zip(&scenario.frames)
        .map(|(s, f)| {
            pose_error(model.skeleton(), &s.theta, &f.truth.theta)
                .unwrap()
                .1
                .to_degrees()
        })
        .collect();
    println!("tracked deg per frame: {:?}", tracked_deg.iter().map(|d| d.round()).collect::<Vec<_>>());
    let limb_deg: Vec<f64> = sizing
        .tracked
        .iter()
        .zip(&scenario.frames)
        .map(|(s, f)| score_ellipsoids(model, s, &f.truth).unwrap().joint_angle_error_deg.round())
        .collect();
    println!("tracked limb deg per frame: {limb_deg:?}");
    let true_deg: Vec<f64> = scenario.frames.windows(2).map(|w| pose_error(model.skeleton(), &w[0].truth.theta, &w[1].truth.theta).unwrap().1.to_degrees()).collect();
    println!("true motion deg per frame: {:?}", true_deg.iter().map(|d| (d * 10.0).round() / 10.0).collect::<Vec<_>>());
    // The template tracker's poses at default proportions from the automatic first pose.
    let performer = dynamic_shapes::core::studio::procedural_performer(
        &dynamic_shapes::core::studio::ProceduralBodyParams::default(),
    )
    .unwrap();
    let template = Template::new(
        performer.template.clone(),
        performer.skeleton.clone(),
        performer.weights.clone(),
    )
    .unwrap();
    let t = Instant::now();
    let pose_model = dynamic_shapes::template::PoseModel::new(&template, &PoseParams::default()).unwrap();
    let pframes: Vec<_> = obs
        .iter()
        .map(|o| dynamic_shapes::template::PoseFrame { hull: &o.hull, rays: &o.rays, user: &[] })
        .collect();
    let first = sizing.init.as_ref().unwrap().theta().to_vec();
    let track = dynamic_shapes::template::track(&pose_model, &pframes, &first, None, &PoseParams::default()).unwrap();
    let track_s = t.elapsed().as_secs_f64();
    let tmpl_deg: Vec<f64> = track
        .poses
        .iter()
        .zip(&scenario.frames)
        .map(|(p, f)| {
            let s = model.initial_state(p, 0.05).unwrap();
            score_ellipsoids(model, &s, &f.truth).unwrap().joint_angle_error_deg.round()
        })
        .collect();
    println!("template tracker limb deg per frame ({track_s:.1} s): {tmpl_deg:?}");
    let t = Instant::now();
    let from_tracker = dynamic_shapes::template::size_from_poses(model, &obs, &track.poses, &params).unwrap();
    let tsized: Vec<EllipsoidScores> = from_tracker
        .fit
        .states
        .iter()
        .zip(&from_tracker.chosen)
        .map(|(s, &f)| score_ellipsoids(model, s, &scenario.frames[f].truth).unwrap())
        .collect();
    let tbase: Vec<EllipsoidScores> = from_tracker
        .chosen
        .iter()
        .map(|&f| score_ellipsoids(model, &from_tracker.tracked[f], &scenario.frames[f].truth).unwrap())
        .collect();
    let mean_of = |s: &[EllipsoidScores]| {
        let m = |g: fn(&EllipsoidScores) -> f64| mean(&s.iter().map(g).collect::<Vec<_>>());
        (
            m(|s| s.bone_length_error_mm),
            m(|s| s.width_error_mm),
            m(|s| s.joint_angle_error_deg),
        )
    };
    let sized: Vec<EllipsoidScores> = sizing
        .fit
        .states
        .iter()
        .zip(&sizing.chosen)
        .map(|(s, &f)| score_ellipsoids(model, s, &scenario.frames[f].truth).unwrap())
        .collect();
    let baseline: Vec<EllipsoidScores> = sizing
        .chosen
        .iter()
        .map(|&f| {
            let s = model
                .initial_state(&sizing.tracked[f].theta, params.init.half_width_m)
                .unwrap();
            score_ellipsoids(model, &s, &scenario.frames[f].truth).unwrap()
        })
        .collect();
    let (sl, sw, sd) = mean_of(&sized);
    let (bl, bw, bd) = mean_of(&baseline);
    println!(
        "tracked bone directions over {} frames: mean {:.1} deg, max {:.1} deg; chosen {:?}",
        tracked_deg.len(),
        mean(&tracked_deg),
        tracked_deg.iter().fold(0f64, |a, b| a.max(*b)),
        sizing.chosen
    );
    println!("re-initialised: {:?}", sizing.reinitialised);
    for &f in &sizing.chosen {
        let sc = |t: &[f64]| dynamic_shapes::template::initial_pose_score(model, &obs[f].hull, t, &params.init).unwrap();
        println!("frame {f}: score tracked {:.3} true {:.3}", sc(&sizing.tracked[f].theta), sc(&scenario.frames[f].truth.theta));
    }
    println!(
        "sizing: lengths {sl:.1} mm widths {sw:.1} mm directions {sd:.1} deg; default \
         proportions {bl:.1} / {bw:.1} / {bd:.1} ({sizing_s:.1} s)"
    );
    let (tl, tw, td) = mean_of(&tsized);
    let (ul, uw, ud) = mean_of(&tbase);
    println!(
        "sizing from the template tracker's poses: lengths {tl:.1} mm widths {tw:.1} mm directions {td:.1} deg; default \
         proportions {ul:.1} / {uw:.1} / {ud:.1} ({:.1} s)", t.elapsed().as_secs_f64()
    );
    assert!(sw < bw, "widths {sw} vs {bw}");
}
