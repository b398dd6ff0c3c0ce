//! The screening term in its consistent form: `α/h Σᵢ mᵢ χ(pᵢ)²` with `χ(pᵢ)` the trilinear
//! value at the sample, so the term couples the 8 corners of each sample's cell
//! ([`ScreeningForm::Consistent`](super::ScreeningForm::Consistent)): each screened cell's
//! 8 × 8 block is `α/h Σ mᵢ φ(pᵢ) φ(pᵢ)ᵀ` over its samples. Each unknown lists the (cell,
//! corner) pairs it belongs to. A product is taken in two parallel passes with a fixed order
//! of sums: every cell's block times its corners' values, then every unknown's share
//! gathered from its cells. On levels with few samples a cell, the blocks are applied from
//! their samples' local coordinates (32 bytes a sample) rather than stored (512 bytes a cell;
//! ours, measured on workload 6b, about one sample per finest cell: streaming stored blocks
//! cost more than the arithmetic they save, and on the coarse levels, thousands of samples a
//! cell, the reverse). A gather of each cell's corners per unknown instead of the two
//! passes costs 8 times the reads.

use std::sync::{Mutex, MutexGuard};

use skin_core::math::DVec3;

use rayon::prelude::*;

use crate::marching_cubes::{Node, NodeMap};

use super::cells::{cell_of, corners8, NONE};

/// The screened cells of one level and, per unknown, the cells it is a corner of.
pub(super) struct CellScreening {
    /// Corner unknowns of each screened cell ([`corners8`] order; `NONE` outside the band).
    corners: Vec<[u32; 8]>,
    /// The diagonal of each screened cell's block.
    diagonals: Vec<[f64; 8]>,
    /// The blocks, stored or from their samples.
    blocks: Blocks,
    /// Unknown `i`'s entries are `entries[start[i]..start[i + 1]]`, each `cell · 8 + corner`.
    start: Vec<u32>,
    entries: Vec<u32>,
    /// The cells' products with the last vector ([`CellScreening::products`]), 8 per cell.
    scratch: Mutex<Vec<f64>>,
}

/// How the cells' blocks are held.
enum Blocks {
    /// Each cell's block, row-major.
    Stored(Vec<[f64; 64]>),
    /// Cell `c`'s samples are `samples[cell_start[c]..cell_start[c + 1]]`: each sample's
    /// local coordinates in its cell and its screening weight `α/h · mᵢ`, in sample order
    /// within a cell.
    FromSamples {
        cell_start: Vec<u32>,
        samples: Vec<[f64; 4]>,
    },
}

/// Samples a cell on average from which a level's blocks are stored rather than applied
/// from their samples (a stored block reads 64 numbers, a sample 4 and costs about 30
/// operations).
const STORE_FROM: usize = 8;

/// Screened cells per parallel task of the products.
const CELL_CHUNK: usize = 4096;

/// The trilinear weights of a cell's corners ([`corners8`] order) at local coordinates `t`.
#[inline]
fn weights(t: &[f64; 4]) -> [f64; 8] {
    let (x, y, z) = (t[0], t[1], t[2]);
    let (ax, ay, az) = ([1.0 - x, x], [1.0 - y, y], [1.0 - z, z]);
    std::array::from_fn(|k| ax[k & 1] * ay[(k >> 1) & 1] * az[k >> 2])
}

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
                        *slot = index([c[0] + o[0], c[1] + o[1], c[2] + o[2]])
                            .map_or(NONE, |i| i as u32);
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
        let cell_start = offsets(cell_and_local.iter().map(|&(c, _)| c as usize), cells);
        let mut fill = cell_start.clone();
        let mut by_cell = vec![[0.0; 4]; cell_and_local.len()];
        for &(c, local) in &cell_and_local {
            by_cell[fill[c as usize] as usize] = local;
            fill[c as usize] += 1;
        }
        drop(cell_and_local);
        let mut diagonals = vec![[0.0; 8]; cells];
        let stored = by_cell.len() >= STORE_FROM * cells;
        let mut stored_blocks = vec![[0.0; 64]; if stored { cells } else { 0 }];
        for c in 0..cells {
            for local in &by_cell[cell_start[c] as usize..cell_start[c + 1] as usize] {
                let w = weights(local);
                for (d, wk) in diagonals[c].iter_mut().zip(w) {
                    *d += local[3] * wk * wk;
                }
                if stored {
                    let block = &mut stored_blocks[c];
                    for k in 0..8 {
                        for l in (0..8).filter(|&l| l != k) {
                            block[8 * k + l] += local[3] * w[k] * w[l];
                        }
                    }
                }
            }
        }
        let blocks = if stored {
            Blocks::Stored(stored_blocks)
        } else {
            Blocks::FromSamples {
                cell_start,
                samples: by_cell,
            }
        };
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
                    let mut acc = [0.0; 8];
                    match &self.blocks {
                        Blocks::Stored(blocks) => {
                            for (k, a) in acc.iter_mut().enumerate() {
                                let row = &blocks[c][8 * k..8 * k + 8];
                                *a = row.iter().zip(&xc).map(|(m, v)| m * v).sum();
                            }
                            out.copy_from_slice(&acc);
                            continue;
                        }
                        Blocks::FromSamples {
                            cell_start,
                            samples,
                        } => {
                            let range = cell_start[c] as usize..cell_start[c + 1] as usize;
                            for local in &samples[range] {
                                let w = weights(local);
                                let at: f64 = w.iter().zip(&xc).map(|(a, b)| a * b).sum();
                                let mv = local[3] * at;
                                for (a, wk) in acc.iter_mut().zip(w) {
                                    *a += mv * wk;
                                }
                            }
                        }
                    }
                    for ((o, a), (d, xk)) in out
                        .iter_mut()
                        .zip(acc)
                        .zip(self.diagonals[c].iter().zip(xc))
                    {
                        *o = a - d * xk;
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
