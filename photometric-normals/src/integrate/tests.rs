use super::*;
use skin_core::camera::Intrinsics;
use skin_core::mesh::shapes::uv_sphere;
use skin_core::raster::{Rasterizer, RenderParams};

/// A sphere seen by one camera: exact normals, truth, and a proxy pushed 3 cm forward.
fn sphere_view() -> (Camera, NormalMap, DepthMap, DepthMap) {
    let k = Intrinsics::from_horizontal_fov(0.5, 96, 96).unwrap();
    let cam = Camera::look_at(k, DVec3::new(0.0, 0.0, 3.0), DVec3::ZERO, DVec3::Y).unwrap();
    let mesh = uv_sphere(DVec3::ZERO, 0.4, 64, 128).unwrap();
    let view = Rasterizer::new(&cam)
        .render(&mesh, &RenderParams::default())
        .unwrap();
    let truth = DepthMap::from_view(&view).unwrap();
    let normals = rendered_normals(&cam, &view).unwrap();
    let proxy = DepthMap::new(96, 96, truth.depth_m.iter().map(|d| d - 0.03).collect()).unwrap();
    (cam, normals, truth, proxy)
}

#[test]
fn exact_normals_recover_the_sphere_far_better_than_a_biased_proxy() {
    let (cam, normals, truth, _) = sphere_view();
    // A proxy that is right on average but wrong in shape: a flat plane through the
    // sphere's mean depth (the baseline could win only if the shape were flat).
    let mean =
        truth.depth_m.iter().filter(|d| !d.is_nan()).sum::<f64>() / truth.valid_count() as f64;
    let proxy = DepthMap::new(
        96,
        96,
        truth
            .depth_m
            .iter()
            .map(|d| if d.is_nan() { f64::NAN } else { mean })
            .collect(),
    )
    .unwrap();
    let out =
        integrate_normals(&cam, &normals, &proxy, None, &IntegrationParams::default()).unwrap();
    let err = |m: &DepthMap| {
        let mut e: Vec<f64> = m
            .depth_m
            .iter()
            .zip(&truth.depth_m)
            .filter(|(a, b)| !a.is_nan() && !b.is_nan())
            .map(|(a, b)| (a - b).abs())
            .collect();
        e.sort_by(f64::total_cmp);
        e[e.len() / 2]
    };
    let (ours, base) = (err(&out.depth), err(&proxy));
    assert!(out.report.unknowns > 1500, "{:?}", out.report);
    // Relative shape from the normals, absolute placement from the mean of the proxy:
    // the median error is a few mm against the plane's ~10 cm.
    assert!(ours < 0.005 && base > 0.05, "ours {ours} base {base}");
}

/// Largest depth difference (m) between two integrations where both have a surface, and
/// whether they have surfaces at the same pixels.
fn max_difference(a: &DepthMap, b: &DepthMap) -> (f64, bool) {
    let same = a
        .depth_m
        .iter()
        .zip(&b.depth_m)
        .all(|(x, y)| x.is_nan() == y.is_nan());
    let max = a
        .depth_m
        .iter()
        .zip(&b.depth_m)
        .filter(|(x, y)| !x.is_nan() && !y.is_nan())
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max);
    (max, same)
}

#[test]
fn multigrid_matches_the_direct_solve_on_a_sphere_view() {
    let (cam, normals, _, shifted) = sphere_view();
    // A proxy wrong in shape as well (a bulge of 5 cm), and noisy normals, so that the
    // warm start is far from the solution and the normals are not exactly integrable.
    let bulged = DepthMap::new(
        96,
        96,
        shifted
            .depth_m
            .iter()
            .enumerate()
            .map(|(i, d)| d + 0.05 * ((i % 96) as f64 / 96.0 * std::f64::consts::PI).sin())
            .collect(),
    )
    .unwrap();
    let mut noisy = normals.clone();
    for (i, n) in noisy.normals.iter_mut().enumerate() {
        let e = skin_core::random::SplitMix64::new(7).uniform_at(i as u64) - 0.5;
        *n = (*n + DVec3::new(0.1 * e, -0.05 * e, 0.0)).normalize();
    }
    // Breaks that cut the view into four regions, each with its own scale mode.
    let cross = Mask::from_fn(96, 96, |x, y| x == 48 || y == 40);
    for (nm, proxy, alpha, breaks) in [
        (&normals, &shifted, 1e-6, None),
        (&noisy, &bulged, 1e-6, None),
        (&noisy, &bulged, 1e-5, None),
        (&noisy, &bulged, 1e-6, Some(&cross)),
    ] {
        let p = IntegrationParams {
            alpha,
            ..IntegrationParams::default()
        };
        let direct = integrate_normals(&cam, nm, proxy, breaks, &p).unwrap();
        assert_eq!(p.solver, IntegrationSolver::Direct);
        let mg = integrate_normals(
            &cam,
            nm,
            proxy,
            breaks,
            &p.with_solver(IntegrationSolver::multigrid()),
        )
        .unwrap();
        let (max, same) = max_difference(&direct.depth, &mg.depth);
        // 1 µm: far below the 2 mm goal and the studio's noise (measured: 2·10⁻¹⁰ m).
        assert!(same && max < 1e-6, "max {max} m, same pixels {same}");
        assert!(
            mg.report.iterations > 0 && mg.report.iterations < 60,
            "{:?}",
            mg.report
        );
        assert!(mg.report.relative_residual <= 1e-7, "{:?}", mg.report);
        assert_eq!(direct.report.iterations, 0);
        // Not trivially equal to the warm start: the solve moved the depths by mm (1000×
        // the agreement).
        let (moved, _) = max_difference(&mg.depth, proxy);
        assert!(moved > 1e-3, "moved {moved}");
        eprintln!("multigrid vs direct: max {max:e} m, {:?}", mg.report);
    }
}

/// `proxy` with its right half (columns 48 on of the 96² view) 1 m farther: a stepped
/// proxy with a jump between columns 47 and 48.
fn with_jump(proxy: &DepthMap) -> DepthMap {
    let mut jumpy = proxy.clone();
    for y in 0..96 {
        for x in 48..96 {
            let i = jumpy.index(x, y);
            jumpy.depth_m[i] += 1.0;
        }
    }
    jumpy
}

#[test]
fn proxy_jumps_and_match_breaks_remove_pixels() {
    let (cam, normals, _, proxy) = sphere_view();
    let jumpy = with_jump(&proxy);
    let out =
        integrate_normals(&cam, &normals, &jumpy, None, &IntegrationParams::default()).unwrap();
    assert!(out.report.removed_proxy_jumps > 20, "{:?}", out.report);
    // Cutting the links instead keeps the straddling pixels, the two halves integrated
    // apart: each is placed by its own proxy (the right half 1 m farther).
    let linked = IntegrationParams {
        cut_proxy_links: true,
        ..IntegrationParams::default()
    };
    let cut = integrate_normals(&cam, &normals, &jumpy, None, &linked).unwrap();
    assert_eq!(cut.report.removed_proxy_jumps, 0, "{:?}", cut.report);
    assert!(
        cut.report.unknowns >= out.report.unknowns + out.report.removed_proxy_jumps,
        "{:?} vs {:?}",
        cut.report,
        out.report
    );
    let (l, r) = (cut.depth.index(47, 48), cut.depth.index(48, 48));
    assert!(
        (cut.depth.depth_m[r] - cut.depth.depth_m[l] - 1.0).abs() < 0.05,
        "{} {}",
        cut.depth.depth_m[l],
        cut.depth.depth_m[r]
    );
    let breaks = Mask::from_fn(96, 96, |x, _| x == 30);
    let out = integrate_normals(
        &cam,
        &normals,
        &proxy,
        Some(&breaks),
        &IntegrationParams::default(),
    )
    .unwrap();
    assert!(out.report.removed_match_jumps > 20, "{:?}", out.report);
}

#[test]
fn layers_put_straddling_pixels_on_the_side_their_evidence_agrees_with() {
    let (cam, normals, truth, proxy) = sphere_view();
    // A jump between columns 47 and 48 that the true (continuous) sphere does not have,
    // so column 48 truly lies on the near layer.
    let jumpy = with_jump(&proxy);
    let layered = IntegrationParams {
        layers: true,
        ..IntegrationParams::default()
    };
    // Without evidence every straddling pixel stays, on its own proxy's layer (as the
    // link cut).
    let own = integrate_normals(&cam, &normals, &jumpy, None, &layered).unwrap();
    assert_eq!(own.report.removed_proxy_jumps, 0, "{:?}", own.report);
    let cut = IntegrationParams {
        cut_proxy_links: true,
        ..IntegrationParams::default()
    };
    let linked = integrate_normals(&cam, &normals, &jumpy, None, &cut).unwrap();
    let bits = |d: &DepthMap| d.depth_m.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
    assert!(bits(&own.depth) == bits(&linked.depth));
    // Evidence: the true depth from row 30 down, none above.
    let evidence = DepthMap::new(
        96,
        96,
        (0..96 * 96)
            .map(|i| {
                if i / 96 >= 30 {
                    truth.depth_m[i]
                } else {
                    f64::NAN
                }
            })
            .collect(),
    )
    .unwrap();
    let out =
        integrate_normals_with_evidence(&cam, &normals, &jumpy, None, Some(&evidence), &layered)
            .unwrap();
    // The step from column 47 to 48 along a row (the true sphere's is millimetres).
    let step = |d: &DepthMap, y: u32| (d.depth_m[d.index(48, y)] - d.depth_m[d.index(47, y)]).abs();
    let mut checked = 0;
    for y in 30..96 {
        let (l, r) = (out.depth.index(47, y), out.depth.index(48, y));
        if truth.depth_m[l].is_nan() || truth.depth_m[r].is_nan() {
            continue;
        }
        // Column 48 is integrated on the near layer with its left neighbours, where its
        // own proxy's layer puts it 1 m farther.
        assert!(
            step(&out.depth, y) < 0.01,
            "row {y}: {}",
            step(&out.depth, y)
        );
        assert!(
            step(&own.depth, y) > 0.5,
            "row {y}: {}",
            step(&own.depth, y)
        );
        checked += 1;
    }
    assert!(checked > 20, "{checked}");
    // Above row 30 the straddling pixels have no evidence and are removed, as the thesis.
    let jumps = depth_jumps(&jumpy, IntegrationParams::jump_threshold_m(0.02, 96)).unwrap();
    let straddling_above = (0..30u32)
        .flat_map(|y| (0..96u32).map(move |x| (x, y)))
        .filter(|&(x, y)| jumps.get(x, y) && normals.valid[jumpy.index(x, y)])
        .count();
    assert!(straddling_above > 5, "{straddling_above}");
    assert_eq!(
        out.report.removed_proxy_jumps, straddling_above,
        "{:?}",
        out.report
    );
    // Evidence of another size and a non-positive agreement are errors.
    let bad = IntegrationParams {
        layer_agreement: 0.0,
        ..layered
    };
    assert!(integrate_normals(&cam, &normals, &jumpy, None, &bad).is_err());
    let small = DepthMap::empty(8, 8).unwrap();
    assert!(
        integrate_normals_with_evidence(&cam, &normals, &jumpy, None, Some(&small), &layered)
            .is_err()
    );
}

#[test]
fn bad_input_is_an_error() {
    let (cam, normals, _, proxy) = sphere_view();
    let p = IntegrationParams::default();
    let mut nan = normals.clone();
    let i = nan.valid.iter().position(|v| *v).unwrap();
    nan.normals[i] = DVec3::NAN;
    assert!(integrate_normals(&cam, &nan, &proxy, None, &p).is_err());
    let mut none = normals.clone();
    none.valid.iter_mut().for_each(|v| *v = false);
    assert!(integrate_normals(&cam, &none, &proxy, None, &p).is_err());
    let small = DepthMap::empty(8, 8).unwrap();
    assert!(integrate_normals(&cam, &normals, &small, None, &p).is_err());
    // A proxy that misses the subject entirely leaves nothing anchored.
    let missing = DepthMap::empty(96, 96).unwrap();
    assert!(integrate_normals(&cam, &normals, &missing, None, &p).is_err());
    let bad = IntegrationParams {
        alpha: f64::NAN,
        ..p
    };
    assert!(integrate_normals(&cam, &normals, &proxy, None, &bad).is_err());
    for mg in [
        MultigridParams {
            tolerance: 0.0,
            ..MultigridParams::default()
        },
        MultigridParams {
            max_iterations: 0,
            ..MultigridParams::default()
        },
        MultigridParams {
            coarse_scale: 2.0,
            ..MultigridParams::default()
        },
        MultigridParams {
            tolerance: f64::NAN,
            ..MultigridParams::default()
        },
    ] {
        let bad = p.with_solver(IntegrationSolver::Multigrid(mg));
        assert!(integrate_normals(&cam, &normals, &proxy, None, &bad).is_err());
    }
}

#[test]
fn given_camera_rays_integrate_to_the_bit_and_rays_of_another_size_are_an_error() {
    let (cam, normals, _, proxy) = sphere_view();
    let p = IntegrationParams::default();
    let bits = |d: &DepthMap| d.depth_m.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
    let own = integrate_normals(&cam, &normals, &proxy, None, &p).unwrap();
    let rays = camera_rays(&cam).unwrap();
    let given = integrate_with_rays(&cam, &normals, &proxy, None, None, &p, Some(&rays)).unwrap();
    assert_eq!(bits(&own.depth), bits(&given.depth));
    // The given rays are the ones used: another camera's (wider field of view) change the
    // surface.
    let wide = Camera::look_at(
        Intrinsics::from_horizontal_fov(0.6, 96, 96).unwrap(),
        DVec3::new(0.0, 0.0, 3.0),
        DVec3::ZERO,
        DVec3::Y,
    )
    .unwrap();
    let other = camera_rays(&wide).unwrap();
    let moved = integrate_with_rays(&cam, &normals, &proxy, None, None, &p, Some(&other)).unwrap();
    assert_ne!(bits(&own.depth), bits(&moved.depth));
    let short = integrate_with_rays(&cam, &normals, &proxy, None, None, &p, Some(&rays[1..]));
    let message = short.expect_err("rays of another size").to_string();
    assert!(message.contains("camera rays"), "{message}");
}
