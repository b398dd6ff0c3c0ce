//! The synthetic capture studio end to end: the MakeHuman performer walks the CMU walk
//! (`mocap-cmu/131_01.bvh`, retargeted), an 8-camera ring at 1600×1200 captures the frame of
//! largest non-skinning deformation under the 1,200-light dome of Vlasic thesis §3.2.1, and a
//! contact sheet shows for every camera: silhouette, depth, normals, shading (with cast
//! shadows) and the distance between the true surface and linear blend skinning coloured on
//! the mesh (the part of the deformation no skinning method can reach).
//!
//! Writes under `out/studio/`: `contact_sheet.png` (each camera cropped to its silhouette; rows: silhouette, depth, normals, shaded,
//! LBS-vs-truth; one column per camera) and full-size `cam0_*.png` pictures (the depth as a
//! 16-bit PNG in mm). Timings (medians after a warm-up): `raster_ms_per_view` (silhouette +
//! depth + normals of the posed performer at 1600×1200, over the 8 views),
//! `shade_ms_per_view_shadowed` (dome with per-vertex shadows at 1024×1024, visibility
//! excluded: it is computed once per frame for all cameras; the shadow rays of the
//! vertices one view sees are reported as `visibility_ms_per_view`), `fk_jacobian_us` (FK +
//! positional Jacobians of the 42-DOF skeleton with 18 attached points).
//!
//! The performers' non-skinning deformation over the studio's motions: the largest
//! |truth − LBS| of the MakeHuman performer over the range of motion
//! (`rom_max_nonskinning_mm`, with its cost `nonskinning_ms_per_frame`), the fast motion
//! (`fast_max_nonskinning_mm`) and the MakeHuman walk (`walk1_*`), and of the procedural
//! performer (`procedural_*`); `nonskinning_pose.png`, the MakeHuman body in a test pose
//! (elbow, knee, hip and shoulder flexed) coloured by |truth − LBS|, front and side.
//!
//! The free exercise (`exercise_range_coverage_min`, `exercise_max_pose_share`, against the
//! range of motion's `rom_max_pose_share`) and every effect of the ground truth, on the
//! performer with all of them on (pose-driven shapes, hip flap, skirt, wrinkles), over the
//! CMU walk and the exercise: per effect (`pose_deform`, `dynamic`, `wrinkle`) the largest
//! displacement and the most vertices moved more than 2, 5 and 10 mm in one frame
//! (`{walk,exercise}_{effect}_*`), `skirt_hem_lag_max_mm`, `wrinkle_amplitude_mm`,
//! `deform_ms_per_frame` (posing with every effect plus the render-time refinement, one
//! core) and `raster_fine_ms_per_view` (the refined surface in the 8 views). Pictures:
//! `effects.png` (one panel per effect), `skirt_swing.png` (skinned against simulated skirt,
//! from the side), `wrinkle_closeup.png` (normal maps of the elbow crease with and without
//! the wrinkles).
//!
//! `cargo run --release --example studio [-- --quick] [-- --out DIR]` (`--quick`: 400×300
//! views, the first 90 frames of the walk, fewer repetitions). Last stdout line: one JSON
//! object of figures.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)] // not library code

mod contact_sheet;
mod effects;

use contact_sheet::write_pictures;
use effects::{
    deformation_figures, effect_figures, effects_picture, exercise_figures, full_deformation,
    pose_picture, posed_at, skirt_picture, wrinkle_closeup,
};

use std::time::Instant;

use clap::Parser;
use dynamic_shapes::core::camera::{Camera, Intrinsics, Rig};
use dynamic_shapes::core::math::DVec3;
use dynamic_shapes::core::mesh::{MeshQuery, TriMesh};
use dynamic_shapes::core::raster::{Buffers, RenderParams, RenderedView};
use dynamic_shapes::core::skeleton::{
    AttachedPoint, BvhParams, ForwardKinematics, Motion, Skeleton, CMU_METRES_PER_UNIT,
};
use dynamic_shapes::core::stats::median;
use dynamic_shapes_studio::shading::{
    dome_lights, shade, vertices_seen, Albedo, DomeParams, LightVisibility, Shadows,
};
use dynamic_shapes_studio::{
    makehuman_performer, play_bvh, Capture, CaptureLighting, CaptureSpec, DeformationParams,
    RetargetParams,
};
use example_kit::{data_path, Goal, Headline, Run};
use nalgebra::DMatrix;
use serde_json::json;

pub(crate) type AnyResult<T> = Result<T, Box<dyn std::error::Error>>;

/// Capture frame rate, Hz (Vlasic thesis §2.5.1: 25 FPS).
const FRAME_RATE_HZ: f64 = 25.0;
/// Cameras in the ring (Vlasic thesis §2.5.1: "a ring of eight cameras").
const CAMERAS: usize = 8;
/// Ring radius, m: a 1.8 m body fills ~75 % of the image height from 3 m with the focal length
/// below.
const RING_RADIUS_M: f64 = 3.0;
/// Height of the cameras above the centre of the body's bounding box (they look slightly
/// down, as in Vlasic thesis §2.5.1), m.
const RING_HEIGHT_ABOVE_M: f64 = 0.3;
/// Focal length of the full-size 1600×1200 cameras, px.
const FOCAL_PX: f64 = 1500.0;
/// Frames of the exercise whose effects `--quick` measures (30 s at 30 fps).
const QUICK_EXERCISE_FRAMES: usize = 900;
/// Frames of the walk in `--quick` mode.
const QUICK_FRAMES: usize = 90;
/// Attached points of the Jacobian timing (the sensor count of Vlasic thesis §4.2).
const JACOBIAN_POINTS: usize = 18;

/// Median of the wall times (ms) of `reps` runs of `f` after one warm-up.
fn median_ms(reps: usize, mut f: impl FnMut() -> AnyResult<()>) -> AnyResult<f64> {
    f()?;
    let mut t = Vec::with_capacity(reps);
    for _ in 0..reps {
        let s = Instant::now();
        f()?;
        t.push(s.elapsed().as_secs_f64() * 1e3);
    }
    Ok(median(&t))
}

/// The synthetic capture studio end to end: the MakeHuman performer walking CMU 131_01 seen
/// by an 8-camera ring, with timings and the size of its non-skinning deformation.
#[derive(Parser)]
struct Args {
    #[command(flatten)]
    common: example_kit::Common,
}

fn main() -> AnyResult<()> {
    let start = Instant::now();
    let args = Args::parse();
    let quick = args.common.quick;
    let (w, h) = if quick { (400, 300) } else { (1600, 1200) };
    let mut run = Run::start(
        "studio",
        &args.common,
        &format!(
            "The synthetic capture studio: the MakeHuman performer walks the CMU 131_01 motion \
             capture (retargeted{}), an 8-camera ring at {w}×{h} captures the frame of largest \
             non-skinning deformation under a 1,200-light dome, with rasteriser, shading and \
             kinematics timings; then the size of the deformation no skinning reaches, over the \
             studio's motions and in one test pose.",
            if quick { ", first 90 frames" } else { "" }
        ),
    )?;
    let out = run.out().to_path_buf();
    let out = out.as_path();
    let stage = run.stage("performer", None);

    let mh = data_path("makehuman/base.obj")?;
    let performer = makehuman_performer(
        mh.parent().ok_or("data path has a parent")?,
        &DeformationParams::default(),
    )?;
    stage.println(format!(
        "MakeHuman performer, {} vertices, {} DOFs",
        performer.vertex_count(),
        performer.skeleton.dof_count()
    ));
    let walk = play_bvh(
        data_path("mocap-cmu/131_01.bvh")?,
        &BvhParams {
            metres_per_unit: CMU_METRES_PER_UNIT,
        },
        &performer.skeleton,
        1.0 / FRAME_RATE_HZ,
        &RetargetParams::default(),
    )?;
    let mut motion = walk.motion;
    if quick && motion.frame_count() > QUICK_FRAMES {
        motion = Motion::new(
            motion.frame_time_s,
            motion.frames.columns(0, QUICK_FRAMES).into_owned(),
        )?;
    }
    stage.finish(format!(
        "CMU 131_01 retargeted (scale {:.3}), {} frames at {FRAME_RATE_HZ} Hz",
        walk.scale,
        motion.frame_count()
    ));
    let stage = run.stage("walk deformation", Some(motion.frame_count() as u64));

    // The non-skinning deformation over the motion, and the frame where it is largest.
    let (mut worst_m, mut worst_frame, mut centre) = (0.0f64, 0, DVec3::ZERO);
    performer.perform(&motion, |k, f| {
        stage.inc(1);
        let d = f.max_nonskinning_m();
        if d > worst_m {
            let (lo, hi) = f
                .true_vertices
                .iter()
                .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), v| {
                    (lo.min(*v), hi.max(*v))
                });
            (worst_m, worst_frame, centre) = (d, k, (lo + hi) / 2.0);
        }
        Ok(())
    })?;
    stage.finish(format!(
        "max non-skinning {:.1} mm (frame {worst_frame})",
        worst_m * 1e3
    ));
    let stage = run.stage("capture", None);

    // The ring, centred on the body's bounding box at that frame.
    let scale = if quick { 0.25 } else { 1.0 };
    let f = FOCAL_PX * scale;
    let k = Intrinsics::new(f, f, (w as f64 - 1.0) / 2.0, (h as f64 - 1.0) / 2.0, w, h)?;
    let look_at = centre;
    // Rig::ring centres the circle on the look-at point's vertical.
    let rig = Rig::ring(
        CAMERAS,
        RING_RADIUS_M,
        centre.y + RING_HEIGHT_ABOVE_M,
        look_at,
        DVec3::Y,
        k,
    )?;
    let lights = dome_lights(&DomeParams {
        floor_centre: DVec3::new(centre.x, 0.0, centre.z),
        ..Default::default()
    })?;
    let spec = CaptureSpec::new(rig)
        .with_frame_rate_hz(FRAME_RATE_HZ)
        .with_seed(131)
        .with_render(RenderParams::default().with_buffers(Buffers {
            triangle: true,
            ..Buffers::default()
        }))
        .with_lighting(CaptureLighting::new(lights.clone()));
    let capture = Capture::new(&performer, &motion, spec)?;
    let t = Instant::now();
    let frame = capture
        .frames_in(worst_frame..worst_frame + 1)
        .next()
        .ok_or("the chosen frame is in the motion")??;
    let capture_frame_s = t.elapsed().as_secs_f64();
    stage.finish(format!("frame {worst_frame} captured from {CAMERAS} cameras at {w}x{h} under {} lights in {capture_frame_s:.2} s", lights.len()));
    let stage = run.stage("timings", None);

    // Rasteriser speed: silhouette + depth + normals of the posed body, median over the views.
    let mesh = frame.truth.true_mesh(&performer);
    let params = RenderParams::default();
    let reps = if quick { 3 } else { 5 };
    let mut per_view = Vec::new();
    let mut scratch = RenderedView::default();
    for r in capture.rasterizers() {
        per_view.push(median_ms(reps, || {
            r.render_into(&mesh, &params, &mut scratch)?;
            Ok(())
        })?);
    }
    let raster_ms = median(&per_view);
    stage.println(format!(
        "raster {raster_ms:.2} ms per {w}x{h} view (mask + depth + normals)"
    ));

    let (shade_ms, visibility_ms) =
        shade_timing(&mesh, &lights, look_at, if quick { 1 } else { 3 })?;
    stage.println(format!("dome shading {shade_ms:.1} ms per 1024x1024 view, shadow visibility of its vertices {visibility_ms:.0} ms"));
    let fk_us = fk_jacobian_us(&performer.skeleton, if quick { 2_000 } else { 20_000 })?;
    stage.finish(format!(
        "FK + Jacobians of {JACOBIAN_POINTS} points: {fk_us:.2} us"
    ));

    let stage = run.stage("contact sheet", None);
    let diff_max_mm = write_pictures(&performer, &frame, out)?;
    stage.finish(format!("{}/contact_sheet.png", out.display()));
    run.picture(
        "contact_sheet.png",
        &format!(
            "Frame {worst_frame} of the walk from the {CAMERAS} cameras (columns), each cropped to \
             its silhouette. Rows: silhouette, depth (near bright), normals, shading under the \
             dome with cast shadows, and |truth − LBS| on the body (colour bar, mm): the \
             deformation no skinning method reaches."
        ),
    );

    let stage = run.stage("deformation figures", None);
    let deformation = deformation_figures(&performer)?;
    stage.finish("range of motion, fast motion, MakeHuman walk, procedural performer");
    let stage = run.stage("exercise", None);
    let (exercise, exercise_fig) = exercise_figures(&performer)?;
    stage.finish(format!(
        "exercise: min range coverage {:.3}, max pose share {:.4}",
        exercise_fig["exercise_range_coverage_min"]
            .as_f64()
            .unwrap_or(f64::NAN),
        exercise_fig["exercise_max_pose_share"]
            .as_f64()
            .unwrap_or(f64::NAN),
    ));
    let stage = run.stage("performer with every effect", None);
    let full = makehuman_performer(
        mh.parent().ok_or("data path has a parent")?,
        &full_deformation(),
    )?;
    let fine = full.fine_surface(
        motion.frame(worst_frame),
        &posed_at(&full, &motion, worst_frame)?,
    )?;
    let fine = fine.ok_or("the full performer has wrinkles")?;
    let mut per_view = Vec::new();
    for r in capture.rasterizers() {
        per_view.push(median_ms(reps, || {
            r.render_into(&fine.mesh, &params, &mut scratch)?;
            Ok(())
        })?);
    }
    let raster_fine_ms = median(&per_view);
    stage.finish(format!(
        "{} vertices ({} of the garment); refined surface {} vertices, {} faces, raster {raster_fine_ms:.1} ms per {w}x{h} view",
        full.vertex_count(),
        full.garment_vertices().len(),
        fine.mesh.vertex_count(),
        fine.mesh.face_count()
    ));
    // Every frame of the walk; the exercise every 10th frame (every 100th with --quick).
    let stride = if quick { 30 } else { 10 };
    let stage = run.stage("effects", None);
    // With --quick, the first 30 s of the exercise (every frame is posed with the skirt's
    // simulation).
    let exercise = if quick {
        Motion::new(
            exercise.frame_time_s,
            exercise
                .frames
                .columns(0, exercise.frame_count().min(QUICK_EXERCISE_FRAMES))
                .into_owned(),
        )?
    } else {
        exercise
    };
    let effects = effect_figures(&full, &motion, &exercise, stride)?;
    stage.finish(format!(
        "pose-driven up to {:.1} mm, skirt hem lag up to {:.0} mm, wrinkles up to {:.1} mm; the whole deformation {:.1} ms per frame on one core",
        effects["pose_deform_max_mm"].as_f64().unwrap_or(f64::NAN),
        effects["skirt_hem_lag_max_mm"].as_f64().unwrap_or(f64::NAN),
        effects["wrinkle_amplitude_mm"].as_f64().unwrap_or(f64::NAN),
        effects["deform_ms_per_frame"].as_f64().unwrap_or(f64::NAN),
    ));
    let stage = run.stage("pictures", None);
    let pose = pose_picture(&performer, out)?;
    run.picture(
        "nonskinning_pose.png",
        "The MakeHuman performer with elbow, knee, hip and shoulder flexed, front and side, \
         coloured by the distance between the true surface and linear blend skinning (mm): \
         the pose-driven muscle and joint shapes the studio adds to skinning.",
    );
    effects_picture(&full, &motion, worst_frame, out)?;
    run.picture(
        "effects.png",
        "The performer with every effect on at the walk's frame of largest deformation, \
         coloured by each part of the ground truth beyond skinning: the pose-driven shapes, \
         the dynamic skirt (from the side), and the render-time wrinkles.",
    );
    let swing = effects["walk_skirt_hem_lag_frame"]
        .as_u64()
        .ok_or("effect_figures reports the walk's frame of largest hem lag")?
        as usize;
    skirt_picture(&full, &motion, swing, out)?;
    run.picture(
        "skirt_swing.png",
        &format!(
            "Frame {swing} of the walk, where the skirt departs most from the skinned skirt, \
             from the performer's left: skinned (left) and simulated (right, coloured by lag)."
        ),
    );
    let closeup = wrinkle_closeup(&full, out)?;
    run.picture(
        "wrinkle_closeup.png",
        "The left elbow crease at 90° flexion seen from inside the bend: normal maps of the \
         refined surface with its wrinkles and without them.",
    );
    stage.finish("nonskinning_pose.png, effects.png, skirt_swing.png, wrinkle_closeup.png");
    headlines(&mut run, w, h);

    let mut figures = json!({
            "raster_ms_per_view": raster_ms,
            "shade_ms_per_view_shadowed": shade_ms,
            "visibility_ms_per_view": visibility_ms,
            "fk_jacobian_us": fk_us,
            "performer_vertices": performer.vertex_count(),
            "max_nonskinning_mm": worst_m * 1e3,
            "frame_nonskinning_mm": diff_max_mm,
            "frame_index": worst_frame,
            "motion_frames": motion.frame_count(),
            "capture_frame_s": capture_frame_s,
            "width": w,
            "height": h,
            "quick": quick,
            "seconds": start.elapsed().as_secs_f64(),
    });
    let obj = figures.as_object_mut().ok_or("json object")?;
    obj.insert("raster_fine_ms_per_view".into(), json!(raster_fine_ms));
    for extra in [deformation, exercise_fig, effects, pose, closeup] {
        if let serde_json::Value::Object(m) = extra {
            obj.extend(m);
        }
    }
    run.finish(figures)?;
    Ok(())
}

/// The figures `tour` shows, with the goals of `docs/skin-core.md`.
fn headlines(run: &mut Run, w: u32, h: u32) {
    let doc = "goal from docs/skin-core.md";
    for hl in [
        Headline::new(
            "raster_ms_per_view",
            "rasterise mask + depth + normals, per view",
            "ms",
        )
        .goal(Goal::AtMost(10.0))
        .note(&format!("{doc}, at 1600×1200; this run {w}×{h}")),
        Headline::new(
            "shade_ms_per_view_shadowed",
            "dome shading with shadows, 1024×1024 view",
            "ms",
        ),
        Headline::new(
            "visibility_ms_per_view",
            "shadow visibility of one view's vertices",
            "ms",
        ),
        Headline::new(
            "fk_jacobian_us",
            "FK + positional Jacobians, 42 DOF, 18 points",
            "µs",
        )
        .goal(Goal::AtMost(20.0))
        .note(doc),
        Headline::new(
            "max_nonskinning_mm",
            "largest |truth − LBS| over the walk",
            "mm",
        )
        .goal(Goal::AtLeast(10.0))
        .note("\"tens of mm\", docs/skin-core.md"),
        Headline::new(
            "rom_max_nonskinning_mm",
            "largest |truth − LBS| over the range of motion",
            "mm",
        ),
        Headline::new(
            "fast_max_nonskinning_mm",
            "largest |truth − LBS| over the fast motion",
            "mm",
        ),
        Headline::new(
            "pose_max_nonskinning_mm",
            "largest |truth − LBS| in the test pose",
            "mm",
        ),
        Headline::new(
            "exercise_range_coverage_min",
            "free exercise: smallest share of a DOF's range visited",
            "",
        )
        .goal(Goal::AtLeast(0.8))
        .note("goal in docs/studio.md, 5 minutes at 30 fps"),
        Headline::new(
            "exercise_max_pose_share",
            "free exercise: largest share of frames in one 5° pose cell",
            "",
        )
        .goal(Goal::AtMost(0.05))
        .note("goal in docs/studio.md; the range of motion's is rom_max_pose_share"),
        Headline::new(
            "pose_deform_max_mm",
            "pose-driven shapes: largest displacement (walk, exercise)",
            "mm",
        ),
        Headline::new(
            "pose_deform_vertices_over_5mm",
            "pose-driven shapes: most vertices moved > 5 mm in one frame",
            "",
        ),
        Headline::new(
            "skirt_hem_lag_max_mm",
            "skirt: largest hem displacement from the skinned skirt (walk, exercise, fast)",
            "mm",
        )
        .goal(Goal::AtLeast(100.0))
        .note("goal in docs/studio.md: ≥ 10 cm in fast motion"),
        Headline::new(
            "wrinkle_amplitude_mm",
            "wrinkles: largest fold displacement (walk, exercise)",
            "mm",
        )
        .goal(Goal::AtMost(3.0))
        .note("goal in docs/studio.md: folds of 1–3 mm"),
        Headline::new(
            "deform_ms_per_frame",
            "the whole deformation per frame on one core (skirt, wrinkles)",
            "ms",
        )
        .goal(Goal::AtMost(20.0))
        .note("goal in docs/studio.md"),
        Headline::new(
            "raster_fine_ms_per_view",
            "rasterise the refined, wrinkled surface, per view",
            "ms",
        )
        .note(&format!("reported; this run {w}×{h}")),
    ] {
        run.headline(hl);
    }
}

/// Median ms of shading one 1024×1024 view under the dome with per-vertex shadows, and ms of
/// the shadow visibility of the vertices that view sees (once).
fn shade_timing(
    mesh: &TriMesh,
    lights: &[dynamic_shapes_studio::shading::Light],
    look_at: DVec3,
    reps: usize,
) -> AnyResult<(f64, f64)> {
    let k = Intrinsics::new(1400.0, 1400.0, 511.5, 511.5, 1024, 1024)?;
    let cam = Camera::look_at(k, look_at + DVec3::new(0.5, 0.8, 3.0), look_at, DVec3::Y)?;
    let view = dynamic_shapes::core::raster::Rasterizer::new(&cam)
        .render(mesh, &RenderParams::default().with_buffers(Buffers::ALL))?;
    let query = MeshQuery::new(mesh)?;
    // Visibility is per frame and shared by all cameras; one view needs only the vertices it
    // sees (about half the mesh).
    let seen = vertices_seen(mesh, &[&view])?;
    let t = Instant::now();
    let vis = LightVisibility::compute_for(
        mesh,
        &query,
        lights,
        LightVisibility::DEFAULT_SHADOW_BIAS_M,
        Some(&seen),
    )?;
    let visibility_ms = t.elapsed().as_secs_f64() * 1e3;
    let alb = Albedo::Uniform([0.8, 0.6, 0.5]);
    let shade_ms = median_ms(reps, || {
        shade(&view, mesh, lights, &alb, &Shadows::PerVertex(&vis))?;
        Ok(())
    })?;
    Ok((shade_ms, visibility_ms))
}

/// Median µs of FK + the 54×42 positional Jacobian of 18 points attached mid-bone.
fn fk_jacobian_us(s: &Skeleton, reps: usize) -> AnyResult<f64> {
    let mut points: Vec<AttachedPoint> = (0..s.joint_count())
        .filter(|&j| !s.joints()[j].dofs.is_empty())
        .map(|j| AttachedPoint {
            joint: j,
            offset: s.joints()[j]
                .end_site
                .or_else(|| s.children(j).next().map(|c| s.joints()[c].offset))
                .unwrap_or(DVec3::ZERO)
                * 0.5
                + DVec3::new(0.0, 0.0, 0.05),
        })
        .collect();
    while points.len() < JACOBIAN_POINTS {
        points.push(AttachedPoint {
            joint: points.len() % s.joint_count(),
            offset: DVec3::new(0.0, 0.1, 0.12),
        });
    }
    points.truncate(JACOBIAN_POINTS);
    let n = s.dof_count();
    let theta: Vec<f64> = (0..n)
        .map(|d| 0.3 * ((d * 7 % 11) as f64 / 11.0 - 0.5))
        .collect();
    let mut fk = ForwardKinematics::new(s);
    let mut jp = DMatrix::zeros(3 * points.len(), n);
    const BATCH: usize = 100;
    let mut times = Vec::new();
    for _ in 0..reps / BATCH + 1 {
        let t = Instant::now();
        for _ in 0..BATCH {
            s.forward_kinematics_into(std::hint::black_box(&theta), &mut fk)?;
            s.point_jacobians_into(&fk, &points, &mut jp)?;
            std::hint::black_box(&jp);
        }
        times.push(t.elapsed().as_secs_f64() * 1e6 / BATCH as f64);
    }
    Ok(median(&times))
}
