//! Volumetric merging of per-view depth maps (§3.3.3): VRIP (Curless & Levoy 1996) with the
//! thesis's weights, on a sparse volume, polygonised by marching cubes.
//!
//! Each view contributes, at every voxel its pixels see within the ramp, the signed distance
//! along the line of sight `s = D(pixel) − ‖voxel − camera‖` (positive in front of the
//! surface), clamped to the ramp `[−ramp/2, ramp/2]` (6 cm in the thesis, to absorb the
//! worst-case misalignment), and a weight: the product of
//!
//! * the distance (px) of the pixel to the depth map's boundary (no surface, or a depth jump
//!   between neighbours above [`MergeParams::max_depth_jump_m`]), ramped from 0 at the edge
//!   to 1 at [`MergeParams::boundary_blend_px`], for smooth blending of overlapping views,
//! * the cosine between the surface normal (from the depth map's neighbours) and the line of
//!   sight, down-weighting foreshortened data,
//! * `1 / distance to the camera` (the thesis's addition: sparsely sampled data counts less),
//! * the caller's per-pixel confidence, when given,
//! * and VRIP's taper behind the surface (the weight falls linearly to zero over the last
//!   quarter of the ramp behind the surface), so thin parts are not eaten by the far side.
//!
//! Depth and weight are interpolated bilinearly between the four pixels around the voxel's
//! projection, only where all four have a surface and no depth jump (so views never bridge
//! discontinuities). The merged surface is the zero set of the weighted mean distance where
//! the summed weight is positive.
//!
//! **Sparse volume**: the volume is a hash of blocks of 8³ voxels, allocated only along each
//! view's ramp (pixels subsampled so that every block the ramp crosses is hit), so memory
//! grows with the surface area, not the bounding volume: a 2 m cube at 2 mm would be 10⁹
//! voxels dense. Blocks are filled in parallel (rayon); each voxel's value depends only on
//! the views, so the result does not depend on the thread count.

use std::time::Instant;

use rayon::prelude::*;
use skin_core::camera::Camera;
use skin_core::check;
use skin_core::image::{distance_to_background, Mask};
use skin_core::math::{DVec2, DVec3};
use skin_core::mesh::TriMesh;

use crate::marching_cubes::{march_cells_par, EdgeFit, Node, NodeMap, NodeSet};
use crate::{Context, DepthMap, Error, Result, ResultExt};

/// Voxels along each side of a block of the sparse volume.
pub(crate) const BLOCK_VOXELS: usize = 8;
const BLOCK: i64 = BLOCK_VOXELS as i64;
const BLOCK_LEN: usize = BLOCK_VOXELS * BLOCK_VOXELS * BLOCK_VOXELS;
/// Cells per parallel task of the merge's marching cubes.
const MARCH_CHUNK: usize = 32_768;

/// Parameters of the volumetric merge.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MergeParams {
    /// Voxel size, m. Thesis: 2 mm ("approximately matches the average resolution of our raw
    /// data").
    pub voxel_m: f64,
    /// Length of the signed-distance ramp along each line of sight, m, centred on the
    /// surface. Thesis: 6 cm ("to allow for worst-case misalignment").
    pub ramp_m: f64,
    /// Distance from the depth map's boundary (px) over which the boundary weight rises from
    /// 0 to 1. Not given in the thesis; 8 px here.
    pub boundary_blend_px: f64,
    /// Neighbouring pixels whose depths differ by more than this (m) straddle a depth
    /// discontinuity, which counts as boundary. Default 1 cm (the thesis's discontinuity
    /// threshold per pixel, §3.3.1).
    pub max_depth_jump_m: f64,
    /// Weight every sample 1 (times the confidence and the taper) instead of the thesis's
    /// boundary × cosine × inverse-distance weight: plain Curless–Levoy / TSDF averaging, the
    /// baseline. Default `false`.
    pub uniform_weights: bool,
}

impl Default for MergeParams {
    fn default() -> Self {
        Self {
            voxel_m: 0.002,
            ramp_m: 0.06,
            boundary_blend_px: 8.0,
            max_depth_jump_m: 0.01,
            uniform_weights: false,
        }
    }
}

impl MergeParams {
    /// With another voxel size, m.
    pub fn with_voxel_m(mut self, v: f64) -> Self {
        self.voxel_m = v;
        self
    }

    /// With another ramp length, m.
    pub fn with_ramp_m(mut self, v: f64) -> Self {
        self.ramp_m = v;
        self
    }

    /// With another boundary blend width, px.
    pub fn with_boundary_blend_px(mut self, v: f64) -> Self {
        self.boundary_blend_px = v;
        self
    }

    /// With another depth-discontinuity threshold, m.
    pub fn with_max_depth_jump_m(mut self, v: f64) -> Self {
        self.max_depth_jump_m = v;
        self
    }

    /// With uniform weights (the baseline) or the thesis's.
    pub fn with_uniform_weights(mut self, uniform: bool) -> Self {
        self.uniform_weights = uniform;
        self
    }

    fn validate(&self) -> Result<()> {
        check::positive("voxel_m", self.voxel_m)?;
        check::positive("ramp_m", self.ramp_m)?;
        check::positive("boundary_blend_px", self.boundary_blend_px)?;
        check::positive("max_depth_jump_m", self.max_depth_jump_m)?;
        if self.ramp_m < 2.0 * self.voxel_m {
            return Err(Error::InvalidParam {
                name: "ramp_m",
                reason: format!(
                    "{} m is shorter than two voxels ({} m each); raise ramp_m or lower voxel_m",
                    self.ramp_m, self.voxel_m
                ),
            });
        }
        Ok(())
    }
}

/// One view to merge: its camera, its depth map (distance along the pixel rays) and an
/// optional per-pixel confidence in `[0, ∞)` multiplying the merge weight (row-major, one per
/// pixel).
#[derive(Debug, Clone, Copy)]
pub struct MergeView<'a> {
    /// The camera that sees the depth map's pixels.
    pub camera: &'a Camera,
    /// Depth along each pixel's ray, m (`NaN` = no surface).
    pub depth: &'a DepthMap,
    /// Optional per-pixel confidence (≥ 0, finite), multiplied into the weight.
    pub confidence: Option<&'a [f64]>,
}

impl<'a> MergeView<'a> {
    /// A view without confidence (every pixel counts fully).
    pub fn new(camera: &'a Camera, depth: &'a DepthMap) -> Self {
        Self {
            camera,
            depth,
            confidence: None,
        }
    }
}

/// Size figures of a merge.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MergeStats {
    /// Allocated 8³ blocks.
    pub blocks: usize,
    /// Voxels in the allocated blocks.
    pub voxels_allocated: usize,
    /// Voxels with a positive summed weight.
    pub voxels_observed: usize,
    /// Bytes held by the volume's voxels (distance and weight, `f32` each).
    pub volume_bytes: usize,
}

/// Wall times of a merge's stages, s.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct MergeTimes {
    /// Preparing the views: per-pixel weights (boundary distance, cosine, inverse distance).
    pub prepare_s: f64,
    /// Finding the blocks each view's ramp crosses.
    pub blocks_s: f64,
    /// Filling the blocks' voxels (every voxel projected into the views that may see it).
    pub fill_s: f64,
    /// Finding the cells with a sign change.
    pub cells_s: f64,
    /// Marching cubes over those cells.
    pub march_s: f64,
}

/// The merged surface and the volume's size.
#[derive(Debug, Clone)]
pub struct MergedSurface {
    /// The zero set of the merged signed distance where observed (open where no view saw
    /// the surface; closed and 2-manifold where observed all round).
    pub mesh: TriMesh,
    /// Volume size figures.
    pub stats: MergeStats,
    /// Wall times of the stages.
    pub times: MergeTimes,
}

/// One view, prepared: per-pixel depth (NaN where unusable) and weight.
struct PreparedView<'a> {
    camera: &'a Camera,
    width: usize,
    height: usize,
    depth: Vec<f64>,
    weight: Vec<f32>,
}

impl PreparedView<'_> {
    /// Bilinear depth and weight at a pixel position, `None` unless all four pixels around it
    /// have a surface without a depth jump between them.
    fn sample(&self, px: DVec2, max_jump: f64) -> Option<(f64, f64)> {
        // `0 <= px < size − 1` is `floor(px) + 1 < size`; on that range truncation is
        // `floor`, exactly, and far cheaper than the libm call on this hot path (every voxel
        // × view of the merge). NaN fails the test.
        let inside = |v: f64, size: usize| v >= 0.0 && v < (size - 1) as f64;
        if !(inside(px.x, self.width) && inside(px.y, self.height)) {
            return None;
        }
        let (x, y) = (px.x as usize, px.y as usize);
        let (fx, fy) = (x as f64, y as f64);
        let (tx, ty) = (px.x - fx, px.y - fy);
        let i = y * self.width + x;
        let idx = [i, i + 1, i + self.width, i + self.width + 1];
        let d = idx.map(|j| self.depth[j]);
        if d.iter().any(|v| v.is_nan()) {
            return None;
        }
        let (lo, hi) = d
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                (a.min(v), b.max(v))
            });
        if hi - lo > max_jump {
            return None;
        }
        let w = [
            (1.0 - tx) * (1.0 - ty),
            tx * (1.0 - ty),
            (1.0 - tx) * ty,
            tx * ty,
        ];
        let depth = (0..4).map(|k| w[k] * d[k]).sum();
        let weight = (0..4).map(|k| w[k] * f64::from(self.weight[idx[k]])).sum();
        Some((depth, weight))
    }
}

fn prepare<'a>(view: &MergeView<'a>, params: &MergeParams) -> Result<PreparedView<'a>> {
    let map = view.depth;
    map.check_camera(view.camera)?;
    let (w, h) = (map.width as usize, map.height as usize);
    if let Some(c) = view.confidence {
        check::same_size("confidence", w * h, c.len())?;
        if let Some(i) = c.iter().position(|v| !(v.is_finite() && *v >= 0.0)) {
            return Err(Error::InvalidParam {
                name: "confidence",
                reason: format!("pixel {i} is {}: must be finite and >= 0", c[i]),
            });
        }
    }
    if map.valid_count() == 0 {
        return Err(Error::Empty {
            what: "depth map (no pixel has a surface)",
        });
    }
    let jump = params.max_depth_jump_m;
    // Interior pixels: a surface, and no jump to any 4-neighbour (neighbours off the image or
    // without a surface make the pixel a boundary pixel).
    let depth = &map.depth_m;
    let interior = Mask::from_fn(map.width, map.height, |x, y| {
        let (x, y) = (x as usize, y as usize);
        let d = depth[y * w + x];
        if d.is_nan() || x == 0 || y == 0 || x + 1 == w || y + 1 == h {
            return false;
        }
        [(x - 1, y), (x + 1, y), (x, y - 1), (x, y + 1)]
            .iter()
            .all(|&(u, v)| {
                let n = depth[v * w + u];
                !n.is_nan() && (n - d).abs() <= jump
            })
    });
    if interior.is_empty() {
        return Err(Error::Empty {
            what: "depth map interior (every surface pixel is on a boundary)",
        });
    }
    let dist = if interior.is_full() {
        None
    } else {
        Some(distance_to_background(&interior)?)
    };
    let cam = view.camera;
    let rows: Vec<Result<Vec<f32>>> = (0..h)
        .into_par_iter()
        .map(|y| {
            let mut row = vec![0.0f32; w];
            for (x, out) in row.iter_mut().enumerate() {
                if !interior.get(x as u32, y as u32) {
                    continue;
                }
                let i = y * w + x;
                let point = |u: usize, v: usize| -> Result<DVec3> {
                    let ray = cam.ray(DVec2::new(u as f64, v as f64))?;
                    Ok(ray.origin + ray.direction * depth[v * w + u])
                };
                let ray = cam.ray(DVec2::new(x as f64, y as f64))?;
                let du = point(x + 1, y)? - point(x - 1, y)?;
                let dv = point(x, y + 1)? - point(x, y - 1)?;
                let n = du.cross(dv).normalize_or_zero();
                let cosine = n.dot(ray.direction).abs();
                let boundary = dist
                    .as_ref()
                    .map_or(1.0, |d| f64::from(d.get_pixel(x as u32, y as u32).0[0]))
                    / params.boundary_blend_px;
                let conf = view.confidence.map_or(1.0, |c| c[i]);
                if params.uniform_weights {
                    *out = conf as f32;
                    continue;
                }
                *out = (boundary.min(1.0) * cosine / depth[i] * conf) as f32;
            }
            Ok(row)
        })
        .collect();
    let mut weight = Vec::with_capacity(w * h);
    for r in rows {
        weight.extend(r?);
    }
    Ok(PreparedView {
        camera: cam,
        width: w,
        height: h,
        depth: depth.clone(),
        weight,
    })
}

/// Blocks (by block coordinates) that a view's ramp crosses.
fn view_blocks(view: &PreparedView, params: &MergeParams) -> Result<NodeSet<Node>> {
    let block_m = params.voxel_m * BLOCK as f64;
    // Subsample pixels so that neighbouring samples are at most half a block apart at the
    // farthest depth.
    let max_depth = view
        .depth
        .iter()
        .filter(|d| !d.is_nan())
        .fold(0.0f64, |a, &d| a.max(d));
    let k = &view.camera.intrinsics;
    let footprint = (max_depth + params.ramp_m) / k.fx.min(k.fy);
    let stride = ((0.5 * block_m / footprint).floor() as usize).max(1);
    let steps = (params.ramp_m / (0.5 * block_m)).ceil() as usize;
    let mut ys: Vec<usize> = (0..view.height).step_by(stride).collect();
    if ys.last() != Some(&(view.height - 1)) {
        ys.push(view.height - 1);
    }
    let per_row: Vec<Result<NodeSet<Node>>> = ys
        .par_iter()
        .map(|&y| {
            let mut set = NodeSet::default();
            let mut xs: Vec<usize> = (0..view.width).step_by(stride).collect();
            if xs.last() != Some(&(view.width - 1)) {
                xs.push(view.width - 1);
            }
            for x in xs {
                let d = view.depth[y * view.width + x];
                if d.is_nan() {
                    continue;
                }
                let ray = view.camera.ray(DVec2::new(x as f64, y as f64))?;
                for s in 0..=steps {
                    let t = d - 0.5 * params.ramp_m + params.ramp_m * s as f64 / steps as f64;
                    let p = (ray.origin + ray.direction * t) / block_m;
                    set.insert([p.x.floor() as i64, p.y.floor() as i64, p.z.floor() as i64]);
                }
            }
            Ok(set)
        })
        .collect();
    let mut all = NodeSet::default();
    for s in per_row {
        all.extend(s?);
    }
    Ok(all)
}

/// One block's voxels: weighted mean signed distance (m) and summed weight.
struct Block {
    distance: Vec<f32>,
    weight: Vec<f32>,
}

fn fill_block(b: Node, views: &[PreparedView], params: &MergeParams) -> Block {
    let mut distance = vec![0.0f32; BLOCK_LEN];
    let mut weight = vec![0.0f32; BLOCK_LEN];
    let half = 0.5 * params.ramp_m;
    let taper = 0.25 * params.ramp_m;
    // Each view that may see the block, with the range of camera distances at which a voxel
    // can get a sample from it (the footprint's depths ± half the ramp, and a hair more).
    let near: Vec<(&PreparedView, DVec3, f64, f64)> = views
        .iter()
        .filter_map(|v| {
            let (dmin, dmax) = block_may_see(b, v, params)?;
            let margin = 1e-9 * (1.0 + dmax);
            Some((
                v,
                v.camera.centre(),
                dmin - half - margin,
                dmax + half + margin,
            ))
        })
        .collect();
    if near.is_empty() {
        return Block { distance, weight };
    }
    for (i, (dist, wsum)) in distance.iter_mut().zip(weight.iter_mut()).enumerate() {
        let node = block_node(b, i);
        let p = node_position(node, params.voxel_m);
        let (mut sw, mut swd) = (0.0, 0.0);
        for &(v, centre, lo, hi) in &near {
            // The bilinear depth lies within the footprint's depth range, so a voxel whose
            // distance is outside it by more than half the ramp gets |s| > half: skip it
            // before projecting (the result is the same).
            let range = (p - centre).length();
            if range < lo || range > hi {
                continue;
            }
            let Ok(proj) = v.camera.project(p) else {
                continue;
            };
            let Some((d, w)) = v.sample(proj, params.max_depth_jump_m) else {
                continue;
            };
            let s = d - range;
            if s.abs() > half || w <= 0.0 {
                continue;
            }
            let w = w * ((s + half) / taper).min(1.0);
            sw += w;
            swd += w * s;
        }
        if sw > 0.0 {
            *dist = (swd / sw) as f32;
            *wsum = sw as f32;
        }
    }
    Block { distance, weight }
}

/// Nodes along each side of a block's cells: its voxels and the next blocks' first layer.
const PAD: usize = BLOCK_VOXELS + 1;

/// The cells of block `b` (by their lowest node, in the block's voxel order) whose eight
/// corners are all observed and not all on one side of the zero level: exactly the cells
/// the marching cubes draw something in (`cell_straddles` with iso 0). `around[k]` is the
/// block at offset `(k & 1, (k >> 1) & 1, (k >> 2) & 1)` from `b` (`None`: not allocated),
/// which holds the cells' corners beyond `b`'s last layer. The corner values are gathered
/// once into a padded grid instead of eight look-ups per cell through the neighbour blocks.
fn straddling_cells(b: Node, around: &[Option<&Block>; 8]) -> Vec<Node> {
    let mut value = [0.0f64; PAD * PAD * PAD];
    let mut observed = [false; PAD * PAD * PAD];
    for z in 0..PAD {
        for y in 0..PAD {
            for x in 0..PAD {
                let k = usize::from(x >= BLOCK_VOXELS)
                    | usize::from(y >= BLOCK_VOXELS) << 1
                    | usize::from(z >= BLOCK_VOXELS) << 2;
                let Some(block) = around[k] else { continue };
                let i = x % BLOCK_VOXELS
                    + BLOCK_VOXELS * (y % BLOCK_VOXELS + BLOCK_VOXELS * (z % BLOCK_VOXELS));
                if block.weight[i] > 0.0 {
                    let j = x + PAD * (y + PAD * z);
                    observed[j] = true;
                    value[j] = f64::from(block.distance[i]);
                }
            }
        }
    }
    (0..BLOCK_LEN)
        .filter(|&i| {
            let (x, y, z) = (
                i % BLOCK_VOXELS,
                (i / BLOCK_VOXELS) % BLOCK_VOXELS,
                i / (BLOCK_VOXELS * BLOCK_VOXELS),
            );
            let (mut below, mut above) = (false, false);
            for c in 0..8 {
                let j = x + (c & 1) + PAD * (y + ((c >> 1) & 1) + PAD * (z + ((c >> 2) & 1)));
                if !observed[j] {
                    return false;
                }
                if value[j] < 0.0 {
                    below = true;
                } else {
                    above = true;
                }
            }
            below && above
        })
        .map(|i| block_node(b, i))
        .collect()
}

/// Whether any voxel of block `b` can get a sample from view `v`: the block's pixel footprint
/// (its corners' projections) overlaps the image, and the distances of the block's points to
/// the camera overlap the ramp around the depths in that footprint. A conservative test: it
/// only skips views that would contribute nothing. Returns the range of depths in the
/// footprint (unbounded when a corner is behind the camera).
fn block_may_see(b: Node, v: &PreparedView, params: &MergeParams) -> Option<(f64, f64)> {
    let lo = node_position(b.map(|c| c * BLOCK), params.voxel_m);
    let side = (BLOCK - 1) as f64 * params.voxel_m;
    let centre = lo + DVec3::splat(0.5 * side);
    let radius = 0.5 * side * 3f64.sqrt();
    let dist = (centre - v.camera.centre()).length();
    let (mut u0, mut v0, mut u1, mut v1) = (
        f64::INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::NEG_INFINITY,
    );
    for c in 0..8 {
        let p =
            lo + DVec3::new((c & 1) as f64, ((c >> 1) & 1) as f64, ((c >> 2) & 1) as f64) * side;
        // A corner behind the camera: keep the view (no cheap bound).
        let Ok(px) = v.camera.project(p) else {
            return Some((f64::NEG_INFINITY, f64::INFINITY));
        };
        (u0, v0, u1, v1) = (u0.min(px.x), v0.min(px.y), u1.max(px.x), v1.max(px.y));
    }
    let (w, h) = (v.width as f64, v.height as f64);
    if u1 < 0.0 || v1 < 0.0 || u0 > w - 1.0 || v0 > h - 1.0 {
        return None;
    }
    // Bilinear samples use the pixels around the projection: widen by one pixel.
    let x0 = (u0.floor() - 1.0).max(0.0) as usize;
    let y0 = (v0.floor() - 1.0).max(0.0) as usize;
    let x1 = ((u1.ceil() + 1.0) as usize).min(v.width - 1);
    let y1 = ((v1.ceil() + 1.0) as usize).min(v.height - 1);
    let (mut dmin, mut dmax) = (f64::INFINITY, f64::NEG_INFINITY);
    for y in y0..=y1 {
        for d in &v.depth[y * v.width + x0..=y * v.width + x1] {
            if !d.is_nan() {
                dmin = dmin.min(*d);
                dmax = dmax.max(*d);
            }
        }
    }
    let half = 0.5 * params.ramp_m;
    (dmin <= dmax && dist - radius <= dmax + half && dist + radius >= dmin - half)
        .then_some((dmin, dmax))
}

fn block_node(b: Node, i: usize) -> Node {
    let i = i as i64;
    [
        b[0] * BLOCK + i % BLOCK,
        b[1] * BLOCK + (i / BLOCK) % BLOCK,
        b[2] * BLOCK + i / (BLOCK * BLOCK),
    ]
}

fn node_position(n: Node, voxel_m: f64) -> DVec3 {
    DVec3::new(n[0] as f64, n[1] as f64, n[2] as f64) * voxel_m
}

/// Merges per-view depth maps into one surface (§3.3.3): VRIP signed-distance ramps along the
/// lines of sight, weighted by boundary distance, view cosine, inverse camera distance and the
/// optional confidence, on a sparse block volume, then marching cubes at the zero crossing
/// where the summed weight is positive.
///
/// # Errors
/// [`Error::Empty`] for no views or a view with no usable surface pixel;
/// [`Error::InvalidParam`] for bad parameters, a camera whose image size differs from its
/// depth map or a negative / non-finite confidence; [`Error::SizeMismatch`] for a confidence
/// of the wrong length. Errors about one view are wrapped in [`Error::At`] with
/// [`Context::Camera`].
///
/// # Example
/// A sphere rendered into depth maps from four cameras and merged at 5 mm voxels:
/// ```
/// use photometric_normals::{merge_views, DepthMap, MergeParams, MergeView};
/// use skin_core::camera::{Camera, Intrinsics};
/// use skin_core::math::DVec3;
/// use skin_core::mesh::shapes::uv_sphere;
/// use skin_core::raster::{Buffers, Rasterizer, RenderParams};
///
/// let sphere = uv_sphere(DVec3::ZERO, 0.2, 48, 96)?;
/// let k = Intrinsics::from_horizontal_fov(0.5, 64, 64)?;
/// let params = RenderParams::default().with_buffers(Buffers { depth: true, ..Buffers::MASK_ONLY });
/// let mut views = Vec::new();
/// for eye in [DVec3::X, -DVec3::X, DVec3::Z, -DVec3::Z] {
///     let cam = Camera::look_at(k, eye * 1.2, DVec3::ZERO, DVec3::Y)?;
///     let map = DepthMap::from_view(&Rasterizer::new(&cam).render(&sphere, &params)?)?;
///     views.push((cam, map));
/// }
/// let inputs: Vec<MergeView> = views.iter().map(|(c, d)| MergeView::new(c, d)).collect();
/// let merged = merge_views(&inputs, &MergeParams::default().with_voxel_m(0.005))?;
/// assert!(merged.mesh.vertices.iter().all(|v| (v.length() - 0.2).abs() < 0.005));
/// # Ok::<(), photometric_normals::Error>(())
/// ```
pub fn merge_views(views: &[MergeView], params: &MergeParams) -> Result<MergedSurface> {
    params.validate()?;
    if views.is_empty() {
        return Err(Error::Empty {
            what: "views to merge",
        });
    }
    let mut times = MergeTimes::default();
    let t = Instant::now();
    let prepared = views
        .iter()
        .enumerate()
        .map(|(i, v)| prepare(v, params).at(Context::Camera(i)))
        .collect::<Result<Vec<_>>>()?;
    times.prepare_s = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let mut keys = NodeSet::default();
    for (i, v) in prepared.iter().enumerate() {
        keys.extend(view_blocks(v, params).at(Context::Camera(i))?);
    }
    let mut keys: Vec<Node> = keys.into_iter().collect();
    keys.sort_unstable();
    times.blocks_s = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let blocks: Vec<Block> = keys
        .par_iter()
        .map(|&b| fill_block(b, &prepared, params))
        .collect();
    times.fill_s = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let voxels_observed = blocks
        .iter()
        .map(|b| b.weight.iter().filter(|&&w| w > 0.0).count())
        .sum();
    let index: NodeMap<Node, usize> = keys.iter().enumerate().map(|(i, &k)| (k, i)).collect();
    let value = |n: Node| -> Option<f64> {
        let b = [
            n[0].div_euclid(BLOCK),
            n[1].div_euclid(BLOCK),
            n[2].div_euclid(BLOCK),
        ];
        let block = &blocks[*index.get(&b)?];
        let l = n.map(|c| c.rem_euclid(BLOCK));
        let i = (l[0] + BLOCK * (l[1] + BLOCK * l[2])) as usize;
        (block.weight[i] > 0.0).then(|| f64::from(block.distance[i]))
    };
    // Only cells with a sign change draw anything: find them in parallel (same order as a
    // sequential walk over the blocks, so the mesh does not depend on the thread count).
    // Per block, the blocks at offsets (0|1, 0|1, 0|1) hold all its cells' corners: look
    // them up once, then read the voxels directly (`straddling_cells`).
    let cells: Vec<Node> = keys
        .par_iter()
        .enumerate()
        .flat_map_iter(|(bi, &b)| {
            let around: [Option<&Block>; 8] = std::array::from_fn(|k| {
                if k == 0 {
                    return Some(&blocks[bi]);
                }
                let o = [(k & 1) as i64, ((k >> 1) & 1) as i64, ((k >> 2) & 1) as i64];
                index
                    .get(&[b[0] + o[0], b[1] + o[1], b[2] + o[2]])
                    .map(|&j| &blocks[j])
            });
            straddling_cells(b, &around)
        })
        .collect();
    times.cells_s = t.elapsed().as_secs_f64();
    let t = Instant::now();
    // In parallel chunks, stitched in order: the same mesh as one serial march.
    let mesh = march_cells_par(
        &cells,
        MARCH_CHUNK,
        || value,
        0.0,
        |n| node_position(n, params.voxel_m),
        EdgeFit::Linear,
    )?;
    times.march_s = t.elapsed().as_secs_f64();
    Ok(MergedSurface {
        mesh,
        times,
        stats: MergeStats {
            blocks: keys.len(),
            voxels_allocated: keys.len() * BLOCK_LEN,
            voxels_observed,
            volume_bytes: keys.len() * BLOCK_LEN * 2 * std::mem::size_of::<f32>(),
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use skin_core::camera::Intrinsics;
    use skin_core::mesh::shapes::uv_sphere;
    use skin_core::raster::{Buffers, Rasterizer, RenderParams};

    fn sphere_views(n: usize, size: u32) -> (Vec<Camera>, Vec<DepthMap>) {
        let mesh = uv_sphere(DVec3::ZERO, 0.2, 64, 128).unwrap();
        let k = Intrinsics::from_horizontal_fov(0.5, size, size).unwrap();
        let params = RenderParams::default().with_buffers(Buffers {
            depth: true,
            ..Buffers::MASK_ONLY
        });
        let mut cams = Vec::new();
        let mut maps = Vec::new();
        for i in 0..n {
            let a = std::f64::consts::TAU * i as f64 / n as f64;
            let eye = DVec3::new(a.cos(), 0.3 * (i % 2) as f64, a.sin()) * 1.2;
            let cam = Camera::look_at(k, eye, DVec3::ZERO, DVec3::Y).unwrap();
            let view = Rasterizer::new(&cam).render(&mesh, &params).unwrap();
            maps.push(DepthMap::from_view(&view).unwrap());
            cams.push(cam);
        }
        (cams, maps)
    }

    #[test]
    fn merged_sphere_lies_on_the_sphere() {
        let (cams, maps) = sphere_views(6, 96);
        let views: Vec<MergeView> = cams
            .iter()
            .zip(&maps)
            .map(|(camera, depth)| MergeView::new(camera, depth))
            .collect();
        let params = MergeParams::default().with_voxel_m(0.005);
        let merged = merge_views(&views, &params).unwrap();
        assert!(merged.mesh.face_count() > 1000);
        let err: Vec<f64> = merged
            .mesh
            .vertices
            .iter()
            .map(|v| (v.length() - 0.2).abs())
            .collect();
        let med = skin_core::stats::median(&err);
        assert!(med < 0.002, "median {med}");
        assert!(merged.stats.voxels_observed > 0);
        assert!(merged.stats.voxels_observed <= merged.stats.voxels_allocated);
    }

    #[test]
    fn straddling_cells_are_the_cells_that_straddle() {
        // Eight blocks around block `b` (some missing), distances of both signs and a
        // quarter of the voxels unobserved; the padded scan must find exactly the cells
        // `cell_straddles` accepts.
        use crate::marching_cubes::cell_straddles;
        let rng = skin_core::random::SplitMix64::new(7);
        let u = rng.uniform(8 * 2 * BLOCK_LEN);
        let blocks: Vec<Block> = (0..8)
            .map(|k| Block {
                distance: (0..BLOCK_LEN)
                    .map(|i| (u[2 * (k * BLOCK_LEN + i)] - 0.45) as f32)
                    .collect(),
                weight: (0..BLOCK_LEN)
                    .map(|i| f32::from(u[2 * (k * BLOCK_LEN + i) + 1] > 0.25))
                    .collect(),
            })
            .collect();
        let b: Node = [-3, 2, 5];
        for missing in [None, Some(3), Some(6)] {
            let around: [Option<&Block>; 8] =
                std::array::from_fn(|k| (Some(k) != missing).then(|| &blocks[k]));
            let value = |n: Node| -> Option<f64> {
                let l = [
                    n[0] - b[0] * BLOCK,
                    n[1] - b[1] * BLOCK,
                    n[2] - b[2] * BLOCK,
                ];
                let k = usize::from(l[0] >= BLOCK)
                    | usize::from(l[1] >= BLOCK) << 1
                    | usize::from(l[2] >= BLOCK) << 2;
                let block = around[k]?;
                let m = l.map(|c| c % BLOCK);
                let i = (m[0] + BLOCK * (m[1] + BLOCK * m[2])) as usize;
                (block.weight[i] > 0.0).then(|| f64::from(block.distance[i]))
            };
            let expected: Vec<Node> = (0..BLOCK_LEN)
                .map(|i| block_node(b, i))
                .filter(|&c| cell_straddles(c, value, 0.0))
                .collect();
            assert!(!expected.is_empty());
            assert_eq!(
                straddling_cells(b, &around),
                expected,
                "missing {missing:?}"
            );
        }
    }

    #[test]
    fn rejects_bad_input() {
        let (cams, maps) = sphere_views(2, 32);
        let params = MergeParams::default();
        assert!(matches!(
            merge_views(&[], &params),
            Err(Error::Empty { .. })
        ));
        let good = MergeView::new(&cams[0], &maps[0]);
        let bad_conf = vec![1.0; 3];
        let short = MergeView {
            confidence: Some(&bad_conf),
            ..good
        };
        let e = merge_views(&[good, short], &params).unwrap_err();
        assert!(matches!(e, Error::At { .. }), "{e}");
        assert!(
            matches!(e.root(), Error::Core(_) | Error::SizeMismatch { .. }),
            "{e}"
        );
        let nan_conf = vec![f64::NAN; 32 * 32];
        let nan = MergeView {
            confidence: Some(&nan_conf),
            ..good
        };
        assert!(merge_views(&[nan], &params).is_err());
        let empty = DepthMap::empty(32, 32).unwrap();
        let none = MergeView {
            depth: &empty,
            ..good
        };
        assert!(matches!(
            merge_views(&[none], &params).unwrap_err().root(),
            Error::Empty { .. }
        ));
        let small = DepthMap::empty(16, 16).unwrap();
        let wrong = MergeView {
            depth: &small,
            ..good
        };
        assert!(merge_views(&[wrong], &params).is_err());
        assert!(merge_views(&[good], &params.with_voxel_m(f64::NAN)).is_err());
        assert!(merge_views(&[good], &params.with_ramp_m(0.001)).is_err());
    }
}
