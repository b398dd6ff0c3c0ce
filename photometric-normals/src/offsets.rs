//! Depth offsets that pull an integrated surface to its matches (Vlasic 2010 §3.3.2,
//! Eq. 3.4):
//!
//! ```text
//! argmin_d  Σ_i Σ_j∈N(i) (d_i − d_j)²  +  β Σ_i (d_i − d̄_i)²      (3.4)
//! ```
//!
//! over the pixels of the view's surface, `N(i)` its 4-neighbours with a surface and `d̄_i`
//! the offset the matches ask for (matched depth minus integrated depth, the mean over the
//! neighbouring views that matched the pixel). The first term is a membrane: each offset is
//! pulled toward the centroid of its neighbours' offsets, so the constraints are smoothly
//! interpolated and the surface keeps its high-frequency detail (only the smooth offset field
//! is added). Regions far from any constraint would be deformed freely, so pixels farther
//! than [`OffsetParams::max_distance_px`] from the nearest matched pixel are discarded, as
//! are regions with no constraint at all. Solved with [`skin_core::lsq`].

use nalgebra::DMatrix;
use nalgebra_sparse::{CooMatrix, CscMatrix};
use serde::{Deserialize, Serialize};
use skin_core::check;
use skin_core::image::{distance_to_foreground, Mask};
use skin_core::lsq::{LsqParams, LsqProblem};

use std::time::Instant;

use rayon::prelude::*;
use skin_core::camera::Camera;

use crate::integrate::{
    camera_rays, integrate_with_rays, neighbour_pairs, regions, IntegrationParams,
};
use crate::matching::match_pair_with_rays;
use crate::{
    depth_errors, Context, DepthErrors, DepthMap, Error, Integrated, IntegrationReport, MatchStats,
    MatchView, MatchingParams, NormalMap, PairMatches, PolygonalHull, Result, ResultExt,
};

/// Knobs of Eq. 3.4.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct OffsetParams {
    /// β, the weight of a match's offset against one neighbour difference of the membrane.
    /// The thesis gives no value; default 0.1 (ours): matches are quantised to the pixel grid
    /// (§3.3.2), so each is trusted a tenth of a neighbour link and the membrane averages
    /// their noise over a few pixels while still reaching them (with dense matches the offset
    /// field follows them to ≈ 1/√β ≈ 3 px).
    pub beta: f64,
    /// Pixels farther than this from the nearest matched pixel are discarded (px, at the
    /// thesis' 1024-px width and scaled like [`IntegrationParams::jump_threshold_m`]).
    /// Default 40 (ours).
    pub max_distance_px: f64,
    /// γ, the weight of each pixel's pull toward its proxy depth, `γ Σ_i (d_i − (p_i − z_i))²`
    /// (p the proxy's depth, z the integrated one), relative to one neighbour difference.
    /// 0 (the default, the thesis's Eq. 3.4) leaves it out. With γ > 0 ([`depth_offsets_guided`]
    /// with a proxy) a pixel with a proxy depth is never discarded: far from every match its
    /// offset relaxes to the proxy instead (pass 2's proxy is the pass-1 mesh). Ours.
    #[serde(default)]
    pub proxy_weight: f64,
    /// Matches farther than this from the proxy depth along the ray (m) are dropped before
    /// Eq. 3.4 ([`depth_offsets_guided`] with a proxy). `None` (default) keeps every match.
    /// Ours.
    #[serde(default)]
    pub proxy_gate_m: Option<f64>,
    /// Rejects matches whose asked offset is an outlier of the offsets asked around it
    /// ([`OffsetOutliers`]). Default `Some(OffsetOutliers::default())` (ours): at the thesis's
    /// 1024² it improved every Table 3.1 key and distance of both passes on the studio's skirt
    /// (docs: "Reliable matches in Eq. 3.4") for ≈ 3 % more CPU; `None` is the thesis's Eq. 3.4,
    /// which keeps every match.
    #[serde(default)]
    pub outliers: Option<OffsetOutliers>,
    /// Down-weights, rather than rejects, the matches the membrane cannot follow
    /// ([`RobustWeights`], iteratively reweighted solves). `None` (default, the thesis's
    /// Eq. 3.4) weights every match by β. Ours.
    #[serde(default)]
    pub robust: Option<RobustWeights>,
}

/// Rejection of unreliable matches before Eq. 3.4 (ours): the offset field
/// `d̄` must be smooth (it corrects the integrated surface's low-frequency error), so a match
/// whose asked offset differs from the median of the offsets asked by the matches within
/// [`OffsetOutliers::radius_px`] (on the same connected part of the surface, every
/// neighbouring view's matches pooled) by more than `max(k · 1.4826 · MAD, floor_m)` is a
/// wrong correspondence of the surface metric and is dropped. Each view's match is tested
/// on its own, so one view's gross match does not take the other view's good one with it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct OffsetOutliers {
    /// Window radius, px at the thesis's 1024-px width (scaled with the image width).
    pub radius_px: f64,
    /// Multiple of the robust standard deviation (1.4826 · MAD) allowed.
    pub k: f64,
    /// Smallest allowed deviation, m (the good matches' own scatter: ≈ a pixel's footprint).
    pub floor_m: f64,
    /// Fewest other matches in the window for the test to apply (below it, the match is kept).
    pub min_neighbours: usize,
}

impl Default for OffsetOutliers {
    fn default() -> Self {
        Self {
            radius_px: 8.0,
            k: 2.0,
            floor_m: 0.002,
            min_neighbours: 8,
        }
    }
}

/// Iteratively reweighted least squares on Eq. 3.4's data term (ours): after each
/// solve, a match whose residual `r = d_i − d̄_i` is large is weighted by the Cauchy weight
/// `β / (1 + (r / scale_m)²)` in the next solve (same sparsity, numeric refactorisation only).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RobustWeights {
    /// Reweighted solves after the first one.
    pub iterations: usize,
    /// Cauchy scale, m.
    pub scale_m: f64,
}

impl Default for RobustWeights {
    fn default() -> Self {
        Self {
            iterations: 3,
            scale_m: 0.005,
        }
    }
}

impl Default for OffsetParams {
    fn default() -> Self {
        Self {
            beta: 0.1,
            max_distance_px: 40.0,
            proxy_weight: 0.0,
            proxy_gate_m: None,
            outliers: Some(OffsetOutliers::default()),
            robust: None,
        }
    }
}

/// What Eq. 3.4 did to one view.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
pub struct OffsetReport {
    /// Pixels with a match constraint.
    pub constrained: usize,
    /// Pixels of the offset surface.
    pub kept: usize,
    /// Surface pixels discarded (too far from any constraint, or in an unconstrained region).
    pub discarded: usize,
    /// Median |d̄| over the constrained pixels, mm.
    pub median_target_offset_mm: f64,
    /// Matches (per neighbouring view and pixel) dropped as outliers ([`OffsetOutliers`]).
    #[serde(default)]
    pub rejected: usize,
    /// Constrained pixels whose final robust weight is below half of β ([`RobustWeights`]).
    #[serde(default)]
    pub down_weighted: usize,
}

/// An offset surface.
#[derive(Debug, Clone, PartialEq)]
pub struct OffsetSurface {
    /// `z + d` along each pixel ray.
    pub depth: DepthMap,
    /// Sizes.
    pub report: OffsetReport,
}

/// Applies Eq. 3.4 to `surface` with the matched depths `targets` (one per neighbouring view
/// that was matched, `NaN` where it has no match).
///
/// # Errors
/// [`Error::SizeMismatch`] for maps of different sizes; [`Error::Empty`] if no pixel of the
/// surface has a match; [`Error::InvalidParam`] for bad params; solver errors.
pub fn depth_offsets(
    surface: &DepthMap,
    targets: &[&DepthMap],
    params: &OffsetParams,
) -> Result<OffsetSurface> {
    depth_offsets_guided(surface, targets, None, params)
}

/// [`depth_offsets`] with the view's proxy depth map (ours): matches farther than
/// [`OffsetParams::proxy_gate_m`] from the proxy are dropped, and with
/// [`OffsetParams::proxy_weight`] γ > 0 every pixel's offset is also pulled toward the proxy,
/// `γ Σ_i (d_i − (p_i − z_i))²`, so that pixels far from every match follow the proxy instead
/// of being discarded. With `proxy` `None` (or γ = 0 and no gate) this is Eq. 3.4 as written.
///
/// # Errors
/// As [`depth_offsets`]; [`Error::SizeMismatch`] for a proxy of another size;
/// [`Error::InvalidParam`] for a negative or non-finite γ or a non-positive gate.
pub fn depth_offsets_guided(
    surface: &DepthMap,
    targets: &[&DepthMap],
    proxy: Option<&DepthMap>,
    params: &OffsetParams,
) -> Result<OffsetSurface> {
    check::positive("beta", params.beta)?;
    check::positive("max_distance_px", params.max_distance_px)?;
    check::non_negative("proxy_weight", params.proxy_weight)?;
    if let Some(g) = params.proxy_gate_m {
        check::positive("proxy_gate_m", g)?;
    }
    if let Some(o) = &params.outliers {
        check::positive("outliers.radius_px", o.radius_px)?;
        check::positive("outliers.k", o.k)?;
        check::non_negative("outliers.floor_m", o.floor_m)?;
    }
    if let Some(r) = &params.robust {
        check::positive("robust.scale_m", r.scale_m)?;
    }
    let n_px = surface.depth_m.len();
    let (w, h) = (surface.width, surface.height);
    for t in targets {
        check::same_size("matched depth map pixels", n_px, t.depth_m.len())?;
    }
    if let Some(p) = proxy {
        check::same_size("proxy depth map pixels", n_px, p.depth_m.len())?;
    }
    let proxy_at = |i: usize| proxy.map_or(f64::NAN, |p| p.depth_m[i]);
    let gate = proxy.and(params.proxy_gate_m);
    let anchor_weight = if proxy.is_some() {
        params.proxy_weight
    } else {
        0.0
    };
    // d̄_i: the mean of the offsets asked by the views that matched pixel i (within the gate
    // of the proxy, if one is given).
    let admitted = |i: usize, d: f64| {
        let p = proxy_at(i);
        !d.is_nan() && gate.is_none_or(|g| p.is_nan() || (d - p).abs() <= g)
    };
    // With `outliers`, each view's match is kept only if its offset agrees with its
    // neighbourhood's (ours).
    let (keep, rejected) = match &params.outliers {
        Some(o) => {
            let (keep, rejected) = outlier_matches(surface, targets, &admitted, o)?;
            (Some(keep), rejected)
        }
        None => (None, 0),
    };
    let mut target = vec![f64::NAN; n_px];
    for (i, t) in target.iter_mut().enumerate() {
        let z = surface.depth_m[i];
        if z.is_nan() {
            continue;
        }
        let asks: Vec<f64> = targets
            .iter()
            .enumerate()
            .filter(|(k, _)| keep.as_ref().is_none_or(|kp| kp[*k][i]))
            .map(|(_, m)| m.depth_m[i])
            .filter(|&d| admitted(i, d))
            .collect();
        if !asks.is_empty() {
            *t = asks.iter().sum::<f64>() / asks.len() as f64 - z;
        }
    }
    let constrained = Mask::from_bools(
        w,
        h,
        &target.iter().map(|t| !t.is_nan()).collect::<Vec<_>>(),
    )?;
    if constrained.is_empty() {
        return Err(Error::Empty {
            what: "matched pixels on the surface (Eq. 3.4 has no constraint)",
        });
    }
    let far = distance_to_foreground(&constrained)?;
    let limit = IntegrationParams::jump_threshold_m(params.max_distance_px, w);
    let proxied = |i: usize| anchor_weight > 0.0 && !proxy_at(i).is_nan();
    let mut inside: Vec<bool> = (0..n_px)
        .map(|i| {
            !surface.depth_m[i].is_nan() && (f64::from(far.as_raw()[i]) <= limit || proxied(i))
        })
        .collect();
    let (label, count) = regions(w, h, &inside)?;
    let mut anchored = vec![false; count];
    for i in 0..n_px {
        if label[i] != usize::MAX && !target[i].is_nan() {
            anchored[label[i]] = true;
        }
    }
    for i in 0..n_px {
        if label[i] != usize::MAX && !anchored[label[i]] {
            inside[i] = false;
        }
    }
    let mut unknown = vec![usize::MAX; n_px];
    let mut pixels = Vec::new();
    for i in (0..n_px).filter(|&i| inside[i]) {
        unknown[i] = pixels.len();
        pixels.push(i);
    }
    let n = pixels.len();
    let edges: Vec<(usize, usize)> = neighbour_pairs(w, &pixels, &unknown)
        .map(|(i, j)| (unknown[i], unknown[j]))
        .collect();
    let mut a = CooMatrix::new(edges.len(), n);
    for (r, &(p, q)) in edges.iter().enumerate() {
        a.push(r, p, 1.0);
        a.push(r, q, -1.0);
    }
    let anchors: Vec<(usize, f64)> = pixels
        .iter()
        .filter(|&&i| !target[i].is_nan())
        .map(|&i| (unknown[i], target[i]))
        .collect();
    let mut c = CooMatrix::new(anchors.len(), n);
    for (r, &(col, _)) in anchors.iter().enumerate() {
        c.push(r, col, 1.0);
    }
    let d = DMatrix::from_iterator(anchors.len(), 1, anchors.iter().map(|a| a.1));
    // The proxy's pull (γ > 0): toward the offset that puts the pixel on its proxy.
    let pulls: Vec<(usize, f64)> = pixels
        .iter()
        .filter(|&&i| proxied(i))
        .map(|&i| (unknown[i], proxy_at(i) - surface.depth_m[i]))
        .collect();
    let a = CscMatrix::from(&a);
    let mut problem = LsqProblem::new(a.clone()).with_term(CscMatrix::from(&c), params.beta);
    let mut rhs = vec![d];
    let mut g_csc = None;
    if !pulls.is_empty() {
        let mut g = CooMatrix::new(pulls.len(), n);
        for (r, &(col, _)) in pulls.iter().enumerate() {
            g.push(r, col, 1.0);
        }
        let g = CscMatrix::from(&g);
        problem = problem.with_term(g.clone(), anchor_weight);
        g_csc = Some(g);
        rhs.push(DMatrix::from_iterator(
            pulls.len(),
            1,
            pulls.iter().map(|p| p.1),
        ));
    }
    let mut solver = problem.factor(&LsqParams::default())?;
    let zeros = DMatrix::zeros(edges.len(), 1);
    let mut off = solver.solve(&zeros, &rhs)?;
    // IRLS (ours): each match's row scaled by the square root of its Cauchy
    // weight, the same sparsity refactorised numerically.
    let mut down_weighted = 0;
    if let Some(rw) = &params.robust {
        let mut weight = vec![1.0; anchors.len()];
        for _ in 0..rw.iterations {
            for (wt, &(col, t)) in weight.iter_mut().zip(&anchors) {
                let r = (off[col] - t) / rw.scale_m;
                *wt = 1.0 / (1.0 + r * r);
            }
            let mut cw = CooMatrix::new(anchors.len(), n);
            for (r, (&(col, _), wt)) in anchors.iter().zip(&weight).enumerate() {
                cw.push(r, col, wt.sqrt());
            }
            let cw = CscMatrix::from(&cw);
            let mut terms = vec![&cw];
            if let Some(g) = &g_csc {
                terms.push(g);
            }
            solver.set_values(&a, &terms)?;
            rhs[0] = DMatrix::from_iterator(
                anchors.len(),
                1,
                anchors
                    .iter()
                    .zip(&weight)
                    .map(|(&(_, t), wt)| t * wt.sqrt()),
            );
            off = solver.solve(&zeros, &rhs)?;
        }
        down_weighted = weight.iter().filter(|&&wt| wt < 0.5).count();
    }
    let mut depth = vec![f64::NAN; n_px];
    for (k, &i) in pixels.iter().enumerate() {
        let v = surface.depth_m[i] + off[k];
        if v.is_finite() && v > 0.0 {
            depth[i] = v;
        }
    }
    let abs: Vec<f64> = anchors.iter().map(|a| a.1.abs() * 1e3).collect();
    let depth = DepthMap::new(w, h, depth)?;
    let kept = depth.valid_count();
    Ok(OffsetSurface {
        report: OffsetReport {
            constrained: anchors.len(),
            kept,
            discarded: surface.valid_count().saturating_sub(kept),
            median_target_offset_mm: skin_core::stats::median(&abs),
            rejected,
            down_weighted,
        },
        depth,
    })
}

/// The matches [`OffsetOutliers`] keeps, per target map and pixel, and how many it dropped.
/// `admitted(i, d)` says whether a matched depth `d` at pixel `i` enters Eq. 3.4 at all.
fn outlier_matches(
    surface: &DepthMap,
    targets: &[&DepthMap],
    admitted: &dyn Fn(usize, f64) -> bool,
    o: &OffsetOutliers,
) -> Result<(Vec<Vec<bool>>, usize)> {
    let (w, h) = (surface.width as usize, surface.height as usize);
    let n_px = w * h;
    let valid: Vec<bool> = surface.depth_m.iter().map(|z| !z.is_nan()).collect();
    let (label, _) = regions(surface.width, surface.height, &valid)?;
    // Each view's asked offset (NaN: no admitted match).
    let asked: Vec<Vec<f64>> = targets
        .iter()
        .map(|m| {
            (0..n_px)
                .map(|i| {
                    let d = m.depth_m[i];
                    if valid[i] && admitted(i, d) {
                        d - surface.depth_m[i]
                    } else {
                        f64::NAN
                    }
                })
                .collect()
        })
        .collect();
    let radius = (o.radius_px * w as f64 / 1024.0).round().max(1.0) as usize;
    let mut keep: Vec<Vec<bool>> = asked
        .iter()
        .map(|a| a.iter().map(|v| !v.is_nan()).collect())
        .collect();
    let mut rejected = 0;
    let mut window = Vec::new();
    let mut spread = Vec::new();
    for i in 0..n_px {
        if !asked.iter().any(|a| !a[i].is_nan()) {
            continue;
        }
        let (x, y) = (i % w, i / w);
        window.clear();
        for v in y.saturating_sub(radius)..(y + radius + 1).min(h) {
            for u in x.saturating_sub(radius)..(x + radius + 1).min(w) {
                let j = v * w + u;
                if label[j] == label[i] {
                    window.extend(asked.iter().map(|a| a[j]).filter(|d| !d.is_nan()));
                }
            }
        }
        // The pixel's own asks are in the window; the test needs `min_neighbours` others.
        let own = asked.iter().filter(|a| !a[i].is_nan()).count();
        if window.len() < own + o.min_neighbours {
            continue;
        }
        let med = median_in_place(&mut window);
        spread.clear();
        spread.extend(window.iter().map(|v| (v - med).abs()));
        let mad = median_in_place(&mut spread);
        let allowed = (o.k * 1.4826 * mad).max(o.floor_m);
        for (k, a) in asked.iter().enumerate() {
            if !a[i].is_nan() && (a[i] - med).abs() > allowed {
                keep[k][i] = false;
                rejected += 1;
            }
        }
    }
    Ok((keep, rejected))
}

/// The median of a non-empty slice of finite values (reorders it).
fn median_in_place(v: &mut [f64]) -> f64 {
    let n = v.len();
    let (_, m, _) = v.select_nth_unstable_by(n / 2, f64::total_cmp);
    let upper = *m;
    if n % 2 == 1 {
        upper
    } else {
        let lower = v[..n / 2].iter().copied().fold(f64::NEG_INFINITY, f64::max);
        0.5 * (lower + upper)
    }
}

/// Knobs of the per-view stage of §3.3 ([`per_view_surfaces`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
pub struct SurfaceParams {
    /// Eq. 3.3.
    pub integration: IntegrationParams,
    /// §3.3.2 matching.
    pub matching: MatchingParams,
    /// Eq. 3.4.
    pub offsets: OffsetParams,
    /// Guide the matching band with the proxy instead of the integrated surfaces (pass 2,
    /// Figure 3-6c). Default false (pass 1).
    pub proxy_guided: bool,
}

impl SurfaceParams {
    /// Pass 1 of §3.3 as [`crate::ReconstructParams::default`] runs it: the defaults (α =
    /// 10⁻⁶, ±20 cm band about each view's integrated surface) with coarse-to-fine matching
    /// ([`MatchingParams::coarse_to_fine`]; ours, the thesis evaluates the whole band at full
    /// resolution). Why: pass 1's only product used later is pass 2's proxy, and at 1024²
    /// (skirt, part-1 normals) the narrow band left pass 2 as accurate (coverage 86.01 →
    /// 85.75 %, normal / local deviation +0.01° / +0.02°, merged median / p95 1.728 / 21.3 →
    /// 1.689 / 20.7 mm) for less pass-1 matching (docs: "Pass-1 speed").
    pub fn pass1() -> Self {
        Self {
            matching: MatchingParams {
                coarse_to_fine: true,
                ..MatchingParams::default()
            },
            ..Self::default()
        }
    }

    /// Pass 2 of §3.3: α = 10⁻⁵ and the search band guided by the (mesh) proxy, 3 cm wide
    /// each side (ours: the pass-1 mesh is expected within a few mm of the surface).
    pub fn pass2() -> Self {
        Self {
            integration: IntegrationParams::pass2(),
            matching: MatchingParams {
                band_m: 0.03,
                ..MatchingParams::default()
            },
            offsets: OffsetParams::default(),
            proxy_guided: true,
        }
    }
}

/// Wall times of the per-view stage, s.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
pub struct SurfaceTimes {
    /// Both integrations of every view, with the cameras' pixel rays they share with matching.
    pub integration_s: f64,
    /// Both matchings of every pair.
    pub matching_s: f64,
    /// Eq. 3.4 for every view.
    pub offsets_s: f64,
}

/// The per-view surfaces of one pass.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewSurfaces {
    /// Each view's integrated surface (Eq. 3.3, with the matching's discontinuities removed).
    pub integrated: Vec<DepthMap>,
    /// Each view's discontinuities found by matching.
    pub breaks: Vec<Mask>,
    /// Each view's matched depths, one map per pair the view belongs to.
    pub matched: Vec<Vec<DepthMap>>,
    /// Each view's surface after the offsets of Eq. 3.4: the input of volumetric merging.
    pub surfaces: Vec<DepthMap>,
    /// Per pair, the second matching's sizes.
    pub match_stats: Vec<MatchStats>,
    /// Per view, the integration's sizes.
    pub integration: Vec<IntegrationReport>,
    /// Per view, the offsets' sizes.
    pub offsets: Vec<OffsetReport>,
    /// Wall times.
    pub times: SurfaceTimes,
}

/// The per-view stage of §3.3 for one pass: every view's normals integrated against its
/// proxy (Eq. 3.3, proxy discontinuities removed), the neighbouring `pairs` matched
/// (§3.3.2), every view integrated again with the discontinuities the matching found
/// removed and matched again, and each surface pulled to its matches (Eq. 3.4).
///
/// Every camera's pixel rays are computed once and shared by its two integrations and every
/// pair it belongs to (24 bytes a pixel per camera while the stage runs; measured at 8 ×
/// 1024²: the stage 0.93–0.98× the time, 120 MB more peak memory).
///
/// # Errors
/// [`Error::SizeMismatch`] for counts that differ from the cameras'; [`Error::IndexOutOfRange`]
/// for a pair naming a missing view; a view that cannot be integrated (no valid normals, no
/// proxy) or that no pair matched (e.g. cameras whose views do not overlap) is an error
/// naming the camera ([`Error::At`]); errors of the stages.
pub fn per_view_surfaces(
    cameras: &[Camera],
    normals: &[NormalMap],
    proxies: &[DepthMap],
    pairs: &[(usize, usize)],
    hull: Option<&PolygonalHull>,
    params: &SurfaceParams,
) -> Result<ViewSurfaces> {
    let n = cameras.len();
    check::same_size("normal maps per camera", n, normals.len())?;
    check::same_size("proxies per camera", n, proxies.len())?;
    for &(a, b) in pairs {
        check::index("pair's left view", a, n)?;
        check::index("pair's right view", b, n)?;
    }
    if pairs.is_empty() {
        return Err(Error::Empty {
            what: "pairs of neighbouring views to match",
        });
    }
    let mut times = SurfaceTimes::default();
    // Every camera's pixel rays once, for both integrations and every pair it is in.
    let t = Instant::now();
    let rays = cameras
        .iter()
        .enumerate()
        .map(|(c, cam)| camera_rays(cam).at(Context::Camera(c)))
        .collect::<Result<Vec<_>>>()?;
    times.integration_s += t.elapsed().as_secs_f64();
    let integrate_all =
        |breaks: Option<&[Mask]>, ev: Option<&[DepthMap]>, times: &mut SurfaceTimes| {
            let t = Instant::now();
            let out = (0..n)
                .into_par_iter()
                .map(|c| {
                    integrate_with_rays(
                        &cameras[c],
                        &normals[c],
                        &proxies[c],
                        breaks.map(|b| &b[c]),
                        ev.map(|e| &e[c]),
                        &params.integration,
                        Some(&rays[c]),
                    )
                    .at(Context::Camera(c))
                })
                .collect::<Result<Vec<Integrated>>>();
            times.integration_s += t.elapsed().as_secs_f64();
            out
        };
    let match_all = |surfaces: &[DepthMap], times: &mut SurfaceTimes| {
        let t = Instant::now();
        let out = pairs
            .iter()
            .map(|&(a, b)| {
                let view = |c: usize| MatchView {
                    camera: &cameras[c],
                    surface: &surfaces[c],
                    guide: params.proxy_guided.then_some(&proxies[c]),
                    images: None,
                };
                let pair_rays = [rays[a].as_slice(), rays[b].as_slice()];
                match_pair_with_rays(&view(a), &view(b), hull, &params.matching, Some(pair_rays))
                    .at(Context::Camera(a))
            })
            .collect::<Result<Vec<PairMatches>>>();
        times.matching_s += t.elapsed().as_secs_f64();
        out
    };
    let first = integrate_all(None, None, &mut times)?;
    let first_surfaces: Vec<DepthMap> = first.into_iter().map(|i| i.depth).collect();
    let first_matches = match_all(&first_surfaces, &mut times)?;
    let mut breaks: Vec<Vec<bool>> = cameras
        .iter()
        .map(|c| vec![false; c.intrinsics.width as usize * c.intrinsics.height as usize])
        .collect();
    for (m, &(a, b)) in first_matches.iter().zip(pairs) {
        for (flags, mask) in [(a, &m.left.breaks), (b, &m.right.breaks)] {
            for (f, v) in breaks[flags].iter_mut().zip(mask.iter()) {
                *f |= v;
            }
        }
    }
    let breaks: Vec<Mask> = cameras
        .iter()
        .zip(&breaks)
        .map(|(c, f)| Mask::from_bools(c.intrinsics.width, c.intrinsics.height, f))
        .collect::<std::result::Result<_, _>>()?;
    // With layers at the proxy's jumps, the first matching's depths decide the side of each
    // straddling pixel in the second integration.
    let evidence = if params.integration.layers {
        let mut per_view: Vec<Vec<&DepthMap>> = vec![Vec::new(); n];
        for (m, &(a, b)) in first_matches.iter().zip(pairs) {
            per_view[a].push(&m.left.target);
            per_view[b].push(&m.right.target);
        }
        Some(
            per_view
                .iter()
                .zip(&first_surfaces)
                .map(|(maps, s)| mean_depth(s.width, s.height, maps))
                .collect::<Result<Vec<DepthMap>>>()?,
        )
    } else {
        None
    };
    let second = integrate_all(Some(&breaks), evidence.as_deref(), &mut times)?;
    let integration: Vec<IntegrationReport> = second.iter().map(|i| i.report).collect();
    let integrated: Vec<DepthMap> = second.into_iter().map(|i| i.depth).collect();
    let matches = match_all(&integrated, &mut times)?;
    let mut matched: Vec<Vec<DepthMap>> = vec![Vec::new(); n];
    let match_stats = matches.iter().map(|m| m.stats).collect();
    for (m, &(a, b)) in matches.into_iter().zip(pairs) {
        matched[a].push(m.left.target);
        matched[b].push(m.right.target);
    }
    let t = Instant::now();
    let offset = (0..n)
        .into_par_iter()
        .map(|c| {
            let refs: Vec<&DepthMap> = matched[c].iter().collect();
            depth_offsets_guided(&integrated[c], &refs, Some(&proxies[c]), &params.offsets)
                .at(Context::Camera(c))
        })
        .collect::<Result<Vec<OffsetSurface>>>()?;
    times.offsets_s = t.elapsed().as_secs_f64();
    Ok(ViewSurfaces {
        integrated,
        breaks,
        matched,
        offsets: offset.iter().map(|o| o.report).collect(),
        surfaces: offset.into_iter().map(|o| o.depth).collect(),
        match_stats,
        integration,
        times,
    })
}

/// The mean of `maps` per pixel over those with a depth (`NaN` where none has one).
fn mean_depth(width: u32, height: u32, maps: &[&DepthMap]) -> Result<DepthMap> {
    let n_px = width as usize * height as usize;
    for m in maps {
        check::same_size("matched depth map pixels", n_px, m.depth_m.len())?;
    }
    let depth = (0..n_px)
        .map(|i| {
            let (sum, count) = maps
                .iter()
                .map(|m| m.depth_m[i])
                .filter(|d| !d.is_nan())
                .fold((0.0, 0usize), |(s, c), d| (s + d, c + 1));
            if count > 0 {
                sum / count as f64
            } else {
                f64::NAN
            }
        })
        .collect();
    DepthMap::new(width, height, depth)
}

/// Pooled accuracy of one pass's per-view surfaces against reference depth maps (e.g. the
/// studio's true depths, or a reference scan), each stage scored like [`depth_errors`] and
/// pooled over the views (pixel-weighted medians and 95th percentiles).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SurfaceErrors {
    /// The proxy, over the pixels of the offset surfaces (the baseline).
    pub proxy: DepthErrors,
    /// The integrated surfaces (Eq. 3.3), over the same pixels.
    pub integrated: DepthErrors,
    /// The matched depths (§3.3.2), over the matched pixels.
    pub matches: DepthErrors,
    /// The offset surfaces (Eq. 3.4).
    pub offset: DepthErrors,
    /// Fraction of the measured (valid) normals that ended in an offset surface, %.
    pub coverage_pct: f64,
}

fn pool(errors: &[DepthErrors]) -> DepthErrors {
    let n: usize = errors.iter().map(|e| e.pixels).sum();
    let w = |f: fn(&DepthErrors) -> f64| {
        errors.iter().map(|e| f(e) * e.pixels as f64).sum::<f64>() / n.max(1) as f64
    };
    DepthErrors {
        pixels: n,
        median_mm: w(|e| e.median_mm),
        p95_mm: w(|e| e.p95_mm),
        mean_mm: w(|e| e.mean_mm),
    }
}

impl ViewSurfaces {
    /// Scores every stage against `reference` (one depth map per view) beside the `proxies`;
    /// `normals` give the coverage's denominator.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] for counts or sizes that differ; [`Error::Empty`] if a view's
    /// offset surface does not overlap its reference.
    pub fn errors_against(
        &self,
        reference: &[DepthMap],
        proxies: &[DepthMap],
        normals: &[NormalMap],
    ) -> Result<SurfaceErrors> {
        let n = self.surfaces.len();
        check::same_size("reference depth maps", n, reference.len())?;
        check::same_size("proxies", n, proxies.len())?;
        check::same_size("normal maps", n, normals.len())?;
        let (mut proxy, mut integrated, mut matches, mut offset) = (vec![], vec![], vec![], vec![]);
        let (mut kept, mut measured) = (0usize, 0usize);
        for c in 0..n {
            let region: Vec<bool> = self.surfaces[c]
                .depth_m
                .iter()
                .map(|d| !d.is_nan())
                .collect();
            proxy.push(
                depth_errors(&proxies[c], &reference[c], Some(&region)).at(Context::Camera(c))?,
            );
            integrated.push(
                depth_errors(&self.integrated[c], &reference[c], Some(&region))
                    .at(Context::Camera(c))?,
            );
            offset
                .push(depth_errors(&self.surfaces[c], &reference[c], None).at(Context::Camera(c))?);
            for m in &self.matched[c] {
                if let Ok(e) = depth_errors(m, &reference[c], None) {
                    matches.push(e);
                }
            }
            kept += self.surfaces[c].valid_count();
            measured += normals[c].valid.iter().filter(|&&v| v).count();
        }
        Ok(SurfaceErrors {
            proxy: pool(&proxy),
            integrated: pool(&integrated),
            matches: pool(&matches),
            offset: pool(&offset),
            coverage_pct: 100.0 * kept as f64 / measured.max(1) as f64,
        })
    }
}

#[cfg(test)]
mod tests;
