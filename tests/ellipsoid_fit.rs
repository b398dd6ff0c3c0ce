//! Articulated ellipsoid fitting (Fua et al., paper 003 §4.2, §5) on the studio: a performer
//! whose bone lengths differ from the default skeleton by up to 10 %, three cameras, 5,000
//! noisy points (σ = 5 mm) with 30 % gross outliers, silhouettes and 20 markers, at frames of
//! the fast motion (0: rest; the others bent). The fit starts from the default
//! proportions and the true pose with 5° Gaussian noise per rotation. Accuracy against ground
//! truth, and against the same fit without IRLS given the same Levenberg–Marquardt budget
//! (`EllipsoidParams::without_irls`: 24 iterations, the IRLS fit's 6 rounds × 4; the baseline
//! that could have won); speed is printed, not asserted.
//!
//! The model is the limbs plus the end sites (hands, feet, head; the scenario's default).
//!
//! Asserted is what the method achieves here: on every frame IRLS rejects most gross
//! outliers and is better than the unweighted fit on every figure, ≥ 1.5× on one; the fit
//! over frames 0, 5, …, 35 together (shared lengths and widths, a pose per frame) meets the
//! length goal (≤ 10 mm mean), the width goal (≤ 5 mm) and the mean direction goal (≤ 3°; no
//! frame above 5°) and beats its unweighted version the same way (same model, same data,
//! same budget); the end sites beat the limb model's lengths (the baseline that could have
//! won). See docs/template-silhouette.md.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)] // not library code

use std::time::Instant;

use dynamic_shapes::template::{
    ellipsoid_scenario, fit_ellipsoids, fit_ellipsoids_multi, score_ellipsoids, EllipsoidParams,
    EllipsoidScenario, EllipsoidScenarioParams, EllipsoidScores,
};

fn worse_by(plain: &EllipsoidScores, robust: &EllipsoidScores) -> f64 {
    (plain.bone_length_error_mm / robust.bone_length_error_mm)
        .max(plain.width_error_mm / robust.width_error_mm)
        .max(plain.joint_angle_error_deg / robust.joint_angle_error_deg)
}

/// IRLS lower than the plain fit on all three figures.
fn better_on_every_figure(plain: &EllipsoidScores, robust: &EllipsoidScores) -> bool {
    robust.bone_length_error_mm < plain.bone_length_error_mm
        && robust.width_error_mm < plain.width_error_mm
        && robust.joint_angle_error_deg < plain.joint_angle_error_deg
}

fn scenario(frames: &[usize]) -> EllipsoidScenario {
    ellipsoid_scenario(&EllipsoidScenarioParams {
        frames: frames.to_vec(),
        ..EllipsoidScenarioParams::default()
    })
    .unwrap()
}

#[test]
fn ellipsoid_fit_irls_rejects_outliers_and_beats_plain_least_squares() {
    let frames = [0, 5, 10, 30];
    let scenario = scenario(&frames);
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
        // The baseline: the same least squares without reweighting (an outright failure,
        // e.g. a collapsed ellipsoid, counts as worse).
        match fit_ellipsoids(
            &scenario.model,
            &frame.start,
            &frame.observations,
            &EllipsoidParams::default().without_irls(),
        ) {
            Ok(f) => {
                let p = score_ellipsoids(&scenario.model, &f.state, &frame.truth).unwrap();
                println!("frame {k}: without IRLS {p:?}");
                let w = worse_by(&p, &r);
                assert!(w >= 1.5, "frame {k}: without IRLS only {w:.2}x worse");
                assert!(better_on_every_figure(&p, &r), "frame {k}: {p:?} vs {r:?}");
            }
            Err(e) => println!("frame {k}: plain fit failed: {e}"),
        }
    }
}

#[test]
fn ellipsoid_multi_frame_fit_meets_length_width_and_direction_goals() {
    let frames = [0, 5, 10, 15, 20, 25, 30, 35];
    let scenario = scenario(&frames);
    let (starts, obs) = scenario.starts_and_observations();
    let t = Instant::now();
    let fit =
        fit_ellipsoids_multi(&scenario.model, &starts, &obs, &EllipsoidParams::default()).unwrap();
    let ms = t.elapsed().as_secs_f64() * 1e3 / frames.len() as f64;
    println!("{}-frame fit: {ms:.0} ms per frame", frames.len());
    let plain = fit_ellipsoids_multi(
        &scenario.model,
        &starts,
        &obs,
        &EllipsoidParams::default().without_irls(),
    );
    let m = &scenario.model;
    let fl = m.bone_lengths(&fit.states[0]);
    let tl = m.bone_lengths(&scenario.frames[0].truth);
    for (b, bone) in m.bones().iter().enumerate() {
        println!(
            "{} -> {:?}: fitted - true length {:+.1} mm, half-width {:.1} vs {:.1} mm, {} \
             observations",
            m.skeleton().joints()[bone.parent].name,
            bone.child.map(|c| m.skeleton().joints()[c].name.clone()),
            1e3 * (fl[b] - tl[b]),
            1e3 * fit.states[0].half_width[b],
            1e3 * scenario.frames[0].truth.half_width[b],
            fit.observations_per_bone[b]
        );
    }
    let (mut mean_angle, mut mean_length) = (0.0, 0.0);
    for (i, (k, frame)) in frames.iter().zip(&scenario.frames).enumerate() {
        let r = score_ellipsoids(&scenario.model, &fit.states[i], &frame.truth).unwrap();
        println!("frame {k}: {r:?}");
        assert!(r.width_error_mm <= 5.0, "frame {k}: {r:?}");
        assert!(r.joint_angle_error_deg <= 5.0, "frame {k}: {r:?}");
        mean_angle += r.joint_angle_error_deg / frames.len() as f64;
        mean_length += r.bone_length_error_mm / frames.len() as f64;
        assert!(fit.rejected_points[i] >= 1000, "frame {k}");
        // Shared unknowns are shared.
        assert_eq!(fit.states[i].length_scale, fit.states[0].length_scale);
        assert_eq!(fit.states[i].half_width, fit.states[0].half_width);
        match &plain {
            Ok(p) => {
                let p = score_ellipsoids(&scenario.model, &p.states[i], &frame.truth).unwrap();
                println!("frame {k}: without IRLS {p:?}");
                let w = worse_by(&p, &r);
                assert!(w >= 1.5, "frame {k}: without IRLS only {w:.2}x worse");
                assert!(better_on_every_figure(&p, &r), "frame {k}: {p:?} vs {r:?}");
            }
            Err(e) => println!("plain multi-frame fit failed: {e}"),
        }
    }
    assert!(mean_angle <= 3.0, "mean direction error {mean_angle:.2}°");
    assert!(mean_length <= 10.0, "mean length error {mean_length:.1} mm");
    // The points' robust scale: from the kept observations once a round rejects ≥ 20 % of
    // them (every round after the first here: the 30 % gross outliers), against the baseline
    // that could have won, the scale over all of them in every round (the MAD of Beaton and
    // Tukey, inflated by the outliers).
    println!(
        "points rejected per round {:?}, scale from the kept {:?}",
        fit.irls_rejected.iter().map(|r| r[0]).collect::<Vec<_>>(),
        fit.irls_scale_from_kept
            .iter()
            .map(|k| k[0])
            .collect::<Vec<_>>()
    );
    assert!(fit.irls_scale_from_kept[1..].iter().all(|k| k[0]));
    let all = fit_ellipsoids_multi(
        &scenario.model,
        &starts,
        &obs,
        &EllipsoidParams {
            kept_scale_min_rejected: None,
            ..EllipsoidParams::default()
        },
    )
    .unwrap();
    let all_length = frames
        .iter()
        .zip(&scenario.frames)
        .zip(&all.states)
        .map(|((_, f), st)| {
            score_ellipsoids(&scenario.model, st, &f.truth)
                .unwrap()
                .bone_length_error_mm
        })
        .sum::<f64>()
        / frames.len() as f64;
    println!("scale over all observations: mean length error {all_length:.1} mm");
    assert!(
        mean_length < all_length,
        "lengths {mean_length:.1} mm, with the scale over all {all_length:.1} mm"
    );
}

/// The chain-end bones (forearms, shins) with data beyond them: the 8-frame fit with the
/// end-site model (the default: hands, feet, head, their length scales held at 1 by
/// `sigma_end_site_scale_prior`) against the limb model's fit (the baseline that could have
/// won), same data otherwise.
#[test]
fn ellipsoid_multi_frame_fit_with_end_sites_improves_lengths() {
    let frames = vec![0, 5, 10, 15, 20, 25, 30, 35];
    let fit_with = |end_sites: bool| {
        let scenario = ellipsoid_scenario(&EllipsoidScenarioParams {
            frames: frames.clone(),
            end_sites,
            ..EllipsoidScenarioParams::default()
        })
        .unwrap();
        let (starts, obs) = scenario.starts_and_observations();
        let m = &scenario.model;
        let fit = fit_ellipsoids_multi(m, &starts, &obs, &EllipsoidParams::default()).unwrap();
        let s: Vec<EllipsoidScores> = scenario
            .frames
            .iter()
            .zip(&fit.states)
            .map(|(f, st)| score_ellipsoids(m, st, &f.truth).unwrap())
            .collect();
        let n = s.len() as f64;
        let mean = |g: fn(&EllipsoidScores) -> f64| s.iter().map(g).sum::<f64>() / n;
        (
            mean(|x| x.bone_length_error_mm),
            mean(|x| x.width_error_mm),
            mean(|x| x.joint_angle_error_deg),
        )
    };
    let (el, ew, ed) = fit_with(true);
    let (ll, lw, ld) = fit_with(false);
    println!(
        "8-frame fit, end sites: lengths {el:.1} mm widths {ew:.2} mm directions {ed:.2} deg; \
         limbs only: {ll:.1} / {lw:.2} / {ld:.2}"
    );
    assert!(el < ll, "lengths {el} vs {ll}");
    assert!(
        el <= 10.0 && ew <= 5.0 && ed <= 3.0,
        "{el} mm, {ew} mm, {ed} deg"
    );
}
