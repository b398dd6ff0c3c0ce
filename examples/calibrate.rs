//! Camera calibration from 2D–3D correspondences (Sand 2003 §4.1) on a synthetic problem with
//! known truth: a distorted camera ~3 m from 300 random points, σ = 0.5 px Gaussian pixel noise.
//! Calibrates with DLT + Levenberg–Marquardt and with Sand's Nelder–Mead simplex, and writes the
//! cameras (JSON and OpenCV YAML) to `out/calibrate/`.
//!
//! `cargo run --release --example calibrate [-- --quick]` (`--quick` runs the same, it is fast).
//! Last stdout line: JSON with `calib_rms_px`, `calib_center_mm`, `calib_nm_rms_px`, `calib_ms`,
//! `seconds`.

use std::time::Instant;

use dynamic_shapes::core::camera::{
    calibrate, synthetic_calibration, CalibrationMethod, CalibrationParams, OpenCvCalibration,
    OpenCvParams, SyntheticCalibrationParams,
};
use rand::SeedableRng;

const SEED: u64 = 7;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let t0 = Instant::now();
    let quick = std::env::args().any(|a| a == "--quick");
    let out = std::path::Path::new("out/calibrate");
    std::fs::create_dir_all(out)?;
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
    eprintln!(
        "DLT rms {:.3} px -> LM rms {:.3} px in {} iterations, centre error {:.3} mm, k1 {:.4} (truth {:.4}), {:.1} ms",
        lm.dlt_rms_px, lm.rms_px, lm.iterations, centre_mm, lm.camera.distortion.k1, params.k1, calib_ms
    );

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
    eprintln!(
        "Nelder-Mead rms {:.3} px after {} evaluations, centre error {:.3} mm, {:.1} ms",
        nm.rms_px, nm.evaluations, nm_centre_mm, nm_ms
    );

    let json = serde_json::json!({ "truth": problem.truth, "lm": lm, "nelder_mead": nm });
    std::fs::write(
        out.join("calibration.json"),
        serde_json::to_string_pretty(&json)?,
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
        "wrote out/calibrate/calibration.json and camera_opencv.yaml (OpenCV model deviation {:.3} px)",
        export.max_deviation_px
    );

    let summary = serde_json::json!({
        "calib_rms_px": lm.rms_px,
        "calib_center_mm": centre_mm,
        "calib_nm_rms_px": nm.rms_px,
        "calib_nm_center_mm": nm_centre_mm,
        "calib_ms": calib_ms,
        "calib_nm_ms": nm_ms,
        "seconds": t0.elapsed().as_secs_f64(),
    });
    println!("{summary}");
    Ok(())
}
