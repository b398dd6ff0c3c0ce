//! Validation of template-silhouette (Vlasic 2010 thesis, Chapter 2) on the synthetic studio.
//!
//! The MakeHuman performer seen by a ring of 8 cameras 3.5 m away (§2.5.1), in several runs:
//! the performer **in the skirt** in the exercise motion, the fast motion and the real CMU
//! 131_01 walk, and, for reference, the body alone in the exercise.
//! Per frame: the visual hull (§2.3.2) and the contour rays (§2.4.2); the skeleton tracked
//! through the hulls with the refinement term (§2.3.1, §2.3.3; the first frame's true pose
//! stands in for the user's fit of the first frame, no other user constraint; with
//! `--auto-init` the automatic initialisation `initialise_pose` replaces it, no user
//! constraint at all; with `--auto-size` the body runs use a performer whose bones differ
//! from the default by up to 10 % (`Performer::with_bone_scales`), the tracker is given the
//! default proportions and sizes them itself from its first frames: `auto_size_*` figures
//! for the tracker with default, sized and true proportions); then
//! Algorithm 1 (§2.4.2). The template is rigged as a user's would be (the thesis attached
//! its templates with Pinocchio, §2.5.1): bone-heat weights with Pinocchio's visibility test
//! computed by the library from the template mesh and the skeleton
//! (`heat_weights_mean_abs_diff` from the performer's own). Scored against the performer's
//! true posed mesh, against linear blend skinning with those weights driven by the same
//! estimated poses (`lbs_*`, the baseline) and by the true poses (`lbs_true_pose_*`), and
//! against the oracle the studio's truth is built from — the performer's own weights at the
//! true poses (`lbs_oracle_pose_*`: the truth minus its muscles and cloth); the weights
//! without the visibility test at the true poses (`lbs_no_visibility_true_pose_*`). The legs
//! inside the skirt are part of the template and of the truth and are scored with the body
//! (the silhouettes cannot see them: only the pose and the Laplacian prior place them).
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
//! Beside vertex RMS (which also counts sliding along the surface, §2.6's texture sliding, and
//! twists no silhouette sees), the two-way point-to-surface distance to the true surface
//! (`surface_*`, `skirt_surface_*`: mean and p95, for the result, for LBS with the same poses,
//! and for the oracle `oracle_attainable_*`: the template's vertices placed on the true
//! surface, what a template of this topology can attain).
//!
//! The protocol (`--protocol`, default `beyond`): the thesis' four switches — the user of
//! §2.3.3 who fixes hard frames, emulated by an oracle that sees the true pose
//! (`fixed_frames_pct`, `user_rays`); the ring 2.2 m above the floor looking down; 30 fps; the
//! template as a scanner gives it (`scan_outer_surface`: one closed outer surface, the legs
//! under the skirt left out, the hem closed, decimated to 10,000 vertices) — and, beyond the
//! thesis, each frame's molding started from the previous frame's (`ShapeStart::PreviousFrame`).
//! `before` has none of them, `thesis` the four. The full run also measures every protocol on
//! the skirt exercise and walk at 800 × 600, 30 frames a run, and the thesis' at full size:
//! the `protocol` table of the JSON (`{protocol: {figure: value}}`), the full-size thesis'
//! figures also as `thesis_*`.
//!
//! `cargo run --release --example template_capture [-- --quick] [-- --out DIR]` (`--quick`:
//! 480 × 360 views, the body in 12 frames of the exercise and the skirt in 8, no table; the
//! full run: 1600 × 1200 views, 100 frames per run).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)] // not library code

use std::time::Instant;

use clap::Parser;
use serde_json::{json, Map, Value};

use dynamic_shapes::core::camera::{Camera, Intrinsics, Rig};
use dynamic_shapes::core::image::Mask;
use dynamic_shapes::core::math::{DVec3, Ray};
use dynamic_shapes::core::mesh::{save_gltf_animation, DistanceStats, MeshQuery, MeshSequence};
use dynamic_shapes::core::random::SplitMix64;
use dynamic_shapes::core::skeleton::{BvhParams, Motion, Skeleton, CMU_METRES_PER_UNIT};
use dynamic_shapes::core::stats::{mean, rms};
use dynamic_shapes::template::{
    capture_sequence, capture_sequence_corrected, edge_error_pct, initialise_pose, pose_error,
    reference_sizes, rest_pose_start, score_ellipsoids, silhouette_error_pct, size_from_poses,
    AutoInitParams, ContourRayHullParams, DeformationTransfer, EllipsoidModel, EllipsoidState,
    FrameObservation, OracleUser, PoseEditor, PoseModel, PoseParams, SequenceCapture,
    ShapeEstimator, ShapeFrame, ShapeParams, ShapeStart, SilhouetteParams, SizingParams, Template,
    UserRay,
};
use dynamic_shapes_studio::{
    exercise_motion, fast_motion, makehuman_performer, play_bvh, preview, Capture, CaptureSpec,
    DeformationParams, ExerciseParams, FastMotionParams, FrameTruth, GarmentParams, Paint,
    Performer, PreviewPanel, RetargetParams, SkirtParams,
};
use example_kit::plot::{error_colour, Chart, ColourBar, Series, Style};
use example_kit::{Goal, Headline, Run};

#[path = "../common/scanned_template.rs"]
mod scanned_template;
use scanned_template::{SurfaceScore, TemplateEmbedding};

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

/// Every run takes every second frame of its motion unless `--fps` says otherwise.
const FRAME_STEP: usize = 2;

/// Vertices of the decimated template the figures are measured with (≈ 10k).
const TEMPLATE_VERTICES: usize = 10_000;

/// The example's options: the common ones and the protocol's knobs.
#[derive(Parser, Debug, Clone)]
struct Cli {
    #[command(flatten)]
    common: example_kit::cli::Common,
    /// Vertices of the decimated template; 0 keeps the performer's full mesh.
    #[arg(long, default_value_t = TEMPLATE_VERTICES)]
    template_vertices: usize,
    /// Camera resolution, `WIDTHxHEIGHT` (default: 1600x1200, `--quick` 480x360).
    #[arg(long, value_parser = parse_resolution)]
    resolution: Option<(u32, u32)>,
    /// Camera height above the floor (the rest mesh's lowest point), m: the ring looking down
    /// at the pelvis from this height, as the thesis's rigs did (§2.5.1: "a ring of eight
    /// cameras looking down at the performer"; 2.2 m puts them above a standing performer's
    /// head). Default: level with the pelvis (its height + 0.15 m).
    #[arg(long)]
    camera_height_m: Option<f64>,
    /// Frame rate of the captured frames, Hz: each motion is sampled every
    /// `round(motion rate / fps)` frames (the thesis captured at 25 fps, §2.5.1). Default:
    /// every second frame of each motion (15 fps for the 30 Hz exercise, 30 fps for the
    /// 60 Hz fast motion and walk).
    #[arg(long)]
    fps: Option<f64>,
    /// Frames per run (default: 100, `--quick` 12 and 8).
    #[arg(long)]
    frames: Option<usize>,
    /// Mark the skirt below its waistband as loose cloth (never pinned; beyond the thesis,
    /// `Template::with_loose_vertices`).
    #[arg(long)]
    loose_skirt: bool,
    /// Also run Algorithm 1 on the true poses (`molded_true_pose_*` figures), which separates
    /// the molding's error from the tracker's; on in `--quick`.
    #[arg(long)]
    true_pose_shape: bool,
    /// `ShapeParams::w_anchor` (0: the thesis' Eq. 2.2).
    #[arg(long, default_value_t = 0.0)]
    anchor_weight: f64,
    /// Start the tracker from the automatic first-frame initialisation
    /// (`initialise_pose`: global search over the ellipsoid model, then its robust fit to the
    /// first hull and silhouettes) instead of the first frame's true pose; adds the
    /// `auto_init_*` figures (first frame: the automatic start against the rest-pose start).
    #[arg(long)]
    auto_init: bool,
    /// Automatic sizing (implies `--auto-init`; runs without the skirt only): the performer's
    /// bones scaled by seeded factors in [0.9, 1.1] (`Performer::with_bone_scales`); the
    /// tracker's template has the default proportions; the automatic first pose, the tracker
    /// at default proportions, `size_from_poses` on its poses, the template re-rigged to the
    /// sized skeleton (`Template::resized`) and tracked again; adds the `auto_size_*` figures
    /// (sizes, and the tracker with default / sized / true proportions).
    #[arg(long)]
    auto_size: bool,
    /// Seed of `--auto-size`'s bone scale factors.
    #[arg(long, default_value_t = 12)]
    size_seed: u64,
    /// The user who fixes frames (§2.3.3), emulated by an oracle that sees the true pose: in
    /// the forward pass, every joint farther than `--user-threshold-mm` from its true
    /// position gets user rays through its true position from two cameras 90° apart, and
    /// the frame is re-fitted (`capture_sequence_corrected`). Adds `fixed_frames_pct` and
    /// counts `user_rays`.
    #[arg(long)]
    oracle_user: bool,
    /// The emulated user's threshold, mm (the thesis fixes "hard frames"; 5 cm is where a
    /// joint visibly leaves its limb in a camera view at the studio's resolution).
    #[arg(long, default_value_t = 50.0)]
    user_threshold_mm: f64,
    /// Where each frame's molding starts: `skinning` (the thesis, Eq. 2.1) or `previous`
    /// (beyond it: the previous frame's molded surface carried by the pose change,
    /// `ShapeStart::PreviousFrame`).
    #[arg(long, value_parser = parse_start)]
    shape_start: Option<ShapeStart>,
    /// The template as a scanner would give it (`scan_outer_surface`: the performer's outer
    /// surface in its rest pose, one closed mesh, the legs under the skirt left out and the
    /// hem closed), decimated and rigged by the library's weights; as the thesis' templates
    /// (§2.5.1). Default: the performer's rest mesh, the body with its skirt as a separate
    /// open tube.
    #[arg(long)]
    scan_template: bool,
    /// The protocol of the main runs (the individual switches above add to it):
    /// `before` (cameras level with the pelvis, 15 fps, the body-and-skirt template, no user,
    /// the thesis' start), one switch of the thesis' protocol on its own (`oracle-user`,
    /// `cameras-down`: 2.2 m above the floor, `fps30`, `scan-template`), `thesis` (all four),
    /// or `beyond` (the thesis' protocol with each frame's molding started from the previous
    /// frame's, the headline).
    #[arg(long, value_enum, default_value = "beyond")]
    protocol: Protocol,
    /// Also measure every protocol on the skirt in the exercise and the walk at a reduced
    /// size (`--table-frames`, `--table-resolution`): the `protocol` table of the JSON. On in
    /// the full run unless `--no-protocol-table`.
    #[arg(long)]
    protocol_table: bool,
    /// No `protocol` table in the full run.
    #[arg(long, conflicts_with = "protocol_table")]
    no_protocol_table: bool,
    /// Frames per run of the `protocol` table.
    #[arg(long, default_value_t = 30)]
    table_frames: usize,
    /// Camera resolution of the `protocol` table, `WIDTHxHEIGHT`.
    #[arg(long, value_parser = parse_resolution, default_value = "800x600")]
    table_resolution: (u32, u32),
    /// Only the runs with these names (e.g. `skirt_walk`); default: all.
    #[arg(long = "run", value_name = "NAME")]
    runs: Vec<String>,
}

/// The thesis' camera height above the floor, m (`Protocol::CamerasDown`).
const THESIS_CAMERA_HEIGHT_M: f64 = 2.2;
/// The thesis' frame rate, Hz (§2.5.1 captured at 25–30 fps; the studio's 30 and 60 Hz
/// motions give 30 exactly).
const THESIS_FPS: f64 = 30.0;

/// A capture protocol: which of the thesis' switches are on, and where the molding starts.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum Protocol {
    /// None of the switches: the cameras level with the pelvis, 15 fps, the body-and-skirt
    /// template, no user, the thesis' start.
    Before,
    /// The emulated user of §2.3.3 alone.
    OracleUser,
    /// The cameras 2.2 m above the floor, looking down, alone.
    CamerasDown,
    /// 30 fps alone.
    Fps30,
    /// The scanned template alone.
    ScanTemplate,
    /// All four switches: the thesis' protocol.
    Thesis,
    /// The thesis' protocol, each frame's molding started from the previous frame's.
    Beyond,
}

impl Protocol {
    /// Every protocol, in the table's order.
    const ALL: [Protocol; 7] = [
        Protocol::Before,
        Protocol::OracleUser,
        Protocol::CamerasDown,
        Protocol::Fps30,
        Protocol::ScanTemplate,
        Protocol::Thesis,
        Protocol::Beyond,
    ];

    /// The protocol's key in the JSON table.
    fn key(self) -> &'static str {
        match self {
            Protocol::Before => "before",
            Protocol::OracleUser => "oracle_user",
            Protocol::CamerasDown => "cameras_down",
            Protocol::Fps30 => "fps30",
            Protocol::ScanTemplate => "scan_template",
            Protocol::Thesis => "thesis",
            Protocol::Beyond => "beyond",
        }
    }

    /// Turns this protocol's switches on in `args` (switches already on stay on).
    fn apply(self, args: &mut Cli) {
        let all = matches!(self, Protocol::Thesis | Protocol::Beyond);
        args.oracle_user |= all || self == Protocol::OracleUser;
        if all || self == Protocol::CamerasDown {
            args.camera_height_m.get_or_insert(THESIS_CAMERA_HEIGHT_M);
        }
        if all || self == Protocol::Fps30 {
            args.fps.get_or_insert(THESIS_FPS);
        }
        args.scan_template |= all || self == Protocol::ScanTemplate;
        if self == Protocol::Beyond {
            args.shape_start.get_or_insert(ShapeStart::PreviousFrame);
        }
    }

    /// `args` with every switch off, then this protocol's on (the table's runs).
    fn only(self, args: &Cli) -> Cli {
        let mut a = args.clone();
        a.oracle_user = false;
        a.camera_height_m = None;
        a.fps = None;
        a.scan_template = false;
        a.shape_start = None;
        self.apply(&mut a);
        a
    }
}

/// The figures of the `protocol` table (means over its skirt runs).
const TABLE_FIGURES: [&str; 17] = [
    "joint_error_mm",
    "silhouette_error_pct",
    "edge_error_pct",
    "vertex_rms_mm",
    "surface_mean_mm",
    "surface_p95_mm",
    "skirt_surface_mean_mm",
    "skirt_surface_p95_mm",
    "lbs_skirt_surface_mean_mm",
    "skirt_surface_ratio_lbs",
    "oracle_attainable_skirt_surface_mean_mm",
    "fixed_frames_pct",
    "user_rays",
    "pose_s_per_frame",
    "shape_s_per_frame",
    "lbs_silhouette_error_pct",
    "oracle_attainable_edge_error_pct",
];

/// `skinning` or `previous`.
fn parse_start(s: &str) -> Result<ShapeStart, String> {
    match s {
        "skinning" => Ok(ShapeStart::Skinning),
        "previous" => Ok(ShapeStart::PreviousFrame),
        _ => Err(format!("`{s}`: give skinning or previous")),
    }
}

/// `WIDTHxHEIGHT` in pixels.
fn parse_resolution(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once('x')
        .ok_or_else(|| format!("`{s}`: give WIDTHxHEIGHT, e.g. 800x600"))?;
    let parse = |v: &str| {
        v.parse::<u32>()
            .ok()
            .filter(|&v| v >= 16)
            .ok_or_else(|| format!("`{s}`: each side a whole number of pixels ≥ 16"))
    };
    Ok((parse(w)?, parse(h)?))
}

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
    /// Before the run's name in its progress stages (the protocol of a table run).
    stage_prefix: String,
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
    embedding: TemplateEmbedding,
    truths: Vec<FrameTruth>,
    observations: Vec<FrameObservation>,
    result: SequenceCapture,
    sil: Vec<f64>,
    sil_lbs: Vec<f64>,
    frame_time_s: f64,
}

fn deformation(skirt: bool) -> DeformationParams {
    // With the skirt the hip flap is off (DeformationParams::garment: it only distorts the
    // thighs the skirt collides with); the pose-driven muscles stay on in both.
    if skirt {
        DeformationParams::default()
            .with_flap(None)
            .with_garment(Some(GarmentParams::Skirt(SkirtParams::default())))
    } else {
        DeformationParams::default()
    }
}

fn performer(skirt: bool) -> Result<Performer, Box<dyn std::error::Error>> {
    Ok(makehuman_performer(
        example_kit::data_path("makehuman")?,
        &deformation(skirt),
    )?)
}

/// `--auto-size`'s bone scale factors: for every joint at the far end of a bone of the
/// sizing's ellipsoid model, a factor drawn uniformly in [0.9, 1.1] (seeded); 1 elsewhere.
fn bone_factors(model: &EllipsoidModel, seed: u64) -> Vec<f64> {
    let rng = SplitMix64::new(seed);
    let mut factors = vec![1.0; model.skeleton().joint_count()];
    for (k, bone) in model.bones().iter().enumerate() {
        if let Some(c) = bone.child {
            factors[c] = 0.9 + 0.2 * rng.uniform_at(k as u64);
        }
    }
    factors
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
    args: &Cli,
    figures: &mut Map<String, Value>,
) -> Result<Captured, Box<dyn std::error::Error>> {
    let shape_params = ShapeParams {
        w_anchor: args.anchor_weight,
        start: args.shape_start.unwrap_or_default(),
        ..ShapeParams::default()
    };
    let default_performer = performer(spec.skirt)?;
    // The motion is made on the default skeleton (the same angles for every performer).
    let motion = motion(spec.motion, &default_performer)?;
    let auto_size = args.auto_size && !spec.skirt;
    let size_model = EllipsoidModel::with_end_sites(default_performer.skeleton.clone(), 0.1)?;
    let performer = if auto_size {
        default_performer.with_bone_scales(
            &bone_factors(&size_model, args.size_seed),
            &deformation(spec.skirt),
        )?
    } else {
        default_performer
    };
    let (name, first) = (spec.name(), spec.motion.first_frame());
    let label = format!("{}{name}", spec.stage_prefix);
    let root = performer
        .skeleton
        .forward_kinematics(motion.frame(first))?
        .joint_positions()[0];
    let k = Intrinsics::from_horizontal_fov(55f64.to_radians(), width, height)?;
    let rig = Rig::ring(
        8,
        3.5,
        args.camera_height_m.map_or(root.y + 0.15, |h| {
            performer
                .template
                .vertices
                .iter()
                .map(|v| v.y)
                .fold(f64::INFINITY, f64::min)
                + h
        }),
        root,
        DVec3::Y,
        k,
    )?;
    let step = match args.fps {
        Some(fps) if fps.is_finite() && fps > 0.0 => {
            ((1.0 / motion.frame_time_s / fps).round() as usize).max(1)
        }
        Some(fps) => return Err(format!("--fps {fps}: give a positive frame rate").into()),
        None => FRAME_STEP,
    };
    let cameras = rig.cameras.clone();
    let capture_spec = CaptureSpec::masks_only(rig).with_frame_rate_hz(1.0 / motion.frame_time_s);
    let capture = Capture::new(&performer, &motion, capture_spec)?;
    let mut embedding = TemplateEmbedding::new(
        &performer,
        args.template_vertices,
        args.loose_skirt,
        args.scan_template,
    )?;

    // Observations (§2.3.2, §2.4.2).
    let stage = run.stage(
        &format!("{label}: capture and observe"),
        Some(spec.frames as u64),
    );
    let (mut truths, mut masks, mut observations) = (vec![], vec![], vec![]);
    let mut observe_s = 0.0;
    let last = first + step * spec.frames;
    if last > motion.frame_count() {
        return Err(format!(
            "{}: {} frames from {} every {} pass the motion's {}",
            name,
            spec.frames,
            first,
            step,
            motion.frame_count()
        )
        .into());
    }
    for f in capture.frames_stepped(first..last, step) {
        let f = f?;
        let m = f.masks();
        let t0 = Instant::now();
        observations.push(FrameObservation::new(
            &cameras,
            &m,
            &ContourRayHullParams::default(),
            &SilhouetteParams::default(),
        )?);
        observe_s += t0.elapsed().as_secs_f64();
        masks.push(m);
        truths.push(f.truth);
        stage.inc(1);
    }
    stage.finish(format!("{} frames", truths.len()));
    let n = truths.len() as f64;

    // §2.3 then §2.4; the first frame's true pose stands in for the user's fit of frame 0,
    // or (`--auto-init`) the automatic initialisation replaces it.
    let params = PoseParams::default();
    let sequence = |template: &Template, first_pose: &[f64]| {
        capture_sequence(
            template,
            &observations,
            first_pose,
            &[],
            &params,
            &shape_params,
        )
    };
    let result = if auto_size {
        // The tracker is given the default proportions, sized from its own first frames.
        let true_template = embedding.template.clone();
        let default_template = true_template.resized(size_model.skeleton().clone())?;
        let stage = run.stage(&format!("{label}: automatic first pose"), None);
        let first_pose = auto_init(
            &default_template,
            &observations[0],
            &truths[0].theta,
            &name,
            figures,
        )?;
        stage.finish("");
        let stage = run.stage(&format!("{label}: sizing (3 tracker runs)"), None);
        let t0 = Instant::now();
        let default_result = sequence(&default_template, &first_pose)?;
        let t1 = Instant::now();
        let sizing = size_from_poses(
            &size_model,
            &observations,
            &default_result.poses.poses,
            &SizingParams::default(),
        )?;
        let size_s = t1.elapsed().as_secs_f64();
        let sized_template = default_template.resized(sizing.skeleton(&size_model)?)?;
        let sized_result = sequence(&sized_template, &first_pose)?;
        let true_result = sequence(&true_template, &first_pose)?;
        let key = |k: &str| format!("{name}_auto_size_{k}");
        let scored = SizeScoring {
            model: &size_model,
            // Scored against the truth: the performer's own rig.
            reference: &reference_sizes(&size_model, &embedding.oracle_template, 0.05)?,
        };
        // Diagnostic: the sizing from the true poses (the fit's own error, without the
        // tracked poses').
        let true_poses: Vec<Vec<f64>> = truths.iter().map(|t| t.theta.clone()).collect();
        let oracle = size_from_poses(
            &size_model,
            &observations,
            &true_poses,
            &SizingParams::default(),
        )?;
        for (which, state) in [
            ("sized", sizing.state()?.clone()),
            ("from_true_poses", oracle.state()?.clone()),
            (
                "default",
                size_model.initial_state(&sizing.state()?.theta, 0.05)?,
            ),
        ] {
            let (length, width, per_bone) = scored.errors(&state)?;
            figures.insert(key(&format!("{which}_bone_length_error_mm")), json!(length));
            figures.insert(key(&format!("{which}_width_error_mm")), json!(width));
            figures.insert(key(&format!("{which}_per_bone_mm")), per_bone);
        }
        for (which, template, result) in [
            ("default", &default_template, &default_result),
            ("sized", &sized_template, &sized_result),
            ("true", &true_template, &true_result),
        ] {
            let embedded = TemplateEmbedding {
                template: template.clone(),
                ..embedding.clone()
            };
            let (joint, sil, vertex) =
                tracker_scores(&embedded, &performer, &truths, &masks, &cameras, result)?;
            figures.insert(key(&format!("{which}_joint_error_mm")), json!(joint));
            figures.insert(key(&format!("{which}_silhouette_error_pct")), json!(sil));
            figures.insert(key(&format!("{which}_vertex_rms_mm")), json!(vertex));
        }
        figures.insert(key("frames_sized"), json!(sizing.chosen));
        figures.insert(key("fit_s"), json!(size_s));
        figures.insert(key("s"), json!(t0.elapsed().as_secs_f64()));
        stage.finish("");
        // The run's figures and pictures are the sized template's.
        embedding.template = sized_template;
        sized_result
    } else {
        let first_pose = if args.auto_init {
            let stage = run.stage(&format!("{label}: automatic first pose"), None);
            let theta = auto_init(
                &embedding.template,
                &observations[0],
                &truths[0].theta,
                &name,
                figures,
            )?;
            stage.finish("");
            theta
        } else {
            truths[0].theta.clone()
        };
        let stage = run.stage(&format!("{label}: pose and shape"), None);
        let result = if args.oracle_user {
            let mut user = OracleUser::new(
                embedding.template.skeleton(),
                &performer.skeleton,
                truths.iter().map(|t| t.theta.clone()).collect(),
                [cameras[0].clone(), cameras[cameras.len() / 4].clone()],
                args.user_threshold_mm * 1e-3,
            )?;
            capture_sequence_corrected(
                &embedding.template,
                &observations,
                &first_pose,
                &[],
                &mut user,
                &params,
                &shape_params,
            )?
        } else {
            sequence(&embedding.template, &first_pose)?
        };
        stage.finish(format!(
            "pose {:.2} s, shape {:.2} s per frame",
            result.pose_seconds / n,
            result.shape_seconds / n
        ));
        result
    };
    let template = &embedding.template;
    // Diagnostic (`--true-pose-shape`): Algorithm 1 on the true poses, which separates the
    // molding's own error from the tracker's.
    let true_shapes = if args.true_pose_shape {
        let stage = run.stage(&format!("{label}: shape on the true poses"), None);
        let shapes = ShapeEstimator::new(template.clone(), shape_params.clone())?.estimate(
            &truths
                .iter()
                .zip(&observations)
                .map(|(t, o)| ShapeFrame {
                    theta: &t.theta,
                    rays: &o.rays,
                })
                .collect::<Vec<_>>(),
        )?;
        stage.finish("");
        Some(shapes)
    } else {
        None
    };
    let reoptimise_ms = reoptimise_ms(template, &observations, &result, &cameras[0], &params)?;

    // Scores.
    let stage = run.stage(&format!("{label}: score"), Some(spec.frames as u64));
    let sk = template.skeleton();
    let original = &embedding.original;
    let garment = performer.garment_vertices();
    let (skirt, body): (Vec<usize>, Vec<usize>) =
        (0..original.len()).partition(|&v| embedding.on_skirt[v]);
    let deforming: Vec<usize> = body
        .iter()
        .copied()
        .filter(|&v| {
            truths
                .iter()
                .any(|t| t.posed.pose_displacement[original[v]].length() >= DEFORMING_MIN_M)
        })
        .collect();
    let (mut joint, mut sil, mut sil_lbs) = (vec![], vec![], vec![]);
    // Edge error (Table 2.1) of the result, of skinning with the same poses and of the
    // template's vertices on the true surface (what the truth's own motion stretches).
    let mut edge: [Vec<f64>; 3] = [vec![], vec![], vec![]];
    // Per vertex subset (all, skirt, body, pose-deforming): the result, then skinning with
    // the same poses, the true poses, the true poses and the generator's weights (oracle),
    // the true poses and weights without visibility, and the result on the true poses.
    let subsets: [(&str, Option<&[usize]>); 4] = [
        ("", None),
        ("skirt_", Some(&skirt)),
        ("body_", Some(&body)),
        ("deforming_", Some(&deforming)),
    ];
    let mut scores = vec![[vec![], vec![], vec![], vec![], vec![], vec![]]; subsets.len()];
    // Two-way surface distances, m: the result, skinning with the same poses, and the
    // template's vertices placed on the true surface (the oracle of what this template's
    // topology can attain).
    let mut surface: [Vec<SurfaceScore>; 3] = [vec![], vec![], vec![]];
    for (t, truth) in truths.iter().enumerate() {
        let true_mesh = truth.true_mesh(&performer);
        let true_v = &embedding.truth(&true_mesh)?;
        let true_query = MeshQuery::new(&true_mesh)?;
        let true_skirt: Vec<DVec3> = garment.clone().map(|v| true_mesh.vertices[v]).collect();
        let true_seen: Vec<DVec3> = (0..true_mesh.vertex_count())
            .filter(|&v| !embedding.hidden[v])
            .map(|v| true_mesh.vertices[v])
            .collect();
        joint.push(joint_error_mm(
            sk,
            &result.poses.poses[t],
            &performer.skeleton,
            &truth.theta,
        )?);
        let lbs = template.skin(&result.poses.poses[t])?;
        let lbs_true = template.skin(&truth.theta)?;
        let lbs_oracle = embedding.oracle_template.skin(&truth.theta)?;
        let lbs_no_visibility = embedding.no_visibility_template.skin(&truth.theta)?;
        for (s, (_, subset)) in subsets.iter().enumerate() {
            if subset.is_some_and(|v| v.is_empty()) {
                continue;
            }
            scores[s][0].push(rms_mm(&result.shapes.frames[t], true_v, *subset));
            scores[s][1].push(rms_mm(&lbs, true_v, *subset));
            scores[s][2].push(rms_mm(&lbs_true, true_v, *subset));
            scores[s][3].push(rms_mm(&lbs_oracle, true_v, *subset));
            scores[s][4].push(rms_mm(&lbs_no_visibility, true_v, *subset));
            if let Some(shapes) = &true_shapes {
                scores[s][5].push(rms_mm(&shapes.frames[t], true_v, *subset));
            }
        }
        let molded = template.mesh_with(result.shapes.frames[t].clone());
        let lbs_mesh = template.mesh_with(lbs);
        for (k, mesh) in [&molded, &lbs_mesh, &template.mesh_with(true_v.clone())]
            .into_iter()
            .enumerate()
        {
            edge[k].push(edge_error_pct(template.mesh(), &mesh.vertices)?);
            surface[k].push(SurfaceScore::new(
                mesh,
                &skirt,
                &true_query,
                &true_seen,
                &true_skirt,
            )?);
        }
        sil.push(mean(&silhouette_error_pct(&molded, &cameras, &masks[t])?));
        sil_lbs.push(mean(&silhouette_error_pct(&lbs_mesh, &cameras, &masks[t])?));
        stage.inc(1);
    }
    stage.finish("");
    let key = |k: &str| format!("{name}_{k}");
    let mut put = |k: &str, v: Value| {
        figures.insert(key(k), v);
    };
    put("frames", json!(truths.len()));
    put("fps", json!(1.0 / (motion.frame_time_s * step as f64)));
    put("skirt", json!(spec.skirt));
    put("template_vertices", json!(template.mesh().vertex_count()));
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
        put(
            &format!("lbs_oracle_pose_{prefix}vertex_rms_mm"),
            json!(mean(&scores[s][3])),
        );
        put(
            &format!("lbs_no_visibility_true_pose_{prefix}vertex_rms_mm"),
            json!(mean(&scores[s][4])),
        );
        if !scores[s][5].is_empty() {
            put(
                &format!("molded_true_pose_{prefix}vertex_rms_mm"),
                json!(mean(&scores[s][5])),
            );
        }
    }
    put(
        "heat_weights_mean_abs_diff",
        json!(embedding.weights_mean_abs_diff.0),
    );
    put(
        "heat_weights_no_visibility_mean_abs_diff",
        json!(embedding.weights_mean_abs_diff.1),
    );
    // Per mesh (result, LBS, oracle) and part (whole, skirt): the frames' mean and p95, mm.
    for (k, prefix) in ["", "lbs_", "oracle_attainable_"].iter().enumerate() {
        let whole: Vec<&DistanceStats> = surface[k].iter().map(|s| &s.whole).collect();
        let skirt: Vec<&DistanceStats> =
            surface[k].iter().filter_map(|s| s.skirt.as_ref()).collect();
        for (part, frames) in [("", whole), ("skirt_", skirt)] {
            if frames.is_empty() {
                continue;
            }
            for (stat, of) in [
                (
                    "mean",
                    (|d: &DistanceStats| d.mean) as fn(&DistanceStats) -> f64,
                ),
                ("p95", |d| d.p95),
            ] {
                let v: Vec<f64> = frames.iter().map(|d| of(d)).collect();
                put(
                    &format!("{prefix}{part}surface_{stat}_mm"),
                    json!(1e3 * mean(&v)),
                );
            }
        }
    }
    // The skirt's surface distance against LBS's with the same poses (goal: at most ½).
    let skirt_mean = |k: usize| {
        let v: Vec<f64> = surface[k]
            .iter()
            .filter_map(|s| Some(s.skirt.as_ref()?.mean))
            .collect();
        (!v.is_empty()).then(|| mean(&v))
    };
    if let (Some(m), Some(l)) = (skirt_mean(0), skirt_mean(1)) {
        put("skirt_surface_ratio_lbs", json!(m / l));
    }
    let added = &result.poses.added_user_rays;
    let fixed = added.iter().filter(|r| !r.is_empty()).count();
    put("fixed_frames", json!(fixed));
    put("fixed_frames_pct", json!(100.0 * fixed as f64 / n));
    put(
        "user_rays",
        json!(added.iter().map(Vec::len).sum::<usize>()),
    );
    put("heat_weights_s", json!(embedding.heat_weights_s));
    put("deforming_vertices", json!(deforming.len()));
    put("silhouette_error_pct", json!(mean(&sil)));
    put("lbs_silhouette_error_pct", json!(mean(&sil_lbs)));
    for (k, prefix) in ["", "lbs_", "oracle_attainable_"].iter().enumerate() {
        put(&format!("{prefix}edge_error_pct"), json!(mean(&edge[k])));
    }
    put("observe_s_per_frame", json!(observe_s / n));
    put("pose_s_per_frame", json!(result.pose_seconds / n));
    put("shape_s_per_frame", json!(result.shape_seconds / n));
    put("reoptimise_ms", json!(reoptimise_ms));
    Ok(Captured {
        performer,
        embedding,
        truths,
        observations,
        result,
        sil,
        sil_lbs,
        frame_time_s: motion.frame_time_s * step as f64,
    })
}

/// The sizing's errors against the true performer's reference sizes
/// ([`reference_sizes`]), over the limbs (bones between two joints).
struct SizeScoring<'a> {
    model: &'a EllipsoidModel,
    reference: &'a EllipsoidState,
}

impl SizeScoring<'_> {
    /// Mean bone length and half-width errors, mm, and per bone `{joint: [length, width]}`.
    fn errors(
        &self,
        state: &EllipsoidState,
    ) -> Result<(f64, f64, Value), Box<dyn std::error::Error>> {
        let at_rest = |s: &EllipsoidState| EllipsoidState {
            theta: self.model.skeleton().rest_pose(),
            ..s.clone()
        };
        let scores = score_ellipsoids(self.model, &at_rest(state), &at_rest(self.reference))?;
        let (fitted, truth) = (
            self.model.bone_lengths(state),
            self.model.bone_lengths(self.reference),
        );
        let sk = self.model.skeleton();
        let mut per_bone = Map::new();
        for (b, bone) in self.model.bones().iter().enumerate() {
            if let Some(c) = bone.child {
                per_bone.insert(
                    sk.joints()[c].name.clone(),
                    json!([
                        1e3 * (fitted[b] - truth[b]),
                        1e3 * (state.half_width[b] - self.reference.half_width[b])
                    ]),
                );
            }
        }
        Ok((
            scores.bone_length_error_mm,
            scores.width_error_mm,
            Value::Object(per_bone),
        ))
    }
}

/// Mean distance between the joints of `estimate` posed by `theta` and of the performer's
/// `truth` skeleton posed by `true_theta`, mm (the skeletons may differ in bone lengths).
fn joint_error_mm(
    estimate: &Skeleton,
    theta: &[f64],
    truth: &Skeleton,
    true_theta: &[f64],
) -> Result<f64, Box<dyn std::error::Error>> {
    let est = estimate.forward_kinematics(theta)?.joint_positions();
    let tru = truth.forward_kinematics(true_theta)?.joint_positions();
    let d: Vec<f64> = est.iter().zip(&tru).map(|(a, b)| a.distance(*b)).collect();
    Ok(1e3 * mean(&d))
}

/// A tracker run's mean joint error (mm, against the true performer's joints), silhouette
/// error (%) and vertex RMS of the molded result (mm).
fn tracker_scores(
    embedding: &TemplateEmbedding,
    performer: &Performer,
    truths: &[FrameTruth],
    masks: &[Vec<Mask>],
    cameras: &[Camera],
    result: &SequenceCapture,
) -> Result<(f64, f64, f64), Box<dyn std::error::Error>> {
    let template = &embedding.template;
    let (mut joint, mut sil, mut vertex) = (vec![], vec![], vec![]);
    for (t, truth) in truths.iter().enumerate() {
        joint.push(joint_error_mm(
            template.skeleton(),
            &result.poses.poses[t],
            &performer.skeleton,
            &truth.theta,
        )?);
        let molded = template.mesh_with(result.shapes.frames[t].clone());
        sil.push(mean(&silhouette_error_pct(&molded, cameras, &masks[t])?));
        let true_v = embedding.truth(&truth.true_mesh(performer))?;
        vertex.push(rms_mm(&molded.vertices, &true_v, None));
    }
    Ok((mean(&joint), mean(&sil), mean(&vertex)))
}

/// The automatic first pose (`initialise_pose`) of a run's first frame, with its errors and
/// those of the baseline that could have won (the rest pose at the hull's centroid, then the
/// same robust fit) under `{name}_auto_init_*` and `{name}_rest_init_*`.
fn auto_init(
    template: &Template,
    first: &FrameObservation,
    truth: &[f64],
    name: &str,
    figures: &mut Map<String, Value>,
) -> Result<Vec<f64>, Box<dyn std::error::Error>> {
    let sk = template.skeleton();
    let model = EllipsoidModel::with_end_sites(sk.clone(), 0.1)?;
    let params = AutoInitParams::default();
    let t = Instant::now();
    let auto = initialise_pose(&model, &first.hull, &first.rays, &params)?;
    let auto_s = t.elapsed().as_secs_f64();
    // Baseline: the rest pose moved to the hull samples' centroid, then the same fit.
    let rest_fit = rest_pose_start(&model, &first.hull, &first.rays, &params)?;
    for (key, theta) in [
        ("auto_init", auto.theta()),
        ("auto_init_global", auto.global.theta.as_slice()),
        ("rest_init", rest_fit.state.theta.as_slice()),
    ] {
        let (joint_m, angle) = pose_error(sk, theta, truth)?;
        figures.insert(format!("{name}_{key}_joint_error_mm"), json!(1e3 * joint_m));
        figures.insert(
            format!("{name}_{key}_angle_error_deg"),
            json!(angle.to_degrees()),
        );
    }
    figures.insert(format!("{name}_auto_init_s"), json!(auto_s));
    figures.insert(
        format!("{name}_auto_init_evaluations"),
        json!(auto.evaluations),
    );
    figures.insert(format!("{name}_auto_init_fit_kept"), json!(auto.fit_kept));
    Ok(auto.theta().to_vec())
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

fn pictures(
    run: &mut Run,
    c: &Captured,
    name: &str,
    figures: &mut Map<String, Value>,
) -> Result<(), Box<dyn std::error::Error>> {
    let template = &c.embedding.template;
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
    let truth = &c.embedding.truth(&truth_mesh)?;
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
    editing(run, c, name, t, figures)?;
    // The template's texture coordinates serve every frame (§2.5.3, Figure 2-8): the file
    // holds the vertices split at the atlas' seams, each frame gathered onto them.
    let glb = run.path("sequence.glb");
    let frames = &c.result.shapes.frames;
    match &c.embedding.uvs {
        Some(uvs) => {
            let split = uvs.split_seams(template.mesh())?;
            let gathered = frames
                .iter()
                .map(|f| split.gather(f))
                .collect::<Result<Vec<_>, _>>()?;
            save_gltf_animation(
                &glb,
                &MeshSequence {
                    faces: &split.faces,
                    frames: &gathered,
                    frame_time_s: c.frame_time_s,
                    uvs: Some(&split.uvs),
                    name,
                },
            )?;
        }
        None => save_gltf_animation(
            &glb,
            &MeshSequence {
                faces: &template.mesh().faces,
                frames,
                frame_time_s: c.frame_time_s,
                uvs: None,
                name,
            },
        )?,
    }
    Ok(())
}

/// A geometry edit of the template carried to every frame by deformation transfer (§2.5.3,
/// Figure 2-9): the head grown by 25 % about the neck, blended over 6 cm above it.
/// Writes `editing.png` and the figures `edit_transfer_ms_per_frame` and
/// `edit_unedited_shift_mm` (RMS motion of the vertices the edit left alone, against the
/// captured frames: the transfer must not disturb them).
fn editing(
    run: &mut Run,
    c: &Captured,
    name: &str,
    t: usize,
    figures: &mut Map<String, Value>,
) -> Result<(), Box<dyn std::error::Error>> {
    let template = &c.embedding.template;
    let sk = template.skeleton();
    let neck = sk.joint_index("neck").ok_or("no neck joint")?;
    let centre = sk
        .forward_kinematics(&vec![0.0; sk.dof_count()])?
        .joint_positions()[neck];
    let edited: Vec<DVec3> = template
        .mesh()
        .vertices
        .iter()
        .map(|v| {
            let s = ((v.y - centre.y) / 0.06).clamp(0.0, 1.0);
            let grow = 0.25 * s * s * (3.0 - 2.0 * s);
            *v + (*v - centre) * grow
        })
        .collect();
    let transfer = DeformationTransfer::new(template.mesh(), &edited)?;
    let frames = &c.result.shapes.frames;
    let t0 = Instant::now();
    let out = transfer.transfer_sequence(frames)?;
    let ms = 1e3 * t0.elapsed().as_secs_f64() / frames.len() as f64;
    let unedited: Vec<usize> = (0..edited.len())
        .filter(|&v| edited[v] == template.mesh().vertices[v])
        .collect();
    let shift: Vec<f64> = frames
        .iter()
        .zip(&out)
        .map(|(f, e)| rms_mm(f, e, Some(&unedited)))
        .collect();
    figures.insert("edit_transfer_ms_per_frame".into(), json!(ms));
    figures.insert("edit_unedited_shift_mm".into(), json!(mean(&shift)));
    let grey = Paint::Flat([180, 180, 180]);
    let blue = Paint::Flat([120, 170, 220]);
    let meshes = [
        template.mesh().clone(),
        template.mesh_with(edited),
        template.mesh_with(frames[t].clone()),
        template.mesh_with(out[t].clone()),
    ];
    let panels: Vec<PreviewPanel> = meshes
        .iter()
        .zip([grey, blue, grey, blue])
        .map(|(mesh, paint)| PreviewPanel { mesh, paint })
        .collect();
    let img = example_kit::plot::titled(
        &preview(&panels, 320)?,
        &format!("{name}, frame {t}: a template edit carried to the capture (Figure 2-9)"),
        Some("left to right: template, edited template (head +25 %), captured frame, edited frame (deformation transfer)"),
    )?;
    run.save_picture(
        "editing.png",
        &img,
        "Deformation transfer of a template edit (the head grown by 25 %) to a captured frame",
    )?;
    Ok(())
}

/// Runs `specs` with `args` (its protocol applied) at `size`, pictures of the first when
/// `pictures_first`; the runs' figures prefixed by their names, and each figure's mean over
/// the skirt runs unprefixed (`user_rays`: their sum).
fn run_all(
    run: &mut Run,
    specs: &[RunSpec],
    size: (u32, u32),
    args: &Cli,
    pictures_first: bool,
) -> Result<Map<String, Value>, Box<dyn std::error::Error>> {
    let mut figures = Map::new();
    for (i, spec) in specs.iter().enumerate() {
        let captured = capture_run(run, spec, size, args, &mut figures)?;
        if i == 0 && pictures_first {
            let stage = run.stage("pictures", None);
            pictures(run, &captured, &spec.name(), &mut figures)?;
            stage.finish("");
        }
    }
    let skirt_runs: Vec<String> = specs
        .iter()
        .filter(|r| r.skirt)
        .map(RunSpec::name)
        .collect();
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
    let user_rays: u64 = skirt_runs
        .iter()
        .filter_map(|r| figures.get(&format!("{r}_user_rays"))?.as_u64())
        .sum();
    figures.insert("user_rays".into(), json!(user_rays));
    figures.insert("skirt_runs".into(), json!(skirt_runs));
    Ok(figures)
}

/// One row of the `protocol` table: the [`TABLE_FIGURES`] of `figures`, with the size.
fn table_row(figures: &Map<String, Value>, size: (u32, u32), frames: usize) -> Value {
    let mut row: Map<String, Value> = TABLE_FIGURES
        .iter()
        .filter_map(|&k| Some((k.to_string(), figures.get(k)?.clone())))
        .collect();
    row.insert("image_width_px".into(), json!(size.0));
    row.insert("image_height_px".into(), json!(size.1));
    row.insert("frames_per_run".into(), json!(frames));
    row.insert("runs".into(), figures["skirt_runs"].clone());
    Value::Object(row)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = Cli::parse();
    args.auto_init |= args.auto_size;
    let quick = args.common.quick;
    args.true_pose_shape |= quick;
    let main_args = {
        let mut a = args.clone();
        a.protocol.apply(&mut a);
        a
    };
    let size = args
        .resolution
        .unwrap_or(if quick { (480, 360) } else { (1600, 1200) });
    let n = args.frames.unwrap_or(if quick { 12 } else { 100 });
    // The skirt protocol first, then the body alone for reference.
    let run_spec = |skirt, motion, frames, prefix: &str| RunSpec {
        skirt,
        motion,
        frames,
        stage_prefix: prefix.to_string(),
    };
    let runs: Vec<RunSpec> = if quick {
        vec![
            run_spec(false, MotionKind::Exercise, n, ""),
            run_spec(true, MotionKind::Exercise, args.frames.unwrap_or(8), ""),
        ]
    } else {
        vec![
            run_spec(true, MotionKind::Exercise, n, ""),
            run_spec(true, MotionKind::Fast, n, ""),
            run_spec(true, MotionKind::Walk, n, ""),
            run_spec(false, MotionKind::Exercise, n, ""),
        ]
    };
    let runs: Vec<RunSpec> = runs
        .into_iter()
        .filter(|r| args.runs.is_empty() || args.runs.contains(&r.name()))
        .collect();
    if runs.is_empty() {
        return Err(format!("no run is called any of {:?}", args.runs).into());
    }
    let table = args.protocol_table || (!quick && !args.no_protocol_table);
    let mut run = Run::start(
        "template_capture",
        &args.common,
        &format!(
            "MakeHuman with and without its skirt, 8 cameras at {}×{}, runs: {}, protocol {}: \
             pose tracking in the visual hulls, then Laplacian molding to the silhouettes \
             (Vlasic 2010 Ch. 2){}",
            size.0,
            size.1,
            runs.iter()
                .map(RunSpec::name)
                .collect::<Vec<_>>()
                .join(", "),
            main_args.protocol.key(),
            if table {
                format!(
                    "; every protocol on the skirt exercise and walk at {}×{}, {} frames",
                    args.table_resolution.0, args.table_resolution.1, args.table_frames
                )
            } else {
                String::new()
            }
        ),
    )?;
    let mut figures = run_all(&mut run, &runs, size, &main_args, true)?;
    if table {
        let mut rows = Map::new();
        for p in Protocol::ALL {
            let specs: Vec<RunSpec> = [MotionKind::Exercise, MotionKind::Walk]
                .into_iter()
                .map(|m| run_spec(true, m, args.table_frames, &format!("{}/", p.key())))
                .collect();
            let mut a = p.only(&args);
            a.true_pose_shape = false;
            let f = run_all(&mut run, &specs, args.table_resolution, &a, false)?;
            rows.insert(
                p.key().into(),
                table_row(&f, args.table_resolution, args.table_frames),
            );
        }
        let skirt_main: Vec<&RunSpec> = runs.iter().filter(|r| r.skirt).collect();
        if !quick && !skirt_main.is_empty() {
            // The thesis' protocol at the main runs' size (the headline's is the main runs).
            let specs: Vec<RunSpec> = skirt_main
                .iter()
                .map(|r| run_spec(true, r.motion, r.frames, "thesis_full/"))
                .collect();
            let mut a = Protocol::Thesis.only(&args);
            a.true_pose_shape = false;
            let f = run_all(&mut run, &specs, size, &a, false)?;
            rows.insert("thesis_full".into(), table_row(&f, size, n));
        }
        rows.insert(
            format!("{}_full", main_args.protocol.key()),
            table_row(&figures, size, n),
        );
        figures.insert("protocol".into(), Value::Object(rows));
    }
    // The thesis' protocol at full size beside the headline's (from the table).
    if let Some(row) = figures
        .get("protocol")
        .and_then(|t| t.get("thesis_full"))
        .and_then(Value::as_object)
        .cloned()
    {
        for (k, v) in row.into_iter().filter(|(_, v)| v.is_f64()) {
            figures.insert(format!("thesis_{k}"), v);
        }
    }
    let args = main_args;
    figures.insert("protocol_name".into(), json!(args.protocol.key()));
    figures.insert("image_width_px".into(), json!(size.0));
    figures.insert("image_height_px".into(), json!(size.1));
    figures.insert("oracle_user".into(), json!(args.oracle_user));
    figures.insert("scan_template".into(), json!(args.scan_template));
    figures.insert(
        "shape_start".into(),
        json!(format!("{:?}", args.shape_start.unwrap_or_default())),
    );
    if let Some(h) = args.camera_height_m {
        figures.insert("camera_height_m".into(), json!(h));
    }
    if args.oracle_user {
        figures.insert("user_threshold_mm".into(), json!(args.user_threshold_mm));
    }
    if args.auto_init {
        figures.insert("first_pose".into(), json!("automatic"));
    }
    if args.auto_size {
        figures.insert("proportions".into(), json!("sized"));
        figures.insert("size_seed".into(), json!(args.size_seed));
    }
    figures.insert("peak_rss_mb".into(), json!(example_kit::peak_rss_mb()));
    for h in [
        Headline::new("joint_error_mm", "joint error (skirt runs)", "mm").goal(Goal::AtMost(30.0)),
        Headline::new("silhouette_error_pct", "silhouette error", "%")
            .paper("6.11–14.10 %, Table 2.1")
            .goal(Goal::AtMost(10.0)),
        Headline::new("edge_error_pct", "edge error", "%")
            .paper("8.69–13.27 %, Table 2.1")
            .goal(Goal::AtMost(13.0)),
        Headline::new(
            "oracle_attainable_edge_error_pct",
            "template vertices on the true surface: edge error",
            "%",
        )
        .oracle(),
        Headline::new("fixed_frames_pct", "frames fixed by the user", "%")
            .paper("0–13 fixed frames per sequence, Table 2.1")
            .goal(Goal::AtMost(5.0)),
        Headline::new("user_rays", "user rays placed (all skirt runs)", ""),
        Headline::new(
            "skirt_surface_mean_mm",
            "skirt two-way surface distance, mean",
            "mm",
        ),
        Headline::new(
            "lbs_skirt_surface_mean_mm",
            "LBS (same poses) skirt surface distance, mean",
            "mm",
        )
        .baseline(),
        Headline::new(
            "skirt_surface_ratio_lbs",
            "skirt surface distance / LBS's",
            "",
        )
        .goal(Goal::AtMost(0.5)),
        Headline::new(
            "thesis_skirt_surface_mean_mm",
            "the thesis' start (Eq. 2.1 each frame): skirt surface distance, mean",
            "mm",
        )
        .baseline(),
        Headline::new(
            "oracle_attainable_skirt_surface_mean_mm",
            "template vertices on the true surface: skirt surface distance, mean",
            "mm",
        )
        .oracle(),
        Headline::new("surface_mean_mm", "two-way surface distance, mean", "mm"),
        Headline::new("surface_p95_mm", "two-way surface distance, p95", "mm"),
        Headline::new(
            "lbs_surface_mean_mm",
            "LBS (same poses) surface distance, mean",
            "mm",
        )
        .baseline(),
        Headline::new("vertex_rms_mm", "vertex RMS error", "mm").goal(Goal::AtMost(15.0)),
        Headline::new("lbs_vertex_rms_mm", "LBS (same poses) vertex RMS", "mm").baseline(),
        Headline::new(
            "body_exercise_joint_error_mm",
            "body alone: joint error",
            "mm",
        )
        .goal(Goal::AtMost(20.0)),
        Headline::new(
            "body_exercise_silhouette_error_pct",
            "body alone: silhouette error",
            "%",
        )
        .goal(Goal::AtMost(3.0)),
        Headline::new(
            "body_exercise_edge_error_pct",
            "body alone: edge error",
            "%",
        )
        .goal(Goal::AtMost(8.0)),
        Headline::new("pose_s_per_frame", "pose time per frame", "s")
            .paper("7.6 s (4.3 s forward + 3.3 s backward, Samba), thesis §2.5.2")
            .goal(Goal::AtMost(0.3)),
        Headline::new("shape_s_per_frame", "shape time per frame", "s")
            .paper("4.8 s (Samba), thesis §2.5.2")
            .goal(Goal::AtMost(0.3)),
        Headline::new("reoptimise_ms", "one re-optimisation", "ms")
            .paper("\"several times per second\" while a constraint is dragged, thesis §2.5.2")
            .goal(Goal::AtMost(100.0)),
    ] {
        run.headline(h);
    }
    run.finish(Value::Object(figures))?;
    Ok(())
}
