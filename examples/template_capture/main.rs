//! Validation of template-silhouette (Vlasic 2010 thesis, Chapter 2) on the synthetic studio.
//!
//! The MakeHuman performer seen by a ring of 8 cameras 3.5 m away (§2.5.1), in several runs:
//! the protocol — the performer **in the skirt** (its template is the rest mesh with
//! the skirt's rest drape, as the thesis' scanned templates) in the exercise motion, the fast
//! motion and the real CMU 131_01 walk — and, for reference, the body alone in the exercise.
//! Per frame: the visual hull (§2.3.2) and the contour rays (§2.4.2); the skeleton tracked
//! through the hulls with the refinement term (§2.3.1, §2.3.3; the first frame's true pose
//! stands in for the user's fit of the first frame, no other user constraint); then
//! Algorithm 1 (§2.4.2). Scored against the performer's true posed mesh, against linear
//! blend skinning driven by the same estimated poses (`lbs_*`) and by the true poses
//! (`lbs_true_pose_*`). The legs inside the skirt are part of the template and of the truth
//! and are scored with the body (the silhouettes cannot see them: only the pose and the
//! Laplacian prior place them).
//!
//! Writes under `out/template_capture/`:
//! * `figure_2_7.png`: one frame of the first run, like the thesis' Figure 2-7 — template,
//!   visual hull, skinning with the estimated pose, the molded result, the truth.
//! * `vertex_error.png`: the same frame, skinning with the estimated pose and the molded
//!   result, each vertex coloured by its distance to the true vertex, with a colour bar (mm).
//! * `silhouette_error.png`: per-frame silhouette error (%) of the result and of skinning.
//! * `sequence.glb`: the first run's captured mesh sequence (glTF 2.0, morph-target
//!   animation), loadable in Blender or any glTF viewer.
//! * `figures.json`, `manifest.json`; progress on stderr; last stdout line one JSON object
//!   with per-run figures prefixed by the run's name and their mean over the skirt runs.
//!
//! `cargo run --release --example template_capture [-- --quick] [-- --out DIR]` (`--quick`:
//! 480 × 360 views, the body in 12 frames of the exercise and the skirt in 8; the full run:
//! 1600 × 1200 views, 100 frames per run).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)] // not library code

use std::time::Instant;

use clap::Parser;
use serde_json::{json, Map, Value};

use dynamic_shapes::core::camera::{Camera, Intrinsics, Rig};
use dynamic_shapes::core::math::{DVec3, Ray};
use dynamic_shapes::core::mesh::{save_gltf_animation, MeshSequence};
use dynamic_shapes::core::skeleton::{BvhParams, Motion, CMU_METRES_PER_UNIT};
use dynamic_shapes::core::stats::{mean, rms};
use dynamic_shapes::core::studio::{
    exercise_motion, fast_motion, makehuman_performer, play_bvh, preview, Capture, CaptureSpec,
    DeformationParams, ExerciseParams, FastMotionParams, FrameTruth, GarmentParams, Paint,
    Performer, PreviewPanel, RetargetParams, SkirtParams,
};
use dynamic_shapes::template::{
    capture_sequence, edge_error_pct, silhouette_error_pct, FrameObservation, PoseEditor,
    PoseModel, PoseParams, SequenceCapture, ShapeParams, SilhouetteParams, Template, UserRay,
    VisualHullParams,
};
use example_kit::plot::{error_colour, Chart, ColourBar, Series, Style};
use example_kit::{Goal, Headline, Run};

/// Vertex error at the top of `vertex_error.png`'s colour scale, mm.
const VERTEX_ERROR_MAX_MM: f64 = 50.0;
/// A vertex is pose-deforming when the studio's pose-driven displacement (muscles, joint
/// shapes) moves it at least this far in some frame of the run, m.
const DEFORMING_MIN_M: f64 = 0.003;

/// RMS distance between corresponding vertices (all, or those in `subset`), mm.
fn rms_mm(a: &[DVec3], b: &[DVec3], subset: Option<&[usize]>) -> f64 {
    let d: Vec<f64> = match subset {
        None => a.iter().zip(b).map(|(x, y)| x.distance(*y)).collect(),
        Some(s) => s.iter().map(|&i| a[i].distance(b[i])).collect(),
    };
    1e3 * rms(&d)
}

/// Every run takes every second frame of its motion.
const FRAME_STEP: usize = 2;

/// The motions of the protocol.
#[derive(Clone, Copy)]
enum MotionKind {
    Exercise,
    Fast,
    Walk,
}

impl MotionKind {
    fn name(self) -> &'static str {
        match self {
            MotionKind::Exercise => "exercise",
            MotionKind::Fast => "fast",
            MotionKind::Walk => "walk",
        }
    }

    /// The first frame a run takes: the exercise and the fast motion after their first
    /// second, the walk at its start.
    fn first_frame(self) -> usize {
        match self {
            MotionKind::Exercise => 40,
            MotionKind::Fast => 30,
            MotionKind::Walk => 0,
        }
    }
}

/// One run of the protocol: the performer with or without its skirt in one motion.
struct RunSpec {
    skirt: bool,
    motion: MotionKind,
    frames: usize,
}

impl RunSpec {
    /// The run's name, the prefix of its figures: `skirt_walk`, `body_exercise`, ….
    fn name(&self) -> String {
        let who = if self.skirt { "skirt" } else { "body" };
        format!("{who}_{}", self.motion.name())
    }
}

/// What a run leaves for the pictures.
struct Captured {
    performer: Performer,
    template: Template,
    truths: Vec<FrameTruth>,
    observations: Vec<FrameObservation>,
    result: SequenceCapture,
    sil: Vec<f64>,
    sil_lbs: Vec<f64>,
    frame_time_s: f64,
}

fn performer(skirt: bool) -> Result<Performer, Box<dyn std::error::Error>> {
    // With the skirt the hip flap is off (DeformationParams::garment: it only distorts the
    // thighs the skirt collides with); the pose-driven muscles stay on in both.
    let params = if skirt {
        DeformationParams::default()
            .with_flap(None)
            .with_garment(Some(GarmentParams::Skirt(SkirtParams::default())))
    } else {
        DeformationParams::default()
    };
    Ok(makehuman_performer(
        example_kit::data_path("makehuman")?,
        &params,
    )?)
}

fn motion(kind: MotionKind, performer: &Performer) -> Result<Motion, Box<dyn std::error::Error>> {
    let sk = &performer.skeleton;
    Ok(match kind {
        MotionKind::Exercise => exercise_motion(sk, &ExerciseParams::default())?,
        MotionKind::Fast => fast_motion(sk, &FastMotionParams::default())?,
        MotionKind::Walk => {
            play_bvh(
                example_kit::data_path("mocap-cmu/131_01.bvh")?,
                &BvhParams {
                    metres_per_unit: CMU_METRES_PER_UNIT,
                },
                sk,
                1.0 / 60.0,
                &RetargetParams::default(),
            )?
            .motion
        }
    })
}

fn capture_run(
    run: &mut Run,
    spec: &RunSpec,
    (width, height): (u32, u32),
    figures: &mut Map<String, Value>,
) -> Result<Captured, Box<dyn std::error::Error>> {
    let performer = performer(spec.skirt)?;
    let motion = motion(spec.motion, &performer)?;
    let (name, first) = (spec.name(), spec.motion.first_frame());
    let root = performer
        .skeleton
        .forward_kinematics(motion.frame(first))?
        .joint_positions()[0];
    let k = Intrinsics::from_horizontal_fov(55f64.to_radians(), width, height)?;
    let rig = Rig::ring(8, 3.5, root.y + 0.15, root, DVec3::Y, k)?;
    let cameras = rig.cameras.clone();
    let capture_spec = CaptureSpec::masks_only(rig).with_frame_rate_hz(1.0 / motion.frame_time_s);
    let capture = Capture::new(&performer, &motion, capture_spec)?;
    let template = Template::new(
        performer.template.clone(),
        performer.skeleton.clone(),
        performer.weights.clone(),
    )?;

    // Observations (§2.3.2, §2.4.2).
    let stage = run.stage(
        &format!("{name}: capture and observe"),
        Some(spec.frames as u64),
    );
    let (mut truths, mut masks, mut observations) = (vec![], vec![], vec![]);
    let mut observe_s = 0.0;
    let last = first + FRAME_STEP * spec.frames;
    if last > motion.frame_count() {
        return Err(format!(
            "{}: {} frames from {} every {} pass the motion's {}",
            name,
            spec.frames,
            first,
            FRAME_STEP,
            motion.frame_count()
        )
        .into());
    }
    for f in capture.frames_stepped(first..last, FRAME_STEP) {
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
        truths.push(f.truth);
        stage.inc(1);
    }
    stage.finish(format!("{} frames", truths.len()));
    let n = truths.len() as f64;

    // §2.3 then §2.4; the first frame's true pose stands in for the user's fit of frame 0.
    let stage = run.stage(&format!("{name}: pose and shape"), None);
    let params = PoseParams::default();
    let result = capture_sequence(
        &template,
        &observations,
        &truths[0].theta,
        &[],
        &params,
        &ShapeParams::default(),
    )?;
    stage.finish(format!(
        "pose {:.2} s, shape {:.2} s per frame",
        result.pose_seconds / n,
        result.shape_seconds / n
    ));
    let reoptimise_ms = reoptimise_ms(&template, &observations, &result, &cameras[0], &params)?;

    // Scores.
    let stage = run.stage(&format!("{name}: score"), Some(spec.frames as u64));
    let sk = template.skeleton();
    let skirt: Vec<usize> = performer.garment_vertices().collect();
    let body: Vec<usize> = (0..performer.garment_vertices().start).collect();
    let deforming: Vec<usize> = body
        .iter()
        .copied()
        .filter(|&v| {
            truths
                .iter()
                .any(|t| t.posed.pose_displacement[v].length() >= DEFORMING_MIN_M)
        })
        .collect();
    let (mut joint, mut sil, mut sil_lbs, mut edge) = (vec![], vec![], vec![], vec![]);
    // Per vertex subset (all, skirt, body, pose-deforming): result, LBS same poses, LBS true.
    let subsets: [(&str, Option<&[usize]>); 4] = [
        ("", None),
        ("skirt_", Some(&skirt)),
        ("body_", Some(&body)),
        ("deforming_", Some(&deforming)),
    ];
    let mut scores = vec![[vec![], vec![], vec![]]; subsets.len()];
    for (t, truth) in truths.iter().enumerate() {
        let true_v = &truth.posed.true_vertices;
        let est = sk
            .forward_kinematics(&result.poses.poses[t])?
            .joint_positions();
        let tru = sk.forward_kinematics(&truth.theta)?.joint_positions();
        joint.push(
            1e3 * est
                .iter()
                .zip(&tru)
                .map(|(a, b)| (*a - *b).length())
                .sum::<f64>()
                / est.len() as f64,
        );
        let lbs = template.skin(&result.poses.poses[t])?;
        let lbs_true = template.skin(&truth.theta)?;
        for (s, (_, subset)) in subsets.iter().enumerate() {
            if subset.is_some_and(|v| v.is_empty()) {
                continue;
            }
            scores[s][0].push(rms_mm(&result.shapes.frames[t], true_v, *subset));
            scores[s][1].push(rms_mm(&lbs, true_v, *subset));
            scores[s][2].push(rms_mm(&lbs_true, true_v, *subset));
        }
        let molded = template.mesh_with(result.shapes.frames[t].clone());
        sil.push(mean(&silhouette_error_pct(&molded, &cameras, &masks[t])?));
        sil_lbs.push(mean(&silhouette_error_pct(
            &template.mesh_with(lbs),
            &cameras,
            &masks[t],
        )?));
        edge.push(edge_error_pct(template.mesh(), &result.shapes.frames[t])?);
        stage.inc(1);
    }
    stage.finish("");
    let key = |k: &str| format!("{name}_{k}");
    let mut put = |k: &str, v: Value| {
        figures.insert(key(k), v);
    };
    put("frames", json!(truths.len()));
    put("skirt", json!(spec.skirt));
    put("joint_error_mm", json!(mean(&joint)));
    for (s, (prefix, _)) in subsets.iter().enumerate() {
        if scores[s][0].is_empty() {
            continue;
        }
        put(
            &format!("{prefix}vertex_rms_mm"),
            json!(mean(&scores[s][0])),
        );
        put(
            &format!("lbs_{prefix}vertex_rms_mm"),
            json!(mean(&scores[s][1])),
        );
        put(
            &format!("lbs_true_pose_{prefix}vertex_rms_mm"),
            json!(mean(&scores[s][2])),
        );
    }
    put("deforming_vertices", json!(deforming.len()));
    put("silhouette_error_pct", json!(mean(&sil)));
    put("lbs_silhouette_error_pct", json!(mean(&sil_lbs)));
    put("edge_error_pct", json!(mean(&edge)));
    put("observe_s_per_frame", json!(observe_s / n));
    put("pose_s_per_frame", json!(result.pose_seconds / n));
    put("shape_s_per_frame", json!(result.shape_seconds / n));
    put("reoptimise_ms", json!(reoptimise_ms));
    Ok(Captured {
        performer,
        template,
        truths,
        observations,
        result,
        sil,
        sil_lbs,
        frame_time_s: motion.frame_time_s * FRAME_STEP as f64,
    })
}

/// A user correction (§2.3.3, Figure 2-4): the left wrist of the middle frame dragged 5 cm
/// up in one camera's view and the frame re-optimised at once; the time of that, ms.
fn reoptimise_ms(
    template: &Template,
    observations: &[FrameObservation],
    result: &SequenceCapture,
    camera: &Camera,
    params: &PoseParams,
) -> Result<f64, Box<dyn std::error::Error>> {
    let sk = template.skeleton();
    let model = PoseModel::new(template, params)?;
    let poses = &result.poses.poses;
    let mut editor = PoseEditor::new(&model, observations, poses.clone(), params.clone())?;
    let mid = poses.len() / 2;
    let wrist = sk.joint_index("l_wrist").ok_or("no l_wrist")?;
    let q = sk.forward_kinematics(&poses[mid])?.joint_positions()[wrist];
    let eye = camera.centre();
    let ray = Ray::new(eye, (q + DVec3::new(0.0, 0.05, 0.0) - eye).normalize());
    let t0 = Instant::now();
    editor.add_user_ray(mid, UserRay { joint: wrist, ray })?;
    let ms = 1e3 * t0.elapsed().as_secs_f64();
    editor.remove_user_ray(mid, 0)?;
    Ok(ms)
}

fn pictures(run: &mut Run, c: &Captured, name: &str) -> Result<(), Box<dyn std::error::Error>> {
    let template = &c.template;
    let t = c.truths.len() / 2;
    let lbs_mesh = template.mesh_with(template.skin(&c.result.poses.poses[t])?);
    let result = template.mesh_with(c.result.shapes.frames[t].clone());
    let truth_mesh = c.truths[t].true_mesh(&c.performer);
    let grey = Paint::Flat([180, 180, 180]);
    let panels = [
        PreviewPanel {
            mesh: template.mesh(),
            paint: grey,
        },
        PreviewPanel {
            mesh: c.observations[t].hull.polygon(),
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
        &format!("{name}, frame {t}: like Vlasic 2010 Figure 2-7"),
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
    let truth = &c.truths[t].posed.true_vertices;
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
        &format!("{name}, frame {t}: vertex error against the truth"),
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
        format!("Silhouette error per frame, {name} (Table 2.1 measure)"),
        "frame",
        "silhouette error (%)",
    )
    .with(Series::new(
        "result",
        [40, 90, 200],
        Style::LineMarkers,
        pts(&c.sil),
    ))
    .with(Series::new(
        "LBS, same poses",
        [220, 120, 40],
        Style::Dashed,
        pts(&c.sil_lbs),
    ));
    run.save_picture(
        "silhouette_error.png",
        &chart.draw()?,
        "Silhouette error per frame: the molded result against skinning with the same poses",
    )?;
    let glb = run.path("sequence.glb");
    save_gltf_animation(
        &glb,
        &MeshSequence {
            faces: &template.mesh().faces,
            frames: &c.result.shapes.frames,
            frame_time_s: c.frame_time_s,
            uvs: None,
            name,
        },
    )?;
    Ok(())
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = example_kit::cli::Args::parse();
    let quick = args.common.quick;
    let size = if quick { (480, 360) } else { (1600, 1200) };
    let n = if quick { 12 } else { 100 };
    // The protocol (skirt) first, then the body alone for reference.
    let run_spec = |skirt, motion, frames| RunSpec {
        skirt,
        motion,
        frames,
    };
    let runs: Vec<RunSpec> = if quick {
        vec![
            run_spec(false, MotionKind::Exercise, n),
            run_spec(true, MotionKind::Exercise, 8),
        ]
    } else {
        vec![
            run_spec(true, MotionKind::Exercise, n),
            run_spec(true, MotionKind::Fast, n),
            run_spec(true, MotionKind::Walk, n),
            run_spec(false, MotionKind::Exercise, n),
        ]
    };
    let mut run = Run::start(
        "template_capture",
        &args.common,
        &format!(
            "MakeHuman with and without its skirt, 8 cameras at {}×{}, runs: {}: pose \
             tracking in the visual hulls, then Laplacian molding to the silhouettes (Vlasic \
             2010 Ch. 2)",
            size.0,
            size.1,
            runs.iter()
                .map(RunSpec::name)
                .collect::<Vec<_>>()
                .join(", ")
        ),
    )?;
    let mut figures = Map::new();
    for (i, spec) in runs.iter().enumerate() {
        let captured = capture_run(&mut run, spec, size, &mut figures)?;
        if i == 0 {
            let stage = run.stage("pictures", None);
            pictures(&mut run, &captured, &spec.name())?;
            stage.finish("");
        }
    }
    // The mean over the skirt runs (the protocol), each figure the runs report.
    let skirt_runs: Vec<String> = runs.iter().filter(|r| r.skirt).map(RunSpec::name).collect();
    let mut averaged = Map::new();
    for (k, v) in &figures {
        let Some(rest) = skirt_runs
            .iter()
            .find_map(|r| k.strip_prefix(&format!("{r}_")))
        else {
            continue;
        };
        if averaged.contains_key(rest) || !v.is_f64() {
            continue;
        }
        let vals: Vec<f64> = skirt_runs
            .iter()
            .filter_map(|r| figures.get(&format!("{r}_{rest}"))?.as_f64())
            .collect();
        averaged.insert(rest.to_string(), json!(mean(&vals)));
    }
    figures.extend(averaged);
    figures.insert("image_width_px".into(), json!(size.0));
    figures.insert("image_height_px".into(), json!(size.1));
    figures.insert("user_constraints".into(), json!(0));
    figures.insert("skirt_runs".into(), json!(skirt_runs));
    figures.insert("peak_rss_mb".into(), json!(example_kit::peak_rss_mb()));
    for h in [
        Headline::new("joint_error_mm", "joint error (skirt runs)", "mm").goal(Goal::AtMost(20.0)),
        Headline::new("silhouette_error_pct", "silhouette error", "%").goal(Goal::AtMost(5.0)),
        Headline::new("edge_error_pct", "edge error", "%").goal(Goal::AtMost(8.0)),
        Headline::new("vertex_rms_mm", "vertex RMS error", "mm").goal(Goal::AtMost(15.0)),
        Headline::new("lbs_vertex_rms_mm", "LBS (same poses) vertex RMS", "mm"),
        Headline::new("skirt_vertex_rms_mm", "skirt vertex RMS", "mm"),
        Headline::new(
            "lbs_skirt_vertex_rms_mm",
            "LBS (same poses) skirt RMS",
            "mm",
        ),
        Headline::new("pose_s_per_frame", "pose time per frame", "s").goal(Goal::AtMost(0.3)),
        Headline::new("shape_s_per_frame", "shape time per frame", "s").goal(Goal::AtMost(0.3)),
        Headline::new("reoptimise_ms", "one re-optimisation", "ms").goal(Goal::AtMost(100.0)),
    ] {
        run.headline(h);
    }
    run.finish(Value::Object(figures))?;
    Ok(())
}
