//! Validation of inertial-acoustic (Vlasic 2010 thesis, Chapter 4) on the synthetic studio.
//!
//! The thesis's suit (18 boards, 8 sources) is simulated on studio motions down to its raw
//! signals — 12-bit inertial counts through the 6-bit delta code with error correction and
//! scrambling, 140 kHz microphone frames with 10-cycle 40 kHz pulses — and processed by the
//! crate: ultrasonic detection (§4.3.1), calibration (§4.3.3), initialisation (§4.4.4) and the
//! skeletal EKF (§4.4).
//!
//! * Distance accuracy as §4.3.3 measures it: static placements 30–90 cm apart, per-source
//!   offsets, leave-one-out errors (`distance_error_mean_mm`, `_sd_mm`).
//! * Filter noise levels and the 3-DOF joints' chart tuned on separate tuning clips (exercise
//!   motion, two other seeds; one with `--quick`) on a grid, then frozen (§4.4.1 "hand
//!   tuned ... by tracking several motions").
//! * Table 4.1: neck, right shoulder, left hip orientation errors for A, A+D, D, G, G+D, A+G,
//!   A+G+D, with and without the root transform supplied, on the exercise motion (30 s), its
//!   range of motion and the CMU walk (8 s) — `table_4_1.png`, `figures.json`.
//! * Skin motion: the boards and sources ride on the studio's MakeHuman performer, attached to
//!   triangles of its surface that move with the pose-driven deformation; the same suit fixed
//!   rigidly to the bones is run on the exercise motion too (`table_4_1_exercise_rigid_
//!   attachment`), and the per-board motion relative to the bone is reported
//!   (`skin_motion_*`, `skin_motion.png`).
//! * Local parameterisation of the 3-DOF joints (`FilterParams::recentre_rad`): the tuning
//!   grid includes the chart (Euler angles throughout or re-centred), and the exercise table
//!   is also run in the chart not picked (`table_4_1_exercise_other_chart`,
//!   `agd_other_chart_deg`): before and after.
//! * Gyroscope bias: the suit's gyroscopes carry the MEMS bias model
//!   (`GyroBiasModel::Mems`, ADXRS300-class figures: turn-on offset, warm-up drift,
//!   instability, g-sensitivity); the exercise table is also run with the bias as a random
//!   walk from zero (`table_4_1_exercise_random_walk_bias`, `agd_random_walk_bias_deg`).
//! * Figure 4-7 over minutes: a treadmill walk (the CMU walk looped in place, 180 s; 45 s with
//!   `--quick`; its bone twist rate limited to 10 rad/s: the capture's right humerus twists at
//!   35 rad/s), A+G+D and A+G each tuned on the same grid (the distance gate, 4σ or 8σ, is
//!   a point of A+G+D's only) on a separate treadmill clip (another simulation seed, 30 s;
//!   15 s with `--quick`), run through the pipeline with its
//!   default per-board noise on the simulated suit and on oracle measurements: left-shoulder
//!   error over the last 30 s (`drift_with_d_deg`, `drift_without_d_deg`), the slope of a
//!   line fitted to it (`drift_slope_*_deg_per_s`), the oracle's largest error
//!   (`drift_oracle_max_deg`), `treadmill` with the left-arm boards' distance innovations,
//!   `drift.png`.
//! * The pipeline as a user runs it: every simulated recording is written in the crate's
//!   recording format (a JSON manifest and CSV streams, `Recording::write`), read back
//!   (checked exact) and run through the public `pipeline` (Table 4.1's runs with its
//!   default per-board noise); the exercise recording stays in `recording_exercise/`.
//! * Speed: `realtime_factor` = seconds of motion per second of compute for ultrasonic
//!   processing + inertial decoding + EKF (A+G+D, root supplied), one core, per stage too.
//!
//! * Real recordings (`real_imu.rs`): the orientation part of the filter on BROAD, its gain
//!   tuned on trial 09 and tested on trial 07 (`broad_test_rmse_deg`, inclination and
//!   heading, against the optical reference, beside `broad_gyro_only_test_rmse_deg`;
//!   estimate in `broad_ours.csv`) and on the 135 s x-io log (stability). The x-io Fusion
//!   AHRS comparison runs outside CI: `bench/inertial_vs_peers.sh` (needs a Python venv with
//!   `imufusion` and `filterpy`; see the script) runs this example with `--real-only`, then
//!   `examples/inertial_capture/fusion_broad.py`, which tunes Fusion's gain on trial 09 the
//!   same way and scores both estimates on trial 07 with the same metric, in one run.
//!
//! * The FilterPy peer workload (`peer_ekf.rs`: `../shared/bench/peers/ekf.py` regenerated,
//!   per-step time and RMS error as the peer line; the ratio comes from
//!   `bench/inertial_vs_peers.sh`).
//!
//! `cargo run --release --example inertial_capture [-- --quick]` (`--quick`: 10 s exercise,
//! 10 s of the range of motion, the walk, a 45 s treadmill run, smaller tuning grids;
//! `--delta-step N`: the noise-shaped delta code's unit, default 16, 0 for the whole-count
//! code; `--no-code-noise`: the filter is not told the code's per-frame error; `--ber R`: the
//! link's bit error rate; `--key-interval K`: key frames every K frames, 0 for none;
//! `--ber-sweep K1,K2,…`: only the bit-error sweep over key intervals;
//! `--real-only`: only the real recordings and the FilterPy workload, seconds).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)] // not library code

mod peer_ekf;
mod real_imu;

use clap::Parser;
use serde_json::{json, Value};

use dynamic_shapes::core::math::DQuat;
use dynamic_shapes::core::skeleton::{BvhParams, Motion, Skeleton};
use dynamic_shapes::inertial::pipeline::fit_headings;
use dynamic_shapes::inertial::score::{run_filter, table_4_1, tune, FilterRun, TuningPoint};
use dynamic_shapes::inertial::simulate::{
    model_recording, prepare_motion, treadmill_motion, GyroBiasModel, SimulatedRecording,
    SimulationParams, SuitSimulator,
};
use dynamic_shapes::inertial::tuning::{estimate_board_axis_noise, estimate_board_noise};
use dynamic_shapes::inertial::{
    FilterParams, InnovationStats, Recording, RobustLoss, SensorSet, INNOVATION_TYPES,
};
use dynamic_shapes_studio::{
    exercise_motion, makehuman_performer, play_bvh, range_of_motion, DeformationParams,
    ExerciseParams, RangeOfMotionParams, RetargetParams,
};
use example_kit::plot::{Chart, Series, Style};
use example_kit::{Goal, Headline, Run};

const JOINTS: [&str; 3] = ["neck", "r_shoulder", "l_hip"];
/// Seconds of motion the per-board heading fit (beyond §4.4.4) uses from the recording's start.
const HEADING_FIT_S: f64 = 6.0;
/// Seconds of motion the first pass that estimates the per-board noise (beyond §4.4.2) uses
/// from the recording's start — the pipeline's default
/// (`PipelineParams::DEFAULT_FIRST_PASS_S`).
const BOARD_NOISE_S: f64 = 6.0;

/// A+G+D with the root supplied after the per-board heading step beyond §4.4.4
/// (`refine_recording_headings` over the first `HEADING_FIT_S` of motion), and with the
/// distance σ widened by the garment's unknown placement and skin motion (1 cm and up to
/// 1.4 cm: σ = 12 mm instead of 2.5 mm).
fn variants(
    skeleton: &Skeleton,
    rec: &SimulatedRecording,
    params: FilterParams,
    joints: &[usize],
) -> Result<Value, Box<dyn std::error::Error>> {
    let h = fit_headings(skeleton, &rec.recording, params, true, HEADING_FIT_S)?;
    let mut refined = rec.clone();
    refined.recording.suit = h.suit;
    let stats = |r: &FilterRun| {
        json!({"neck": r.stats[0].mean_deg, "right_shoulder": r.stats[1].mean_deg,
               "left_hip": r.stats[2].mean_deg, "nees": r.nees_mean,
               "swing_twist_deg": r.swing_twist_deg,
               "innovations": consistency(r)})
    };
    let heading = run_filter(skeleton, &refined, params, true, joints)?;
    let wide =
        params.with_measurement_sigmas(params.accelerometer_sigma, params.gyroscope_sigma, 0.012);
    let inflated = run_filter(skeleton, rec, wide, true, joints)?;
    let both = run_filter(skeleton, &refined, wide, true, joints)?;
    // Per-board R from a first pass (same seconds as the heading
    // fit), robust distance updates, and the neck board's readings left out.
    let with_noise =
        |r: &SimulatedRecording| -> Result<SimulatedRecording, Box<dyn std::error::Error>> {
            let n = estimate_board_noise(skeleton, &r.recording, params, true, HEADING_FIT_S)?;
            let mut out = r.clone();
            out.recording.suit = out.recording.suit.with_board_noise(n)?;
            Ok(out)
        };
    let noisy = with_noise(rec)?;
    let refined_noisy = with_noise(&refined)?;
    // One σ per board axis from the same first pass.
    let with_axis_noise =
        |r: &SimulatedRecording| -> Result<SimulatedRecording, Box<dyn std::error::Error>> {
            let n = estimate_board_axis_noise(skeleton, &r.recording, params, true, HEADING_FIT_S)?;
            let mut out = r.clone();
            out.recording.suit = out.recording.suit.with_board_noise(n)?;
            Ok(out)
        };
    let axis_noisy = with_axis_noise(rec)?;
    let refined_axis_noisy = with_axis_noise(&refined)?;
    // Each board's σ from its worst axis (`BoardNoise::worst_axis`).
    let worst = |r: &SimulatedRecording| -> Result<SimulatedRecording, Box<dyn std::error::Error>> {
        let mut out = r.clone();
        out.recording.suit = out.recording.suit.with_worst_axis_noise()?;
        Ok(out)
    };
    let worst_noisy = worst(&axis_noisy)?;
    let refined_worst_noisy = worst(&refined_axis_noisy)?;
    let (huber, cauchy) = (
        params.with_distance_robust(RobustLoss::Huber { k: 1.345 }),
        params.with_distance_robust(RobustLoss::Cauchy { c: 2.385 }),
    );
    let mut no_neck = rec.clone();
    if let Some(b) = rec
        .recording
        .suit
        .boards()
        .iter()
        .position(|b| b.name == "neck")
    {
        for f in &mut no_neck.recording.frames[rec.recording.rest_frames..] {
            f.inertial[b] = None;
        }
    }
    let sigmas = |r: &SimulatedRecording| {
        r.recording
            .suit
            .board_noise()
            .iter()
            .map(|n| json!([n.gyroscope_sigma, n.accelerometer_sigma]))
            .collect::<Vec<_>>()
    };
    let axis_sigmas = |r: &SimulatedRecording| {
        r.recording
            .suit
            .board_noise()
            .iter()
            .map(|n| json!([n.gyroscope_axes(), n.accelerometer_axes()]))
            .collect::<Vec<_>>()
    };
    let baseline = run_filter(skeleton, rec, params, true, joints)?;
    Ok(json!({
        "heading_fit_s": HEADING_FIT_S,
        "headings_deg": h.headings_deg,
        "baseline": stats(&baseline),
        "heading_refined": stats(&heading),
        "distance_sigma_12mm": stats(&inflated),
        "heading_refined_distance_sigma_12mm": stats(&both),
        "board_sigmas": sigmas(&noisy),
        "per_board_noise": stats(&run_filter(skeleton, &noisy, params, true, joints)?),
        "huber": stats(&run_filter(skeleton, rec, huber, true, joints)?),
        "cauchy": stats(&run_filter(skeleton, rec, cauchy, true, joints)?),
        "per_board_noise_huber": stats(&run_filter(skeleton, &noisy, huber, true, joints)?),
        "per_board_noise_cauchy": stats(&run_filter(skeleton, &noisy, cauchy, true, joints)?),
        "heading_refined_per_board_noise": stats(&run_filter(skeleton, &refined_noisy, params, true, joints)?),
        "heading_refined_per_board_noise_cauchy": stats(&run_filter(skeleton, &refined_noisy, cauchy, true, joints)?),
        "neck_board_dropped": stats(&run_filter(skeleton, &no_neck, params, true, joints)?),
        "board_axis_sigmas": axis_sigmas(&axis_noisy),
        "per_axis_noise": stats(&run_filter(skeleton, &axis_noisy, params, true, joints)?),
        "per_axis_noise_cauchy": stats(&run_filter(skeleton, &axis_noisy, cauchy, true, joints)?),
        "heading_refined_per_axis_noise": stats(&run_filter(skeleton, &refined_axis_noisy, params, true, joints)?),
        "heading_refined_per_axis_noise_cauchy": stats(&run_filter(skeleton, &refined_axis_noisy, cauchy, true, joints)?),
        "worst_axis_noise": stats(&run_filter(skeleton, &worst_noisy, params, true, joints)?),
        "heading_refined_worst_axis_noise": stats(&run_filter(skeleton, &refined_worst_noisy, params, true, joints)?),
    }))
}

/// The treadmill's bone twist rate limit (rad/s): under the simulated gyroscopes' ±20 rad/s
/// with room for the swing (≤ 6.6 rad/s on the walk's upper arms).
const TWIST_LIMIT_RAD_S: f64 = 10.0;

/// One treadmill run: left-shoulder error over time, its first / last 5 s and last 30 s
/// means, the slope of a least-squares line through it and its largest value.
struct DriftRun {
    source: &'static str,
    distances: bool,
    first_5s_deg: f64,
    last_5s_deg: f64,
    last_30s_deg: f64,
    slope_deg_per_s: f64,
    max_deg: f64,
    /// Largest error after the first `DRIFT_SETTLE_S` of motion.
    max_settled_deg: f64,
    diverged_frames: usize,
    errors_deg: Vec<f64>,
    /// Distances used over the whole body (passed the confidence, field-of-view and gate
    /// tests), and per left-arm board the distance innovations that reached the gate.
    distances_used: usize,
    left_arm_distances: Value,
}

/// Seconds of the treadmill's error series (after the rest hold) left out of the settled
/// maximum: the blend from the rest pose into the walk and the filter's first gait cycles.
const DRIFT_SETTLE_S: f64 = 10.0;

/// Slope (per second) of the least-squares line through `e`, one value per 140 Hz frame.
fn fitted_slope_per_s(e: &[f64]) -> f64 {
    let n = e.len() as f64;
    let t_mean = (n - 1.0) / 2.0 / 140.0;
    let e_mean = e.iter().sum::<f64>() / n;
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for (i, v) in e.iter().enumerate() {
        let dt = i as f64 / 140.0 - t_mean;
        sxy += dt * (v - e_mean);
        sxx += dt * dt;
    }
    sxy / sxx
}

/// Largest world-frame angular speed (rad/s) of joint `j` between consecutive frames.
fn max_world_speed(skeleton: &Skeleton, motion: &Motion, j: usize) -> f64 {
    let rot = |k: usize| {
        let fk = skeleton.forward_kinematics(motion.frame(k)).unwrap();
        DQuat::from_mat3(&fk.world_from_joint()[j].matrix3)
    };
    let mut prev = rot(0);
    let mut worst = 0.0f64;
    for k in 1..motion.frame_count() {
        let q = rot(k);
        worst = worst.max(q.angle_between(prev) / motion.frame_time_s);
        prev = q;
    }
    worst
}

/// The suit simulated along `motion`, its recording written to `dir` in the crate's
/// recording format and read back, so that every run scores what a user's file gives the
/// pipeline (the round trip is checked to be exact).
fn record(
    sim: &SuitSimulator,
    skeleton: &Skeleton,
    motion: &Motion,
    params: &SimulationParams,
    offsets: &[f64],
    dir: &std::path::Path,
) -> SimulatedRecording {
    let smooth = prepare_motion(skeleton, motion, params).unwrap();
    let mut rec = sim.record(&smooth, offsets).unwrap();
    rec.recording.write(dir, skeleton).unwrap();
    let read = Recording::read(dir, skeleton).unwrap();
    assert!(
        read == rec.recording,
        "the recording file must read back exactly"
    );
    rec.recording = read;
    rec
}

/// A Table 4.1's A+G+D row with the root supplied (the headline row).
fn agd_rooted(table: &[FilterRun]) -> &FilterRun {
    table
        .iter()
        .find(|r| r.sensors == "A+G+D" && r.root_supplied)
        .expect("table_4_1 has an A+G+D row with the root supplied")
}

/// A run's mean error of the three Table 4.1 joints, deg.
fn joint_means(r: &FilterRun) -> Value {
    json!({"neck": r.stats[0].mean_deg, "right_shoulder": r.stats[1].mean_deg,
        "left_hip": r.stats[2].mean_deg})
}

fn run_json(r: &FilterRun) -> Value {
    json!({
        "sensors": r.sensors,
        "root_supplied": r.root_supplied,
        "neck": {"mean_deg": r.stats[0].mean_deg, "sd_deg": r.stats[0].sd_deg},
        "right_shoulder": {"mean_deg": r.stats[1].mean_deg, "sd_deg": r.stats[1].sd_deg},
        "left_hip": {"mean_deg": r.stats[2].mean_deg, "sd_deg": r.stats[2].sd_deg},
        "diverged_frames": r.diverged_frames,
        "distances_used": r.distances_used,
        "ekf_s": r.ekf_s,
        "ekf_cpu_s": r.ekf_cpu_s,
        "nees_mean": r.nees_mean,
        "swing_twist_deg": r.swing_twist_deg,
        "innovations": consistency(r),
    })
}

/// Per sensor type: count, mean normalised innovation and mean NIS over all boards, and the
/// right upper arm's (board 9).
fn consistency(r: &FilterRun) -> Value {
    let mut out = serde_json::Map::new();
    for (t, per_board) in INNOVATION_TYPES.iter().zip(&r.innovations) {
        let all = InnovationStats::pooled(per_board);
        let arm = per_board.get(9).copied().unwrap_or_default();
        out.insert(
            (*t).to_string(),
            json!({"count": all.count, "mean_normalised": all.mean_normalised(),
                   "mean_nis": all.mean_nis(), "pass_rate": all.pass_rate(),
                   "mean_nis_passed": all.mean_nis_passed(), "r_upper_arm_mean_normalised": arm.mean_normalised(),
                   "r_upper_arm_mean_nis": arm.mean_nis()}),
        );
    }
    Value::Object(out)
}

#[derive(Parser, Debug)]
struct Args {
    #[command(flatten)]
    common: example_kit::cli::Common,
    /// The inertial link's code unit in counts for the noise-shaped delta code
    /// (`SimulationParams::delta_step`; default `SimulationParams::DEFAULT_DELTA_STEP`, 16); 0 for
    /// the whole-count code (the thesis's).
    #[arg(long)]
    delta_step: Option<i32>,
    /// Do not add the delta code's per-frame error to the filter's σ_g and σ_a
    /// (`SimulationParams::with_code_noise`, the default); the per-board σ estimate then
    /// has to find it (a comparison).
    #[arg(long)]
    no_code_noise: bool,
    /// Bit error rate of the inertial link (`SimulationParams::bit_error_rate`; default
    /// 2·10⁻⁴).
    #[arg(long)]
    ber: Option<f64>,
    /// Frames between a channel's key frames on the inertial link
    /// (`SimulationParams::key_interval`, default `SimulationParams::DEFAULT_KEY_INTERVAL`); 0 for
    /// none (the thesis's code).
    #[arg(long)]
    key_interval: Option<u32>,
    /// Only the bit-error sweep: the exercise clip (10 s with
    /// `--quick`, else 30 s), A+G+D with the root supplied at the full run's frozen point
    /// (q 20, σ_a 0.3, σ_g 0.002 m/s² / rad/s with the code's σ, gate 4σ, re-centring 0.3),
    /// at the default bit error rate (and the CMU walk there) and at 10⁻³, 3·10⁻³, 10⁻², for
    /// the key intervals given (comma-separated, 0 for none); one JSON line per setting,
    /// then exit.
    #[arg(long, value_delimiter = ',')]
    ber_sweep: Option<Vec<u32>>,
    /// Only the real recordings (BROAD tuning and test trials, the x-io log) and the FilterPy
    /// peer workload, a few seconds: their figures as the JSON line, then exit.
    #[arg(long)]
    real_only: bool,
}

/// The shipped CMU walk (131_01) retargeted onto `skeleton` at 120 Hz.
fn cmu_walk(skeleton: &Skeleton) -> Result<Motion, Box<dyn std::error::Error>> {
    Ok(play_bvh(
        example_kit::data_path("mocap-cmu/131_01.bvh")?,
        &BvhParams::default(),
        skeleton,
        1.0 / 120.0,
        &RetargetParams::default(),
    )?
    .motion)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = Args::parse();
    let quick = args.common.quick;
    let (exercise_s, rom_s, treadmill_s, drift_tune_s) = if quick {
        (10.0, 10.0, 45.0, 15.0)
    } else {
        (30.0, f64::INFINITY, 180.0, 30.0)
    };
    let mut run = Run::start(
        "inertial_capture",
        &args.common,
        &format!(
            "The thesis's suit simulated to raw signals on the exercise motion ({exercise_s} s), \
             the range of motion and the CMU walk; ultrasonic and inertial processing and the \
             skeletal EKF (Vlasic 2010 Ch. 4)"
        ),
    )?;
    // Real recordings first (seconds): BROAD against its optical reference, x-io for stability.
    let mut real = real_imu::run(&mut run)?;
    let stage = run.stage("FilterPy peer workload", None);
    let peer = peer_ekf::run();
    stage.finish(format!(
        "{:.1} µs per step, RMS {:.4} rad",
        1e6 * peer["seconds"].as_f64().unwrap_or(f64::NAN),
        peer["quality"]["rms_angle_err"]
            .as_f64()
            .unwrap_or(f64::NAN)
    ));
    if let Some(r) = real.as_object_mut() {
        r.insert("ekf_peer_workload".into(), peer);
    }
    if args.real_only {
        for h in real_imu::headlines() {
            run.headline(h);
        }
        run.finish(real)?;
        return Ok(());
    }

    // The studio's MakeHuman performer with its pose-driven shapes (no flap: a tight suit);
    // the suit rides on its deforming surface, and the same suit fixed rigidly to the bones
    // is the baseline that shows what the skin motion costs.
    let deformation = DeformationParams::default().with_flap(None);
    let performer = makehuman_performer(example_kit::data_path("makehuman")?, &deformation)?;
    let skeleton = performer.skeleton.clone();
    let joints: Vec<usize> = JOINTS
        .iter()
        .map(|n| skeleton.joint_index(n).unwrap())
        .collect();
    let sim_params = SimulationParams {
        delta_step: match args.delta_step {
            None => SimulationParams::default().delta_step,
            Some(0) => None,
            Some(step) => Some(step),
        },
        bit_error_rate: args
            .ber
            .unwrap_or(SimulationParams::default().bit_error_rate),
        key_interval: args
            .key_interval
            .unwrap_or(SimulationParams::default().key_interval),
        ..SimulationParams::default()
    };
    // The filter's σ_g and σ_a are the sensor's noise (the grid's
    // values) and the delta code's per-frame error in quadrature.
    let (code_gyro, code_accel) = if args.no_code_noise {
        (0.0, 0.0)
    } else {
        sim_params.code_noise()?
    };
    let with_code = |sensor: f64, code: f64| sensor.hypot(code);
    let sim = SuitSimulator::on_performer(&performer, &deformation, sim_params)?;
    // Every simulated recording goes through a file (`record`); this folder is scratch.
    let scratch = run.path("recording_scratch");
    let rigid = sim.clone().with_rigid_attachment();

    // §4.3.3: offsets from static placements; leave-one-out distance errors.
    let stage = run.stage("offset calibration", None);
    let cal = sim.calibrate_offsets(3)?;
    let loo_mm: Vec<f64> = cal.loo_abs_errors_m.iter().map(|e| 1e3 * e).collect();
    let dist_mean = loo_mm.iter().sum::<f64>() / loo_mm.len() as f64;
    let dist_sd =
        (loo_mm.iter().map(|e| (e - dist_mean).powi(2)).sum::<f64>() / loo_mm.len() as f64).sqrt();
    stage.finish(format!("{dist_mean:.2} ± {dist_sd:.2} mm"));

    if let Some(keys) = &args.ber_sweep {
        // The lost-frame weakness of the noise-shaped code and the
        // key frames that resynchronise it, at the full run's frozen filter point.
        let params = FilterParams {
            process_sigma: 20.0,
            distance_gate_sigma: 4.0,
            ..FilterParams::default()
                .with_recentre_rad(0.3)
                .with_measurement_sigmas(
                    with_code(0.3, code_accel),
                    with_code(0.002, code_gyro),
                    0.0025,
                )
        };
        let exercise = exercise_motion(
            &skeleton,
            &ExerciseParams::default().with_duration_s(exercise_s),
        )?;
        let walk = cmu_walk(&skeleton)?;
        let default_ber = SimulationParams::default().bit_error_rate;
        for (motion_name, motion, ber) in [
            ("cmu_walk", &walk, default_ber),
            ("exercise", &exercise, default_ber),
            ("exercise", &exercise, 1e-3),
            ("exercise", &exercise, 3e-3),
            ("exercise", &exercise, 1e-2),
        ] {
            for &key in keys {
                let sim_b = sim.clone().with_link(ber, key)?;
                let rec = record(
                    &sim_b,
                    &skeleton,
                    motion,
                    &sim_params,
                    &cal.offsets,
                    &scratch,
                );
                let r = dynamic_shapes::inertial::score::run_filter_board_noise(
                    &skeleton,
                    &rec,
                    params,
                    true,
                    &joints,
                    BOARD_NOISE_S,
                )?;
                let line = json!({
                    "motion": motion_name, "ber": ber, "key_interval": key,
                    "delta_step": sim_params.delta_step, "exercise_s": exercise_s,
                    "agd_deg": [r.stats[0].mean_deg, r.stats[1].mean_deg, r.stats[2].mean_deg],
                    "diverged_frames": r.diverged_frames,
                    "inertial_frames_flagged": rec.inertial_frames_flagged,
                    "inertial_channels_unsynced": rec.inertial_channels_unsynced,
                    "inertial_channels_decoded": rec.inertial_channels_decoded,
                });
                println!("{line}");
            }
        }
        return Ok(());
    }

    // Tuning on separate clips (other exercise seeds): §4.4.1 hand-tunes "by tracking several
    // motions"; one 10 s clip proved too noisy to choose between the joints' charts.
    let stage = run.stage("tuning grid", None);
    let (qs, sas, gates): (&[f64], &[f64], &[f64]) = if quick {
        (&[0.04, 20.0], &[0.02, 2.0], &[0.0, 4.0])
    } else {
        (&[0.04, 4.0, 20.0, 100.0], &[0.02, 0.3, 2.0], &[0.0, 4.0])
    };
    let sas: Vec<f64> = sas.iter().map(|&sa| with_code(sa, code_accel)).collect();
    let tune_seeds: &[u64] = if quick { &[29] } else { &[29, 31] };
    let mut grid: Vec<(TuningPoint, f64)> = Vec::new();
    for &seed in tune_seeds {
        let tune_motion = exercise_motion(
            &skeleton,
            &ExerciseParams::default()
                .with_duration_s(if quick { 6.0 } else { 10.0 })
                .with_seed(seed),
        )?;
        let tune_rec = record(
            &sim,
            &skeleton,
            &tune_motion,
            &sim_params,
            &cal.offsets,
            &scratch,
        );
        // The 3-DOF joints are re-centred (local chart): fed perfect measurements from its
        // own models (`model_recording`), the filter in Euler angles throughout loses the
        // right shoulder near gimbal lock while the local chart tracks it (docs, test
        // `oracle_measurements_are_tracked_in_the_local_chart`), so the chart is no longer
        // a tuning choice. The gyroscope σ is: the thesis's 0.002 rad/s, or 0.01 rad/s,
        // the RMS of the simulated counts' 10-bit steps (four 10-bit samples without
        // dither), which the consistency check found (gyroscope NIS 20–150 at 0.002).
        for gyro_sigma in [0.002, 0.01].map(|sg| with_code(sg, code_gyro)) {
            let base = FilterParams::default()
                .with_recentre_rad(0.3)
                .with_measurement_sigmas(0.02, gyro_sigma, 0.0025);
            for g in tune(&skeleton, &tune_rec, base, &joints, qs, &sas, gates)? {
                let share = g.score_deg / tune_seeds.len() as f64;
                let key = (
                    g.process_sigma,
                    g.accelerometer_sigma,
                    g.distance_gate_sigma,
                );
                match grid.iter_mut().find(|(o, s)| {
                    (
                        o.process_sigma,
                        o.accelerometer_sigma,
                        o.distance_gate_sigma,
                    ) == key
                        && *s == gyro_sigma
                }) {
                    Some((o, _)) => o.score_deg += share,
                    None => grid.push((
                        TuningPoint {
                            score_deg: share,
                            ..g
                        },
                        gyro_sigma,
                    )),
                }
            }
        }
    }
    grid.sort_by(|a, b| a.0.score_deg.total_cmp(&b.0.score_deg));
    let (best, best_gyro_sigma) = grid[0];
    let paper_point = grid
        .iter()
        .find(|(g, s)| {
            g.process_sigma == 0.04
                && g.accelerometer_sigma == with_code(0.02, code_accel)
                && g.distance_gate_sigma == 0.0
                && *s == with_code(0.002, code_gyro)
        })
        .map(|g| g.0);
    let params = FilterParams {
        process_sigma: best.process_sigma,
        accelerometer_sigma: best.accelerometer_sigma,
        gyroscope_sigma: best_gyro_sigma,
        distance_gate_sigma: best.distance_gate_sigma,
        recentre_rad: best.recentre_rad,
        ..FilterParams::default()
    };
    // The thesis's chart (Euler angles throughout), for the before/after comparison.
    let other_chart = 0.0;
    stage.finish(format!(
        "q {} σa {} σg {} gate {} re-centring {}: {:.2}°",
        best.process_sigma,
        best.accelerometer_sigma,
        best_gyro_sigma,
        best.distance_gate_sigma,
        best.recentre_rad,
        best.score_deg
    ));

    // The evaluation motions.
    let stage = run.stage("simulate and filter", None);
    let exercise = exercise_motion(
        &skeleton,
        &ExerciseParams::default().with_duration_s(exercise_s),
    )?;
    let rom_full = range_of_motion(&skeleton, &RangeOfMotionParams::default())?;
    let rom = if rom_s.is_finite() {
        let n = ((rom_s / rom_full.frame_time_s) as usize + 1).min(rom_full.frame_count());
        Motion::new(
            rom_full.frame_time_s,
            rom_full.frames.columns(0, n).into_owned(),
        )?
    } else {
        rom_full
    };
    let walk = cmu_walk(&skeleton)?;
    let mut tables = Vec::new();
    let (mut us_s, mut in_s, mut ekf_s, mut motion_s) = (0.0, 0.0, 0.0, 0.0);
    let (mut us_cpu_s, mut ekf_cpu_s) = (0.0, 0.0);
    let mut los_errors = Vec::new();
    let mut main_table = Vec::new();
    let mut rigid_table = Vec::new();
    let mut euler_table = Vec::new();
    let mut global_table = Vec::new();
    let mut walk_bias_table = Vec::new();
    let mut skin_motion = Vec::new();
    let mut beyond = Value::Null;
    for (name, motion) in [
        ("exercise", &exercise),
        ("range_of_motion", &rom),
        ("cmu_walk", &walk),
    ] {
        // The exercise recording stays in the output folder, for a user to open.
        let dir = if name == "exercise" {
            run.path("recording_exercise")
        } else {
            scratch.clone()
        };
        let rec = record(&sim, &skeleton, motion, &sim_params, &cal.offsets, &dir);
        let table = table_4_1(&skeleton, &rec, params, &joints, Some(BOARD_NOISE_S))?;
        let seconds = (rec.recording.frames.len() - 1) as f64 / 140.0;
        let agd = agd_rooted(&table);
        us_s += rec.ultrasound_s;
        in_s += rec.inertial_s;
        ekf_s += agd.ekf_s;
        us_cpu_s += rec.ultrasound_cpu_s;
        ekf_cpu_s += agd.ekf_cpu_s;
        motion_s += seconds;
        los_errors.extend(rec.los_distance_errors_m.iter().map(|e| 1e3 * e.abs()));
        stage.println(format!(
            "{name}: {seconds:.1} s, A+G+D with root {:.1}/{:.1}/{:.1}°, heard {}/{} pulses, \
             {} inertial frames flagged",
            agd.stats[0].mean_deg,
            agd.stats[1].mean_deg,
            agd.stats[2].mean_deg,
            rec.pulses_heard,
            rec.pulses_total,
            rec.inertial_frames_flagged
        ));
        if name == "exercise" {
            main_table = table.clone();
            skin_motion = rec.skin_motion.clone();
            let rec_rigid = record(
                &rigid,
                &skeleton,
                motion,
                &sim_params,
                &cal.offsets,
                &scratch,
            );
            rigid_table = table_4_1(&skeleton, &rec_rigid, params, &joints, Some(BOARD_NOISE_S))?;
            // The global σ for every board (§4.4.2), the before of the per-board noise.
            global_table = table_4_1(&skeleton, &rec, params, &joints, None)?;
            // The same suit and seed with the gyroscopes' bias as a random walk from zero
            // (`GyroBiasModel::RandomWalk`) instead of the MEMS model (the default).
            let sim_walk_bias = sim.clone().with_gyro_bias(GyroBiasModel::RandomWalk)?;
            let rec_walk_bias = record(
                &sim_walk_bias,
                &skeleton,
                motion,
                &sim_params,
                &cal.offsets,
                &scratch,
            );
            walk_bias_table = table_4_1(
                &skeleton,
                &rec_walk_bias,
                params,
                &joints,
                Some(BOARD_NOISE_S),
            )?;
            // The same recording with the 3-DOF joints in the other chart (Euler angles
            // throughout, or re-centred): before and after the local parameterisation.
            euler_table = table_4_1(
                &skeleton,
                &rec,
                params.with_recentre_rad(other_chart),
                &joints,
                Some(BOARD_NOISE_S),
            )?;
            let v_garment = variants(&skeleton, &rec, params, &joints)?;
            let v_rigid = variants(&skeleton, &rec_rigid, params, &joints)?;
            for (label, v) in [("garment", &v_garment), ("rigid", &v_rigid)] {
                for key in [
                    "baseline",
                    "heading_refined",
                    "distance_sigma_12mm",
                    "heading_refined_distance_sigma_12mm",
                    "per_board_noise",
                    "huber",
                    "cauchy",
                    "per_board_noise_huber",
                    "per_board_noise_cauchy",
                    "heading_refined_per_board_noise",
                    "heading_refined_per_board_noise_cauchy",
                    "neck_board_dropped",
                    "per_axis_noise",
                    "per_axis_noise_cauchy",
                    "heading_refined_per_axis_noise",
                    "heading_refined_per_axis_noise_cauchy",
                    "worst_axis_noise",
                    "heading_refined_worst_axis_noise",
                ] {
                    let f = |a: &Value| a.as_f64().unwrap_or(f64::NAN);
                    let i = &v[key]["innovations"];
                    stage.println(format!(
                        "exercise, {label}, {key}: A+G+D with root {:.2}/{:.2}/{:.2}° | neck swing/twist {:.2}/{:.2}° | NIS gyro {:.2} accel {:.3} | distances ν/σ {:+.1} NIS {:.0} pass {:.3} NIS passed {:.2}",
                        f(&v[key]["neck"]),
                        f(&v[key]["right_shoulder"]),
                        f(&v[key]["left_hip"]),
                        f(&v[key]["swing_twist_deg"][0][0]),
                        f(&v[key]["swing_twist_deg"][0][1]),
                        f(&i["gyroscope"]["mean_nis"]),
                        f(&i["accelerometer"]["mean_nis"]),
                        f(&i["distance"]["mean_normalised"]),
                        f(&i["distance"]["mean_nis"]),
                        f(&i["distance"]["pass_rate"]),
                        f(&i["distance"]["mean_nis_passed"]),
                    ));
                }
            }
            beyond = json!({"garment": v_garment, "rigid": v_rigid});
            for (label, t) in [
                ("suit rigid on the bones", &rigid_table),
                ("global σ (before per-board noise)", &global_table),
                ("gyroscope bias as a random walk", &walk_bias_table),
                ("other chart of the 3-DOF joints", &euler_table),
            ] {
                let r = agd_rooted(t);
                stage.println(format!(
                    "exercise, {label}: A+G+D with root {:.1}/{:.1}/{:.1}°",
                    r.stats[0].mean_deg, r.stats[1].mean_deg, r.stats[2].mean_deg
                ));
            }
        }
        tables.push(json!({
            "motion": name,
            "seconds": seconds,
            "pulses_heard": rec.pulses_heard,
            "pulses_total": rec.pulses_total,
            "inertial_frames_flagged": rec.inertial_frames_flagged,
            "inertial_channels_unsynced": rec.inertial_channels_unsynced,
            "bits_corrected": rec.bits_corrected,
            "runs": table.iter().map(run_json).collect::<Vec<_>>(),
        }));
    }
    stage.finish("");

    // Figure 4-7: treadmill-like drift, with and without distances. The CMU walk's right
    // humerus twists at 35 rad/s in the source capture itself (as the elbow extends; see
    // skin-core's `retarget_adds_no_angular_velocity_on_the_cmu_walk`), beyond the suit's
    // ±20 rad/s gyroscopes, so the treadmill plays the walk retargeted with the twist rate
    // limited to TWIST_LIMIT_RAD_S (swing kept exactly). Oracle control: the filter's own
    // measurement models along the same truth (no noise, bias or skin motion).
    let stage = run.stage("treadmill drift", None);
    let tread_walk = play_bvh(
        example_kit::data_path("mocap-cmu/131_01.bvh")?,
        &BvhParams::default(),
        &skeleton,
        1.0 / 120.0,
        &RetargetParams {
            twist_rate_limit_rad_per_s: Some(TWIST_LIMIT_RAD_S),
            ..RetargetParams::default()
        },
    )?
    .motion;
    let tread = treadmill_motion(&skeleton, &tread_walk, treadmill_s)?;
    let arm_speeds: Vec<f64> = ["l_shoulder", "r_shoulder", "l_elbow", "r_elbow"]
        .iter()
        .map(|n| max_world_speed(&skeleton, &tread, skeleton.joint_index(n).unwrap()))
        .collect();
    let rec = record(&sim, &skeleton, &tread, &sim_params, &cal.offsets, &scratch);
    let smooth = prepare_motion(&skeleton, &tread, &sim_params)?;
    let oracle = model_recording(&skeleton, sim.nominal_suit(), &smooth, sim_params.rest_s)?;
    let l_shoulder = skeleton.joint_index("l_shoulder").unwrap();
    let no_d = SensorSet {
        distances: false,
        ..SensorSet::ALL
    };
    // A+G and A+G+D are tuned alike on a separate treadmill clip (another simulation seed:
    // other placement errors, bias draws and noise; `drift_tune_s` long), each on the same
    // grid, scored by the mean error of the table's three joints and the left shoulder,
    // through the pipeline with its default per-board noise.
    let tune_sim_params = SimulationParams {
        seed: sim_params.seed + 1,
        ..sim_params
    };
    let sim_tune = SuitSimulator::on_performer(&performer, &deformation, tune_sim_params)?;
    let cal_tune = sim_tune.calibrate_offsets(3)?;
    let tune_tread = treadmill_motion(&skeleton, &tread_walk, drift_tune_s)?;
    let tune_rec = record(
        &sim_tune,
        &skeleton,
        &tune_tread,
        &tune_sim_params,
        &cal_tune.offsets,
        &scratch,
    );
    let (drift_qs, drift_sas, drift_sgs): (&[f64], &[f64], &[f64]) = if quick {
        (&[4.0, 20.0], &[0.3, 2.0], &[0.002])
    } else {
        (&[4.0, 20.0, 100.0], &[0.3, 2.0], &[0.002, 0.01])
    };
    let tune_joints: Vec<usize> = joints.iter().copied().chain([l_shoulder]).collect();
    let mut drift_grid = Vec::new();
    let mut drift_tuned = Vec::new();
    for sensors in [SensorSet::ALL, no_d] {
        let mut best_drift: Option<(f64, FilterParams)> = None;
        // The distance gate (4σ, the Table 4.1 point, or 8σ) acts on distances only: A+G's
        // runs would repeat, so A+G is run once per point.
        let gates: &[f64] = if sensors.distances {
            &[4.0, 8.0]
        } else {
            &[4.0]
        };
        for (&q, &gate) in drift_qs
            .iter()
            .flat_map(|q| gates.iter().map(move |g| (q, g)))
        {
            for &sa in drift_sas {
                for &sg in drift_sgs {
                    let p = FilterParams {
                        process_sigma: q,
                        distance_gate_sigma: gate,
                        ..FilterParams::default()
                            .with_recentre_rad(0.3)
                            .with_measurement_sigmas(
                                with_code(sa, code_accel),
                                with_code(sg, code_gyro),
                                0.0025,
                            )
                            .with_sensors(sensors)
                    };
                    let r = dynamic_shapes::inertial::score::run_filter_board_noise(
                        &skeleton,
                        &tune_rec,
                        p,
                        true,
                        &tune_joints,
                        BOARD_NOISE_S,
                    )?;
                    let score =
                        r.stats.iter().map(|st| st.mean_deg).sum::<f64>() / r.stats.len() as f64;
                    drift_grid.push(json!({"sensors": r.sensors, "process_sigma": q,
                        "distance_gate_sigma": gate,
                        "accelerometer_sigma": p.accelerometer_sigma,
                        "gyroscope_sigma": p.gyroscope_sigma, "score_deg": score}));
                    if best_drift.is_none_or(|(b, _)| score < b) {
                        best_drift = Some((score, p));
                    }
                }
            }
        }
        let (score, p) = best_drift.unwrap();
        stage.println(format!(
            "tuned on the separate clip, {}: q {} σa {:.3} σg {:.4} gate {}: {score:.2}°",
            if sensors.distances { "A+G+D" } else { "A+G" },
            p.process_sigma,
            p.accelerometer_sigma,
            p.gyroscope_sigma,
            p.distance_gate_sigma
        ));
        drift_tuned.push((score, p));
    }
    let mut drift = Vec::new();
    for (source, recording) in [("simulated", &rec), ("oracle", &oracle)] {
        for &(_, p) in &drift_tuned {
            let r = dynamic_shapes::inertial::score::run_filter_board_noise(
                &skeleton,
                recording,
                p,
                true,
                &[l_shoulder],
                BOARD_NOISE_S,
            )?;
            let e = r.errors_deg[0].clone();
            let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
            let tail = |seconds: f64| {
                let n = (seconds * 140.0) as usize;
                mean(&e[e.len().saturating_sub(n)..])
            };
            let first = mean(&e[..(5 * 140).min(e.len())]);
            let settle = ((DRIFT_SETTLE_S * 140.0) as usize).min(e.len());
            let left_arm_distances: serde_json::Map<String, Value> =
                ["l_upper_arm", "l_forearm", "l_hand"]
                    .iter()
                    .filter_map(|name| {
                        let b = recording
                            .recording
                            .suit
                            .boards()
                            .iter()
                            .position(|b| b.name == *name)?;
                        let st = r.innovations[2].get(b)?;
                        Some((
                            (*name).to_string(),
                            json!({"count": st.count, "mean_normalised": st.mean_normalised(),
                                "nis": st.mean_nis()}),
                        ))
                    })
                    .collect();
            drift.push(DriftRun {
                source,
                distances: p.sensors.distances,
                first_5s_deg: first,
                last_5s_deg: tail(5.0),
                last_30s_deg: tail(30.0),
                slope_deg_per_s: fitted_slope_per_s(&e),
                max_deg: e.iter().copied().fold(0.0, f64::max),
                max_settled_deg: e[settle..].iter().copied().fold(0.0, f64::max),
                diverged_frames: r.diverged_frames,
                errors_deg: e,
                distances_used: r.distances_used,
                left_arm_distances: Value::Object(left_arm_distances),
            });
        }
    }
    for d in &drift {
        stage.println(format!(
            "{} {}: left shoulder first 5 s {:.2}°, last 30 s {:.2}°, last 5 s {:.2}°, \
             slope {:+.4}°/s, max {:.2}° ({:.2}° after {DRIFT_SETTLE_S} s), {} diverged frames",
            d.source,
            if d.distances { "A+G+D" } else { "A+G" },
            d.first_5s_deg,
            d.last_30s_deg,
            d.last_5s_deg,
            d.slope_deg_per_s,
            d.max_deg,
            d.max_settled_deg,
            d.diverged_frames
        ));
    }
    stage.finish(format!(
        "left shoulder, last 30 s: with D {:.2}°, without {:.2}° (oracle {:.2}° / {:.2}°)",
        drift[0].last_30s_deg, drift[1].last_30s_deg, drift[2].last_30s_deg, drift[3].last_30s_deg
    ));

    // Plots.
    let colours = [[40, 90, 200], [220, 120, 40], [40, 160, 80]];
    let mut chart = Chart::new(
        "Table 4.1 on the simulated exercise motion (root supplied: solid, free: dashed)",
        "sensor combination (1 A, 2 A+D, 3 D, 4 G, 5 G+D, 6 A+G, 7 A+G+D)",
        "mean orientation error (deg)",
    );
    for (j, label) in ["neck", "right shoulder", "left hip"].iter().enumerate() {
        for root in [true, false] {
            let pts = main_table
                .iter()
                .filter(|r| r.root_supplied == root)
                .enumerate()
                .map(|(i, r)| ((i + 1) as f64, r.stats[j].mean_deg))
                .collect();
            let style = if root {
                Style::LineMarkers
            } else {
                Style::Dashed
            };
            let l = if root {
                format!("{label}, root supplied")
            } else {
                format!("{label}, root free")
            };
            chart = chart.with(Series::new(l, colours[j], style, pts));
        }
    }
    chart.size = (900, 520);
    run.save_picture(
        "table_4_1.png",
        &chart.draw()?,
        "Mean orientation error of neck, right shoulder and left hip for every sensor combination",
    )?;
    // One point per second (the mean over its 140 frames): the trend over minutes, not the
    // gait cycle's ripple.
    let pts = |e: &[f64]| {
        e.chunks(140)
            .enumerate()
            .map(|(i, w)| (i as f64 + 0.5, w.iter().sum::<f64>() / w.len() as f64))
            .collect()
    };
    let mut chart = Chart::new(
        format!("Treadmill walk (Figure 4-7), {treadmill_s} s, MEMS gyroscope bias: left shoulder"),
        "time after the rest hold (s)",
        "orientation error, 1 s means (deg)",
    );
    chart.size = (1000, 500);
    for (d, colour) in
        drift
            .iter()
            .zip([[40, 90, 200], [220, 60, 40], [40, 160, 80], [150, 60, 170]])
    {
        let label = format!(
            "{}{}",
            if d.distances {
                "A+G+D"
            } else {
                "A+G (no distances)"
            },
            if d.source == "oracle" {
                ", oracle measurements"
            } else {
                ", simulated suit"
            }
        );
        let style = if d.source == "oracle" {
            Style::Dashed
        } else {
            Style::Line
        };
        chart = chart.with(Series::new(label, colour, style, pts(&d.errors_deg)));
    }
    run.save_picture(
        "drift.png",
        &chart.draw()?,
        "Left shoulder error (1 s means) with and without distances, simulated suit and oracle",
    )?;

    let by_board = |f: fn(&dynamic_shapes::inertial::simulate::SkinMotion) -> f64| {
        skin_motion
            .iter()
            .enumerate()
            .map(|(i, m)| (i as f64, f(m)))
            .collect::<Vec<_>>()
    };
    let mut chart = Chart::new(
        "Skin motion on the exercise motion: boards on the deforming surface vs fixed to the bone",
        "board (0 sacrum … 17 r_foot, order of the placement table)",
        "displacement from the bone-fixed placement (mm)",
    )
    .with(Series::new(
        "mean",
        [40, 90, 200],
        Style::LineMarkers,
        by_board(|m| m.mean_mm),
    ))
    .with(Series::new(
        "largest",
        [220, 60, 40],
        Style::LineMarkers,
        by_board(|m| m.max_mm),
    ));
    chart.size = (900, 480);
    run.save_picture(
        "skin_motion.png",
        &chart.draw()?,
        "Per board: how far the garment carries it away from its bone-fixed placement",
    )?;

    let agd = agd_rooted(&main_table);
    let agd_rigid = agd_rooted(&rigid_table);
    let agd_global = agd_rooted(&global_table);
    let agd_walk_bias = agd_rooted(&walk_bias_table);
    let agd_euler = agd_rooted(&euler_table);
    let nsk = skin_motion.len().max(1) as f64;
    let skin_mean_mm = skin_motion.iter().map(|m| m.mean_mm).sum::<f64>() / nsk;
    let skin_mean_deg = skin_motion.iter().map(|m| m.mean_deg).sum::<f64>() / nsk;
    let skin_max_mm = skin_motion.iter().map(|m| m.max_mm).fold(0.0, f64::max);
    let skin_max_deg = skin_motion.iter().map(|m| m.max_deg).fold(0.0, f64::max);
    let los_mean = los_errors.iter().sum::<f64>() / los_errors.len().max(1) as f64;
    let compute_s = us_s + in_s + ekf_s;
    // The same from the thread's CPU time (single-threaded pipeline): what the code costs
    // on one core, without the waits for a core on a loaded machine. Decoding is timed by
    // the wall clock only (per board and frame, microseconds; a CPU-clock read would cost
    // more than the decoding).
    let compute_cpu_s = us_cpu_s + in_s + ekf_cpu_s;
    let [broad_test, broad_gyro_only, broad_inclination, broad_heading] = real_imu::headlines();
    for h in [
        Headline::new(
            "distance_error_mean_mm",
            "distance error (LOO, static)",
            "mm",
        )
        .paper("2.35 mm, thesis §4.3.3")
        .goal(Goal::AtMost(2.5))
        .note("thesis 2.35"),
        Headline::new("distance_error_sd_mm", "distance error SD", "mm")
            .paper("1.92 mm, thesis §4.3.3")
            .goal(Goal::AtMost(2.0))
            .note("thesis 1.92"),
        Headline::new("agd_neck_deg", "A+G+D neck (root supplied)", "deg")
            .paper("5.7° (σ 2.9°), Table 4.1")
            .goal(Goal::AtMost(3.0))
            .note("thesis 5.7"),
        Headline::new("agd_shoulder_deg", "A+G+D right shoulder", "deg")
            .paper("8.0° (σ 5.0°), Table 4.1")
            .goal(Goal::AtMost(3.0))
            .note("thesis 8.0"),
        Headline::new("agd_hip_deg", "A+G+D left hip", "deg")
            .paper("6.6° (σ 3.8°), Table 4.1")
            .goal(Goal::AtMost(3.0))
            .note("thesis 6.6"),
        Headline::new(
            "skin_motion_max_mm",
            "largest board motion relative to its bone (exercise)",
            "mm",
        )
        .oracle(),
        Headline::new(
            "drift_with_d_deg",
            "treadmill left shoulder, last 30 s, A+G+D",
            "deg",
        ),
        Headline::new(
            "drift_without_d_deg",
            "treadmill left shoulder, last 30 s, A+G",
            "deg",
        )
        .baseline(),
        Headline::new(
            "drift_slope_with_d_deg_per_s",
            "treadmill left shoulder, fitted slope, A+G+D",
            "deg/s",
        )
        .goal(Goal::AtMost(0.01)),
        Headline::new(
            "drift_slope_without_d_deg_per_s",
            "treadmill left shoulder, fitted slope, A+G",
            "deg/s",
        )
        .baseline(),
        Headline::new(
            "drift_oracle_max_deg",
            "treadmill left shoulder, largest error, perfect measurements (A+G+D and A+G)",
            "deg",
        )
        .oracle()
        .goal(Goal::AtMost(1.0)),
        broad_test,
        broad_gyro_only,
        broad_inclination,
        broad_heading,
        Headline::new(
            "realtime_factor_cpu",
            "motion seconds per CPU second (thread CPU time, one core)",
            "",
        )
        .goal(Goal::AtLeast(10.0)),
        Headline::new(
            "realtime_factor",
            "motion seconds per wall-clock second (machine load included)",
            "",
        ),
    ] {
        run.headline(h);
    }
    let mut figures = json!({
        "distance_error_mean_mm": dist_mean,
        "distance_error_sd_mm": dist_sd,
        "calibration_snr_db_at_90cm": cal.snr_db_at_90cm,
        "in_motion_los_distance_error_mean_mm": los_mean,
        "agd_neck_deg": agd.stats[0].mean_deg,
        "agd_shoulder_deg": agd.stats[1].mean_deg,
        "agd_hip_deg": agd.stats[2].mean_deg,
        "drift_with_d_deg": drift[0].last_30s_deg,
        "drift_without_d_deg": drift[1].last_30s_deg,
        "drift_oracle_with_d_deg": drift[2].last_30s_deg,
        "drift_oracle_without_d_deg": drift[3].last_30s_deg,
        "treadmill": {
            "duration_s": treadmill_s,
            "twist_rate_limit_rad_per_s": TWIST_LIMIT_RAD_S,
            "max_world_speed_rad_s": {"l_upper_arm": arm_speeds[0], "r_upper_arm": arm_speeds[1],
                "l_forearm": arm_speeds[2], "r_forearm": arm_speeds[3]},
            "runs": drift.iter().map(|d| json!({"measurements": d.source, "distances": d.distances,
                "first_5s_deg": d.first_5s_deg, "last_5s_deg": d.last_5s_deg,
                "last_30s_deg": d.last_30s_deg, "slope_deg_per_s": d.slope_deg_per_s,
                "max_deg": d.max_deg, "max_settled_deg": d.max_settled_deg,
                "diverged_frames": d.diverged_frames, "distances_used": d.distances_used,
                "left_arm_distance_innovations": d.left_arm_distances})).collect::<Vec<_>>(),
        },
        "realtime_factor": motion_s / compute_s,
        "realtime_factor_ultrasound": motion_s / us_s,
        "realtime_factor_inertial_decoding": motion_s / in_s,
        "realtime_factor_ekf": motion_s / ekf_s,
        "realtime_factor_cpu": motion_s / compute_cpu_s,
        "realtime_factor_cpu_ultrasound": motion_s / us_cpu_s,
        "realtime_factor_cpu_ekf": motion_s / ekf_cpu_s,
        "motion_seconds": motion_s,
        "tuned": {"process_sigma": best.process_sigma, "accelerometer_sigma": best.accelerometer_sigma,
                  "gyroscope_sigma": best_gyro_sigma,
                  "distance_gate_sigma": best.distance_gate_sigma, "recentre_rad": best.recentre_rad,
                  "score_deg": best.score_deg},
        "paper_noise_score_deg": paper_point.map(|p| p.score_deg),
        "tuning_grid": grid.iter().map(|(g, sg)| json!({"process_sigma": g.process_sigma, "gyroscope_sigma": sg,
            "accelerometer_sigma": g.accelerometer_sigma, "distance_gate_sigma": g.distance_gate_sigma,
            "recentre_rad": g.recentre_rad, "score_deg": g.score_deg})).collect::<Vec<_>>(),
        "table_4_1": tables,
        "table_4_1_exercise_rigid_attachment": rigid_table.iter().map(run_json).collect::<Vec<_>>(),
        "table_4_1_exercise_other_chart": euler_table.iter().map(run_json).collect::<Vec<_>>(),
        "agd_other_chart_deg": joint_means(agd_euler),
        "other_chart_recentre_rad": other_chart,
        "recentre_rad": params.recentre_rad,
        "agd_rigid_attachment_deg": joint_means(agd_rigid),
        "skin_motion_exercise": skin_motion,
        "skin_motion_mean_mm": skin_mean_mm,
        "skin_motion_max_mm": skin_max_mm,
        "skin_motion_mean_deg": skin_mean_deg,
        "skin_motion_max_deg": skin_max_deg,
        "agd_beyond_4_4_4": beyond,
        "performer": "makehuman, pose-driven shapes, no flap",
        "quick": quick,
        "delta_step": sim_params.delta_step,
        "key_interval": sim_params.key_interval,
        "bit_error_rate": sim_params.bit_error_rate,
    });
    // The per-board noise of the pipeline, and the global σ
    // before it.
    if let Some(f) = figures.as_object_mut() {
        f.insert(
            "table_4_1_exercise_global_sigma".into(),
            global_table.iter().map(run_json).collect(),
        );
        f.insert("agd_global_sigma_deg".into(), joint_means(agd_global));
        f.insert("board_noise_s".into(), json!(BOARD_NOISE_S));
        // Figure 4-7 over minutes, and Table 4.1 under the other bias model.
        for (key, v) in [
            ("drift_slope_with_d_deg_per_s", drift[0].slope_deg_per_s),
            ("drift_slope_without_d_deg_per_s", drift[1].slope_deg_per_s),
            (
                "drift_oracle_slope_with_d_deg_per_s",
                drift[2].slope_deg_per_s,
            ),
            (
                "drift_oracle_slope_without_d_deg_per_s",
                drift[3].slope_deg_per_s,
            ),
            (
                "drift_oracle_max_deg",
                drift[2].max_deg.max(drift[3].max_deg),
            ),
            (
                "drift_oracle_max_settled_deg",
                drift[2].max_settled_deg.max(drift[3].max_settled_deg),
            ),
        ] {
            f.insert(key.into(), json!(v));
        }
        f.insert("gyro_bias".into(), json!(sim_params.gyro_bias));
        f.insert(
            "table_4_1_exercise_random_walk_bias".into(),
            walk_bias_table.iter().map(run_json).collect(),
        );
        f.insert(
            "agd_random_walk_bias_deg".into(),
            joint_means(agd_walk_bias),
        );
        let tuned: Vec<Value> = drift_tuned
            .iter()
            .map(|(score, p)| {
                json!({"sensors": if p.sensors.distances { "A+G+D" } else { "A+G" },
                    "process_sigma": p.process_sigma, "accelerometer_sigma": p.accelerometer_sigma,
                    "gyroscope_sigma": p.gyroscope_sigma, "distance_gate_sigma": p.distance_gate_sigma,
                    "recentre_rad": p.recentre_rad, "score_deg": score})
            })
            .collect();
        if let Some(t) = f.get_mut("treadmill").and_then(Value::as_object_mut) {
            t.insert("gyro_bias".into(), json!(sim_params.gyro_bias));
            t.insert("settle_s".into(), json!(DRIFT_SETTLE_S));
            t.insert("tuning_clip_s".into(), json!(drift_tune_s));
            t.insert("tuning_seed".into(), json!(tune_sim_params.seed));
            t.insert("tuned".into(), Value::Array(tuned));
            t.insert("tuning_grid".into(), Value::Array(drift_grid));
        }
        f.insert(
            "code_noise".into(),
            json!({"gyroscope_sigma": code_gyro, "accelerometer_sigma": code_accel}),
        );
        f.insert(
            "agd_board_sigmas".into(),
            agd.board_noise
                .iter()
                .map(|n| json!([n.gyroscope_sigma, n.accelerometer_sigma]))
                .collect(),
        );
    }
    if let (Some(f), Value::Object(r)) = (figures.as_object_mut(), real) {
        f.extend(r);
    }
    std::fs::remove_dir_all(&scratch)?;
    run.finish(figures)?;
    Ok(())
}
