//! Diagnosis of the right-shoulder offset (issue 15): oracle measurements from the filter's
//! own models, then the simulator's error sources added one at a time. `treadmill` traces the
//! oracle's left-shoulder drift on the looped walk on the MakeHuman skeleton (sixth session):
//! per 5 s window the shoulder's error, its axis in the bone frame, the world errors of the
//! upper arm and chest, the left arm boards' innovations; sensor sets, charts, Eq. 4.1's
//! first-order step against the exact transition, the gate, q, the twist limit, half speed.
//!
//! `cargo run --release -p inertial-acoustic --features validation --example trace_shoulder
//! [-- SECONDS [SEED] [walk | oracle | sigmas | sat | budget | treadmill [sensors | causes | gate | q | twist | sat | shaped | codeq | all]
//! | axes [SEEDS] | rom [base | causes | attrib | legs | knobs | cmp | restbias
//! | all]]]`
//!
//! `rom` (issue 15, ninth session): the full run's range-of-motion clip (SECONDS 0 for the
//! whole clip) on the example's garment suit at the full run's tuned point — the left hip's
//! error per second and per frame, which distances turn the still hip, one cause switched at
//! a time, and a candidate correction of each pair's distance bias from the rest hold (see
//! `rom_trace`).
//!
//! `axes` (issue 15, seventh session): the example's garment and rigid suits on the MakeHuman
//! performer, exercise clips of SECONDS for SEEDS seeds from SEED (motion and sensor noise),
//! A+G+D with the root supplied at the full run's tuned point: global σ, per-board σ, per-axis
//! σ, each with and without the heading fit and Cauchy distances.
#![allow(clippy::unwrap_used, clippy::print_stdout)] // a diagnostic, not library code

use dynamic_shapes_studio::{exercise_motion, ExerciseParams};
use inertial_acoustic::simulate::{
    estimate_recording_board_axis_noise, estimate_recording_board_noise, model_recording,
    prepare_motion, refine_recording_headings, run_filter, run_filter_board_noise, start_filter,
    treadmill_motion, SimulatedRecording, SimulationParams, SmoothMotion, SuitSimulator,
};
use inertial_acoustic::{
    initialise, FilterParams, InnovationStats, RobustLoss, SensorSet, SkeletalEkf, Suit,
    INNOVATION_TYPES,
};
use skin_core::math::{DQuat, DVec3};
use skin_core::skeleton::{human_skeleton, BvhParams, HumanParams, Motion, Skeleton};

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
    if args.get(3).is_some_and(|a| a == "axes") {
        let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../data/makehuman");
        let deformation = dynamic_shapes_studio::DeformationParams::default().with_flap(None);
        let performer = dynamic_shapes_studio::makehuman_performer(dir, &deformation).unwrap();
        let seeds: u64 = args.get(4).map_or(1, |a| a.parse().unwrap());
        axes_trace(&performer, &deformation, seconds, seed, seeds);
        return;
    }
    if args.get(3).is_some_and(|a| a == "rom") {
        // Issue 15, ninth session: the full run's range-of-motion clip and suit.
        let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../data/makehuman");
        let deformation = dynamic_shapes_studio::DeformationParams::default().with_flap(None);
        let performer = dynamic_shapes_studio::makehuman_performer(dir, &deformation).unwrap();
        let what = args.get(4).map_or("base", String::as_str);
        rom_trace(&performer, &deformation, seconds, what);
        return;
    }
    if args.get(3).is_some_and(|a| a == "treadmill") {
        // The example's skeleton: the MakeHuman performer's (its drift run's figures).
        let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../data/makehuman");
        let deformation = dynamic_shapes_studio::DeformationParams::default().with_flap(None);
        let performer = dynamic_shapes_studio::makehuman_performer(dir, &deformation).unwrap();
        let what = args.get(4).map_or("all", String::as_str);
        treadmill_trace(&performer, &deformation, seconds, what);
        return;
    }
    let motion = if args.get(3).is_some_and(|a| a == "walk") {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../data/mocap-cmu/131_01.bvh");
        let bvh = skin_core::skeleton::BvhParams::default();
        let retarget = dynamic_shapes_studio::RetargetParams::default();
        dynamic_shapes_studio::play_bvh(path, &bvh, &s, 1.0 / 120.0, &retarget)
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
    if args.get(3).is_some_and(|a| a == "sat") {
        // Issue 15, seventh session: the decoder's saturation flags on the exercise motion,
        // the flagged rows used or skipped (default), every sensor set.
        let sim = SuitSimulator::new(&s, SimulationParams { seed, ..base }).unwrap();
        let offsets = sim.calibrate_offsets(3).unwrap().offsets;
        let rec = sim.record(&smooth, &offsets).unwrap();
        let (mut flagged, mut rows) = (0usize, 0usize);
        for r in rec.frames.iter().flat_map(|f| f.inertial.iter().flatten()) {
            flagged += r.saturated.iter().filter(|&&x| x).count();
            rows += 6;
        }
        println!(
            "flagged inertial rows: {flagged} of {rows} ({:.2} %)",
            100.0 * flagged as f64 / rows.max(1) as f64
        );
        let p = tuned
            .with_measurement_sigmas(2.0, 0.01, 0.0025)
            .with_recentre_rad(0.3);
        for skip in [false, true] {
            for set in sets {
                line(
                    &format!("simulated, skip_saturated {skip}"),
                    &s,
                    &rec,
                    p.with_skip_saturated(skip).with_sensors(set),
                    &joints,
                );
            }
        }
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
        ultrasound: false,
        seed,
        ..errors_off(base)
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

/// `base` with every sensing error off (noise, zero and scale, bias walk, bit errors,
/// placement, slide, dither); the quantisation and the delta code stay.
fn errors_off(base: SimulationParams) -> SimulationParams {
    SimulationParams {
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
        ..base
    }
}

/// Per frame, the largest per-axis change of board `name`'s true angular rate (rad/s²),
/// sorted ascending.
fn angular_accelerations(rec: &SimulatedRecording, suit: &Suit, name: &str) -> Vec<f64> {
    let b = suit.boards().iter().position(|b| b.name == name).unwrap();
    let g = |f: &inertial_acoustic::FrameObservations| f.inertial[b].unwrap().gyro_rad_s;
    let mut acc: Vec<f64> = rec
        .frames
        .windows(2)
        .map(|w| {
            let d = (g(&w[1]) - g(&w[0])) * 140.0;
            d.x.abs().max(d.y.abs()).max(d.z.abs())
        })
        .collect();
    acc.sort_by(f64::total_cmp);
    acc
}

/// The suit `sim` recorded on `smooth` (offsets calibrated) and filtered with and without
/// distances.
fn suit_lines(
    label: &str,
    s: &Skeleton,
    sim: &SuitSimulator,
    smooth: &SmoothMotion,
    p: FilterParams,
) {
    let t0 = std::time::Instant::now();
    let offsets = sim.calibrate_offsets(3).unwrap().offsets;
    let rec = sim.record(smooth, &offsets).unwrap();
    let label = format!("{label} ({:.0} s)", t0.elapsed().as_secs_f64());
    let no_d = SensorSet {
        distances: false,
        ..SensorSet::ALL
    };
    for set in [SensorSet::ALL, no_d] {
        treadmill_line(&label, s, &rec, p.with_sensors(set));
    }
}

/// Median, 99th percentile and largest of ascending `v`, and how many exceed `limit`.
fn spread(v: &[f64], limit: f64) -> String {
    let over = v.iter().filter(|&&a| a > limit).count();
    format!(
        "median {:.1}, 99th percentile {:.1}, max {:.1}; {over} of {} frames above {limit}",
        v[v.len() / 2],
        v[v.len() * 99 / 100],
        v[v.len() - 1],
        v.len()
    )
}

/// Issue 15, sixth session: the oracle's left-shoulder drift on the treadmill. One filter run
/// with per-window logs: the left shoulder's mean error, the mean rotation vector of its error
/// `R_trueᵀ R_est` in the bone's own (upper-arm) frame with its angle to the humerus's long axis,
/// and the left arm boards' innovation means and distance counts.
struct Traced {
    windows: Vec<(f64, DVec3)>,
    /// Per window: mean world-orientation error (deg) of the upper arm and of the chest.
    world: Vec<(f64, f64)>,
    long_axis: DVec3,
    diverged: usize,
}

fn traced_run(
    s: &Skeleton,
    rec: &SimulatedRecording,
    p: FilterParams,
    window_s: f64,
) -> (Traced, SkeletalEkf) {
    let j = s.joint_index("l_shoulder").unwrap();
    let elbow = s.joint_index("l_elbow").unwrap();
    let (mut ekf, _) = start_filter(s, rec, p, true).unwrap();
    let chest = s.joint_index("chest").unwrap();
    // (parent → l_shoulder, world l_shoulder, world chest)
    let rots = |th: &[f64]| {
        let fk = s.forward_kinematics(th).unwrap();
        let w = fk.world_from_joint();
        let parent = s.joints()[j].parent.unwrap();
        let q = |i: usize| DQuat::from_mat3(&w[i].matrix3);
        (q(parent).inverse() * q(j), q(j), q(chest))
    };
    let (mut sum_arm, mut sum_chest) = (0.0, 0.0);
    let mut world = Vec::new();
    let per = (window_s * 140.0).round() as usize;
    let (mut sum_deg, mut sum_vec, mut n) = (0.0, DVec3::ZERO, 0usize);
    let mut windows = Vec::new();
    let mut diverged = 0;
    for (k, f) in rec.frames.iter().enumerate() {
        let r = ekf.step(f, Some(&rec.root[k])).unwrap();
        diverged += usize::from(r.diverged);
        if k < rec.rest_frames {
            continue;
        }
        let (lt, at, ct) = rots(&rec.truth[k].theta);
        let (le, ae, ce) = rots(ekf.theta());
        sum_arm += at.angle_between(ae).to_degrees();
        sum_chest += ct.angle_between(ce).to_degrees();
        let e = lt.inverse() * le;
        let e = if e.w < 0.0 { -e } else { e };
        let (axis, angle) = e.to_axis_angle();
        sum_deg += angle.to_degrees();
        sum_vec += axis * angle.to_degrees();
        n += 1;
        if n == per {
            windows.push((sum_deg / n as f64, sum_vec / n as f64));
            world.push((sum_arm / n as f64, sum_chest / n as f64));
            (sum_deg, sum_vec, n) = (0.0, DVec3::ZERO, 0);
            (sum_arm, sum_chest) = (0.0, 0.0);
        }
    }
    let long_axis = s.joints()[elbow].offset.normalize();
    (
        Traced {
            windows,
            world,
            long_axis,
            diverged,
        },
        ekf,
    )
}

fn treadmill_line(label: &str, s: &Skeleton, rec: &SimulatedRecording, p: FilterParams) -> f64 {
    let (t, ekf) = traced_run(s, rec, p, 5.0);
    let w: Vec<String> = t.windows.iter().map(|(m, _)| format!("{m:.1}")).collect();
    let last = t.windows.last().map_or(f64::NAN, |w| w.0);
    println!(
        "{label:<40} {:<6} L-shoulder per 5 s: {} | div {}",
        p.sensors.label(),
        w.join(" "),
        t.diverged
    );
    let w: Vec<String> = t
        .world
        .iter()
        .map(|(a, c)| format!("{a:.1}/{c:.1}"))
        .collect();
    println!("    world error upper arm / chest per 5 s: {}", w.join(" "));
    if let Some((_, v)) = t.windows.last() {
        let c = v
            .normalize()
            .dot(t.long_axis)
            .abs()
            .min(1.0)
            .acos()
            .to_degrees();
        println!(
            "    last-5 s mean error rotation vector (bone frame, deg) [{:+.1} {:+.1} {:+.1}], {c:.0}° from the humerus axis",
            v.x, v.y, v.z
        );
    }
    let names = ["l_upper_arm", "l_forearm", "l_hand"];
    let mut c = String::new();
    for name in names {
        let b = ekf
            .suit()
            .boards()
            .iter()
            .position(|b| b.name == name)
            .unwrap();
        c += &format!(" {name}:");
        for (t, per_board) in INNOVATION_TYPES.iter().zip(ekf.innovation_stats()) {
            let st = per_board[b];
            if st.count > 0 {
                c += &format!(
                    " {t} n {} ν/√s {:+.3} NIS {:.3};",
                    st.count,
                    st.mean_normalised(),
                    st.mean_nis()
                );
            }
        }
    }
    println!("   {c}");
    last
}

fn treadmill_trace(
    performer: &dynamic_shapes_studio::Performer,
    deformation: &dynamic_shapes_studio::DeformationParams,
    seconds: f64,
    what: &str,
) {
    let s = &performer.skeleton;
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../data/mocap-cmu/131_01.bvh");
    let walk = |limit: Option<f64>| {
        let retarget = dynamic_shapes_studio::RetargetParams {
            twist_rate_limit_rad_per_s: limit,
            ..dynamic_shapes_studio::RetargetParams::default()
        };
        dynamic_shapes_studio::play_bvh(path, &BvhParams::default(), s, 1.0 / 120.0, &retarget)
            .unwrap()
            .motion
    };
    let base = SimulationParams::default();
    let suit = Suit::vlasic(s).unwrap();
    let oracle_of = |m: &Motion| {
        let smooth = prepare_motion(s, m, &base).unwrap();
        model_recording(s, &suit, &smooth, base.rest_s).unwrap()
    };
    let tuned = FilterParams::default()
        .with_process_sigma(4.0)
        .with_measurement_sigmas(2.0, 0.01, 0.0025)
        .with_distance_gate_sigma(4.0)
        .with_recentre_rad(0.3);
    let g = SensorSet {
        accelerometers: false,
        distances: false,
        ..SensorSet::ALL
    };
    let ag = SensorSet {
        distances: false,
        ..SensorSet::ALL
    };
    let tread = treadmill_motion(s, &walk(Some(10.0)), seconds).unwrap();
    let oracle = oracle_of(&tread);
    if what == "sensors" || what == "all" {
        // Before → after: Eq. 4.1's first-order step against the exact transition.
        for first_order in [true, false] {
            let p = tuned.with_first_order_step(first_order);
            let step = if first_order {
                "θ+Δtθ̇"
            } else {
                "θ+Δtθ̇+½Δt²θ̈"
            };
            for set in [g, ag, SensorSet::ALL] {
                let label = format!("oracle, {step}, local 0.3");
                treadmill_line(&label, s, &oracle, p.with_sensors(set));
            }
            let label = format!("oracle, {step}, Euler");
            treadmill_line(&label, s, &oracle, p.with_recentre_rad(0.0));
        }
    }
    if what == "causes" || what == "all" {
        // Without the left hand's board (its gyroscope's NIS is in the hundreds).
        let b = suit
            .boards()
            .iter()
            .position(|b| b.name == "l_hand")
            .unwrap();
        let mut no_hand = oracle.clone();
        for f in no_hand.frames.iter_mut().skip(no_hand.rest_frames) {
            f.inertial[b] = None;
        }
        treadmill_line("oracle without the l_hand board", s, &no_hand, tuned);
        // The same walk at half speed (each frame twice as long).
        let slow = Motion::new(2.0 * tread.frame_time_s, tread.frames.clone()).unwrap();
        treadmill_line(
            "oracle, walk at half speed (2x longer)",
            s,
            &oracle_of(&slow),
            tuned,
        );
    }
    if what == "suit" || what == "all" {
        // The simulated suit (garment, rigid on the bones, and the bare-skeleton stand-in)
        // with and without distances: Figure 4-7 as the data give it.
        let smooth = prepare_motion(s, &tread, &base).unwrap();
        let garment = SuitSimulator::on_performer(performer, deformation, base).unwrap();
        let rigid = garment.clone().with_rigid_attachment();
        let bare = SuitSimulator::new(s, base).unwrap();
        for (name, sim) in [
            ("garment", garment),
            ("rigid", rigid),
            ("bare skeleton", bare),
        ] {
            suit_lines(&format!("simulated, {name}"), s, &sim, &smooth, tuned);
        }
    }
    if what == "sat" || what == "all" {
        // Issue 15, seventh session: the decoder's saturation flags (clipped counts, deltas at
        // the 6-bit code's extremes), the filter using flagged rows or skipping them (default).
        let smooth = prepare_motion(s, &tread, &base).unwrap();
        let garment = SuitSimulator::on_performer(performer, deformation, base).unwrap();
        let bare = SuitSimulator::new(s, base).unwrap();
        for (name, sim) in [("garment", garment), ("bare skeleton", bare)] {
            let offsets = sim.calibrate_offsets(3).unwrap().offsets;
            let rec = sim.record(&smooth, &offsets).unwrap();
            for board in ["l_upper_arm", "l_forearm", "l_hand", "r_hand"] {
                let b = suit.boards().iter().position(|b| b.name == board).unwrap();
                let (mut gyro, mut accel, mut n) = (0usize, 0usize, 0usize);
                for r in rec.frames.iter().filter_map(|f| f.inertial[b]) {
                    n += 1;
                    gyro += r.saturated[..3].iter().filter(|&&x| x).count();
                    accel += r.saturated[3..].iter().filter(|&&x| x).count();
                }
                println!(
                    "{name} {board}: flagged gyro rows {:.1} %, accel rows {:.1} % of {n} frames",
                    100.0 * gyro as f64 / (3 * n).max(1) as f64,
                    100.0 * accel as f64 / (3 * n).max(1) as f64
                );
            }
            let no_d = SensorSet {
                distances: false,
                ..SensorSet::ALL
            };
            for skip in [false, true] {
                for set in [SensorSet::ALL, no_d] {
                    treadmill_line(
                        &format!("{name}, skip_saturated {skip}"),
                        s,
                        &rec,
                        tuned.with_skip_saturated(skip).with_sensors(set),
                    );
                }
            }
        }
    }
    if what == "shaped" || what == "all" {
        // Issue 15, seventh session: the noise-shaped delta code (§4.2.3's "compensate by
        // overestimating in the next frame") with code units of 1–16 counts against the
        // whole-count code, garment suit, flagged rows skipped (the default).
        let smooth = prepare_motion(s, &tread, &base).unwrap();
        let no_d = SensorSet {
            distances: false,
            ..SensorSet::ALL
        };
        for step in [None, Some(1), Some(4), Some(8), Some(16)] {
            let sp = SimulationParams {
                delta_step: step,
                ..base
            };
            let garment = SuitSimulator::on_performer(performer, deformation, sp).unwrap();
            let offsets = garment.calibrate_offsets(3).unwrap().offsets;
            let rec = garment.record(&smooth, &offsets).unwrap();
            for set in [SensorSet::ALL, no_d] {
                treadmill_line(
                    &format!("garment, delta step {step:?}"),
                    s,
                    &rec,
                    tuned.with_sensors(set),
                );
            }
        }
    }
    if what == "codeq" || what == "all" {
        // Issue 15, eighth session: why the full run's treadmill shows no drift without
        // distances at its tuned point (q 20, σ_a 0.354, σ_g 0.0638 — the code's σ included)
        // while the test's point (q 4, σ_a 2, σ_g 0.01) drifts: the default 16-count code's
        // recording, each knob moved alone.
        let smooth = prepare_motion(s, &tread, &base).unwrap();
        let garment = SuitSimulator::on_performer(performer, deformation, base).unwrap();
        let offsets = garment.calibrate_offsets(3).unwrap().offsets;
        let rec = garment.record(&smooth, &offsets).unwrap();
        let no_d = SensorSet {
            distances: false,
            ..SensorSet::ALL
        };
        for (q, sa, sg) in [
            (4.0, 2.0, 0.01),
            (20.0, 2.0, 0.01),
            (4.0, 0.354, 0.0638),
            (4.0, 2.0, 0.0638),
            (4.0, 0.354, 0.01),
            (20.0, 0.354, 0.0638),
        ] {
            for set in [SensorSet::ALL, no_d] {
                treadmill_line(
                    &format!("garment, q {q} σa {sa} σg {sg}"),
                    s,
                    &rec,
                    tuned
                        .with_process_sigma(q)
                        .with_measurement_sigmas(sa, sg, 0.0025)
                        .with_sensors(set),
                );
            }
        }
    }
    if what == "slew" || what == "all" {
        // The true boards' angular accelerations against the 6-bit delta code's slew limit
        // (31 counts per frame: 42 rad/s² at ±20 rad/s).
        for name in ["l_upper_arm", "l_forearm", "l_hand", "r_forearm", "sternum"] {
            let acc = angular_accelerations(&oracle, &suit, name);
            println!(
                "{name}: largest per-axis angular acceleration (rad/s²): {}",
                spread(&acc, 42.0)
            );
        }
        let smooth = prepare_motion(s, &tread, &base).unwrap();
        let off = errors_off(base);
        for (name, sp) in [
            ("bare, every error off", off),
            (
                "bare, every error off, gyro ±60 rad/s",
                SimulationParams {
                    gyro_range: 60.0,
                    ..off
                },
            ),
            (
                "bare, everything on, gyro ±60 rad/s",
                SimulationParams {
                    gyro_range: 60.0,
                    ..base
                },
            ),
        ] {
            let sim = SuitSimulator::new(s, sp).unwrap();
            suit_lines(name, s, &sim, &smooth, tuned);
        }
    }
    if what == "smooth" || what == "all" {
        // More binomial smoothing passes over the treadmill (the scored truth and the suit's
        // motion alike): how fast the left hand turns, and the simulated suit's drift.
        for passes in [2usize, 8, 32] {
            let sp = SimulationParams {
                smoothing_passes: passes,
                ..base
            };
            let smooth = prepare_motion(s, &tread, &sp).unwrap();
            let oracle = model_recording(s, &suit, &smooth, sp.rest_s).unwrap();
            let acc = angular_accelerations(&oracle, &suit, "l_hand");
            println!(
                "{passes} passes: l_hand angular acceleration (rad/s²): {}",
                spread(&acc, 42.0)
            );
            treadmill_line(&format!("oracle, {passes} passes"), s, &oracle, tuned);
            let sim = SuitSimulator::new(s, sp).unwrap();
            suit_lines(
                &format!("bare suit, {passes} passes"),
                s,
                &sim,
                &smooth,
                tuned,
            );
        }
    }
    if what == "clamp" || what == "all" {
        // The walk retargeted with every DOF clamped into the performer's limits (the wrist's
        // flexion sits near ±π otherwise): the hand's rates, then the garment suit.
        let retarget = dynamic_shapes_studio::RetargetParams {
            twist_rate_limit_rad_per_s: Some(10.0),
            clamp_to_limits: true,
        };
        let clamped =
            dynamic_shapes_studio::play_bvh(path, &BvhParams::default(), s, 1.0 / 120.0, &retarget)
                .unwrap()
                .motion;
        let tread = treadmill_motion(s, &clamped, seconds).unwrap();
        let oracle = oracle_of(&tread);
        let rates = angular_accelerations(&oracle, &suit, "l_hand");
        println!(
            "clamped: l_hand angular acceleration 99th percentile {:.1}, max {:.1} rad/s²",
            rates[rates.len() * 99 / 100],
            rates[rates.len() - 1]
        );
        for set in [SensorSet::ALL, ag] {
            treadmill_line("oracle, clamped walk", s, &oracle, tuned.with_sensors(set));
        }
        let smooth = prepare_motion(s, &tread, &base).unwrap();
        let garment = SuitSimulator::on_performer(performer, deformation, base).unwrap();
        suit_lines("garment suit, clamped walk", s, &garment, &smooth, tuned);
    }
    if what == "dofs" || what == "all" {
        // The boards' largest true per-axis rates against the gyroscopes' ±20 rad/s range.
        for name in ["l_upper_arm", "l_forearm", "l_hand", "r_hand"] {
            let b = suit.boards().iter().position(|b| b.name == name).unwrap();
            let mut rates: Vec<f64> = oracle
                .frames
                .iter()
                .map(|f| f.inertial[b].unwrap().gyro_rad_s.abs().max_element())
                .collect();
            rates.sort_by(f64::total_cmp);
            println!(
                "{name}: largest per-axis rate (rad/s): {}",
                spread(&rates, 20.0)
            );
        }
        // Per left-arm DOF: the largest rate and acceleration (finite differences) in the
        // walk and in the looped treadmill, and the loop's residual.
        let w = walk(Some(10.0));
        for j in ["l_shoulder", "l_elbow", "l_wrist"] {
            for d in s.joint_dofs(s.joint_index(j).unwrap()) {
                let stat = |m: &Motion| {
                    let h = m.frame_time_s;
                    let (mut r, mut a) = (0.0f64, 0.0f64);
                    for k in 1..m.frame_count() - 1 {
                        let (p, c, n) =
                            (m.frames[(d, k - 1)], m.frames[(d, k)], m.frames[(d, k + 1)]);
                        r = r.max(((n - p) / (2.0 * h)).abs());
                        a = a.max(((n - 2.0 * c + p) / (h * h)).abs());
                    }
                    (r, a)
                };
                let (rw, aw) = stat(&w);
                let (rt, at) = stat(&tread);
                println!("{j} DOF {d}: walk max rate {rw:.1} rad/s, acc {aw:.0} rad/s²; treadmill {rt:.1}, {at:.0}");
                let jumps: Vec<String> = (1..w.frame_count())
                    .filter(|&k| (w.frames[(d, k)] - w.frames[(d, k - 1)]).abs() > 1.0)
                    .map(|k| format!("{k}: {:.2}→{:.2}", w.frames[(d, k - 1)], w.frames[(d, k)]))
                    .collect();
                if !jumps.is_empty() {
                    println!("    jumps > 1 rad in one walk frame: {}", jumps.join(", "));
                }
            }
        }
    }
    if what == "gate" || what == "all" {
        // The 4σ distance gate against none: perfect distances rejected once the arm is off.
        treadmill_line(
            "oracle, no distance gate",
            s,
            &oracle,
            tuned.with_distance_gate_sigma(0.0),
        );
    }
    if what == "q" || what == "all" {
        for q in [0.4, 40.0] {
            treadmill_line(
                &format!("oracle, q {q}"),
                s,
                &oracle,
                tuned.with_process_sigma(q),
            );
        }
    }
    if what == "twist" || what == "all" {
        for limit in [Some(5.0), None] {
            let m = treadmill_motion(s, &walk(limit), seconds).unwrap();
            treadmill_line(
                &format!("oracle, twist limit {limit:?}"),
                s,
                &oracle_of(&m),
                tuned,
            );
        }
        let w = walk(Some(10.0));
        treadmill_line("oracle, un-looped walk (8 s)", s, &oracle_of(&w), tuned);
    }
}

/// Issue 15, seventh session: per-axis σ against per-board σ (and the heading fit, Cauchy
/// distances) on the example's garment and rigid suits, several seeds; means at the end.
fn axes_trace(
    performer: &dynamic_shapes_studio::Performer,
    deformation: &dynamic_shapes_studio::DeformationParams,
    seconds: f64,
    seed0: u64,
    seeds: u64,
) {
    let s = &performer.skeleton;
    let joints: Vec<usize> = ["neck", "r_shoulder", "l_hip"]
        .iter()
        .map(|n| s.joint_index(n).unwrap())
        .collect();
    // The full run's tuned point (sixth session): q 4, σ_a 2, σ_g 0.01, gate 4σ, local chart.
    let p = FilterParams::default()
        .with_process_sigma(4.0)
        .with_measurement_sigmas(2.0, 0.01, 0.0025)
        .with_distance_gate_sigma(4.0)
        .with_recentre_rad(0.3);
    let cauchy = p.with_distance_robust(RobustLoss::Cauchy { c: 2.385 });
    let names = [
        "global σ",
        "per-board σ (headline)",
        "per-axis σ",
        "per-board σ + Cauchy",
        "per-axis σ + Cauchy",
        "heading fit",
        "heading fit + per-board σ",
        "heading fit + per-axis σ",
        "heading fit + per-board σ + Cauchy",
        "heading fit + per-axis σ + Cauchy",
        "per-board σ from the worst axis",
        "heading fit + worst-axis σ",
    ];
    // [suit][variant] → per seed (neck, shoulder, hip).
    let mut all = vec![vec![Vec::<[f64; 3]>::new(); names.len()]; 2];
    for seed in seed0..seed0 + seeds {
        let base = SimulationParams {
            seed,
            ..SimulationParams::default()
        };
        let motion = exercise_motion(
            s,
            &ExerciseParams::default()
                .with_duration_s(seconds)
                .with_seed(seed),
        )
        .unwrap();
        let smooth = prepare_motion(s, &motion, &base).unwrap();
        let garment = SuitSimulator::on_performer(performer, deformation, base).unwrap();
        let rigid = garment.clone().with_rigid_attachment();
        for (si, (suit_name, sim)) in [("garment", garment), ("rigid", rigid)]
            .into_iter()
            .enumerate()
        {
            let offsets = sim.calibrate_offsets(3).unwrap().offsets;
            let rec = sim.record(&smooth, &offsets).unwrap();
            let with = |r: &SimulatedRecording, per_axis: bool| {
                let n = if per_axis {
                    estimate_recording_board_axis_noise(s, r, p, true, 6.0).unwrap()
                } else {
                    estimate_recording_board_noise(s, r, p, true, 6.0).unwrap()
                };
                let mut out = r.clone();
                out.nominal_suit = out.nominal_suit.with_board_noise(n).unwrap();
                out
            };
            let mut headed = rec.clone();
            headed.nominal_suit = refine_recording_headings(s, &rec, p, true, 6.0)
                .unwrap()
                .suit;
            let (board, axis) = (with(&rec, false), with(&rec, true));
            let (h_board, h_axis) = (with(&headed, false), with(&headed, true));
            // Each board's σ from its worst axis (the largest per-axis σ on all three).
            let worst = |r: &SimulatedRecording| {
                let mut out = r.clone();
                out.nominal_suit = out.nominal_suit.with_worst_axis_noise().unwrap();
                out
            };
            let (worst_axis, h_worst) = (worst(&axis), worst(&h_axis));
            // Per-axis σ_g of the boards over blended skin.
            let bn = axis.nominal_suit.board_noise();
            let sig: Vec<String> = ["sacrum", "lower_back", "neck", "sternum", "upper_back"]
                .iter()
                .filter_map(|n| {
                    let b = rec
                        .nominal_suit
                        .boards()
                        .iter()
                        .position(|b| b.name == *n)?;
                    let g = bn.get(b)?.gyroscope_axes();
                    let a = bn.get(b)?.accelerometer_axes();
                    Some(format!(
                        "{n} g {:.3}/{:.3}/{:.3} (board {:.3}) a {:.2}/{:.2}/{:.2}",
                        g[0], g[1], g[2], bn[b].gyroscope_sigma, a[0], a[1], a[2]
                    ))
                })
                .collect();
            println!("seed {seed} {suit_name}: per-axis σ: {}", sig.join("; "));
            let runs: [(&SimulatedRecording, FilterParams); 12] = [
                (&rec, p),
                (&board, p),
                (&axis, p),
                (&board, cauchy),
                (&axis, cauchy),
                (&headed, p),
                (&h_board, p),
                (&h_axis, p),
                (&h_board, cauchy),
                (&h_axis, cauchy),
                (&worst_axis, p),
                (&h_worst, p),
            ];
            for (vi, (r, fp)) in runs.into_iter().enumerate() {
                let run = run_filter(s, r, fp, true, &joints).unwrap();
                let e = [
                    run.stats[0].mean_deg,
                    run.stats[1].mean_deg,
                    run.stats[2].mean_deg,
                ];
                let g = InnovationStats::pooled(&run.innovations[0]);
                println!(
                    "seed {seed} {suit_name:<8} {:<36} {:6.2} / {:6.2} / {:6.2} (mean {:5.2}) neck swing/twist {:.2}/{:.2} gyro NIS {:.2} div {}",
                    names[vi],
                    e[0],
                    e[1],
                    e[2],
                    (e[0] + e[1] + e[2]) / 3.0,
                    run.swing_twist_deg[0][0],
                    run.swing_twist_deg[0][1],
                    g.mean_nis(),
                    run.diverged_frames
                );
                all[si][vi].push(e);
            }
        }
    }
    for (si, suit_name) in ["garment", "rigid"].iter().enumerate() {
        println!("mean over {seeds} seeds, {suit_name}:");
        for (vi, name) in names.iter().enumerate() {
            let v = &all[si][vi];
            let m = |k: usize| v.iter().map(|e| e[k]).sum::<f64>() / v.len() as f64;
            println!(
                "  {name:<36} {:6.2} / {:6.2} / {:6.2} (mean {:5.2})",
                m(0),
                m(1),
                m(2),
                (m(0) + m(1) + m(2)) / 3.0
            );
        }
    }
}

/// Issue 15, ninth session: the range-of-motion hip. The full run's clip (`range_of_motion`,
/// 74.5 s; SECONDS > 0 cuts it), garment suit on the MakeHuman performer, default front end
/// (16-count noise-shaped code), A+G+D with the root supplied at the full run's tuned point
/// (q 20, σ_a 0.3 ⊕ code, σ_g 0.002 ⊕ code, gate 4σ, local chart 0.3 rad) and per-board σ
/// from a 6 s first pass — `inertial_capture`'s figure. `base`: lost frames and flagged rows
/// per board, per second the exercised DOF, the hip's true and estimated angles, its error and
/// the left thigh board's innovations (per frame in /tmp/romhip-rom.csv); `causes`: one thing
/// switched at a time; `attrib`: the oracle, exact placements and which microphones'
/// distances turn the still hip (first 16 s); `legs`: the leg microphones' distances dropped;
/// `knobs`: σ_d, Cauchy, q, the placement split, other seeds; `cmp`: the whole-count code's
/// tuned point on both codes; `restbias`: the rest hold's per-pair distance bias removed.
fn rom_trace(
    performer: &dynamic_shapes_studio::Performer,
    deformation: &dynamic_shapes_studio::DeformationParams,
    seconds: f64,
    what: &str,
) {
    use dynamic_shapes_studio::{range_of_motion, RangeOfMotionParams};
    let s = &performer.skeleton;
    let full = range_of_motion(s, &RangeOfMotionParams::default()).unwrap();
    let rom = if seconds > 0.0 {
        let n = ((seconds / full.frame_time_s) as usize + 1).min(full.frame_count());
        Motion::new(full.frame_time_s, full.frames.columns(0, n).into_owned()).unwrap()
    } else {
        full
    };
    let joints: Vec<usize> = ["neck", "r_shoulder", "l_hip"]
        .iter()
        .map(|n| s.joint_index(n).unwrap())
        .collect();
    let base = SimulationParams::default();
    let (cg, ca) = base.code_noise().unwrap();
    let tuned = FilterParams {
        process_sigma: 20.0,
        accelerometer_sigma: 0.3f64.hypot(ca),
        gyroscope_sigma: 0.002f64.hypot(cg),
        distance_gate_sigma: 4.0,
        recentre_rad: 0.3,
        ..FilterParams::default()
    };
    println!(
        "ROM {:.1} s; tuned q {} σa {:.4} σg {:.4} gate {} chart {}",
        (rom.frame_count() - 1) as f64 * rom.frame_time_s,
        tuned.process_sigma,
        tuned.accelerometer_sigma,
        tuned.gyroscope_sigma,
        tuned.distance_gate_sigma,
        tuned.recentre_rad
    );
    let record = |sp: SimulationParams, rigid: bool| -> SimulatedRecording {
        let sim = SuitSimulator::on_performer(performer, deformation, sp).unwrap();
        let sim = if rigid {
            sim.with_rigid_attachment()
        } else {
            sim
        };
        let offsets = sim.calibrate_offsets(3).unwrap().offsets;
        let smooth = prepare_motion(s, &rom, &sp).unwrap();
        sim.record(&smooth, &offsets).unwrap()
    };
    let t0 = std::time::Instant::now();
    let rec = record(base, false);
    println!(
        "recorded in {:.1} s: {} inertial frames lost (uncorrectable), {} bits corrected",
        t0.elapsed().as_secs_f64(),
        rec.inertial_frames_flagged,
        rec.bits_corrected
    );
    let names: Vec<String> = rec
        .nominal_suit
        .boards()
        .iter()
        .map(|b| b.name.clone())
        .collect();
    let thigh = names.iter().position(|n| n == "l_thigh").unwrap();
    let hip_dofs: Vec<usize> = s.joint_dofs(joints[2]).collect();
    let dof_names: Vec<String> = s.dofs().map(|d| d.name.clone()).collect();
    let root_dofs: Vec<usize> = s.joint_dofs(0).collect();
    let dt = 1.0 / 140.0;
    let t_of = |k: usize| (k as f64 - rec.rest_frames as f64) * dt;
    if what == "base" || what == "all" {
        for (b, name) in names.iter().enumerate() {
            let lost: Vec<String> = rec
                .frames
                .iter()
                .enumerate()
                .filter(|(_, f)| f.inertial[b].is_none())
                .map(|(k, _)| format!("{:.2}", t_of(k)))
                .collect();
            let (mut gyro, mut accel, mut n) = (0usize, 0usize, 0usize);
            for r in rec.frames.iter().filter_map(|f| f.inertial[b]) {
                n += 1;
                gyro += r.saturated[..3].iter().filter(|&&x| x).count();
                accel += r.saturated[3..].iter().filter(|&&x| x).count();
            }
            println!(
                "{name:<12} lost frames {} at t = [{}] s; flagged gyro rows {gyro}, accel rows {accel} of {n} frames",
                lost.len(),
                lost.join(" ")
            );
        }
        // The full run's figure, then the same stepped by hand for the per-frame trace.
        let r = run_filter_board_noise(s, &rec, tuned, true, &joints, 6.0).unwrap();
        println!(
            "run_filter_board_noise A+G+D root: neck {:.2} shoulder {:.2} hip {:.2} div {}",
            r.stats[0].mean_deg, r.stats[1].mean_deg, r.stats[2].mean_deg, r.diverged_frames
        );
        let noise = estimate_recording_board_noise(s, &rec, tuned, true, 6.0).unwrap();
        println!(
            "per-board σ (gyro, accel): l_thigh {:.4} {:.3}, sacrum {:.4} {:.3}",
            noise[thigh].gyroscope_sigma,
            noise[thigh].accelerometer_sigma,
            noise[0].gyroscope_sigma,
            noise[0].accelerometer_sigma
        );
        let mut adapted = rec.clone();
        adapted.nominal_suit = adapted.nominal_suit.with_board_noise(noise).unwrap();
        rom_stepped(
            s, &adapted, tuned, &joints, thigh, &hip_dofs, &dof_names, &root_dofs,
        );
    }
    let line = |label: &str, rec: &SimulatedRecording, p: FilterParams, per_board: bool| {
        let r = if per_board {
            run_filter_board_noise(s, rec, p, true, &joints, 6.0).unwrap()
        } else {
            run_filter(s, rec, p, true, &joints).unwrap()
        };
        let w: Vec<String> = r.errors_deg[2]
            .chunks(700)
            .map(|c| format!("{:.0}", c.iter().sum::<f64>() / c.len() as f64))
            .collect();
        println!(
            "{label:<44} {:<6} neck {:5.2} shoulder {:5.2} hip {:5.2} div {} | hip per 5 s: {}",
            r.sensors,
            r.stats[0].mean_deg,
            r.stats[1].mean_deg,
            r.stats[2].mean_deg,
            r.diverged_frames,
            w.join(" ")
        );
    };
    if what == "attrib" || what == "all" {
        // The filter's own models along the true motion (no sensing error at all), and the
        // suit without placement errors, garment and rigid.
        let smooth = prepare_motion(s, &rom, &base).unwrap();
        let oracle = model_recording(s, &rec.nominal_suit, &smooth, base.rest_s).unwrap();
        line("oracle (the filter's own models)", &oracle, tuned, false);
        line("default (the full run's figure)", &rec, tuned, true);
        let no_d = SensorSet {
            distances: false,
            ..SensorSet::ALL
        };
        line(
            "oracle (the filter's own models)",
            &oracle,
            tuned.with_sensors(no_d),
            false,
        );
        let exact = SimulationParams {
            placement_sd_m: 0.0,
            placement_sd_deg: 0.0,
            ..base
        };
        line("no placement error", &record(exact, false), tuned, true);
        line(
            "no placement error, rigid",
            &record(exact, true),
            tuned,
            true,
        );
        line(
            "every error off, rigid",
            &record(errors_off(base), true),
            tuned,
            true,
        );
        rom_attrib(s, &rec, tuned, thigh, hip_dofs[2], 16.0);
    }
    if what == "legs" || what == "all" {
        // The leg microphones' distances dropped (after the rest hold), and the hip's NEES.
        let board = |n: &str| names.iter().position(|b| b == n).unwrap();
        for drop in [
            vec!["l_thigh"],
            vec!["l_thigh", "l_shin", "l_foot"],
            vec!["l_thigh", "l_shin", "l_foot", "r_thigh", "r_shin", "r_foot"],
        ] {
            let ids: Vec<usize> = drop.iter().map(|n| board(n)).collect();
            let mut r = rec.clone();
            for f in &mut r.frames[rec.rest_frames..] {
                f.distances.retain(|d| !ids.contains(&d.sensor));
            }
            line(
                &format!("no distances at {}", drop.join(", ")),
                &r,
                tuned,
                true,
            );
        }
        // The feet hear the hat brim at rest 0.106 m long (`restbias`): those pairs dropped.
        let hat = rec
            .nominal_suit
            .sources()
            .iter()
            .position(|x| x.name == "hat_brim")
            .unwrap();
        let feet = [board("l_foot"), board("r_foot")];
        let mut r = rec.clone();
        for f in &mut r.frames {
            f.distances
                .retain(|d| !(d.source == hat && feet.contains(&d.sensor)));
        }
        line("no feet – hat_brim distances", &r, tuned, true);
        let run = run_filter_board_noise(s, &rec, tuned, true, &joints, 6.0).unwrap();
        println!(
            "NEES neck / shoulder / hip {:.1} / {:.1} / {:.1} (consistent: 2 / 3 / 3)",
            run.nees_mean[0], run.nees_mean[1], run.nees_mean[2]
        );
    }
    if what == "restbias" || what == "all" {
        // A candidate, not in the library: each microphone–source pair's distance bias
        // measured on the rest hold (median of measured − nominal suit at the known rest
        // pose, confidence ≥ 0.5) and subtracted from all its distances — the placement's
        // projection on the rest line of sight. The ROM and the full run's 30 s exercise.
        let exercise =
            exercise_motion(s, &ExerciseParams::default().with_duration_s(30.0)).unwrap();
        let ex_rec = {
            let sim = SuitSimulator::on_performer(performer, deformation, base).unwrap();
            let offsets = sim.calibrate_offsets(3).unwrap().offsets;
            let smooth = prepare_motion(s, &exercise, &base).unwrap();
            sim.record(&smooth, &offsets).unwrap()
        };
        for (name, r) in [("ROM", &rec), ("exercise 30 s", &ex_rec)] {
            line(&format!("{name}, default"), r, tuned, true);
            for limit in [f64::INFINITY, 0.04, 0.02] {
                let corrected = rest_bias_corrected(s, r, limit);
                line(
                    &format!("{name}, rest-hold pair bias ≤ {} mm removed", 1e3 * limit),
                    &corrected,
                    tuned,
                    true,
                );
            }
        }
        for seed in [2u64, 3] {
            let r = record(base.with_seed(seed), false);
            line(&format!("ROM seed {seed}, default"), &r, tuned, true);
            for limit in [0.04, 0.02] {
                let corrected = rest_bias_corrected(s, &r, limit);
                line(
                    &format!(
                        "ROM seed {seed}, rest-hold pair bias ≤ {} mm removed",
                        1e3 * limit
                    ),
                    &corrected,
                    tuned,
                    true,
                );
            }
        }
    }
    if what == "cmp" || what == "all" {
        // The whole-count code's full-run point against the default's: the code or σ_a.
        let whole = record(
            SimulationParams {
                delta_step: None,
                ..base
            },
            false,
        );
        for (label, r) in [("whole-count code", &whole), ("16-count code", &rec)] {
            for sa in [0.02, 0.02f64.hypot(ca), 2.0] {
                line(
                    &format!("{label}, q 0.04, σa {sa:.3}, σg 0.002"),
                    r,
                    tuned
                        .with_process_sigma(0.04)
                        .with_measurement_sigmas(sa, 0.002, 0.0025),
                    true,
                );
            }
        }
    }
    if what == "knobs" || what == "all" {
        // What would hold the still leg's rotation: the distances' σ (the placement error the
        // filter is not told), a robust loss, the process noise; the placement error split.
        line("default (the full run's figure)", &rec, tuned, true);
        for sd in [0.006, 0.012] {
            line(
                &format!("σ_d {} mm", 1e3 * sd),
                &rec,
                tuned.with_measurement_sigmas(tuned.accelerometer_sigma, tuned.gyroscope_sigma, sd),
                true,
            );
        }
        line(
            "Cauchy distances",
            &rec,
            tuned.with_distance_robust(RobustLoss::Cauchy { c: 2.385 }),
            true,
        );
        line("q 0.04", &rec, tuned.with_process_sigma(0.04), true);
        line("q 0.4", &rec, tuned.with_process_sigma(0.4), true);
        let whole = record(
            SimulationParams {
                delta_step: None,
                ..base
            },
            false,
        );
        let whole_point = tuned
            .with_process_sigma(0.04)
            .with_measurement_sigmas(0.02, 0.002, 0.0025);
        line(
            "whole-count code at its full-run point (q 0.04, σa 0.02, σg 0.002)",
            &whole,
            whole_point,
            true,
        );
        line(
            "16-count code at q 0.04, σa 0.02 ⊕ code, σg 0.002 ⊕ code",
            &rec,
            tuned.with_process_sigma(0.04).with_measurement_sigmas(
                0.02f64.hypot(ca),
                tuned.gyroscope_sigma,
                0.0025,
            ),
            true,
        );
        // The gyroscope trusted beyond the code's white σ (its error telescopes when
        // integrated): the sensor's σ alone, at both process noises.
        for q in [0.04, 20.0] {
            line(
                &format!("16-count code at q {q}, σa 0.02 ⊕ code, σg 0.002 (code σ not told)"),
                &rec,
                tuned.with_process_sigma(q).with_measurement_sigmas(
                    0.02f64.hypot(ca),
                    0.002,
                    0.0025,
                ),
                true,
            );
        }
        for (label, m, d) in [
            (
                "placement: position error only (1 cm)",
                base.placement_sd_m,
                0.0,
            ),
            (
                "placement: angle error only (3°)",
                0.0,
                base.placement_sd_deg,
            ),
        ] {
            let sp = SimulationParams {
                placement_sd_m: m,
                placement_sd_deg: d,
                ..base
            };
            line(label, &record(sp, false), tuned, true);
        }
        for seed in [2u64, 3] {
            line(
                &format!("simulation seed {seed}"),
                &record(base.with_seed(seed), false),
                tuned,
                true,
            );
        }
    }
    if what == "causes" || what == "all" {
        let no_d = SensorSet {
            distances: false,
            ..SensorSet::ALL
        };
        let g = SensorSet {
            accelerometers: false,
            ..no_d
        };
        line("default (the full run's figure)", &rec, tuned, true);
        line("global σ (no first pass)", &rec, tuned, false);
        for set in [g, no_d] {
            line("sensor set", &rec, tuned.with_sensors(set), true);
        }
        line("Euler chart", &rec, tuned.with_recentre_rad(0.0), true);
        line(
            "skip_saturated off",
            &rec,
            tuned.with_skip_saturated(false),
            true,
        );
        line(
            "code σ not told (σa 0.3, σg 0.002)",
            &rec,
            tuned.with_measurement_sigmas(0.3, 0.002, tuned.distance_sigma_m),
            true,
        );
        for q in [4.0, 100.0] {
            line(&format!("q {q}"), &rec, tuned.with_process_sigma(q), true);
        }
        line(
            "σa 2.01 (2 ⊕ code)",
            &rec,
            tuned.with_measurement_sigmas(2f64.hypot(ca), tuned.gyroscope_sigma, 0.0025),
            true,
        );
        line(
            "σg 0.0646 (0.01 ⊕ code)",
            &rec,
            tuned.with_measurement_sigmas(tuned.accelerometer_sigma, 0.01f64.hypot(cg), 0.0025),
            true,
        );
        // Bit errors off with the same random stream: `random_bool` draws one number per
        // bit whatever its probability, so only the flips go.
        let quiet = record(
            SimulationParams {
                bit_error_rate: 1e-12,
                ..base
            },
            false,
        );
        println!(
            "bit errors off: {} frames lost",
            quiet.inertial_frames_flagged
        );
        line("no bit errors (same noise)", &quiet, tuned, true);
        let whole = record(
            SimulationParams {
                delta_step: None,
                ..base
            },
            false,
        );
        println!(
            "whole-count code: {} frames lost",
            whole.inertial_frames_flagged
        );
        line(
            "whole-count code, filter told its σ (0)",
            &whole,
            tuned,
            true,
        );
        line(
            "whole-count code, σa 0.3 σg 0.002",
            &whole,
            tuned.with_measurement_sigmas(0.3, 0.002, 0.0025),
            true,
        );
        let rigid = record(base, true);
        line("rigid suit", &rigid, tuned, true);
    }
}

/// The filter stepped by hand over `rec` (its suit's per-board σ as given), A+G+D with the
/// root supplied: per second the exercised DOF, the hip's true and estimated angles, its
/// error, board `thigh`'s innovations, flagged rows skipped and distances used / rejected;
/// per frame in /tmp/romhip-rom.csv.
#[allow(clippy::too_many_arguments)]
fn rom_stepped(
    s: &Skeleton,
    rec: &SimulatedRecording,
    p: FilterParams,
    joints: &[usize],
    thigh: usize,
    hip_dofs: &[usize],
    dof_names: &[String],
    root_dofs: &[usize],
) {
    use inertial_acoustic::joint_orientation_errors_deg;
    let (mut ekf, _) = start_filter(s, rec, p, true).unwrap();
    let mut csv = String::from("t_s,neck_deg,shoulder_deg,hip_deg");
    for &d in hip_dofs {
        csv += &format!(",{0}_true_deg,{0}_est_deg", dof_names[d]);
    }
    csv += ",lost_any,thigh_lost\n";
    let per = 140usize;
    let mut sums = [0.0; 3];
    let mut total = [0.0; 3];
    let mut n_total = 0usize;
    let mut prev = ekf.innovation_stats().clone();
    let (mut sat, mut used, mut rejected, mut lost, mut div) = (0, 0, 0, 0, 0);
    let mut n = 0usize;
    println!(
        "t (s) | exercised DOF (|θ| max) | hip true [{}] deg | est | err neck/shoulder/hip | l_thigh NIS gyro / accel / dist (n) | sat rows, dist used/rejected, lost frames, div",
        hip_dofs.iter().map(|&d| dof_names[d].as_str()).collect::<Vec<_>>().join(" ")
    );
    let mut biggest = (0usize, 0.0f64);
    for (k, f) in rec.frames.iter().enumerate() {
        let r = ekf.step(f, Some(&rec.root[k])).unwrap();
        if k < rec.rest_frames {
            prev = ekf.innovation_stats().clone();
            continue;
        }
        let truth = &rec.truth[k].theta;
        let est = ekf.theta();
        let e = joint_orientation_errors_deg(s, est, truth, joints).unwrap();
        let t = (k - rec.rest_frames) as f64 / 140.0;
        csv += &format!("{t:.4},{:.3},{:.3},{:.3}", e[0], e[1], e[2]);
        for &d in hip_dofs {
            csv += &format!(",{:.3},{:.3}", truth[d].to_degrees(), est[d].to_degrees());
        }
        let lost_any = f.inertial.iter().filter(|x| x.is_none()).count();
        csv += &format!(",{lost_any},{}\n", u8::from(f.inertial[thigh].is_none()));
        for i in 0..3 {
            sums[i] += e[i];
            total[i] += e[i];
        }
        n_total += 1;
        sat += r.inertial_saturated;
        used += r.distances_used;
        rejected += r.distances_rejected;
        lost += lost_any;
        div += usize::from(r.diverged);
        for (d, &v) in truth.iter().enumerate() {
            if !root_dofs.contains(&d) && v.abs() > biggest.1 {
                biggest = (d, v.abs());
            }
        }
        n += 1;
        if n == per || k + 1 == rec.frames.len() {
            let now = ekf.innovation_stats().clone();
            let nis = |t: usize| {
                let (a, b) = (now[t][thigh], prev[t][thigh]);
                let c = a.count - b.count;
                format!("{:.2} ({c})", (a.sum_nis - b.sum_nis) / c.max(1) as f64)
            };
            let deg = |v: &[f64]| {
                hip_dofs
                    .iter()
                    .map(|&d| format!("{:+5.0}", v[d].to_degrees()))
                    .collect::<Vec<_>>()
                    .join(" ")
            };
            println!(
                "{:5.1} | {:<18} {:4.0}° | {} | {} | {:5.1} {:5.1} {:5.1} | {} / {} / {} | {sat} {used}/{rejected} {lost} {div}",
                t,
                dof_names[biggest.0],
                biggest.1.to_degrees(),
                deg(truth),
                deg(est),
                sums[0] / n as f64,
                sums[1] / n as f64,
                sums[2] / n as f64,
                nis(0),
                nis(1),
                nis(2)
            );
            prev = now;
            sums = [0.0; 3];
            (sat, used, rejected, lost, div, n) = (0, 0, 0, 0, 0, 0);
            biggest = (0, 0.0);
        }
    }
    println!(
        "stepped by hand: neck {:.2} shoulder {:.2} hip {:.2}",
        total[0] / n_total as f64,
        total[1] / n_total as f64,
        total[2] / n_total as f64
    );
    std::fs::write("/tmp/romhip-rom.csv", csv).unwrap();
}

/// Which distances move the hip's rotation: the filter (per-board σ from the 6 s first pass,
/// as the full run) stepped over the first `seconds` of `rec`; on every frame whose step
/// turns the hip DOF `rot` by more than 0.2°, the same step repeated without each
/// microphone's distances in turn, and the distances of the microphones whose removal changes
/// the turn by more than 0.1° listed with their true (rigid, true suit) lengths.
fn rom_attrib(
    s: &Skeleton,
    rec: &SimulatedRecording,
    p: FilterParams,
    thigh: usize,
    rot: usize,
    seconds: f64,
) {
    let noise = estimate_recording_board_noise(s, rec, p, true, 6.0).unwrap();
    let mut rec = rec.clone();
    rec.nominal_suit = rec.nominal_suit.with_board_noise(noise).unwrap();
    let (mut ekf, _) = start_filter(s, &rec, p, true).unwrap();
    let boards: Vec<String> = rec
        .nominal_suit
        .boards()
        .iter()
        .map(|b| b.name.clone())
        .collect();
    let sources: Vec<String> = rec
        .nominal_suit
        .sources()
        .iter()
        .map(|b| b.name.clone())
        .collect();
    let end = (rec.rest_frames + (seconds * 140.0) as usize).min(rec.frames.len());
    let mut by_mic = vec![0.0f64; boards.len()];
    let mut total = 0.0;
    for k in 0..end {
        let f = &rec.frames[k];
        let before = ekf.theta()[rot];
        let mut trial = Vec::new();
        if k >= rec.rest_frames && !f.distances.is_empty() {
            let mut mics: Vec<usize> = f.distances.iter().map(|m| m.sensor).collect();
            mics.sort_unstable();
            mics.dedup();
            for m in mics {
                let mut e = ekf.clone();
                let mut g = f.clone();
                g.distances.retain(|d| d.sensor != m);
                e.step(&g, Some(&rec.root[k])).unwrap();
                trial.push((m, e.theta()[rot] - before));
            }
        }
        ekf.step(f, Some(&rec.root[k])).unwrap();
        let turn = ekf.theta()[rot] - before;
        if k < rec.rest_frames {
            continue;
        }
        total += turn;
        for &(m, without) in &trial {
            by_mic[m] += turn - without;
        }
        if turn.abs().to_degrees() > 0.2 {
            let t = (k - rec.rest_frames) as f64 / 140.0;
            println!("t {t:.3} s: hip rotation turns {:+.2}°", turn.to_degrees());
            let fk = s.forward_kinematics(&rec.truth[k].theta).unwrap();
            for &(m, without) in &trial {
                let share = (turn - without).to_degrees();
                if share.abs() > 0.1 {
                    let pm = fk.point(&rec.true_suit.boards()[m].point()).unwrap();
                    let ds: Vec<String> = f
                        .distances
                        .iter()
                        .filter(|d| d.sensor == m)
                        .map(|d| {
                            let ps = fk
                                .point(&rec.true_suit.sources()[d.source].point())
                                .unwrap();
                            format!(
                                "{} {:.1} mm (true {:.1}, conf {:.2}, age {:.1} ms)",
                                sources[d.source],
                                1e3 * d.distance_m,
                                1e3 * pm.distance(ps),
                                d.confidence,
                                1e3 * d.age_s
                            )
                        })
                        .collect();
                    println!(
                        "    {:<12} share {share:+.2}°: {}{}",
                        boards[m],
                        ds.join("; "),
                        if m == thigh { " [the thigh]" } else { "" }
                    );
                }
            }
        }
    }
    println!(
        "first {seconds} s: hip rotation turned {:+.2}° in all; per microphone (its distances' share, > 0.2°):",
        total.to_degrees()
    );
    for (m, v) in by_mic.iter().enumerate() {
        if v.abs().to_degrees() > 0.2 {
            println!("    {:<12} {:+.2}°", boards[m], v.to_degrees());
        }
    }
}

/// `rec` with each microphone–source pair's median distance residual on the rest hold
/// (measured against the nominal suit at the known rest pose, confidence ≥ 0.5, at least 3
/// pulses) subtracted from every distance of that pair if it is at most `limit` metres (a
/// larger one is taken for a longer path heard at rest, not the placement).
fn rest_bias_corrected(s: &Skeleton, rec: &SimulatedRecording, limit: f64) -> SimulatedRecording {
    let fk = s.forward_kinematics(&rec.truth[0].theta).unwrap();
    let suit = &rec.nominal_suit;
    let ns = suit.sources().len();
    let mut residuals = vec![Vec::new(); suit.boards().len() * ns];
    for f in &rec.frames[..rec.rest_frames] {
        for d in f.distances.iter().filter(|d| d.confidence >= 0.5) {
            let pm = fk.point(&suit.boards()[d.sensor].point()).unwrap();
            let ps = fk.point(&suit.sources()[d.source].point()).unwrap();
            residuals[d.sensor * ns + d.source].push(d.distance_m - pm.distance(ps));
        }
    }
    let bias: Vec<f64> = residuals
        .iter_mut()
        .map(|v| {
            if v.len() < 3 {
                return 0.0;
            }
            v.sort_by(f64::total_cmp);
            let m = v[v.len() / 2];
            if m.abs() <= limit {
                m
            } else {
                0.0
            }
        })
        .collect();
    if limit.is_infinite() {
        for (i, v) in residuals.iter().enumerate() {
            if v.len() >= 3 && v[v.len() / 2].abs() > 0.02 {
                println!(
                    "    pair {} – {}: median {:.1} mm over {} pulses (range {:.1} … {:.1})",
                    suit.boards()[i / ns].name,
                    suit.sources()[i % ns].name,
                    1e3 * v[v.len() / 2],
                    v.len(),
                    1e3 * v[0],
                    1e3 * v[v.len() - 1]
                );
            }
        }
    }
    let used: Vec<f64> = bias.iter().copied().filter(|b| *b != 0.0).collect();
    let rms = (used.iter().map(|b| b * b).sum::<f64>() / used.len().max(1) as f64).sqrt();
    println!(
        "    rest-hold pair bias: {} of {} pairs, RMS {:.1} mm, largest {:.1} mm",
        used.len(),
        bias.len(),
        1e3 * rms,
        1e3 * used.iter().fold(0.0f64, |a, b| a.max(b.abs()))
    );
    let mut out = rec.clone();
    for f in &mut out.frames {
        for d in &mut f.distances {
            d.distance_m -= bias[d.sensor * ns + d.source];
        }
    }
    out
}
