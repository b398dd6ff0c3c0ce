//! Articulated ellipsoid fitting (Fua et al., paper 003 §4.2, §5) on the studio: a performer
//! whose bone lengths differ from the default skeleton by up to 10 %, three cameras, 5,000
//! noisy points (σ = 5 mm) with 30 % gross outliers, silhouettes and 20 markers, at four
//! frames of the fast motion. Accuracy against ground truth, and against the same fit
//! without IRLS (the baseline that could have won); speed is printed, not asserted.
//!
//! Asserted is what the method achieves here: on every frame IRLS rejects most gross
//! outliers and is ≥ 1.5× better than the unweighted fit; at frame 0 (limbs nearly straight)
//! the widths are within 5 mm and the bone directions within 3°. NOT met, printed: the bone
//! lengths (≈ 120 mm off: a straight chain's inner joint slides along the limb), and the
//! widths and directions at the bent frames 5, 10, 30 (tens of mm and 10–30°, even from the
//! true pose: the fit drifts away from it) — see docs/template-silhouette.md.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)] // not library code

use std::time::Instant;

use dynamic_shapes::template::{
    ellipsoid_scenario, fit_ellipsoids, score_ellipsoids, EllipsoidParams, EllipsoidScenarioParams,
    EllipsoidScores,
};

fn worse_by(plain: &EllipsoidScores, robust: &EllipsoidScores) -> f64 {
    (plain.bone_length_error_mm / robust.bone_length_error_mm)
        .max(plain.width_error_mm / robust.width_error_mm)
        .max(plain.joint_angle_error_deg / robust.joint_angle_error_deg)
}

#[test]
fn ellipsoid_fit_irls_rejects_outliers_and_beats_plain_least_squares() {
    let frames = vec![0, 5, 10, 30];
    let scenario = ellipsoid_scenario(&EllipsoidScenarioParams {
        frames: frames.clone(),
        ..EllipsoidScenarioParams::default()
    })
    .unwrap();
    for (k, frame) in frames.iter().zip(&scenario.frames) {
        let t = Instant::now();
        let fit = fit_ellipsoids(
            &scenario.model,
            &frame.start,
            &frame.observations,
            &EllipsoidParams::default(),
        )
        .unwrap();
        let ms = t.elapsed().as_secs_f64() * 1e3;
        let r = score_ellipsoids(&scenario.model, &fit.state, &frame.truth).unwrap();
        let start = score_ellipsoids(&scenario.model, &frame.start, &frame.truth).unwrap();
        println!("frame {k}: fit {ms:.0} ms, IRLS {r:?}, start {start:?}");
        assert!(
            fit.rejected_points >= 1000,
            "frame {k}: rejected {} of 1500 outliers",
            fit.rejected_points
        );
        if *k == 0 {
            assert!(r.width_error_mm <= 5.0, "{r:?}");
            assert!(r.joint_angle_error_deg <= 3.0, "{r:?}");
        }
        // The baseline: the same least squares without reweighting (an outright failure,
        // e.g. a collapsed ellipsoid, counts as worse).
        match fit_ellipsoids(
            &scenario.model,
            &frame.start,
            &frame.observations,
            &EllipsoidParams::default().with_irls_rounds(1),
        ) {
            Ok(f) => {
                let p = score_ellipsoids(&scenario.model, &f.state, &frame.truth).unwrap();
                println!("frame {k}: without IRLS {p:?}");
                let w = worse_by(&p, &r);
                assert!(w >= 1.5, "frame {k}: without IRLS only {w:.2}x worse");
            }
            Err(e) => println!("frame {k}: plain fit failed: {e}"),
        }
    }
}
