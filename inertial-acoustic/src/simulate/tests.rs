//! Tests of the simulator's parts: the front ends, the splines, the occlusion geometry, the
//! bench calibration and the treadmill loop.

use super::motion::SmoothMotion;
use super::physics::{segment_distance, Channel};
use super::*;
use crate::ekf::InertialReading;
use crate::inertial::CHANNELS;
use crate::Error;
use nalgebra::DMatrix;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::Distribution;
use rand_distr::Normal;
use skin_core::math::DVec3;
use skin_core::skeleton::{human_skeleton, HumanParams, Motion};
use std::f64::consts::TAU;

/// §4.2.3's accumulation of four 10-bit samples gives a 12-bit quantity only with dither:
/// a constant rate 0.3 of a 10-bit step above a bin centre reads as the bin without analog
/// noise (bias 1.2 counts), and to a tenth of a count with half a step of analog noise.
#[test]
fn dither_makes_the_accumulated_counts_twelve_bit() {
    let normal = Normal::new(0.0, 1.0).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let slope = 4096.0 / 40.0; // ±20 rad/s
    let step10 = 4.0 / slope;
    let value = 0.3 * step10; // zero at 2048, a bin centre of the 10-bit converter
    let mean_error = |noise: f64, rng: &mut ChaCha8Rng| {
        let ch = Channel {
            zero: 2048.0,
            slope,
            noise,
            accumulate: true,
        };
        let n = 20_000;
        let sum: f64 = (0..n)
            .map(|_| f64::from(ch.count(value, rng, &normal)))
            .sum();
        sum / f64::from(n) - (2048.0 + slope * value)
    };
    let plain = mean_error(0.002, &mut rng);
    let dithered = mean_error(0.002f64.hypot(0.5 * step10), &mut rng);
    assert!((plain + 1.2).abs() < 0.05, "no dither: bias {plain} counts");
    assert!(dithered.abs() < 0.1, "dither: bias {dithered} counts");
}

#[test]
fn spline_reproduces_a_parabola_inside() {
    let h = 0.05;
    let y = DMatrix::from_fn(1, 41, |_, k| (k as f64 * h).powi(2));
    let s = SmoothMotion::new(h, y);
    let (mut a, mut b, mut c) = ([0.0], [0.0], [0.0]);
    s.eval(1.0, &mut a, &mut b, &mut c);
    assert!((a[0] - 1.0).abs() < 1e-4 && (b[0] - 2.0).abs() < 1e-3 && (c[0] - 2.0).abs() < 0.02);
}

#[test]
fn segment_distance_cases() {
    let d = segment_distance(
        DVec3::ZERO,
        DVec3::X,
        DVec3::new(0.5, 1.0, -1.0),
        DVec3::new(0.5, 1.0, 1.0),
    );
    assert!((d - 1.0).abs() < 1e-12);
}

#[test]
fn still_suit_reads_gravity_and_bench_calibration_is_millimetric() {
    let s = human_skeleton(&HumanParams::default()).unwrap();
    let sim = SuitSimulator::new(&s, SimulationParams::default()).unwrap();
    let cal = sim.calibrate_offsets(3).unwrap();
    let mean = cal.loo_abs_errors_m.iter().sum::<f64>() / cal.loo_abs_errors_m.len() as f64;
    assert!(mean < 0.0025, "LOO mean {mean}");
    let still = Motion::new(1.0 / 30.0, DMatrix::zeros(s.dof_count(), 10)).unwrap();
    let motion = prepare_motion(&s, &still, &SimulationParams::default()).unwrap();
    let rec = sim.record(&motion, &cal.offsets).unwrap();
    assert!(rec.pulses_heard > 0);
    // The default front end is the noise-shaped 16-count code:
    // one frame's reading is off by the difference of two round-offs, up to 16 counts per
    // axis (0.16 rad/s, 0.46 m/s²) by design, σ 16/√6 counts (`code_noise`), and the mean
    // over frames is exact to a step over their number. So a single frame is held to the
    // code's documented bound (plus 5σ of the sensor noise), and the mean over 0.5 s (70
    // frames) to the bounds the whole-count code meets per frame (0.05 rad/s, 0.3 m/s²):
    // a biased code or calibration would still fail them.
    let (sg, sa) = SimulationParams::default().code_noise().unwrap();
    let step = f64::from(SimulationParams::DEFAULT_DELTA_STEP);
    let (gyro_count, accel_count) = (40.0 / 4096.0, 6.0 * GRAVITY_M_S2 * 2.0 / 4096.0);
    assert!((sg - step / 6f64.sqrt() * gyro_count).abs() < 1e-12);
    assert!((sa - step / 6f64.sqrt() * accel_count).abs() < 1e-12);
    // With key frames each channel's two key frames of every
    // `key_interval` are flagged unsynced (extrapolated, not readings): skipped here as
    // the filter skips them, and counted.
    let window = 10..80;
    let value = |r: &InertialReading, c: usize| {
        if c < 3 {
            r.gyro_rad_s[c]
        } else {
            r.accel_m_s2[c - 3]
        }
    };
    let (mut sum, mut used) = ([0.0f64; CHANNELS], [0usize; CHANNELS]);
    for k in window.clone() {
        let r = rec.recording.frames[k].inertial[0].unwrap();
        for c in (0..CHANNELS).filter(|&c| !r.saturated[c]) {
            sum[c] += value(&r, c);
            used[c] += 1;
        }
    }
    let flagged = CHANNELS * window.len() - used.iter().sum::<usize>();
    let keys = 2 * CHANNELS * window.len() / SimulationParams::DEFAULT_KEY_INTERVAL as usize;
    assert!(
        flagged.abs_diff(keys) <= CHANNELS,
        "{flagged} flagged, {keys} key frames"
    );
    let mean: [f64; CHANNELS] = std::array::from_fn(|c| sum[c] / used[c] as f64);
    for k in window.clone() {
        let r = rec.recording.frames[k].inertial[0].unwrap();
        for c in (0..CHANNELS).filter(|&c| !r.saturated[c]) {
            let (bound, off) = if c < 3 {
                (1.05 * step * gyro_count + 0.05, value(&r, c).abs())
            } else {
                (
                    1.05 * step * accel_count + 0.3,
                    (value(&r, c) - mean[c]).abs(),
                )
            };
            assert!(off < bound, "frame {k} channel {c}: {off} ≥ {bound}");
        }
    }
    let gyro_mean = DVec3::new(mean[0], mean[1], mean[2]);
    let accel_mean = DVec3::new(mean[3], mean[4], mean[5]);
    assert!(
        (accel_mean.length() - GRAVITY_M_S2).abs() < 0.3,
        "{accel_mean}"
    );
    assert!(gyro_mean.length() < 0.05, "{gyro_mean}");

    // The whole-count code (an option, the earlier default) still reads each frame to
    // the per-frame bounds.
    let whole = SimulationParams {
        delta_step: None,
        ..SimulationParams::default()
    };
    assert_eq!(whole.code_noise().unwrap(), (0.0, 0.0));
    let sim = SuitSimulator::new(&s, whole).unwrap();
    let rec = sim.record(&motion, &cal.offsets).unwrap();
    let r = rec.recording.frames[10].inertial[0].unwrap();
    assert!(
        (r.accel_m_s2.length() - GRAVITY_M_S2).abs() < 0.3,
        "{}",
        r.accel_m_s2
    );
    assert!(r.gyro_rad_s.length() < 0.05);
}

/// The treadmill loops a matched gait cycle: on a noisy periodic "walk" (1.1 s period,
/// 4 s) its largest change of any joint rate between frames (second difference) stays
/// within 1.5× the walk's own, the held root DOFs are constant, and a walk too short for
/// a cycle is refused. The old forward–backward playback fails the first check by 20×:
/// each reversal flips the rates in one frame.
#[test]
fn treadmill_loops_a_gait_cycle_without_jumps() {
    let sk = human_skeleton(&HumanParams::default()).unwrap();
    let dt = 1.0 / 120.0;
    let n = 480;
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let noise = Normal::new(0.0, 1e-4).unwrap();
    let tx = sk.dof_index("pelvis.tx").unwrap();
    let frames = DMatrix::from_fn(sk.dof_count(), n, |d, k| {
        let t = k as f64 * dt;
        if d == tx {
            return t; // walking at 1 m/s
        }
        let phase = d as f64 * 0.7;
        0.4 * (TAU * t / 1.1 + phase).sin()
            + 0.05 * t * (d % 2) as f64 / 4.0
            + noise.sample(&mut rng)
    });
    let walk = Motion::new(dt, frames).unwrap();
    let tread = treadmill_motion(&sk, &walk, 20.0).unwrap();
    assert_eq!(tread.frame_count(), 2401);
    // Largest second difference (rate change per frame) of any joint angle.
    let max_jerk = |m: &Motion| {
        (1..m.frame_count() - 1)
            .flat_map(|k| (0..sk.dof_count()).map(move |d| (d, k)))
            .map(|(d, k)| {
                (m.frames[(d, k + 1)] - 2.0 * m.frames[(d, k)] + m.frames[(d, k - 1)]).abs()
            })
            .fold(0.0, f64::max)
    };
    let (walk_jerk, tread_jerk) = (max_jerk(&walk), max_jerk(&tread));
    assert!(
        tread_jerk < walk_jerk * 1.5,
        "treadmill rate change {tread_jerk} vs walk {walk_jerk}"
    );
    for name in ["pelvis.tx", "pelvis.tz", "pelvis.yaw"] {
        let d = sk.dof_index(name).unwrap();
        assert!((0..tread.frame_count()).all(|k| tread.frames[(d, k)] == walk.frames[(d, 0)]));
    }
    let mut standing = walk.clone();
    standing.frames.row_mut(tx).fill(0.0);
    standing
        .frames
        .row_mut(sk.dof_index("pelvis.tz").unwrap())
        .fill(0.0);
    assert!(matches!(
        treadmill_motion(&sk, &standing, 20.0),
        Err(Error::InvalidParam { name: "walk", .. })
    ));
    let short = Motion::new(dt, walk.frames.columns(0, 90).into_owned()).unwrap();
    assert!(matches!(
        treadmill_motion(&sk, &short, 20.0),
        Err(Error::InvalidParam { name: "walk", .. })
    ));
}

/// The gyroscope bias models on a still suit (no ultrasound). Both models share every random
/// stream but the MEMS constants': with every bias figure zero they record the same. A turn-on
/// offset alone is constant (the rest pose removes it); a warm-up moves the bias after the rest
/// pose by far more than the rest window's noise; bad figures are refused.
#[test]
fn gyro_bias_models_turn_on_warm_up_and_bad_figures() {
    let s = human_skeleton(&HumanParams::default()).unwrap();
    let still = Motion::new(1.0 / 30.0, DMatrix::zeros(s.dof_count(), 300)).unwrap();
    let base = SimulationParams::default().with_ultrasound(false);
    let motion = prepare_motion(&s, &still, &base).unwrap();
    let zero = MemsGyroBias {
        turn_on_sd: 0.0,
        temp_coeff_sd: 0.0,
        instability_sd: 0.0,
        g_sensitivity_sd: 0.0,
        ..MemsGyroBias::adxrs300()
    };
    let record = |bias: GyroBiasModel, walk: f64| {
        let p = SimulationParams {
            gyro_bias_walk: walk,
            ..base.with_gyro_bias(bias)
        };
        let sim = SuitSimulator::new(&s, p).unwrap();
        sim.record(&motion, &[0.0; 8]).unwrap()
    };
    let a = record(GyroBiasModel::RandomWalk, 0.0);
    let b = record(GyroBiasModel::Mems(zero), 0.0005);
    assert!(
        a.recording == b.recording,
        "zero bias differs between models"
    );
    // Per board: mean gyroscope reading over the rest hold and over the last 2 s.
    let rest = a.recording.rest_frames;
    let n = a.recording.frames.len();
    let mean = |rec: &SimulatedRecording, range: std::ops::Range<usize>, board: usize| {
        let (mut sum, mut k) = (DVec3::ZERO, 0u32);
        for f in &rec.recording.frames[range] {
            if let Some(r) = f.inertial[board] {
                if !r.saturated[..3].iter().any(|&x| x) {
                    sum += r.gyro_rad_s;
                    k += 1;
                }
            }
        }
        sum / f64::from(k)
    };
    let shift = |rec: &SimulatedRecording| -> Vec<f64> {
        (0..rec.recording.suit.boards().len())
            .map(|board| (mean(rec, n - 280..n, board) - mean(rec, 0..rest, board)).length())
            .collect()
    };
    let turn_on = MemsGyroBias {
        turn_on_sd: 0.05,
        ..zero
    };
    let on = record(GyroBiasModel::Mems(turn_on), 0.0);
    let offset = mean(&on, 0..rest, 0).length();
    assert!(offset > 0.02, "no turn-on offset: {offset}");
    let none = shift(&a);
    let kept = shift(&on);
    let warm = record(
        GyroBiasModel::Mems(MemsGyroBias {
            temp_coeff_sd: 0.01,
            warm_up_k: 8.0,
            warm_up_tau_s: 2.0,
            ..zero
        }),
        0.0,
    );
    let drift = shift(&warm);
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let (none, kept, drift) = (median(none), median(kept), median(drift));
    // The rest window's noise: a few thousandths of a rad/s at most.
    assert!(
        none < 0.01 && kept < 0.01,
        "constant offsets moved: {none}, {kept}"
    );
    assert!(drift > 0.05, "warm-up drift {drift} rad/s");
    for bad in [
        MemsGyroBias {
            turn_on_sd: -1.0,
            ..zero
        },
        MemsGyroBias {
            g_sensitivity_sd: f64::NAN,
            ..zero
        },
        MemsGyroBias {
            warm_up_tau_s: 0.0,
            ..zero
        },
    ] {
        let p = base.with_gyro_bias(GyroBiasModel::Mems(bad));
        assert!(SuitSimulator::new(&s, p).is_err(), "{bad:?} accepted");
    }
    // Parameters written before the bias model existed read back as the random walk.
    let mut json = serde_json::to_value(SimulationParams::default()).unwrap();
    json.as_object_mut().unwrap().remove("gyro_bias");
    let old: SimulationParams = serde_json::from_value(json).unwrap();
    assert_eq!(old.gyro_bias, GyroBiasModel::RandomWalk);
    assert!(matches!(
        SimulationParams::default().gyro_bias,
        GyroBiasModel::Mems(_)
    ));
}
