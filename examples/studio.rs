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
//! The performers' non-skinning deformation over the studio's motions (formerly an ignored
//! test of skin-core): the largest |truth − LBS| of the MakeHuman performer over the range of
//! motion (`rom_max_nonskinning_mm`, with its cost `nonskinning_ms_per_frame`), the fast motion
//! (`fast_max_nonskinning_mm`) and the MakeHuman walk (`walk1_*`), and of the procedural
//! performer (`procedural_*`); and `nonskinning_pose.png`, the MakeHuman body in a test pose
//! (elbow, knee, hip and shoulder flexed) coloured by |truth − LBS|, front and side.
//!
//! `cargo run --release --example studio [-- --quick] [-- --out DIR]` (`--quick`: 400×300
//! views, the first 90 frames of the walk, fewer repetitions). Last stdout line: one JSON
//! object of figures.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)] // not library code

use std::path::Path;
use std::time::Instant;

use clap::Parser;
use dynamic_shapes::core::camera::{Camera, Intrinsics, Rig};
use dynamic_shapes::core::image::{
    normals_rgb8, write_depth_png16, write_mask_png, DepthEncoding, GrayF32Image, Mask,
};
use dynamic_shapes::core::math::{DQuat, DVec3};
use dynamic_shapes::core::mesh::{MeshQuery, TriMesh};
use dynamic_shapes::core::raster::{Buffers, RenderParams, RenderedView, NO_TRIANGLE};
use dynamic_shapes::core::skeleton::{
    read_bvh, AttachedPoint, BvhParams, ForwardKinematics, Motion, Skeleton, CMU_METRES_PER_UNIT,
};
use dynamic_shapes::core::stats::median;
use dynamic_shapes::core::studio::shading::{
    dome_lights, shade, srgb8, vertices_seen, Albedo, DomeParams, LightVisibility, Shadows,
    DEFAULT_SHADOW_BIAS_M,
};
use dynamic_shapes::core::studio::{
    exercise_motion, fast_motion, makehuman_performer, max_pose_share, play_bvh, preview,
    procedural_performer, range_coverage, range_of_motion, retarget, Capture, CaptureFrame,
    CaptureLighting, CaptureSpec, DeformationParams, DeformationState, ExerciseParams,
    FastMotionParams, JointMap, Paint, Performer, PoseDeformParams, PreviewPanel,
    ProceduralBodyParams, RangeOfMotionParams, RetargetParams, ViewTruth,
};
use example_kit::plot::{self as kplot, ColourBar};
use example_kit::{data_path, Goal, Headline, Run};
use image::imageops::{resize, FilterType};
use image::{Rgb, Rgb32FImage, RgbImage};
use nalgebra::DMatrix;
use serde_json::json;

type AnyResult<T> = Result<T, Box<dyn std::error::Error>>;

/// Top of the colour scale of `nonskinning_pose.png`, mm.
const POSE_SCALE_MM: f64 = 30.0;
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
/// Tile size of the contact sheet, px.
const TILE: (u32, u32) = (240, 180);
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
    let stage = run.stage("exercise and pose-driven shapes", None);
    let exercise = exercise_figures(&performer, &motion, quick)?;
    stage.finish(format!(
        "exercise: min range coverage {:.3}, max pose share {:.4}; pose-driven shapes up to {:.1} mm",
        exercise["exercise_range_coverage_min"].as_f64().unwrap_or(f64::NAN),
        exercise["exercise_max_pose_share"].as_f64().unwrap_or(f64::NAN),
        exercise["pose_deform_max_mm"].as_f64().unwrap_or(f64::NAN),
    ));
    let stage = run.stage("test pose", None);
    let pose = pose_picture(&performer, out)?;
    stage.finish("nonskinning_pose.png");
    run.picture(
        "nonskinning_pose.png",
        "The MakeHuman performer with elbow, knee, hip and shoulder flexed, front and side, \
         coloured by the distance between the true surface and linear blend skinning (mm): \
         the muscle bulges and flap the studio adds to skinning.",
    );
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
    for extra in [deformation, exercise, pose] {
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
        .note("studio issue, 5 minutes at 30 fps"),
        Headline::new(
            "exercise_max_pose_share",
            "free exercise: largest share of frames in one 5° pose cell",
            "",
        )
        .goal(Goal::AtMost(0.05))
        .note("studio issue; the range of motion's is rom_max_pose_share"),
        Headline::new(
            "pose_deform_max_mm",
            "opt-in pose-driven shapes: largest displacement (walk, exercise)",
            "mm",
        ),
    ] {
        run.headline(hl);
    }
}

/// The free multi-DOF exercise (5 minutes at 30 fps, the acceptance length of the studio
/// issue) measured by its range coverage and largest held-pose share, and the opt-in
/// pose-driven muscle and joint shapes ([`PoseDeformParams`]) measured on the walk and on the
/// exercise: their largest displacement, the largest number of vertices moved more than 2, 5
/// and 10 mm in one frame, and the cost of posing with them.
fn exercise_figures(p: &Performer, walk: &Motion, quick: bool) -> AnyResult<serde_json::Value> {
    let exercise = exercise_motion(&p.skeleton, &ExerciseParams::default())?;
    let coverage = range_coverage(&p.skeleton, &exercise)?
        .iter()
        .map(|c| c.coverage)
        .fold(1.0, f64::min);
    let share = max_pose_share(&p.skeleton, &exercise, 5.0)?;
    let rom_share = max_pose_share(
        &p.skeleton,
        &range_of_motion(&p.skeleton, &RangeOfMotionParams::default())?,
        5.0,
    )?;
    let muscled = Performer::new(
        "makehuman with pose-driven shapes",
        p.template.clone(),
        p.skeleton.clone(),
        p.weights.clone(),
        &DeformationParams::default().with_pose(Some(PoseDeformParams::default())),
    )?;
    // Every frame of the walk; the exercise every 10th frame (every 100th with --quick).
    let stride = if quick { 100 } else { 10 };
    let mut out = serde_json::Map::new();
    let mut pose_ms = Vec::new();
    let mut overall_max_mm = 0.0f64;
    for (name, motion, step) in [("walk", walk, 1), ("exercise", &exercise, stride)] {
        let (mut max_mm, mut over) = (0.0f64, [0usize; 3]);
        for k in (0..motion.frame_count()).step_by(step) {
            let t = Instant::now();
            let f = muscled.pose(motion.frame(k), &mut DeformationState::default(), 0.0)?;
            pose_ms.push(t.elapsed().as_secs_f64() * 1e3);
            let mm: Vec<f64> = f
                .pose_displacement
                .iter()
                .map(|d| d.length() * 1e3)
                .collect();
            max_mm = max_mm.max(mm.iter().copied().fold(0.0, f64::max));
            for (o, limit) in over.iter_mut().zip([2.0, 5.0, 10.0]) {
                *o = (*o).max(mm.iter().filter(|&&d| d > limit).count());
            }
        }
        overall_max_mm = overall_max_mm.max(max_mm);
        out.insert(format!("{name}_pose_deform_max_mm"), json!(max_mm));
        for (o, limit) in over.iter().zip([2, 5, 10]) {
            out.insert(
                format!("{name}_pose_deform_vertices_over_{limit}mm"),
                json!(o),
            );
        }
    }
    out.insert("pose_deform_max_mm".into(), json!(overall_max_mm));
    out.insert(
        "pose_deform_vertices_over_5mm".into(),
        json!(out["exercise_pose_deform_vertices_over_5mm"]
            .as_u64()
            .max(out["walk_pose_deform_vertices_over_5mm"].as_u64())),
    );
    out.insert(
        "deform_ms_per_frame_with_pose".into(),
        json!(median(&pose_ms)),
    );
    out.insert("exercise_frames".into(), json!(exercise.frame_count()));
    out.insert("exercise_range_coverage_min".into(), json!(coverage));
    out.insert("exercise_max_pose_share".into(), json!(share.share));
    out.insert(
        "exercise_max_pose_share_joint".into(),
        json!(p.skeleton.joints()[share.joint].name),
    );
    out.insert("rom_max_pose_share".into(), json!(rom_share.share));
    Ok(serde_json::Value::Object(out))
}

/// The non-skinning deformation of the performers over the studio's motions (the figures of
/// the former ignored test `studio::tests::figures`).
fn deformation_figures(p: &Performer) -> AnyResult<serde_json::Value> {
    let rom = range_of_motion(&p.skeleton, &RangeOfMotionParams::default())?;
    let fast = fast_motion(&p.skeleton, &FastMotionParams::default())?;
    let t = Instant::now();
    let d_rom = p.max_nonskinning_m(&rom)?;
    let per_frame_ms = t.elapsed().as_secs_f64() * 1e3 / rom.frame_count() as f64;
    let d_fast = p.max_nonskinning_m(&fast)?;
    eprintln!(
        "deformation: makehuman {} vertices; range of motion {} frames, max non-skinning {:.1} mm ({per_frame_ms:.2} ms/frame); fast motion {:.1} mm",
        p.vertex_count(),
        rom.frame_count(),
        d_rom * 1e3,
        d_fast * 1e3
    );
    let mut fig = json!({
        "rom_frames": rom.frame_count(),
        "rom_max_nonskinning_mm": d_rom * 1e3,
        "nonskinning_ms_per_frame": per_frame_ms,
        "fast_max_nonskinning_mm": d_fast * 1e3,
    });
    let obj = fig.as_object_mut().ok_or("json object")?;
    // The MakeHuman walk (CMU 131_01 is the capture above), retargeted at 30 Hz.
    let bvh = read_bvh(
        data_path("makehuman/walk1.bvh")?,
        &BvhParams {
            metres_per_unit: 0.1,
        },
    )?;
    let map = JointMap::detect(&bvh.skeleton)?;
    let r = retarget(
        &bvh.skeleton,
        &bvh.motion,
        &p.skeleton,
        &map,
        &RetargetParams::default(),
    )?;
    let m = r.motion.resample(&p.skeleton, 1.0 / 30.0)?;
    let d_walk1 = p.max_nonskinning_m(&m)?;
    eprintln!(
        "deformation: makehuman/walk1.bvh scale {:.3}, {} frames at 30 Hz, max non-skinning {:.1} mm",
        r.scale,
        m.frame_count(),
        d_walk1 * 1e3
    );
    obj.insert("walk1_scale".into(), json!(r.scale));
    obj.insert("walk1_frames".into(), json!(m.frame_count()));
    obj.insert("walk1_max_nonskinning_mm".into(), json!(d_walk1 * 1e3));
    // The procedural performer: built at its default 2 cm grid (timed); the 3 cm grid of the
    // tests over the range of motion.
    let t = Instant::now();
    let q = procedural_performer(&ProceduralBodyParams::default())?;
    obj.insert(
        "procedural_build_s".into(),
        json!(t.elapsed().as_secs_f64()),
    );
    obj.insert("procedural_vertices".into(), json!(q.vertex_count()));
    let q3 = procedural_performer(&ProceduralBodyParams {
        grid_spacing_m: 0.03,
        ..Default::default()
    })?;
    let d = q3.max_nonskinning_m(&range_of_motion(
        &q3.skeleton,
        &RangeOfMotionParams::default(),
    )?)?;
    obj.insert("procedural_3cm_vertices".into(), json!(q3.vertex_count()));
    obj.insert(
        "procedural_3cm_rom_max_nonskinning_mm".into(),
        json!(d * 1e3),
    );
    Ok(fig)
}

/// `nonskinning_pose.png` (the former ignored test `studio::tests::picture`): the performer
/// with four joints flexed, coloured by |truth − LBS|, front and side; returns its figures.
fn pose_picture(p: &Performer, out: &Path) -> AnyResult<serde_json::Value> {
    let mut theta = p.skeleton.rest_pose();
    for (n, v) in [
        ("l_elbow.flexion", 2.0),
        ("r_knee.flexion", 1.5),
        ("r_hip.flexion", 0.8),
        ("l_shoulder.flexion", 0.6),
    ] {
        theta[p.skeleton.dof_index(n).ok_or("the performer has the DOF")?] = v;
    }
    let f = p.pose(&theta, &mut DeformationState::default(), 0.05)?;
    let dist_mm: Vec<f64> = f
        .lbs_vertices
        .iter()
        .zip(&f.true_vertices)
        .map(|(a, b)| a.distance(*b) * 1e3)
        .collect();
    let max_mm = dist_mm.iter().copied().fold(0.0, f64::max);
    let above_10mm = dist_mm.iter().filter(|&&d| d > 10.0).count();
    let colours: Vec<[u8; 3]> = dist_mm
        .iter()
        .map(|d| ramp(d / POSE_SCALE_MM).map(|c| (255.0 * c) as u8))
        .collect();
    let front = p.mesh(f.true_vertices.clone());
    let turn = DQuat::from_rotation_y(-std::f64::consts::FRAC_PI_2);
    let side = p.mesh(f.true_vertices.iter().map(|v| turn * *v).collect());
    let img = preview(
        &[
            PreviewPanel {
                mesh: &front,
                paint: Paint::PerVertex(&colours),
            },
            PreviewPanel {
                mesh: &side,
                paint: Paint::PerVertex(&colours),
            },
        ],
        480,
    )?;
    let ramp_u8 = |t: f64| ramp(t).map(|c| (255.0 * c) as u8);
    let img = kplot::with_colour_bar(
        &img,
        &ColourBar {
            label: "|truth − LBS| (mm)",
            min: 0.0,
            max: POSE_SCALE_MM,
            ramp: &ramp_u8,
            note: Some(&format!("top: ≥ {POSE_SCALE_MM} mm")),
        },
    )?;
    let img = kplot::titled(
        &img,
        "Non-skinning deformation in a test pose",
        Some(&format!(
            "left elbow, right knee, right hip and left shoulder flexed; front and side; largest {max_mm:.1} mm, {above_10mm} vertices above 10 mm"
        )),
    )?;
    kplot::save(&img, out.join("nonskinning_pose.png"))?;
    Ok(json!({
        "pose_max_nonskinning_mm": max_mm,
        "pose_vertices_above_10mm": above_10mm,
    }))
}

/// Median ms of shading one 1024×1024 view under the dome with per-vertex shadows, and ms of
/// the shadow visibility of the vertices that view sees (once).
fn shade_timing(
    mesh: &TriMesh,
    lights: &[dynamic_shapes::core::studio::shading::Light],
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
    let vis =
        LightVisibility::compute_for(mesh, &query, lights, DEFAULT_SHADOW_BIAS_M, Some(&seen))?;
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

/// A false-colour ramp (dark blue → cyan → yellow → red) of `t ∈ [0, 1]`.
fn ramp(t: f64) -> [f64; 3] {
    let stops = [
        [0.05, 0.05, 0.5],
        [0.0, 0.7, 0.9],
        [0.95, 0.9, 0.1],
        [0.9, 0.1, 0.05],
    ];
    let x = t.clamp(0.0, 1.0) * (stops.len() - 1) as f64;
    let i = (x.floor() as usize).min(stops.len() - 2);
    let f = x - i as f64;
    std::array::from_fn(|c| stops[i][c] * (1.0 - f) + stops[i + 1][c] * f)
}

/// Depth as grey (near bright), scaled over the covered pixels of the view.
fn depth_picture(depth_m: &GrayF32Image) -> RgbImage {
    let covered = depth_m.as_raw().iter().filter(|d| d.is_finite());
    let (lo, hi) = covered.fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &d| {
        (a.min(d), b.max(d))
    });
    let mut img = RgbImage::new(depth_m.width(), depth_m.height());
    for (p, &d) in img.pixels_mut().zip(depth_m.as_raw()) {
        if d.is_finite() {
            let g = (255.0 * (1.0 - 0.8 * (d - lo) / (hi - lo).max(1e-6))) as u8;
            *p = Rgb([g, g, g]);
        }
    }
    img
}

/// Per-pixel |truth − LBS| (mm) interpolated from the vertices with the barycentrics, coloured
/// on a false-colour scale from 0 to `max_mm` and shaded by the normal for shape.
fn difference_picture(
    v: &ViewTruth,
    faces: &[[u32; 3]],
    dist_mm: &[f64],
    max_mm: f64,
) -> AnyResult<RgbImage> {
    let ids = v
        .triangle_ids
        .as_ref()
        .ok_or("the spec renders triangle ids")?;
    let bary = v
        .barycentric
        .as_ref()
        .ok_or("the spec renders barycentrics")?;
    let normals = v
        .normals_camera
        .as_ref()
        .ok_or("the spec renders normals")?;
    let mut img = RgbImage::new(ids.width(), ids.height());
    for (x, y, p) in img.enumerate_pixels_mut() {
        let t = ids.get_pixel(x, y)[0];
        if t == NO_TRIANGLE {
            continue;
        }
        let f = faces[t as usize];
        let [b1, b2] = bary.get_pixel(x, y).0.map(f64::from);
        let d = dist_mm[f[0] as usize] * (1.0 - b1 - b2)
            + dist_mm[f[1] as usize] * b1
            + dist_mm[f[2] as usize] * b2;
        let light = 0.45 + 0.55 * f64::from(-normals.get_pixel(x, y)[2]).clamp(0.0, 1.0);
        *p = Rgb(ramp(d / max_mm).map(|c| (255.0 * c * light) as u8));
    }
    Ok(img)
}

/// Exposure mapping the 99th percentile of the covered radiance to 0.9.
fn exposure(views: &[&Rgb32FImage], masks: &[&Mask]) -> f32 {
    let mut lum: Vec<f32> = views
        .iter()
        .zip(masks)
        .flat_map(|(s, m)| {
            s.pixels()
                .zip(m.iter())
                .filter(|(_, m)| *m)
                .map(|(r, _)| r[0].max(r[1]).max(r[2]))
        })
        .collect();
    if lum.is_empty() {
        return 1.0;
    }
    lum.sort_by(f32::total_cmp);
    let p99 = lum[lum.len() * 99 / 100];
    if p99 > 0.0 {
        0.9 / p99
    } else {
        1.0
    }
}

/// The silhouette's bounding box, padded by 10 % and widened to the tile's aspect ratio,
/// clipped to the image: `(x, y, width, height)` (the whole image for an empty mask).
fn crop_box(mask: &Mask) -> (u32, u32, u32, u32) {
    let (w, h) = mask.dimensions();
    let Some(b) = mask.bounding_box() else {
        return (0, 0, w, h);
    };
    let (lo, hi) = ((b.x_min, b.y_min), (b.x_max, b.y_max));
    let aspect = f64::from(TILE.0) / f64::from(TILE.1);
    let (cx, cy) = (f64::from(lo.0 + hi.0) / 2.0, f64::from(lo.1 + hi.1) / 2.0);
    let mut bh = f64::from(hi.1 - lo.1 + 1) * 1.2;
    let bw = (f64::from(hi.0 - lo.0 + 1) * 1.2).max(bh * aspect);
    bh = bw / aspect;
    let (bw, bh) = (bw.min(f64::from(w)), bh.min(f64::from(h)));
    let x0 = (cx - bw / 2.0).clamp(0.0, f64::from(w) - bw);
    let y0 = (cy - bh / 2.0).clamp(0.0, f64::from(h) - bh);
    (x0 as u32, y0 as u32, (bw as u32).max(1), (bh as u32).max(1))
}

/// Writes the contact sheet and camera 0's full-size pictures; returns the frame's largest
/// |truth − LBS|, mm.
fn write_pictures(performer: &Performer, frame: &CaptureFrame, out: &Path) -> AnyResult<f64> {
    let dist_mm: Vec<f64> = frame
        .truth
        .nonskinning_m()
        .iter()
        .map(|d| d * 1e3)
        .collect();
    let max_mm = dist_mm.iter().copied().fold(0.0, f64::max).max(1e-3);
    let faces = &performer.template.faces;
    let shaded: Vec<&Rgb32FImage> = frame
        .observations
        .iter()
        .map(|o| o.shaded.as_ref().ok_or("the spec has lighting"))
        .collect::<Result<_, _>>()?;
    let masks: Vec<&Mask> = frame.observations.iter().map(|o| &o.mask).collect();
    let exp = exposure(&shaded, &masks);
    let n = frame.observations.len() as u32;
    let mut sheet = RgbImage::new(TILE.0 * n, TILE.1 * 5);
    for (c, (o, v)) in frame
        .observations
        .iter()
        .zip(&frame.truth.views)
        .enumerate()
    {
        let mask_rgb = image::DynamicImage::ImageLuma8(o.mask.to_gray()).to_rgb8();
        let depth = v.depth_m.as_ref().ok_or("the spec renders depth")?;
        let normals = v
            .normals_camera
            .as_ref()
            .ok_or("the spec renders normals")?;
        let pictures = [
            mask_rgb,
            depth_picture(depth),
            normals_rgb8(normals),
            srgb8(shaded[c], exp),
            difference_picture(v, faces, &dist_mm, max_mm)?,
        ];
        let (x0, y0, cw, ch) = crop_box(&o.mask);
        for (row, pic) in pictures.iter().enumerate() {
            let cropped = image::imageops::crop_imm(pic, x0, y0, cw, ch).to_image();
            let tile = resize(&cropped, TILE.0, TILE.1, FilterType::Triangle);
            image::imageops::replace(
                &mut sheet,
                &tile,
                (c as u32 * TILE.0).into(),
                (row as u32 * TILE.1).into(),
            );
        }
        if c == 0 {
            write_mask_png(&o.mask, out.join("cam0_silhouette.png"))?;
            let mm = DepthEncoding {
                scale_m: 1e-3,
                offset_m: 0.0,
            };
            write_depth_png16(depth, out.join("cam0_depth_mm.png"), &mm)?;
            pictures[1].save(out.join("cam0_depth_grey.png"))?;
            pictures[2].save(out.join("cam0_normals.png"))?;
            pictures[3].save(out.join("cam0_shaded.png"))?;
            pictures[4].save(out.join("cam0_lbs_vs_truth.png"))?;
        }
    }
    let sheet = kplot::label_rows(
        &sheet,
        &["silhouette", "depth", "normals", "shaded", "|truth − LBS|"],
        110,
    )?;
    let ramp_u8 = |t: f64| ramp(t).map(|c| (255.0 * c) as u8);
    let sheet = kplot::with_colour_bar(
        &sheet,
        &ColourBar {
            label: "|truth − LBS| (mm), last row",
            min: 0.0,
            max: max_mm,
            ramp: &ramp_u8,
            note: None,
        },
    )?;
    let sheet = kplot::titled(
        &sheet,
        "Studio capture of the frame of largest non-skinning deformation",
        Some(&format!(
            "columns: the {n} ring cameras, each cropped to its silhouette; depth near = bright; normals in camera space"
        )),
    )?;
    kplot::save(&sheet, out.join("contact_sheet.png"))?;
    Ok(max_mm)
}
