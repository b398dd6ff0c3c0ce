//! Each level's solver: conjugate gradients ([`skin_core::lsq::pcg`]) preconditioned by a
//! multigrid V-cycle over the coarser levels or by the diagonal.

use rayon::prelude::*;
use skin_core::lsq::{
    pcg, LinearOperator, PcgParams, PcgStats, Preconditioner, Reduction, Reference, ResidualNorm,
};

use crate::marching_cubes::Node;
use crate::Result;

use super::cells::NONE;
use super::grid::Level;
use super::PoissonParams;

/// Damping of the Jacobi smoother (the 3-D 7-point stencil's smoothing optimum is 6/7; a
/// little less is safer with the screening on the diagonal).
pub(super) const OMEGA: f64 = 0.8;
/// Jacobi sweeps before and after each coarse-grid correction.
pub(super) const SWEEPS: usize = 1;
/// Jacobi sweeps that stand for the solve on the coarsest (5³-node) level.
pub(super) const COARSEST_SWEEPS: usize = 60;
/// Depth of the coarsest multigrid level.
pub(super) const COARSEST_DEPTH: u32 = 2;

impl Level {
    /// `y = A x` for this level's operator ([`Level::row`]).
    pub(super) fn apply(&self, x: &[f64], y: &mut [f64]) {
        let u = self.screen.as_ref().map(|s| s.products(x));
        let u = u.as_deref().map(Vec::as_slice);
        y.par_iter_mut()
            .enumerate()
            .for_each(|(i, yi)| *yi = self.row(i, x, u));
    }

    /// Row `i` of the operator applied to `x`: the diagonal `diag`, −1 to each unknown
    /// neighbour and, with the consistent screening, its couplings (`u`, the screening's
    /// [`products`](super::screening::CellScreening::products) with `x`).
    #[inline]
    pub(super) fn row(&self, i: usize, x: &[f64], u: Option<&[f64]>) -> f64 {
        let mut s = self.diag[i] * x[i];
        for &j in &self.nbr[i] {
            if j != NONE {
                s -= x[j as usize];
            }
        }
        if let (Some(screen), Some(u)) = (&self.screen, u) {
            s += screen.off_diagonal(i, u);
        }
        s
    }

    /// `sweeps` damped Jacobi sweeps on `A e = r` (a symmetric smoother).
    pub(super) fn smooth(&self, r: &[f64], e: &mut [f64], sweeps: usize) {
        let mut ae = vec![0.0; e.len()];
        for _ in 0..sweeps {
            self.apply(e, &mut ae);
            e.par_iter_mut()
                .zip(&ae)
                .zip(r)
                .zip(self.smoother_diag())
                .for_each(|(((ei, ai), ri), di)| *ei += OMEGA * (ri - ai) / di);
        }
    }
}

/// Coarse nodes (of the level above) whose trilinear basis functions are nonzero at the
/// fine node `p`, with the interpolation weights: per axis `p/2` (weight 1) for even `p`,
/// `(p ± 1)/2` (weight ½ each) for odd `p`.
pub(super) fn parents(p: Node) -> impl Iterator<Item = (Node, f64)> {
    let lo = p.map(|c| c.div_euclid(2));
    let hi = p.map(|c| (c + 1).div_euclid(2));
    (0..8usize).filter_map(move |corner| {
        let mut q = lo;
        let mut w = 1.0;
        for k in 0..3 {
            if lo[k] != hi[k] {
                w *= 0.5;
                if corner & (1 << k) != 0 {
                    q[k] = hi[k];
                }
            } else if corner & (1 << k) != 0 {
                return None;
            }
        }
        Some((q, w))
    })
}

/// Interpolation weights of [`parents`] at node `p`, in the same order.
pub(super) fn parent_weights(p: Node) -> impl Iterator<Item = f64> {
    parents(p).map(|(_, w)| w)
}

/// Prolongation `P`: the coarse correction interpolated trilinearly onto the fine unknowns
/// (coarse nodes outside the coarse band count zero, as the error's Dirichlet values there).
pub(super) fn prolong(fine: &Level, ec: &[f64], ef: &mut [f64]) {
    ef.par_iter_mut()
        .zip(&fine.nodes)
        .zip(&fine.up)
        .for_each(|((out, &p), up)| {
            *out = up
                .iter()
                .zip(parent_weights(p))
                .filter(|(j, _)| **j != NONE)
                .map(|(&j, w)| w * ec[j as usize])
                .sum();
        });
}

/// Restriction `Pᵀ`: every fine residual scattered to its coarse parents with the
/// interpolation weights (sequential: a scatter, and cheap next to the smoothing).
pub(super) fn restrict(coarse: &Level, fine: &Level, rf: &[f64]) -> Vec<f64> {
    let mut rc = vec![0.0; coarse.nodes.len()];
    for ((&p, up), &r) in fine.nodes.iter().zip(&fine.up).zip(rf) {
        for (&j, w) in up.iter().zip(parent_weights(p)) {
            if j != NONE {
                rc[j as usize] += w * r;
            }
        }
    }
    rc
}

/// One multigrid V-cycle for `A e = r` on level `top` over the hierarchy `coarser` (coarsest
/// first): damped Jacobi, the residual restricted by `Pᵀ`, the coarse problem (the coarser
/// level's own operator, which equals the Galerkin product `Pᵀ A P` up to the factor 2 of
/// the grid spacing) solved recursively, the correction prolongated, Jacobi again. Pre- and
/// post-smoothing are the same symmetric sweeps, so the cycle is a symmetric positive
/// preconditioner for conjugate gradients.
pub(super) fn v_cycle(top: &Level, coarser: &[Level], r: &[f64]) -> Vec<f64> {
    let mut e = vec![0.0; r.len()];
    let Some((coarse, rest)) = coarser.split_last() else {
        top.smooth(r, &mut e, COARSEST_SWEEPS);
        return e;
    };
    top.smooth(r, &mut e, SWEEPS);
    let mut ae = vec![0.0; r.len()];
    top.apply(&e, &mut ae);
    let res: Vec<f64> = r.iter().zip(&ae).map(|(ri, ai)| ri - ai).collect();
    let mut rc = restrict(coarse, top, &res);
    rc.iter_mut().for_each(|v| *v *= 0.5);
    let ec = v_cycle(coarse, rest, &rc);
    prolong(top, &ec, &mut ae);
    e.iter_mut().zip(&ae).for_each(|(ei, pi)| *ei += pi);
    top.smooth(r, &mut e, SWEEPS);
    e
}

/// Conjugate gradients ([`skin_core::lsq::pcg`]) on `level`'s operator from `x`,
/// preconditioned by a multigrid V-cycle over `coarser` ([`v_cycle`]) or by the diagonal
/// (Jacobi), the residual relative to `‖b‖`, the sums in [`CG_CHUNK`] chunks.
///
/// The Jacobi iteration runs in three fused passes over the vectors (`q = A p` with `p · q`;
/// `x`, `r` updated with `r · z` and `r · r`, `z = r / diag` not stored; `p = z + β p`), with
/// no allocation per iteration: the same arithmetic per element as the textbook loop (ours,
/// measured: the separate loops, and a fresh preconditioned vector each iteration — fresh
/// pages from the kernel at the band levels' millions of nodes — were most of the hole
/// filling's time).
pub(super) fn level_cg(
    level: &Level,
    coarser: &[Level],
    multigrid: bool,
    b: &[f64],
    x: &mut [f64],
    params: &PoissonParams,
) -> Result<PcgStats> {
    let mut v = |r: &[f64], z: &mut [f64]| z.copy_from_slice(&v_cycle(level, coarser, r));
    let preconditioner = if multigrid {
        Preconditioner::Apply(&mut v)
    } else {
        Preconditioner::Jacobi(level.smoother_diag())
    };
    Ok(pcg(
        level,
        preconditioner,
        b,
        x,
        ResidualNorm::Euclidean,
        &PcgParams {
            tolerance: params.tolerance,
            max_iterations: params.max_iterations,
            reference: Reference::RightHandSide,
            reduction: Reduction::Chunked(CG_CHUNK),
        },
    )?)
}

/// Elements per task of the conjugate gradients' vector loops. Every sum over a vector is
/// taken serially within such a chunk and the chunks' sums are added in chunk order, so the
/// iterates do not depend on how the work is split among threads (ours: rayon's
/// `sum` adds in an order that depends on work stealing, which made the mesh differ in its
/// last bits from run to run).
pub(super) const CG_CHUNK: usize = 8192;

impl LinearOperator for Level {
    fn apply(&self, x: &[f64], y: &mut [f64]) {
        Level::apply(self, x, y);
    }

    /// `q = A p` ([`Level::apply`]) and `p · q` in the same pass (chunked: the sum of
    /// [`Reduction::dot`]).
    fn apply_dot(&self, p: &[f64], q: &mut [f64], reduction: Reduction) -> f64 {
        let Reduction::Chunked(chunk) = reduction else {
            Level::apply(self, p, q);
            return reduction.dot(p, q);
        };
        let u = self.screen.as_ref().map(|s| s.products(p));
        let u = u.as_deref().map(Vec::as_slice);
        let partial: Vec<f64> = q
            .par_chunks_mut(chunk)
            .enumerate()
            .map(|(ci, qc)| {
                let base = ci * chunk;
                let mut pq = 0.0;
                for (k, qi) in qc.iter_mut().enumerate() {
                    let i = base + k;
                    let s = self.row(i, p, u);
                    *qi = s;
                    pq += p[i] * s;
                }
                pq
            })
            .collect();
        partial.iter().sum()
    }
}
