//! Capture anywhere (Vlasic 2010 Ch. 6, Figure 6-1): a dynamic shape model learned in the
//! studio from template-silhouette's own molded sequences, then driven by the inertial suit's
//! poses in motions it never saw, scored against the studio's truth.
//!
//! **Learn.** The MakeHuman performer in the skirt is captured by the ring of 8 cameras
//! 2.2 m above the floor at 30 fps, with the scanned 10,000-vertex template rigged by the
//! library's bone-heat weights; each frame is tracked and molded (`capture_sequence`, the
//! previous-frame start), in an exercise (seed 1) and the MakeHuman walk
//! (`makehuman/walk1.bvh`). The molded frames go to sequence files and
//! `ShapeModel::learn` streams them (never the truth). The same model learned from the true
//! template vertices and true poses of the same frames is the oracle
//! `oracle_truth_trained_*`, what the molding costs.
//!
//! **Drive.** The suit (Ch. 4) is simulated on the same performer in an exercise of another
//! seed, the CMU 131_01 walk and a stop-and-go walk (131_01 held still for a second at three
//! points); the inertial pipeline (A+G+D, root supplied from the truth, as the thesis's system
//! cannot recover it) gives the poses at 140 Hz, resampled to the model's 30 fps.
//!
//! **Score**, against the true surface (two-way point-to-surface distance, mean and p95, the
//! whole surface and the skirt), per frame after the suit's rest hold: LBS of the template
//! with the suit's poses (`lbs_*`, what a user has today), the pose-dependent part alone
//! (`pose_only_*`), the full model (`*`), the full model with the true poses
//! (`oracle_pose_*`) and LBS with them (`oracle_pose_lbs_*`), which the oracles are read
//! against. `oracle_in_sample_*`: the model's ceiling, learned from the truth of the three
//! test motions themselves (default ridge weights, no validation) and driven by their true
//! poses — what its form can show of them at all. `dynamic_variance_explained`: with the true poses, the share of what the
//! pose part leaves on the skirt (squared vertex distance to the true skirt, summed over
//! frames) that the dynamic part removes. `model_fps`: frames per second of the driver on one
//! thread; `learn_s`: learning the model; `learn_5min_s`: learning from five minutes of
//! frames (the molded files streamed again and again). `pose_ridge`, `dynamic_ridge`: the
//! ridge weights the leave-one-sequence-out validation chose from `RIDGE_GRID` (relative to
//! the features' mean Gram diagonal; the grid's largest leaves a part all but silent), and
//! `validation_rms_mm` the left-out sequences' normal-offset error; `oracle_truth_trained_*`
//! the same for the model learned from the truth.
//!
//! Writes under `out/capture_anywhere/`: `hem_lag.png` (the hem's forward offset from the
//! pelvis over the stop-and-go walk: truth, LBS, the model), `skirt_error.png` (skirt
//! surface error per frame of the stop-and-go walk), `frames.png` (one frame of it: truth,
//! LBS, the model), `stop_and_go.glb` (the model's surfaces over the walk, glTF 2.0),
//! `model.dssm` (the learned model); `figures.json`, `manifest.json`.
//!
//! `cargo run --release --example capture_anywhere [-- --quick]` (`--quick`: 480 × 360 views,
//! 90 molded frames per training motion, 8 s test motions; full: 800 × 600, 300 frames per
//! training motion, 20 s test motions).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)] // not library code

#[path = "../common/scanned_template.rs"]
mod scanned_template;

use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::Parser;
use nalgebra::DMatrix;
use serde_json::{json, Map, Value};

use dynamic_shapes::core::camera::{Intrinsics, Rig};
use dynamic_shapes::core::math::{DQuat, DVec3};
use dynamic_shapes::core::mesh::{
    points_to_surface, save_gltf_animation, DistanceStats, MeshQuery, MeshSequence, TriMesh,
};
use dynamic_shapes::core::skeleton::{read_bvh, BvhParams, Motion, Skeleton, CMU_METRES_PER_UNIT};
use dynamic_shapes::core::stats::mean;
use dynamic_shapes::inertial::pipeline::{self, PipelineParams};
use dynamic_shapes::inertial::simulate::{
    prepare_motion, SimulationParams, SmoothMotion, SuitSimulator,
};
use dynamic_shapes::inertial::FilterParams;
use dynamic_shapes::template::shape_model::{
    SequenceFiles, SequenceWriter, ShapeModel, ShapeModelParams,
};
use dynamic_shapes::template::{
    capture_sequence, ContourRayHullParams, FrameObservation, PoseParams, ShapeParams, ShapeStart,
    SilhouetteParams,
};
use dynamic_shapes_studio::{
    exercise_motion, makehuman_performer, play_bvh, preview, retarget, Capture, CaptureSpec,
    DeformationParams, DeformationState, ExerciseParams, GarmentParams, JointMap, Paint, Performer,
    PreviewPanel, RetargetParams, SkirtParams,
};
use example_kit::plot::{Chart, Series, Style};
use example_kit::{Goal, Headline, Run};
use scanned_template::TemplateEmbedding;

/// The model's frame rate, Hz (the thesis's capture rate).
const FPS: f64 = 30.0;
/// The cameras' height above the floor, m (the thesis's rig).
const CAMERA_HEIGHT_M: f64 = 2.2;
/// Template vertices.
const TEMPLATE_VERTICES: usize = 10_000;
/// Exercise seeds: learned from, driven in.
const TRAIN_SEED: u64 = 1;
const TEST_SEED: u64 = 2;
/// The stop-and-go walk: 131_01 held still for this long at each of three points, s.
const HOLD_S: f64 = 1.0;
/// The molded training frames are scored on every this many frames.
const TEACHER_STEP: usize = 3;
/// Radius of the circle the training walk follows, m.
const CIRCLE_RADIUS_M: f64 = 1.0;
/// Height above the hem's lowest point within which a skirt vertex is on the hem, m.
const HEM_BAND_M: f64 = 0.05;

#[derive(Parser)]
struct Args {
    #[command(flatten)]
    common: example_kit::cli::Common,
    /// Keep the molded training sequences (and the true ones) in DIR, and learn from those
    /// already there instead of capturing and molding again.
    #[arg(long, value_name = "DIR")]
    sequences: Option<PathBuf>,
    /// Score the surfaces on every STEP-th frame (default: 3 with --quick, else 1).
    #[arg(long, value_name = "STEP")]
    score_step: Option<usize>,
}

fn skirt_performer() -> Result<(Performer, DeformationParams), Box<dyn std::error::Error>> {
    let deformation = DeformationParams::default()
        .with_flap(None)
        .with_garment(Some(GarmentParams::Skirt(SkirtParams::default())));
    let performer = makehuman_performer(example_kit::data_path("makehuman")?, &deformation)?;
    Ok((performer, deformation))
}

/// A walk from `makehuman/walk1.bvh`, an artist's in-place walk cycle: the cycle looped for
/// `duration_s`, blended in from the rest pose over the first second and out to it over the
/// last (the performer starts and stops), carried forward at the speed at which the stance
/// foot does not slide (the lower ankle's median backward speed in the cycle) along a circle
/// of [`CIRCLE_RADIUS_M`] (a studio walk that stays in the cameras' view, turning as it goes),
/// speed and turn scaled by the same blend.
fn walk1(skeleton: &Skeleton, duration_s: f64) -> Result<Motion, Box<dyn std::error::Error>> {
    let bvh = read_bvh(
        example_kit::data_path("makehuman/walk1.bvh")?,
        &BvhParams {
            metres_per_unit: 0.1,
        },
    )?;
    let map = JointMap::detect(&bvh.skeleton)?;
    let cycle = retarget(
        &bvh.skeleton,
        &bvh.motion,
        skeleton,
        &map,
        &RetargetParams::default(),
    )?
    .motion;
    let (n, h) = (cycle.frame_count(), cycle.frame_time_s);
    // The stance foot's backward speed: the lower foot joint's horizontal velocity.
    let feet: Vec<usize> = ["l_ankle", "r_ankle"]
        .iter()
        .map(|f| skeleton.joint_index(f).ok_or(format!("no joint {f}")))
        .collect::<Result<_, _>>()?;
    let positions: Vec<Vec<DVec3>> = (0..n)
        .map(|k| {
            Ok(skeleton
                .forward_kinematics(cycle.frame(k))?
                .joint_positions())
        })
        .collect::<Result<_, Box<dyn std::error::Error>>>()?;
    let mut backward: Vec<DVec3> = (0..n)
        .filter_map(|k| {
            let j = *feet
                .iter()
                .min_by(|&&a, &&b| positions[k][a].y.total_cmp(&positions[k][b].y))?;
            let d = positions[(k + 1) % n][j] - positions[k][j];
            Some(-DVec3::new(d.x, 0.0, d.z) / h)
        })
        .collect();
    backward.sort_by(|a, b| a.length().total_cmp(&b.length()));
    let velocity = backward
        .get(backward.len() / 2)
        .copied()
        .unwrap_or(DVec3::ZERO);
    let dof = |name: &str| skeleton.dof_index(name).ok_or(format!("no DOF {name}"));
    let (tx, tz, yaw) = (dof("pelvis.tx")?, dof("pelvis.tz")?, dof("pelvis.yaw")?);
    let root: Vec<usize> = skeleton.joint_dofs(0).collect();
    let frames = (duration_s / h).round() as usize;
    let blend = |t: f64| {
        let u = t.min(duration_s - t).clamp(0.0, 1.0);
        u * u * (3.0 - 2.0 * u)
    };
    let (speed, turn_rate) = (velocity.length(), velocity.length() / CIRCLE_RADIUS_M);
    let forward = velocity.normalize_or_zero();
    let (mut position, mut heading) = (DVec3::ZERO, 0.0f64);
    let mut out = DMatrix::zeros(cycle.frames.nrows(), frames);
    for k in 0..frames {
        let a = blend(k as f64 * h);
        let source = cycle.frame(k % n);
        for d in 0..out.nrows() {
            out[(d, k)] = if root.contains(&d) {
                source[d]
            } else {
                a * source[d]
            };
        }
        out[(tx, k)] += position.x;
        out[(tz, k)] += position.z;
        out[(yaw, k)] += heading;
        position += DQuat::from_rotation_y(heading) * forward * (a * speed * h);
        heading += a * turn_rate * h;
    }
    Ok(Motion::new(h, out)?.resample(skeleton, 1.0 / FPS)?)
}

fn cmu_walk(skeleton: &Skeleton) -> Result<Motion, Box<dyn std::error::Error>> {
    Ok(play_bvh(
        example_kit::data_path("mocap-cmu/131_01.bvh")?,
        &BvhParams {
            metres_per_unit: CMU_METRES_PER_UNIT,
        },
        skeleton,
        1.0 / FPS,
        &RetargetParams::default(),
    )?
    .motion)
}

/// `motion` held still for [`HOLD_S`] at a quarter, half and three quarters of its length.
fn stop_and_go(motion: &Motion) -> Result<Motion, Box<dyn std::error::Error>> {
    let n = motion.frame_count();
    let hold = (HOLD_S / motion.frame_time_s).round() as usize;
    let mut columns = Vec::new();
    for k in 0..n {
        columns.push(k);
        if k == n / 4 || k == n / 2 || k == 3 * n / 4 {
            columns.extend(std::iter::repeat_n(k, hold));
        }
    }
    let frames = DMatrix::from_fn(motion.frames.nrows(), columns.len(), |d, c| {
        motion.frames[(d, columns[c])]
    });
    Ok(Motion::new(motion.frame_time_s, frames)?)
}

/// The first `seconds` of `motion`.
fn first(motion: &Motion, seconds: f64) -> Result<Motion, Box<dyn std::error::Error>> {
    let n = ((seconds / motion.frame_time_s).round() as usize).min(motion.frame_count());
    Ok(Motion::new(
        motion.frame_time_s,
        motion.frames.columns(0, n).into_owned(),
    )?)
}

/// A molded training motion: its files, the seconds molding took, the teacher's scores.
type Molded = (PathBuf, PathBuf, f64, [Scores; 2]);

/// Captures `frames` frames of `motion` and molds them; writes the molded sequence and the
/// true one (true poses, the template's vertices on the true surface) to files; scores the
/// molded frames and LBS with the tracked poses against the truth (every
/// [`TEACHER_STEP`]-th frame).
#[allow(clippy::too_many_arguments)]
fn mold(
    run: &Run,
    dir: &Path,
    name: &str,
    performer: &Performer,
    embedding: &TemplateEmbedding,
    parts: &Parts,
    motion: &Motion,
    frames: usize,
    (width, height): (u32, u32),
) -> Result<Molded, Box<dyn std::error::Error>> {
    let template = &embedding.template;
    // The ring is centred on the root's mean position over the captured frames.
    let frames = frames.min(motion.frame_count());
    let mut root = DVec3::ZERO;
    for k in 0..frames {
        root += performer
            .skeleton
            .forward_kinematics(motion.frame(k))?
            .joint_positions()[0]
            / frames as f64;
    }
    let floor = performer
        .template
        .vertices
        .iter()
        .map(|v| v.y)
        .fold(f64::INFINITY, f64::min);
    let k = Intrinsics::from_horizontal_fov(55f64.to_radians(), width, height)?;
    let rig = Rig::ring(8, 3.5, floor + CAMERA_HEIGHT_M, root, DVec3::Y, k)?;
    let cameras = rig.cameras.clone();
    let spec = CaptureSpec::masks_only(rig).with_frame_rate_hz(FPS);
    let capture = Capture::new(performer, motion, spec)?;
    let stage = run.stage(&format!("{name}: capture and observe"), Some(frames as u64));
    let (mut observations, mut truths, mut meshes) = (Vec::new(), Vec::new(), Vec::new());
    for (k, f) in capture.frames_stepped(0..frames, 1).enumerate() {
        let f = f?;
        if k % TEACHER_STEP == 0 {
            meshes.push(f.truth.true_mesh(performer));
        }
        observations.push(FrameObservation::new(
            &cameras,
            &f.masks(),
            &ContourRayHullParams::default(),
            &SilhouetteParams::default(),
        )?);
        truths.push((
            f.truth.theta.clone(),
            embedding.truth(&f.truth.true_mesh(performer))?,
        ));
        stage.inc(1);
    }
    stage.finish(format!("{frames} frames"));
    let stage = run.stage(&format!("{name}: track and mold"), None);
    let t0 = Instant::now();
    let result = capture_sequence(
        template,
        &observations,
        &truths[0].0,
        &[],
        &PoseParams::default(),
        &ShapeParams {
            start: ShapeStart::PreviousFrame,
            ..ShapeParams::default()
        },
    )?;
    let seconds = t0.elapsed().as_secs_f64();
    stage.finish(format!("{:.2} s per frame", seconds / frames as f64));
    let dofs = template.skeleton().dof_count();
    let n = template.vertex_count();
    let (molded, truth) = sequence_paths(dir, name);
    let mut w = SequenceWriter::create(&molded, n, dofs, 1.0 / FPS)?;
    for (theta, v) in result.poses.poses.iter().zip(&result.shapes.frames) {
        w.push(theta, v)?;
    }
    w.finish()?;
    let mut w = SequenceWriter::create(&truth, n, dofs, 1.0 / FPS)?;
    for (theta, v) in &truths {
        w.push(theta, v)?;
    }
    w.finish()?;
    // The teacher: the molded frames and LBS with the tracked poses against the truth.
    let mut teacher = [Scores::default(), Scores::default()];
    for (k, true_mesh) in meshes.iter().enumerate() {
        let t = k * TEACHER_STEP;
        let lbs = template.skin(&result.poses.poses[t])?;
        parts.score(
            &mut teacher,
            &[&result.shapes.frames[t], &lbs],
            template,
            true_mesh,
        )?;
    }
    Ok((molded, truth, seconds, teacher))
}

/// The molded and the true sequence files of training motion `name`.
fn sequence_paths(dir: &Path, name: &str) -> (PathBuf, PathBuf) {
    (
        dir.join(format!("{name}_molded.dsmold")),
        dir.join(format!("{name}_truth.dsmold")),
    )
}

/// One driven test motion: per frame (30 fps, after the rest hold) the suit's poses, the true
/// poses and the true meshes.
struct Driven {
    name: &'static str,
    suit: Vec<Vec<f64>>,
    truth: Vec<Vec<f64>>,
    meshes: Vec<TriMesh>,
    /// Frames before the first scored one (the suit's rest hold).
    rest: usize,
    suit_error_deg: f64,
}

/// The suit simulated on `motion`, the pipeline's poses resampled to [`FPS`] with the root
/// from the truth, and the studio's truth along the same smoothed motion.
fn drive(
    name: &'static str,
    performer: &Performer,
    deformation: &DeformationParams,
    motion: &Motion,
) -> Result<Driven, Box<dyn std::error::Error>> {
    let skeleton = &performer.skeleton;
    let sim_params = SimulationParams::default();
    let sim = SuitSimulator::on_performer(performer, deformation, sim_params)?;
    let cal = sim.calibrate_offsets(3)?;
    let smooth = prepare_motion(skeleton, motion, &sim_params)?;
    let rec = sim.record(&smooth, &cal.offsets)?;
    let (code_gyro, code_accel) = sim_params.code_noise()?;
    // The inertial example's frozen filter point (A+G+D, root supplied).
    let filter = FilterParams {
        process_sigma: 20.0,
        distance_gate_sigma: 4.0,
        ..FilterParams::default()
            .with_recentre_rad(0.3)
            .with_measurement_sigmas(0.3f64.hypot(code_accel), 0.002f64.hypot(code_gyro), 0.0025)
    };
    let result = pipeline::run(
        skeleton,
        &rec.recording,
        &PipelineParams::default().with_filter(filter),
    )?;
    let (suit_hz, start_s) = (rec.recording.rate_hz, rec.recording.start_s);
    let (truth, meshes) = true_frames(performer, &smooth)?;
    let nd = skeleton.dof_count();
    let root: Vec<usize> = skeleton.joint_dofs(0).collect();
    let mut suit = Vec::new();
    let mut errors = Vec::new();
    for (k, theta) in truth.iter().enumerate() {
        let t = k as f64 / FPS;
        let x = ((t - start_s) * suit_hz).max(0.0);
        let i = (x.floor() as usize).min(result.theta.len() - 1);
        let j = (i + 1).min(result.theta.len() - 1);
        let u = x - i as f64;
        let mut estimate: Vec<f64> = (0..nd)
            .map(|d| {
                let (a, b) = (result.theta[i][d], result.theta[j][d]);
                let step = if skeleton.is_rotation(d) {
                    (b - a) - std::f64::consts::TAU * ((b - a) / std::f64::consts::TAU).round()
                } else {
                    b - a
                };
                a + u * step
            })
            .collect();
        for &d in &root {
            estimate[d] = theta[d];
        }
        errors.push(
            dynamic_shapes::inertial::joint_orientation_errors_deg(
                skeleton,
                &estimate,
                theta,
                &(1..skeleton.joint_count()).collect::<Vec<_>>(),
            )?
            .iter()
            .copied()
            .sum::<f64>()
                / (skeleton.joint_count() - 1) as f64,
        );
        suit.push(estimate);
    }
    let rest = ((start_s + rec.recording.rest_frames as f64 / suit_hz) * FPS).ceil() as usize;
    Ok(Driven {
        name,
        suit,
        truth,
        meshes,
        rest,
        suit_error_deg: mean(&errors[rest..]),
    })
}

/// Per frame, a pose and the true mesh.
type TrueFrames = (Vec<Vec<f64>>, Vec<TriMesh>);

/// The studio's truth along `smooth` (a motion as the suit simulation smooths it), per frame
/// at [`FPS`]: the pose and the true mesh.
fn true_frames(
    performer: &Performer,
    smooth: &SmoothMotion,
) -> Result<TrueFrames, Box<dyn std::error::Error>> {
    let frames = (smooth.duration_s() * FPS).floor() as usize;
    let nd = performer.skeleton.dof_count();
    let (mut theta, mut rate, mut acc) = (vec![0.0; nd], vec![0.0; nd], vec![0.0; nd]);
    let truth: Vec<Vec<f64>> = (0..frames)
        .map(|k| {
            smooth.eval(k as f64 / FPS, &mut theta, &mut rate, &mut acc);
            theta.clone()
        })
        .collect();
    let mut state = DeformationState::default();
    let meshes = truth
        .iter()
        .map(|th| Ok(performer.mesh(performer.pose(th, &mut state, 1.0 / FPS)?.true_vertices)))
        .collect::<Result<Vec<_>, Box<dyn std::error::Error>>>()?;
    Ok((truth, meshes))
}

/// A shape model driven from rest along `poses`, one surface per pose.
fn driven(
    model: &ShapeModel,
    poses: &[Vec<f64>],
) -> Result<Vec<Vec<DVec3>>, Box<dyn std::error::Error>> {
    let mut driver = model.driver();
    Ok(poses
        .iter()
        .map(|th| driver.step(th))
        .collect::<Result<_, _>>()?)
}

/// Surface scores of one variant over a driven motion: per frame (skirt mean, m) and pooled.
#[derive(Default)]
struct Scores {
    skirt: Vec<f64>,
    skirt_p95: Vec<f64>,
    body: Vec<f64>,
    body_p95: Vec<f64>,
}

impl Scores {
    /// Scores `mesh` against the truth: per part (the skirt, the body), the part's vertices
    /// to the true surface pooled with the true part's vertices to `mesh`'s surface.
    fn add(
        &mut self,
        mesh: &TriMesh,
        [skirt, body]: [&[usize]; 2],
        truth: &MeshQuery,
        [true_skirt, true_body]: [&[DVec3]; 2],
    ) -> Result<(), Box<dyn std::error::Error>> {
        let query = MeshQuery::new(mesh)?;
        let to_truth = points_to_surface(&mesh.vertices, truth)?.per_vertex;
        let part = |ours: &[usize],
                    theirs: &[DVec3]|
         -> Result<DistanceStats, Box<dyn std::error::Error>> {
            let pooled: Vec<f64> = ours
                .iter()
                .map(|&v| to_truth[v])
                .chain(points_to_surface(theirs, &query)?.per_vertex)
                .collect();
            Ok(DistanceStats::from_distances(&pooled)?)
        };
        let (s, b) = (part(skirt, true_skirt)?, part(body, true_body)?);
        self.skirt.push(s.mean);
        self.skirt_p95.push(s.p95);
        self.body.push(b.mean);
        self.body_p95.push(b.p95);
        Ok(())
    }

    fn extend(&mut self, other: Scores) {
        self.skirt.extend(other.skirt);
        self.skirt_p95.extend(other.skirt_p95);
        self.body.extend(other.body);
        self.body_p95.extend(other.body_p95);
    }

    fn insert(&self, figures: &mut Map<String, Value>, prefix: &str) {
        for (k, v) in [
            ("skirt_surface_mean_mm", &self.skirt),
            ("skirt_surface_p95_mm", &self.skirt_p95),
            ("body_surface_mean_mm", &self.body),
            ("body_surface_p95_mm", &self.body_p95),
        ] {
            figures.insert(format!("{prefix}{k}"), json!(1e3 * mean(v)));
        }
    }
}

/// Which vertices the scores split into skirt and body, on the template and on the truth.
struct Parts {
    skirt: Vec<usize>,
    body: Vec<usize>,
    true_skirt: std::ops::Range<usize>,
    /// Per true vertex, whether the template cannot show it (the legs under the skirt).
    hidden: Vec<bool>,
}

impl Parts {
    fn new(performer: &Performer, embedding: &TemplateEmbedding) -> Self {
        let (skirt, body) =
            (0..embedding.template.vertex_count()).partition(|&v| embedding.on_skirt[v]);
        Parts {
            skirt,
            body,
            true_skirt: performer.garment_vertices(),
            hidden: embedding.hidden.clone(),
        }
    }

    /// Adds the scores of each of `variants` (template vertices) against `true_mesh`.
    fn score(
        &self,
        scores: &mut [Scores],
        variants: &[&[DVec3]],
        template: &dynamic_shapes::template::Template,
        true_mesh: &TriMesh,
    ) -> Result<(), Box<dyn std::error::Error>> {
        let query = MeshQuery::new(true_mesh)?;
        let true_skirt: Vec<DVec3> = self
            .true_skirt
            .clone()
            .map(|v| true_mesh.vertices[v])
            .collect();
        let true_body: Vec<DVec3> = (0..self.true_skirt.start)
            .filter(|&v| !self.hidden[v])
            .map(|v| true_mesh.vertices[v])
            .collect();
        for (s, v) in scores.iter_mut().zip(variants) {
            s.add(
                &template.mesh_with(v.to_vec()),
                [&self.skirt, &self.body],
                &query,
                [&true_skirt, &true_body],
            )?;
        }
        Ok(())
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = Args::parse();
    let quick = args.common.quick;
    let score_step = args.score_step.unwrap_or(if quick { 3 } else { 1 }).max(1);
    let (size, train_frames, test_s) = if quick {
        ((480, 360), 90, 8.0)
    } else {
        ((800, 600), 300, 20.0)
    };
    let mut run = Run::start(
        "capture_anywhere",
        &args.common,
        "A dynamic shape model learned from template-silhouette's molded sequences of the \
         performer in the skirt, driven by the inertial suit's poses in unseen motions, scored \
         against the studio's truth (Vlasic 2010 Ch. 6)",
    )?;
    let mut figures = Map::new();
    let (performer, deformation) = skirt_performer()?;
    let stage = run.stage("scanned template, bone-heat weights", None);
    let embedding = TemplateEmbedding::new(&performer, TEMPLATE_VERTICES, true, true)?;
    stage.finish(format!("{} vertices", embedding.template.vertex_count()));
    let template = &embedding.template;
    let skeleton = performer.skeleton.clone();
    let parts = Parts::new(&performer, &embedding);

    // 1. Learn in the studio.
    let exercise = |seed: u64, s: f64| {
        exercise_motion(
            &skeleton,
            &ExerciseParams::default().with_seed(seed).with_duration_s(s),
        )
        .and_then(|m| m.resample(&skeleton, 1.0 / FPS))
    };
    let train_s = train_frames as f64 / FPS + 1.0;
    let dir = args
        .sequences
        .clone()
        .unwrap_or_else(|| run.path("sequences"));
    std::fs::create_dir_all(&dir)?;
    let (mut molded, mut truth_files) = (Vec::new(), Vec::new());
    let mut mold_s = None;
    // The molded training frames and LBS with their tracked poses, against the truth.
    let mut teacher = [Scores::default(), Scores::default()];
    for (name, motion) in [
        ("train_exercise", exercise(TRAIN_SEED, train_s)?),
        ("train_walk1", walk1(&skeleton, train_s)?),
    ] {
        let (m, t) = sequence_paths(&dir, name);
        if !(args.sequences.is_some() && m.exists() && t.exists()) {
            let (.., s, [molding, lbs]) = mold(
                &run,
                &dir,
                name,
                &performer,
                &embedding,
                &parts,
                &motion,
                train_frames,
                size,
            )?;
            *mold_s.get_or_insert(0.0) += s;
            teacher[0].extend(molding);
            teacher[1].extend(lbs);
        }
        molded.push(m);
        truth_files.push(t);
    }
    let stage = run.stage("learn the shape model", None);
    let params = ShapeModelParams::default();
    let t0 = Instant::now();
    let model = ShapeModel::learn(template, &mut SequenceFiles(molded.clone()), &params)?;
    let learn_s = t0.elapsed().as_secs_f64();
    let oracle = ShapeModel::learn(template, &mut SequenceFiles(truth_files.clone()), &params)?;
    stage.finish(format!(
        "{} frames, {} components, {learn_s:.2} s",
        model.training_frames(),
        model.components()
    ));
    let five_minutes = (300.0 * FPS) as usize;
    let repeats = five_minutes.div_ceil(model.training_frames());
    let stage = run.stage("learn from five minutes of frames", None);
    let t0 = Instant::now();
    let long = ShapeModel::learn(
        template,
        &mut SequenceFiles(
            molded
                .iter()
                .cycle()
                .take(repeats * molded.len())
                .cloned()
                .collect(),
        ),
        &params,
    )?;
    let learn_5min_s = t0.elapsed().as_secs_f64();
    stage.finish(format!(
        "{} frames, {learn_5min_s:.1} s",
        long.training_frames()
    ));
    drop(long);
    let model_path = run.path("model.dssm");
    model.save(&model_path)?;
    let model = ShapeModel::load(&model_path)?;
    if args.sequences.is_none() {
        std::fs::remove_dir_all(&dir)?;
    }

    // 2. Drive it anywhere.
    let walk = cmu_walk(&skeleton)?;
    let tests = [
        ("exercise", exercise(TEST_SEED, test_s)?),
        ("cmu_walk", first(&walk, test_s)?),
        (
            "stop_and_go",
            first(&stop_and_go(&walk)?, test_s + 3.0 * HOLD_S)?,
        ),
    ];
    // The model's ceiling: learned from the truth of the test motions themselves (true poses,
    // the template's vertices on the true surface), with the default ridge weights and no
    // validation. What the model's form can show of these motions, whatever it is taught.
    let stage = run.stage("learn from the test motions' truth (ceiling)", None);
    let in_sample_dir = run.path("in_sample");
    std::fs::create_dir_all(&in_sample_dir)?;
    let mut in_sample_files = Vec::new();
    for (name, motion) in &tests {
        let smooth = prepare_motion(&skeleton, motion, &SimulationParams::default())?;
        let (truth, meshes) = true_frames(&performer, &smooth)?;
        let path = in_sample_dir.join(format!("{name}.dsmold"));
        let mut w = SequenceWriter::create(
            &path,
            template.vertex_count(),
            skeleton.dof_count(),
            1.0 / FPS,
        )?;
        for (theta, mesh) in truth.iter().zip(&meshes) {
            w.push(theta, &embedding.truth(mesh)?)?;
        }
        w.finish()?;
        in_sample_files.push(path);
    }
    let ceiling = ShapeModel::learn(
        template,
        &mut SequenceFiles(in_sample_files),
        &ShapeModelParams {
            cross_validate: false,
            ..params.clone()
        },
    )?;
    std::fs::remove_dir_all(&in_sample_dir)?;
    stage.finish(format!("{} frames", ceiling.training_frames()));
    let skirt = &parts.skirt;
    let rest_skirt: Vec<DVec3> = skirt.iter().map(|&v| template.mesh().vertices[v]).collect();
    let hem_y = rest_skirt.iter().map(|v| v.y).fold(f64::INFINITY, f64::min);
    let hem: Vec<usize> = skirt
        .iter()
        .copied()
        .filter(|&v| template.mesh().vertices[v].y < hem_y + HEM_BAND_M)
        .collect();
    let names = [
        "lbs_",
        "pose_only_",
        "",
        "oracle_pose_",
        "oracle_truth_trained_",
        "oracle_in_sample_",
        "oracle_pose_lbs_",
    ];
    let mut all: Vec<Scores> = names.iter().map(|_| Scores::default()).collect();
    // Squared skirt distances to the truth, true poses: [full model, pose part] for the
    // model, the truth-trained oracle and the ceiling.
    let mut explained = [[0.0; 2]; 3];
    let (mut model_frames, mut model_s) = (0usize, 0.0);
    let mut suit_errors = Vec::new();
    for (name, motion) in &tests {
        let stage = run.stage(&format!("{name}: suit, pipeline, truth"), None);
        let d = drive(name, &performer, &deformation, motion)?;
        stage.finish(format!(
            "{} frames, suit error {:.2}°",
            d.suit.len(),
            d.suit_error_deg
        ));
        suit_errors.push(d.suit_error_deg);
        figures.insert(
            format!("{name}_suit_joint_error_deg"),
            json!(d.suit_error_deg),
        );
        // The variants' surfaces.
        let t0 = Instant::now();
        let full = driven(&model, &d.suit)?;
        model_s += t0.elapsed().as_secs_f64();
        model_frames += d.suit.len();
        let full_true = driven(&model, &d.truth)?;
        let oracle_true = driven(&oracle, &d.truth)?;
        let ceiling_true = driven(&ceiling, &d.truth)?;
        let mut scores: Vec<Scores> = names.iter().map(|_| Scores::default()).collect();
        let mut hem_lag: [Vec<(f64, f64)>; 3] = [vec![], vec![], vec![]];
        let stage = run.stage(
            &format!("{name}: score"),
            Some((d.suit.len() - d.rest) as u64),
        );
        let mut scored = Vec::new();
        for t in d.rest..d.suit.len() {
            let true_mesh = &d.meshes[t];
            let variants = [
                template.skin(&d.suit[t])?,
                model.pose_shape(&d.suit[t])?,
                full[t].clone(),
                full_true[t].clone(),
                oracle_true[t].clone(),
                ceiling_true[t].clone(),
                template.skin(&d.truth[t])?,
            ];
            if (t - d.rest) % score_step == 0 {
                scored.push(t as f64 / FPS);
                let refs: Vec<&[DVec3]> = variants.iter().map(Vec::as_slice).collect();
                parts.score(&mut scores, &refs, template, true_mesh)?;
            }
            // Dynamic variance explained, true poses: the pose part's skirt residual against
            // the full model's.
            let on_truth = embedding.truth(true_mesh)?;
            for (k, (m, full)) in [
                (&model, &full_true[t]),
                (&oracle, &oracle_true[t]),
                (&ceiling, &ceiling_true[t]),
            ]
            .into_iter()
            .enumerate()
            {
                let pose_true = m.pose_shape(&d.truth[t])?;
                for &v in skirt {
                    explained[k][1] += pose_true[v].distance_squared(on_truth[v]);
                    explained[k][0] += full[v].distance_squared(on_truth[v]);
                }
            }
            // Hem lag: the hem's mean offset from the pelvis along the pelvis's forward axis.
            let fk = skeleton.forward_kinematics(&d.truth[t])?;
            let pelvis = fk.world_from_joint()[0];
            let forward = pelvis.transform_vector3(DVec3::Z).normalize();
            let lag = |x: &[DVec3]| {
                1e3 * hem
                    .iter()
                    .map(|&v| (x[v] - pelvis.translation).dot(forward))
                    .sum::<f64>()
                    / hem.len() as f64
            };
            let time = t as f64 / FPS;
            hem_lag[0].push((time, lag(&on_truth)));
            hem_lag[1].push((time, lag(&variants[0])));
            hem_lag[2].push((time, lag(&full[t])));
            stage.inc(1);
        }
        stage.finish("");
        if d.name == "stop_and_go" {
            pictures(&mut run, &d, template, &full, (&scored, &scores), &hem_lag)?;
        }
        for (k, prefix) in names.iter().enumerate() {
            scores[k].insert(&mut figures, &format!("{name}_{prefix}"));
            all[k].extend(std::mem::take(&mut scores[k]));
        }
    }
    for (k, prefix) in names.iter().enumerate() {
        all[k].insert(&mut figures, prefix);
    }
    if !teacher[0].skirt.is_empty() {
        teacher[0].insert(&mut figures, "teacher_");
        teacher[1].insert(&mut figures, "teacher_lbs_");
    }
    let ratio = figures["skirt_surface_mean_mm"]
        .as_f64()
        .unwrap_or(f64::NAN)
        / figures["lbs_skirt_surface_mean_mm"]
            .as_f64()
            .unwrap_or(f64::NAN);
    figures.insert("skirt_surface_ratio_lbs".into(), json!(ratio));
    for (k, prefix) in ["", "oracle_truth_trained_", "oracle_in_sample_"]
        .iter()
        .enumerate()
    {
        figures.insert(
            format!("{prefix}dynamic_variance_explained"),
            json!(1.0 - explained[k][0] / explained[k][1]),
        );
    }
    figures.insert("model_fps".into(), json!(model_frames as f64 / model_s));
    figures.insert("learn_s".into(), json!(learn_s));
    figures.insert("learn_5min_s".into(), json!(learn_5min_s));
    if let Some(s) = mold_s {
        figures.insert(
            "mold_s_per_frame".into(),
            json!(s / (2 * train_frames) as f64),
        );
    }
    for (prefix, m) in [("", &model), ("oracle_truth_trained_", &oracle)] {
        let ([pose, dynamic], validation_m) = m.ridge();
        figures.insert(format!("{prefix}pose_ridge"), json!(pose));
        figures.insert(format!("{prefix}dynamic_ridge"), json!(dynamic));
        figures.insert(
            format!("{prefix}validation_rms_mm"),
            json!(validation_m.map(|e| e * 1e3)),
        );
    }
    figures.insert("training_frames".into(), json!(model.training_frames()));
    figures.insert("components".into(), json!(model.components()));
    figures.insert("suit_joint_error_deg".into(), json!(mean(&suit_errors)));
    for h in headlines() {
        run.headline(h);
    }
    run.finish(Value::Object(figures))?;
    Ok(())
}

fn headlines() -> Vec<Headline> {
    vec![
        Headline::new(
            "skirt_surface_mean_mm",
            "skirt surface error, suit poses",
            "mm",
        ),
        Headline::new(
            "lbs_skirt_surface_mean_mm",
            "LBS skirt surface error, suit poses",
            "mm",
        )
        .baseline(),
        Headline::new("skirt_surface_ratio_lbs", "model / LBS on the skirt", "")
            .goal(Goal::AtMost(0.6)),
        Headline::new(
            "pose_only_skirt_surface_mean_mm",
            "pose-dependent part alone, skirt",
            "mm",
        )
        .baseline(),
        Headline::new(
            "oracle_pose_skirt_surface_mean_mm",
            "model with the true poses, skirt",
            "mm",
        )
        .oracle(),
        Headline::new(
            "oracle_truth_trained_skirt_surface_mean_mm",
            "model learned from the truth, true poses, skirt",
            "mm",
        )
        .oracle(),
        Headline::new(
            "oracle_pose_lbs_skirt_surface_mean_mm",
            "LBS with the true poses, skirt",
            "mm",
        )
        .oracle(),
        Headline::new(
            "oracle_in_sample_skirt_surface_mean_mm",
            "model learned from the test motions' truth (its ceiling), true poses, skirt",
            "mm",
        )
        .oracle(),
        Headline::new(
            "dynamic_variance_explained",
            "skirt dynamics explained, true poses",
            "",
        )
        .goal(Goal::AtLeast(0.5)),
        Headline::new(
            "oracle_in_sample_dynamic_variance_explained",
            "skirt dynamics explained by the ceiling, true poses",
            "",
        )
        .oracle(),
        Headline::new(
            "body_surface_mean_mm",
            "body surface error, suit poses",
            "mm",
        ),
        Headline::new("model_fps", "model speed, one thread", "fps").goal(Goal::AtLeast(100.0)),
        Headline::new("learn_5min_s", "learning five minutes of frames", "s")
            .goal(Goal::AtMost(60.0)),
    ]
}

/// The stop-and-go walk's pictures and glTF.
fn pictures(
    run: &mut Run,
    d: &Driven,
    template: &dynamic_shapes::template::Template,
    full: &[Vec<DVec3>],
    (scored, scores): (&[f64], &[Scores]),
    hem_lag: &[Vec<(f64, f64)>; 3],
) -> Result<(), Box<dyn std::error::Error>> {
    let chart = Chart::new(
        "Skirt hem lag over the stop-and-go walk (suit poses)",
        "time (s)",
        "hem ahead of the pelvis (mm)",
    );
    let mut chart = chart
        .with(Series::new(
            "truth",
            [30, 30, 30],
            Style::Line,
            hem_lag[0].clone(),
        ))
        .with(Series::new(
            "LBS",
            [220, 120, 40],
            Style::Dashed,
            hem_lag[1].clone(),
        ))
        .with(Series::new(
            "model",
            [40, 90, 200],
            Style::Line,
            hem_lag[2].clone(),
        ));
    chart.y_from_zero = false;
    run.save_picture(
        "hem_lag.png",
        &chart.draw()?,
        "The skirt hem's mean offset along the pelvis's forward axis over the stop-and-go walk: \
         the truth, LBS and the learned model, both driven by the suit's poses",
    )?;
    let series = |k: usize| {
        scored
            .iter()
            .copied()
            .zip(scores[k].skirt.iter().map(|e| 1e3 * e))
            .collect()
    };
    let chart = Chart::new(
        "Skirt surface error per frame, stop-and-go walk",
        "time (s)",
        "two-way surface distance, mean (mm)",
    )
    .with(Series::new(
        "LBS, suit poses",
        [220, 120, 40],
        Style::Dashed,
        series(0),
    ))
    .with(Series::new(
        "pose part, suit poses",
        [120, 160, 60],
        Style::Line,
        series(1),
    ))
    .with(Series::new(
        "model, suit poses",
        [40, 90, 200],
        Style::Line,
        series(2),
    ))
    .with(Series::new(
        "model, true poses (oracle)",
        [150, 150, 150],
        Style::Dashed,
        series(3),
    ));
    run.save_picture(
        "skirt_error.png",
        &chart.draw()?,
        "Skirt surface error per frame over the stop-and-go walk",
    )?;
    // One frame a second after the first hold starts.
    let k = (d.suit.len() / 4 + (FPS as usize)).clamp(d.rest, d.suit.len() - 1);
    let lbs = template.mesh_with(template.skin(&d.suit[k])?);
    let model = template.mesh_with(full[k].clone());
    let img = preview(
        &[
            PreviewPanel {
                mesh: &d.meshes[k],
                paint: Paint::Flat([200, 200, 200]),
            },
            PreviewPanel {
                mesh: &lbs,
                paint: Paint::Flat([230, 170, 120]),
            },
            PreviewPanel {
                mesh: &model,
                paint: Paint::Flat([140, 170, 230]),
            },
        ],
        360,
    )?;
    run.save_picture(
        "frames.png",
        &img,
        "One frame of the stop-and-go walk, a second into the first hold: the truth (grey), \
         LBS with the suit's pose (orange), the learned model with the suit's pose (blue)",
    )?;
    let frames: Vec<Vec<DVec3>> = full[d.rest..].to_vec();
    save_gltf_animation(
        run.path("stop_and_go.glb"),
        &MeshSequence {
            faces: &template.mesh().faces,
            frames: &frames,
            frame_time_s: 1.0 / FPS,
            uvs: None,
            name: "capture_anywhere",
        },
    )?;
    run.picture(
        "stop_and_go.glb",
        "The learned model driven by the suit over the stop-and-go walk (glTF 2.0 morph-target \
         animation)",
    );
    Ok(())
}
