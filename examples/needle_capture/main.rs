//! Validation of the needle model (Sand, McMillan and Popović 2003) on the synthetic studio.
//!
//! **Training**: 5 minutes of the studio's free multi-DOF exercise (every limited DOF at once,
//! seed 11) while the performer turns on the spot at 12°/s, 30 fps, seen by 3 cameras at
//! 720×480 (the paper: "local configurations repeated"). The performer has its pose-driven
//! shapes (muscles, joint creases) and no hip flap: what the test scores is what a
//! pose-driven model can predict. **Test**, never seen in training: a minute of the exercise
//! with another seed (23), and the real CMU motion capture 131_01 ("start, walk, stop",
//! retargeted; `walk_*`). Ground truth is the performer's true posed mesh
//! (`needle_model::truth`).
//!
//! Compared on the same needles: the model (capped neighbourhoods, the default), the paper's
//! fraction neighbourhoods (`fraction_*`), parameters selected automatically by silhouette
//! error (§6.3, Figure 11; `selected_*`), a **static** model (`F_near = 1`, thesis Figure
//! 6-2c; `static_*`), **LBS** of the model's own rest shape captured from the same
//! silhouettes with automatic bone-heat weights (`needle_model::baseline`; `lbs_*` with the
//! library's default weights, Pinocchio's visibility test on; `lbs_no_visibility_*` without
//! it), the same shape with the performer's own weights (`lbs_true_weights_*`), LBS of the
//! performer's EXACT rest shape (`lbs_exact_rest_*`, an oracle no capture has), and on the
//! exercise a pose-local visual-hull oracle (`hull_oracle_*`: 24 cameras on three rings see
//! every test pose; `hull_oracle_fallback_share` of the pose-deforming needle-frames no view
//! saw, `…_all_needles` of all; every predictor on the needle-frames it saw,
//! `{predictor}_observed_*`, the model's `model_observed_*`; `hull_oracle_observed_short_share`
//! the share of those pose-deforming needle-frames where the oracle is shorter than the truth
//! by more than a pixel's footprint at the ring's distance, `hull_oracle_pixel_mm`: where it
//! is no outer bound). Pose-deforming needles are
//! those whose non-skinning length spans more than 3 mm over the test
//! (`deforming_mean_mm`, `pose_r2`, ...); `deforming_error_by_effect` (and `walk_…`) splits
//! each predictor's error on them by the studio effect that moves each needle most
//! (`needle_model::truth::EffectAttribution`: skinning geometry, each pose-driven muscle or
//! crease, the flap — off here, so empty). Figures of §6: error against N (10, 30, 100, 300)
//! over 3 prototype seeds, 30 s against 5 minutes of training; the neighbourhood diagnostics
//! (`pool_max_pose_share`, `pool_radius_deg_median`, `floor_bound_share`, per primitive in
//! `pools`).
//!
//! Writes under `out/needle_capture/`:
//! * `error_vs_n.png`: error (mm) against N (log axis) — pose-deforming mean (red, each seed
//!   pink), all-needle median (blue); dashed: static, captured-rest LBS (with and without the
//!   visibility test) and exact-rest LBS at their pose-deforming means; title, axis labels
//!   and legend.
//! * `flexed_elbow.png`: the test frame of the most flexed elbow from the static model, LBS
//!   and the model, coloured by needle error with a colour bar, beside the truth (like Sand
//!   2003 Figure 12).
//! * `silhouette_error_vs_params.png`: silhouette error against F_near, F_min, W and N (log x
//!   for F_near and N), one panel each, from the last coordinate-descent sweep (like Sand 2003
//!   Figure 11), the selected value marked.
//! * `test_poses.png`: three walk poses, top row the true body (grey), bottom row the model's
//!   watertight union surface (blue).
//! * `error_map.png`: the model's per-primitive surfaces at one walk pose, coloured by needle
//!   error with a colour bar in mm (blue 0 → red ≥ 20 mm; grey: needle not scored).
//! * `figures.json`, `manifest.json` (captions and headline figures for `tour`); progress on
//!   stderr; last stdout line one JSON object.
//!
//! `cargo run --release --example needle_capture [-- --quick] [-- --out DIR]` (`--quick`:
//! procedural performer, 360×240 views, 24 s of training, one seed, small grids; under two
//! minutes).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)] // not library code

mod pictures;

use std::time::Instant;

use clap::Parser;

use dynamic_shapes::core::camera::{Camera, Rig};
use dynamic_shapes::core::image::Mask;
use dynamic_shapes::core::mesh::{HeatWeightsParams, TriMesh};
use dynamic_shapes::core::skeleton::{BvhParams, Motion, CMU_METRES_PER_UNIT};
use dynamic_shapes::core::stats::{mean, median};
use dynamic_shapes::needle::baseline::SkinnedShape;
use dynamic_shapes::needle::truth::{
    EffectAttribution, EffectErrors, Errors, HullOracle, NeedleTruth, TestSet,
};
use dynamic_shapes::needle::{
    animate, merged_mesh, primitive_meshes, select_params, union_mesh, BodyLayout, FrameInput,
    NeedleBody, NeedleModel, Neighbourhood, ObservationStore, ObserveParams, Observer, Parameter,
    PoseSpaceModel, PrimitiveFitReport, ReconstructionParams, SelectionParams,
    SilhouetteErrorParams, SilhouetteScorer, SurfaceParams, ValidationFrame,
};
use dynamic_shapes_studio::{
    exercise_motion, makehuman_performer, play_bvh, preview, procedural_performer, studio_ring,
    Capture, CaptureFrame, CaptureSpec, DeformationParams, DeformationState, ExerciseParams, Paint,
    Performer, PoseDeformParams, PreviewPanel, ProceduralBodyParams, RetargetParams,
    STUDIO_RING_HFOV_DEG, STUDIO_RING_RADIUS_M,
};
use example_kit::plot::{self as kplot, Chart, LegendPosition, Series, Style};
use example_kit::{Goal, Headline, Run};
use pictures::{needle_error_colours, with_error_bar, Figure12, Predictor};
use serde_json::{json, Map, Value};

/// Needle error at the top of the error map's colour scale, mm.
const ERROR_MAP_MAX_MM: f64 = 20.0;
/// Seed of the training exercise.
const TRAIN_SEED: u64 = 11;
/// Seed of the test exercise (another motion of the same kind).
const TEST_SEED: u64 = 23;
/// Step between the prototype seeds of the error-against-N sweep.
const SEED_STEP: u64 = 1000;

type Res<T> = Result<T, Box<dyn std::error::Error>>;

struct Setup {
    quick: bool,
    width: u32,
    height: u32,
    train_s: f64,
    short_s: f64,
    test_s: f64,
    test_stride: usize,
    walk_stride: usize,
    validation_frames: usize,
    seeds: usize,
    selection: SelectionParams,
}

impl Setup {
    fn new(quick: bool) -> Self {
        let full_grid = SelectionParams::default();
        if quick {
            Setup {
                quick,
                width: 360,
                height: 240,
                train_s: 24.0,
                short_s: 6.0,
                test_s: 8.0,
                test_stride: 8,
                walk_stride: 16,
                validation_frames: 4,
                seeds: 1,
                selection: SelectionParams {
                    f_near_grid: vec![0.01, 0.022, 0.1],
                    f_min_grid: vec![0.05, 0.1, 0.2],
                    kernel_width_w_grid: vec![2.0, 7.0, 15.0],
                    prototype_count_n_grid: vec![10, 30, 100],
                    rounds: 1,
                    ..full_grid
                },
            }
        } else {
            Setup {
                quick,
                width: 720,
                height: 480,
                train_s: 300.0,
                short_s: 30.0,
                test_s: 60.0,
                test_stride: 8,
                walk_stride: 4,
                validation_frames: 12,
                seeds: 3,
                selection: full_grid,
            }
        }
    }
}

/// The performer's deformation: its pose-driven shapes and no hip flap, so the test scores
/// what a pose-driven model can predict (the validation protocol; no garment, no wrinkles).
fn deformation() -> DeformationParams {
    DeformationParams::default().with_flap(None)
}

/// The performer with [`deformation`].
fn performer(quick: bool) -> Res<Performer> {
    let deformation = deformation();
    if !quick {
        eprintln!("performer: MakeHuman, pose-driven shapes, no flap");
        let dir = example_kit::data_path("makehuman")?;
        return Ok(makehuman_performer(dir, &deformation)?);
    }
    eprintln!("performer: procedural, pose-driven shapes, no flap");
    Ok(procedural_performer(&ProceduralBodyParams {
        deformation,
        ..Default::default()
    })?)
}

/// The studio's free multi-DOF exercise, turning on the spot, `seconds` long.
fn exercise(p: &Performer, seconds: f64, seed: u64) -> Res<Motion> {
    let params = ExerciseParams::default()
        .with_duration_s(seconds)
        .with_seed(seed);
    Ok(exercise_motion(&p.skeleton, &params)?)
}

/// A test motion's truth, plus the true silhouettes of its scored frames and which studio
/// effect moves each needle most.
struct Test {
    set: TestSet,
    masks: Vec<Vec<Mask>>,
    effects: EffectAttribution,
}

/// A silhouette capture of `motion` at its own frame rate by `rig`.
fn silhouettes<'a>(p: &'a Performer, rig: &Rig, motion: &Motion) -> Res<Capture<'a>> {
    let spec = CaptureSpec::masks_only(rig.clone()).with_frame_rate_hz(1.0 / motion.frame_time_s);
    Ok(Capture::new(p, motion, spec)?)
}

fn test_set(
    p: &Performer,
    body: &NeedleBody,
    rig: &Rig,
    motion: &Motion,
    stride: usize,
) -> Res<Test> {
    let mut set = TestSet::default();
    let mut masks = vec![];
    let pose_effects = deformation().pose.unwrap_or_else(PoseDeformParams::none);
    let mut effects = EffectAttribution::new(p, &pose_effects)?;
    let capture = silhouettes(p, rig, motion)?;
    for frame in capture.frames_stepped(0..capture.frame_count(), stride) {
        let frame = frame?;
        masks.push(frame.masks());
        set.push_frame(body, p, &frame.truth)?;
        if let Some(last) = set.frames.last() {
            effects.push_frame(body, p, &frame.truth, last)?;
        }
    }
    Ok(Test {
        set,
        masks,
        effects,
    })
}

/// Medians and tail of one predictor's errors, as JSON fields `{prefix}_…`.
fn summary(prefix: &str, e: &mut Errors, out: &mut Map<String, Value>) {
    let p90 = |v: &mut [f64]| {
        v.sort_by(f64::total_cmp);
        v.get(v.len() * 9 / 10).copied().unwrap_or(f64::NAN)
    };
    // Means near joints are summed in increasing order (the order of the figures so far).
    e.near_joints_mm.sort_by(f64::total_cmp);
    out.insert(format!("{prefix}_mean_mm"), json!(mean(&e.all_mm)));
    out.insert(format!("{prefix}_median_mm"), json!(median(&e.all_mm)));
    out.insert(
        format!("{prefix}_median_near_joints_mm"),
        json!(median(&e.near_joints_mm)),
    );
    out.insert(
        format!("{prefix}_mean_near_joints_mm"),
        json!(mean(&e.near_joints_mm)),
    );
    out.insert(
        format!("{prefix}_p90_near_joints_mm"),
        json!(p90(&mut e.near_joints_mm)),
    );
    out.insert(
        format!("{prefix}_median_deforming_mm"),
        json!(median(&e.deforming_mm)),
    );
    // The pose-deforming needles (non-skinning length spanning > 3 mm over the test): the
    // model's figures carry no prefix (`deforming_mean_mm`, `pose_r2`, ...).
    let name = |field: &str| match prefix.strip_suffix("test") {
        Some(head) => format!("{head}{field}"),
        None => format!("{prefix}_{field}"),
    };
    let r2 = e.pose_r2();
    // Median per primitive (the hips' crotch is where pose-local estimates lose).
    let mut per_primitive: Vec<Vec<f64>> = vec![];
    for s in &e.samples {
        let p = s.key.0 as usize;
        if per_primitive.len() <= p {
            per_primitive.resize(p + 1, vec![]);
        }
        per_primitive[p].push((s.predicted_m - s.true_m).abs() * 1e3);
    }
    let per_primitive: Vec<f64> = per_primitive.iter().map(|v| median(v)).collect();
    out.insert(name("primitive_median_mm"), json!(per_primitive));
    out.insert(name("deforming_mean_mm"), json!(mean(&e.pose_deforming_mm)));
    out.insert(
        name("deforming_p90_mm"),
        json!(p90(&mut e.pose_deforming_mm)),
    );
    out.insert(name("pose_r2"), json!(r2.r2));
    out.insert(name("pose_r2_centred"), json!(r2.r2_centred));
    out.insert(name("deforming_bias_rms_mm"), json!(r2.bias_rms_mm));
    out.insert(name("deforming_centred_rms_mm"), json!(r2.centred_rms_mm));
    out.insert(name("deforming_pose_rms_mm"), json!(r2.pose_rms_mm));
}

/// Validation of the needle model (Sand, McMillan and Popović 2003) on the synthetic studio.
#[derive(Parser)]
struct Args {
    #[command(flatten)]
    common: example_kit::Common,
}

fn main() -> Res<()> {
    let t0 = Instant::now();
    let args = Args::parse();
    let s = Setup::new(args.common.quick);
    let mut run =
        Run::start(
            "needle_capture",
            &args.common,
            &format!(
            "Needle model (Sand 2003) trained on silhouettes of {} performer turning through a \
             free exercise ({} s, 3 cameras at {}×{}), then tested against ground truth on an \
             exercise of another seed and the real CMU 131_01 walk, never seen, beside a static \
             model and linear blend skinning of the captured rest shape; pose-deforming \
             needles, error against N, automatic parameter selection by silhouette error, \
             speed.",
            if s.quick { "the procedural" } else { "the MakeHuman" },
            s.train_s,
            s.width,
            s.height
        ),
        )?;
    let out_dir = run.out().to_path_buf();
    let performer = performer(s.quick)?;
    let sk = performer.skeleton.clone();
    let body = NeedleBody::new(&sk, &BodyLayout::table_3_1())?;
    let rig = studio_ring(3, s.width, s.height)?;
    let cameras = rig.cameras.clone();
    let observer = Observer::new(
        body.clone(),
        sk.clone(),
        cameras.clone(),
        ObserveParams::default(),
    )?;
    let mut out = Map::new();

    // --- Training captures, streamed in chunks (masks are not kept). ---
    let train = exercise(&performer, s.train_s, TRAIN_SEED)?;
    let n_train = train.frame_count();
    eprintln!(
        "training: exercise (seed {TRAIN_SEED}) turning, {n_train} frames ({:.1} s) at {:.0} fps, {} needles, 3 cameras {}×{}",
        train.duration_s(),
        1.0 / train.frame_time_s,
        body.needle_count(),
        s.width,
        s.height
    );
    let stage = run.stage("capture", Some(n_train as u64));
    let long = capture(&performer, &observer, &rig, &train, &stage)?;
    stage.finish(format!("{n_train} frames"));
    let store = long.store;
    let train_thetas = long.thetas;
    let short_motion = exercise(&performer, s.short_s, TRAIN_SEED)?;
    eprintln!(
        "short training: exercise, {} frames ({:.1} s)",
        short_motion.frame_count(),
        short_motion.duration_s()
    );
    let stage = run.stage("short capture", Some(short_motion.frame_count() as u64));
    let short_store = capture(&performer, &observer, &rig, &short_motion, &stage)?.store;
    stage.finish(format!("{} frames", short_motion.frame_count()));
    // The unit: camera-frames (one 720×480 mask walked) per second.
    let camera_frames = (n_train * cameras.len()) as f64;
    let accumulate_fps = camera_frames / long.accumulate_s;
    eprintln!(
        "accumulate {accumulate_fps:.0} camera-frames/s (render {:.0}), {} observations, {:.2} B/observation",
        camera_frames / long.render_s,
        store.total_observations(),
        store.bytes_per_observation()
    );

    // --- Test truth: motions never seen in training. ---
    let stage = run.stage("test truth", None);
    let test_motion = exercise(&performer, s.test_s, TEST_SEED)?;
    let test = test_set(&performer, &body, &rig, &test_motion, s.test_stride)?;
    let walk_motion = play_bvh(
        example_kit::data_path("mocap-cmu/131_01.bvh")?,
        &BvhParams {
            metres_per_unit: CMU_METRES_PER_UNIT,
        },
        &sk,
        train.frame_time_s,
        &RetargetParams::default(),
    )?
    .motion;
    let walk = test_set(&performer, &body, &rig, &walk_motion, s.walk_stride)?;
    let scored = |t: &Test| t.set.frames.iter().map(|f| f.needles.len()).sum::<usize>();
    stage.finish(format!(
        "exercise (seed {TEST_SEED}) {} frames ({} needles), CMU 131_01 walk {} frames ({} needles)",
        test.set.frames.len(),
        scored(&test),
        walk.set.frames.len(),
        scored(&walk)
    ));

    // --- Reconstructions and baselines. ---
    let stage = run.stage("reconstruct", None);
    let base = ReconstructionParams::default();
    let tr = Instant::now();
    let main_fit = NeedleModel::reconstruct(&store, &body, &base)?;
    let reconstruct_s = tr.elapsed().as_secs_f64();
    let main = main_fit.model.clone();
    stage.println(format!("N = 100: {reconstruct_s:.2} s"));
    // The paper's size, 8 minutes × 3 cameras = 43,200 camera-frames: the real store appended
    // to itself until it is at least that big (only the cost is of interest here).
    let mut big = store.clone();
    let mut big_camera_frames = n_train * cameras.len();
    while big_camera_frames < 43_200 {
        big.append(&store)?;
        big_camera_frames += n_train * cameras.len();
    }
    let tb = Instant::now();
    NeedleModel::reconstruct(&big, &body, &base)?;
    let reconstruct_s_24min = tb.elapsed().as_secs_f64();
    stage.println(format!(
        "at {big_camera_frames} camera-frames ({} observations): {reconstruct_s_24min:.2} s",
        big.total_observations()
    ));
    drop(big);
    let stat = NeedleModel::reconstruct(&store, &body, &base.with_f_near(1.0))?.model;
    let fraction = NeedleModel::reconstruct(
        &store,
        &body,
        &base.with_neighbourhood(Neighbourhood::Fraction),
    )?
    .model;
    let tp = Instant::now();
    let psd = PoseSpaceModel::reconstruct(
        &store,
        &body,
        &sk,
        &train_thetas,
        &base,
        &SurfaceParams::default(),
    )?
    .model;
    let psd_reconstruct_s = tp.elapsed().as_secs_f64();
    stage.println(format!(
        "residual over skinning (plain model + skinning + residual NRBF): {psd_reconstruct_s:.2} s"
    ));
    out.insert("psd_reconstruct_s".into(), json!(psd_reconstruct_s));
    stage.finish(
        "model, 24-minute store, static model, the paper's fraction neighbourhoods, the model \
         over skinning",
    );
    let stage = run.stage("score baselines", None);
    let rest = animate(&body, &main, &sk, &sk.rest_pose())?;
    let rest_mesh = union_mesh(&rest, &SurfaceParams::default())?;
    let lbs_heat = SkinnedShape::heat(&sk, rest_mesh.clone(), &HeatWeightsParams::default())?;
    let lbs_no_visibility = SkinnedShape::heat(
        &sk,
        rest_mesh.clone(),
        &HeatWeightsParams::default().without_visibility(),
    )?;
    let lbs_true = SkinnedShape::transfer(&performer, rest_mesh)?;
    let surface = |shape: &SkinnedShape, theta: &[f64]| {
        let fk = sk.forward_kinematics(theta)?;
        shape.pose(&performer, fk.world_from_joint())
    };
    let oracle = hull_oracle(&performer, &body, &s, &test_motion, &test)?;
    for (name, t) in [("", &test), ("walk_", &walk)] {
        let pre = |p: &str| format!("{name}{p}");
        let mut scored: Vec<(&str, Errors)> = vec![
            ("model", t.set.errors(&main)?),
            ("static", t.set.errors(&stat)?),
            ("fraction", t.set.errors(&fraction)?),
            ("psd", psd_errors(&psd, &body, &sk, &t.set)?),
            (
                "lbs",
                t.set
                    .surface_errors(&body, &sk, |th| surface(&lbs_heat, th))?,
            ),
            (
                "lbs_no_visibility",
                t.set
                    .surface_errors(&body, &sk, |th| surface(&lbs_no_visibility, th))?,
            ),
            (
                "lbs_true_weights",
                t.set
                    .surface_errors(&body, &sk, |th| surface(&lbs_true, th))?,
            ),
            ("lbs_exact_rest", t.set.lbs_errors()),
        ];
        // The oracle sees the exercise only (24 views of every test frame).
        if name.is_empty() {
            scored.push(("hull_oracle", oracle.errors(&t.set, &stat)?));
        }
        for (p, e) in &mut scored {
            // The model's figures: `test_*` and, for the pose figures, no prefix.
            let prefix = if *p == "model" { "test" } else { *p };
            summary(&pre(prefix), e, &mut out);
        }
        out.insert(
            pre("pose_deforming_needles"),
            json!(t.set.pose_deforming().len()),
        );
        // Every predictor on the needle-frames some oracle view saw, the oracle alone there.
        let observed = if name.is_empty() {
            let seen =
                |k: usize, n: &NeedleTruth| oracle.length(k, (n.primitive, n.needle)).is_some();
            let coverage = oracle.coverage(&t.set);
            out.insert(
                "hull_oracle_fallback_share".into(),
                json!(coverage.pose_deforming_fallback_share()),
            );
            out.insert(
                "hull_oracle_fallback_share_all_needles".into(),
                json!(coverage.fallback_share()),
            );
            let mut observed = vec![];
            for (p, e) in &scored {
                let r = e.restricted(&t.set, seen)?;
                observed_summary(p, &r, &mut out);
                observed.push((*p, r));
            }
            // Where the oracle is an outer bound: its length at least the truth's, up to one
            // pixel's footprint at the ring's distance.
            let pixel_m =
                2.0 * STUDIO_RING_RADIUS_M * (STUDIO_RING_HFOV_DEG.to_radians() / 2.0).tan()
                    / f64::from(s.width);
            if let Some((_, e)) = observed.iter().find(|(p, _)| *p == "hull_oracle") {
                out.insert("hull_oracle_pixel_mm".into(), json!(pixel_m * 1e3));
                out.insert(
                    "hull_oracle_observed_short_share".into(),
                    json!(e.pose_short_share(pixel_m)),
                );
                out.insert(
                    "hull_oracle_observed_short_share_all_needles".into(),
                    json!(e.short_share(pixel_m)),
                );
            }
            observed
        } else {
            vec![]
        };
        out.insert(
            pre("deforming_error_by_effect"),
            by_effect(&t.effects, &scored, &observed)?,
        );
    }
    out.insert(
        "test_silhouette_error".into(),
        json!(silhouette_error(&body, &main, &sk, &cameras, &test)?),
    );
    out.insert(
        "static_silhouette_error".into(),
        json!(silhouette_error(&body, &stat, &sk, &cameras, &test)?),
    );
    for k in [
        "test_median_mm",
        "static_median_mm",
        "lbs_median_mm",
        "lbs_exact_rest_median_mm",
        "deforming_mean_mm",
        "static_deforming_mean_mm",
        "fraction_deforming_mean_mm",
        "lbs_deforming_mean_mm",
        "lbs_no_visibility_deforming_mean_mm",
        "lbs_exact_rest_deforming_mean_mm",
        "hull_oracle_deforming_mean_mm",
        "hull_oracle_pose_r2_centred",
        "hull_oracle_fallback_share",
        "hull_oracle_fallback_share_all_needles",
        "hull_oracle_observed_deforming_mean_mm",
        "hull_oracle_observed_pose_r2_centred",
        "hull_oracle_observed_short_share",
        "model_observed_deforming_mean_mm",
        "model_observed_pose_r2_centred",
        "pose_r2_centred",
        "lbs_pose_r2_centred",
        "psd_deforming_mean_mm",
        "psd_pose_r2_centred",
        "walk_deforming_mean_mm",
        "walk_static_deforming_mean_mm",
        "walk_lbs_deforming_mean_mm",
    ] {
        stage.println(format!("{k}: {:.3}", out[k].as_f64().unwrap_or(f64::NAN)));
    }
    if let Some(Value::Object(rows)) = out.get("deforming_error_by_effect") {
        for (effect, row) in rows {
            if row["needles"].as_u64().unwrap_or(0) == 0 {
                continue;
            }
            let m = |p: &str| row["mean_mm"][p].as_f64().unwrap_or(f64::NAN);
            let o = |p: &str| row["observed_mean_mm"][p].as_f64().unwrap_or(f64::NAN);
            stage.println(format!(
                "{effect}: {} needles, {} needle-frames: model {:.2}, static {:.2}, lbs {:.2}, \
                 oracle {:.2} mm; seen by the oracle ({} needle-frames): model {:.2}, oracle {:.2} mm",
                row["needles"],
                row["needle_frames"],
                m("model"),
                m("static"),
                m("lbs"),
                m("hull_oracle"),
                row["observed_needle_frames"],
                o("model"),
                o("hull_oracle"),
            ));
        }
    }
    stage.finish("exercise and walk tests");

    // --- Where the neighbourhoods came from (the pool diagnostics). ---
    let pools = pool_figures(&main_fit.reports, &body);
    for (k, v) in pools {
        out.insert(k, v);
    }

    // --- Error vs N over seeds, and short vs long training (exercise test). ---
    let ns = [10usize, 30, 100, 300];
    let mut sweep: Vec<SweepPoint> = vec![];
    let stage = run.stage("error vs N", Some((ns.len() * s.seeds) as u64));
    for n in ns {
        let mut point = SweepPoint {
            n,
            ..Default::default()
        };
        for k in 0..s.seeds {
            let params = base
                .with_prototype_count_n(n)
                .with_seed(base.seed.wrapping_add(SEED_STEP * k as u64));
            // The main model (N = 100, first seed) is already reconstructed.
            let e = if params == base {
                test.set.errors(&main)?
            } else {
                test.set
                    .errors(&NeedleModel::reconstruct(&store, &body, &params)?.model)?
            };
            point.median_mm.push(median(&e.all_mm));
            point.near_joints_mm.push(median(&e.near_joints_mm));
            point.deforming_mean_mm.push(mean(&e.pose_deforming_mm));
            stage.inc(1);
        }
        stage.println(format!(
            "N = {n}: median {:.2} mm, pose-deforming mean {:.2} mm (seeds {:?})",
            mean(&point.median_mm),
            mean(&point.deforming_mean_mm),
            point.deforming_mean_mm
        ));
        sweep.push(point);
    }
    let at = |n: usize| sweep.iter().find(|p| p.n == n);
    if let (Some(a), Some(b)) = (at(10), at(100)) {
        let (ma, mb) = (mean(&a.deforming_mean_mm), mean(&b.deforming_mean_mm));
        out.insert("n10_to_100_drop".into(), json!(1.0 - mb / ma));
        out.insert("n10_to_100_drop_mm".into(), json!(ma - mb));
        out.insert("n_seed_spread_mm".into(), json!(a.spread().max(b.spread())));
    }
    out.insert(
        "median_vs_n".into(),
        json!(sweep.iter().map(SweepPoint::to_json).collect::<Vec<_>>()),
    );
    stage.finish(format!("N = 10, 30, 100, 300 × {} seeds", s.seeds));
    // A primitive never observed in the short capture makes its reconstruction fail:
    // reported, not fatal.
    match NeedleModel::reconstruct(&short_store, &body, &base)
        .and_then(|r| test.set.errors(&r.model))
    {
        Ok(mut e) => {
            out.insert("short_train_median_mm".into(), json!(median(&e.all_mm)));
            out.insert(
                "short_train_deforming_mean_mm".into(),
                json!(mean(&e.pose_deforming_mm)),
            );
            e.near_joints_mm.sort_by(f64::total_cmp);
            out.insert(
                "short_train_median_near_joints_mm".into(),
                json!(median(&e.near_joints_mm)),
            );
        }
        Err(e) => {
            out.insert("short_train_error".into(), json!(e.to_string()));
        }
    }

    // --- Automatic parameter selection by silhouette error (§6.3, Figure 11). ---
    let stage = run.stage("selection", None);
    let selection = select(&s, &performer, &body, &rig, &train, &store)?;
    let chosen = selection.params;
    stage.finish(format!(
        "selected F_near {} F_min {} W {} N {} (silhouette error {:.4} → {:.4}, {} reconstructions)",
        chosen.f_near,
        chosen.f_min,
        chosen.kernel_width_w,
        chosen.prototype_count_n,
        selection.start_error,
        selection.error,
        selection.evaluations
    ));
    let selected = NeedleModel::reconstruct(&store, &body, &chosen)?.model;
    summary("selected", &mut test.set.errors(&selected)?, &mut out);
    out.insert("selected_params".into(), json!(chosen));
    out.insert("selection_evaluations".into(), json!(selection.evaluations));
    plot_selection(&mut run, &selection.curves, &chosen)?;

    // --- Animation speed: NRBF + per-primitive meshes, and the watertight union. ---
    let stage = run.stage("speed", None);
    let poses: Vec<&[f64]> = walk.set.frames.iter().map(|f| f.theta.as_slice()).collect();
    let ta = Instant::now();
    for th in &poses {
        let posed = animate(&body, &main, &sk, th)?;
        std::hint::black_box(primitive_meshes(&posed)?);
    }
    let animate_fps = poses.len() as f64 / ta.elapsed().as_secs_f64();
    let union_poses = &poses[..poses.len().min(4)];
    let tu = Instant::now();
    for th in union_poses {
        let posed = animate(&body, &main, &sk, th)?;
        std::hint::black_box(union_mesh(&posed, &SurfaceParams::default())?);
    }
    let union_fps = union_poses.len() as f64 / tu.elapsed().as_secs_f64();
    stage.finish(format!(
        "animate {animate_fps:.0} fps (per-primitive surfaces), union {union_fps:.2} fps"
    ));

    // --- Pictures. ---
    let stage = run.stage("pictures", None);
    plot_error_vs_n(&mut run, &sweep, &out)?;
    render_test_poses(&mut run, &performer, &body, &main, &walk)?;
    render_error_map(&mut run, &body, &main, &sk, &walk)?;
    let figure12 = Figure12 {
        performer: &performer,
        body: &body,
        test: &test,
        base: &main,
    };
    let flexed = figure12.render(
        &mut run,
        &[
            ("static model", Predictor::Model(&stat)),
            ("LBS of the captured shape", Predictor::Surface(&lbs_heat)),
            ("needle model", Predictor::Model(&main)),
        ],
    )?;
    out.insert("flexed_elbow_frame".into(), json!(flexed));
    stage.finish(format!("written under {}", out_dir.display()));

    for (k, v) in [
        ("quick", json!(s.quick)),
        ("performer", json!(performer.name)),
        ("train_s", json!(train.duration_s())),
        ("train_frames", json!(n_train)),
        ("train_seed", json!(TRAIN_SEED)),
        ("test_seed", json!(TEST_SEED)),
        (
            "turn_deg_per_s",
            json!(ExerciseParams::default().turn_deg_per_s),
        ),
        ("short_train_s", json!(short_motion.duration_s())),
        ("test_frames", json!(test.set.frames.len())),
        ("test_needles", json!(scored(&test))),
        ("walk_test_frames", json!(walk.set.frames.len())),
        ("walk_test_needles", json!(scored(&walk))),
        ("accumulate_frames_per_s", json!(accumulate_fps)),
        ("render_frames_per_s", json!(camera_frames / long.render_s)),
        ("reconstruct_s", json!(reconstruct_s)),
        ("reconstruct_s_24min", json!(reconstruct_s_24min)),
        ("reconstruct_24min_camera_frames", json!(big_camera_frames)),
        ("animate_fps", json!(animate_fps)),
        ("union_fps", json!(union_fps)),
        (
            "bytes_per_observation",
            json!(store.bytes_per_observation()),
        ),
        ("observations", json!(store.total_observations())),
        ("seconds", json!(t0.elapsed().as_secs_f64())),
    ] {
        out.insert(k.into(), v);
    }
    // The accuracy goals are these ratios ≥ 2.
    let f = |k: &str| out[k].as_f64().unwrap_or(f64::NAN);
    let over_static = f("static_deforming_mean_mm") / f("deforming_mean_mm");
    let over_lbs = f("lbs_deforming_mean_mm") / f("deforming_mean_mm");
    let over_lbs_no_visibility = f("lbs_no_visibility_deforming_mean_mm") / f("deforming_mean_mm");
    out.insert("deforming_gain_over_static".into(), json!(over_static));
    out.insert("deforming_gain_over_lbs".into(), json!(over_lbs));
    out.insert(
        "deforming_gain_over_lbs_no_visibility".into(),
        json!(over_lbs_no_visibility),
    );
    headlines(&mut run, &s);
    run.finish(Value::Object(out))?;
    Ok(())
}

/// One N of the error-against-N sweep: a figure per seed.
#[derive(Default)]
struct SweepPoint {
    n: usize,
    median_mm: Vec<f64>,
    near_joints_mm: Vec<f64>,
    deforming_mean_mm: Vec<f64>,
}

impl SweepPoint {
    /// Largest minus smallest pose-deforming mean over the seeds, mm.
    fn spread(&self) -> f64 {
        let v = &self.deforming_mean_mm;
        v.iter().copied().fold(f64::NEG_INFINITY, f64::max)
            - v.iter().copied().fold(f64::INFINITY, f64::min)
    }

    fn to_json(&self) -> Value {
        json!({
            "n": self.n,
            "median_mm": mean(&self.median_mm),
            "near_joints_mm": mean(&self.near_joints_mm),
            "deforming_mean_mm": mean(&self.deforming_mean_mm),
            "deforming_mean_mm_seeds": self.deforming_mean_mm,
            "deforming_spread_mm": self.spread(),
        })
    }
}

/// The figures `tour` shows, with their goals (`docs/needle-model.md`).
fn headlines(run: &mut Run, s: &Setup) {
    let doc = "goal from docs/needle-model.md";
    for h in [
        Headline::new(
            "deforming_mean_mm",
            "model error on pose-deforming needles of the test exercise, mean",
            "mm",
        ),
        Headline::new(
            "static_deforming_mean_mm",
            "static model (F_near = 1) on pose-deforming needles, mean",
            "mm",
        )
        .baseline(),
        Headline::new(
            "lbs_deforming_mean_mm",
            "LBS of the captured rest shape on pose-deforming needles, mean",
            "mm",
        )
        .baseline(),
        Headline::new(
            "deforming_gain_over_static",
            "pose-deforming error of the static model ÷ that of the model",
            "×",
        )
        .goal(Goal::AtLeast(2.0))
        .note("accuracy goal (docs/needle-model.md)"),
        Headline::new(
            "deforming_gain_over_lbs",
            "pose-deforming error of captured-shape LBS ÷ that of the model",
            "×",
        )
        .goal(Goal::AtLeast(2.0))
        .note("accuracy goal (docs/needle-model.md)"),
        Headline::new(
            "pose_r2_centred",
            "share of the pose variance the model explains (each needle's bias removed)",
            "",
        )
        .goal(Goal::AtLeast(0.5))
        .note("goal in docs/needle-model.md"),
        Headline::new(
            "n10_to_100_drop",
            "drop of the pose-deforming error from N = 10 to N = 100",
            "fraction",
        )
        .goal(Goal::AtLeast(0.1))
        .note("compare n_seed_spread_mm"),
        Headline::new(
            "test_median_mm",
            "model error on the test exercise, median over needles",
            "mm",
        ),
        Headline::new(
            "walk_test_median_mm",
            "model error on the CMU walk, median over needles",
            "mm",
        ),
        Headline::new(
            "pool_max_pose_share",
            "largest share of one 5° pose in a prototype's pool, median",
            "",
        ),
        Headline::new(
            "test_silhouette_error",
            "silhouette error on the test exercise (fraction of band pixels)",
            "",
        ),
        Headline::new(
            "accumulate_frames_per_s",
            "observation accumulation",
            "camera-frames/s",
        )
        .paper("\"can be done in real time\" (30 fps video), Sand 2003 thesis §6.2")
        .goal(Goal::AtLeast(300.0))
        .note(&format!(
            "{doc}, at 720×480; this run {}×{}",
            s.width, s.height
        )),
        Headline::new(
            "reconstruct_s_24min",
            "reconstruction from ≥ 43,200 camera-frames",
            "s",
        )
        .paper("< 30 min for the observations of 30 min of video, Sand 2003 thesis §6.2")
        .goal(Goal::AtMost(60.0))
        .note(doc),
        Headline::new(
            "animate_fps",
            "animation (NRBF + per-primitive surfaces)",
            "fps",
        )
        .goal(Goal::AtLeast(30.0))
        .note(doc),
        Headline::new(
            "union_fps",
            "animation with the watertight union surface",
            "fps",
        )
        .paper("≈ 0.05 fps (about 20 s per frame: FastRBF mesh), Sand 2003 thesis §6.3")
        .goal(Goal::AtLeast(2.0))
        .note(doc),
        Headline::new("bytes_per_observation", "memory per observation", "B")
            .goal(Goal::AtMost(4.0))
            .note(doc),
    ] {
        run.headline(h);
    }
}

/// Mean silhouette error (§6.2) of `model`'s surface over the test frames.
fn silhouette_error(
    body: &NeedleBody,
    model: &NeedleModel,
    sk: &dynamic_shapes::core::skeleton::Skeleton,
    cameras: &[Camera],
    t: &Test,
) -> Res<f64> {
    let scorer = SilhouetteScorer::new(cameras, SilhouetteErrorParams::default())?;
    let meshes: Vec<TriMesh> = t
        .set
        .frames
        .iter()
        .map(|f| merged_mesh(&animate(body, model, sk, &f.theta)?))
        .collect::<Result<_, _>>()?;
    Ok(scorer.sequence_error(&meshes, &t.masks)?.mean)
}

/// Coordinate descent on the silhouette error of training frames spread over the capture.
fn select(
    s: &Setup,
    performer: &Performer,
    body: &NeedleBody,
    rig: &Rig,
    train: &Motion,
    store: &ObservationStore,
) -> Res<dynamic_shapes::needle::Selection> {
    let stride = (train.frame_count() / s.validation_frames).max(1);
    let mut thetas = vec![];
    let mut masks = vec![];
    let capture = silhouettes(performer, rig, train)?;
    for frame in capture.frames_stepped(0..capture.frame_count(), stride) {
        let frame = frame?;
        masks.push(frame.masks());
        thetas.push(frame.truth.theta);
    }
    let cameras = &rig.cameras;
    let frames: Vec<ValidationFrame> = thetas
        .iter()
        .zip(&masks)
        .map(|(theta, masks)| ValidationFrame { theta, masks })
        .collect();
    let scorer = SilhouetteScorer::new(cameras, SilhouetteErrorParams::default())?;
    Ok(select_params(
        store,
        body,
        &performer.skeleton,
        &scorer,
        &frames,
        ReconstructionParams::default(),
        &s.selection,
    )?)
}

/// Result of [`capture`].
struct Captured {
    store: ObservationStore,
    /// Pose of every frame (what the model over skinning needs).
    thetas: Vec<Vec<f64>>,
    accumulate_s: f64,
    render_s: f64,
}

/// Captures the performer's silhouettes along `motion` and accumulates the observations,
/// streamed in chunks of 48 frames (masks are not kept).
fn capture(
    performer: &Performer,
    observer: &Observer,
    rig: &Rig,
    motion: &Motion,
    progress: &example_kit::Stage,
) -> Res<Captured> {
    let mut store = observer.empty_store()?;
    let mut thetas = vec![];
    let (mut accumulate_s, mut render_s) = (0.0, 0.0);
    let chunk = 48usize;
    let capture = silhouettes(performer, rig, motion)?;
    let mut frames = capture.frames();
    let mut done = 0;
    loop {
        let tr = Instant::now();
        let pending: Vec<CaptureFrame> = frames.by_ref().take(chunk).collect::<Result<_, _>>()?;
        render_s += tr.elapsed().as_secs_f64();
        if pending.is_empty() {
            break;
        }
        thetas.extend(pending.iter().map(|f| f.truth.theta.clone()));
        let masks: Vec<Vec<Mask>> = pending.iter().map(CaptureFrame::masks).collect();
        let inputs: Vec<FrameInput> = pending
            .iter()
            .zip(&masks)
            .map(|(f, m)| FrameInput {
                theta: &f.truth.theta,
                masks: m,
            })
            .collect();
        let ta = Instant::now();
        let acc = observer.accumulate(&inputs)?;
        accumulate_s += ta.elapsed().as_secs_f64();
        store.append(&acc.store)?;
        done += pending.len();
        progress.set_position(done as u64);
        progress.set_message(format!("{} observations", store.total_observations()));
    }
    Ok(Captured {
        store,
        thetas,
        accumulate_s,
        render_s,
    })
}

/// `error_vs_n.png` (see the module docs).
fn plot_error_vs_n(run: &mut Run, sweep: &[SweepPoint], fig: &Map<String, Value>) -> Res<()> {
    let (x0, x1) = (sweep[0].n as f64, sweep[sweep.len() - 1].n as f64);
    let baseline = |k: &str| {
        let y = fig[k].as_f64().unwrap_or(f64::NAN);
        vec![(x0, y), (x1, y)]
    };
    let mut chart = Chart::new(
        "Test exercise error against the number of prototypes N",
        "prototypes per primitive N (log scale)",
        "needle-length error (mm)",
    );
    chart.log_x = true;
    chart.legend = LegendPosition::UpperRight;
    let img = chart
        .with(Series::new(
            "needle model, pose-deforming needles, mean over seeds",
            [220, 0, 0],
            Style::LineMarkers,
            sweep
                .iter()
                .map(|p| (p.n as f64, mean(&p.deforming_mean_mm)))
                .collect(),
        ))
        .with(Series::new(
            "needle model, pose-deforming needles, each seed",
            [220, 120, 120],
            Style::Markers,
            sweep
                .iter()
                .flat_map(|p| p.deforming_mean_mm.iter().map(|&e| (p.n as f64, e)))
                .collect(),
        ))
        .with(Series::new(
            "needle model, all needles, median",
            [0, 60, 220],
            Style::LineMarkers,
            sweep
                .iter()
                .map(|p| (p.n as f64, mean(&p.median_mm)))
                .collect(),
        ))
        .with(Series::new(
            "static model (F_near = 1), pose-deforming mean",
            [128, 128, 128],
            Style::Dashed,
            baseline("static_deforming_mean_mm"),
        ))
        .with(Series::new(
            "LBS of the captured rest shape, pose-deforming mean",
            [230, 140, 0],
            Style::Dashed,
            baseline("lbs_deforming_mean_mm"),
        ))
        .with(Series::new(
            "the same, heat weights without visibility test, pose-deforming mean",
            [150, 90, 30],
            Style::Dashed,
            baseline("lbs_no_visibility_deforming_mean_mm"),
        ))
        .with(Series::new(
            "LBS of the exact rest shape (oracle), pose-deforming mean",
            [40, 160, 40],
            Style::Dashed,
            baseline("lbs_exact_rest_deforming_mean_mm"),
        ))
        .draw()?;
    run.save_picture(
        "error_vs_n.png",
        &img,
        "Needle-length error on the test exercise against the number of prototypes N (log \
         axis): mean over the pose-deforming needles (red line: mean over the prototype \
         seeds; pink: each seed) and median over all needles (blue); dashed: the static \
         model, LBS of the captured rest shape (bone-heat weights with and without the \
         visibility test) and LBS of the exact rest shape (an oracle), each at its \
         pose-deforming mean.",
    )?;
    Ok(())
}

/// The pool diagnostics: per primitive, the median pool radius in degrees of its
/// driving joints, the median largest share of one 5° pose cell in a pool, and how often
/// the `min_near` floor bound; overall, the medians over primitives and the floor's share.
fn pool_figures(reports: &[PrimitiveFitReport], body: &NeedleBody) -> Vec<(String, Value)> {
    let mut rows = vec![];
    let (mut radius, mut share) = (vec![], vec![]);
    let (mut floored, mut estimates) = (0, 0);
    for (r, p) in reports.iter().zip(&body.primitives) {
        let n = &r.neighbourhood;
        floored += n.floor_bound;
        estimates += n.estimates;
        radius.extend(n.pool_radius_deg_median.map(f64::from));
        share.extend(n.pool_max_pose_share_median.map(f64::from));
        rows.push(json!({
            "primitive": p.name,
            "pool_radius_deg_median": n.pool_radius_deg_median,
            "pool_max_pose_share": n.pool_max_pose_share_median,
            "floor_bound": n.floor_bound,
            "estimates": n.estimates,
        }));
    }
    vec![
        ("pool_radius_deg_median".into(), json!(median(&radius))),
        ("pool_max_pose_share".into(), json!(median(&share))),
        (
            "pool_max_pose_share_worst".into(),
            json!(share.iter().copied().fold(f64::NAN, f64::max)),
        ),
        (
            "floor_bound_share".into(),
            json!(floored as f64 / estimates.max(1) as f64),
        ),
        ("pools".into(), Value::Array(rows)),
    ]
}

/// `silhouette_error_vs_params.png`: one panel per parameter, F_near, F_min, W, N, the
/// selected value marked.
fn plot_selection(
    run: &mut Run,
    curves: &[dynamic_shapes::needle::ParameterCurve],
    chosen: &ReconstructionParams,
) -> Res<()> {
    let panels: Vec<_> = curves
        .iter()
        .map(|c| {
            let (name, what, value) = match c.parameter {
                Parameter::FNear => ("F_near", "F_near (fraction, log scale)", chosen.f_near),
                Parameter::FMin => ("F_min", "F_min (percentile fraction)", chosen.f_min),
                Parameter::KernelWidthW => {
                    ("W", "kernel width W (dimensionless)", chosen.kernel_width_w)
                }
                Parameter::PrototypeCountN => (
                    "N",
                    "prototypes N (log scale)",
                    chosen.prototype_count_n as f64,
                ),
            };
            let points: Vec<(f64, f64)> = c
                .values
                .iter()
                .copied()
                .zip(c.errors.iter().copied())
                .collect();
            let pick = points
                .iter()
                .filter(|p| (p.0 - value).abs() <= 1e-9 * value.abs().max(1.0))
                .copied()
                .collect();
            let mut chart = Chart::new(
                format!("silhouette error against {name}"),
                what,
                "silhouette error (fraction)",
            );
            chart.size = (480, 340);
            chart.y_from_zero = false;
            chart.log_x = matches!(c.parameter, Parameter::FNear | Parameter::PrototypeCountN);
            chart
                .with(Series::new("", [0, 60, 220], Style::LineMarkers, points))
                .with(Series::new("", [220, 0, 0], Style::Markers, pick))
                .draw()
        })
        .collect::<Result<_, _>>()?;
    let img = kplot::titled(
        &kplot::stacked(&[
            kplot::side_by_side(&panels[..panels.len().min(2)])?,
            kplot::side_by_side(&panels[panels.len().min(2)..])?,
        ])?,
        "Automatic parameter selection by silhouette error (Sand 2003 §6.3, Figure 11)",
        Some("blue: last coordinate-descent sweep; red: the selected value; error: mean fraction of mismatched pixels in a 3 px band around the predicted silhouette"),
    )?;
    run.save_picture(
        "silhouette_error_vs_params.png",
        &img,
        "Silhouette error of the reconstruction against each parameter in the last \
         coordinate-descent sweep, the others held at their values of that sweep (like Sand \
         2003 Figure 11); red: the selected value.",
    )?;
    Ok(())
}

/// `test_poses.png`: three walk poses, truth above, the model's union surface below.
fn render_test_poses(
    run: &mut Run,
    performer: &Performer,
    body: &NeedleBody,
    model: &NeedleModel,
    walk: &Test,
) -> Res<()> {
    let n = walk.set.frames.len();
    let picks = [n / 6, n / 2, 5 * n / 6];
    let mut rows = vec![];
    for truth_row in [true, false] {
        let mut meshes = vec![];
        for &k in &picks {
            let theta = &walk.set.frames[k].theta;
            meshes.push(if truth_row {
                // A fresh flap state: the picture shows the pose, not the flap's lag (the
                // scoring in `test_set` runs the dynamics over every frame).
                let posed = performer.pose(theta, &mut DeformationState::default(), 1.0)?;
                performer.mesh(posed.true_vertices)
            } else {
                let posed = animate(body, model, &performer.skeleton, theta)?;
                union_mesh(&posed, &SurfaceParams::default())?
            });
        }
        let colour = if truth_row {
            [150, 150, 150]
        } else {
            [90, 120, 200]
        };
        let panels: Vec<PreviewPanel> = meshes
            .iter()
            .map(|mesh| PreviewPanel {
                mesh,
                paint: Paint::Flat(colour),
            })
            .collect();
        rows.push(preview(&panels, 320)?);
    }
    let (w, h) = (rows[0].width(), rows[0].height());
    let mut img = image::RgbImage::new(w, 2 * h);
    image::imageops::overlay(&mut img, &rows[0], 0, 0);
    image::imageops::overlay(&mut img, &rows[1], 0, h as i64);
    let img = kplot::titled(
        &img,
        "Three poses of the CMU walk (never seen in training)",
        Some(
            "top: the true body (grey); bottom: the needle model's watertight union surface (blue)",
        ),
    )?;
    run.save_picture(
        "test_poses.png",
        &img,
        "Three walk poses: the true body (top, grey) and the needle model's watertight union \
         surface (bottom, blue), front views.",
    )?;
    Ok(())
}

/// `error_map.png`: per-primitive surfaces at the middle walk pose coloured by needle error.
fn render_error_map(
    run: &mut Run,
    body: &NeedleBody,
    model: &NeedleModel,
    sk: &dynamic_shapes::core::skeleton::Skeleton,
    walk: &Test,
) -> Res<()> {
    let frame = &walk.set.frames[walk.set.frames.len() / 2];
    let posed = animate(body, model, sk, &frame.theta)?;
    let mut err: Vec<Vec<Option<f64>>> = posed
        .primitives
        .iter()
        .map(|p| vec![None; p.endpoints.len()])
        .collect();
    for n in &frame.needles {
        let (p, j) = (n.primitive as usize, n.needle as usize);
        err[p][j] = Some((posed.primitives[p].lengths[j] - n.true_m).abs() * 1e3);
    }
    let colours = needle_error_colours(&primitive_meshes(&posed)?, &err);
    let mesh = merged_mesh(&posed)?;
    let img = with_error_bar(
        &preview(
            &[PreviewPanel {
                mesh: &mesh,
                paint: Paint::PerVertex(&colours),
            }],
            640,
        )?,
        "Needle error at the middle walk pose",
        "the model's per-primitive surfaces coloured by |model − true| needle length",
    )?;
    run.save_picture(
        "error_map.png",
        &img,
        "The model's per-primitive surfaces at the middle walk pose, each needle endpoint \
         coloured by its length error against the truth (colour bar in mm; grey: needle not \
         scored).",
    )?;
    Ok(())
}

/// The pose-local visual-hull oracle ([`HullOracle`]) on the test motion: 24 cameras at
/// three heights ([`HullOracle::rig`]) see every scored test frame at the run's image size.
fn hull_oracle(
    performer: &Performer,
    body: &NeedleBody,
    setup: &Setup,
    motion: &Motion,
    test: &Test,
) -> Res<HullOracle> {
    let sk = &performer.skeleton;
    let rig = HullOracle::rig(setup.width, setup.height)?;
    let observer = Observer::new(
        body.clone(),
        sk.clone(),
        rig.cameras.clone(),
        ObserveParams::default(),
    )?;
    let capture = silhouettes(performer, &rig, motion)?;
    let mut oracle = HullOracle::default();
    let mut frames = capture.frames_stepped(0..capture.frame_count(), setup.test_stride);
    loop {
        // A few frames at a time: walked in parallel, masks not kept.
        let pending: Vec<CaptureFrame> = frames.by_ref().take(8).collect::<Result<_, _>>()?;
        if pending.is_empty() {
            break;
        }
        let masks: Vec<Vec<Mask>> = pending.iter().map(CaptureFrame::masks).collect();
        let inputs: Vec<FrameInput> = pending
            .iter()
            .zip(&masks)
            .map(|(f, m)| FrameInput {
                theta: &f.truth.theta,
                masks: m,
            })
            .collect();
        oracle.push_frames(&observer, &inputs)?;
    }
    if oracle.frame_count() != test.set.frames.len() {
        return Err("hull oracle: frames differ from the test set's".into());
    }
    Ok(oracle)
}

/// The pose-deforming figures of predictor `name` on the needle-frames the hull oracle saw,
/// as JSON fields `{name}_observed_…` (the model's `model_observed_…`).
fn observed_summary(name: &str, e: &Errors, out: &mut Map<String, Value>) {
    let r2 = e.pose_r2();
    for (field, v) in [
        ("median_mm", median(&e.all_mm)),
        ("deforming_mean_mm", mean(&e.pose_deforming_mm)),
        ("pose_r2", r2.r2),
        ("pose_r2_centred", r2.r2_centred),
        ("deforming_bias_rms_mm", r2.bias_rms_mm),
        ("deforming_centred_rms_mm", r2.centred_rms_mm),
        ("deforming_pose_rms_mm", r2.pose_rms_mm),
    ] {
        out.insert(format!("{name}_observed_{field}"), json!(v));
    }
    out.insert(
        format!("{name}_observed_deforming_needle_frames"),
        json!(e.pose_deforming_mm.len()),
    );
}

/// `deforming_error_by_effect`: per category of [`EffectAttribution`] (skinning geometry,
/// each pose effect, the flap), its pose-deforming needles and needle-frames and each
/// predictor's mean error there (`mean_mm`); with `observed` (the predictors restricted to
/// the needle-frames the hull oracle saw), the same there (`observed_needles`,
/// `observed_needle_frames`, `observed_mean_mm`). A category no needle falls in has counts
/// and no means.
fn by_effect(
    effects: &EffectAttribution,
    scored: &[(&str, Errors)],
    observed: &[(&str, Errors)],
) -> Res<Value> {
    let split = |list: &[(&str, Errors)]| -> Res<Vec<(String, Vec<EffectErrors>)>> {
        list.iter()
            .map(|(p, e)| Ok((p.to_string(), effects.breakdown(e)?)))
            .collect()
    };
    let (all, seen) = (split(scored)?, split(observed)?);
    let mut rows = Map::new();
    for (i, effect) in effects.categories().iter().enumerate() {
        let means = |rows: &[(String, Vec<EffectErrors>)]| -> Map<String, Value> {
            rows.iter()
                .map(|(p, b)| (p.clone(), json!(b[i].mean_mm)))
                .collect()
        };
        let first = |rows: &[(String, Vec<EffectErrors>)]| rows.first().map(|(_, b)| b[i].clone());
        // An empty category (no needle it dominates) lists no means.
        let mut row = Map::new();
        if let Some(b) = first(&all) {
            row.insert("needles".into(), json!(b.needles));
            row.insert("needle_frames".into(), json!(b.needle_frames));
            if b.needle_frames > 0 {
                row.insert("mean_mm".into(), Value::Object(means(&all)));
            }
        }
        if let Some(b) = first(&seen) {
            row.insert("observed_needles".into(), json!(b.needles));
            row.insert("observed_needle_frames".into(), json!(b.needle_frames));
            if b.needle_frames > 0 {
                row.insert("observed_mean_mm".into(), Value::Object(means(&seen)));
            }
        }
        rows.insert(effect.clone(), Value::Object(row));
    }
    Ok(Value::Object(rows))
}

/// Errors of the model over skinning ([`PoseSpaceModel`]) on a test set.
fn psd_errors(
    model: &PoseSpaceModel,
    body: &NeedleBody,
    sk: &dynamic_shapes::core::skeleton::Skeleton,
    set: &TestSet,
) -> Res<Errors> {
    let lengths: Vec<Vec<Vec<f32>>> = set
        .frames
        .iter()
        .map(|f| model.lengths(body, sk, &f.theta))
        .collect::<Result<_, _>>()?;
    Ok(set.errors_of(|k, n| {
        Ok::<_, std::convert::Infallible>(f64::from(
            lengths[k][n.primitive as usize][n.needle as usize],
        ))
    })?)
}
