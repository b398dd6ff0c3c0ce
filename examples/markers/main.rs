//! Markers and bar calibration (Fua et al. §2), skin-core's optical motion-capture chain.
//!
//! 1. **Bar calibration (§2.2)**: a 0.5 m bar with two retro-reflective markers waved through
//!    the volume of three 768 × 576 cameras, σ = 0.3 px pixel noise; self-calibrating sparse
//!    bundle adjustment of the camera poses and focal lengths and the bar positions, started
//!    from an approximate rig (cameras moved by ~6 cm, turned by ~1°, focal lengths 2 % off;
//!    each bar position from the forward intersection through that rig), scale from the bar
//!    length. Figures: reprojection RMS, camera centres after a similarity alignment to the
//!    true rig, the RMS error of the bar length triangulated freely on held-out bar positions,
//!    and a plot of the centre error against the number of bar positions.
//! 2. **Markers (§2.3–2.4)**: 20 skin markers on the studio performer during its fast motion,
//!    drawn with occlusion into four grey cameras at 60 Hz, detected, matched, triangulated and
//!    tracked with the three-frame rule with the search volumes of the published human limits
//!    (`TrackParams::human`: 40 m/s, 800 m/s²; `track_*_limit_*`, against the motion's own
//!    maxima `true_max_*`); identity switches against the same tracker without the
//!    acceleration volume (nearest-prediction linking, the baseline that could have won).
//!
//! `cargo run --release --example markers [-- --quick] [-- --out DIR]`
//! Last stdout line: one JSON object with all figures.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)] // not library code

use std::time::Instant;

use clap::Parser;
use dynamic_shapes::core::camera::Camera;
use dynamic_shapes::core::markers::{
    bar_length_rms_m, calibrate_with_bar, id_switches, synthetic_bar_calibration, track_markers,
    BarCalibrationParams, TrackParams,
};
use dynamic_shapes::core::math::{fit_similarity, Alignment, DVec3};
use dynamic_shapes::core::stats::percentile;
use dynamic_shapes_studio::MarkerScenario;
use example_kit::plot::{Chart, Series, Style};
use example_kit::{Goal, Headline, Run};
use serde_json::json;

type AnyResult<T> = Result<T, Box<dyn std::error::Error>>;

/// Pixel noise of the bar markers' centroids, px (the validation condition).
const SIGMA_PX: f64 = 0.3;

fn centre_error_m(cams: &[Camera], truth: &[Camera]) -> AnyResult<f64> {
    let from: Vec<DVec3> = cams.iter().map(Camera::centre).collect();
    let to: Vec<DVec3> = truth.iter().map(Camera::centre).collect();
    let s = fit_similarity(&from, &to, None, Alignment::Similarity)?;
    Ok(from
        .iter()
        .zip(&to)
        .map(|(f, t)| s.apply(*f).distance(*t))
        .fold(0.0, f64::max))
}

fn main() -> AnyResult<()> {
    let start = Instant::now();
    let args = example_kit::cli::Args::parse();
    let quick = args.common.quick;
    let mut run = Run::start(
        "markers",
        &args.common,
        "Markers and bar calibration (Fua et al. §2): three cameras calibrated by \
         self-calibrating sparse bundle adjustment from a 0.5 m bar waved through the volume \
         (σ = 0.3 px), started from an approximate rig (scale from the bar length, gauge from \
         camera 0); then 20 skin markers detected, triangulated and tracked through the \
         studio's fast motion in four cameras.",
    )?;
    let bars = if quick { 60 } else { 120 };
    let problem = synthetic_bar_calibration(bars, SIGMA_PX, false, 5)?;
    let held_out = synthetic_bar_calibration(40, SIGMA_PX, false, 6)?;
    let params = BarCalibrationParams::new(problem.bar_length_m);
    let t = Instant::now();
    let cal = calibrate_with_bar(&problem.initial, &problem.observations, &params)?;
    let calibrate_s = t.elapsed().as_secs_f64();
    let centre_mm = 1e3 * centre_error_m(&cal.cameras, &problem.truth.cameras)?;
    let initial_centre_mm = 1e3 * centre_error_m(&problem.initial, &problem.truth.cameras)?;
    let length_mm = 1e3 * bar_length_rms_m(&cal.cameras, &held_out.observations, 0.5)?;
    let initial_length_mm = 1e3 * bar_length_rms_m(&problem.initial, &held_out.observations, 0.5)?;
    // Centre error against the number of bar positions.
    let counts: Vec<usize> = if quick {
        vec![10, 20, 40, 60]
    } else {
        vec![10, 20, 40, 80, 120]
    };
    let mut curve = Vec::new();
    for &n in &counts {
        let p = synthetic_bar_calibration(n, SIGMA_PX, false, 5)?;
        let c = calibrate_with_bar(&p.initial, &p.observations, &params)?;
        curve.push((
            n as f64,
            1e3 * centre_error_m(&c.cameras, &p.truth.cameras)?,
        ));
    }
    let file = "centre_error_vs_bars.png";
    let chart = Chart::new(
        "Bar calibration: camera centre error vs bar positions (σ = 0.3 px)",
        "bar positions",
        "max camera centre error after similarity alignment (mm)",
    )
    .with(Series::new(
        "bundle adjustment from the approximate rig",
        [40, 80, 220],
        Style::LineMarkers,
        curve.clone(),
    ))
    .with(Series::new(
        "goal (3 mm)",
        [220, 40, 40],
        Style::Dashed,
        vec![(counts[0] as f64, 3.0), (bars as f64, 3.0)],
    ));
    run.save_picture(
        file,
        &chart.draw()?,
        "Camera centre error against the number of bar positions",
    )?;
    // Markers through the studio's fast motion.
    let t = Instant::now();
    let scenario = MarkerScenario::default();
    let frames = scenario.observe()?;
    let sets: Vec<Vec<DVec3>> = frames.iter().map(|f| f.points.clone()).collect();
    let ids: Vec<Vec<usize>> = frames.iter().map(|f| f.nearest_true.clone()).collect();
    let errors_mm: Vec<f64> = frames
        .iter()
        .flat_map(|f| f.error_m.iter().map(|e| 1e3 * e))
        .collect();
    // The true markers' largest speed and acceleration (finite differences at the frame rate).
    let rate = scenario.frame_rate_hz;
    let (mut true_speed, mut true_accel) = (0.0f64, 0.0f64);
    for w in frames.windows(3) {
        for ((a, b), c) in w[0].truth.iter().zip(&w[1].truth).zip(&w[2].truth) {
            true_speed = true_speed.max(a.distance(*b) * rate);
            true_accel = true_accel.max((*c - 2.0 * *b + *a).length() * rate * rate);
        }
    }
    let params3 = scenario.track_params();
    let trajectories = track_markers(&sets, &params3)?;
    let switches = id_switches(&trajectories, &ids)?;
    let loose = TrackParams {
        max_acceleration_m_per_frame2: params3.max_velocity_m_per_frame,
        ..params3
    };
    let loose_switches = id_switches(&track_markers(&sets, &loose)?, &ids)?;
    let markers_s = t.elapsed().as_secs_f64();
    run.headline(
        Headline::new(
            "marker_tracking_id_switches",
            "identity switches, three-frame rule, fast motion",
            "switches",
        )
        .note(
            "search volumes from human limits (40 m/s, 800 m/s²); nearest-prediction \
             linking in loose_tracking_id_switches",
        ),
    );
    run.headline(Headline::new(
        "marker_error_median_mm",
        "triangulated marker error, median",
        "mm",
    ));
    run.headline(
        Headline::new("bar_calibration_rms_px", "reprojection RMS", "px")
            .goal(Goal::AtMost(0.5))
            .note("goal in docs/skin-core.md, at σ = 0.3 px"),
    );
    run.headline(
        Headline::new(
            "bar_camera_centre_mm",
            "camera centres after similarity alignment (max)",
            "mm",
        )
        .goal(Goal::AtMost(3.0))
        .note("goal in docs/skin-core.md"),
    );
    run.headline(Headline::new(
        "bar_length_rms_mm",
        "bar length RMS, free triangulation, held-out positions",
        "mm",
    ));
    run.finish(json!({
        "example": "markers",
        "bar_initialisation": "approximate rig (cameras 4-5 cm and 1 degree off, focal 2 % off); bars by forward intersection through it",
        "bar_unknowns": cal.unknowns,
        "quick": quick,
        "bar_positions": bars,
        "sigma_px": SIGMA_PX,
        "bar_calibration_rms_px": cal.rms_px,
        "bar_camera_centre_mm": centre_mm,
        "initial_camera_centre_mm": initial_centre_mm,
        "bar_length_rms_mm": length_mm,
        "initial_bar_length_rms_mm": initial_length_mm,
        "iterations": cal.iterations,
        "calibrate_s": calibrate_s,
        "centre_mm_vs_bars": curve,
        "marker_frames": frames.len(),
        "marker_reconstructions": errors_mm.len(),
        "marker_error_median_mm": percentile(&errors_mm, 0.5),
        "marker_error_p95_mm": percentile(&errors_mm, 0.95),
        "marker_trajectories": trajectories.len(),
        "marker_tracking_id_switches": switches,
        "track_speed_limit_m_per_s": params3.max_velocity_m_per_frame * rate,
        "track_acceleration_limit_m_per_s2": params3.max_acceleration_m_per_frame2 * rate * rate,
        "true_max_speed_m_per_s": true_speed,
        "true_max_acceleration_m_per_s2": true_accel,
        "loose_tracking_id_switches": loose_switches,
        "markers_s": markers_s,
        "seconds": start.elapsed().as_secs_f64(),
    }))?;
    Ok(())
}
