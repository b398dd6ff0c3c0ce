use super::*;
use crate::image::distance::signed_distance;
use proptest::prelude::*;

/// One point per traced boundary pixel, at the pixel centre.
fn raw_params() -> ContourParams {
    all_points().with_outward_offset_px(0.0)
}

/// One point per traced boundary pixel, default offset.
fn all_points() -> ContourParams {
    ContourParams::default().with_sample_step_px(0.0)
}

fn ellipse(w: u32, h: u32, c: DVec2, a: f64, b: f64, rot: f64) -> Mask {
    let (s, co) = rot.sin_cos();
    Mask::from_fn(w, h, |x, y| {
        let d = DVec2::new(x as f64, y as f64) - c;
        let u = co * d.x + s * d.y;
        let v = -s * d.x + co * d.y;
        (u / a).powi(2) + (v / b).powi(2) <= 1.0
    })
}

#[test]
fn disc_normals_are_radial_and_leave_the_mask() {
    for r in [4.0, 9.0, 20.0] {
        let c = DVec2::new(25.3, 24.6);
        let m = ellipse(52, 52, c, r, r, 0.0);
        let cs = extract_contours(&m, &raw_params()).unwrap();
        assert_eq!(cs.len(), 1);
        let k = &cs[0];
        assert!(k.is_outer);
        assert_eq!(k.points.len(), k.normals.len());
        for (p, n) in k.points.iter().zip(&k.normals) {
            assert!((n.length() - 1.0).abs() < 1e-12);
            let radial = (*p - c).normalize();
            assert!(n.dot(radial) > 0.9, "r {r}: normal {n} vs radial {radial}");
            assert!(
                m.get(p.x as u32, p.y as u32),
                "raw points are foreground pixels"
            );
            assert!(
                !is_fg_at(&m, *p + 1.5 * *n),
                "step along normal stays inside"
            );
        }
    }
}

#[test]
fn hole_normals_point_into_the_hole() {
    let c = DVec2::new(20.0, 20.0);
    let outer = ellipse(41, 41, c, 15.0, 15.0, 0.0);
    let hole = ellipse(41, 41, c, 6.0, 6.0, 0.0);
    let ring = outer.and_not(&hole).unwrap();
    let cs = extract_contours(&ring, &raw_params()).unwrap();
    assert_eq!(cs.len(), 2);
    let (o, h) = if cs[0].is_outer {
        (&cs[0], &cs[1])
    } else {
        (&cs[1], &cs[0])
    };
    assert!(o.is_outer && !h.is_outer);
    assert_eq!(cs.iter().filter(|k| k.parent.is_some()).count(), 1);
    for (p, n) in h.points.iter().zip(&h.normals) {
        assert!(n.dot((c - *p).normalize()) > 0.9);
        assert!(!is_fg_at(&ring, *p + 1.5 * *n));
    }
    for (p, n) in o.points.iter().zip(&o.normals) {
        assert!(n.dot((*p - c).normalize()) > 0.9);
    }
}

#[test]
fn default_offset_lands_on_the_zero_level_set() {
    let m = ellipse(60, 40, DVec2::new(30.0, 20.0), 20.0, 9.0, 0.4);
    let sd = signed_distance(&m).unwrap();
    let mut worst = 0.0f64;
    // Both the traced points and the default 10-pixel samples lie near the zero set.
    let mut cs = extract_contours(&m, &all_points()).unwrap();
    cs.extend(extract_contours(&m, &ContourParams::default()).unwrap());
    for p in cs.iter().flat_map(|c| &c.points) {
        // Bilinear interpolation of the signed distance at the contour point.
        let (x0, y0) = (p.x.floor(), p.y.floor());
        let (fx, fy) = (p.x - x0, p.y - y0);
        let g = |x: f64, y: f64| f64::from(sd.get_pixel(x as u32, y as u32).0[0]);
        let v = g(x0, y0) * (1.0 - fx) * (1.0 - fy)
            + g(x0 + 1.0, y0) * fx * (1.0 - fy)
            + g(x0, y0 + 1.0) * (1.0 - fx) * fy
            + g(x0 + 1.0, y0 + 1.0) * fx * fy;
        worst = worst.max(v.abs());
    }
    assert!(worst < 0.6, "worst |sd| at contour points {worst}");
}

#[test]
fn regions_touching_the_image_border_are_traced() {
    let full = Mask::new(6, 5).not();
    let cs = extract_contours(&full, &raw_params()).unwrap();
    assert_eq!(cs.len(), 1);
    assert_eq!(cs[0].points.len(), 2 * (6 + 5) - 4);
    // Left half of the image.
    let half = Mask::from_fn(10, 8, |x, _| x < 4);
    let cs = extract_contours(&half, &raw_params()).unwrap();
    assert_eq!(cs.len(), 1);
    // Normals on the right edge (x = 3, away from corners) point to +x.
    for (p, n) in cs[0].points.iter().zip(&cs[0].normals) {
        if p.x == 3.0 && (2.0..=5.0).contains(&p.y) {
            assert!(n.x > 0.99, "{n}");
        }
    }
}

#[test]
fn empty_and_degenerate_masks() {
    assert!(
        extract_contours(&Mask::new(5, 5), &ContourParams::default())
            .unwrap()
            .is_empty()
    );
    assert!(
        extract_contours(&Mask::new(0, 0), &ContourParams::default())
            .unwrap()
            .is_empty()
    );
    // Single pixel and a one-pixel-wide line: unit normals that leave the mask.
    let mut m = Mask::new(12, 12);
    m.set(2, 2, true).unwrap();
    for x in 5..11 {
        m.set(x, 8, true).unwrap();
    }
    let cs = extract_contours(&m, &raw_params()).unwrap();
    assert_eq!(cs.len(), 2);
    for k in &cs {
        for (p, n) in k.points.iter().zip(&k.normals) {
            assert!((n.length() - 1.0).abs() < 1e-12);
            assert!(!is_fg_at(&m, *p + 1.5 * *n));
        }
    }
    let dropped = extract_contours(&m, &raw_params().with_min_points(2)).unwrap();
    assert_eq!(dropped.len(), 1);
    for bad in [
        ContourParams::default().with_tangent_half_window(0),
        ContourParams::default().with_outward_offset_px(f64::NAN),
        ContourParams::default().with_sample_step_px(-1.0),
    ] {
        assert!(matches!(
            extract_contours(&m, &bad),
            Err(Error::InvalidParam { .. })
        ));
    }
}

#[test]
fn resampling_spaces_points_by_arc_length() {
    let m = ellipse(80, 80, DVec2::new(40.0, 40.0), 30.0, 30.0, 0.0);
    let cs = extract_contours(&m, &all_points()).unwrap();
    let k = &cs[0];
    let step = 5.0;
    let r = k.resample(step).unwrap();
    let expected = (k.perimeter_px() / step).ceil() as usize;
    assert_eq!(r.len(), expected);
    for i in 0..r.len() - 1 {
        let d = r.points[i].distance(r.points[i + 1]);
        assert!(d <= step + 1e-9 && d > 0.8 * step, "{d}");
        assert!((r.normals[i].length() - 1.0).abs() < 1e-12);
    }
    let via_params = extract_contours(&m, &all_points().with_sample_step_px(step)).unwrap();
    assert_eq!(via_params[0], r);
    assert!(matches!(k.resample(0.0), Err(Error::InvalidParam { .. })));
    assert!(matches!(
        k.resample(1e-300),
        Err(Error::InvalidParam { .. })
    ));
    let mut bad = k.clone();
    bad.normals.pop();
    assert!(matches!(
        bad.resample(step),
        Err(Error::SizeMismatch { .. })
    ));
    let mut bad = k.clone();
    bad.points[3].x = f64::NAN;
    assert!(matches!(bad.resample(step), Err(Error::NonFinite { .. })));
}

/// Normal accuracy against the analytic normals of rotated ellipses (semi-axes 6–30 px).
/// Measured with the default window (w = 3): mean 2.2°, 95th percentile 5.4°, max 8.7°.
#[test]
fn normals_match_analytic_ellipse_normals() {
    let c = DVec2::new(40.2, 40.7);
    let mut err_deg = Vec::new();
    for (a, b, rot) in [
        (20.0, 12.0, 0.3),
        (30.0, 25.0, 1.1),
        (9.0, 6.0, 0.7),
        (15.0, 15.0, 0.0),
    ] {
        let m = ellipse(82, 82, c, a, b, rot);
        let cs = extract_contours(&m, &all_points()).unwrap();
        let (s, co) = f64::sin_cos(rot);
        for (p, n) in cs[0].points.iter().zip(&cs[0].normals) {
            // Gradient of (u/a)² + (v/b)² at the point, rotated back to image axes.
            let d = *p - c;
            let (u, v) = (co * d.x + s * d.y, -s * d.x + co * d.y);
            let (gu, gv) = (u / (a * a), v / (b * b));
            let g = DVec2::new(co * gu - s * gv, s * gu + co * gv).normalize();
            err_deg.push(g.dot(*n).clamp(-1.0, 1.0).acos().to_degrees());
        }
    }
    err_deg.sort_by(f64::total_cmp);
    let mean = err_deg.iter().sum::<f64>() / err_deg.len() as f64;
    let p95 = err_deg[err_deg.len() * 95 / 100];
    let max = err_deg[err_deg.len() - 1];
    assert!(
        mean < 3.0 && p95 < 7.0 && max < 12.0,
        "mean {mean} p95 {p95} max {max}"
    );
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    /// Random rotated ellipses plus a blob: nearly every normal leaves the mask, and each
    /// normal points away from the region's side (negative signed distance behind it).
    #[test]
    fn normals_point_outward_on_random_shapes(
        a in 3.0f64..18.0, b in 3.0f64..18.0, rot in 0.0f64..3.2,
        cx in 18.0f64..22.0, cy in 18.0f64..22.0,
    ) {
        let m = ellipse(40, 40, DVec2::new(cx, cy), a, b, rot);
        let cs = extract_contours(&m, &raw_params()).unwrap();
        prop_assert_eq!(cs.len(), 1);
        let k = &cs[0];
        let leaving = k.points.iter().zip(&k.normals)
            .filter(|(p, n)| !is_fg_at(&m, **p + 1.5 * **n))
            .count();
        prop_assert!(leaving as f64 >= 0.97 * k.len() as f64, "{} of {}", leaving, k.len());
        let inward = k.points.iter().zip(&k.normals)
            .filter(|(p, n)| is_fg_at(&m, **p - 1.0 * **n))
            .count();
        prop_assert!(inward as f64 >= 0.9 * k.len() as f64, "{} of {}", inward, k.len());
    }
}
