use skin_core::camera::Camera;
use skin_core::image::Mask;
use skin_core::math::{DVec2, DVec3};
use skin_core::mesh::TriMesh;

use crate::integrate::camera_rays;
use crate::{mesh_proxy_depth, DepthMap, PolygonalHull};

use super::batch::{window_distances, Fixed, Scratch};
use super::coarse_to_fine::{match_pair, match_pair_with_rays};
use super::epipolar_dp::{lowest_cost_path, LV, RV};
use super::horn::horn_rotation;
use super::metrics::{partial_window_distance, rigid_residual, Windows};
use super::params::{MatchMetric, MatchingParams, SubPixel};
use super::plane::DENSE_PROGRAMME;
use super::views::{MatchView, PairMatches};

const LO: usize = 2;
const RO: usize = 3;
use nalgebra::Matrix3;

/// The reference: Kabsch by a 3 × 3 SVD with the reflection fix.
fn rigid_residual_svd(pairs: &[(DVec3, DVec3)]) -> f64 {
    let n = pairs.len() as f64;
    let ca = pairs.iter().map(|p| p.0).sum::<DVec3>() / n;
    let cb = pairs.iter().map(|p| p.1).sum::<DVec3>() / n;
    let mut h = Matrix3::zeros();
    for (a, b) in pairs {
        let (a, b) = (*a - ca, *b - cb);
        h += nalgebra::Vector3::new(a.x, a.y, a.z)
            * nalgebra::Vector3::new(b.x, b.y, b.z).transpose();
    }
    let svd = h.svd(true, true);
    let (u, vt) = (svd.u.unwrap(), svd.v_t.unwrap());
    let mut d = Matrix3::identity();
    if (vt.transpose() * u.transpose()).determinant() < 0.0 {
        d[(2, 2)] = -1.0;
    }
    let r = vt.transpose() * d * u.transpose();
    pairs
        .iter()
        .map(|(a, b)| {
            let a = *a - ca;
            let ra = r * nalgebra::Vector3::new(a.x, a.y, a.z);
            (DVec3::new(ra.x, ra.y, ra.z) - (*b - cb)).length()
        })
        .sum::<f64>()
        / n
}

/// Uniform draws in [0, 1) from a seeded generator.
fn uniform_draws(seed: u64) -> impl FnMut() -> f64 {
    let rng = skin_core::random::SplitMix64::new(seed);
    let mut draws = 0u64;
    move || {
        draws += 1;
        rng.uniform_at(draws)
    }
}

#[test]
fn quaternion_kabsch_equals_the_svd_kabsch() {
    let mut uniform = uniform_draws(7);
    let mut worst: f64 = 0.0;
    for trial in 0..2000 {
        let n = 13 + trial % 13;
        let q = skin_core::math::DQuat::from_axis_angle(
            DVec3::new(uniform() - 0.5, uniform() - 0.5, uniform() - 0.5).normalize(),
            6.0 * uniform() - 3.0,
        );
        // Patch-like sets: a 5 × 5 grid of cm-sized points, some planar, bent,
        // mirrored or noisy, at a few metres from the origin.
        let kind = trial % 4;
        let pairs: Vec<(DVec3, DVec3)> = (0..n)
            .map(|k| {
                let p = DVec3::new(
                    (k % 5) as f64 * 0.005,
                    (k / 5) as f64 * 0.005,
                    if kind == 0 { 0.0 } else { 0.002 * uniform() },
                ) + DVec3::new(1.0, 2.0, 3.0);
                let mut m = q * p + DVec3::new(0.3, -0.1, 0.2);
                match kind {
                    1 => m += DVec3::splat(0.001) * (uniform() - 0.5),
                    2 => m.z = -m.z,
                    3 => m += DVec3::new(0.0, 0.0, 0.003 * (p.x * 300.0).sin()),
                    _ => {}
                }
                (p, m)
            })
            .collect();
        let (fast, slow) = (rigid_residual(&pairs), rigid_residual_svd(&pairs));
        let scale = slow.abs().max(1e-6);
        worst = worst.max((fast - slow).abs() / scale);
        assert!(
            (fast - slow).abs() <= 1e-7 * scale,
            "trial {trial}: {fast} vs {slow}"
        );
    }
    eprintln!("worst relative difference {worst:e}");
}

/// The reference of [`window_distances`]: one comparison alone, in scalar arithmetic (two
/// full windows by [`aligned_distance_full`], others by [`partial_window_distance`]).
fn window_distance_alone(
    own: &Windows,
    s: usize,
    other: &Windows,
    t: usize,
    pairs: &mut Vec<(DVec3, DVec3)>,
) -> f64 {
    if own.centroids[s].is_some() && other.centroids[t].is_some() {
        return aligned_distance_full(
            own.centred(s),
            other.centred(t),
            own.spread[s] + other.spread[t],
        );
    }
    partial_window_distance(own, s, other, t, pairs)
}

/// The reference for two full windows, one comparison at a time in scalar arithmetic:
/// centred (`xs, ys, zs`), with the sum `g` of both windows' squared norms.
fn aligned_distance_full(
    (ax, ay, az): (&[f64], &[f64], &[f64]),
    (bx, by, bz): (&[f64], &[f64], &[f64]),
    g: f64,
) -> f64 {
    if g <= 0.0 {
        return 0.0;
    }
    let k = ax
        .len()
        .min(ay.len())
        .min(az.len())
        .min(bx.len())
        .min(by.len())
        .min(bz.len());
    let (ax, ay, az, bx, by, bz) = (&ax[..k], &ay[..k], &az[..k], &bx[..k], &by[..k], &bz[..k]);
    let mut h = [0.0f64; 9];
    for i in 0..k {
        let (x, y, z) = (ax[i], ay[i], az[i]);
        let (u, v, w) = (bx[i], by[i], bz[i]);
        h[0] += x * u;
        h[1] += x * v;
        h[2] += x * w;
        h[3] += y * u;
        h[4] += y * v;
        h[5] += y * w;
        h[6] += z * u;
        h[7] += z * v;
        h[8] += z * w;
    }
    let s = 1.0 / (0.5 * g);
    let h = h.map(|v| v * s);
    let Some(r) = horn_rotation(&[[h[0], h[1], h[2]], [h[3], h[4], h[5]], [h[6], h[7], h[8]]])
    else {
        return f64::INFINITY;
    };
    let [[r00, r01, r02], [r10, r11, r12], [r20, r21, r22]] = r;
    let mut sum = 0.0;
    for i in 0..k {
        let (x, y, z) = (ax[i], ay[i], az[i]);
        let dx = r00 * x + r01 * y + r02 * z - bx[i];
        let dy = r10 * x + r11 * y + r12 * z - by[i];
        let dz = r20 * x + r21 * y + r22 * z - bz[i];
        sum += (dx * dx + dy * dy + dz * dz).sqrt();
    }
    sum / k as f64
}

#[test]
fn one_window_against_many_is_each_comparison_to_the_bit() {
    // Two 14 × 11 surfaces of bumpy cm-scale points with holes, a flat constant patch (every
    // point at its centroid) and one non-finite point; every pixel a window centre, so
    // windows are full, partial (holes, the border) or missing.
    let (w, h) = (14u32, 11u32);
    let mut uniform = uniform_draws(11);
    let mut surface = |shift: f64| -> Vec<Option<DVec3>> {
        (0..w * h)
            .map(|i| {
                let (x, y) = (f64::from(i % w), f64::from(i / w));
                let hole = uniform() < 0.06;
                let p = if (2.0..5.0).contains(&x) && (6.0..9.0).contains(&y) {
                    DVec3::new(0.1, 0.2, 2.0)
                } else {
                    DVec3::new(
                        0.004 * x,
                        0.004 * y,
                        2.0 + shift + 0.003 * (x * 0.7 + y).sin() + 0.0005 * uniform(),
                    )
                };
                (!hole).then_some(p)
            })
            .collect()
    };
    let (mut own_field, other_field) = (surface(0.0), surface(0.01));
    own_field[5 * w as usize + 10] = Some(DVec3::new(f64::NAN, 0.0, 2.0));
    let all = || (0..(w * h) as usize).map(Some);
    let own = Windows::gather(&own_field, (w, h), all(), 2, None);
    let other = Windows::gather(&other_field, (w, h), all(), 2, None);
    let n = (w * h) as usize;
    // Batches of every length mod 4, with repeats.
    let ts: Vec<usize> = (0..n).chain((0..n).step_by(7)).collect();
    let (mut scratch, mut out, mut pairs) = (Scratch::default(), Vec::new(), Vec::new());
    let mut compared = 0;
    for s in 0..n {
        for (start, len) in [
            (0, ts.len()),
            ((s * 13) % 40, 1),
            (s % 3, 2),
            (s % 5, 3),
            (s, 5),
        ] {
            let ts = &ts[start..start + len];
            for fixed in [Fixed::Own, Fixed::Other] {
                let (fixed_windows, varying) = match fixed {
                    Fixed::Own => (&own, &other),
                    Fixed::Other => (&other, &own),
                };
                window_distances(
                    (fixed_windows, s),
                    varying,
                    ts,
                    fixed,
                    &mut scratch,
                    &mut out,
                );
                for (&t, &d) in ts.iter().zip(&out) {
                    let (a, b) = if fixed == Fixed::Own { (s, t) } else { (t, s) };
                    let one = window_distance_alone(&own, a, &other, b, &mut pairs);
                    assert_eq!(
                        d.to_bits(),
                        one.to_bits(),
                        "own {a} against {b}: {d} vs {one}"
                    );
                    compared += usize::from(fixed == Fixed::Other && d.is_finite() && d > 0.0);
                }
            }
        }
    }
    // The comparisons were mostly of real windows, not of the special cases.
    assert!(compared > 10_000, "{compared} finite comparisons");
}

#[test]
fn rigid_residual_ignores_a_rigid_motion_and_sees_a_bend() {
    let pts: Vec<DVec3> = (0..25)
        .map(|k| DVec3::new((k % 5) as f64 * 0.01, (k / 5) as f64 * 0.01, 0.0))
        .collect();
    let q = skin_core::math::DQuat::from_axis_angle(DVec3::new(1.0, 2.0, 0.5).normalize(), 0.3);
    let moved: Vec<(DVec3, DVec3)> = pts
        .iter()
        .map(|p| (*p, q * *p + DVec3::new(0.1, -0.2, 0.3)))
        .collect();
    assert!(rigid_residual(&moved) < 1e-9);
    let bent: Vec<(DVec3, DVec3)> = pts
        .iter()
        .map(|p| (*p, *p + DVec3::Z * (p.x * 10.0).powi(2) * 0.01))
        .collect();
    assert!(rigid_residual(&bent) > 1e-4);
}

/// Two cameras 45° apart around a bumpy sphere, with its true depth maps.
fn sphere_pair() -> (Vec<Camera>, Vec<DepthMap>) {
    sphere_ring(96, 2)
}

/// The first `n` of a ring of 8 cameras at `size`² around the bumpy sphere.
fn sphere_ring(size: u32, n: usize) -> (Vec<Camera>, Vec<DepthMap>) {
    use skin_core::camera::{Intrinsics, Rig};
    use skin_core::mesh::shapes::uv_sphere;
    let k = Intrinsics::from_horizontal_fov(0.5, size, size).unwrap();
    let rig = Rig::ring(8, 3.0, 0.0, DVec3::ZERO, DVec3::Y, k).unwrap();
    let cams = rig.cameras[..n].to_vec();
    let mut mesh = uv_sphere(DVec3::ZERO, 0.4, 48, 96).unwrap();
    for v in &mut mesh.vertices {
        // Low bumps so that the surface metric has shape to match.
        *v *= 1.0 + 0.05 * (5.0 * v.x).sin() * (5.0 * v.y).cos();
    }
    let depths = cams
        .iter()
        .map(|c| mesh_proxy_depth(c, &mesh).unwrap())
        .collect();
    (cams, depths)
}

fn plain<'a>(camera: &'a Camera, surface: &'a DepthMap) -> MatchView<'a> {
    MatchView {
        camera,
        surface,
        guide: None,
        images: None,
    }
}

/// Per matched pixel of `target`, the matched depth minus the true depth, m.
fn target_errors(target: &DepthMap, truth: &DepthMap) -> Vec<f64> {
    target
        .depth_m
        .iter()
        .zip(&truth.depth_m)
        .map(|(a, b)| a - b)
        .collect()
}

#[test]
fn subpixel_matches_are_closer_to_the_true_depths_and_smoother() {
    // The true surfaces matched at 128²: integer matches snap each pixel's depth to
    // where its ray meets the other view's pixel rays; the parabola's vertex between
    // them must lower both the error and its pixel-to-pixel variation (the slope noise
    // Eq. 3.4 hands to the surface).
    let (cams, truth) = sphere_ring(128, 2);
    let (left, right) = (plain(&cams[0], &truth[0]), plain(&cams[1], &truth[1]));
    let run = |subpixel: SubPixel| {
        let params = MatchingParams {
            subpixel,
            ..MatchingParams::default()
        };
        match_pair(&left, &right, None, &params).unwrap()
    };
    let (whole, sub) = (run(SubPixel::Off), run(SubPixel::PathFit));
    let parabola = run(SubPixel::CostParabola);
    // The same path and matches: only the depths move.
    assert_eq!(whole.stats, sub.stats);
    let w = truth[0].width as usize;
    let summary = |m: &PairMatches| {
        let e = target_errors(&m.left.target, &truth[0]);
        let mut abs: Vec<f64> = e.iter().filter(|x| !x.is_nan()).map(|x| x.abs()).collect();
        abs.sort_by(f64::total_cmp);
        // Differences of the error between horizontally neighbouring matched pixels.
        let mut steps: Vec<f64> = (0..e.len())
            .filter(|&i| (i + 1) % w != 0 && !e[i].is_nan() && !e[i + 1].is_nan())
            .map(|i| (e[i + 1] - e[i]).abs())
            .collect();
        steps.sort_by(f64::total_cmp);
        let mean_step = steps.iter().sum::<f64>() / steps.len() as f64;
        (abs[abs.len() / 2], mean_step, abs.len())
    };
    let (med_whole, step_whole, n_whole) = summary(&whole);
    let (med_sub, step_sub, n_sub) = summary(&sub);
    let (med_par, step_par, _) = summary(&parabola);
    println!(
        "median |error| / mean step, mm: whole {:.3} / {:.3}, cost parabola {:.3} / {:.3}, path fit {:.3} / {:.3}",
        med_whole * 1e3, step_whole * 1e3, med_par * 1e3, step_par * 1e3, med_sub * 1e3, step_sub * 1e3
    );
    assert_eq!(n_whole, n_sub, "matched pixels");
    assert!(n_sub > 500, "{n_sub} matched pixels");
    assert!(
        med_sub < 0.9 * med_whole && step_sub < 0.9 * step_whole,
        "median |error| {med_whole} → {med_sub} m, mean step {step_whole} → {step_sub} m"
    );
}

#[test]
fn matching_true_surfaces_recovers_their_depths_and_bad_input_is_an_error() {
    let (cams, truth) = sphere_pair();
    let (left, right) = (plain(&cams[0], &truth[0]), plain(&cams[1], &truth[1]));
    let m = match_pair(&left, &right, None, &MatchingParams::default()).unwrap();
    assert!(m.stats.good_matches > 300, "{:?}", m.stats);
    let mut err: Vec<f64> = m
        .left
        .target
        .depth_m
        .iter()
        .zip(&truth[0].depth_m)
        .filter(|(a, b)| !a.is_nan() && !b.is_nan())
        .map(|(a, b)| (a - b).abs())
        .collect();
    err.sort_by(f64::total_cmp);
    // A 96² pixel covers ≈ 1.4 cm at 3 m: matches are within a pixel's footprint.
    let median = err[err.len() / 2];
    assert!(median < 0.01, "{median}");
    let distorted = cams[0]
        .clone()
        .with_distortion(skin_core::camera::RadialDistortion::new(
            -0.1,
            DVec2::new(48.0, 48.0),
        ));
    let bad = plain(&distorted, &truth[0]);
    assert!(match_pair(&bad, &right, None, &MatchingParams::default()).is_err());
    let even = MatchingParams {
        window_px: 4,
        ..MatchingParams::default()
    };
    assert!(match_pair(&left, &right, None, &even).is_err());
    let image_metric = MatchingParams {
        metric: MatchMetric::FullOnWindow,
        ..MatchingParams::default()
    };
    assert!(match_pair(&left, &right, None, &image_metric).is_err());
}

/// A bumpy box 0.5 m in front of a bumpy backdrop (one height field over the plane
/// z = 0, facing +z), seen by two cameras 3 m away and 45° apart, with the true depth maps.
fn box_pair(size: u32) -> (Vec<Camera>, Vec<DepthMap>) {
    use skin_core::camera::Intrinsics;
    let k = Intrinsics::from_horizontal_fov(0.5, size, size).unwrap();
    let eye = |a: f64| DVec3::new(3.0 * a.sin(), 0.0, 3.0 * a.cos());
    let a = std::f64::consts::FRAC_PI_8;
    let cams: Vec<Camera> = [-a, a]
        .iter()
        .map(|&t| Camera::look_at(k, eye(t), DVec3::ZERO, DVec3::Y).unwrap())
        .collect();
    let n = 241;
    let coord = |i: usize| -1.2 + 2.4 * i as f64 / (n - 1) as f64;
    let mut vertices = Vec::with_capacity(n * n);
    for j in 0..n {
        for i in 0..n {
            let (x, y) = (coord(i), coord(j));
            let front = x.abs() < 0.2 && y.abs() < 0.3;
            let z = if front { 0.1 } else { -0.4 };
            let bumps = 0.02 * (17.0 * x).sin() * (13.0 * y).cos();
            vertices.push(DVec3::new(x, y, z + bumps));
        }
    }
    let mut faces = Vec::new();
    let at = |i: usize, j: usize| (j * n + i) as u32;
    for j in 0..n - 1 {
        for i in 0..n - 1 {
            faces.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
            faces.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
        }
    }
    let mesh = TriMesh::new(vertices, faces).unwrap();
    let depths = cams
        .iter()
        .map(|c| mesh_proxy_depth(c, &mesh).unwrap())
        .collect();
    (cams, depths)
}

#[test]
fn contour_windows_give_fewer_gross_matches_beside_a_step_and_bad_input_is_an_error() {
    // Exact surfaces of a box in front of a backdrop: the whole 5 × 5 windows of the
    // thesis straddle the box's edges, whose background differs between the views (each
    // sees another stretch of the backdrop beside the box), so matches beside the step go
    // wrong; windows keeping only their centre's side must give at least 3× fewer (300 →
    // 57 when written).
    let size = 192;
    let (cams, truth) = box_pair(size);
    let (left, right) = (plain(&cams[0], &truth[0]), plain(&cams[1], &truth[1]));
    let run = |contour_jump_m: Option<f64>| {
        let params = MatchingParams {
            contour_jump_m,
            ..MatchingParams::default()
        };
        match_pair(&left, &right, None, &params).unwrap()
    };
    let (whole, contour) = (run(None), run(Some(0.01)));
    // Pixels within 3 px of a true depth jump of more than 10 cm (the box's edges).
    let w = size as usize;
    let d = &truth[0].depth_m;
    let jump = |i: usize, j: usize| (d[i] - d[j]).abs() > 0.1;
    let mut edge = vec![false; d.len()];
    for (i, e) in edge.iter_mut().enumerate() {
        let (x, y) = (i % w, i / w);
        *e = (x + 1 < w && jump(i, i + 1)) || (y + 1 < w && jump(i, i + w));
    }
    let near = |i: usize| {
        let (x, y) = ((i % w) as i64, (i / w) as i64);
        (-3..=3i64).any(|dy| {
            (-3..=3i64).any(|dx| {
                let (u, v) = (x + dx, y + dy);
                u >= 0
                    && v >= 0
                    && u < w as i64
                    && v < w as i64
                    && edge[(v * w as i64 + u) as usize]
            })
        })
    };
    // Matches more than 1 cm off (a 192² pixel covers ≈ 8 mm at 3 m), and all matches,
    // beside the step.
    let count = |m: &PairMatches| {
        let e = target_errors(&m.left.target, &truth[0]);
        let beside: Vec<f64> = (0..e.len())
            .filter(|&i| near(i) && !e[i].is_nan())
            .map(|i| e[i])
            .collect();
        let gross = beside.iter().filter(|x| x.abs() > 0.01).count();
        let all = e.iter().filter(|x| !x.is_nan()).count();
        (gross, beside.len(), all)
    };
    let (gross_whole, beside_whole, all_whole) = count(&whole);
    let (gross_contour, beside_contour, all_contour) = count(&contour);
    println!(
        "beside the step: > 1 cm off {gross_whole} of {beside_whole} (whole windows) → \
         {gross_contour} of {beside_contour} (contour windows); matched pixels {all_whole} → {all_contour}"
    );
    assert!(
        gross_whole >= 20,
        "the step must trouble whole windows: {gross_whole}"
    );
    assert!(
        3 * gross_contour <= gross_whole,
        "gross matches beside the step {gross_whole} → {gross_contour}"
    );
    // Not by matching less: at least as many matched pixels overall.
    assert!(
        10 * all_contour >= 9 * all_whole,
        "{all_whole} → {all_contour}"
    );
    for bad in [0.0, -0.01, f64::NAN] {
        let params = MatchingParams {
            contour_jump_m: Some(bad),
            ..MatchingParams::default()
        };
        assert!(match_pair(&left, &right, None, &params).is_err(), "{bad}");
    }
}

/// The reference: the four-state programme over every node of the `(na + 1) × (nb + 1)`
/// grid, as it was before the band-only form ([`lowest_cost_path`]).
pub(super) fn lowest_cost_path_dense(
    costs: &[f64],
    na: usize,
    nb: usize,
    occ: f64,
    disc: f64,
) -> Vec<(usize, usize)> {
    let (ri, rj) = (na + 1, nb + 1);
    let at = |i: usize, j: usize| i * rj + j;
    // The costs of rows i − 1 and i (rolling); the back-pointers of all cells.
    let mut above = vec![[f64::INFINITY; 4]; rj];
    let mut here = vec![[f64::INFINITY; 4]; rj];
    let mut from = vec![[u8::MAX; 4]; ri * rj];
    let matched = |s: usize| s == LV || s == RV;
    let offer = |s: usize, v: f64, p: usize, best: &mut [f64; 4], arg: &mut [u8; 4]| {
        if v < best[s] {
            best[s] = v;
            arg[s] = p as u8;
        }
    };
    for i in 0..ri {
        for j in 0..rj {
            if i == 0 && j == 0 {
                here[0] = [f64::INFINITY; 4];
                here[0][LO] = 0.0;
                continue;
            }
            let mut best = [f64::INFINITY; 4];
            let mut arg = [u8::MAX; 4];
            if i > 0 && j > 0 {
                let c = costs[(i - 1) * nb + (j - 1)];
                if c.is_finite() {
                    // Diagonal match from any state; left-slanted from a match at (i−1, j).
                    for (p, &prev) in above[j - 1].iter().enumerate() {
                        let pen = if matched(p) { 0.0 } else { disc };
                        offer(LV, prev + c + pen, p, &mut best, &mut arg);
                    }
                    for p in [LV, RV] {
                        offer(LV, above[j][p] + c, 4 + p, &mut best, &mut arg);
                        offer(RV, here[j - 1][p] + c, p, &mut best, &mut arg);
                    }
                }
            }
            if i > 0 {
                for (p, &prev) in above[j].iter().enumerate() {
                    let pen = if matched(p) { disc } else { 0.0 };
                    offer(LO, prev + occ + pen, p, &mut best, &mut arg);
                }
            }
            if j > 0 {
                for (p, &prev) in here[j - 1].iter().enumerate() {
                    let pen = if matched(p) { disc } else { 0.0 };
                    offer(RO, prev + occ + pen, p, &mut best, &mut arg);
                }
            }
            here[j] = best;
            from[at(i, j)] = arg;
        }
        std::mem::swap(&mut above, &mut here);
    }
    // Backtrack from the cheapest end state (row na is `above` after the last swap).
    let end = above[nb];
    let Some(mut s) = (0..4)
        .filter(|&s| end[s].is_finite())
        .min_by(|&a, &b| end[a].total_cmp(&end[b]))
    else {
        return Vec::new();
    };
    let (mut i, mut j) = (na, nb);
    let mut path = Vec::new();
    while i > 0 || j > 0 {
        let p = from[at(i, j)][s];
        if p == u8::MAX {
            break;
        }
        let p = p as usize;
        match s {
            LV => {
                path.push((i - 1, j - 1));
                if p >= 4 {
                    i -= 1;
                    s = p - 4;
                } else {
                    i -= 1;
                    j -= 1;
                    s = p;
                }
            }
            RV => {
                path.push((i - 1, j - 1));
                j -= 1;
                s = p;
            }
            LO => {
                i -= 1;
                s = p;
            }
            _ => {
                j -= 1;
                s = p;
            }
        }
    }
    path.reverse();
    path
}

/// The rows' ranges of finite cells.
fn row_ranges(costs: &[f64], na: usize, nb: usize) -> Vec<(usize, usize)> {
    (0..na)
        .map(|a| {
            let row = &costs[a * nb..(a + 1) * nb];
            match row.iter().position(|c| c.is_finite()) {
                None => (0, 0),
                Some(lo) => (
                    lo,
                    nb - row.iter().rev().position(|c| c.is_finite()).unwrap_or(0),
                ),
            }
        })
        .collect()
}

#[test]
fn band_only_programme_finds_the_paths_of_the_full_grid() {
    // Random bands of random costs (some holes), random penalties: the band-only form
    // returns the dense programme's path on every grid.
    let mut uniform = uniform_draws(11);
    let mut compared = 0;
    for trial in 0..400 {
        let na = 1 + (uniform() * 40.0) as usize;
        let nb = 1 + (uniform() * 40.0) as usize;
        let half = 1.0 + uniform() * 8.0;
        let slope = nb as f64 / na as f64 * (0.6 + 0.8 * uniform());
        let shift = (uniform() - 0.5) * 10.0;
        let costs: Vec<f64> = (0..na * nb)
            .map(|k| {
                let (a, b) = (k / nb, k % nb);
                let inside = ((b as f64) - (a as f64 * slope + shift)).abs() <= half;
                if inside && uniform() > 0.1 {
                    uniform() * uniform()
                } else {
                    f64::INFINITY
                }
            })
            .collect();
        let (occ, disc) = (0.2 + uniform(), 2.0 * uniform());
        let dense = lowest_cost_path_dense(&costs, na, nb, occ, disc);
        let band = lowest_cost_path(&costs, na, nb, &row_ranges(&costs, na, nb), occ, disc);
        assert_eq!(
            dense, band,
            "trial {trial}: {na} × {nb}, occ {occ}, disc {disc}"
        );
        compared += dense.len();
    }
    assert!(compared > 1000, "{compared} matches compared");
}

fn bits(d: &DepthMap) -> Vec<u64> {
    d.depth_m.iter().map(|v| v.to_bits()).collect()
}

/// Runs `f` on a rayon pool of its own whose threads use the dense programme.
fn on_dense_pool<T: Send>(f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .start_handler(|_| DENSE_PROGRAMME.with(|d| d.set(true)))
        .build()
        .unwrap()
        .install(f)
}

#[test]
fn band_only_matching_equals_the_dense_programme_and_coarse_to_fine_keeps_the_accuracy() {
    // A pair at 192² with the hull of the whole ring: the band-only programme gives the
    // same matches, bit for bit, as the dense one (the form before).
    let (cams, truth) = sphere_ring(192, 8);
    let masks: Vec<Mask> = truth
        .iter()
        .map(|d| {
            Mask::from_fn(d.width, d.height, |x, y| {
                !d.depth_m[(y * d.width + x) as usize].is_nan()
            })
        })
        .collect();
    let hull = PolygonalHull::new(&cams, &masks).unwrap();
    let (left, right) = (plain(&cams[0], &truth[0]), plain(&cams[1], &truth[1]));
    let params = MatchingParams {
        coarse_to_fine: false,
        ..MatchingParams::default()
    };
    let band = match_pair(&left, &right, Some(&hull), &params).unwrap();
    let dense = on_dense_pool(|| match_pair(&left, &right, Some(&hull), &params)).unwrap();
    assert_eq!(band.stats, dense.stats);
    assert!(band.stats.good_matches > 2000, "{:?}", band.stats);
    for (b, d) in [(&band.left, &dense.left), (&band.right, &dense.right)] {
        assert_eq!(bits(&b.target), bits(&d.target));
        assert_eq!(b.breaks, d.breaks);
    }
    // Coarse-to-fine: far fewer cells, and the matches as close to the truth (median
    // within a tenth of a pixel footprint, ≈ 0.5 mm here).
    let c2f = MatchingParams {
        coarse_to_fine: true,
        ..params
    };
    let fine = match_pair(&left, &right, Some(&hull), &c2f).unwrap();
    let err = |m: &PairMatches| {
        let e = crate::depth_errors(&m.left.target, &truth[0], None).unwrap();
        (e.median_mm, e.p95_mm, e.pixels)
    };
    let (full_e, fine_e) = (err(&band), err(&fine));
    eprintln!(
        "full {:?} {full_e:?}\ncoarse-to-fine {:?} {fine_e:?}",
        band.stats, fine.stats
    );
    assert!(
        fine.stats.cells_evaluated * 4 < band.stats.cells_evaluated * 3,
        "{:?} vs {:?}",
        fine.stats,
        band.stats
    );
    assert!(fine_e.0 <= full_e.0 + 0.5, "{fine_e:?} vs {full_e:?}");
    assert!(
        fine_e.2 as f64 >= 0.95 * full_e.2 as f64,
        "{fine_e:?} vs {full_e:?}"
    );
    // Too small for a coarse level: the same as without.
    let (small, small_truth) = sphere_pair();
    let (l, r) = (
        plain(&small[0], &small_truth[0]),
        plain(&small[1], &small_truth[1]),
    );
    let a = match_pair(&l, &r, None, &params).unwrap();
    let b = match_pair(&l, &r, None, &c2f).unwrap();
    assert_eq!(bits(&a.left.target), bits(&b.left.target));
    let bad = MatchingParams {
        coarse_band_px: f64::NAN,
        ..c2f
    };
    assert!(match_pair(&l, &r, None, &bad).is_err());
}

#[test]
fn dynamic_programme_follows_the_cheap_diagonal_and_skips_an_occlusion() {
    // 6 × 6 grid: cheap along a = b except that left sample 2 has no good match.
    let (na, nb) = (6, 6);
    let mut costs = vec![1.0; na * nb];
    for k in 0..6 {
        costs[k * nb + k] = 0.01;
    }
    costs[2 * nb + 2] = f64::INFINITY;
    let path = lowest_cost_path(&costs, na, nb, &row_ranges(&costs, na, nb), 0.5, 0.1);
    assert!(path.contains(&(0, 0)) && path.contains(&(5, 5)), "{path:?}");
    assert!(!path.iter().any(|&(a, _)| a == 2), "{path:?}");
    let none = lowest_cost_path(&[f64::INFINITY; 4], 2, 2, &[(0, 0); 2], 0.5, 0.1);
    assert!(none.is_empty());
}

#[test]
fn given_camera_rays_match_to_the_bit_and_rays_of_another_size_are_an_error() {
    // 128² so that the pair is matched coarse to fine (the half-resolution pass computes its
    // own rays).
    let (cams, truth) = sphere_ring(128, 2);
    let (left, right) = (plain(&cams[0], &truth[0]), plain(&cams[1], &truth[1]));
    let params = MatchingParams::default();
    let own = match_pair(&left, &right, None, &params).unwrap();
    let rays: Vec<Vec<DVec3>> = cams.iter().map(|c| camera_rays(c).unwrap()).collect();
    let given = |r: [&[DVec3]; 2]| match_pair_with_rays(&left, &right, None, &params, Some(r));
    let cached = given([&rays[0], &rays[1]]).unwrap();
    for (a, b) in [(&own.left, &cached.left), (&own.right, &cached.right)] {
        assert_eq!(bits(&a.target), bits(&b.target));
        assert_eq!(a.breaks, b.breaks);
    }
    assert_eq!(own.stats, cached.stats);
    // The given rays are the ones used: the two cameras' swapped change the matches.
    let swapped = given([&rays[1], &rays[0]]).unwrap();
    assert_ne!(bits(&own.left.target), bits(&swapped.left.target));
    let short = given([&rays[0][1..], &rays[1]]);
    let message = short.expect_err("rays of another size").to_string();
    assert!(message.contains("camera rays"), "{message}");
}
