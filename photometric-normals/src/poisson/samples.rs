//! The samples in the unit cube: their areas from the local sample density, and the band
//! of blocks around them on a level.

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use rayon::prelude::*;
use skin_core::math::DVec3;

use crate::marching_cubes::{Node, NodeMap, NodeSet};

use super::cells::{cell_of, nearest_node};
use super::grid::B;
use super::OrientedSample;

/// Unit-cube sample: position, oriented area `w a n`, screening mass `w a`.
pub(super) struct UnitSample {
    pub(super) q: DVec3,
    pub(super) flux: DVec3,
    pub(super) mass: f64,
    pub(super) weight: f64,
}

pub(super) fn unit_samples(
    samples: &[OrientedSample],
    scale: f64,
    depth: u32,
) -> (Vec<UnitSample>, DVec3, f64) {
    let (lo, hi) = samples.iter().fold(
        (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
        |(a, b), s| (a.min(s.position), b.max(s.position)),
    );
    let side = (hi - lo).max_element().max(1e-9) * scale;
    let origin = 0.5 * (lo + hi) - DVec3::splat(0.5 * side);
    let qs: Vec<DVec3> = samples
        .iter()
        .map(|s| (s.position - origin) / side)
        .collect();
    let areas = kernel_areas(&qs, depth).unwrap_or_else(|| cell_areas(&qs, samples, depth));
    let out = qs
        .iter()
        .zip(samples)
        .zip(areas)
        .map(|((&q, s), a)| UnitSample {
            q,
            flux: s.normal.normalize_or_zero() * (s.weight * a),
            mass: s.weight * a,
            weight: s.weight,
        })
        .collect();
    (out, origin, side)
}

/// Radius of the density kernel at most, in cells of the finest level.
pub(super) const DENSITY_RADIUS_CELLS: f64 = 4.0;
/// Neighbours the density kernel spans at most (dense samples shrink its radius, so the cost
/// does not grow with the sample density).
pub(super) const DENSITY_NEIGHBOURS: usize = 40;

/// The surface area each sample stands for, `1 / σᵢ` with `σᵢ` the local sample density per
/// unit area, estimated by a smooth kernel over the samples within `rᵢ` (the
/// [`DENSITY_NEIGHBOURS`]-th neighbour's distance, at most [`DENSITY_RADIUS_CELLS`] finest
/// cells): `ρᵢ = Σⱼ (1 − dᵢⱼ²/rᵢ²)²`, which for samples of a plane at density `σ` is
/// `σ π rᵢ² / 3`, so `aᵢ = π rᵢ² / (3 ρᵢ)`. Unlike a count per grid cell, this does not
/// depend on where the surface cuts the grid (a plane clipping a cell's corner leaves few
/// samples in it, and a per-cell count then gives each of them a large area: a wiggle of the
/// iso-surface at the grid's period). `None` if the kd-tree cannot be built (heavily
/// duplicated samples).
///
/// The neighbours are found on a uniform grid of cells `r / 2` wide ([`grid_kernel_areas`]),
/// which gives the kd-tree's neighbours ([`tree_kernel_areas`], kept as the reference) at a
/// fraction of its cost (measured: the kd-tree's 40-nearest queries were a quarter of each
/// 1024² hole filling).
pub(super) fn kernel_areas(qs: &[DVec3], depth: u32) -> Option<Vec<f64>> {
    grid_kernel_areas(qs, depth).or_else(|| tree_kernel_areas(qs, depth))
}

/// The kernel's weight sum `ρ` and squared radius `r²` of one sample from the squared
/// distances `d2` to its candidate neighbours (itself included), of which every sample within
/// `r` (`r2_max = r²`) must be one: the `k` nearest ([`DENSITY_NEIGHBOURS`], or all samples
/// when fewer) are moved to the front, `r²` is the farthest of them (at most `r2_max`;
/// `r2_max` when fewer than `k` lie within `r`, or when they all sit at distance 0), and `ρ`
/// sums over them — as [`tree_kernel_areas`] does over the kd-tree's nearest.
pub(super) fn kernel_sum(d2: &mut [f64], r2_max: f64, k: usize) -> f64 {
    let near = if d2.len() > k {
        d2.select_nth_unstable_by(k - 1, f64::total_cmp);
        &d2[..k]
    } else {
        &d2[..]
    };
    let far = near.iter().fold(0.0f64, |a, &d| a.max(d));
    let within = near.iter().filter(|&&d| d <= r2_max).count();
    let r2 = if within < k || far <= 0.0 {
        r2_max
    } else {
        far.min(r2_max)
    };
    let rho: f64 = near
        .iter()
        .map(|&d| {
            let t = (1.0 - d / r2).max(0.0);
            t * t
        })
        .sum();
    std::f64::consts::PI * r2 / 3.0 / rho.max(1.0)
}

/// [`kernel_areas`] with the neighbours from a uniform grid of cells half the kernel's
/// largest radius `r` wide (ours; the same neighbours as the kd-tree's up to ties at the
/// [`DENSITY_NEIGHBOURS`]-th distance, which weigh 0): the 3 × 3 × 3 cells around a sample
/// hold every sample within `r / 2`, so when at least [`DENSITY_NEIGHBOURS`] of those lie
/// within `r / 2` they are the nearest; otherwise the 5 × 5 × 5 cells (every sample within
/// `r`) are searched. `None` for fewer samples than [`DENSITY_NEIGHBOURS`] (where the kd-tree
/// answers) or a grid too fine to index.
pub(super) fn grid_kernel_areas(qs: &[DVec3], depth: u32) -> Option<Vec<f64>> {
    if qs.len() < DENSITY_NEIGHBOURS || qs.len() > u32::MAX as usize {
        return None;
    }
    let r = DENSITY_RADIUS_CELLS / (1u64 << depth) as f64;
    let cell = 0.5 * r;
    let lo = qs
        .iter()
        .fold(DVec3::splat(f64::INFINITY), |a, q| a.min(*q));
    let hi = qs
        .iter()
        .fold(DVec3::splat(f64::NEG_INFINITY), |a, q| a.max(*q));
    if !(lo.is_finite() && hi.is_finite()) {
        return None;
    }
    let dims = ((hi - lo) / cell).floor() + DVec3::ONE;
    if dims.max_element() > f64::from(1u32 << 20) {
        return None;
    }
    let dims = [dims.x as i64, dims.y as i64, dims.z as i64];
    let coords = |q: DVec3| -> [i64; 3] {
        let g = (q - lo) / cell;
        [
            (g.x.floor() as i64).clamp(0, dims[0] - 1),
            (g.y.floor() as i64).clamp(0, dims[1] - 1),
            (g.z.floor() as i64).clamp(0, dims[2] - 1),
        ]
    };
    let key = |c: [i64; 3]| (c[0] + dims[0] * (c[1] + dims[1] * c[2])) as u64;
    // Samples sorted by cell; each occupied cell's run in that order.
    let mut order: Vec<(u64, u32)> = qs
        .par_iter()
        .enumerate()
        .map(|(i, &q)| (key(coords(q)), i as u32))
        .collect();
    order.par_sort_unstable();
    let mut runs: NodeMap<u64, (u32, u32)> = NodeMap::default();
    let mut cells: Vec<(u32, u32)> = Vec::new();
    let mut start = 0usize;
    for i in 1..=order.len() {
        if i == order.len() || order[i].0 != order[start].0 {
            runs.insert(order[start].0, (start as u32, i as u32));
            cells.push((start as u32, i as u32));
            start = i;
        }
    }
    let points: Vec<DVec3> = order.iter().map(|&(_, i)| qs[i as usize]).collect();
    let (half2, r2_max) = (cell * cell, r * r);
    // The samples of the cells within `reach` of cell `c`, cell by cell in z, y, x order.
    let candidates = |c: [i64; 3], reach: i64, out: &mut Vec<DVec3>| {
        out.clear();
        for z in (c[2] - reach).max(0)..=(c[2] + reach).min(dims[2] - 1) {
            for y in (c[1] - reach).max(0)..=(c[1] + reach).min(dims[1] - 1) {
                for x in (c[0] - reach).max(0)..=(c[0] + reach).min(dims[0] - 1) {
                    if let Some(&(a, b)) = runs.get(&key([x, y, z])) {
                        out.extend_from_slice(&points[a as usize..b as usize]);
                    }
                }
            }
        }
    };
    // Cell by cell: every sample of a cell has the same candidates (gathered once per cell,
    // the wider ones only when a sample needs them), and each sample's squared distances to
    // them, in their order, are what a gather per sample would give.
    let per_cell: Vec<Vec<(u32, f64)>> = cells
        .par_iter()
        .map_init(
            || (Vec::new(), Vec::new(), Vec::new()),
            |(near, far, d2): &mut (Vec<DVec3>, Vec<DVec3>, Vec<f64>), &(a, b)| {
                let c = coords(points[a as usize]);
                candidates(c, 1, near);
                far.clear();
                order[a as usize..b as usize]
                    .iter()
                    .map(|&(_, i)| {
                        let q = qs[i as usize];
                        d2.clear();
                        d2.extend(near.iter().map(|p| (*p - q).length_squared()));
                        if d2.iter().filter(|&&d| d <= half2).count() < DENSITY_NEIGHBOURS {
                            if far.is_empty() {
                                candidates(c, 2, far);
                            }
                            d2.clear();
                            d2.extend(far.iter().map(|p| (*p - q).length_squared()));
                        }
                        (i, kernel_sum(d2, r2_max, DENSITY_NEIGHBOURS))
                    })
                    .collect()
            },
        )
        .collect();
    let mut areas = vec![0.0; qs.len()];
    for (i, a) in per_cell.into_iter().flatten() {
        areas[i as usize] = a;
    }
    Some(areas)
}

/// [`kernel_areas`] with the neighbours from a kd-tree (the reference of
/// [`grid_kernel_areas`]). `None` if the kd-tree cannot be built (heavily duplicated
/// samples).
pub(super) fn tree_kernel_areas(qs: &[DVec3], depth: u32) -> Option<Vec<f64>> {
    let keys: Vec<[f64; 3]> = qs.iter().map(|q| q.to_array()).collect();
    let tree = ImmutableKdTree::<f64, 3>::new_from_slice(&keys).ok()?;
    let r = DENSITY_RADIUS_CELLS / (1u64 << depth) as f64;
    let k = std::num::NonZero::new(DENSITY_NEIGHBOURS.min(keys.len()))?;
    Some(
        keys.par_iter()
            .map(|key| {
                let found = tree
                    .query(key)
                    .nearest_n::<SquaredEuclidean<f64>>(k)
                    .unsorted()
                    .execute();
                let far = found.iter().fold(0.0f64, |a, f| a.max(f.distance));
                let r2 = if found.len() < k.get() || far <= 0.0 {
                    r * r
                } else {
                    far.min(r * r)
                };
                let rho: f64 = found
                    .iter()
                    .map(|f| {
                        let t = (1.0 - f.distance / r2).max(0.0);
                        t * t
                    })
                    .sum();
                std::f64::consts::PI * r2 / 3.0 / rho.max(1.0)
            })
            .collect(),
    )
}

/// The former estimate (fallback): the area of the surface in the sample's cell two levels
/// above the finest (a plane with unit normal `n̄` covers `H² / (|n̄ₓ| + |n̄_y| + |n̄_z|)` of a
/// cell of side `H` on average) shared equally among the samples in that cell.
pub(super) fn cell_areas(qs: &[DVec3], samples: &[OrientedSample], depth: u32) -> Vec<f64> {
    let dn = 1i64 << depth.saturating_sub(2).max(1);
    let hd = 1.0 / dn as f64;
    let mut cells: NodeMap<Node, (usize, DVec3)> = NodeMap::default();
    for (q, s) in qs.iter().zip(samples) {
        let e = cells.entry(cell_of(*q, dn).0).or_insert((0, DVec3::ZERO));
        e.0 += 1;
        e.1 += s.normal.normalize_or_zero();
    }
    qs.iter()
        .map(|&q| {
            let (count, nsum) = cells[&cell_of(q, dn).0];
            let nbar = nsum.normalize_or_zero();
            let l1 = nbar.x.abs() + nbar.y.abs() + nbar.z.abs();
            hd * hd / if l1 > 0.0 { l1 } else { 1.0 } / count as f64
        })
        .collect()
}

/// Active-block mask of a band level: blocks holding a node of a sample's splats, dilated
/// by `dilate` blocks. The flux splat's quadratic stencil reaches one node beyond the
/// sample cell's corners; a dilation by a block or more holds it, so the corners' blocks
/// are dilated then, and the stencil's span only without dilation.
pub(super) fn band_blocks(samples: &[UnitSample], depth: u32, dilate: i64) -> Vec<bool> {
    let n = 1i64 << depth;
    let nb = n / B + 1;
    let mut active = vec![false; (nb * nb * nb) as usize];
    let mut core: NodeSet<Node> = NodeSet::default();
    let mut last = [[-1i64; 3]; 2];
    for s in samples {
        let (lo, hi) = if dilate > 0 {
            let (c, _) = cell_of(s.q, n);
            (c, c.map(|v| v + 1))
        } else {
            let (c, _) = nearest_node(s.q, n);
            (c.map(|v| (v - 1).max(0)), c.map(|v| (v + 1).min(n)))
        };
        let (lo, hi) = (lo.map(|v| v / B), hi.map(|v| v / B));
        if [lo, hi] == last {
            continue;
        }
        last = [lo, hi];
        for bz in lo[2]..=hi[2] {
            for by in lo[1]..=hi[1] {
                for bx in lo[0]..=hi[0] {
                    core.insert([bx, by, bz]);
                }
            }
        }
    }
    for b in core {
        for dz in -dilate..=dilate {
            for dy in -dilate..=dilate {
                for dx in -dilate..=dilate {
                    let q = [b[0] + dx, b[1] + dy, b[2] + dz];
                    if q.iter().all(|&v| (0..nb).contains(&v)) {
                        active[(q[0] + nb * (q[1] + nb * q[2])) as usize] = true;
                    }
                }
            }
        }
    }
    active
}
