//! Camera calibration from 2D–3D correspondences (Sand 2003 §4.1) on a synthetic problem with
//! known truth: a distorted camera ~3 m from 300 random points, σ = 0.5 px Gaussian pixel noise.
//! Calibrates with DLT + Levenberg–Marquardt and with Sand's Nelder–Mead simplex, and writes the
//! cameras (JSON and OpenCV YAML) and a picture of the residuals (DLT red, LM blue, ×15) to
//! `out/calibrate/`.
//!
//! `cargo run --release --example calibrate [-- --quick] [-- --out DIR]` (`--quick` runs the same, it is fast).
//! Last stdout line: JSON with `calib_rms_px`, `calib_center_mm`, `calib_nm_rms_px`, `calib_ms`,
//! `seconds`.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)] // not library code

use std::time::Instant;

use clap::Parser;
use dynamic_shapes::core::camera::{
    calibrate, dlt, synthetic_calibration, CalibrationMethod, CalibrationParams, Camera,
    OpenCvCalibration, OpenCvParams, SyntheticCalibration, SyntheticCalibrationParams,
};
use dynamic_shapes::core::math::DVec2;
use example_kit::plot::{Chart, LegendPosition, Series, Style};
use example_kit::{Goal, Headline, Run};
use rand::SeedableRng;

const SEED: u64 = 7;
/// Residual vectors are drawn this many times longer than they are.
const RESIDUAL_GAIN: f64 = 15.0;

/// Length of the scale bar, px of residual.
const SCALE_BAR_PX: f64 = 2.0;

/// Picture of the reprojection residuals (×RESIDUAL_GAIN) of the DLT (red) and LM (blue)
/// cameras at the measured points, in image coordinates, with a legend and a scale bar.
fn residual_picture(
    problem: &SyntheticCalibration,
    dlt: &Camera,
    lm: &Camera,
    rms: (f64, f64),
) -> Result<image::RgbImage, Box<dyn std::error::Error>> {
    let k = problem.truth.intrinsics;
    let (w, h) = (f64::from(k.width), f64::from(k.height));
    let mut segments = [vec![], vec![]];
    for (w, p) in problem.world.iter().zip(&problem.pixels) {
        for (cam, seg) in [dlt, lm].into_iter().zip(segments.iter_mut()) {
            let q = cam.project(*w)?;
            let e = *p + (q - *p) * RESIDUAL_GAIN;
            seg.extend([(p.x, p.y), (e.x, e.y)]);
        }
    }
    let [dlt_seg, lm_seg] = segments;
    let bar = DVec2::new(0.04 * w, 0.95 * h);
    let mut chart = Chart::new(
        format!(
            "Reprojection residuals at the {} points, drawn ×{RESIDUAL_GAIN}",
            problem.pixels.len()
        ),
        "image x (px)",
        "image y (px)",
    );
    chart.size = (960, 780);
    chart.y_down = true;
    chart.marker_px = 2;
    chart.x_range = Some((0.0, w));
    chart.y_range = Some((0.0, h));
    chart.legend = LegendPosition::UpperRight;
    let chart = chart
        .with(Series::new(
            format!("DLT residual (rms {:.3} px)", rms.0),
            [220, 40, 40],
            Style::Segments,
            dlt_seg,
        ))
        .with(Series::new(
            format!("DLT + LM residual (rms {:.3} px)", rms.1),
            [40, 80, 220],
            Style::Segments,
            lm_seg,
        ))
        .with(Series::new(
            "measured point (σ = 0.5 px noise)",
            [0, 0, 0],
            Style::Markers,
            problem.pixels.iter().map(|p| (p.x, p.y)).collect(),
        ))
        .with(Series::new(
            format!("scale bar: {SCALE_BAR_PX} px of residual"),
            [0, 150, 0],
            Style::Line,
            vec![
                (bar.x, bar.y),
                (bar.x + SCALE_BAR_PX * RESIDUAL_GAIN, bar.y),
            ],
        ));
    Ok(chart.draw()?)
}

/// Camera calibration from 2D–3D correspondences on a synthetic problem with known truth
/// (Sand 2003 §4.1): DLT + Levenberg–Marquardt and Nelder–Mead.
#[derive(Parser)]
struct Args {
    #[command(flatten)]
    common: example_kit::Common,
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let t0 = Instant::now();
    let args = Args::parse();
    let quick = args.common.quick;
    let mut run = Run::start(
        "calibrate",
        &args.common,
        "Calibrates a synthetic distorted camera ~3 m from 300 random points with σ = 0.5 px \
         pixel noise (Sand 2003 §4.1), with DLT + Levenberg–Marquardt and with Sand's \
         Nelder–Mead simplex, and compares each with the true camera.",
    )?;
    let out = run.out().to_path_buf();
    let params = SyntheticCalibrationParams::default();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(SEED);
    let problem = synthetic_calibration(&params, &mut rng)?;
    eprintln!(
        "synthetic problem: {} points, camera {:.2} m from the volume centre, noise {} px{}",
        problem.world.len(),
        problem.truth.centre().length(),
        params.noise_px,
        if quick { " (--quick: same size)" } else { "" }
    );

    let stage = run.stage("DLT + LM", None);
    let t = Instant::now();
    let lm = calibrate(
        &problem.world,
        &problem.pixels,
        params.width,
        params.height,
        &CalibrationParams::default(),
    )?;
    let calib_ms = t.elapsed().as_secs_f64() * 1e3;
    let centre_mm = (lm.camera.centre() - problem.truth.centre()).length() * 1e3;
    stage.finish(format!(
        "DLT rms {:.3} px -> LM rms {:.3} px in {} iterations, centre error {:.3} mm, k1 {:.4} (truth {:.4}), {:.1} ms",
        lm.dlt_rms_px, lm.rms_px, lm.iterations, centre_mm, lm.camera.distortion.k1, params.k1, calib_ms
    ));

    let stage = run.stage("Nelder-Mead", None);
    let t = Instant::now();
    let nm_params = CalibrationParams::default().with_method(CalibrationMethod::NelderMead);
    let nm = calibrate(
        &problem.world,
        &problem.pixels,
        params.width,
        params.height,
        &nm_params,
    )?;
    let nm_ms = t.elapsed().as_secs_f64() * 1e3;
    let nm_centre_mm = (nm.camera.centre() - problem.truth.centre()).length() * 1e3;
    stage.finish(format!(
        "rms {:.3} px after {} evaluations, centre error {:.3} mm, {:.1} ms",
        nm.rms_px, nm.evaluations, nm_centre_mm, nm_ms
    ));

    let json = serde_json::json!({ "truth": problem.truth, "lm": lm, "nelder_mead": nm });
    std::fs::write(
        out.join("calibration.json"),
        serde_json::to_string_pretty(&json)?,
    )?;
    let init = dlt(
        &problem.world,
        &problem.pixels,
        params.width,
        params.height,
        1e-3,
    )?;
    let img = residual_picture(&problem, &init.camera, &lm.camera, (init.rms_px, lm.rms_px))?;
    run.save_picture(
        "residuals.png",
        &img,
        &format!(
            "Reprojection residuals at the 300 noisy image points, drawn {RESIDUAL_GAIN}× longer: \
             DLT alone (red) and DLT refined by Levenberg–Marquardt (blue); the scale bar is \
             {SCALE_BAR_PX} px of residual."
        ),
    )?;
    let lenient = OpenCvParams {
        max_deviation_px: f64::INFINITY,
        ..Default::default()
    };
    let export = OpenCvCalibration::from_camera(&lm.camera, &lenient)?;
    std::fs::write(
        out.join("camera_opencv.yaml"),
        export.calibration.to_yaml_string(),
    )?;
    eprintln!(
        "wrote out/calibrate/calibration.json, camera_opencv.yaml and residuals.png (OpenCV model deviation {:.3} px)",
        export.max_deviation_px
    );

    run.headline(
        Headline::new("calib_rms_px", "LM reprojection RMS per coordinate", "px")
            .paper("sub-pixel RMS over several hundred points, Sand 2003 §4.1")
            .goal(Goal::AtMost(0.6))
            .note("noise σ = 0.5 px; goal from docs/skin-core.md"),
    );
    run.headline(
        Headline::new("calib_center_mm", "LM camera-centre error", "mm")
            .goal(Goal::AtMost(2.0))
            .note("goal from docs/skin-core.md"),
    );
    run.headline(
        Headline::new("calib_nm_rms_px", "Nelder–Mead reprojection RMS", "px")
            .baseline()
            .paper("sub-pixel RMS over several hundred points, Sand 2003 §4.1"),
    );
    run.headline(
        Headline::new(
            "calib_nm_center_mm",
            "Nelder–Mead camera-centre error",
            "mm",
        )
        .baseline(),
    );
    run.headline(Headline::new("calib_ms", "DLT + LM time", "ms"));
    let summary = serde_json::json!({
        "calib_rms_px": lm.rms_px,
        "calib_center_mm": centre_mm,
        "calib_nm_rms_px": nm.rms_px,
        "calib_nm_center_mm": nm_centre_mm,
        "calib_ms": calib_ms,
        "calib_nm_ms": nm_ms,
        "seconds": t0.elapsed().as_secs_f64(),
    });
    run.finish(summary)?;
    Ok(())
}
