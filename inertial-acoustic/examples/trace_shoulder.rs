//! Diagnosis of the right-shoulder offset (issue 15): oracle measurements from the filter's
//! own models, then the simulator's error sources added one at a time.
//!
//! `cargo run --release -p inertial-acoustic --features validation --example trace_shoulder
//! [-- SECONDS [SEED]]`
#![allow(clippy::unwrap_used, clippy::print_stdout)] // a diagnostic, not library code

use inertial_acoustic::simulate::{
    estimate_recording_board_noise, model_recording, prepare_motion, refine_recording_headings,
    run_filter, SimulatedRecording, SimulationParams, SmoothMotion, SuitSimulator,
};
use inertial_acoustic::{
    initialise, FilterParams, InnovationStats, RobustLoss, SensorSet, Suit, INNOVATION_TYPES,
};
use skin_core::skeleton::{human_skeleton, HumanParams, Skeleton};
use skin_core::studio::{exercise_motion, ExerciseParams};

fn line(label: &str, s: &Skeleton, rec: &SimulatedRecording, p: FilterParams, joints: &[usize]) {
    let r = run_filter(s, rec, p, true, joints).unwrap();
    let seg = 280;
    let segs: Vec<String> = r.errors_deg[1]
        .chunks(seg)
        .map(|c| format!("{:.1}", c.iter().sum::<f64>() / c.len() as f64))
        .collect();
    println!(
        "{label:<44} {:<6} neck {:6.2} shoulder {:6.2} hip {:6.2} (chest {:5.2} spine {:5.2}) div {} | R-shoulder per 2 s: {}",
        r.sensors,
        r.stats[0].mean_deg,
        r.stats[1].mean_deg,
        r.stats[2].mean_deg,
        r.stats[3].mean_deg,
        r.stats[4].mean_deg,
        r.diverged_frames,
        segs.join(" ")
    );
    // Consistency: per sensor type, all boards and the right upper arm (board 9).
    let mut c = String::new();
    for (t, per_board) in INNOVATION_TYPES.iter().zip(&r.innovations) {
        let all = InnovationStats::pooled(per_board);
        if all.count > 0 {
            c += &format!(
                " {t}: NIS {:.2} mean ν/√s {:+.2} (r_upper_arm NIS {:.2}, {:+.2});",
                all.mean_nis(),
                all.mean_normalised(),
                per_board[9].mean_nis(),
                per_board[9].mean_normalised()
            );
        }
    }
    println!(
        "    NEES neck/shoulder/hip {:.1}/{:.1}/{:.1};{c}",
        r.nees_mean[0], r.nees_mean[1], r.nees_mean[2]
    );
    let d = InnovationStats::pooled(&r.innovations[2]);
    println!(
        "    neck swing / twist {:.2} / {:.2}°, shoulder {:.2} / {:.2}°; distances: gate pass rate {:.3}, NIS of the passed {:.2}",
        r.swing_twist_deg[0][0],
        r.swing_twist_deg[0][1],
        r.swing_twist_deg[1][0],
        r.swing_twist_deg[1][1],
        d.pass_rate(),
        d.mean_nis_passed()
    );
}

/// The suit simulated with `sp` on `smooth` and the sensors its run uses: the source offsets
/// calibrated (§4.3.3) and every sensor when the ultrasound is on, else `no_distances`.
fn simulate(
    s: &Skeleton,
    sp: SimulationParams,
    smooth: &SmoothMotion,
    no_distances: SensorSet,
) -> (SimulatedRecording, SensorSet) {
    let sim = SuitSimulator::new(s, sp).unwrap();
    if sp.ultrasound {
        let offsets = sim.calibrate_offsets(3).unwrap().offsets;
        (sim.record(smooth, &offsets).unwrap(), SensorSet::ALL)
    } else {
        let offsets = vec![0.0; sim.nominal_suit().sources().len()];
        (sim.record(smooth, &offsets).unwrap(), no_distances)
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let seconds: f64 = args.get(1).map_or(10.0, |a| a.parse().unwrap());
    let seed: u64 = args.get(2).map_or(1, |a| a.parse().unwrap());
    let s = human_skeleton(&HumanParams::default()).unwrap();
    let joints: Vec<usize> = ["neck", "r_shoulder", "l_hip", "chest", "spine"]
        .iter()
        .map(|n| s.joint_index(n).unwrap())
        .collect();
    let motion = if args.get(3).is_some_and(|a| a == "walk") {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../data/mocap-cmu/131_01.bvh");
        let bvh = skin_core::skeleton::BvhParams::default();
        let retarget = skin_core::studio::RetargetParams::default();
        skin_core::studio::play_bvh(path, &bvh, &s, 1.0 / 120.0, &retarget)
            .unwrap()
            .motion
    } else {
        exercise_motion(
            &s,
            &ExerciseParams::default()
                .with_duration_s(seconds)
                .with_seed(seed),
        )
        .unwrap()
    };
    let base = SimulationParams::default();
    let smooth = prepare_motion(&s, &motion, &base).unwrap();
    let tuned = FilterParams::default()
        .with_process_sigma(4.0)
        .with_measurement_sigmas(2.0, 0.002, 0.0025)
        .with_distance_gate_sigma(4.0);
    let thesis = FilterParams::default();
    let sets = [
        SensorSet {
            accelerometers: false,
            distances: false,
            ..SensorSet::ALL
        },
        SensorSet {
            distances: false,
            ..SensorSet::ALL
        },
        SensorSet::ALL,
    ];
    // (a) Oracle: the filter's own h(θ_true), no noise.
    let suit = Suit::vlasic(&s).unwrap();
    let oracle = model_recording(&s, &suit, &smooth, base.rest_s).unwrap();
    {
        // How fast the true right upper arm turns (physical), and its Euler-angle rates.
        let w: Vec<f64> = oracle
            .frames
            .iter()
            .map(|f| f.inertial[9].map_or(0.0, |r| r.gyro_rad_s.length()))
            .collect();
        let sh: Vec<usize> = s.joint_dofs(s.joint_index("r_shoulder").unwrap()).collect();
        let dt = 1.0 / 140.0;
        let mut max_rate = 0.0f64;
        let mut near = 0usize;
        for k in 1..oracle.truth.len() {
            for &d in &sh {
                let r = (oracle.truth[k].theta[d] - oracle.truth[k - 1].theta[d]) / dt;
                max_rate = max_rate.max(r.abs());
            }
            near += usize::from(oracle.truth[k].theta[sh[1]].abs().to_degrees() > 75.0);
        }
        let mut sorted = w.clone();
        sorted.sort_by(f64::total_cmp);
        println!(
            "true r_upper_arm |ω|: median {:.2}, 99th percentile {:.2}, max {:.2} rad/s; \
             largest r_shoulder Euler rate {max_rate:.1} rad/s; frames with |abduction| > 75°: {near} of {}",
            sorted[sorted.len() / 2],
            sorted[sorted.len() * 99 / 100],
            sorted[sorted.len() - 1],
            oracle.truth.len()
        );
    }
    for (name, p) in [
        ("tuned q4 σa2", tuned),
        ("thesis q0.04 σa0.02", thesis),
        ("tuned, re-centred 0.3", tuned.with_recentre_rad(0.3)),
        ("q100 σa2", tuned.with_process_sigma(100.0)),
        (
            "q100 σa2, re-centred 0.3",
            tuned.with_process_sigma(100.0).with_recentre_rad(0.3),
        ),
    ] {
        for set in sets {
            line(
                &format!("oracle h(θ), {name}"),
                &s,
                &oracle,
                p.with_sensors(set),
                &joints,
            );
        }
    }
    if args.get(3).is_some_and(|a| a == "oracle") {
        return;
    }
    if args.get(3).is_some_and(|a| a == "sigmas") {
        // (c) The gyroscope σ against the simulated sensors' real resolution: four 10-bit
        // samples without dither give 10-bit steps (0.039 rad/s at ±20 rad/s, RMS 0.011).
        let sim = SuitSimulator::new(&s, SimulationParams { seed, ..base }).unwrap();
        let offsets = sim.calibrate_offsets(3).unwrap().offsets;
        let rec = sim.record(&smooth, &offsets).unwrap();
        for sg in [0.002, 0.005, 0.01, 0.02] {
            for sa in [0.3, 2.0] {
                for q in [4.0, 20.0] {
                    for rc in [0.0, 0.3] {
                        let p = tuned
                            .with_process_sigma(q)
                            .with_measurement_sigmas(sa, sg, 0.0025)
                            .with_recentre_rad(rc);
                        line(
                            &format!("σg {sg} σa {sa} q {q} recentre {rc}"),
                            &s,
                            &rec,
                            p,
                            &joints,
                        );
                    }
                }
            }
        }
        return;
    }
    // (b) The simulator with every error source off, then each one on.
    let off = SimulationParams {
        accel_noise: 0.0,
        gyro_noise: 0.0,
        accel_zero_sd: 0.0,
        gyro_zero_sd: 0.0,
        scale_sd: 0.0,
        gyro_bias_walk: 0.0,
        bit_error_rate: 0.0,
        placement_sd_m: 0.0,
        placement_sd_deg: 0.0,
        skin_slide_m_per_rad: 0.0,
        analog_noise_lsb: 0.0,
        ultrasound: false,
        seed,
        ..base
    };
    if args.get(3).is_some_and(|a| a == "budget") {
        // (f) Per-cause budget: everything on (dithered front end), then one cause off at a
        // time; the difference is what that cause costs each joint. A+G+D, root supplied,
        // the pipeline's tuned point, with and without the heading fit.
        let pipeline = tuned
            .with_measurement_sigmas(2.0, 0.01, 0.0025)
            .with_recentre_rad(0.3);
        let all = SimulationParams { seed, ..base };
        for (name, sp) in [
            ("everything", all),
            (
                "− placement 3°",
                SimulationParams {
                    placement_sd_deg: 0.0,
                    ..all
                },
            ),
            (
                "− placement 1 cm",
                SimulationParams {
                    placement_sd_m: 0.0,
                    ..all
                },
            ),
            (
                "− slide 1 cm/rad",
                SimulationParams {
                    skin_slide_m_per_rad: 0.0,
                    ..all
                },
            ),
            (
                "− zero & scale",
                SimulationParams {
                    accel_zero_sd: 0.0,
                    gyro_zero_sd: 0.0,
                    scale_sd: 0.0,
                    ..all
                },
            ),
            (
                "− gyro bias walk",
                SimulationParams {
                    gyro_bias_walk: 0.0,
                    ..all
                },
            ),
            (
                "− bit errors",
                SimulationParams {
                    bit_error_rate: 0.0,
                    ..all
                },
            ),
            (
                "− white and analog noise",
                SimulationParams {
                    accel_noise: 0.0,
                    gyro_noise: 0.0,
                    analog_noise_lsb: 0.0,
                    ..all
                },
            ),
            (
                "− dither (the earlier front end)",
                SimulationParams {
                    analog_noise_lsb: 0.0,
                    ..all
                },
            ),
            ("only quantisation + code (all off)", off),
        ] {
            let (rec, set) = simulate(&s, sp, &smooth, sets[1]);
            let p = pipeline.with_sensors(set);
            line(name, &s, &rec, p, &joints);
            let mut r = rec.clone();
            r.nominal_suit =
                inertial_acoustic::simulate::refine_recording_headings(&s, &rec, p, true, 6.0)
                    .unwrap()
                    .suit;
            line(&format!("{name}, heading fit"), &s, &r, p, &joints);
        }
        return;
    }
    if args.get(3).is_some_and(|a| a == "heading") {
        // (e) Per-board heading about gravity, estimated from a first filter pass over the
        // first seconds of motion (beyond §4.4.4), against §4.4.4 alone.
        let pipeline = tuned
            .with_measurement_sigmas(2.0, 0.01, 0.0025)
            .with_recentre_rad(0.3);
        for (name, sp) in [
            (
                "+ placement 3° (dither)",
                SimulationParams {
                    placement_sd_deg: base.placement_sd_deg,
                    analog_noise_lsb: 0.5,
                    ..off
                },
            ),
            ("everything (dither)", SimulationParams { seed, ..base }),
        ] {
            let (rec, set) = simulate(&s, sp, &smooth, sets[1]);
            let p = pipeline.with_sensors(set);
            line(&format!("{name}, §4.4.4 only"), &s, &rec, p, &joints);
            let fk = s.forward_kinematics(&rec.truth[0].theta).unwrap();
            let heading_err = |suit: &Suit| -> Vec<f64> {
                suit.boards()
                    .iter()
                    .zip(rec.true_suit.boards())
                    .map(|(e, t)| {
                        let d = fk.frame_rotation(&t.frame()).unwrap()
                            * fk.frame_rotation(&e.frame()).unwrap().inverse();
                        let v = if d.w < 0.0 {
                            (-d).to_scaled_axis()
                        } else {
                            d.to_scaled_axis()
                        };
                        v.y.to_degrees()
                    })
                    .collect()
            };
            let rest: Vec<_> = rec.frames[..rec.rest_frames]
                .iter()
                .map(|f| f.inertial.clone())
                .collect();
            let init = initialise(&s, &rec.nominal_suit, &rec.truth[0].theta, &rest).unwrap();
            let fmt = |v: &[f64]| {
                v.iter()
                    .map(|x| format!("{x:+.1}"))
                    .collect::<Vec<_>>()
                    .join(" ")
            };
            let before = heading_err(&init.suit);
            println!("    heading error about up after §4.4.4: {}", fmt(&before));
            for secs in [3.0, 6.0] {
                let mut r = rec.clone();
                for pass in 0..2 {
                    let h = inertial_acoustic::simulate::refine_recording_headings(
                        &s, &r, p, true, secs,
                    )
                    .unwrap();
                    r.nominal_suit = h.suit;
                    let after = heading_err(&r.nominal_suit);
                    println!(
                        "    {secs} s, pass {pass}: heading error {} (RMS {:.2} → {:.2}°)",
                        fmt(&after),
                        (before.iter().map(|x| x * x).sum::<f64>() / before.len() as f64).sqrt(),
                        (after.iter().map(|x| x * x).sum::<f64>() / after.len() as f64).sqrt()
                    );
                    line(
                        &format!("{name}, headings {secs} s pass {pass}"),
                        &s,
                        &r,
                        p,
                        &joints,
                    );
                }
            }
        }
        return;
    }
    if args.get(3).is_some_and(|a| a == "robust") {
        // (f) Issue 15, sixth session: per-board R from a first pass's innovations, robust
        // distance updates, the neck board's gyroscope left out.
        let pipeline = tuned
            .with_measurement_sigmas(2.0, 0.01, 0.0025)
            .with_recentre_rad(0.3);
        let (rec, set) = simulate(&s, SimulationParams { seed, ..base }, &smooth, sets[1]);
        let p = pipeline.with_sensors(set);
        let noisy = |r: &SimulatedRecording| {
            let n = estimate_recording_board_noise(&s, r, p, true, 6.0).unwrap();
            let g: Vec<String> = n
                .iter()
                .map(|b| format!("{:.3}", b.gyroscope_sigma))
                .collect();
            println!("    per-board σ_g: {}", g.join(" "));
            let mut out = r.clone();
            out.nominal_suit = out.nominal_suit.with_board_noise(n).unwrap();
            out
        };
        let per_board = noisy(&rec);
        let huber = RobustLoss::Huber { k: 1.345 };
        let cauchy = RobustLoss::Cauchy { c: 2.385 };
        line("everything, §4.4.4 only", &s, &rec, p, &joints);
        line("+ per-board R", &s, &per_board, p, &joints);
        line(
            "+ Huber 1.345",
            &s,
            &rec,
            p.with_distance_robust(huber),
            &joints,
        );
        line(
            "+ Cauchy 2.385",
            &s,
            &rec,
            p.with_distance_robust(cauchy),
            &joints,
        );
        line(
            "+ Cauchy 2.385, no gate",
            &s,
            &rec,
            p.with_distance_robust(cauchy).with_distance_gate_sigma(0.0),
            &joints,
        );
        line(
            "+ per-board R + Huber",
            &s,
            &per_board,
            p.with_distance_robust(huber),
            &joints,
        );
        line(
            "+ per-board R + Cauchy",
            &s,
            &per_board,
            p.with_distance_robust(cauchy),
            &joints,
        );
        let mut headed = rec.clone();
        headed.nominal_suit = refine_recording_headings(&s, &rec, p, true, 6.0)
            .unwrap()
            .suit;
        line("+ heading fit", &s, &headed, p, &joints);
        let headed_noise = noisy(&headed);
        line("+ heading fit + per-board R", &s, &headed_noise, p, &joints);
        line(
            "+ heading fit + per-board R + Cauchy",
            &s,
            &headed_noise,
            p.with_distance_robust(cauchy),
            &joints,
        );
        let neck_board = 4;
        let mut no_neck = rec.clone();
        for f in &mut no_neck.frames[no_neck.rest_frames..] {
            f.inertial[neck_board] = None;
        }
        line(
            "neck board's readings dropped after the rest",
            &s,
            &no_neck,
            p,
            &joints,
        );
        return;
    }
    if args.get(3).is_some_and(|a| a == "frontend") {
        // (d) The front end as §4.2.3 describes it: analog noise of half a 10-bit step dithers
        // the converter, so four accumulated samples make a 12-bit quantity (issue 15, fifth
        // session). Before (no dither) → after, at the pipeline's tuned point.
        let pipeline = tuned
            .with_measurement_sigmas(2.0, 0.01, 0.0025)
            .with_recentre_rad(0.3);
        for (name, sp) in [
            ("quantisation only, no dither", off),
            (
                "quantisation only, dither ½ step",
                SimulationParams {
                    analog_noise_lsb: 0.5,
                    ..off
                },
            ),
            (
                "everything, no dither",
                SimulationParams {
                    seed,
                    analog_noise_lsb: 0.0,
                    ..base
                },
            ),
            (
                "everything, dither ½ step",
                SimulationParams { seed, ..base },
            ),
            (
                "everything but placement 3°, no dither",
                SimulationParams {
                    seed,
                    analog_noise_lsb: 0.0,
                    placement_sd_deg: 0.0,
                    ..base
                },
            ),
            (
                "everything but placement 3°, dither ½ step",
                SimulationParams {
                    seed,
                    placement_sd_deg: 0.0,
                    ..base
                },
            ),
        ] {
            let (rec, set) = simulate(&s, sp, &smooth, sets[1]);
            line(name, &s, &rec, pipeline.with_sensors(set), &joints);
            line(
                &format!("{name}, σg 0.002"),
                &s,
                &rec,
                pipeline
                    .with_measurement_sigmas(2.0, 0.002, 0.0025)
                    .with_sensors(set),
                &joints,
            );
        }
        return;
    }
    let variants: Vec<(&str, SimulationParams)> = vec![
        ("sim, all errors off", off),
        (
            "off, ranges ×4 (coarser LSB, faster slew)",
            SimulationParams {
                accel_range: 4.0 * base.accel_range,
                gyro_range: 4.0 * base.gyro_range,
                ..off
            },
        ),
        (
            "off, ranges ×¼ (finer LSB, slower slew)",
            SimulationParams {
                accel_range: 0.25 * base.accel_range,
                gyro_range: 0.25 * base.gyro_range,
                ..off
            },
        ),
        (
            "off, one 12-bit sample per count",
            SimulationParams {
                accumulate_10bit: false,
                ..off
            },
        ),
        (
            "+ white noise",
            SimulationParams {
                accel_noise: base.accel_noise,
                gyro_noise: base.gyro_noise,
                ..off
            },
        ),
        (
            "+ zero & scale (calibrated)",
            SimulationParams {
                accel_zero_sd: base.accel_zero_sd,
                gyro_zero_sd: base.gyro_zero_sd,
                scale_sd: base.scale_sd,
                ..off
            },
        ),
        (
            "+ gyro bias walk",
            SimulationParams {
                gyro_bias_walk: base.gyro_bias_walk,
                ..off
            },
        ),
        (
            "+ bit errors",
            SimulationParams {
                bit_error_rate: base.bit_error_rate,
                ..off
            },
        ),
        (
            "+ placement 1 cm",
            SimulationParams {
                placement_sd_m: base.placement_sd_m,
                ..off
            },
        ),
        (
            "+ placement 3°",
            SimulationParams {
                placement_sd_deg: base.placement_sd_deg,
                ..off
            },
        ),
        (
            "+ slide",
            SimulationParams {
                skin_slide_m_per_rad: base.skin_slide_m_per_rad,
                ..off
            },
        ),
        (
            "+ ultrasound",
            SimulationParams {
                ultrasound: true,
                ..off
            },
        ),
        (
            "everything but placement 3°",
            SimulationParams {
                seed,
                placement_sd_deg: 0.0,
                ..base
            },
        ),
        ("everything (default)", SimulationParams { seed, ..base }),
        (
            "everything, one 12-bit sample per count",
            SimulationParams {
                seed,
                accumulate_10bit: false,
                ..base
            },
        ),
    ];
    for (name, sp) in variants {
        let (rec, set) = simulate(&s, sp, &smooth, sets[1]);
        if name == "+ placement 3°" {
            // Is the board's frame right after §4.4.4? Residual misalignment per board and
            // its part about gravity at rest (which the accelerometers cannot see).
            let rest: Vec<_> = rec.frames[..rec.rest_frames]
                .iter()
                .map(|f| f.inertial.clone())
                .collect();
            let init = initialise(&s, &rec.nominal_suit, &rec.truth[0].theta, &rest).unwrap();
            let fk = s.forward_kinematics(&rec.truth[0].theta).unwrap();
            let mut out = String::new();
            for (b, (est, tru)) in init
                .suit
                .boards()
                .iter()
                .zip(rec.true_suit.boards())
                .enumerate()
            {
                let qe = fk.frame_rotation(&est.frame()).unwrap();
                let qt = fk.frame_rotation(&tru.frame()).unwrap();
                let d = qt * qe.inverse(); // world-frame error rotation
                let v = if d.w < 0.0 {
                    (-d).to_scaled_axis()
                } else {
                    d.to_scaled_axis()
                };
                let before = fk
                    .frame_rotation(&rec.nominal_suit.boards()[b].frame())
                    .unwrap();
                out += &format!(
                    " {}: {:.1}° (about up {:+.1}°, placement {:.1}°);",
                    est.name,
                    v.length().to_degrees(),
                    v.y.to_degrees(),
                    qt.angle_between(before).to_degrees()
                );
            }
            println!("    residual board misalignment after §4.4.4:{out}");
        }
        line(name, &s, &rec, tuned.with_sensors(set), &joints);
        line(
            &format!("{name}, re-centred"),
            &s,
            &rec,
            tuned.with_sensors(set).with_recentre_rad(0.3),
            &joints,
        );
    }
}
