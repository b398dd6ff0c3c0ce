//! Single-view surface reconstruction (Vlasic 2010 §3.3.1, Eq. 3.3): a normal map integrated
//! into depths along the pixel rays, held in place by soft proxy depths.
//!
//! ```text
//! argmin_z  Σ_(i,j) ((n_i + n_j)ᵀ (r_i z_i − r_j z_j))²  +  α Σ_i (z_i − z̄_i)²      (3.3)
//! ```
//!
//! over 4-neighbour pixel pairs `(i, j)` (right and down neighbours): `z_i` is the distance
//! along pixel `i`'s unit ray `r_i` (the [`DepthMap`] convention), `n_i` the measured normal,
//! `z̄_i` the proxy's depth where it has one. The normal constraint is **exactly linear** in
//! the depths — the surface point of pixel `i` is `c + r_i z_i` for the camera centre `c`, and
//! the chord `r_i z_i − r_j z_j` between neighbouring points must be perpendicular to the
//! averaged normal — so Eq. 3.3 is a sparse linear least-squares problem with no
//! linearisation error, solved here with [`skin_core::lsq`] (normal equations, sparse
//! Cholesky; the normal matrix's pattern and symbolic analysis are built once per call).
//! Rays and normals are both taken in the camera frame (a rotation of the world frame, which
//! leaves Eq. 3.3 unchanged). The constraint is blind to the sign of the normals and to a
//! common scale of all depths of a connected region (`z → s z` keeps every chord
//! perpendicular), which is what the proxy term fixes; a connected region with no proxy
//! depth is therefore left out (and reported).
//!
//! **Depth discontinuities** (§3.3.1): pixels straddling a jump of the proxy's depth larger
//! than [`IntegrationParams::proxy_jump_m`] per pixel are removed from the system, and so are
//! pixels marked by the matching stage (jumps over 1 cm per pixel, [`crate::matching`]). Both
//! thresholds are given at the thesis' image width and scaled with the pixel footprint (see
//! [`IntegrationParams::jump_threshold_m`]).

use std::time::Instant;

use nalgebra::DMatrix;
use nalgebra_sparse::{CooMatrix, CscMatrix};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use skin_core::camera::Camera;
use skin_core::check;
use skin_core::image::{label_components, Mask, Neighbourhood};
use skin_core::lsq::{LsqParams, LsqProblem};
use skin_core::math::{DVec2, DVec3};
use skin_core::raster::RenderedView;
use skin_core::stats::{mean, percentile_sorted};

use crate::multigrid::{self, GridSystem};
use crate::{DepthMap, Error, MultigridParams, NormalMap, Result};

/// Knobs of Eq. 3.3.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct IntegrationParams {
    /// α, the weight of the proxy depths against the normal constraints. Default 10⁻⁶, the
    /// thesis' pass-1 value ("approximately the inverse of the number of our surface
    /// points", §3.3.1); [`IntegrationParams::pass2`] uses 10⁻⁵.
    pub alpha: f64,
    /// A proxy depth jump between 4-neighbours above this (m, at
    /// [`IntegrationParams::THESIS_WIDTH_PX`]) marks both pixels as straddling a discontinuity. The thesis removes pixels along "large
    /// visual hull discontinuities" without a number; default 0.02 (ours: twice its matching
    /// threshold; on the studio's 8-view hull at 256² it keeps 97 % of the pixels and,
    /// after matching, gives 9 mm median error where 0.05 gives 12 mm).
    pub proxy_jump_m: f64,
    /// A jump of the matched depth between neighbours above this (m, at
    /// [`IntegrationParams::THESIS_WIDTH_PX`]) is a discontinuity found by matching. Default
    /// 0.01 (§3.3.1: "jumps by more than 1 cm per pixel").
    pub match_jump_m: f64,
    /// Connected regions with fewer pixels are left out (their normals alone say little).
    /// Default 20 (ours).
    pub min_region_px: usize,
    /// After solving Eq. 3.3, scale each connected region's depths by the least-squares
    /// scale that best fits them to the proxy depths. Eq. 3.3's normal residuals are lengths
    /// that grow with the depths, so wherever the normals are not exactly integrable (noise,
    /// bias, an undetected discontinuity) the least-squares optimum trades the weak proxy
    /// term for a surface shrunk toward the camera — at α = 10⁻⁶ and 256² images by
    /// decimetres to metres on the studio. The scale is exactly the mode α is meant to fix,
    /// so refitting it to the proxy (the α term's own least squares, alone) restores the thesis' intent
    /// without strengthening α against the detail. Default true (ours; not in the thesis).
    pub refit_scale: bool,
    /// How the normal equations are solved. Default [`IntegrationSolver::Direct`] (ours:
    /// the multigrid solver agrees with it to under 2 µm; on the studio's 1024² views —
    /// 75 k to 87 k foreground pixels, ragged masks — it needs 22–31 iterations and about the
    /// same CPU time, so it does not win there; see `docs/photometric-normals.md`).
    pub solver: IntegrationSolver,
    /// At a proxy jump, cut the neighbour constraint across it instead of removing both
    /// pixels that straddle it (regions are then connected only through the links kept).
    /// Default false (the thesis: "pixels straddling depth discontinuities removed"). Ours:
    /// the straddling pixels are each on a surface of their own, and only the
    /// link between them is wrong.
    #[serde(default)]
    pub cut_proxy_links: bool,
    /// Layers at the proxy's jumps (ours): the pixels straddling a proxy jump are
    /// not removed but each assigned to one side of it — a *layer*, the proxy depth of the
    /// pixel itself or of a 4-neighbour across the jump — and linked by Eq. 3.3 only to
    /// neighbours on the same layer (layer depths within the jump threshold), anchored by α
    /// to its layer's depth. Without evidence ([`integrate_normals_with_evidence`] given none,
    /// the first integration of a pass) every straddling pixel keeps its own proxy's layer;
    /// with evidence (the first matching's depths) a straddling pixel takes the layer nearest
    /// its matched depth if that is within [`IntegrationParams::layer_agreement`] of the jump
    /// threshold, and is removed as in the thesis otherwise (no match, or a match on neither
    /// layer). Default false (the thesis: "pixels straddling depth discontinuities removed";
    /// `docs/photometric-normals.md`, *Layers at discontinuities*).
    #[serde(default)]
    pub layers: bool,
    /// With [`IntegrationParams::layers`] and evidence, how near (as a fraction of the jump
    /// threshold) the evidence must be to a layer's depth for a straddling pixel to be kept
    /// on it. Default 0.5 (ours: the nearest layer is then unambiguous, as the layers differ
    /// by more than the threshold).
    #[serde(default = "default_layer_agreement")]
    pub layer_agreement: f64,
}

fn default_layer_agreement() -> f64 {
    0.5
}

/// The solver of Eq. 3.3's normal equations `(AᵀA + α CᵀC) z = α Cᵀ z̄`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
pub enum IntegrationSolver {
    /// Sparse Cholesky through [`skin_core::lsq`] (exact to rounding; the pattern is analysed
    /// and factorised once per call, super-linear in the pixel count). The default.
    #[default]
    Direct,
    /// Conjugate gradients preconditioned by an aggregation-multigrid V-cycle on the
    /// foreground pixels, warm-started from the proxy depth (O(n) per iteration; see the
    /// module `multigrid.rs` for the design).
    Multigrid(MultigridParams),
}

impl IntegrationSolver {
    /// [`IntegrationSolver::Multigrid`] with [`MultigridParams::default`].
    pub fn multigrid() -> Self {
        Self::Multigrid(MultigridParams::default())
    }
}

impl Default for IntegrationParams {
    fn default() -> Self {
        Self {
            alpha: 1e-6,
            proxy_jump_m: 0.02,
            match_jump_m: 0.01,
            min_region_px: 20,
            refit_scale: true,
            solver: IntegrationSolver::default(),
            cut_proxy_links: false,
            layers: false,
            layer_agreement: default_layer_agreement(),
        }
    }
}

impl IntegrationParams {
    /// Image width of the thesis' cameras (§3.2.1: 1024 × 1024), px: the width at which the
    /// jump thresholds ([`IntegrationParams::proxy_jump_m`], [`IntegrationParams::match_jump_m`])
    /// are given.
    pub const THESIS_WIDTH_PX: u32 = 1024;

    /// The same with another solver.
    pub fn with_solver(mut self, solver: IntegrationSolver) -> Self {
        self.solver = solver;
        self
    }

    /// The second pass of §3.3: the proxy is the pass-1 mesh, trusted more (α = 10⁻⁵).
    pub fn pass2() -> Self {
        Self {
            alpha: 1e-5,
            ..Self::default()
        }
    }

    /// A per-pixel jump threshold given at [`IntegrationParams::THESIS_WIDTH_PX`] scaled to an
    /// image `width_px` wide (with the same field of view a pixel covers `THESIS_WIDTH_PX / width_px` times
    /// more surface, and a continuous slope jumps that much more per pixel).
    pub fn jump_threshold_m(threshold_m: f64, width_px: u32) -> f64 {
        threshold_m * f64::from(Self::THESIS_WIDTH_PX) / f64::from(width_px.max(1))
    }

    fn validate(&self) -> Result<()> {
        check::non_negative("alpha", self.alpha)?;
        check::positive("proxy_jump_m", self.proxy_jump_m)?;
        check::positive("match_jump_m", self.match_jump_m)?;
        check::positive("layer_agreement", self.layer_agreement)?;
        if let IntegrationSolver::Multigrid(mg) = &self.solver {
            mg.validate()?;
        }
        Ok(())
    }
}

/// What one integration solved and left out.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
pub struct IntegrationReport {
    /// Depth unknowns solved (pixels with a surface in the result).
    pub unknowns: usize,
    /// Normal constraints (neighbour pairs) of Eq. 3.3.
    pub normal_constraints: usize,
    /// Proxy depth constraints.
    pub depth_constraints: usize,
    /// Valid-normal pixels removed as straddling a proxy discontinuity.
    pub removed_proxy_jumps: usize,
    /// Valid-normal pixels removed as straddling a discontinuity found by matching.
    pub removed_match_jumps: usize,
    /// Pixels left out in regions with no proxy depth or smaller than
    /// [`IntegrationParams::min_region_px`].
    pub dropped_region_px: usize,
    /// Wall time of assembling and solving the system, ms.
    pub solve_ms: f64,
    /// Conjugate-gradient iterations (V-cycles) of [`IntegrationSolver::Multigrid`]; 0 for
    /// the direct solve.
    pub iterations: usize,
    /// Residual norm reached by [`IntegrationSolver::Multigrid`], relative to its warm
    /// start's (the normal equations scaled by the proxy depths); 0 for the direct solve.
    pub relative_residual: f64,
}

/// A view's integrated surface.
#[derive(Debug, Clone, PartialEq)]
pub struct Integrated {
    /// Depth along each pixel ray (`NaN` where nothing was integrated).
    pub depth: DepthMap,
    /// Sizes of the system.
    pub report: IntegrationReport,
}

/// Pixels straddling a depth jump: both pixels of every 4-neighbour pair whose depths (both
/// present) differ by more than `jump_m`.
///
/// # Errors
/// [`Error::InvalidParam`] for a non-positive threshold.
pub fn depth_jumps(depth: &DepthMap, jump_m: f64) -> Result<Mask> {
    check::positive("jump_m", jump_m)?;
    let (w, h) = (depth.width, depth.height);
    let mut flags = vec![false; depth.depth_m.len()];
    for y in 0..h {
        for x in 0..w {
            let i = depth.index(x, y);
            let a = depth.depth_m[i];
            for (nx, ny) in [(x + 1, y), (x, y + 1)] {
                if nx >= w || ny >= h {
                    continue;
                }
                let j = depth.index(nx, ny);
                let b = depth.depth_m[j];
                if (a - b).abs() > jump_m {
                    flags[i] = true;
                    flags[j] = true;
                }
            }
        }
    }
    Ok(Mask::from_bools(w, h, &flags)?)
}

/// Distances between two depth maps of one camera along the pixel rays, over the pixels where
/// both have a surface (and `region` is set): the per-view accuracy of §3.3's stages against
/// a true depth map, or between passes.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct DepthErrors {
    /// Pixels compared.
    pub pixels: usize,
    /// Median absolute difference, mm.
    pub median_mm: f64,
    /// 95th percentile of the absolute difference, mm.
    pub p95_mm: f64,
    /// Mean absolute difference, mm.
    pub mean_mm: f64,
}

/// [`DepthErrors`] of `estimate` against `reference` over the pixels where both have a
/// surface and `region` (row-major flags, optional) is set.
///
/// # Errors
/// [`Error::SizeMismatch`] for maps or a region of different sizes; [`Error::Empty`] if no
/// pixel is compared.
pub fn depth_errors(
    estimate: &DepthMap,
    reference: &DepthMap,
    region: Option<&[bool]>,
) -> Result<DepthErrors> {
    check::same_size(
        "depth map pixels",
        reference.depth_m.len(),
        estimate.depth_m.len(),
    )?;
    if let Some(r) = region {
        check::same_size("region flags", reference.depth_m.len(), r.len())?;
    }
    let mut e: Vec<f64> = estimate
        .depth_m
        .iter()
        .zip(&reference.depth_m)
        .enumerate()
        .filter(|(i, (a, b))| !a.is_nan() && !b.is_nan() && region.is_none_or(|r| r[*i]))
        .map(|(_, (a, b))| (a - b).abs() * 1e3)
        .collect();
    if e.is_empty() {
        return Err(Error::Empty {
            what: "pixels where both depth maps have a surface",
        });
    }
    e.sort_by(f64::total_cmp);
    Ok(DepthErrors {
        pixels: e.len(),
        median_mm: percentile_sorted(&e, 0.5),
        p95_mm: percentile_sorted(&e, 0.95),
        mean_mm: mean(&e),
    })
}

/// Camera-frame unit ray direction of every pixel (row-major). [`crate::per_view_surfaces`]
/// computes them once per camera for its integrations and pairs; the public entry points
/// ([`integrate_normals`], [`crate::match_pair`]) compute their own.
pub(crate) fn camera_rays(camera: &Camera) -> Result<Vec<DVec3>> {
    let (w, h) = (
        camera.intrinsics.width as usize,
        camera.intrinsics.height as usize,
    );
    let rot = camera.camera_from_world();
    // Rows in parallel, written in place (a 1024² camera has a million rays).
    let mut rays = vec![DVec3::ZERO; w * h];
    rays.par_chunks_mut(w.max(1))
        .enumerate()
        .try_for_each(|(y, row)| {
            for (x, out) in row.iter_mut().enumerate() {
                let ray = camera.ray(DVec2::new(x as f64, y as f64))?;
                *out = rot.transform_vector3(ray.direction);
            }
            Ok::<(), Error>(())
        })?;
    Ok(rays)
}

/// Multiplies each region's depths by the least-squares scale `s = Σ z_i z̄_i / Σ z_i²` over
/// its proxy pixels (see [`IntegrationParams::refit_scale`]).
fn refit_region_scales(
    pixels: &[usize],
    label: &[usize],
    regions: usize,
    proxy: &[f64],
    z: &mut [f64],
) {
    let mut sums = vec![(0.0, 0.0); regions];
    for (k, &i) in pixels.iter().enumerate() {
        if !proxy[i].is_nan() && z[k].is_finite() {
            sums[label[i]].0 += z[k] * proxy[i];
            sums[label[i]].1 += z[k] * z[k];
        }
    }
    let scale: Vec<f64> = sums
        .iter()
        .map(|&(zp, zz)| if zz > 0.0 && zp > 0.0 { zp / zz } else { 1.0 })
        .collect();
    for (k, &i) in pixels.iter().enumerate() {
        z[k] *= scale[label[i]];
    }
}

/// Eq. 3.3's normal equations by sparse Cholesky (skin-core `lsq`): `rows` are the normal
/// constraints `(k_i, u, k_j, v)` (`u z_i + v z_j ≈ 0`), `anchors` the proxy depths.
fn solve_direct(
    n: usize,
    rows: &[(usize, f64, usize, f64)],
    anchors: &[(usize, f64)],
    alpha: f64,
) -> Result<Vec<f64>> {
    let mut a = CooMatrix::new(rows.len(), n);
    for (r, &(ci, vi, cj, vj)) in rows.iter().enumerate() {
        a.push(r, ci, vi);
        a.push(r, cj, vj);
    }
    let mut c = CooMatrix::new(anchors.len(), n);
    for (r, &(col, _)) in anchors.iter().enumerate() {
        c.push(r, col, 1.0);
    }
    let d = DMatrix::from_iterator(anchors.len(), 1, anchors.iter().map(|a| a.1));
    let b = DMatrix::zeros(a.nrows(), 1);
    let solver = LsqProblem::new(CscMatrix::from(&a))
        .with_term(CscMatrix::from(&c), alpha)
        .factor(&LsqParams::default())?;
    Ok(solver.solve(&b, &[d])?.iter().copied().collect())
}

/// The multigrid warm start: the proxy depth where there is one, else the mean proxy depth
/// of the pixel's region (every region kept has one).
fn warm_start(pixels: &[usize], label: &[usize], regions: usize, proxy: &[f64]) -> Vec<f64> {
    let mut sums = vec![(0.0, 0usize); regions];
    for &i in pixels {
        if !proxy[i].is_nan() {
            sums[label[i]].0 += proxy[i];
            sums[label[i]].1 += 1;
        }
    }
    pixels
        .iter()
        .map(|&i| {
            if proxy[i].is_nan() {
                let (s, c) = sums[label[i]];
                s / c.max(1) as f64
            } else {
                proxy[i]
            }
        })
        .collect()
}

/// The right and lower 4-neighbour pairs `(i, j)` (row-major pixel indices) of `pixels`
/// whose both ends are unknowns (`unknown[j] != usize::MAX`), in the order of `pixels`.
pub(crate) fn neighbour_pairs<'a>(
    width: u32,
    pixels: &'a [usize],
    unknown: &'a [usize],
) -> impl Iterator<Item = (usize, usize)> + 'a {
    let w = width as usize;
    pixels.iter().flat_map(move |&i| {
        let right = (i % w + 1 < w).then_some(i + 1);
        let down = (i + w < unknown.len()).then_some(i + w);
        [right, down]
            .into_iter()
            .flatten()
            .filter(move |&j| unknown[j] != usize::MAX)
            .map(move |j| (i, j))
    })
}

/// The rasteriser's normals of `view` (seen by `camera`) as a measured normal map: turned to
/// face the camera, as a photometric measurement is (the rasteriser keeps a visible back
/// face's outward normal), valid where the view sees the mesh. The exact-normal control of
/// §3.3's validation.
///
/// # Errors
/// [`Error::SizeMismatch`] if the view lacks its mask or normal buffer or the camera images
/// another size; errors of [`Camera::ray`].
pub fn rendered_normals(camera: &Camera, view: &RenderedView) -> Result<NormalMap> {
    let n_px = view.pixel_count();
    check::same_size(
        "camera pixels",
        n_px,
        camera.intrinsics.width as usize * camera.intrinsics.height as usize,
    )?;
    check::same_size("rendered normals", n_px, view.normal_camera.len())?;
    check::same_size("rendered mask", n_px, view.mask.len())?;
    let rays = camera_rays(camera)?;
    let normals = view
        .normal_camera
        .iter()
        .zip(&rays)
        .map(|(n, r)| {
            let n = DVec3::new(f64::from(n[0]), f64::from(n[1]), f64::from(n[2]));
            if n.dot(*r) > 0.0 {
                -n
            } else {
                n
            }
        })
        .collect();
    Ok(NormalMap {
        width: view.width,
        height: view.height,
        normals,
        valid: view.mask.iter().map(|&m| m > 0).collect(),
    })
}

/// The layers at a proxy's jumps ([`IntegrationParams::layers`]): per pixel the depth of the
/// layer it is integrated on (the proxy's, or for a pixel straddling a jump the proxy depth
/// of the side it is assigned to) and whether a straddling pixel is removed. Without
/// `evidence` every straddling pixel stays on its own proxy's layer; with it, it takes the
/// candidate (its own proxy depth, or a 4-neighbour's across a jump) nearest its evidence
/// depth if that is within `agreement` × `jump_m`, and is removed otherwise.
fn layer_depths(
    proxy: &DepthMap,
    jumps: &Mask,
    evidence: Option<&DepthMap>,
    jump_m: f64,
    agreement: f64,
) -> (Vec<f64>, Vec<bool>) {
    let (w, h) = (proxy.width as usize, proxy.height as usize);
    let p = &proxy.depth_m;
    let mut layer = p.clone();
    let mut removed = vec![false; p.len()];
    let Some(evidence) = evidence else {
        return (layer, removed);
    };
    for i in 0..p.len() {
        let (x, y) = (i % w, i / w);
        if !jumps.get(x as u32, y as u32) {
            continue;
        }
        let e = evidence.depth_m[i];
        if e.is_nan() {
            removed[i] = true;
            continue;
        }
        let neighbours = [
            (x > 0).then(|| i - 1),
            (x + 1 < w).then(|| i + 1),
            (y > 0).then(|| i - w),
            (y + 1 < h).then(|| i + w),
        ];
        let best = std::iter::once(p[i])
            .chain(
                neighbours
                    .into_iter()
                    .flatten()
                    .map(|j| p[j])
                    .filter(|d| (d - p[i]).abs() > jump_m),
            )
            .filter(|d| !d.is_nan())
            .min_by(|a, b| (a - e).abs().total_cmp(&(b - e).abs()));
        match best {
            Some(d) if (d - e).abs() <= agreement * jump_m => layer[i] = d,
            _ => removed[i] = true,
        }
    }
    (layer, removed)
}

/// Labels the 4-connected regions of `inside` (row-major); `usize::MAX` outside.
/// Connected regions of `inside` through the 4-neighbour links that `linked(i, j)` keeps
/// (right and lower neighbours), labelled as [`regions`] (`usize::MAX` outside).
fn linked_regions(
    width: u32,
    inside: &[bool],
    linked: impl Fn(usize, usize) -> bool,
) -> (Vec<usize>, usize) {
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    let w = width as usize;
    let mut parent: Vec<usize> = (0..inside.len()).collect();
    for i in (0..inside.len()).filter(|&i| inside[i]) {
        let right = (i % w + 1 < w).then_some(i + 1);
        let down = (i + w < inside.len()).then_some(i + w);
        for j in [right, down].into_iter().flatten() {
            if inside[j] && linked(i, j) {
                let (a, b) = (root(&mut parent, i), root(&mut parent, j));
                parent[a.max(b)] = a.min(b);
            }
        }
    }
    let mut label = vec![usize::MAX; inside.len()];
    let mut count = 0;
    for i in 0..inside.len() {
        if inside[i] {
            let r = root(&mut parent, i);
            if label[r] == usize::MAX {
                label[r] = count;
                count += 1;
            }
            label[i] = label[r];
        }
    }
    (label, count)
}

pub(crate) fn regions(width: u32, height: u32, inside: &[bool]) -> Result<(Vec<usize>, usize)> {
    let c = label_components(
        &Mask::from_bools(width, height, inside)?,
        true,
        Neighbourhood::Four,
    )?;
    let label = (0..c.label.len())
        .map(|i| c.component_of(i).unwrap_or(usize::MAX))
        .collect();
    Ok((label, c.count()))
}

/// Integrates `normals` (camera frame, as [`NormalMap`]) seen by `camera` into depths along
/// the pixel rays by Eq. 3.3, with `proxy` giving the soft depths `z̄` and its large jumps,
/// and `match_breaks` (optional) the discontinuities found by matching.
///
/// # Errors
/// [`Error::SizeMismatch`] for maps or masks of another size than the camera's image;
/// [`Error::NonFinite`] for a valid normal that is not finite; [`Error::Empty`] if no pixel
/// is left to integrate (no valid normals, or none connected to a proxy depth);
/// [`Error::InvalidParam`] for bad params; solver errors.
///
/// # Example
/// A sphere's exact normals integrated against a proxy that is wrong by up to ±2 cm in a
/// smooth wave: the normals fix the shape, the proxy only the depth scale.
/// ```
/// use photometric_normals::{
///     depth_errors, integrate_normals, rendered_normals, DepthMap, IntegrationParams,
/// };
/// use skin_core::camera::{Camera, Intrinsics};
/// use skin_core::math::DVec3;
/// use skin_core::mesh::shapes::uv_sphere;
/// use skin_core::raster::{Buffers, Rasterizer, RenderParams};
///
/// let sphere = uv_sphere(DVec3::ZERO, 0.2, 64, 128)?;
/// let k = Intrinsics::from_horizontal_fov(0.4, 64, 64)?;
/// let cam = Camera::look_at(k, DVec3::new(0.0, 0.0, 1.2), DVec3::ZERO, DVec3::Y)?;
/// let buffers = Buffers { depth: true, normal: true, ..Buffers::MASK_ONLY };
/// let view = Rasterizer::new(&cam).render(&sphere, &RenderParams::default().with_buffers(buffers))?;
/// let truth = DepthMap::from_view(&view)?;
/// let normals = rendered_normals(&cam, &view)?;
/// let wave: Vec<f64> = (0..truth.depth_m.len())
///     .map(|i| truth.depth_m[i] + 0.02 * (0.3 * (i % 64) as f64).sin())
///     .collect();
/// let proxy = DepthMap::new(64, 64, wave)?;
/// let integrated = integrate_normals(&cam, &normals, &proxy, None, &IntegrationParams::default())?;
/// let proxy_error = depth_errors(&proxy, &truth, None)?;
/// let error = depth_errors(&integrated.depth, &truth, None)?;
/// assert!(error.median_mm < 0.2 * proxy_error.median_mm, "{error:?} vs {proxy_error:?}");
/// # Ok::<(), photometric_normals::Error>(())
/// ```
pub fn integrate_normals(
    camera: &Camera,
    normals: &NormalMap,
    proxy: &DepthMap,
    match_breaks: Option<&Mask>,
    params: &IntegrationParams,
) -> Result<Integrated> {
    integrate_normals_with_evidence(camera, normals, proxy, match_breaks, None, params)
}

/// [`integrate_normals`] with `evidence`, depths along the rays (e.g. the mean matched depth
/// of the pass's first matching, `NaN` where none) that decide, with
/// [`IntegrationParams::layers`], on which side of a proxy jump each straddling pixel is
/// integrated. Without `layers` the evidence is not used.
///
/// # Errors
/// As [`integrate_normals`]; [`Error::SizeMismatch`] for evidence of another size.
pub fn integrate_normals_with_evidence(
    camera: &Camera,
    normals: &NormalMap,
    proxy: &DepthMap,
    match_breaks: Option<&Mask>,
    evidence: Option<&DepthMap>,
    params: &IntegrationParams,
) -> Result<Integrated> {
    integrate_with_rays(camera, normals, proxy, match_breaks, evidence, params, None)
}

/// [`integrate_normals_with_evidence`] with the camera's [`camera_rays`] when the caller has
/// them (computed once per camera for all of a pass's integrations and pairs).
pub(crate) fn integrate_with_rays(
    camera: &Camera,
    normals: &NormalMap,
    proxy: &DepthMap,
    match_breaks: Option<&Mask>,
    evidence: Option<&DepthMap>,
    params: &IntegrationParams,
    camera_frame_rays: Option<&[DVec3]>,
) -> Result<Integrated> {
    params.validate()?;
    let (w, h) = (camera.intrinsics.width, camera.intrinsics.height);
    let n_px = w as usize * h as usize;
    proxy.check_camera(camera)?;
    check::same_size("normal map pixels", n_px, normals.normals.len())?;
    check::same_size("normal map validity flags", n_px, normals.valid.len())?;
    if let Some(m) = match_breaks {
        check::same_size("matching discontinuity mask", n_px, m.pixel_count())?;
    }
    if let Some(e) = evidence {
        check::same_size("evidence depth map pixels", n_px, e.depth_m.len())?;
    }
    if let Some(r) = camera_frame_rays {
        check::same_size("camera rays", n_px, r.len())?;
    }
    for (n, _) in normals
        .normals
        .iter()
        .zip(&normals.valid)
        .filter(|(_, v)| **v)
    {
        if !n.is_finite() {
            return Err(Error::NonFinite {
                what: "valid normal of the normal map",
            });
        }
    }
    let t0 = Instant::now();
    let mut report = IntegrationReport::default();
    let jump_m = IntegrationParams::jump_threshold_m(params.proxy_jump_m, w);
    let proxy_jumps = depth_jumps(proxy, jump_m)?;
    // With `layers`, each straddling pixel's layer depth (`None`: removed); elsewhere the
    // layer depth is the proxy's.
    let layer_depth = if params.layers {
        Some(layer_depths(
            proxy,
            &proxy_jumps,
            evidence,
            jump_m,
            params.layer_agreement,
        ))
    } else {
        None
    };
    let layer = layer_depth.as_ref().map_or(&proxy.depth_m, |(d, _)| d);
    // With `cut_proxy_links` the pixels stay and only the links across a jump are cut; with
    // `layers`, only the links between pixels on the same layer are kept.
    let cut_links = params.cut_proxy_links || params.layers;
    let linked = |i: usize, j: usize| !(cut_links && (layer[i] - layer[j]).abs() > jump_m);
    let mut inside = normals.valid.clone();
    for (i, keep) in inside.iter_mut().enumerate() {
        if !*keep {
            continue;
        }
        let (x, y) = ((i % w as usize) as u32, (i / w as usize) as u32);
        let kept_on_layer =
            params.cut_proxy_links || layer_depth.as_ref().is_some_and(|(_, removed)| !removed[i]);
        if proxy_jumps.get(x, y) && !kept_on_layer {
            report.removed_proxy_jumps += 1;
            *keep = false;
        } else if match_breaks.is_some_and(|m| m.get(x, y)) {
            report.removed_match_jumps += 1;
            *keep = false;
        }
    }
    // Regions without a proxy depth (scale undetermined) or too small are left out.
    let (label, count) = if cut_links {
        linked_regions(w, &inside, linked)
    } else {
        regions(w, h, &inside)?
    };
    let mut size = vec![0usize; count];
    let mut anchored = vec![false; count];
    for i in 0..n_px {
        if label[i] != usize::MAX {
            size[label[i]] += 1;
            anchored[label[i]] |= !layer[i].is_nan();
        }
    }
    for i in 0..n_px {
        let l = label[i];
        if l != usize::MAX && (!anchored[l] || size[l] < params.min_region_px.max(1)) {
            inside[i] = false;
            report.dropped_region_px += 1;
        }
    }
    let mut unknown = vec![usize::MAX; n_px];
    let mut pixels = Vec::new();
    for (i, _) in inside.iter().enumerate().filter(|(_, v)| **v) {
        unknown[i] = pixels.len();
        pixels.push(i);
    }
    if pixels.is_empty() {
        return Err(Error::Empty {
            what: "pixels to integrate (no valid normals connected to a proxy depth)",
        });
    }
    let computed;
    let rays = match camera_frame_rays {
        Some(rays) => rays,
        None => {
            computed = camera_rays(camera)?;
            &computed
        }
    };
    let n = pixels.len();
    let rows: Vec<(usize, f64, usize, f64)> = neighbour_pairs(w, &pixels, &unknown)
        .filter(|&(i, j)| linked(i, j))
        .map(|(i, j)| {
            let m = normals.normals[i] + normals.normals[j];
            (unknown[i], m.dot(rays[i]), unknown[j], -m.dot(rays[j]))
        })
        .collect();
    report.normal_constraints = rows.len();
    let anchors: Vec<(usize, f64)> = pixels
        .iter()
        .filter(|&&i| !layer[i].is_nan())
        .map(|&i| (unknown[i], layer[i]))
        .collect();
    report.depth_constraints = anchors.len();
    let mut z = match &params.solver {
        IntegrationSolver::Direct => solve_direct(n, &rows, &anchors, params.alpha)?,
        IntegrationSolver::Multigrid(mg) => {
            let z0 = warm_start(&pixels, &label, count, layer);
            let system = GridSystem {
                width: w,
                height: h,
                pixels: &pixels,
                rows: &rows,
                anchors: &anchors,
                alpha: params.alpha,
            };
            let (z, stats) = multigrid::solve(&system, &z0, mg)?;
            report.iterations = stats.iterations;
            report.relative_residual = stats.relative_residual;
            z
        }
    };
    if params.refit_scale {
        refit_region_scales(&pixels, &label, count, layer, &mut z);
    }
    let mut depth = vec![f64::NAN; n_px];
    for (k, &i) in pixels.iter().enumerate() {
        let v = z[k];
        // A depth at or behind the camera centre is no surface (a region whose normals
        // contradict its proxy so badly cannot be trusted).
        if v.is_finite() && v > 0.0 {
            depth[i] = v;
            report.unknowns += 1;
        }
    }
    report.solve_ms = t0.elapsed().as_secs_f64() * 1e3;
    Ok(Integrated {
        depth: DepthMap::new(w, h, depth)?,
        report,
    })
}

#[cfg(test)]
mod tests;
