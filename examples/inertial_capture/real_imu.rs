//! Real IMU recordings: the orientation part of the filter (one board, gyroscope +
//! accelerometer, no magnetometer) on BROAD trial 07 against its optical reference, and on
//! the x-io log (135 s, no reference) for stability.
//!
//! BROAD: the accelerometer σ (the filter's one gain here; q stays 4 rad/s², σ_g the
//! thesis's 0.002 rad/s) is chosen on the grid [`GAIN_GRID`] by the error on the first half
//! of the movement samples; `fusion_broad.py` tunes the x-io Fusion AHRS gain on the same
//! grid values and the same half, and scores both estimates with the same metric.

use dynamic_shapes::core::math::DVec3;
use dynamic_shapes::inertial::recordings::{read_broad_csv, read_xio_csv, run_orientation};
use dynamic_shapes::inertial::{heading_inclination_rmse, FilterParams, SensorSet};
use example_kit::plot::{Chart, Series, Style};
use example_kit::Run;
use serde_json::{json, Value};

/// The gain grid shared with `fusion_broad.py` (ours: accelerometer σ in m/s²; Fusion: its
/// dimensionless gain).
pub const GAIN_GRID: [f64; 8] = [0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0, 10.0];
/// Rest interval used for initialisation (§4.4.4), seconds (BROAD's movement starts at 26.5 s).
const BROAD_REST_S: f64 = 20.0;

fn params(accel_sigma: f64) -> FilterParams {
    FilterParams::default()
        .with_process_sigma(4.0)
        .with_measurement_sigmas(accel_sigma, 0.002, 0.0025)
}

fn rmse_json(e: &dynamic_shapes::inertial::HeadingInclinationRmse) -> Value {
    json!({"inclination_deg": e.inclination_deg, "heading_deg": e.heading_deg,
           "heading_offset_deg": e.heading_offset_deg, "samples": e.samples})
}

/// BROAD and x-io runs; returns the figures.
pub fn run(run: &mut Run) -> Result<Value, Box<dyn std::error::Error>> {
    let stage = run.stage("BROAD recording", None);
    let rec = read_broad_csv(example_kit::data_path(
        "imu-broad/07_undisturbed_fast_rotation_B_first60s.csv",
    )?)?;
    let times: Vec<f64> = rec
        .time_s
        .iter()
        .zip(&rec.movement)
        .filter(|(_, m)| **m)
        .map(|(t, _)| *t)
        .collect();
    let split_t = times[times.len() / 2];
    let tune_mask: Vec<bool> = rec
        .movement
        .iter()
        .zip(&rec.time_s)
        .map(|(m, t)| *m && *t < split_t)
        .collect();
    let test_mask: Vec<bool> = rec
        .movement
        .iter()
        .zip(&rec.time_s)
        .map(|(m, t)| *m && *t >= split_t)
        .collect();
    let score = |est: &[dynamic_shapes::core::math::DQuat], mask: &[bool]| {
        heading_inclination_rmse(est, &rec.reference, mask, DVec3::Z)
    };
    let mut grid = Vec::new();
    let mut best: Option<(f64, f64)> = None;
    for &g in &GAIN_GRID {
        let r = run_orientation(&rec, params(g), BROAD_REST_S)?;
        let t = score(&r.orientation, &tune_mask)?;
        let s = t.inclination_deg.hypot(t.heading_deg);
        if best.is_none_or(|(_, b)| s < b) {
            best = Some((g, s));
        }
        let all = score(&r.orientation, &rec.movement)?;
        grid.push((g, s, all));
    }
    let (gain, _) = best.ok_or("empty grid")?;
    let ours = run_orientation(&rec, params(gain), BROAD_REST_S)?;
    let all = score(&ours.orientation, &rec.movement)?;
    let held = score(&ours.orientation, &test_mask)?;
    let gyro_only = params(gain).with_sensors(SensorSet {
        accelerometers: false,
        gyroscopes: true,
        distances: false,
    });
    let gyro = run_orientation(&rec, gyro_only, BROAD_REST_S)?;
    let gyro_all = score(&gyro.orientation, &rec.movement)?;
    let naive = run_orientation(&rec, gyro_only.with_process_sigma(0.04), BROAD_REST_S)?;
    let naive_all = score(&naive.orientation, &rec.movement)?;
    let mut csv = String::from("t_s,qw,qx,qy,qz\n");
    for (t, q) in rec.time_s.iter().zip(&ours.orientation) {
        csv += &format!("{t},{},{},{},{}\n", q.w, q.x, q.y, q.z);
    }
    std::fs::write(run.path("broad_ours.csv"), csv)?;
    let seconds = rec.time_s.last().copied().unwrap_or(0.0) - rec.time_s[0];
    stage.finish(format!(
        "σa {gain}: inclination {:.2}°, heading {:.2}° (gyro-only {:.2}° / {:.2}°)",
        all.inclination_deg, all.heading_deg, gyro_all.inclination_deg, gyro_all.heading_deg
    ));

    let pts = |f: &dyn Fn(&dynamic_shapes::inertial::HeadingInclinationRmse) -> f64| {
        grid.iter()
            .map(|(g, _, e)| (f64::log10(*g), f(e).min(20.0)))
            .collect::<Vec<_>>()
    };
    let chart = Chart::new(
        "BROAD trial 07: orientation RMSE over movement samples vs accelerometer σ",
        "log10 accelerometer σ (m/s²)",
        "RMSE (deg, clipped at 20)",
    )
    .with(Series::new(
        "inclination",
        [40, 90, 200],
        Style::LineMarkers,
        pts(&|e| e.inclination_deg),
    ))
    .with(Series::new(
        "heading (constant offset removed)",
        [220, 120, 40],
        Style::LineMarkers,
        pts(&|e| e.heading_deg),
    ))
    .with(Series::new(
        "gyro-only inclination",
        [120, 120, 120],
        Style::Dashed,
        vec![
            (f64::log10(GAIN_GRID[0]), gyro_all.inclination_deg),
            (f64::log10(GAIN_GRID[7]), gyro_all.inclination_deg),
        ],
    ));
    run.save_picture(
        "broad_grid.png",
        &chart.draw()?,
        "BROAD: inclination and heading RMSE of the one-board filter over the gain grid",
    )?;

    let stage = run.stage("x-io recording", None);
    let xio = read_xio_csv(example_kit::data_path("imu-xio/sensor_data.csv")?)?;
    let xr = run_orientation(&xio, params(gain), 1.0)?;
    let g = dynamic_shapes::inertial::GRAVITY_M_S2;
    let mut thirds = [(0.0, 0usize); 3];
    let span = xio.time_s.last().copied().unwrap_or(0.0) - xio.time_s[0];
    for ((r, q), t) in xio.readings.iter().zip(&xr.orientation).zip(&xio.time_s) {
        if r.gyro_rad_s.length() < 0.1 && (r.accel_m_s2.length() - g).abs() < 0.02 * g {
            let k = (((t - xio.time_s[0]) / span * 3.0) as usize).min(2);
            thirds[k].0 += (q.inverse() * DVec3::Z)
                .angle_between(r.accel_m_s2)
                .to_degrees();
            thirds[k].1 += 1;
        }
    }
    let still_tilt: Vec<f64> = thirds.iter().map(|(s, n)| s / (*n).max(1) as f64).collect();
    let max_norm_dev = xr
        .orientation
        .iter()
        .map(|q| (q.length() - 1.0).abs())
        .fold(0.0, f64::max);
    let finite = xr.orientation.iter().all(|q| q.is_finite());
    stage.finish(format!(
        "{span:.1} s, diverged {}, still-sample tilt vs accelerometer per third {still_tilt:.2?}°",
        xr.diverged
    ));

    Ok(json!({
        "broad_rmse_deg": rmse_json(&all),
        "broad_inclination_rmse_deg": all.inclination_deg,
        "broad_heading_rmse_deg": all.heading_deg,
        "broad_heldout_rmse_deg": rmse_json(&held),
        "broad_gyro_only_rmse_deg": rmse_json(&gyro_all),
        "broad_gyro_only_q004_rmse_deg": rmse_json(&naive_all),
        "broad_accelerometer_sigma": gain,
        "broad_split_t_s": split_t,
        "broad_grid": grid.iter().map(|(g, s, e)| json!({"accelerometer_sigma": g,
            "tuning_score_deg": s, "all_movement": rmse_json(e)})).collect::<Vec<_>>(),
        "broad_realtime_factor": seconds / ours.seconds,
        "xio_seconds": span,
        "xio_diverged": xr.diverged,
        "xio_finite": finite,
        "xio_max_quaternion_norm_error": max_norm_dev,
        "xio_still_tilt_deg_per_third": still_tilt,
    }))
}
