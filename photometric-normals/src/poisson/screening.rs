//! The screening term in its consistent form: `α/h Σᵢ mᵢ χ(pᵢ)²` with `χ(pᵢ)` the trilinear
//! value at the sample, so the term couples the 8 corners of each sample's cell
//! ([`ScreeningForm::Consistent`](super::ScreeningForm::Consistent)): each screened cell's
//! 8 × 8 block is `α/h Σ mᵢ φ(pᵢ) φ(pᵢ)ᵀ` over its samples. Each unknown lists the (cell,
//! corner) pairs it belongs to. A product is taken in two parallel passes with a fixed order
//! of sums: every cell's block times its corners' values, then every unknown's share
//! gathered from its cells (ours: a gather of each cell's corners per unknown instead costs 8
//! times the reads). The blocks take 512 bytes a screened cell.

use std::sync::{Mutex, MutexGuard};

use skin_core::math::DVec3;

use rayon::prelude::*;

use crate::marching_cubes::{Node, NodeMap};

use super::cells::{add, cell_of, corners8, trilinear, NONE};

/// The screened cells of one level and, per unknown, the cells it is a corner of.
pub(super) struct CellScreening {
    /// Corner unknowns of each screened cell ([`corners8`] order; `NONE` outside the band).
    corners: Vec<[u32; 8]>,
    /// The diagonal of each screened cell's block.
    diagonals: Vec<[f64; 8]>,
    /// Each screened cell's block without its diagonal, row-major.
    blocks: Vec<[f64; 64]>,
    /// Unknown `i`'s entries are `entries[start[i]..start[i + 1]]`, each `cell · 8 + corner`.
    start: Vec<u32>,
    entries: Vec<u32>,
    /// The cells' products with the last vector ([`CellScreening::products`]), 8 per cell.
    scratch: Mutex<Vec<f64>>,
}

/// Screened cells per parallel task of the products.
const CELL_CHUNK: usize = 4096;

/// Offsets `start` (length `groups + 1`) of a grouping whose group sizes are counted from
/// `members`, each a group index.
fn offsets(members: impl Iterator<Item = usize>, groups: usize) -> Vec<u32> {
    let mut start = vec![0u32; groups + 1];
    for g in members {
        start[g + 1] += 1;
    }
    for i in 0..groups {
        start[i + 1] += start[i];
    }
    start
}

impl CellScreening {
    /// The blocks of the cells holding the samples (unit-cube position and screening mass
    /// `mᵢ`, in sample order) on a grid of `n` cells (cell size `h`), with `index` giving a
    /// node's unknown (`None` outside the band) and `unknowns` their count.
    /// Each block sums its samples in sample order, so the operator does not depend on the
    /// thread count.
    pub(super) fn new(
        samples: impl Iterator<Item = (DVec3, f64)>,
        n: i64,
        alpha: f64,
        index: impl Fn(Node) -> Option<usize>,
        unknowns: usize,
    ) -> Self {
        let h = 1.0 / n as f64;
        let scale = alpha / h;
        let mut cell_of_key: NodeMap<Node, u32> = NodeMap::default();
        let mut corners: Vec<[u32; 8]> = Vec::new();
        let cell_and_local: Vec<(u32, [f64; 4])> = samples
            .map(|(q, mass)| {
                let (c, t) = cell_of(q, n);
                let ci = *cell_of_key.entry(c).or_insert_with(|| {
                    let mut out = [NONE; 8];
                    for (slot, o) in out.iter_mut().zip(corners8()) {
                        *slot = index(add(c, o, 1)).map_or(NONE, |i| i as u32);
                    }
                    corners.push(out);
                    (corners.len() - 1) as u32
                });
                (ci, [t.x, t.y, t.z, scale * mass])
            })
            .collect();
        drop(cell_of_key);
        // Cells renumbered in the order of their lowest corner's unknown (then of their first
        // sample), so that neighbouring unknowns read neighbouring cells' products (ours,
        // measured on workload 6b at depth 8: in sample order, the reads of the products
        // missed the cache and doubled the finest level's solve).
        let cells = corners.len();
        let mut order: Vec<u32> = (0..cells as u32).collect();
        order.sort_by_key(|&c| corners[c as usize][0]);
        let mut renumber = vec![0u32; cells];
        for (new, &old) in order.iter().enumerate() {
            renumber[old as usize] = new as u32;
        }
        let corners: Vec<[u32; 8]> = order.iter().map(|&c| corners[c as usize]).collect();
        let cell_and_local: Vec<(u32, [f64; 4])> = cell_and_local
            .into_iter()
            .map(|(c, local)| (renumber[c as usize], local))
            .collect();
        let mut diagonals = vec![[0.0; 8]; cells];
        let mut blocks = vec![[0.0; 64]; cells];
        for (c, local) in cell_and_local {
            let t = DVec3::new(local[0], local[1], local[2]);
            let mut w = [0.0; 8];
            for (wk, o) in w.iter_mut().zip(corners8()) {
                *wk = trilinear(t, o);
            }
            let (m, c) = (local[3], c as usize);
            for k in 0..8 {
                diagonals[c][k] += m * w[k] * w[k];
                for l in (0..8).filter(|&l| l != k) {
                    blocks[c][8 * k + l] += m * w[k] * w[l];
                }
            }
        }
        let start = offsets(
            corners
                .iter()
                .flatten()
                .filter(|&&j| j != NONE)
                .map(|&j| j as usize),
            unknowns,
        );
        let mut fill = start.clone();
        let mut entries = vec![0u32; start[unknowns] as usize];
        for (ci, cell) in corners.iter().enumerate() {
            for (k, &j) in cell.iter().enumerate().filter(|(_, &j)| j != NONE) {
                entries[fill[j as usize] as usize] = (ci * 8 + k) as u32;
                fill[j as usize] += 1;
            }
        }
        Self {
            scratch: Mutex::new(vec![0.0; 8 * cells]),
            corners,
            diagonals,
            blocks,
            start,
            entries,
        }
    }

    /// The screening term's diagonal entry of unknown `i`.
    pub(super) fn diagonal(&self, i: usize) -> f64 {
        self.entries[self.start[i] as usize..self.start[i + 1] as usize]
            .iter()
            .map(|&e| self.diagonals[e as usize / 8][e as usize % 8])
            .sum()
    }

    /// Every cell's block without its diagonal times its corners' values in `x` (corners
    /// outside the band count zero), 8 values per cell, held until the guard is dropped;
    /// read each unknown's share with [`CellScreening::off_diagonal`].
    pub(super) fn products(&self, x: &[f64]) -> MutexGuard<'_, Vec<f64>> {
        let mut u = self
            .scratch
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        u.par_chunks_mut(8 * CELL_CHUNK)
            .enumerate()
            .for_each(|(chunk, uc)| {
                for (k, out) in uc.chunks_exact_mut(8).enumerate() {
                    let c = chunk * CELL_CHUNK + k;
                    let xc = self.corners[c].map(|j| if j == NONE { 0.0 } else { x[j as usize] });
                    for (k, o) in out.iter_mut().enumerate() {
                        let row = &self.blocks[c][8 * k..8 * k + 8];
                        *o = row.iter().zip(&xc).map(|(m, v)| m * v).sum();
                    }
                }
            });
        u
    }

    /// Unknown `i`'s share of the off-diagonal screening applied to the vector whose
    /// [`CellScreening::products`] are `u`.
    #[inline]
    pub(super) fn off_diagonal(&self, i: usize, u: &[f64]) -> f64 {
        self.entries[self.start[i] as usize..self.start[i + 1] as usize]
            .iter()
            .map(|&e| u[e as usize])
            .sum()
    }
}
