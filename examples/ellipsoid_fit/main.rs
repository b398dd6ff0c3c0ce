//! Articulated ellipsoid fitting (Fua, Gruen, Plänkers, D'Apuzzo, Thalmann, paper 003 §4.2,
//! §5) on the studio: the procedural performer with bone lengths changed by up to ±10 % from
//! the default skeleton, captured by the studio's `Capture` with three cameras (silhouettes
//! as contour rays), 5,000 noisy points from the limb surface (σ = 5 mm) of which 30 % are
//! gross outliers, and 20 skin markers rendered, detected, triangulated and tracked by the
//! studio's marker chain. The model: the limbs and the end sites (hands, feet, head; the
//! scenario's default; `limbs_only_*`: the limb model, for comparison). The fit starts from
//! the default proportions and a noisy pose (5° per rotation). It is run with IRLS (Tukey;
//! the defaults: a type's robust scale from the observations the previous round kept once
//! that round rejected ≥ 20 % of them, `EllipsoidParams::kept_scale_min_rejected`; per round
//! the points' and rays' rejected fractions and choices in `irls_points_*`, `irls_rays_*`;
//! `scale_all_*`: the scale over all observations in every round) and without (the plain least squares the paper starts
//! from, given the same Levenberg–Marquardt budget: `EllipsoidParams::without_irls`, one
//! round of 6 × 4 = 24 iterations; the `no_irls_*` figures), on frames 0, 5, …, 35 of the
//! fast motion together (shared lengths and widths, a pose per frame: the headline figures,
//! per frame `frameK_*`, and their mean) and on each frame alone (`single_*`,
//! `frameK_single_*`).
//!
//! Also measured (`tracker_inputs_*`): the same fit from what the template tracker has —
//! eight cameras' silhouettes and the visual hull's surface samples as attractors, no
//! markers, no stereo points (`tracker_inputs_irls_*`: the same choice of scale there;
//! `tracker_inputs_scale_kept_*`: the scale from the kept observations in every round).
//!
//! Writes under `out/ellipsoid_fit/`: `ellipsoids.png` (the fitted ellipsoids over each
//! camera's silhouette), `bones.png` (per bone: length error, and the inlier and outlier
//! points each ellipsoid holds), `figures.json` (`per_bone`), `manifest.json`; last stdout
//! line one JSON object. `fit_ms_per_frame` is wall time, `fit_cpu_ms_per_frame` the
//! process's CPU time (all threads) over the same fit.
//!
//! `cargo run --release --example ellipsoid_fit [-- --quick]` (`--quick`: 400 × 300 views;
//! the full run: 800 × 600).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)] // not library code

use std::time::Instant;

use clap::Parser;
use image::{Rgb, RgbImage};
use serde_json::{json, Map, Value};

use dynamic_shapes::core::camera::Camera;
use dynamic_shapes::core::image::Mask;
use dynamic_shapes::core::math::DVec3;
use dynamic_shapes::template::{
    ellipsoid_scenario, fit_ellipsoids, fit_ellipsoids_multi, score_ellipsoids, ContourRayHull,
    ContourRayHullParams, Ellipsoid, EllipsoidModel, EllipsoidMultiFit, EllipsoidObservations,
    EllipsoidParams, EllipsoidScenarioParams, EllipsoidScores, EllipsoidState, ScenarioFrame,
};
use example_kit::plot::{side_by_side, titled, Chart, Series, Style};
use example_kit::{Goal, Headline, Run};

#[derive(Parser)]
struct Cli {
    #[command(flatten)]
    common: example_kit::cli::Common,
}

/// Paints the outline samples of `ellipsoids` seen by `camera` over its silhouette.
fn overlay(camera: &Camera, mask: &Mask, fitted: &[Ellipsoid], plain: &[Ellipsoid]) -> RgbImage {
    let (w, h) = mask.dimensions();
    let mut img = RgbImage::from_fn(w, h, |x, y| {
        if mask.get(x, y) {
            Rgb([150, 150, 150])
        } else {
            Rgb([255, 255, 255])
        }
    });
    let mut dot = |p: DVec3, colour: [u8; 3]| {
        if let Ok(q) = camera.project(p) {
            let (x, y) = (q.x.round() as i64, q.y.round() as i64);
            if x >= 0 && y >= 0 && (x as u32) < w && (y as u32) < h {
                img.put_pixel(x as u32, y as u32, Rgb(colour));
            }
        }
    };
    for (set, colour) in [(plain, [220, 40, 40]), (fitted, [20, 60, 220])] {
        for e in set {
            let side = e.axis.any_orthonormal_vector();
            let up = e.axis.cross(side);
            for i in 0..60 {
                let t = -1.0 + 2.0 * i as f64 / 59.0;
                let r = e.half_width * (1.0 - t * t).max(0.0).sqrt();
                for k in 0..24 {
                    let phi = std::f64::consts::TAU * k as f64 / 24.0;
                    dot(
                        e.centre
                            + e.axis * (t * e.half_length)
                            + (side * phi.cos() + up * phi.sin()) * r,
                        colour,
                    );
                }
            }
        }
    }
    img
}

fn put(figures: &mut Map<String, Value>, prefix: &str, s: &EllipsoidScores) {
    figures.insert(
        format!("{prefix}bone_length_error_mm"),
        json!(s.bone_length_error_mm),
    );
    figures.insert(format!("{prefix}width_error_mm"), json!(s.width_error_mm));
    figures.insert(
        format!("{prefix}joint_angle_error_deg"),
        json!(s.joint_angle_error_deg),
    );
}

/// The IRLS record of the points and the rays (`EllipsoidParams::kept_scale_min_rejected`):
/// per round the fraction the previous round rejected and whether the scale came from the
/// kept ones.
fn irls_figures(figures: &mut Map<String, Value>, prefix: &str, fit: &EllipsoidMultiFit) {
    for (t, kind) in [(0, "points"), (1, "rays")] {
        figures.insert(
            format!("{prefix}irls_{kind}_rejected_fraction"),
            json!(fit.irls_rejected.iter().map(|r| r[t]).collect::<Vec<_>>()),
        );
        figures.insert(
            format!("{prefix}irls_{kind}_scale_from_kept"),
            json!(fit
                .irls_scale_from_kept
                .iter()
                .map(|k| k[t])
                .collect::<Vec<_>>()),
        );
    }
}

/// Mean scores of fitted states against their frames' truth.
fn scores_of(
    model: &EllipsoidModel,
    states: &[EllipsoidState],
    frames: &[ScenarioFrame],
) -> Result<EllipsoidScores, Box<dyn std::error::Error>> {
    let s: Vec<EllipsoidScores> = states
        .iter()
        .zip(frames)
        .map(|(s, f)| score_ellipsoids(model, s, &f.truth))
        .collect::<Result<_, _>>()?;
    Ok(mean_scores(&s))
}

fn mean_scores(s: &[EllipsoidScores]) -> EllipsoidScores {
    let n = s.len() as f64;
    EllipsoidScores {
        bone_length_error_mm: s.iter().map(|x| x.bone_length_error_mm).sum::<f64>() / n,
        width_error_mm: s.iter().map(|x| x.width_error_mm).sum::<f64>() / n,
        joint_angle_error_deg: s.iter().map(|x| x.joint_angle_error_deg).sum::<f64>() / n,
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = Cli::parse();
    let size = if args.common.quick {
        (400, 300)
    } else {
        (800, 600)
    };
    let params = EllipsoidScenarioParams {
        image_size: size,
        frames: vec![0, 5, 10, 15, 20, 25, 30, 35],
        ..EllipsoidScenarioParams::default()
    };
    let mut run = Run::start(
        "ellipsoid_fit",
        &args.common,
        &format!(
            "Articulated ellipsoids (Fua et al. §4.2, §5) fitted to {} points ({:.0} % outliers), \
             {} silhouettes at {}×{} and {} markers; performer bones ±{:.0} % off the default",
            params.points,
            100.0 * params.outlier_fraction,
            params.cameras,
            size.0,
            size.1,
            params.markers,
            100.0 * params.length_spread
        ),
    )?;
    let stage = run.stage("scenario", None);
    let scenario = ellipsoid_scenario(&params)?;
    stage.finish("");
    let model = &scenario.model;
    let mut figures = Map::new();
    // One frame at a time (each frame its own lengths and widths).
    let (mut single_all, mut single_plain_all, mut start_all, mut single_times) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for (k, frame) in params.frames.iter().zip(&scenario.frames) {
        let stage = run.stage(&format!("frame {k} alone"), None);
        let t = Instant::now();
        let fit = fit_ellipsoids(
            model,
            &frame.start,
            &frame.observations,
            &EllipsoidParams::default(),
        )?;
        let fit_ms = t.elapsed().as_secs_f64() * 1e3;
        let plain = fit_ellipsoids(
            model,
            &frame.start,
            &frame.observations,
            &EllipsoidParams::default().without_irls(),
        )?;
        stage.finish(format!("{fit_ms:.0} ms"));
        let single = score_ellipsoids(model, &fit.state, &frame.truth)?;
        let single_plain = score_ellipsoids(model, &plain.state, &frame.truth)?;
        let start = score_ellipsoids(model, &frame.start, &frame.truth)?;
        put(&mut figures, &format!("frame{k}_single_"), &single);
        put(
            &mut figures,
            &format!("frame{k}_single_no_irls_"),
            &single_plain,
        );
        put(&mut figures, &format!("frame{k}_start_"), &start);
        figures.insert(format!("frame{k}_single_fit_ms"), json!(fit_ms));
        single_all.push(single);
        single_plain_all.push(single_plain);
        start_all.push(start);
        single_times.push(fit_ms);
    }
    // All frames at once: shared lengths and widths, a pose per frame (the headline).
    let (starts, obs) = scenario.starts_and_observations();
    let stage = run.stage("all frames together", None);
    let t = Instant::now();
    let cpu = cpu_time::ProcessTime::now();
    let multi = fit_ellipsoids_multi(model, &starts, &obs, &EllipsoidParams::default())?;
    let multi_ms = t.elapsed().as_secs_f64() * 1e3;
    let multi_cpu_ms = cpu.elapsed().as_secs_f64() * 1e3;
    let multi_plain = fit_ellipsoids_multi(
        model,
        &starts,
        &obs,
        &EllipsoidParams::default().without_irls(),
    )?;
    stage.finish(format!("{multi_ms:.0} ms"));
    let (mut robust_all, mut plain_all) = (Vec::new(), Vec::new());
    for (i, (k, frame)) in params.frames.iter().zip(&scenario.frames).enumerate() {
        let r = score_ellipsoids(model, &multi.states[i], &frame.truth)?;
        let p = score_ellipsoids(model, &multi_plain.states[i], &frame.truth)?;
        put(&mut figures, &format!("frame{k}_"), &r);
        put(&mut figures, &format!("frame{k}_no_irls_"), &p);
        figures.insert(
            format!("frame{k}_rejected_points"),
            json!(multi.rejected_points[i]),
        );
        robust_all.push(r);
        plain_all.push(p);
    }
    put(&mut figures, "", &mean_scores(&robust_all));
    put(&mut figures, "no_irls_", &mean_scores(&plain_all));
    irls_figures(&mut figures, "", &multi);
    // The robust scale over all observations in every round (the choice's alternative).
    let scale_all = fit_ellipsoids_multi(
        model,
        &starts,
        &obs,
        &EllipsoidParams {
            kept_scale_min_rejected: None,
            ..EllipsoidParams::default()
        },
    )?;
    put(
        &mut figures,
        "scale_all_",
        &scores_of(model, &scale_all.states, &scenario.frames)?,
    );
    put(&mut figures, "single_", &mean_scores(&single_all));
    put(
        &mut figures,
        "single_no_irls_",
        &mean_scores(&single_plain_all),
    );
    put(&mut figures, "start_", &mean_scores(&start_all));
    figures.insert(
        "fit_ms_per_frame".into(),
        json!(multi_ms / params.frames.len() as f64),
    );
    figures.insert(
        "fit_cpu_ms_per_frame".into(),
        json!(multi_cpu_ms / params.frames.len() as f64),
    );
    // Per bone: length error, widths, and the points each ellipsoid holds at the end (the
    // last `outlier_fraction` of every frame's points are the gross outliers).
    let n_in = params.points - (params.points as f64 * params.outlier_fraction).round() as usize;
    let nb = model.bones().len();
    let (mut inliers, mut outliers) = (vec![0usize; nb], vec![0usize; nb]);
    for frame_bones in &multi.point_bones {
        for (i, b) in frame_bones.iter().enumerate() {
            if let Some(b) = *b {
                if i < n_in {
                    inliers[b] += 1;
                } else {
                    outliers[b] += 1;
                }
            }
        }
    }
    let fitted_l = model.bone_lengths(&multi.states[0]);
    let true_l = model.bone_lengths(&scenario.frames[0].truth);
    let sk = model.skeleton();
    let names: Vec<String> = model
        .bones()
        .iter()
        .map(|b| match b.child {
            Some(c) => format!("{}-{}", sk.joints()[b.parent].name, sk.joints()[c].name),
            None => format!("{} end", sk.joints()[b.parent].name),
        })
        .collect();
    let per_bone: Map<String, Value> = (0..nb)
        .map(|b| {
            (
                names[b].clone(),
                json!({
                    "index": b,
                    "length_error_mm": 1e3 * (fitted_l[b] - true_l[b]),
                    "half_width_mm": 1e3 * multi.states[0].half_width[b],
                    "reference_half_width_mm": 1e3 * scenario.frames[0].truth.half_width[b],
                    "inlier_points": inliers[b],
                    "outlier_points": outliers[b],
                }),
            )
        })
        .collect();
    figures.insert("per_bone".into(), Value::Object(per_bone));
    // Bars 0.3 wide, drawn as vertical segments.
    let bars = |v: &[f64], dx: f64| -> Vec<(f64, f64)> {
        v.iter()
            .enumerate()
            .flat_map(|(b, y)| {
                (0..13).flat_map(move |k| {
                    let x = b as f64 + dx + 0.025 * (k as f64 - 6.0);
                    [(x, 0.0), (x, *y)]
                })
            })
            .collect()
    };
    let lengths_chart = Chart::new(
        "Fitted − true bone length (8-frame fit, IRLS)",
        "bone index (names: figures.json per_bone; ≥ 9: end sites, scale held)",
        "length error (mm)",
    )
    .with(Series::new(
        "fitted − true",
        [20, 60, 220],
        Style::Segments,
        bars(
            &(0..nb)
                .map(|b| 1e3 * (fitted_l[b] - true_l[b]))
                .collect::<Vec<_>>(),
            0.0,
        ),
    ));
    let points_chart = Chart::new(
        "Points each ellipsoid holds at the end (8 frames)",
        "bone index",
        "points with non-zero weight",
    )
    .with(Series::new(
        "inliers (true surface)",
        [20, 60, 220],
        Style::Segments,
        bars(&inliers.iter().map(|&n| n as f64).collect::<Vec<_>>(), 0.0),
    ));
    let outliers_chart = Chart::new(
        "Gross outliers each ellipsoid holds at the end (8 frames)",
        "bone index",
        "outliers with non-zero weight (of 1,500 per frame)",
    )
    .with(Series::new(
        "gross outliers",
        [220, 40, 40],
        Style::Segments,
        bars(&outliers.iter().map(|&n| n as f64).collect::<Vec<_>>(), 0.0),
    ));
    run.save_picture(
        "bones.png",
        &side_by_side(&[
            lengths_chart.draw()?,
            points_chart.draw()?,
            outliers_chart.draw()?,
        ])?,
        "per bone: length error and the inlier / outlier points each ellipsoid holds",
    )?;
    // The limb model alone (no end sites), same protocol: the baseline for the lengths.
    let limbs = ellipsoid_scenario(&EllipsoidScenarioParams {
        end_sites: false,
        ..params.clone()
    })?;
    let (limb_starts, limb_obs) = limbs.starts_and_observations();
    let limb_fit = fit_ellipsoids_multi(
        &limbs.model,
        &limb_starts,
        &limb_obs,
        &EllipsoidParams::default(),
    )?;
    let limb_scores: Vec<EllipsoidScores> = limb_fit
        .states
        .iter()
        .zip(&limbs.frames)
        .map(|(s, f)| score_ellipsoids(&limbs.model, s, &f.truth))
        .collect::<Result<_, _>>()?;
    put(&mut figures, "limbs_only_", &mean_scores(&limb_scores));
    figures.insert(
        "single_fit_ms_per_frame".into(),
        json!(single_times.iter().sum::<f64>() / single_times.len() as f64),
    );
    figures.insert("irls_round_costs".into(), json!(multi.round_costs));
    figures.insert(
        "fitted_bone_lengths_m".into(),
        json!(model.bone_lengths(&multi.states[0])),
    );
    figures.insert(
        "fitted_half_widths_m".into(),
        json!(multi.states[0].half_width),
    );
    figures.insert("frames".into(), json!(params.frames));
    figures.insert(
        "marker_id_switches".into(),
        json!(scenario.marker_id_switches),
    );
    // What the template tracker has (§2.3.2 of Vlasic): 8 cameras' silhouettes and the
    // visual hull's surface as attractors; no markers, no stereo points. Same truth and start.
    let stage = run.stage("tracker inputs (8 cameras, hull, silhouettes)", None);
    let hull_scenario = ellipsoid_scenario(&EllipsoidScenarioParams {
        cameras: 8,
        markers: 0,
        ..params.clone()
    })?;
    let hull_model = &hull_scenario.model;
    let (hull_starts, _) = hull_scenario.starts_and_observations();
    let hull_obs: Vec<EllipsoidObservations> = hull_scenario
        .frames
        .iter()
        .map(
            |f| -> Result<EllipsoidObservations, Box<dyn std::error::Error>> {
                let hull = ContourRayHull::new(
                    &hull_scenario.cameras,
                    &f.masks,
                    &ContourRayHullParams::default(),
                )?;
                let v = &hull.polygon().vertices;
                let step = v.len().div_ceil(params.points).max(1);
                Ok(EllipsoidObservations {
                    points: v.iter().step_by(step).copied().collect(),
                    markers: Vec::new(),
                    rays: f.observations.rays.clone(),
                })
            },
        )
        .collect::<Result<_, _>>()?;
    let t = Instant::now();
    // Hull samples lie outside the body by the hull's excess: σ 2 cm (measured: widths 14 vs
    // 27 mm and directions 11° vs 13° with the stereo points' 5 mm).
    let hull_params = EllipsoidParams {
        sigma_point_m: 0.02,
        ..EllipsoidParams::default()
    };
    let hull_fit = fit_ellipsoids_multi(hull_model, &hull_starts, &hull_obs, &hull_params)?;
    let hull_ms = t.elapsed().as_secs_f64() * 1e3;
    stage.finish(format!("{hull_ms:.0} ms"));
    let hull_scores: Vec<EllipsoidScores> = hull_fit
        .states
        .iter()
        .zip(&hull_scenario.frames)
        .map(|(s, f)| score_ellipsoids(hull_model, s, &f.truth))
        .collect::<Result<_, _>>()?;
    put(&mut figures, "tracker_inputs_", &mean_scores(&hull_scores));
    irls_figures(&mut figures, "tracker_inputs_", &hull_fit);
    // The scale from the kept observations in every round (the choice's alternative).
    let hull_kept = fit_ellipsoids_multi(
        hull_model,
        &hull_starts,
        &hull_obs,
        &EllipsoidParams {
            kept_scale_min_rejected: Some(0.0),
            ..hull_params.clone()
        },
    )?;
    put(
        &mut figures,
        "tracker_inputs_scale_kept_",
        &scores_of(hull_model, &hull_kept.states, &hull_scenario.frames)?,
    );
    figures.insert(
        "tracker_inputs_fit_ms_per_frame".into(),
        json!(hull_ms / params.frames.len() as f64),
    );
    figures.insert(
        "tracker_inputs_points".into(),
        json!(hull_obs.first().map_or(0, |o| o.points.len())),
    );
    figures.insert(
        "tracker_inputs_rays".into(),
        json!(hull_obs.first().map_or(0, |o| o.rays.len())),
    );
    figures.insert(
        "tracker_inputs_fitted_bone_lengths_m".into(),
        json!(hull_model.bone_lengths(&hull_fit.states[0])),
    );
    // An automatic start, no user input: the rest pose (θ = 0) moved to each hull's centroid,
    // default proportions, half-widths 5 cm (the pose tracker's first-frame initialisation).
    let stage = run.stage("tracker inputs from the rest pose", None);
    let rest_starts: Vec<EllipsoidState> = hull_obs
        .iter()
        .map(|o| {
            let n = o.points.len().max(1) as f64;
            let centroid = o.points.iter().fold(DVec3::ZERO, |a, p| a + *p) / n;
            let root = hull_model.skeleton().joints()[0].offset;
            let mut theta = vec![0.0; hull_model.skeleton().dof_count()];
            // The root's first three DOFs are its translations (x, y, z).
            theta[..3].copy_from_slice(&(centroid - root).to_array());
            hull_model.initial_state(&theta, 0.05)
        })
        .collect::<Result<_, _>>()?;
    let t = Instant::now();
    let rest_fit = fit_ellipsoids_multi(hull_model, &rest_starts, &hull_obs, &hull_params)?;
    stage.finish(format!("{:.0} ms", t.elapsed().as_secs_f64() * 1e3));
    let rest_scores: Vec<EllipsoidScores> = rest_fit
        .states
        .iter()
        .zip(&hull_scenario.frames)
        .map(|(s, f)| score_ellipsoids(hull_model, s, &f.truth))
        .collect::<Result<_, _>>()?;
    put(
        &mut figures,
        "tracker_inputs_from_rest_",
        &mean_scores(&rest_scores),
    );
    irls_figures(&mut figures, "tracker_inputs_from_rest_", &rest_fit);
    // The picture: the most bent frame of the protocol (frame 10).
    let shown = params.frames.len().min(3) - 1;
    let frame = &scenario.frames[shown];
    figures.insert("points".into(), json!(frame.observations.points.len()));
    figures.insert(
        "silhouette_rays".into(),
        json!(frame.observations.rays.len()),
    );
    figures.insert("markers".into(), json!(frame.observations.markers.len()));
    figures.insert(
        "true_bone_lengths_m".into(),
        json!(model.bone_lengths(&frame.truth)),
    );
    figures.insert(
        "reference_half_widths_m".into(),
        json!(frame.truth.half_width),
    );
    figures.insert("image_width_px".into(), json!(size.0));
    figures.insert("image_height_px".into(), json!(size.1));

    let fitted = model.ellipsoids(&multi.states[shown])?;
    let plain_e = model.ellipsoids(&multi_plain.states[shown])?;
    let panels: Vec<RgbImage> = scenario
        .cameras
        .iter()
        .zip(&frame.masks)
        .enumerate()
        .map(|(c, (cam, mask))| {
            titled(
                &overlay(cam, mask, &fitted, &plain_e),
                &format!("camera {c}"),
                None,
            )
        })
        .collect::<Result<_, _>>()?;
    let img = titled(
        &side_by_side(&panels)?,
        &format!(
            "Fitted ellipsoids over the silhouettes (grey), frame {} of a {}-frame fit",
            params.frames[shown],
            params.frames.len()
        ),
        Some("blue: joint least squares with IRLS; red: without IRLS (same start, same data)"),
    )?;
    run.save_picture(
        "ellipsoids.png",
        &img,
        "fitted ellipsoids over each camera's silhouette",
    )?;
    for h in [
        Headline::new("bone_length_error_mm", "bone length error", "mm").goal(Goal::AtMost(10.0)),
        Headline::new(
            "width_error_mm",
            "half-width error (vs Eq. 3 fit to the limb)",
            "mm",
        )
        .goal(Goal::AtMost(5.0)),
        Headline::new(
            "joint_angle_error_deg",
            "bone direction error (twist excluded)",
            "°",
        )
        .goal(Goal::AtMost(3.0)),
        Headline::new(
            "no_irls_width_error_mm",
            "half-width error without IRLS",
            "mm",
        )
        .baseline(),
        Headline::new(
            "no_irls_joint_angle_error_deg",
            "bone direction error without IRLS",
            "°",
        )
        .baseline(),
        Headline::new(
            "fit_ms_per_frame",
            "fit time per frame (eight-frame fit)",
            "ms",
        )
        .goal(Goal::AtMost(50.0)),
        Headline::new(
            "fit_cpu_ms_per_frame",
            "fit CPU time per frame, all threads (eight-frame fit)",
            "ms",
        ),
        Headline::new(
            "no_irls_bone_length_error_mm",
            "bone length error without IRLS",
            "mm",
        )
        .baseline(),
        Headline::new(
            "limbs_only_bone_length_error_mm",
            "bone length error, limb model (no end sites)",
            "mm",
        )
        .baseline(),
        Headline::new("single_fit_ms_per_frame", "fit time, one frame alone", "ms").baseline(),
        Headline::new(
            "single_joint_angle_error_deg",
            "bone direction error, each frame alone",
            "°",
        )
        .baseline(),
    ] {
        run.headline(h);
    }
    run.finish(Value::Object(figures))?;
    Ok(())
}
