use super::*;

#[test]
fn offsets_interpolate_constraints_and_keep_the_detail() {
    // A 40 × 40 ripple surface 5 cm behind where sparse matches say it is.
    let (w, h) = (40u32, 40u32);
    let ripple = |x: u32, y: u32| 3.0 + 0.002 * ((x as f64 * 0.9).sin() + (y as f64 * 0.7).cos());
    let surface = DepthMap::new(
        w,
        h,
        (0..w * h).map(|i| ripple(i % w, i / w) + 0.05).collect(),
    )
    .unwrap();
    let target = DepthMap::new(
        w,
        h,
        (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                if x % 4 == 0 && y % 4 == 0 {
                    ripple(x, y)
                } else {
                    f64::NAN
                }
            })
            .collect(),
    )
    .unwrap();
    let out = depth_offsets(&surface, &[&target], &OffsetParams::default()).unwrap();
    let worst = (0..w * h)
        .map(|i| (out.depth.depth_m[i as usize] - ripple(i % w, i / w)).abs())
        .fold(0.0, f64::max);
    // The 5 cm offset is removed everywhere, and the 4 mm ripple is kept to 0.1 mm.
    assert!(worst < 1e-4, "{worst}");
    assert_eq!(out.report.kept, (w * h) as usize);
}

#[test]
fn far_regions_are_discarded_and_bad_input_is_an_error() {
    let (w, h) = (64u32, 8u32);
    let surface = DepthMap::new(w, h, vec![2.0; (w * h) as usize]).unwrap();
    let target = DepthMap::new(
        w,
        h,
        (0..w * h)
            .map(|i| if i % w < 2 { 2.01 } else { f64::NAN })
            .collect(),
    )
    .unwrap();
    let params = OffsetParams::default();
    let out = depth_offsets(&surface, &[&target], &params).unwrap();
    // 40 px at 1024 wide is 40 × 1024 / 64 = 640 px here: nothing is far.
    assert_eq!(out.report.discarded, 0);
    let near = OffsetParams {
        max_distance_px: 0.5,
        ..params
    };
    let out = depth_offsets(&surface, &[&target], &near).unwrap();
    assert!(out.report.discarded > 300, "{:?}", out.report);
    let none = DepthMap::empty(w, h).unwrap();
    assert!(depth_offsets(&surface, &[&none], &params).is_err());
    let small = DepthMap::empty(4, 4).unwrap();
    assert!(depth_offsets(&surface, &[&small], &params).is_err());
    assert!(depth_offsets(
        &surface,
        &[&target],
        &OffsetParams {
            beta: -1.0,
            ..params
        }
    )
    .is_err());
}

#[test]
fn a_proxy_keeps_far_pixels_and_gates_gross_matches() {
    // A flat surface at 2 m; matches at its left edge ask for 2.01 m, one gross match
    // asks for 2.5 m; the proxy says 2.02 m everywhere.
    let (w, h) = (64u32, 8u32);
    let surface = DepthMap::new(w, h, vec![2.0; (w * h) as usize]).unwrap();
    let target = DepthMap::new(
        w,
        h,
        (0..w * h)
            .map(|i| match i % w {
                0 | 1 => 2.01,
                30 => 2.5,
                _ => f64::NAN,
            })
            .collect(),
    )
    .unwrap();
    let proxy = DepthMap::new(w, h, vec![2.02; (w * h) as usize]).unwrap();
    let near = OffsetParams {
        max_distance_px: 0.5,
        ..OffsetParams::default()
    };
    // Without γ the proxy changes nothing: far pixels are discarded as before.
    let plain = depth_offsets(&surface, &[&target], &near).unwrap();
    let guided = depth_offsets_guided(&surface, &[&target], Some(&proxy), &near).unwrap();
    assert_eq!(plain.report, guided.report);
    let bits = |o: &OffsetSurface| {
        o.depth
            .depth_m
            .iter()
            .map(|d| d.to_bits())
            .collect::<Vec<_>>()
    };
    assert_eq!(bits(&plain), bits(&guided));
    // With γ > 0 they are kept and relax to the proxy far from the matches.
    let anchored = OffsetParams {
        proxy_weight: 0.01,
        ..near
    };
    let out = depth_offsets_guided(&surface, &[&target], Some(&proxy), &anchored).unwrap();
    assert_eq!(out.report.discarded, 0, "{:?}", out.report);
    let at = |x: u32, y: u32| out.depth.depth_m[out.depth.index(x, y)];
    // The matched pixels are pulled from the proxy's 2.02 m toward their 2.01 m.
    assert!(at(0, 4) < 2.0195, "{}", at(0, 4));
    // The gross match pulls its neighbourhood toward 2.5 m unless the gate drops it.
    assert!(at(30, 4) > 2.05, "{}", at(30, 4));
    let gated = OffsetParams {
        proxy_gate_m: Some(0.05),
        ..anchored
    };
    let out = depth_offsets_guided(&surface, &[&target], Some(&proxy), &gated).unwrap();
    let v = out.depth.depth_m[out.depth.index(30, 4)];
    assert!((v - 2.02).abs() < 2e-3, "{v}");
    // Far from the (remaining) matches, the offsets relax to the proxy.
    let far = out.depth.depth_m[out.depth.index(60, 4)];
    assert!((far - 2.02).abs() < 1e-3, "{far}");
    assert_eq!(out.report.constrained, 2 * h as usize);
    // Bad input.
    let small = DepthMap::empty(4, 4).unwrap();
    assert!(depth_offsets_guided(&surface, &[&target], Some(&small), &gated).is_err());
    for bad in [
        OffsetParams {
            proxy_weight: -1.0,
            ..gated
        },
        OffsetParams {
            proxy_weight: f64::NAN,
            ..gated
        },
        OffsetParams {
            proxy_gate_m: Some(0.0),
            ..gated
        },
    ] {
        assert!(depth_offsets_guided(&surface, &[&target], Some(&proxy), &bad).is_err());
    }
}

#[test]
fn gross_matches_are_rejected_or_down_weighted_and_the_thesis_form_follows_them() {
    // A flat surface at 2 m that its matches ask to move to 2.01 m (± 1 mm of noise);
    // view A's matches are dense, with a 3 × 3 blob of gross matches asking 2.06 m;
    // view B matched every fourth pixel, correctly, also inside the blob.
    let (w, h) = (48u32, 48u32);
    let noise = |i: u32| 0.001 * (f64::from(i) * 12.9898).sin();
    let blob = |x: u32, y: u32| (20..23).contains(&x) && (20..23).contains(&y);
    let surface = DepthMap::new(w, h, vec![2.0; (w * h) as usize]).unwrap();
    let a = DepthMap::new(
        w,
        h,
        (0..w * h)
            .map(|i| {
                if blob(i % w, i / w) {
                    2.06
                } else {
                    2.01 + noise(i)
                }
            })
            .collect(),
    )
    .unwrap();
    let b = DepthMap::new(
        w,
        h,
        (0..w * h)
            .map(|i| {
                if i % w % 4 == 1 && i / w % 4 == 1 {
                    2.01 + noise(i + 7)
                } else {
                    f64::NAN
                }
            })
            .collect(),
    )
    .unwrap();
    // The thesis's Eq. 3.4: every match kept (the default rejects outliers).
    let plain = OffsetParams {
        outliers: None,
        ..OffsetParams::default()
    };
    let at = |o: &OffsetSurface| o.depth.depth_m[o.depth.index(21, 21)];
    // The thesis's Eq. 3.4 follows the gross matches (the baseline that must lose).
    let thesis = depth_offsets(&surface, &[&a, &b], &plain).unwrap();
    assert!(at(&thesis) > 2.015, "{}", at(&thesis));
    assert_eq!(thesis.report.rejected, 0);
    // Rejection (a 5-px window at this 48-px width: 100 px at 1024) drops exactly the
    // blob's nine gross matches (B's good match inside the blob stays), and the surface
    // stays at 2.01 m.
    let rejecting = OffsetParams {
        outliers: Some(OffsetOutliers {
            radius_px: 100.0,
            ..OffsetOutliers::default()
        }),
        ..plain
    };
    let out = depth_offsets(&surface, &[&a, &b], &rejecting).unwrap();
    assert_eq!(out.report.rejected, 9, "{:?}", out.report);
    assert_eq!(out.report.constrained, thesis.report.constrained - 8);
    assert!((at(&out) - 2.01).abs() < 2e-3, "{}", at(&out));
    // Down-weighting (Cauchy IRLS) also stays near 2.01 m.
    let weighting = OffsetParams {
        robust: Some(RobustWeights::default()),
        ..plain
    };
    let out = depth_offsets(&surface, &[&a, &b], &weighting).unwrap();
    assert!((at(&out) - 2.01).abs() < 5e-3, "{}", at(&out));
    assert!(out.report.down_weighted >= 9, "{:?}", out.report);
    // Without gross matches, rejection drops nothing and the result is the thesis's,
    // bit for bit.
    let clean = DepthMap::new(w, h, (0..w * h).map(|i| 2.01 + noise(i)).collect()).unwrap();
    let thesis = depth_offsets(&surface, &[&clean, &b], &plain).unwrap();
    let out = depth_offsets(&surface, &[&clean, &b], &rejecting).unwrap();
    assert_eq!(out.report.rejected, 0);
    assert_eq!(thesis.depth, out.depth);
    // Bad input is an error.
    let o = OffsetOutliers::default();
    for bad in [
        OffsetParams {
            outliers: Some(OffsetOutliers {
                radius_px: 0.0,
                ..o
            }),
            ..plain
        },
        OffsetParams {
            outliers: Some(OffsetOutliers { k: f64::NAN, ..o }),
            ..plain
        },
        OffsetParams {
            outliers: Some(OffsetOutliers { floor_m: -1.0, ..o }),
            ..plain
        },
        OffsetParams {
            robust: Some(RobustWeights {
                scale_m: 0.0,
                ..RobustWeights::default()
            }),
            ..plain
        },
    ] {
        assert!(depth_offsets(&surface, &[&a, &b], &bad).is_err());
    }
}

/// Two views of a sphere from the ring's cameras `a` and `b` (of 8), exact normals, the
/// true depths pushed 2 cm toward the camera as the proxy.
fn sphere_views(a: usize, b: usize) -> (Vec<Camera>, Vec<NormalMap>, Vec<DepthMap>) {
    use skin_core::camera::{Intrinsics, Rig};
    use skin_core::math::DVec3;
    use skin_core::mesh::shapes::uv_sphere;
    use skin_core::raster::{Rasterizer, RenderParams};
    let k = Intrinsics::from_horizontal_fov(0.5, 64, 64).unwrap();
    let rig = Rig::ring(8, 3.0, 0.0, DVec3::ZERO, DVec3::Y, k).unwrap();
    let cams = vec![rig.cameras[a].clone(), rig.cameras[b].clone()];
    let mesh = uv_sphere(DVec3::ZERO, 0.4, 48, 96).unwrap();
    let mut normals = Vec::new();
    let mut proxies = Vec::new();
    for c in &cams {
        let view = Rasterizer::new(c)
            .render(&mesh, &RenderParams::default())
            .unwrap();
        normals.push(crate::rendered_normals(c, &view).unwrap());
        let truth = DepthMap::from_view(&view).unwrap();
        proxies
            .push(DepthMap::new(64, 64, truth.depth_m.iter().map(|d| d - 0.02).collect()).unwrap());
    }
    (cams, normals, proxies)
}

#[test]
fn a_pass_runs_on_neighbours_and_views_that_do_not_overlap_are_an_error() {
    let (cams, normals, proxies) = sphere_views(0, 1);
    let out = per_view_surfaces(
        &cams,
        &normals,
        &proxies,
        &[(0, 1)],
        None,
        &SurfaceParams::default(),
    )
    .unwrap();
    assert_eq!(out.surfaces.len(), 2);
    assert!(
        out.match_stats[0].good_matches > 100,
        "{:?}",
        out.match_stats
    );
    // Opposite cameras see disjoint halves: no match, so no Eq. 3.4 constraint.
    let (cams, normals, proxies) = sphere_views(0, 4);
    let err = per_view_surfaces(
        &cams,
        &normals,
        &proxies,
        &[(0, 1)],
        None,
        &SurfaceParams::default(),
    )
    .unwrap_err();
    assert!(matches!(err, Error::At { .. }), "{err}");
    assert!(per_view_surfaces(
        &cams,
        &normals,
        &proxies,
        &[(0, 2)],
        None,
        &SurfaceParams::default()
    )
    .is_err());
    assert!(per_view_surfaces(
        &cams,
        &normals,
        &proxies,
        &[],
        None,
        &SurfaceParams::default()
    )
    .is_err());
    assert!(per_view_surfaces(
        &cams,
        &normals[..1],
        &proxies,
        &[(0, 1)],
        None,
        &SurfaceParams::default()
    )
    .is_err());
}
