#![allow(clippy::unwrap_used, clippy::print_stdout)]
use inertial_acoustic::simulate::*;
use inertial_acoustic::*;
use skin_core::skeleton::{human_skeleton, HumanParams};
use skin_core::studio::{exercise_motion, ExerciseParams};
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let dur: f64 = args.get(1).map(|s| s.parse().unwrap()).unwrap_or(10.0);
    let q: f64 = args.get(2).map(|s| s.parse().unwrap()).unwrap_or(0.04);
    let s = human_skeleton(&HumanParams::default()).unwrap();
    let m = exercise_motion(&s, &ExerciseParams::default().with_duration_s(dur)).unwrap();
    let mut sp = SimulationParams::default();
    if let Ok(g) = std::env::var("GR") { sp.gyro_range = g.parse().unwrap(); }
    if let Ok(g) = std::env::var("AR") { sp.accel_range = g.parse().unwrap(); }
    if std::env::var("CLEAN").is_ok() {
        sp.accel_noise = 0.0; sp.gyro_noise = 0.0; sp.accel_zero_sd = 0.0; sp.gyro_zero_sd = 0.0; sp.scale_sd = 0.0;
        sp.gyro_bias_walk = 0.0; sp.bit_error_rate = 0.0; sp.placement_sd_m = 0.0; sp.placement_sd_deg = 0.0; sp.skin_slide_m_per_rad = 0.0;
        
    }
    let sim = SuitSimulator::new(&s, sp).unwrap();
    let t = std::time::Instant::now();
    let cal = sim.calibrate_offsets(3).unwrap();
    let mm = prepare_motion(&s, &m, &sp).unwrap();
    let rec = sim.record(&mm, &cal.offsets).unwrap();
    let e = &rec.los_distance_errors_m;
    let mean = e.iter().map(|v| v.abs()).sum::<f64>() / e.len() as f64;
    println!("sim {:.2}s us {:.2}s in {:.3}s heard {}/{} los n {} mean abs {:.4} flagged {}", t.elapsed().as_secs_f64(), rec.ultrasound_s, rec.inertial_s, rec.pulses_heard, rec.pulses_total, e.len(), mean, rec.inertial_frames_flagged);
    for (lo, hi) in [(0.0, 0.05), (0.05, 0.3), (0.3, 0.7), (0.7, 1.01)] {
        let sel: Vec<_> = rec.detections.iter().filter(|d| d.1 >= lo && d.1 < hi).collect();
        let bad = sel.iter().filter(|d| d.0.abs() > 0.02).count();
        let los = sel.iter().filter(|d| d.2).count();
        println!("conf [{lo},{hi}): n {} los {} |err|>2cm {}", sel.len(), los, bad);
    }
    let joints: Vec<usize> = ["neck", "r_shoulder", "l_hip"].iter().map(|n| s.joint_index(n).unwrap()).collect();
    if args.len() > 4 {
        let all: Vec<usize> = (1..s.joint_count()).collect();
        let p = FilterParams::default().with_sensors(SensorSet { accelerometers: args[4] == "ag", gyroscopes: true, distances: false }).with_process_sigma(q);
        let r = run_filter(&s, &rec, p, true, &all).unwrap();
        for (i, &j) in all.iter().enumerate() {
            println!("{:12} {:.1}/{:.1}", s.joints()[j].name, r.stats[i].mean_deg, r.stats[i].sd_deg);
        }
        return;
    }
    if args.len() > 3 {
            {
        let p = FilterParams::default().with_sensors(SensorSet { accelerometers: false, gyroscopes: true, distances: false }).with_process_sigma(q);
        let r = run_filter(&s, &rec, p, true, &joints).unwrap();
        let sh = s.joint_index("r_shoulder").unwrap();
        let dofs: Vec<usize> = s.joint_dofs(sh).collect();
        for k in (0..r.errors_deg[1].len()).step_by(35) {
            let th = &rec.truth[k + rec.rest_frames].theta;
            println!("t {:.2} err {:.1} truth {:?}", k as f64 / 140.0, r.errors_deg[1][k], dofs.iter().map(|&d| (th[d].to_degrees()).round()).collect::<Vec<_>>());
        }
    }

        return;
    }
    for set in SensorSet::table_4_1() {
        for root in [true, false] {
            let p = FilterParams::default().with_sensors(set).with_process_sigma(q).with_distance_gate_sigma(std::env::var("GATE").map(|g| g.parse().unwrap()).unwrap_or(0.0)).with_measurement_sigmas(std::env::var("SA").map(|g| g.parse().unwrap()).unwrap_or(0.02), 0.002, std::env::var("SD").map(|g| g.parse().unwrap()).unwrap_or(0.0025));
            let r = run_filter(&s, &rec, p, root, &joints).unwrap();
            println!("{:6} root {} : {:?} div {} ekf {:.2}s dist {}", r.sensors, root, r.stats.iter().map(|s| format!("{:.1}/{:.1}", s.mean_deg, s.sd_deg)).collect::<Vec<_>>(), r.diverged_frames, r.ekf_s, r.distances_used);
        }
    }
}
