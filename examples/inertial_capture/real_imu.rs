//! Real IMU recordings: the orientation part of the filter (one board, gyroscope +
//! accelerometer, no magnetometer) on BROAD against its optical reference, and on the x-io
//! log (135 s, no reference) for stability.
//!
//! BROAD, tuned on one trial and tested on another (two trials of the same kind: fast
//! rotations by hand without translation, the same board; first 60 s of each):
//! * tuning trial 09 (fast rotation with breaks B, [`TUNING_TRIAL`]): the accelerometer σ (the
//!   filter's one gain here; q stays 4 rad/s², σ_g the thesis's 0.002 rad/s) is chosen on the
//!   grid [`GAIN_GRID`] by [`HeadingInclinationRmse::combined_deg`] over its movement samples.
//!   The grid was widened until the choice is interior; `broad_tuning_interior` reports
//!   whether it still is.
//! * test trial 07 (fast rotation B, [`TEST_TRIAL`]): `broad_test_rmse_deg` (inclination and
//!   heading split too) over all its movement samples, beside the same filter with the
//!   gyroscope rows only (`broad_gyro_only_test_rmse_deg`).
//!
//! `fusion_broad.py` tunes the x-io Fusion AHRS gain the same way (its own grid, trial 09)
//! and scores it and our estimate (`broad_ours.csv`) on trial 07 with the same metric.

use dynamic_shapes::core::math::{DQuat, DVec3};
use dynamic_shapes::inertial::imu_log::{read_broad_hdf5, read_xio_csv, run_orientation, ImuLog};
use dynamic_shapes::inertial::{
    heading_inclination_rmse, FilterParams, HeadingInclinationRmse, SensorSet,
};
use example_kit::plot::{Chart, Series, Style};
use example_kit::{Headline, Run};
use serde_json::{json, Value};

/// The tuning trial (BROAD 09, first 60 s, in BROAD's HDF5 layout), under `data/`.
pub const TUNING_TRIAL: &str = "imu-broad/09_undisturbed_fast_rotation_with_breaks_B_first60s.hdf5";
/// The test trial (BROAD 07, first 60 s, in BROAD's HDF5 layout), under `data/`.
pub const TEST_TRIAL: &str = "imu-broad/07_undisturbed_fast_rotation_B_first60s.hdf5";
/// The accelerometer σ grid, m/s².
pub const GAIN_GRID: [f64; 14] = [
    0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0, 200.0, 500.0, 1000.0,
];
/// Rest interval used for initialisation (§4.4.4), seconds (movement starts at 30.1 s in
/// trial 09, 26.5 s in trial 07).
const BROAD_REST_S: f64 = 20.0;

/// The filter's noise levels with accelerometer σ `accel_sigma` (m/s²).
fn params(accel_sigma: f64) -> FilterParams {
    FilterParams::default()
        .with_process_sigma(4.0)
        .with_measurement_sigmas(accel_sigma, 0.002, 0.0025)
}

/// The same filter with the gyroscope rows only.
fn gyro_only(p: FilterParams) -> FilterParams {
    p.with_sensors(SensorSet {
        accelerometers: false,
        gyroscopes: true,
        distances: false,
    })
}

fn rmse_json(e: &HeadingInclinationRmse) -> Value {
    json!({"inclination_deg": e.inclination_deg, "heading_deg": e.heading_deg,
           "combined_deg": e.combined_deg(),
           "heading_offset_deg": e.heading_offset_deg, "samples": e.samples})
}

/// The headline figures of the real recordings.
pub fn headlines() -> [Headline; 4] {
    [
        Headline::new(
            "broad_test_rmse_deg",
            "BROAD test trial 07, √(incl² + head²) (σ_a tuned on trial 09)",
            "deg",
        ),
        Headline::new(
            "broad_gyro_only_test_rmse_deg",
            "BROAD test trial 07, gyroscope rows only",
            "deg",
        )
        .baseline(),
        Headline::new(
            "broad_inclination_rmse_deg",
            "BROAD test trial 07 inclination RMSE (one board, gyro + accel)",
            "deg",
        ),
        Headline::new(
            "broad_heading_rmse_deg",
            "BROAD test trial 07 heading RMSE (offset removed)",
            "deg",
        ),
    ]
}

/// Orientation error of `p` on `rec` over its movement samples.
fn score(
    rec: &ImuLog,
    p: FilterParams,
) -> Result<(HeadingInclinationRmse, Vec<DQuat>, f64), Box<dyn std::error::Error>> {
    let r = run_orientation(rec, p, BROAD_REST_S)?;
    if r.diverged > 0 {
        return Err(format!("the orientation filter diverged {} times", r.diverged).into());
    }
    let e = heading_inclination_rmse(&r.orientation, &rec.reference, &rec.movement, DVec3::Z)?;
    Ok((e, r.orientation, r.seconds))
}

/// BROAD and x-io runs; returns the figures.
pub fn run(run: &mut Run) -> Result<Value, Box<dyn std::error::Error>> {
    let stage = run.stage("BROAD recordings", None);
    let tuning = read_broad_hdf5(example_kit::data_path(TUNING_TRIAL)?)?;
    let test = read_broad_hdf5(example_kit::data_path(TEST_TRIAL)?)?;
    // The gain on the tuning trial; the test trial's figures per grid point are reported
    // beside (never used to choose).
    let mut grid = Vec::new();
    for &g in &GAIN_GRID {
        let (t, _, _) = score(&tuning, params(g))?;
        let (e, _, _) = score(&test, params(g))?;
        grid.push((g, t, e));
    }
    let best = (0..grid.len())
        .min_by(|&a, &b| {
            grid[a]
                .1
                .combined_deg()
                .total_cmp(&grid[b].1.combined_deg())
        })
        .ok_or("empty grid")?;
    let interior = best > 0 && best + 1 < grid.len();
    let (gain, tuned, _) = grid[best];
    let (tuning_gyro, _, _) = score(&tuning, gyro_only(params(gain)))?;
    let (ours, ours_q, ours_s) = score(&test, params(gain))?;
    let (gyro, _, _) = score(&test, gyro_only(params(gain)))?;
    let (naive, _, _) = score(&test, gyro_only(params(gain)).with_process_sigma(0.04))?;
    let mut csv = String::from("t_s,qw,qx,qy,qz\n");
    for (t, q) in test.time_s.iter().zip(&ours_q) {
        csv += &format!("{t},{},{},{},{}\n", q.w, q.x, q.y, q.z);
    }
    std::fs::write(run.path("broad_ours.csv"), csv)?;
    let seconds = test.time_s.last().copied().unwrap_or(0.0) - test.time_s[0];
    stage.finish(format!(
        "σa {gain} (trial 09: {:.2}°{}); trial 07: {:.2}° = inclination {:.2}°, heading \
         {:.2}° (gyro-only {:.2}° = {:.2}° / {:.2}°)",
        tuned.combined_deg(),
        if interior { "" } else { ", ON THE GRID'S EDGE" },
        ours.combined_deg(),
        ours.inclination_deg,
        ours.heading_deg,
        gyro.combined_deg(),
        gyro.inclination_deg,
        gyro.heading_deg
    ));

    // Clipped at 3°: the low-σ end runs off to 64° and would hide the differences near the
    // choice.
    const CLIP_DEG: f64 = 3.0;
    let lg = |g: f64| f64::log10(g);
    let pts = |f: &dyn Fn(&(f64, HeadingInclinationRmse, HeadingInclinationRmse)) -> f64| {
        grid.iter()
            .map(|p| (lg(p.0), f(p).min(CLIP_DEG)))
            .collect::<Vec<_>>()
    };
    let flat = |v: f64| {
        vec![
            (lg(GAIN_GRID[0]), v.min(CLIP_DEG)),
            (lg(GAIN_GRID[GAIN_GRID.len() - 1]), v.min(CLIP_DEG)),
        ]
    };
    let chart = Chart::new(
        "BROAD orientation RMSE vs accelerometer σ",
        "log10 accelerometer σ (m/s²)",
        "√(incl² + head²) RMSE, deg (clipped at 3)",
    )
    .with(Series::new(
        "tuning trial 09",
        [40, 90, 200],
        Style::LineMarkers,
        pts(&|p| p.1.combined_deg()),
    ))
    .with(Series::new(
        "test trial 07",
        [220, 120, 40],
        Style::LineMarkers,
        pts(&|p| p.2.combined_deg()),
    ))
    .with(Series::new(
        "test trial 07, inclination only",
        [200, 60, 160],
        Style::Dashed,
        pts(&|p| p.2.inclination_deg),
    ))
    .with(Series::new(
        "trial 09, gyroscope rows only",
        [120, 150, 220],
        Style::Dashed,
        flat(tuning_gyro.combined_deg()),
    ))
    .with(Series::new(
        "trial 07, gyroscope rows only",
        [120, 120, 120],
        Style::Dashed,
        flat(gyro.combined_deg()),
    ))
    .with(Series::new(
        format!("σ chosen on trial 09: {gain} m/s²"),
        [40, 160, 60],
        Style::Line,
        vec![(lg(gain), 0.0), (lg(gain), CLIP_DEG)],
    ));
    run.save_picture(
        "broad_grid.png",
        &chart.draw()?,
        "BROAD: the one-board filter's orientation RMSE over the accelerometer σ grid, on the \
         tuning trial (09, where σ is chosen) and the test trial (07)",
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
        "broad_tuning_trial": TUNING_TRIAL,
        "broad_test_trial": TEST_TRIAL,
        "broad_accelerometer_sigma": gain,
        "broad_tuning_interior": interior,
        "broad_tuning_rmse_deg": rmse_json(&tuned),
        "broad_tuning_gyro_only_rmse_deg": rmse_json(&tuning_gyro),
        "broad_test_rmse_deg": ours.combined_deg(),
        "broad_inclination_rmse_deg": ours.inclination_deg,
        "broad_heading_rmse_deg": ours.heading_deg,
        "broad_rmse_deg": rmse_json(&ours),
        "broad_gyro_only_test_rmse_deg": gyro.combined_deg(),
        "broad_gyro_only_rmse_deg": rmse_json(&gyro),
        "broad_gyro_only_q004_rmse_deg": rmse_json(&naive),
        "broad_grid": grid.iter().map(|(g, t, e)| json!({"accelerometer_sigma": g,
            "tuning": rmse_json(t), "test": rmse_json(e)})).collect::<Vec<_>>(),
        "broad_realtime_factor": seconds / ours_s,
        "xio_seconds": span,
        "xio_diverged": xr.diverged,
        "xio_finite": finite,
        "xio_max_quaternion_norm_error": max_norm_dev,
        "xio_still_tilt_deg_per_third": still_tilt,
    }))
}
