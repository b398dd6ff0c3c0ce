//! inertial-acoustic end to end on the studio: the thesis's suit simulated down to raw
//! signals on the exercise motion, processed by the crate, scored against the true poses.
//! Accuracy is asserted with honest bounds (the figures are in docs/inertial-acoustic.md);
//! the ranking of sensor combinations is measured, and the full set must beat the
//! combinations that could have won.
#![allow(clippy::unwrap_used)] // not library code

use dynamic_shapes::core::math::DVec3;
use dynamic_shapes::core::skeleton::{human_skeleton, HumanParams, Skeleton};
use dynamic_shapes::inertial::pipeline::{self, PipelineParams};
use dynamic_shapes::inertial::score::{run_filter, run_filter_board_noise, table_4_1, FilterRun};
use dynamic_shapes::inertial::simulate::{
    model_recording, prepare_motion, SimulatedRecording, SimulationParams, SmoothMotion,
    SuitSimulator,
};
use dynamic_shapes::inertial::tuning::{estimate_board_axis_noise, estimate_board_noise};
use dynamic_shapes::inertial::{
    refine_headings, BoardNoise, Context, DistanceMeasurement, Error, FilterParams,
    FrameObservations, InertialReading, InnovationStats, Recording, RobustLoss, SensorSet,
    SkeletalEkf, Suit, INNOVATION_TYPES,
};
use dynamic_shapes_studio::{
    exercise_motion, makehuman_performer, DeformationParams, ExerciseParams,
};

/// The filter noise levels the example's tuning grid selects on its separate tuning clip
/// (process σ 20 rad/s² per frame, accelerometer σ 2 m/s², gyroscope σ 0.01 rad/s — the
/// dithered front end's 12-bit counts carry 0.0098 rad/s of noise at ±20 rad/s — distance
/// gate 4σ), for measurements without the delta code (oracle recordings) or with the
/// whole-count code, whose per-frame error is zero.
fn tuned_sensors() -> FilterParams {
    FilterParams::default()
        .with_process_sigma(20.0)
        .with_measurement_sigmas(2.0, 0.01, 0.0025)
        .with_distance_gate_sigma(4.0)
}

/// The filter noise levels for recordings of the default suit: its noise-shaped 16-count delta code
/// adds a per-frame reading error of σ 16/√6 counts (0.064 rad/s, 0.19 m/s²;
/// `SimulationParams::code_noise`), combined with the sensor σ in quadrature. The sensor part is
/// the point the example's grid picked in the full run with that code (q 20 rad/s² per frame, σ_a
/// 0.3 m/s², σ_g the thesis's 0.002 rad/s, gate 4σ): σ_g 0.0638 rad/s, σ_a 0.354 m/s².
fn tuned() -> FilterParams {
    SimulationParams::default()
        .with_code_noise(
            FilterParams::default()
                .with_process_sigma(20.0)
                .with_measurement_sigmas(0.3, 0.002, 0.0025)
                .with_distance_gate_sigma(4.0),
        )
        .unwrap()
}

fn joints(s: &Skeleton) -> Vec<usize> {
    ["neck", "r_shoulder", "l_hip"]
        .iter()
        .map(|n| s.joint_index(n).unwrap())
        .collect()
}

/// The human skeleton, default simulation parameters, the thesis's suit and `seconds` of the
/// exercise motion prepared for simulation.
fn thesis_suit_on_exercise(seconds: f64) -> (Skeleton, SimulationParams, Suit, SmoothMotion) {
    let s = human_skeleton(&HumanParams::default()).unwrap();
    let params = SimulationParams::default();
    let suit = Suit::vlasic(&s).unwrap();
    let motion = exercise_motion(&s, &ExerciseParams::default().with_duration_s(seconds)).unwrap();
    let smooth = prepare_motion(&s, &motion, &params).unwrap();
    (s, params, suit, smooth)
}

fn recording(s: &Skeleton, seconds: f64, params: SimulationParams) -> (SimulatedRecording, f64) {
    let sim = SuitSimulator::new(s, params).unwrap();
    let cal = sim.calibrate_offsets(3).unwrap();
    let loo = cal.loo_abs_errors_m.iter().sum::<f64>() / cal.loo_abs_errors_m.len() as f64;
    let motion = exercise_motion(s, &ExerciseParams::default().with_duration_s(seconds)).unwrap();
    let smooth = prepare_motion(s, &motion, &params).unwrap();
    (sim.record(&smooth, &cal.offsets).unwrap(), loo)
}

#[test]
fn exercise_motion_table_4_1_from_raw_signals() {
    let s = human_skeleton(&HumanParams::default()).unwrap();
    let (rec, loo_m) = recording(&s, 8.0, SimulationParams::default());
    // §4.3.3 distances: static calibration and in-motion line-of-sight pulses.
    assert!(loo_m < 0.0025, "leave-one-out distance error {loo_m} m");
    let los = &rec.los_distance_errors_m;
    let los_mean = los.iter().map(|e| e.abs()).sum::<f64>() / los.len() as f64;
    assert!(
        los.len() > 1000 && los_mean < 0.005,
        "{} LOS pulses, mean {los_mean}",
        los.len()
    );

    // The recording as a user's file: written, read back exactly, and the public pipeline
    // gives the same poses from the file as from memory.
    let dir = std::env::temp_dir().join(format!("ia-exercise-recording-{}", std::process::id()));
    rec.recording.write(&dir, &s).unwrap();
    let read = Recording::read(&dir, &s).unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
    assert!(
        read == rec.recording,
        "the recording file must read back exactly"
    );
    let p = PipelineParams::default().with_filter(tuned());
    let from_file = pipeline::run(&s, &read, &p).unwrap();
    assert_eq!(
        from_file.theta,
        pipeline::run(&s, &rec.recording, &p).unwrap().theta
    );
    assert_eq!(from_file.theta.len(), rec.truth.len());

    let j = joints(&s);
    let table: Vec<_> = table_4_1(&s, &rec, tuned(), &j, None)
        .unwrap()
        .into_iter()
        .filter(|r| r.root_supplied)
        .collect();
    let score = |label: &str| {
        let r = table.iter().find(|r| r.sensors == label).unwrap();
        r.stats.iter().map(|st| st.mean_deg).sum::<f64>() / 3.0
    };
    for r in &table {
        assert!(r.errors_deg.iter().flatten().all(|e| e.is_finite()));
        eprintln!(
            "{}: {:.2} ({:.2} / {:.2} / {:.2})",
            r.sensors,
            score(&r.sensors),
            r.stats[0].mean_deg,
            r.stats[1].mean_deg,
            r.stats[2].mean_deg
        );
    }
    let agd = table.iter().find(|r| r.sensors == "A+G+D").unwrap();
    let (neck, shoulder, hip) = (
        agd.stats[0].mean_deg,
        agd.stats[1].mean_deg,
        agd.stats[2].mean_deg,
    );
    eprintln!("Table 4.1 test, A+G+D with root: {neck:.2} / {shoulder:.2} / {hip:.2}°");
    assert!(
        neck < 5.0 && shoulder < 12.0 && hip < 8.0,
        "A+G+D {neck} {shoulder} {hip}"
    );
    assert_eq!(agd.diverged_frames, 0);
    // The ranking comes from the data: the full set beats accelerometers alone, distances
    // alone and their pair by far, and is within 1.5× of whichever combination is best.
    let best = table
        .iter()
        .map(|r| r.stats.iter().map(|st| st.mean_deg).sum::<f64>() / 3.0)
        .fold(f64::INFINITY, f64::min);
    for weak in ["A", "D", "A+D"] {
        assert!(score("A+G+D") * 4.0 < score(weak), "A+G+D vs {weak}");
    }
    assert!(
        score("A+G+D") <= 1.5 * best,
        "A+G+D {} best {best}",
        score("A+G+D")
    );

    // A source that is never heard (the hat's): the filter runs on the other seven.
    let mut deaf = rec.clone();
    for f in &mut deaf.recording.frames {
        f.distances.retain(|m| m.source != 7);
    }
    let r = run_filter(&s, &deaf, tuned(), true, &j).unwrap();
    assert!(r.stats.iter().all(|st| st.mean_deg < 15.0), "{:?}", r.stats);
}

/// The suit on the garment over the MakeHuman performer's skin: boards and sources move with
/// the pose-driven deformation (measured against the same suit fixed to the bones), the
/// floor echo sits under the performer's feet, and the filter still ranks as it should.
/// Oracle measurements: the filter's OWN models h(θ_true) along the true trajectory, no noise. The
/// local chart of the 3-DOF joints must track every joint to about the one-frame lag of Eq. 4.1; in
/// Euler angles throughout the right shoulder drifts with gyroscopes alone (linearisation near
/// gimbal lock) — the baseline that shows the test can fail — and the filter's innovations are
/// unbiased.
#[test]
fn oracle_measurements_are_tracked_in_the_local_chart() {
    let s = human_skeleton(&HumanParams::default()).unwrap();
    let params = SimulationParams::default();
    let suit = Suit::vlasic(&s).unwrap();
    let mut j = joints(&s);
    j.extend(["chest", "spine"].map(|n| s.joint_index(n).unwrap()));
    let p = FilterParams::default()
        .with_process_sigma(4.0)
        .with_measurement_sigmas(2.0, 0.002, 0.0025)
        .with_distance_gate_sigma(4.0);
    let gyro = SensorSet {
        accelerometers: false,
        distances: false,
        ..SensorSet::ALL
    };
    let means = |r: &FilterRun| r.stats.iter().map(|st| st.mean_deg).collect::<Vec<_>>();
    let (mut euler_shoulder, mut local_shoulder) = (0.0, 0.0);
    for seed in [1, 4] {
        let motion = exercise_motion(
            &s,
            &ExerciseParams::default()
                .with_duration_s(10.0)
                .with_seed(seed),
        )
        .unwrap();
        let smooth = prepare_motion(&s, &motion, &params).unwrap();
        let oracle = model_recording(&s, &suit, &smooth, params.rest_s).unwrap();
        let local = run_filter(&s, &oracle, p.with_recentre_rad(0.3), true, &j).unwrap();
        let local_g = run_filter(
            &s,
            &oracle,
            p.with_recentre_rad(0.3).with_sensors(gyro),
            true,
            &j,
        )
        .unwrap();
        let euler_g = run_filter(&s, &oracle, p.with_sensors(gyro), true, &j).unwrap();
        eprintln!(
            "oracle, seed {seed}: local A+G+D {:?}, local G {:?}, Euler G {:?}",
            means(&local),
            means(&local_g),
            means(&euler_g)
        );
        assert_eq!(local.diverged_frames + local_g.diverged_frames, 0);
        assert!(
            means(&local).iter().all(|&e| e < 2.0),
            "{:?}",
            means(&local)
        );
        assert!(
            means(&local_g).iter().all(|&e| e < 3.0),
            "{:?}",
            means(&local_g)
        );
        euler_shoulder += euler_g.stats[1].mean_deg;
        local_shoulder += local_g.stats[1].mean_deg;
        // Unbiased innovations for every sensor type: |mean ν/√s| small.
        for (t, per_board) in INNOVATION_TYPES.iter().zip(&local.innovations) {
            let all = InnovationStats::pooled(per_board);
            assert!(all.count > 0, "{t}");
            assert!(
                all.mean_normalised().abs() < 0.2,
                "{t}: mean ν/√s {}",
                all.mean_normalised()
            );
        }
    }
    // The Euler chart, fed the same perfect gyroscopes, drifts on the shoulder.
    assert!(
        euler_shoulder > 3.0 * local_shoulder,
        "Euler {euler_shoulder} vs local {local_shoulder} (sum over seeds)"
    );
}

#[test]
fn garment_suit_moves_with_the_skin() {
    let deformation = DeformationParams::default().with_flap(None);
    let performer =
        makehuman_performer(example_kit::data_path("makehuman").unwrap(), &deformation).unwrap();
    let s = performer.skeleton.clone();
    let params = SimulationParams::default();
    let sim = SuitSimulator::on_performer(&performer, &deformation, params).unwrap();
    assert!(sim.on_garment_surface());
    let rigid = sim.clone().with_rigid_attachment();
    assert!(!rigid.on_garment_surface());
    assert_eq!(sim.nominal_suit(), rigid.nominal_suit());
    let cal = sim.calibrate_offsets(3).unwrap();
    let motion = exercise_motion(&s, &ExerciseParams::default().with_duration_s(6.0)).unwrap();
    let smooth = prepare_motion(&s, &motion, &params).unwrap();
    let rec = sim.record(&smooth, &cal.offsets).unwrap();
    let rec_rigid = rigid.record(&smooth, &cal.offsets).unwrap();
    // Skin motion: millimetres to centimetres on the trunk, none on the rigid suit.
    let largest = rec.skin_motion.iter().map(|m| m.max_mm).fold(0.0, f64::max);
    assert!(largest > 2.0 && largest < 50.0, "{:?}", rec.skin_motion);
    let head = rec.skin_motion.iter().find(|m| m.board == "head").unwrap();
    assert!(head.max_mm < 0.01, "{head:?}");
    assert!(rec_rigid
        .skin_motion
        .iter()
        .all(|m| m.max_mm < 1e-6 && m.max_deg < 1e-4));
    // The floor echo is under the feet, not through the body: clean line-of-sight pulses.
    let los = &rec.los_distance_errors_m;
    let los_mean = los.iter().map(|e| e.abs()).sum::<f64>() / los.len() as f64;
    assert!(
        los.len() > 500 && los_mean < 0.005,
        "{} {los_mean}",
        los.len()
    );
    let j = joints(&s);
    let run = |r: &SimulatedRecording, sensors: SensorSet| {
        let f = run_filter(&s, r, tuned().with_sensors(sensors), true, &j).unwrap();
        f.stats.iter().map(|st| st.mean_deg).collect::<Vec<_>>()
    };
    let agd = run(&rec, SensorSet::ALL);
    let agd_rigid = run(&rec_rigid, SensorSet::ALL);
    let local = run_filter(&s, &rec, tuned().with_recentre_rad(0.3), true, &j).unwrap();
    assert_eq!(local.diverged_frames, 0);
    let agd_local: Vec<f64> = local.stats.iter().map(|st| st.mean_deg).collect();
    let a = run(
        &rec,
        SensorSet {
            gyroscopes: false,
            distances: false,
            ..SensorSet::ALL
        },
    );
    eprintln!(
        "A+G+D on the garment {agd:?}, re-centred {agd_local:?}, rigid {agd_rigid:?}, \
         A on the garment {a:?}"
    );
    // Per-board noise from a first pass: the neck board's skin twist is trusted less, and the neck
    // (the garment's largest error) comes down.
    let adapted = run_filter_board_noise(&s, &rec, tuned(), true, &j, 4.0).unwrap();
    eprintln!(
        "A+G+D on the garment with per-board noise {:?} (σ_g {:?})",
        adapted.stats,
        adapted
            .board_noise
            .iter()
            .map(|n| n.gyroscope_sigma)
            .collect::<Vec<_>>()
    );
    assert!(
        adapted.stats[0].mean_deg < agd[0],
        "neck with per-board noise {:.2}° vs global σ {:.2}°",
        adapted.stats[0].mean_deg,
        agd[0]
    );
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    assert!(agd.iter().chain(&agd_rigid).all(|e| e.is_finite()));
    assert!(mean(&agd) * 4.0 < mean(&a), "A+G+D {agd:?} vs A {a:?}");
    assert!(
        mean(&agd_local) * 4.0 < mean(&a),
        "re-centred {agd_local:?} vs A {a:?}"
    );
}

#[test]
fn corrupted_link_and_bad_inputs() {
    let s = human_skeleton(&HumanParams::default()).unwrap();
    // A noisy link: the code corrects single errors and flags the rest; the filter runs on.
    // The default noise-shaped code with its key frames at 50× the default bit error rate
    // (10⁻², as the whole-count code below). Without key frames a lost frame leaves the
    // decoder's reconstruction off the encoder's for good (the decoder repeats the previous
    // delta, and a noise-shaped delta differs from the next by the round-offs' second
    // difference, σ ≈ 0.7 step): the same link then loses the pose (3 s, A+G: 89 / 78 / 72°;
    // 3·10⁻³ 12 / 22 / 7°, 10⁻³ passes) — checked below as the baseline. With key frames a
    // lost channel is flagged (skipped) until its next key frame restores it (docs, "A
    // resynchronising code").
    let params = SimulationParams {
        bit_error_rate: 0.01,
        ..SimulationParams::default()
    }
    .with_ultrasound(false);
    assert!(params.key_interval > 0);
    let (rec, _) = recording(&s, 3.0, params);
    assert!(rec.inertial_frames_flagged > 0 && rec.bits_corrected > 0);
    assert!(rec.inertial_channels_unsynced > 0);
    let gyro_accel = tuned().with_sensors(SensorSet {
        distances: false,
        ..SensorSet::ALL
    });
    let r = run_filter(&s, &rec, gyro_accel, true, &joints(&s)).unwrap();
    let mean = |r: &FilterRun| r.stats.iter().map(|st| st.mean_deg).collect::<Vec<_>>();
    eprintln!(
        "10⁻², key frames every {}: A+G {:.1?}°, {} of {} channel readings unsynced",
        params.key_interval,
        mean(&r),
        rec.inertial_channels_unsynced,
        rec.inertial_channels_decoded
    );
    assert!(r.stats.iter().all(|st| st.mean_deg < 20.0), "{:?}", r.stats);
    let unkeyed = SimulationParams {
        key_interval: 0,
        ..params
    };
    let (rec, _) = recording(&s, 3.0, unkeyed);
    assert_eq!(rec.inertial_channels_unsynced, 0);
    let r = run_filter(&s, &rec, gyro_accel, true, &joints(&s)).unwrap();
    eprintln!("10⁻², no key frames: A+G {:.1?}°", mean(&r));
    assert!(r.stats.iter().any(|st| st.mean_deg > 20.0), "{:?}", r.stats);
    // The whole-count code (`delta_step: None`) on a link ten times noisier, with the sensor σ
    // alone (its per-frame error is zero between slews).
    let whole = SimulationParams {
        delta_step: None,
        bit_error_rate: 0.01,
        ..params
    };
    assert_eq!(whole.code_noise().unwrap(), (0.0, 0.0));
    let (rec, _) = recording(&s, 3.0, whole);
    assert!(rec.inertial_frames_flagged > 0 && rec.bits_corrected > 0);
    let r = run_filter(
        &s,
        &rec,
        tuned_sensors().with_sensors(gyro_accel.sensors),
        true,
        &joints(&s),
    )
    .unwrap();
    assert!(r.stats.iter().all(|st| st.mean_deg < 20.0), "{:?}", r.stats);

    // NaN readings are skipped and counted; bad indices are errors naming the sensor.
    let suit = Suit::vlasic(&s).unwrap();
    let nb = suit.boards().len();
    let mut ekf = SkeletalEkf::new(s.clone(), suit, &s.rest_pose(), tuned(), &[]).unwrap();
    let nan = InertialReading::new(DVec3::NAN, DVec3::ZERO);
    let obs = FrameObservations {
        inertial: vec![Some(nan); nb],
        distances: vec![],
    };
    let report = ekf.step(&obs, None).unwrap();
    assert_eq!(report.inertial_used, 0);
    assert!(report.inertial_skipped >= nb);
    let bad = FrameObservations {
        inertial: vec![None; nb],
        distances: vec![DistanceMeasurement {
            sensor: 99,
            source: 0,
            distance_m: 0.5,
            confidence: 1.0,
            age_s: 0.0,
        }],
    };
    let e = ekf.step(&bad, None).unwrap_err();
    assert_eq!(e.contexts(), [Context::Sensor(99)]);
    assert!(matches!(e.root(), Error::Core(_)));
    let short = FrameObservations {
        inertial: vec![None; 3],
        distances: vec![],
    };
    assert!(ekf.step(&short, None).is_err());
    // Covariance of a DOF the skeleton lacks; an oracle without a rest hold.
    assert!(ekf.theta_covariance(&[0, 999]).is_err());
    assert_eq!(ekf.theta_covariance(&[7, 8]).unwrap().len(), 4);
    let smooth = prepare_motion(
        &s,
        &exercise_motion(&s, &ExerciseParams::default().with_duration_s(1.0)).unwrap(),
        &SimulationParams::default(),
    )
    .unwrap();
    assert!(model_recording(&s, ekf.suit(), &smooth, 0.0).is_err());

    // A diverging filter (absurd readings) is reset and flagged, never a NaN pose.
    let wild = InertialReading::new(DVec3::splat(1e6), DVec3::splat(1e7));
    let obs = FrameObservations {
        inertial: vec![Some(wild); nb],
        distances: vec![],
    };
    let mut flagged = false;
    for _ in 0..5 {
        flagged |= ekf.step(&obs, None).unwrap().diverged;
        assert!(ekf.theta().iter().all(|v| v.is_finite()));
    }
    assert!(flagged);

    // A sensor on a bone the skeleton lacks.
    let small = Skeleton::new(s.joints()[..5].to_vec()).unwrap();
    assert!(matches!(
        Suit::vlasic(&small),
        Err(Error::MissingBone { .. })
    ));
}

/// The one-board filter on real data: q the suit's tuned 4 rad/s², σ_g the thesis's 0.002
/// rad/s, accelerometer σ `accel_sigma` (m/s²).
fn broad_params(accel_sigma: f64) -> FilterParams {
    FilterParams::default()
        .with_process_sigma(4.0)
        .with_measurement_sigmas(accel_sigma, 0.002, 0.0025)
}

/// The accelerometer σ grid of the example (`real_imu.rs`, `GAIN_GRID`), m/s².
const BROAD_GAIN_GRID: [f64; 14] = [
    0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0, 200.0, 500.0, 1000.0,
];

/// The accelerometer σ the BROAD tuning trial (09) selects on that grid (the example's
/// `broad_accelerometer_sigma`; the BROAD test below tunes it afresh).
const BROAD_TUNED_SIGMA: f64 = 5.0;

const GYRO_ONLY: SensorSet = SensorSet {
    accelerometers: false,
    gyroscopes: true,
    distances: false,
};

/// Real data, tuned on one trial and tested on another: the accelerometer σ is chosen on BROAD
/// trial 09 (fast rotations with breaks; first 60 s) over the example's grid by the combined
/// RMSE √(incl² + head²), and the choice is inside the grid (both ends score worse: its top,
/// σ 1000 m/s², is gyro-only to 0.001°). On trial 07 (fast rotations up to 24 rad/s; first 60
/// s) the fused filter with that σ beats the same filter with the gyroscope rows only by more
/// than 0.05° combined and in inclination — gyro-only, and gyro-only with the thesis's q = 0.04,
/// fail both bounds (the accelerometer sees 15–25° of centripetal disturbance, so it is worth
/// only about 0.1°). In heading gyro-only is the better one (by 0.001°: the accelerometer does
/// not observe heading); the tuned σ keeps ours within 0.02° of it, which the grid's σ 0.5 (0.4°
/// worse) fails.
#[test]
fn broad_gain_tuned_on_trial_09_beats_gyro_integration_on_trial_07() {
    use dynamic_shapes::inertial::imu_log::{read_broad_hdf5, run_orientation, ImuLog};
    use dynamic_shapes::inertial::{heading_inclination_rmse, HeadingInclinationRmse};
    let read = |f: &str| read_broad_hdf5(example_kit::data_path(f).unwrap()).unwrap();
    let tuning = read("imu-broad/09_undisturbed_fast_rotation_with_breaks_B_first60s.hdf5");
    let test = read("imu-broad/07_undisturbed_fast_rotation_B_first60s.hdf5");
    assert_eq!((tuning.len(), test.len()), (17_142, 17_142));
    // Sample k at k / 285.714 Hz (BROAD's timing); the movement samples data/imu-broad's
    // SOURCE.md lists.
    assert_eq!(test.time_s[17_141], 17_141.0 / (2000.0 / 7.0));
    let moving = |rec: &ImuLog| rec.movement.iter().filter(|m| **m).count();
    assert_eq!((moving(&tuning), moving(&test)), (8_382, 9_569));
    let score = |rec: &ImuLog, p: FilterParams| -> HeadingInclinationRmse {
        let run = run_orientation(rec, p, 20.0).unwrap();
        assert_eq!(run.diverged, 0);
        heading_inclination_rmse(&run.orientation, &rec.reference, &rec.movement, DVec3::Z).unwrap()
    };
    // Tuning: trial 09 only.
    let tuned: Vec<f64> = BROAD_GAIN_GRID
        .iter()
        .map(|&g| score(&tuning, broad_params(g)).combined_deg())
        .collect();
    let best = (0..tuned.len())
        .min_by(|&a, &b| tuned[a].total_cmp(&tuned[b]))
        .unwrap();
    let gain = BROAD_GAIN_GRID[best];
    // Measured on trial 09: 1.1563° at σ 5, ends 63.78° (σ 0.05) and 1.1665° (σ 1000;
    // gyro-only 1.1665°).
    assert!(
        tuned[best] < tuned[0] - 0.005 && tuned[best] < tuned[tuned.len() - 1] - 0.005,
        "σ {gain}: {tuned:?}"
    );

    // Test: trial 07.
    let ours = score(&test, broad_params(gain));
    let gyro = score(&test, broad_params(gain).with_sensors(GYRO_ONLY));
    let naive = score(
        &test,
        broad_params(gain)
            .with_sensors(GYRO_ONLY)
            .with_process_sigma(0.04),
    );
    assert!(ours.samples > 9000);
    // Measured (σ 5): ours 1.767° = 1.581° / 0.790°, gyro-only 1.862° = 1.687° / 0.789°,
    // q = 0.04 gyro-only 2.667° = 2.203° / 1.504° (combined = inclination / heading).
    let beats = |e: &HeadingInclinationRmse| {
        e.combined_deg() < gyro.combined_deg() - 0.05
            && e.inclination_deg < gyro.inclination_deg - 0.05
    };
    assert!(beats(&ours), "{ours:?} vs {gyro:?}");
    assert!(!beats(&gyro), "{gyro:?}");
    assert!(!beats(&naive), "{naive:?}");
    let heading_kept = |e: &HeadingInclinationRmse| e.heading_deg < gyro.heading_deg + 0.02;
    assert!(heading_kept(&ours), "{ours:?} vs {gyro:?}");
    let low = score(&test, broad_params(0.5));
    assert!(!heading_kept(&low), "{low:?}");
}

/// Real data: the x-io log (135 s, no reference) stays finite and stable: no divergence, unit
/// quaternions, and in the still samples the estimated gravity direction agrees with the
/// accelerometer at the end as at the start.
#[test]
fn xio_recording_stays_finite_and_stable() {
    use dynamic_shapes::inertial::imu_log::{read_xio_csv, run_orientation};
    let rec = read_xio_csv(example_kit::data_path("imu-xio/sensor_data.csv").unwrap()).unwrap();
    assert!(rec.time_s.last().unwrap() - rec.time_s[0] > 135.0);
    let run = run_orientation(&rec, broad_params(BROAD_TUNED_SIGMA), 1.0).unwrap();
    assert_eq!(run.diverged, 0);
    assert!(run
        .orientation
        .iter()
        .all(|q| q.is_finite() && (q.length() - 1.0).abs() < 1e-9));
    // Tilt error against the accelerometer where the board is still (|ω| < 0.1 rad/s and
    // |a| within 2 % of g), per 45 s third of the log.
    let g = 9.80665;
    let mut per_third = [(0.0, 0usize); 3];
    for (i, (r, q)) in rec.readings.iter().zip(&run.orientation).enumerate() {
        if r.gyro_rad_s.length() < 0.1 && (r.accel_m_s2.length() - g).abs() < 0.02 * g {
            let up = q.inverse() * DVec3::Z;
            let e = up.angle_between(r.accel_m_s2).to_degrees();
            let k = ((rec.time_s[i] - rec.time_s[0]) / 45.1) as usize;
            per_third[k.min(2)].0 += e;
            per_third[k.min(2)].1 += 1;
        }
    }
    for (sum, n) in per_third {
        assert!(n > 100, "{per_third:?}");
        // Measured (σ_a 5): 0.78°, 2.45°, 1.39° (σ_a 2: 0.77°, 2.29°, 1.16°).
        assert!(sum / (n as f64) < 3.0, "{per_third:?}");
    }
}

/// The per-board heading step beyond §4.4.4: boards turned about their rest-pose up axis by
/// known angles (what the gravity alignment cannot see) are turned back by `refine_headings`
/// from their gyroscope readings along the poses, where the baseline (§4.4.4 alone) keeps the
/// whole turn; bad input gives errors.
#[test]
fn heading_fit_recovers_turns_about_gravity() {
    let (s, params, nominal, smooth) = thesis_suit_on_exercise(6.0);
    // The rest pose is the first frame (the hold before the motion).
    let probe = model_recording(&s, &nominal, &smooth, params.rest_s).unwrap();
    let rest = probe.truth[0].theta.clone();
    let fk = s.forward_kinematics(&rest).unwrap();
    let turns: Vec<f64> = (0..nominal.boards().len())
        .map(|b| ((b % 5) as f64 - 2.0) * 2.0 + 1.0)
        .collect();
    let mut truth_suit = nominal.clone();
    for (b, psi) in turns.iter().enumerate() {
        let board = &nominal.boards()[b];
        let up = fk.frame_rotation(&board.frame()).unwrap().inverse() * DVec3::Y;
        let turn = dynamic_shapes::core::math::DQuat::from_axis_angle(up, psi.to_radians());
        truth_suit = truth_suit
            .with_board_orientation(b, board.joint_from_sensor * turn)
            .unwrap();
    }
    let rec = model_recording(&s, &truth_suit, &smooth, params.rest_s).unwrap();
    let poses: Vec<Vec<f64>> = rec.truth[rec.recording.rest_frames..]
        .iter()
        .map(|t| t.theta.clone())
        .collect();
    let readings: Vec<_> = rec.recording.frames[rec.recording.rest_frames..]
        .iter()
        .map(|f| f.inertial.clone())
        .collect();
    let offsets = vec![DVec3::ZERO; nominal.boards().len()];
    let dt = 1.0 / 140.0;
    let h = refine_headings(&s, &nominal, &rest, &poses, &readings, &offsets, dt).unwrap();
    let mut fitted = 0;
    for (b, (&got, &want)) in h.headings_deg.iter().zip(&turns).enumerate() {
        if h.frames_used[b] == 0 {
            continue;
        }
        fitted += 1;
        assert!(
            (got - want).abs() < 0.3,
            "board {b}: fitted {got:.2}°, true {want:.2}° (baseline error {want:.2}°)"
        );
    }
    eprintln!("heading fit: {fitted} boards, {:?}", h.headings_deg);
    assert!(fitted >= 12, "only {fitted} boards fitted");
    // Bad input.
    assert!(refine_headings(
        &s,
        &nominal,
        &rest,
        &poses[..2],
        &readings[..2],
        &offsets,
        dt
    )
    .is_err());
    assert!(refine_headings(&s, &nominal, &rest, &poses, &readings, &offsets, f64::NAN).is_err());
    assert!(refine_headings(&s, &nominal, &rest, &poses, &readings, &offsets[1..], dt).is_err());
    assert!(refine_headings(&s, &nominal, &rest, &poses, &readings[1..], &offsets, dt).is_err());
    let mut nan = poses.clone();
    nan[5][7] = f64::NAN;
    let e = refine_headings(&s, &nominal, &rest, &nan, &readings, &offsets, dt).unwrap_err();
    assert_eq!(e.contexts(), [Context::Frame(5)]);
}

/// Figure 4-7 on the filter's own measurement models: the 60 s treadmill (the looped CMU walk on
/// the MakeHuman skeleton, as the example runs it), left shoulder. With the exact
/// constant-acceleration time update the oracle holds its shoulder with distances and drifts
/// without them; Eq. 4.1's first-order step (the baseline) drifts even with distances. (With the
/// wrist's rest correction taken from the hand's bone the walk's hand is calm and the first-order
/// step ends at 7°, 52° with the wrist at its Euler singularity; the test asks it for more than 5°
/// and ten times the exact step's drift.)
/// The example's 60 s treadmill (the looped CMU walk) on the MakeHuman performer without the
/// hip flap, prepared for simulation with default parameters: the performer, its deformation
/// and the prepared motion.
fn treadmill_on_makehuman() -> (
    dynamic_shapes_studio::Performer,
    DeformationParams,
    SmoothMotion,
) {
    treadmill_on_makehuman_s(60.0)
}

/// [`treadmill_on_makehuman`] for `seconds` of walk.
fn treadmill_on_makehuman_s(
    seconds: f64,
) -> (
    dynamic_shapes_studio::Performer,
    DeformationParams,
    SmoothMotion,
) {
    use dynamic_shapes::core::skeleton::BvhParams;
    use dynamic_shapes::inertial::simulate::treadmill_motion;
    use dynamic_shapes_studio::{play_bvh, RetargetParams};
    let deformation = DeformationParams::default().with_flap(None);
    let performer =
        makehuman_performer(example_kit::data_path("makehuman").unwrap(), &deformation).unwrap();
    let s = &performer.skeleton;
    let walk = play_bvh(
        example_kit::data_path("mocap-cmu/131_01.bvh").unwrap(),
        &BvhParams::default(),
        s,
        1.0 / 120.0,
        &RetargetParams {
            twist_rate_limit_rad_per_s: Some(10.0),
            ..RetargetParams::default()
        },
    )
    .unwrap()
    .motion;
    let tread = treadmill_motion(s, &walk, seconds).unwrap();
    let smooth = prepare_motion(s, &tread, &SimulationParams::default()).unwrap();
    (performer, deformation, smooth)
}

/// The example's tuned point (full run): q 4, σ_a 2, σ_g 0.01, gate 4σ, local chart.
fn treadmill_tuned() -> FilterParams {
    FilterParams::default()
        .with_process_sigma(4.0)
        .with_measurement_sigmas(2.0, 0.01, 0.0025)
        .with_distance_gate_sigma(4.0)
        .with_recentre_rad(0.3)
}

/// Mean left-shoulder error over the first and the last 5 s of a filter run on `rec`.
fn treadmill_first_last(s: &Skeleton, rec: &SimulatedRecording, p: FilterParams) -> (f64, f64) {
    let l_shoulder = [s.joint_index("l_shoulder").unwrap()];
    let window = 5 * 140;
    let r = run_filter(s, rec, p, true, &l_shoulder).unwrap();
    assert_eq!(r.diverged_frames, 0, "{}", r.sensors);
    let e = &r.errors_deg[0];
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    (mean(&e[..window]), mean(&e[e.len() - window..]))
}

#[test]
fn treadmill_oracle_distances_hold_the_left_shoulder() {
    let (performer, _, smooth) = treadmill_on_makehuman();
    let s = &performer.skeleton;
    let params = SimulationParams::default();
    let suit = Suit::vlasic(s).unwrap();
    let oracle = model_recording(s, &suit, &smooth, params.rest_s).unwrap();
    let p = treadmill_tuned();
    let first_last = |p: FilterParams| treadmill_first_last(s, &oracle, p);
    let no_d = SensorSet {
        distances: false,
        ..SensorSet::ALL
    };
    let (d_first, d_last) = first_last(p);
    let (a_first, a_last) = first_last(p.with_sensors(no_d));
    let (old_first, old_last) = first_last(p.with_first_order_step(true));
    eprintln!(
        "treadmill oracle, left shoulder first → last 5 s: A+G+D {d_first:.2} → {d_last:.2}°, \
         A+G {a_first:.2} → {a_last:.2}°, A+G+D first-order step {old_first:.2} → {old_last:.2}°"
    );
    // Measured: 0.70 → 0.55°, 6.32 → 11.16°, 1.61 → 7.04° (before the wrist retarget fix:
    // 0.6 → 0.6°, 6.0 → 9.4°, 2.1 → 52.1°).
    assert!(
        d_last < 2.0 && d_last < d_first + 1.0,
        "A+G+D {d_first} → {d_last}"
    );
    assert!(a_last > a_first + 1.0, "A+G {a_first} → {a_last}: no drift");
    assert!(a_last > 4.0 * d_last, "A+G {a_last} vs A+G+D {d_last}");
    assert!(
        old_last > 5.0 && old_last > 10.0 * d_last,
        "first-order step {old_last}"
    );
}

/// Figure 4-7 on the simulated suit: the garment suit on the 60 s treadmill, simulated down to raw
/// signals, with the noise-shaped delta code of 16-count units (`SimulationParams::delta_step`;
/// §4.2.3's "compensate by overestimating in the next frame"). With distances the left shoulder
/// holds; without them it drifts. The baseline that could win is A+G on the same recording. (With
/// the whole-count code (`delta_step: None`) the walk's arm outruns the code's slew and both runs
/// are lost: docs, "The treadmill on the simulated suit".) The gyroscopes' bias is the random
/// walk from zero (`GyroBiasModel::RandomWalk`) this point was measured with: under the default
/// MEMS bias the 4σ gate lets A+G+D drift as well (9.21 → 17.43°, A+G 6.39 → 25.21°; the
/// mechanism is `treadmill_strong_bias_drifts_without_distances_only`'s).
#[test]
fn treadmill_simulated_suit_distances_hold_the_left_shoulder() {
    use dynamic_shapes::inertial::simulate::GyroBiasModel;
    let (performer, deformation, smooth) = treadmill_on_makehuman();
    let s = &performer.skeleton;
    let params = SimulationParams {
        delta_step: Some(16),
        ..SimulationParams::default().with_gyro_bias(GyroBiasModel::RandomWalk)
    };
    let sim = SuitSimulator::on_performer(&performer, &deformation, params).unwrap();
    let cal = sim.calibrate_offsets(3).unwrap();
    let rec = sim.record(&smooth, &cal.offsets).unwrap();
    let p = treadmill_tuned();
    let (d_first, d_last) = treadmill_first_last(s, &rec, p);
    let no_d = SensorSet {
        distances: false,
        ..SensorSet::ALL
    };
    let (a_first, a_last) = treadmill_first_last(s, &rec, p.with_sensors(no_d));
    eprintln!(
        "treadmill, simulated garment suit, noise-shaped code (16 counts), left shoulder \
         first → last 5 s: A+G+D {d_first:.2} → {d_last:.2}°, A+G {a_first:.2} → {a_last:.2}°"
    );
    // Measured: A+G+D 10.99 → 8.99°, A+G 10.88 → 16.23°.
    assert!(
        d_last < 10.0 && d_last < d_first + 2.0,
        "A+G+D {d_first} → {d_last}"
    );
    assert!(a_last > a_first + 3.0, "A+G {a_first} → {a_last}: no drift");
    assert!(a_last > 1.5 * d_last, "A+G {a_last} vs A+G+D {d_last}");
}

/// Per-board R from the data and robust distance updates, on the filter's own models (oracle
/// measurements) with one disturbance each that the global model cannot explain: the neck board's
/// gyroscope carries a skin twist (a 0.6 rad/s, 0.7 Hz rate about its bone axis that the bone does
/// not have), and a quarter of the distances come from a path 0.3 m longer (an echo). Baselines
/// that could have won: the global σ, and the plain update without a gate.
#[test]
fn per_board_noise_and_robust_distances_beat_the_global_model() {
    let (s, params, suit, smooth) = thesis_suit_on_exercise(6.0);
    let clean = model_recording(&s, &suit, &smooth, params.rest_s).unwrap();
    let j = joints(&s);
    let neck_board = suit.boards().iter().position(|b| b.name == "neck").unwrap();
    let filter = tuned_sensors().with_recentre_rad(0.3);
    let mean = |r: &FilterRun| r.stats.iter().map(|st| st.mean_deg).sum::<f64>() / 3.0;

    // 1. Skin twist on the neck board's gyroscope (its axes: the bone's; y along the neck).
    let mut twisted = clean.clone();
    for (k, f) in twisted
        .recording
        .frames
        .iter_mut()
        .enumerate()
        .skip(clean.recording.rest_frames)
    {
        if let Some(r) = f.inertial[neck_board].as_mut() {
            let t = k as f64 / 140.0;
            r.gyro_rad_s.y += 0.6 * (std::f64::consts::TAU * 0.7 * t).sin();
        }
    }
    let noise = estimate_board_noise(&s, &twisted.recording, filter, true, 4.0).unwrap();
    let sg: Vec<f64> = noise.iter().map(|n| n.gyroscope_sigma).collect();
    let others = sg
        .iter()
        .enumerate()
        .filter(|&(b, _)| b != neck_board)
        .map(|(_, v)| *v)
        .fold(0.0, f64::max);
    eprintln!("per-board σ_g {sg:?}");
    assert!(
        sg[neck_board] > 3.0 * others && noise.iter().all(|n| n.gyroscope_sigma >= 0.01),
        "neck σ_g {} vs the others' largest {others}",
        sg[neck_board]
    );
    let global = run_filter(&s, &twisted, filter, true, &j).unwrap();
    let mut per_board = twisted.clone();
    per_board.recording.suit = per_board.recording.suit.with_board_noise(noise).unwrap();
    let adapted = run_filter(&s, &per_board, filter, true, &j).unwrap();
    eprintln!(
        "skin twist on the neck board: global σ {:?}, per-board σ {:?}",
        global.stats, adapted.stats
    );
    assert!(
        adapted.stats[0].mean_deg < 0.7 * global.stats[0].mean_deg,
        "neck: per-board {:.2}° vs global {:.2}°",
        adapted.stats[0].mean_deg,
        global.stats[0].mean_deg
    );
    assert!(mean(&adapted) < mean(&global));
    // One σ per board axis finds the twisted axis (y) of the neck board and leaves its other two
    // near the rating; the neck still beats the global σ.
    let axis_noise = estimate_board_axis_noise(&s, &twisted.recording, filter, true, 4.0).unwrap();
    let g = axis_noise[neck_board].gyroscope_axes();
    eprintln!("neck board per-axis σ_g {g:?}");
    assert!(g[1] > 3.0 * g[0].max(g[2]), "neck board per-axis σ_g {g:?}");
    let mut per_axis = twisted.clone();
    per_axis.recording.suit = per_axis
        .recording
        .suit
        .with_board_noise(axis_noise)
        .unwrap();
    let axis_run = run_filter(&s, &per_axis, filter, true, &j).unwrap();
    eprintln!("per-axis σ {:?}", axis_run.stats);
    // Measured: neck 12.69° (global σ), 1.62° (per-board), 0.11° (per-axis): a twist about
    // one axis that no DOF can absorb is what per-axis σ is for (on the garment the neck
    // board's skin also swings, and that part the state absorbs: docs/inertial-acoustic.md,
    // "Per-axis noise").
    assert!(
        axis_run.stats[0].mean_deg < 0.7 * global.stats[0].mean_deg
            && axis_run.stats[0].mean_deg < 0.5 * adapted.stats[0].mean_deg,
        "neck: per-axis {:.2}° vs global {:.2}°, per-board {:.2}°",
        axis_run.stats[0].mean_deg,
        global.stats[0].mean_deg,
        adapted.stats[0].mean_deg
    );

    // 2. Echoes: every fourth distance 0.3 m long, no gate.
    let mut echoes = clean.clone();
    let mut n = 0usize;
    for f in &mut echoes.recording.frames {
        for d in &mut f.distances {
            n += 1;
            if n.is_multiple_of(4) {
                d.distance_m += 0.3;
            }
        }
    }
    let plain = filter.with_distance_gate_sigma(0.0);
    let cauchy = plain.with_distance_robust(RobustLoss::Cauchy { c: 2.385 });
    let r_plain = run_filter(&s, &echoes, plain, true, &j).unwrap();
    let r_cauchy = run_filter(&s, &echoes, cauchy, true, &j).unwrap();
    let d = InnovationStats::pooled(&r_cauchy.innovations[2]);
    eprintln!(
        "echoes: plain {:?}, Cauchy {:?}; distance pass rate {:.3}",
        r_plain.stats,
        r_cauchy.stats,
        d.pass_rate()
    );
    assert_eq!(d.pass_rate(), 1.0);
    assert!(
        mean(&r_cauchy) < 0.5 * mean(&r_plain),
        "Cauchy {:.2}° vs plain {:.2}°",
        mean(&r_cauchy),
        mean(&r_plain)
    );
    // Bad input: a σ per board or none, positive and finite.
    assert!(suit.clone().with_board_noise(vec![]).is_ok());
    let one = BoardNoise::new(0.01, 2.0);
    assert!(suit.clone().with_board_noise(vec![one; 3]).is_err());
    let mut bad = vec![one; suit.boards().len()];
    bad[2].gyroscope_sigma = f64::NAN;
    let e = suit.clone().with_board_noise(bad).unwrap_err();
    assert_eq!(e.contexts(), [Context::Sensor(2)]);
    let mut bad = vec![one; suit.boards().len()];
    bad[4] = one.with_axes([0.01, 0.0, 0.01], [2.0; 3]);
    let e = suit.clone().with_board_noise(bad).unwrap_err();
    assert_eq!(e.contexts(), [Context::Sensor(4)]);
    assert!(filter
        .with_distance_robust(RobustLoss::Huber { k: 0.0 })
        .validate()
        .is_err());
}

/// Figure 4-7 in a short clip: the garment suit on a 30 s treadmill walk with a strong MEMS
/// gyroscope bias (`MemsGyroBias::adxrs300` with every term ×10 and the warm-up 8× faster:
/// τ 15 s, σ 4 °/s per axis once warm), simulated to raw signals and run through the
/// pipeline (per-board noise from its first pass) at the example's frozen noise levels. The
/// criterion "the error over the last 10 s of the walk is at most 1.5× that over its first
/// 10 s" holds for A+G+D with an 8σ distance gate; A+G on the same recording fails it, and so
/// does A+G+D with the 4σ gate of Table 4.1's point: as the bias turns the arm, the
/// distances' innovations outgrow 4σ and the gate drops the very distances that would pull
/// it back.
#[test]
fn treadmill_strong_bias_drifts_without_distances_only() {
    use dynamic_shapes::inertial::simulate::{GyroBiasModel, MemsGyroBias};
    let (performer, deformation, smooth) = treadmill_on_makehuman_s(30.0);
    let s = &performer.skeleton;
    let params = SimulationParams::default().with_gyro_bias(GyroBiasModel::Mems(
        MemsGyroBias::adxrs300().scaled(10.0, 8.0),
    ));
    let sim = SuitSimulator::on_performer(&performer, &deformation, params).unwrap();
    let cal = sim.calibrate_offsets(3).unwrap();
    let rec = sim.record(&smooth, &cal.offsets).unwrap();
    let l_shoulder = [s.joint_index("l_shoulder").unwrap()];
    let window = 10 * 140;
    let first_last = |p: FilterParams| {
        let r = run_filter_board_noise(s, &rec, p, true, &l_shoulder, 6.0).unwrap();
        assert_eq!(r.diverged_frames, 0, "{}", r.sensors);
        let e = &r.errors_deg[0];
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
        (mean(&e[..window]), mean(&e[e.len() - window..]))
    };
    let p = tuned().with_recentre_rad(0.3).with_distance_gate_sigma(8.0);
    let (d_first, d_last) = first_last(p);
    let (a_first, a_last) = first_last(p.with_sensors(SensorSet {
        distances: false,
        ..SensorSet::ALL
    }));
    let (g_first, g_last) = first_last(p.with_distance_gate_sigma(4.0));
    eprintln!(
        "strong bias, 30 s treadmill, left shoulder first → last 10 s: A+G+D (8σ gate) \
         {d_first:.2} → {d_last:.2}°, A+G {a_first:.2} → {a_last:.2}°, A+G+D (4σ gate) \
         {g_first:.2} → {g_last:.2}°"
    );
    // Measured: 4.62 → 5.72°, 5.13 → 11.82°, 4.29 → 10.02°.
    let holds = |first: f64, last: f64| last <= 1.5 * first;
    assert!(holds(d_first, d_last), "A+G+D {d_first} → {d_last}");
    assert!(
        !holds(a_first, a_last),
        "A+G {a_first} → {a_last}: no drift"
    );
    assert!(a_last > 1.5 * d_last, "A+G {a_last} vs A+G+D {d_last}");
    assert!(
        !holds(g_first, g_last),
        "A+G+D with the 4σ gate {g_first} → {g_last}: no drift"
    );
}

/// The filter holds still on perfect data over minutes: the 180 s treadmill walk on the
/// filter's own measurement models (oracle), A+G+D through the pipeline at the example's frozen
/// point. Every 30 s window's mean left-shoulder error stays under 1°, and a line fitted to the
/// error over the walk is flat (under 0.01°/s). (Single frames peak higher — about 1.1° after
/// the first 10 s in the example's quick run, 3° in the blend from the rest pose — so the bound
/// is on window means.)
#[test]
fn oracle_holds_the_left_shoulder_over_three_minutes() {
    let (performer, _, smooth) = treadmill_on_makehuman_s(180.0);
    let s = &performer.skeleton;
    let suit = Suit::vlasic(s).unwrap();
    let oracle = model_recording(s, &suit, &smooth, SimulationParams::default().rest_s).unwrap();
    let l_shoulder = [s.joint_index("l_shoulder").unwrap()];
    let p = tuned().with_recentre_rad(0.3);
    let r = run_filter_board_noise(s, &oracle, p, true, &l_shoulder, 6.0).unwrap();
    assert_eq!(r.diverged_frames, 0);
    let e = &r.errors_deg[0];
    assert!(e.len() as f64 / 140.0 > 175.0, "{} frames", e.len());
    let windows: Vec<f64> = e
        .chunks(30 * 140)
        .map(|w| w.iter().sum::<f64>() / w.len() as f64)
        .collect();
    let n = e.len() as f64;
    let t_mean = (n - 1.0) / 2.0 / 140.0;
    let e_mean = e.iter().sum::<f64>() / n;
    let (sxy, sxx) = e.iter().enumerate().fold((0.0, 0.0), |(sxy, sxx), (i, v)| {
        let dt = i as f64 / 140.0 - t_mean;
        (sxy + dt * (v - e_mean), sxx + dt * dt)
    });
    let slope = sxy / sxx;
    eprintln!(
        "oracle, 180 s treadmill, A+G+D left shoulder: 30 s window means {windows:.2?}°, \
         slope {slope:+.5}°/s, largest {:.2}°",
        e.iter().copied().fold(0.0, f64::max)
    );
    assert!(windows.iter().all(|&w| w < 1.0), "{windows:?}");
    assert!(slope.abs() < 0.01, "slope {slope}°/s");
}
