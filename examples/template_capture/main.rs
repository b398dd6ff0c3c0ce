//! Validation of template-silhouette (Vlasic 2010 thesis, Chapter 2) on the synthetic studio.
//!
//! The MakeHuman performer (body only: the skirt is not validated yet) in the studio's
//! exercise motion, seen by a ring of 8 cameras 3.5 m away (§2.5.1). Per frame: the visual hull
//! (§2.3.2) and the contour rays (§2.4.2); the skeleton tracked through the hulls with the
//! refinement term (§2.3.1, §2.3.3; the first frame's true pose stands in for the user's fit of
//! the first frame, no other user constraint); then Algorithm 1 (§2.4.2). Scored against the
//! performer's true posed mesh, against linear blend skinning driven by the same estimated
//! poses (`lbs_*`) and by the true poses (`lbs_true_pose_*`).
//!
//! Writes under `out/template_capture/`:
//! * `figure_2_7.png`: one frame, like the thesis' Figure 2-7 — template, visual hull,
//!   skinning with the estimated pose, the molded result, the truth.
//! * `vertex_error.png`: the same frame, skinning with the estimated pose and the molded
//!   result, each vertex coloured by its distance to the true vertex, with a colour bar (mm).
//! * `silhouette_error.png`: per-frame silhouette error (%) of the result and of skinning.
//! * `figures.json`, `manifest.json`; progress on stderr; last stdout line one JSON object.
//!
//! `cargo run --release --example template_capture [-- --quick] [-- --out DIR]` (`--quick`:
//! 480 × 360 views, 12 frames; the full run: 1600 × 1200 views, 100 frames).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)] // not library code

use std::time::Instant;

use clap::Parser;
use serde_json::json;

use dynamic_shapes::core::camera::{Intrinsics, Rig};
use dynamic_shapes::core::math::{DVec3, Ray};
use dynamic_shapes::core::stats::{mean, rms};
use dynamic_shapes::core::studio::{
    exercise_motion, makehuman_performer, preview, Capture, CaptureSpec, DeformationParams,
    ExerciseParams, Paint, PreviewPanel,
};
use dynamic_shapes::template::{
    capture_sequence, edge_error_pct, silhouette_error_pct, FrameObservation, PoseEditor,
    PoseModel, PoseParams, ShapeParams, SilhouetteParams, Template, UserRay, VisualHullParams,
};
use example_kit::plot::{error_colour, Chart, ColourBar, Series, Style};
use example_kit::{Goal, Headline, Run};

/// Vertex error at the top of `vertex_error.png`'s colour scale, mm.
const VERTEX_ERROR_MAX_MM: f64 = 50.0;

/// RMS distance between corresponding vertices, mm.
fn rms_mm(a: &[DVec3], b: &[DVec3]) -> f64 {
    let d: Vec<f64> = a.iter().zip(b).map(|(x, y)| x.distance(*y)).collect();
    1e3 * rms(&d)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = example_kit::cli::Args::parse();
    let quick = args.common.quick;
    let (width, height, frame_count) = if quick {
        (480, 360, 12)
    } else {
        (1600, 1200, 100)
    };
    let mut run = Run::start(
        "template_capture",
        &args.common,
        &format!(
            "MakeHuman (body) in the exercise motion, 8 cameras at {width}×{height}, \
             {frame_count} frames: pose tracking in the visual hulls, then Laplacian molding \
             to the silhouettes (Vlasic 2010 Ch. 2)"
        ),
    )?;

    let performer = makehuman_performer(
        example_kit::data_path("makehuman")?,
        &DeformationParams::default(),
    )?;
    let motion = exercise_motion(&performer.skeleton, &ExerciseParams::default())?;
    let root = performer
        .skeleton
        .forward_kinematics(motion.frame(0))?
        .joint_positions()[0];
    let k = Intrinsics::from_horizontal_fov(55f64.to_radians(), width, height)?;
    let rig = Rig::ring(8, 3.5, root.y + 0.15, root, DVec3::Y, k)?;
    let cameras = rig.cameras.clone();
    let spec = CaptureSpec::masks_only(rig).with_frame_rate_hz(1.0 / motion.frame_time_s);
    let capture = Capture::new(&performer, &motion, spec)?;
    let template = Template::new(
        performer.template.clone(),
        performer.skeleton.clone(),
        performer.weights.clone(),
    )?;
    let sk = template.skeleton();

    // Observations (§2.3.2, §2.4.2).
    let stage = run.stage("capture and observe", Some(frame_count as u64));
    let (mut frames, mut masks, mut observations) = (vec![], vec![], vec![]);
    let mut observe_s = 0.0;
    for f in capture.frames_stepped(40..40 + 2 * frame_count, 2) {
        let f = f?;
        let m = f.masks();
        let t0 = Instant::now();
        observations.push(FrameObservation::new(
            &cameras,
            &m,
            &VisualHullParams::default(),
            &SilhouetteParams::default(),
        )?);
        observe_s += t0.elapsed().as_secs_f64();
        masks.push(m);
        frames.push(f);
        stage.inc(1);
    }
    stage.finish(format!("{} frames", frames.len()));
    let n = frames.len() as f64;

    // §2.3 then §2.4; the first frame's true pose stands in for the user's fit of frame 0.
    let stage = run.stage("pose and shape", None);
    let params = PoseParams::default();
    let result = capture_sequence(
        &template,
        &observations,
        &frames[0].truth.theta,
        &[],
        &params,
        &ShapeParams::default(),
    )?;
    let (poses, seq) = (&result.poses, &result.shapes);
    let (pose_s, shape_s) = (result.pose_seconds, result.shape_seconds);
    stage.finish(format!(
        "pose {:.2} s, shape {:.2} s per frame",
        pose_s / n,
        shape_s / n
    ));

    // A user correction (§2.3.3, Figure 2-4): the left wrist of the middle frame dragged 5 cm
    // up in camera 0's view, the frame re-optimised at once; then the ray is removed again.
    let model = PoseModel::new(&template, &params)?;
    let mut editor = PoseEditor::new(&model, &observations, poses.poses.clone(), params.clone())?;
    let mid = frames.len() / 2;
    let wrist = sk.joint_index("l_wrist").ok_or("no l_wrist")?;
    let q = sk.forward_kinematics(&poses.poses[mid])?.joint_positions()[wrist];
    let eye = cameras[0].centre();
    let ray = Ray::new(eye, (q + DVec3::new(0.0, 0.05, 0.0) - eye).normalize());
    let t0 = Instant::now();
    editor.add_user_ray(mid, UserRay { joint: wrist, ray })?;
    let reoptimise_ms = 1e3 * t0.elapsed().as_secs_f64();
    editor.remove_user_ray(mid, 0)?;

    // Scores.
    let stage = run.stage("score", Some(frames.len() as u64));
    let (mut joint, mut method, mut lbs_est, mut lbs_true) = (vec![], vec![], vec![], vec![]);
    let (mut sil, mut sil_lbs, mut edge) = (vec![], vec![], vec![]);
    for (t, f) in frames.iter().enumerate() {
        let truth = &f.truth.posed.true_vertices;
        let est = sk.forward_kinematics(&poses.poses[t])?.joint_positions();
        let tru = sk.forward_kinematics(&f.truth.theta)?.joint_positions();
        joint.push(
            1e3 * est
                .iter()
                .zip(&tru)
                .map(|(a, b)| (*a - *b).length())
                .sum::<f64>()
                / est.len() as f64,
        );
        let lbs = template.skin(&poses.poses[t])?;
        method.push(rms_mm(&seq.frames[t], truth));
        lbs_est.push(rms_mm(&lbs, truth));
        lbs_true.push(rms_mm(&template.skin(&f.truth.theta)?, truth));
        let result = template.mesh_with(seq.frames[t].clone());
        sil.push(mean(&silhouette_error_pct(&result, &cameras, &masks[t])?));
        sil_lbs.push(mean(&silhouette_error_pct(
            &template.mesh_with(lbs),
            &cameras,
            &masks[t],
        )?));
        edge.push(edge_error_pct(template.mesh(), &seq.frames[t])?);
        stage.inc(1);
    }
    stage.finish("");

    // Pictures.
    let stage = run.stage("pictures", None);
    let t = frames.len() / 2;
    let lbs_mesh = template.mesh_with(template.skin(&poses.poses[t])?);
    let result = template.mesh_with(seq.frames[t].clone());
    let truth_mesh = frames[t].truth.true_mesh(&performer);
    let grey = Paint::Flat([180, 180, 180]);
    let panels = [
        PreviewPanel {
            mesh: template.mesh(),
            paint: grey,
        },
        PreviewPanel {
            mesh: observations[t].hull.polygon(),
            paint: Paint::Flat([150, 170, 200]),
        },
        PreviewPanel {
            mesh: &lbs_mesh,
            paint: Paint::Flat([220, 160, 120]),
        },
        PreviewPanel {
            mesh: &result,
            paint: Paint::Flat([120, 170, 220]),
        },
        PreviewPanel {
            mesh: &truth_mesh,
            paint: grey,
        },
    ];
    let img = preview(&panels, 320)?;
    let img = example_kit::plot::titled(
        &img,
        &format!("Frame {t}: like Vlasic 2010 Figure 2-7"),
        Some(
            "left to right: template, visual hull (8 silhouettes), LBS with the tracked pose, \
             molded result, truth",
        ),
    )?;
    run.save_picture(
        "figure_2_7.png",
        &img,
        "One frame: template, visual hull, skinning with the estimated pose, the molded result, the truth",
    )?;
    // The same frame coloured by each vertex's distance to the truth.
    let truth = &frames[t].truth.posed.true_vertices;
    let colours = |v: &[DVec3]| -> Vec<[u8; 3]> {
        v.iter()
            .zip(truth)
            .map(|(a, b)| error_colour(Some(1e3 * a.distance(*b)), VERTEX_ERROR_MAX_MM))
            .collect()
    };
    let (lbs_colours, result_colours) = (colours(&lbs_mesh.vertices), colours(&result.vertices));
    let img = preview(
        &[
            PreviewPanel {
                mesh: &lbs_mesh,
                paint: Paint::PerVertex(&lbs_colours),
            },
            PreviewPanel {
                mesh: &result,
                paint: Paint::PerVertex(&result_colours),
            },
        ],
        400,
    )?;
    let ramp = |x: f64| error_colour(Some(x * VERTEX_ERROR_MAX_MM), VERTEX_ERROR_MAX_MM);
    let img = example_kit::plot::with_colour_bar(
        &img,
        &ColourBar {
            label: "distance to the true vertex (mm)",
            min: 0.0,
            max: VERTEX_ERROR_MAX_MM,
            ramp: &ramp,
            note: Some("top: ≥ 50 mm"),
        },
    )?;
    let img = example_kit::plot::titled(
        &img,
        &format!("Frame {t}: vertex error against the truth"),
        Some("left: LBS with the tracked pose; right: the molded result"),
    )?;
    run.save_picture(
        "vertex_error.png",
        &img,
        "The frame of figure_2_7.png, each vertex coloured by its distance to the true vertex \
         (colour bar in mm): skinning with the tracked pose (left) and the molded result \
         (right)",
    )?;
    let pts = |v: &[f64]| v.iter().enumerate().map(|(i, e)| (i as f64, *e)).collect();
    let chart = Chart::new(
        "Silhouette error per frame (Table 2.1 measure)",
        "frame",
        "silhouette error (%)",
    )
    .with(Series::new(
        "result",
        [40, 90, 200],
        Style::LineMarkers,
        pts(&sil),
    ))
    .with(Series::new(
        "LBS, same poses",
        [220, 120, 40],
        Style::Dashed,
        pts(&sil_lbs),
    ));
    run.save_picture(
        "silhouette_error.png",
        &chart.draw()?,
        "Silhouette error per frame: the molded result against skinning with the same poses",
    )?;
    stage.finish("");

    for h in [
        Headline::new("joint_error_mm", "joint error", "mm").goal(Goal::AtMost(20.0)),
        Headline::new("silhouette_error_pct", "silhouette error", "%").goal(Goal::AtMost(5.0)),
        Headline::new("edge_error_pct", "edge error", "%").goal(Goal::AtMost(8.0)),
        Headline::new("vertex_rms_mm", "vertex RMS error", "mm").goal(Goal::AtMost(15.0)),
        Headline::new("lbs_vertex_rms_mm", "LBS (same poses) vertex RMS", "mm"),
        Headline::new("pose_s_per_frame", "pose time per frame", "s").goal(Goal::AtMost(0.3)),
        Headline::new("shape_s_per_frame", "shape time per frame", "s").goal(Goal::AtMost(0.3)),
        Headline::new("reoptimise_ms", "one re-optimisation", "ms").goal(Goal::AtMost(100.0)),
    ] {
        run.headline(h);
    }
    run.finish(json!({
        "frames": frames.len(),
        "image_width_px": width,
        "image_height_px": height,
        "joint_error_mm": mean(&joint),
        "vertex_rms_mm": mean(&method),
        "lbs_vertex_rms_mm": mean(&lbs_est),
        "lbs_true_pose_vertex_rms_mm": mean(&lbs_true),
        "silhouette_error_pct": mean(&sil),
        "lbs_silhouette_error_pct": mean(&sil_lbs),
        "edge_error_pct": mean(&edge),
        "observe_s_per_frame": observe_s / n,
        "pose_s_per_frame": pose_s / n,
        "shape_s_per_frame": shape_s / n,
        "reoptimise_ms": reoptimise_ms,
        "user_constraints": 0,
    }))?;
    Ok(())
}
