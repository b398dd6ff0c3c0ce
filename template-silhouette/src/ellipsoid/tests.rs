use super::fit::{FrameData, Normal, Problem};
use super::*;
use crate::error::{Context, Error};
use crate::silhouette_constraints::ContourRay;
use nalgebra::{DMatrix, DVector};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use skin_core::math::DVec3;
use skin_core::skeleton::{human_skeleton, HumanParams};

fn model() -> EllipsoidModel {
    let sk = human_skeleton(&HumanParams::default()).unwrap();
    EllipsoidModel::limbs(sk, 0.1).unwrap()
}

fn posed(m: &EllipsoidModel, rng: &mut ChaCha8Rng) -> EllipsoidState {
    let nd = m.skeleton().dof_count();
    let theta: Vec<f64> = (0..nd).map(|_| rng.random_range(-0.3..0.3)).collect();
    let mut s = m.initial_state(&theta, 0.05).unwrap();
    for b in 0..s.length_scale.len() {
        s.length_scale[b] = rng.random_range(0.9..1.1);
        s.half_width[b] = rng.random_range(0.03..0.08);
        s.half_length[b] =
            rng.random_range(0.8..1.2) * 0.5 * s.length_scale[b] * m.default_lengths()[b];
    }
    s
}

/// Points on the surfaces of the ellipsoids of `state`.
fn surface(
    m: &EllipsoidModel,
    state: &EllipsoidState,
    per: usize,
    rng: &mut ChaCha8Rng,
) -> Vec<DVec3> {
    let mut out = Vec::new();
    for e in m.ellipsoids(state).unwrap() {
        let side = e.axis.any_orthonormal_vector();
        let up = e.axis.cross(side);
        for _ in 0..per {
            let t: f64 = rng.random_range(-0.95..0.95);
            let phi: f64 = rng.random_range(0.0..std::f64::consts::TAU);
            let r = e.half_width * (1.0 - t * t).sqrt();
            out.push(
                e.centre + e.axis * (t * e.half_length) + (side * phi.cos() + up * phi.sin()) * r,
            );
        }
    }
    out
}

#[test]
fn ellipsoids_span_their_bones() {
    let m = model();
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let s = posed(&m, &mut rng);
    let fk = m
        .scaled_skeleton(&s)
        .unwrap()
        .forward_kinematics(&s.theta)
        .unwrap();
    let joints = fk.joint_positions();
    for (e, bone) in m.ellipsoids(&s).unwrap().iter().zip(m.bones()) {
        let child = bone.child.unwrap();
        let mid = 0.5 * (joints[bone.parent] + joints[child]);
        assert!(e.centre.distance(mid) < 1e-12);
        assert!((2.0 * e.half_bone - joints[bone.parent].distance(joints[child])).abs() < 1e-12);
    }
}

#[test]
fn analytic_gradient_matches_finite_differences() {
    let m = model();
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let truth = posed(&m, &mut rng);
    let mut pts = surface(&m, &truth, 20, &mut rng);
    for p in &mut pts {
        *p += DVec3::new(
            rng.random_range(-0.01..0.01),
            0.0,
            rng.random_range(-0.01..0.01),
        );
    }
    let rays: Vec<ContourRay> = pts
        .iter()
        .take(30)
        .map(|&p| {
            let origin = DVec3::new(0.0, 1.0, 4.0);
            let direction = (p + DVec3::new(0.02, 0.0, 0.0) - origin).normalize();
            ContourRay {
                origin,
                direction,
                normal: direction.any_orthonormal_vector(),
            }
        })
        .collect();
    let obs = EllipsoidObservations {
        points: pts,
        markers: vec![MarkerObservation {
            bone: 2,
            position: Some(DVec3::new(0.1, 1.0, 0.1)),
        }],
        rays,
    };
    let params = EllipsoidParams::default();
    // Two frames sharing lengths and widths, each with its own pose (the multi-frame layout).
    let mut second = truth.clone();
    second.theta[7] += 0.2;
    second.theta[20] -= 0.3;
    let states = vec![truth.clone(), second];
    fn frame<'a>(obs: &'a EllipsoidObservations, s: &'a EllipsoidState) -> FrameData<'a> {
        let mut f = FrameData {
            obs,
            start_theta: &s.theta,
            markers: vec![(2, DVec3::new(0.1, 1.0, 0.1))],
            robust: Vec::new(),
            candidates: Vec::new(),
        };
        f.robust = vec![1.0; f.n_obs()];
        f
    }
    let starts: Vec<EllipsoidState> = states
        .iter()
        .map(|s| {
            let mut s = s.clone();
            s.theta[7] += 0.1;
            s
        })
        .collect();
    let mut problem = Problem {
        model: &m,
        params: &params,
        start: &starts[0],
        frames: starts.iter().map(|s| frame(&obs, s)).collect(),
    };
    problem.assign(&states).unwrap();
    let (cost, normal) = problem.linearise(&states, true).unwrap();
    let g = normal.unwrap().gradient();
    let nd = truth.theta.len();
    let nb = truth.half_width.len();
    let mut worst: f64 = 0.0;
    for k in 0..2 * nd + 3 * nb {
        let h = 1e-6;
        let shifted = |d: f64| {
            let mut ss = states.clone();
            for (f, s) in ss.iter_mut().enumerate() {
                if k < 2 * nd {
                    if k / nd == f {
                        s.theta[k % nd] += d;
                    }
                } else if k < 2 * nd + nb {
                    s.length_scale[k - 2 * nd] += d;
                } else if k < 2 * nd + 2 * nb {
                    s.half_width[k - 2 * nd - nb] += d;
                } else {
                    s.half_length[k - 2 * nd - 2 * nb] += d;
                }
            }
            problem.linearise(&ss, false).unwrap().0
        };
        let fd = (shifted(h) - shifted(-h)) / (2.0 * h);
        let an = 2.0 * g[k];
        // Central differences of a cost of size C carry a round-off of about C·1e-16/h.
        let rel = ((fd - an).abs() - 10.0 * cost * f64::EPSILON / h).max(0.0) / (1.0 + an.abs());
        worst = worst.max(rel);
    }
    assert!(worst < 1e-4, "worst relative gradient error {worst}");
}

#[test]
fn recovers_lengths_widths_and_pose_with_outliers_only_with_irls() {
    let m = model();
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let truth = posed(&m, &mut rng);
    let mut pts = surface(&m, &truth, 150, &mut rng);
    let n_in = pts.len();
    for _ in 0..(n_in * 3 / 7) {
        pts.push(DVec3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(0.0..2.0),
            rng.random_range(-1.0..1.0),
        ));
    }
    let mut start = m
        .initial_state(
            &truth
                .theta
                .iter()
                .map(|t| t + rng.random_range(-0.05..0.05))
                .collect::<Vec<_>>(),
            0.05,
        )
        .unwrap();
    start.theta[..3].copy_from_slice(&truth.theta[..3]);
    let obs = EllipsoidObservations {
        points: pts,
        ..Default::default()
    };
    let err = |fit: &EllipsoidFit| {
        let lt = m.bone_lengths(&truth);
        let lf = m.bone_lengths(&fit.state);
        let n = lt.len() as f64;
        let dl = lt.iter().zip(&lf).map(|(a, b)| (a - b).abs()).sum::<f64>() / n;
        let dw = truth
            .half_width
            .iter()
            .zip(&fit.state.half_width)
            .map(|(a, b)| (a - b).abs())
            .sum::<f64>()
            / n;
        (dl, dw)
    };
    // Synthetic data are true ellipsoids: their half-lengths are observable, so free them.
    let params = EllipsoidParams {
        sigma_half_length_prior_m: 0.1,
        ..EllipsoidParams::default()
    };
    let robust = fit_ellipsoids(&m, &start, &obs, &params).unwrap();
    let plain = fit_ellipsoids(&m, &start, &obs, &params.clone().without_irls());
    let (dl, dw) = err(&robust);
    assert!(
        dl < 0.005 && dw < 0.003,
        "IRLS: length {dl} m, width {dw} m"
    );
    // Without IRLS either the fit is much worse or an ellipsoid collapses / loses its points.
    if let Ok(plain) = plain {
        let (pl, pw) = err(&plain);
        assert!(
            pl + pw > 2.0 * (dl + dw),
            "plain {pl} {pw} vs IRLS {dl} {dw}"
        );
    }
    assert!(robust.rejected_points >= n_in * 3 / 7 / 2);
    // 30 % gross outliers: after the first round the points' scale comes from the kept ones.
    let points_kept: Vec<bool> = robust.irls_scale_from_kept.iter().map(|k| k[0]).collect();
    assert_eq!(points_kept.len(), EllipsoidParams::default().irls_rounds);
    assert!(
        !points_kept[0] && points_kept[1..].iter().all(|k| *k),
        "{points_kept:?}"
    );
}

/// A one-sided error without gross outliers (every point pushed off its ellipsoid, away from
/// the bone, by a half-normal distance, as visual-hull samples lie outside the body): the
/// rounds reject far less than the threshold, so the scale stays over all points.
#[test]
fn a_one_sided_error_keeps_the_scale_over_all_points() {
    let m = model();
    let mut rng = ChaCha8Rng::seed_from_u64(6);
    let truth = posed(&m, &mut rng);
    let ells = m.ellipsoids(&truth).unwrap();
    let per = 150;
    let mut pts = surface(&m, &truth, per, &mut rng);
    for (i, p) in pts.iter_mut().enumerate() {
        let e = &ells[i / per];
        let radial = (*p - e.centre) - e.axis * (*p - e.centre).dot(e.axis);
        // |N(0, 1 cm)| by Box–Muller.
        let (u1, u2) = (
            rng.random_range(1e-12f64..1.0),
            rng.random_range(0.0..std::f64::consts::TAU),
        );
        let off = 0.01 * ((-2.0 * u1.ln()).sqrt() * u2.cos()).abs();
        *p += radial.normalize_or_zero() * off;
    }
    let start = m.initial_state(&truth.theta, 0.05).unwrap();
    let obs = EllipsoidObservations {
        points: pts,
        ..Default::default()
    };
    let fit = fit_ellipsoids(&m, &start, &obs, &EllipsoidParams::default()).unwrap();
    let rejected: Vec<f64> = fit.irls_rejected.iter().map(|r| r[0]).collect();
    let min = EllipsoidParams::default()
        .kept_scale_min_rejected
        .unwrap_or(1.0);
    assert!(rejected.iter().all(|f| *f < min), "{rejected:?}");
    assert!(fit.irls_scale_from_kept.iter().all(|k| !k[0]));
    // Rays and markers absent: no record for them.
    assert!(fit
        .irls_rejected
        .iter()
        .all(|r| r[1].is_nan() && r[2].is_nan()));
}

#[test]
fn the_baseline_without_irls_gets_the_same_lm_budget() {
    let p = EllipsoidParams::default();
    let plain = p.clone().without_irls();
    assert_eq!(plain.irls_rounds, 1);
    assert_eq!(plain.lm_iterations, p.irls_rounds * p.lm_iterations);
    assert_eq!(plain.lm_iterations, 24);
    // The old baseline (`with_irls_rounds(1)`) kept 4 iterations: a sixth of the budget.
    assert_eq!(p.with_irls_rounds(1).lm_iterations, 4);
}

#[test]
fn bad_input_is_reported() {
    let m = model();
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let truth = posed(&m, &mut rng);
    let p = EllipsoidParams::default();
    let empty = EllipsoidObservations::default();
    assert!(matches!(
        fit_ellipsoids(&m, &truth, &empty, &p),
        Err(Error::Empty { .. })
    ));
    let nan = EllipsoidObservations {
        points: vec![DVec3::NAN],
        ..Default::default()
    };
    assert!(matches!(
        fit_ellipsoids(&m, &truth, &nan, &p),
        Err(Error::NonFinite { .. })
    ));
    let mut short = truth.clone();
    short.theta.pop();
    assert!(fit_ellipsoids(&m, &short, &nan, &p).is_err());
    let bad_marker = EllipsoidObservations {
        markers: vec![MarkerObservation {
            bone: 99,
            position: Some(DVec3::ZERO),
        }],
        ..Default::default()
    };
    assert!(fit_ellipsoids(&m, &truth, &bad_marker, &p).is_err());
    for bad in [f64::NAN, 0.0, -1.0] {
        let q = EllipsoidParams {
            sigma_translation_prior_m: Some(bad),
            ..EllipsoidParams::default()
        };
        let r = fit_ellipsoids(&m, &truth, &empty, &q);
        assert!(
            r.is_err() && !matches!(r, Err(Error::Empty { .. })),
            "{r:?}"
        );
    }
    for bad in [f64::NAN, -0.1, 1.5] {
        let q = EllipsoidParams {
            kept_scale_min_rejected: Some(bad),
            ..EllipsoidParams::default()
        };
        // The parameter is refused before the (empty) observations are looked at.
        let r = fit_ellipsoids(&m, &truth, &empty, &q);
        assert!(
            r.is_err() && !matches!(r, Err(Error::Empty { .. })),
            "{r:?}"
        );
    }
    // No points near the last limb: its ellipsoid is named.
    let last = m.bones().len() - 1;
    let all = surface(&m, &truth, 60, &mut rng);
    let ells = m.ellipsoids(&truth).unwrap();
    let far: Vec<DVec3> = all
        .into_iter()
        .filter(|x| x.distance(ells[last].centre) > ells[last].half_length + 0.15)
        .collect();
    let obs = EllipsoidObservations {
        points: far,
        ..Default::default()
    };
    match fit_ellipsoids(&m, &truth, &obs, &p) {
        Err(Error::At { at, .. }) => assert!(matches!(at, Context::Joint(_))),
        other => panic!("expected a bone error, got {other:?}"),
    }
    // A limb seen only along its axis: the width collapses onto the floor and is reported.
    let e = ells[0];
    let mut pts = surface(&m, &truth, 60, &mut rng);
    pts.retain(|x| (x - e.centre).dot(e.axis).abs() > e.half_length || x.distance(e.centre) > 0.4);
    for t in 0..40 {
        pts.push(e.centre + e.axis * (e.half_length * (t as f64 / 20.0 - 1.0)));
    }
    let obs = EllipsoidObservations {
        points: pts,
        ..Default::default()
    };
    let r = fit_ellipsoids(&m, &truth, &obs, &p);
    assert!(
        matches!(&r, Err(Error::At { source, .. }) if matches!(**source, Error::Core(skin_core::Error::Degenerate { .. }))),
        "{r:?}"
    );
}

#[test]
fn end_site_segments_are_modelled_and_checked() {
    let sk = human_skeleton(&HumanParams::default()).unwrap();
    let limbs = EllipsoidModel::limbs(sk.clone(), 0.1).unwrap();
    let body = EllipsoidModel::with_end_sites(sk.clone(), 0.1).unwrap();
    // Hands, feet and the head.
    assert_eq!(body.bones().len(), limbs.bones().len() + 5);
    let ends: Vec<_> = body.bones().iter().filter(|b| b.child.is_none()).collect();
    assert_eq!(ends.len(), 5);
    for bone in ends {
        let end = sk.joints()[bone.parent].end_site.unwrap();
        let b = body.bones().iter().position(|x| x == bone).unwrap();
        assert!((body.default_lengths()[b] - end.length()).abs() < 1e-12);
        assert_eq!(bone.joint(), bone.parent);
    }
    // An end-site segment moves no joint: its scale leaves the skeleton as it is.
    let mut s = body.initial_state(&sk.rest_pose(), 0.05).unwrap();
    let before = body.scaled_skeleton(&s).unwrap();
    let last = body.bones().len() - 1;
    s.length_scale[last] = 1.2;
    let after = body.scaled_skeleton(&s).unwrap();
    assert_eq!(before.joints(), after.joints());
    // A joint without an end site cannot carry one.
    let pelvis = EllipsoidBone {
        parent: 0,
        child: None,
    };
    assert!(matches!(
        EllipsoidModel::new(sk, vec![pelvis]),
        Err(Error::InvalidParam { .. })
    ));
}

#[test]
fn block_solve_matches_the_dense_solve() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let (nf, nd, ns) = (3, 4, 2);
    let n = nf * nd + ns;
    // A random SPD matrix with the block-arrow pattern of the multi-frame problem.
    let mut j = DMatrix::<f64>::zeros(40, n);
    for r in 0..40 {
        let f = r % nf;
        for c in 0..nd {
            j[(r, f * nd + c)] = rng.random_range(-1.0..1.0);
        }
        for c in 0..ns {
            j[(r, nf * nd + c)] = rng.random_range(-1.0..1.0);
        }
    }
    let h = j.transpose() * &j + DMatrix::<f64>::identity(n, n) * 0.1;
    let g = DVector::<f64>::from_fn(n, |_, _| rng.random_range(-1.0..1.0));
    let normal = Normal {
        a: (0..nf)
            .map(|f| h.view((f * nd, f * nd), (nd, nd)).into_owned())
            .collect(),
        b: (0..nf)
            .map(|f| h.view((f * nd, nf * nd), (nd, ns)).into_owned())
            .collect(),
        gf: (0..nf).map(|f| g.rows(f * nd, nd).into_owned()).collect(),
        c: h.view((nf * nd, nf * nd), (ns, ns)).into_owned(),
        gs: g.rows(nf * nd, ns).into_owned(),
    };
    let lambda = 0.3;
    let mut damped = h.clone();
    for k in 0..n {
        damped[(k, k)] += lambda * (h[(k, k)] + 1e-9);
    }
    let dense = damped.cholesky().unwrap().solve(&g);
    let block = normal.solve(lambda, false).unwrap();
    assert!((dense - block).amax() < 1e-10);
    // Pose only: the shared part is zero, each frame its own damped block.
    let pose = normal.solve(lambda, true).unwrap();
    assert!(pose.rows(nf * nd, ns).amax() == 0.0);
}
