//! One epipolar plane: its grid of costs in the band, the lowest-cost path, sub-pixel
//! matches, good matches and depth discontinuities.

use skin_core::math::DVec3;
use skin_core::stats::median;

use crate::integrate::IntegrationParams;
use crate::PolygonalHull;

use super::batch::{window_distances, Fixed, Scratch};
use super::epipolar::{Line, Prepared};
use super::epipolar_dp::lowest_cost_path;
use super::metrics::{projected_difference, window_difference, Windows};
use super::params::{MatchMetric, MatchingParams, SubPixel};

/// One plane's result: good matches (left pixel, right pixel, depth along each ray) and break
/// pixels.
#[derive(Default)]
pub(super) struct PlaneResult {
    pub(super) matches: Vec<(usize, usize, f64, f64)>,
    pub(super) left_breaks: Vec<usize>,
    pub(super) right_breaks: Vec<usize>,
    pub(super) evaluated: usize,
    pub(super) path_matches: usize,
    /// Every match of the path (left pixel, right pixel, depth along each ray).
    pub(super) path: Vec<(usize, usize, f64, f64)>,
}

/// Coarse-to-fine: the median cost (the unit of the occlusion cost and the good-match
/// threshold) is estimated from every this-many-th cell of the whole band.
pub(super) const MEDIAN_STRIDE: usize = 8;

/// Whether a depth lies in a coarse-to-fine interval (always, without one).
pub(super) fn within(t: f64, interval: Option<(f64, f64)>) -> bool {
    interval.is_none_or(|(lo, hi)| t >= lo && t <= hi)
}

#[allow(clippy::too_many_arguments)]
pub(super) fn match_plane(
    pl: &Prepared<'_>,
    pr: &Prepared<'_>,
    ll: &Line,
    lr: &Line,
    hull: Option<&PolygonalHull>,
    params: &MatchingParams,
    half: i64,
    jump: f64,
) -> PlaneResult {
    let (na, nb) = (ll.pixels.len(), lr.pixels.len());
    let mut out = PlaneResult::default();
    if na == 0 || nb == 0 {
        return out;
    }
    let mut costs = vec![f64::INFINITY; na * nb];
    let mut stack = (Vec::new(), Vec::new());
    // Per row: the cells to evaluate (right sample, in the narrow band, in the median's
    // sample) and their costs, with the surface metric's scratch space.
    let (mut candidates, mut row_costs) = (Vec::new(), Vec::new());
    let (mut bs, mut sides) = (Vec::new(), (Vec::new(), Vec::new()));
    let mut batch = Scratch::default();
    // Per sample, once per plane: the guide depth, the ray's dot with the centres' offset
    // (closest approach then costs one dot product per cell) and, for the surface metric,
    // the pixel of the sample's surface point in the other view.
    let w = pl.centre - pr.centre;
    let guide_b: Vec<f64> = lr.pixels.iter().map(|&i| pr.guide.depth_m[i]).collect();
    let e_b: Vec<f64> = lr.rays.iter().map(|r| r.dot(w)).collect();
    let surface = params.metric == MatchMetric::SurfaceRigid;
    // The surface metric's windows: around each sample in its own surface, and around the
    // pixel of the sample's point in the other view's rendering of this surface.
    // Contour-aware windows: the camera centre and the jump per pixel at the view's width.
    let contour = |view: &Prepared<'_>| {
        params.contour_jump_m.map(|j| {
            (
                view.centre,
                IntegrationParams::jump_threshold_m(j, view.width),
            )
        })
    };
    let windows = |own: &Prepared<'_>, to: &Prepared<'_>, pixels: &[usize]| {
        let n = if surface { pixels.len() } else { 0 };
        let own_windows = Windows::gather(
            &own.points,
            (own.width, own.height),
            pixels[..n].iter().map(|&i| Some(i)),
            half,
            contour(own),
        );
        let centres = pixels[..n]
            .iter()
            .map(|&i| own.points[i].and_then(|x| to.pixel_of(x)));
        let other_windows = Windows::gather(
            &to.other_points,
            (to.width, to.height),
            centres,
            half,
            contour(to),
        );
        (own_windows, other_windows)
    };
    let (own_a, in_right_a) = windows(pl, pr, &ll.pixels);
    let (own_b, in_left_b) = windows(pr, pl, &lr.pixels);
    // Per row, the range of the cells evaluated (the band the programme works in).
    let mut rows = vec![(0usize, 0usize); na];
    // The unit of the costs is the median over the whole band. Coarse-to-fine evaluates a
    // narrow band around the coarse path, whose costs are lower than the band's (they are
    // the likely matches): there the median is taken of every `MEDIAN_STRIDE`-th cell of the
    // whole band, so that the occlusion cost and the good-match threshold keep their meaning.
    let stride = if pl.narrow.is_some() || pr.narrow.is_some() {
        MEDIAN_STRIDE
    } else {
        1
    };
    let (mut band_cells, mut sample) = (0usize, Vec::new());
    for a in 0..na {
        let ia = ll.pixels[a];
        let guide_a = pl.guide.depth_m[ia];
        if guide_a.is_nan() {
            continue;
        }
        let narrow_a = pl.narrow(ia);
        let ray_a = ll.rays[a];
        let d_a = ray_a.dot(w);
        candidates.clear();
        row_costs.clear();
        for b in 0..nb {
            let gb = guide_b[b];
            if gb.is_nan() {
                continue;
            }
            // `closest_approach`, term for term.
            let ray_b = lr.rays[b];
            let Some((ta, tb)) = meet(ray_a, d_a, ray_b, e_b[b]) else {
                continue;
            };
            if (ta - guide_a).abs() > params.band_m || (tb - gb).abs() > params.band_m {
                continue;
            }
            // Coarse-to-fine: cells outside the narrow band are evaluated only as the
            // median's sample (every `stride`-th cell of the whole band).
            let narrow = within(ta, narrow_a) && within(tb, pr.narrow(lr.pixels[b]));
            let sampled = band_cells.is_multiple_of(stride);
            band_cells += 1;
            if !(narrow || sampled) {
                continue;
            }
            let (pa, pb) = (pl.centre + ray_a * ta, pr.centre + ray_b * tb);
            if (pa - pb).length() > 2.0 * pl.pixel_footprint(ta).max(pr.pixel_footprint(tb)) {
                continue;
            }
            let ib = lr.pixels[b];
            let x = 0.5 * (pl.centre + ray_a * ta + pr.centre + ray_b * tb);
            if hull.is_some_and(|h| !h.contains(x)) {
                continue;
            }
            let (true, Some(xb)) = (pl.points[ia].is_some(), pr.points[ib]) else {
                continue;
            };
            let c = match params.metric {
                // The row's comparisons all at once, below.
                MatchMetric::SurfaceRigid => f64::NAN,
                MatchMetric::FullOnWindow | MatchMetric::IlluminationStack => {
                    let from = usize::from(params.metric == MatchMetric::IlluminationStack);
                    window_difference(pl, pr, ia, ib, half, from, &mut stack)
                }
                MatchMetric::ProjectedIllumination => {
                    projected_difference(pl, pr, ia, xb, half, &mut stack)
                }
            };
            candidates.push((b, narrow, sampled));
            row_costs.push(c);
        }
        if surface {
            // Both windows' distances for every cell of the row; the cost is the larger of
            // the two (∞ when the first is).
            bs.clear();
            bs.extend(candidates.iter().map(|c| c.0));
            let (left, right) = &mut sides;
            window_distances((&own_a, a), &in_left_b, &bs, Fixed::Own, &mut batch, left);
            window_distances(
                (&in_right_a, a),
                &own_b,
                &bs,
                Fixed::Other,
                &mut batch,
                right,
            );
            for ((c, &l), &r) in row_costs.iter_mut().zip(left.iter()).zip(right.iter()) {
                *c = if l == f64::INFINITY { l } else { l.max(r) };
            }
        }
        for (&(b, narrow, sampled), &c) in candidates.iter().zip(&row_costs) {
            out.evaluated += 1;
            if sampled && c.is_finite() {
                sample.push(c);
            }
            if !narrow {
                continue;
            }
            costs[a * nb + b] = c;
            let r = &mut rows[a];
            *r = if r.0 == r.1 { (b, b + 1) } else { (r.0, b + 1) };
        }
    }
    if sample.is_empty() || rows.iter().all(|r| r.0 == r.1) {
        return out;
    }
    let unit = median(&sample).max(1e-12);
    let (occ, disc) = (
        params.occlusion_cost * unit,
        params.discontinuity_penalty * unit,
    );
    #[cfg(test)]
    let path = if DENSE_PROGRAMME.with(std::cell::Cell::get) {
        super::tests::lowest_cost_path_dense(&costs, na, nb, occ, disc)
    } else {
        lowest_cost_path(&costs, na, nb, &rows, occ, disc)
    };
    #[cfg(not(test))]
    let path = lowest_cost_path(&costs, na, nb, &rows, occ, disc);
    out.path_matches = path.len();
    let mut prev: Option<(usize, usize, f64, f64)> = None;
    // The path's matches as samples (a, b), whether good, and whether a discontinuity lies
    // between each and the one before.
    let mut kept: Vec<(usize, usize, bool, bool)> = Vec::with_capacity(path.len());
    for &(a, b) in &path {
        // The cell's point again (path cells are evaluated cells, whose rays meet).
        let (ray_a, ray_b) = (ll.rays[a], lr.rays[b]);
        let Some((ta, tb)) = meet(ray_a, ray_a.dot(w), ray_b, ray_b.dot(w)) else {
            continue;
        };
        let x = 0.5 * (pl.centre + ray_a * ta + pr.centre + ray_b * tb);
        let (ia, ib) = (ll.pixels[a], lr.pixels[b]);
        let (za, zb) = ((x - pl.centre).length(), (x - pr.centre).length());
        let mut broken = false;
        if let Some((pa, pb, pza, pzb)) = prev {
            // Jumps per pixel of the matched depth between consecutive matches.
            let step_a = pixel_distance(pa, ia, pl.width).max(1.0);
            let step_b = pixel_distance(pb, ib, pr.width).max(1.0);
            if (za - pza).abs() / step_a > jump || (zb - pzb).abs() / step_b > jump {
                out.left_breaks.extend([pa, ia]);
                out.right_breaks.extend([pb, ib]);
                broken = true;
            }
        }
        prev = Some((ia, ib, za, zb));
        out.path.push((ia, ib, za, zb));
        kept.push((a, b, costs[a * nb + b] <= params.good_cost * unit, broken));
    }
    // The depth along the left ray `a` where it meets the right sample `b`, and along the
    // right ray `b`.
    let depths = |a: usize, b: usize| -> Option<(f64, f64)> {
        let (ray_a, ray_b) = (ll.rays[a], lr.rays[b]);
        let (ta, tb) = meet(ray_a, ray_a.dot(w), ray_b, ray_b.dot(w))?;
        let x = 0.5 * (pl.centre + ray_a * ta + pr.centre + ray_b * tb);
        Some(((x - pl.centre).length(), (x - pr.centre).length()))
    };
    // Sub-pixel positions: per kept match, the fractional right sample for the left view's
    // depth and the fractional left sample for the right view's.
    let fractional: Vec<(f64, f64)> = match params.subpixel {
        SubPixel::Off => kept.iter().map(|k| (k.1 as f64, k.0 as f64)).collect(),
        SubPixel::CostParabola => kept
            .iter()
            .map(|&(a, b, _, _)| {
                let cost = |i: usize, j: usize| costs[i * nb + j];
                let along_b = (b > 0 && b + 1 < nb)
                    .then(|| parabola_vertex(cost(a, b - 1), cost(a, b), cost(a, b + 1)))
                    .flatten()
                    .unwrap_or(0.0);
                let along_a = (a > 0 && a + 1 < na)
                    .then(|| parabola_vertex(cost(a - 1, b), cost(a, b), cost(a + 1, b)))
                    .flatten()
                    .unwrap_or(0.0);
                (b as f64 + along_b, a as f64 + along_a)
            })
            .collect(),
        SubPixel::PathFit => path_fit(&kept, params.subpixel_window),
    };
    for (&(a, b, good, _), &(fb, fa)) in kept.iter().zip(&fractional) {
        if !good {
            continue;
        }
        let Some((za, zb)) = depths(a, b) else {
            continue;
        };
        // Linear interpolation of the depth between the two samples around the fractional
        // position (the match's own depth where it is whole or a neighbour is missing).
        let between = |f: f64, n: usize, z: f64, at: &dyn Fn(usize) -> Option<f64>| -> f64 {
            let f = f.clamp(0.0, (n - 1) as f64);
            let lo = f.floor() as usize;
            let t = f - lo as f64;
            if t == 0.0 {
                return at(lo).unwrap_or(z);
            }
            match (at(lo), at((lo + 1).min(n - 1))) {
                (Some(u), Some(v)) => u + t * (v - u),
                _ => z,
            }
        };
        let za = between(fb, nb, za, &|j| depths(a, j).map(|d| d.0));
        let zb = between(fa, na, zb, &|i| depths(i, b).map(|d| d.1));
        out.matches.push((ll.pixels[a], lr.pixels[b], za, zb));
    }
    out
}

/// [`SubPixel::PathFit`]: per match `k` of the path (samples `a`, `b`; a discontinuity
/// before it ends a run), the least-squares lines `b(a)` and `a(b)` through the matches of
/// its run within `half` path steps each side (the run also ends where the path skips an
/// occlusion), evaluated at the match: (fractional b, fractional a). A run of one keeps the
/// whole samples.
pub(super) fn path_fit(kept: &[(usize, usize, bool, bool)], half: usize) -> Vec<(f64, f64)> {
    let n = kept.len();
    // Run index per match.
    let mut run = vec![0usize; n];
    for k in 1..n {
        let (pa, pb, _, _) = kept[k - 1];
        let (a, b, _, broken) = kept[k];
        let skip = a > pa + 1 || b > pb + 1;
        run[k] = run[k - 1] + usize::from(broken || skip);
    }
    let fit = |xs: &[f64], ys: &[f64], x: f64, y: f64| -> f64 {
        let m = xs.len() as f64;
        let (mx, my) = (xs.iter().sum::<f64>() / m, ys.iter().sum::<f64>() / m);
        let sxx: f64 = xs.iter().map(|u| (u - mx) * (u - mx)).sum();
        let sxy: f64 = xs.iter().zip(ys).map(|(u, v)| (u - mx) * (v - my)).sum();
        let est = if sxx > 1e-12 {
            my + sxy / sxx * (x - mx)
        } else {
            my
        };
        // Never more than a sample from the match itself.
        est.clamp(y - 1.0, y + 1.0)
    };
    (0..n)
        .map(|k| {
            let lo = (k.saturating_sub(half)..=k)
                .find(|&j| run[j] == run[k])
                .unwrap_or(k);
            let hi = (k..=(k + half).min(n - 1))
                .rev()
                .find(|&j| run[j] == run[k])
                .unwrap_or(k);
            let (a, b) = (kept[k].0 as f64, kept[k].1 as f64);
            if hi == lo {
                return (b, a);
            }
            let xa: Vec<f64> = kept[lo..=hi].iter().map(|m| m.0 as f64).collect();
            let xb: Vec<f64> = kept[lo..=hi].iter().map(|m| m.1 as f64).collect();
            (fit(&xa, &xb, a, b), fit(&xb, &xa, b, a))
        })
        .collect()
}

/// The vertex of the parabola through `(−1, lo)`, `(0, mid)`, `(1, hi)`, clamped to ±½;
/// `None` if a value is not finite or the parabola does not open upward.
pub(super) fn parabola_vertex(lo: f64, mid: f64, hi: f64) -> Option<f64> {
    if !(lo.is_finite() && mid.is_finite() && hi.is_finite()) {
        return None;
    }
    let curvature = lo - 2.0 * mid + hi;
    if curvature <= 0.0 {
        return None;
    }
    Some((0.5 * (lo - hi) / curvature).clamp(-0.5, 0.5))
}

/// Where two rays (unit directions `ray_a`, `ray_b` from the two centres, and their dot
/// products `d_a`, `e_b` with the centres' offset `left − right`) come closest: the
/// parameters along each, `None` for parallel rays.
pub(super) fn meet(ray_a: DVec3, d_a: f64, ray_b: DVec3, e_b: f64) -> Option<(f64, f64)> {
    let dot = ray_a.dot(ray_b);
    let denom = 1.0 - dot * dot;
    if denom < 1e-12 {
        return None;
    }
    Some(((dot * e_b - d_a) / denom, (e_b - dot * d_a) / denom))
}

pub(super) fn pixel_distance(i: usize, j: usize, width: u32) -> f64 {
    let w = width as usize;
    let (xi, yi, xj, yj) = (i % w, i / w, j % w, j / w);
    ((xi as f64 - xj as f64).powi(2) + (yi as f64 - yj as f64).powi(2)).sqrt()
}

// Tests only: match with the dense programme over every grid node (the form before the
// band-only one), to compare whole pairs. Thread-local and set only on the threads of a
// dedicated rayon pool (`tests::on_dense_pool`), so tests running beside that one keep the
// band-only programme (a process-wide flag made them see the dense one's tie-breaks).
#[cfg(test)]
thread_local! {
    pub(super) static DENSE_PROGRAMME: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}
