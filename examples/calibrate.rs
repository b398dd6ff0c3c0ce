//! Camera calibration from 2D–3D correspondences (Sand 2003 §4.1) on a synthetic problem with
//! known truth: a distorted camera ~3 m from 300 random points, σ = 0.5 px Gaussian pixel noise.
//! Calibrates with DLT + Levenberg–Marquardt and with Sand's Nelder–Mead simplex, and writes the
//! cameras (JSON and OpenCV YAML) and a picture of the residuals (DLT red, LM blue, ×15) to
//! `out/calibrate/`.
//!
//! `cargo run --release --example calibrate [-- --quick]` (`--quick` runs the same, it is fast).
//! Last stdout line: JSON with `calib_rms_px`, `calib_center_mm`, `calib_nm_rms_px`, `calib_ms`,
//! `seconds`.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)] // not library code

use std::time::Instant;

use dynamic_shapes::core::camera::{
    calibrate, dlt, synthetic_calibration, CalibrationMethod, CalibrationParams, Camera,
    OpenCvCalibration, OpenCvParams, SyntheticCalibration, SyntheticCalibrationParams,
};
use dynamic_shapes::core::math::DVec2;
use rand::SeedableRng;

const SEED: u64 = 7;
/// Residual vectors are drawn this many times longer than they are.
const RESIDUAL_GAIN: f64 = 15.0;

/// Draws a line segment into an RGB image (clipped, no anti-aliasing).
fn draw_line(img: &mut image::RgbImage, a: DVec2, b: DVec2, colour: [u8; 3]) {
    let steps = (b - a).length().ceil().max(1.0) as usize;
    for i in 0..=steps {
        let p = a + (b - a) * (i as f64 / steps as f64);
        let (x, y) = (p.x.round(), p.y.round());
        if x >= 0.0 && y >= 0.0 && (x as u32) < img.width() && (y as u32) < img.height() {
            img.put_pixel(x as u32, y as u32, image::Rgb(colour));
        }
    }
}

/// Picture of the reprojection residuals (×RESIDUAL_GAIN) of the DLT (red) and LM (blue) cameras.
fn residual_picture(
    problem: &SyntheticCalibration,
    dlt: &Camera,
    lm: &Camera,
    path: &std::path::Path,
) -> Result<(), Box<dyn std::error::Error>> {
    let k = problem.truth.intrinsics;
    let mut img = image::RgbImage::from_pixel(k.width, k.height, image::Rgb([255, 255, 255]));
    for (w, p) in problem.world.iter().zip(&problem.pixels) {
        for (cam, colour) in [(dlt, [220, 40, 40]), (lm, [40, 80, 220])] {
            let q = cam.project(*w)?;
            draw_line(&mut img, *p, *p + (q - *p) * RESIDUAL_GAIN, colour);
        }
        draw_line(
            &mut img,
            *p - DVec2::X * 2.0,
            *p + DVec2::X * 2.0,
            [0, 0, 0],
        );
    }
    img.save(path)?;
    Ok(())
}

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
    let init = dlt(
        &problem.world,
        &problem.pixels,
        params.width,
        params.height,
        1e-3,
    )?;
    residual_picture(
        &problem,
        &init.camera,
        &lm.camera,
        &out.join("residuals.png"),
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
