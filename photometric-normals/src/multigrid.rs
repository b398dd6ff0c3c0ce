//! An O(n) solver for the normal equations of Eq. 3.3 (§3.3.1): conjugate gradients
//! preconditioned by one aggregation-multigrid V-cycle on the masked pixel grid, warm-started
//! from the proxy depth.
//!
//! **The system.** Eq. 3.3's normal matrix `N = AᵀA + α CᵀC` couples each unknown only to its
//! four pixel neighbours (a 5-point stencil on the foreground pixels), and is symmetric
//! positive definite as soon as every connected region has a proxy depth. Its weak modes are
//! not the constants of a Poisson problem but the depth maps the normals integrate to: the
//! chord constraint `(n_i + n_j)ᵀ(r_i z_i − r_j z_j) = 0` is blind to a common scale of `z`,
//! so `N z* ≈ 0` for the true depths `z*` and only `α ≈ 10⁻⁶` lifts that mode.
//!
//! **The change of variables.** With the warm start `z₀` (the proxy depth, positive) we solve
//! for `t` in `z = diag(z₀) t`. The scaled matrix `N' = diag(z₀) N diag(z₀)` has the
//! near-constant `t ≈ 1` as its weak mode (exactly constant where the proxy's shape matches
//! the normals): each constraint becomes `w_ij (t_i − t_j) + (small)`, a weighted graph
//! Laplacian. This is the linear analogue of the log-depth substitution that turns
//! perspective normal integration into a Poisson equation (Quéau, Durou & Aujol, "Normal
//! integration: a survey", 2018), and the same as the tentative prolongator of smoothed
//! aggregation built on a near-null-space candidate (Vaněk, Mandel & Brezina 1996). Once
//! the weak mode is the constant, plain geometric multigrid applies.
//!
//! **The hierarchy.** Each coarse unknown aggregates the (up to four) foreground pixels of a
//! 2 × 2 block of the finer grid that lie in one connected region (a view splits into
//! several regions at silhouettes and removed discontinuities: each has its own scale mode,
//! lifted only by α, which a coarse unknown shared by two regions could not represent); the
//! prolongation `P` is piecewise constant and the coarse
//! operator is Galerkin's `Pᵀ N' P`. For a 5-point stencil this product is again a 5-point
//! stencil on the half-size grid (blocks touch only through their 4-neighbours), so every
//! level has the fine level's data layout and costs a quarter of it: O(n) memory and work per
//! cycle. Galerkin operators respect the mask exactly (no rediscretisation of boundaries or
//! of the varying weights `((n_i + n_j)ᵀ r)²`, which vanish at grazing angles). The coarsest
//! level (≤ [`COARSEST_UNKNOWNS`] unknowns, at the latest a 1 × 1 grid with one unknown per
//! region) is solved by dense Cholesky.
//!
//! **The cycle and the Krylov method.** One V-cycle with symmetric Gauss–Seidel smoothing
//! (forward before the coarse correction, backward after) is a symmetric positive definite
//! preconditioner, so conjugate gradients apply (Tatebe 1993, "The multigrid preconditioned
//! conjugate gradient method"). Piecewise-constant aggregation alone under-corrects smooth
//! errors (the coarse space approximates them by staircases; Braess 1995), and CG makes up
//! for much of this weakness, the standard pairing in aggregation AMG (Notay's AGMG uses it
//! with a Krylov-accelerated cycle). The coarse correction is scaled by
//! [`MultigridParams::coarse_scale`] (over-correction, Braess 1995), which keeps a two-grid
//! preconditioner SPD for values below 2 (the CG loop stops should a search direction lose
//! positive curvature).
//!
//! **Where it stops paying.** On compact foregrounds (a sphere view, 165 k–660 k pixels) CG
//! needs 12–13 cycles at any size and takes about a third of the direct solve's CPU time; on
//! the studio's ragged masks (thin limbs, the hull's discontinuity cuts, weights
//! `((n_i + n_j)ᵀ r)²` vanishing at grazing silhouettes) it needs 25–93 cycles, growing with
//! resolution, and is no faster than the direct solve at 20 k–90 k pixels — which is why
//! [`crate::IntegrationSolver::Direct`] is the default. Strength-of-connection or smoothed
//! aggregation would be the next step.
//!
//! **Stopping.** CG stops when the residual of the normal equations (in depth units, i.e. the
//! scaled residual divided by `z₀`) falls to [`MultigridParams::tolerance`] times the warm
//! start's residual (the proxy's disagreement with the normals), or after
//! [`MultigridParams::max_iterations`].

use std::collections::HashMap;

use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};
use skin_core::check;

use crate::{Error, Result};

/// Levels stop coarsening at this many unknowns; the coarsest is solved by dense Cholesky.
pub const COARSEST_UNKNOWNS: usize = 256;

/// Knobs of the multigrid-preconditioned conjugate gradients solve of Eq. 3.3.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MultigridParams {
    /// CG stops when the residual norm of the normal equations falls to this fraction of the
    /// warm start's. Default 10⁻⁷ (ours: on the 512² and 1024² sphere views of the
    /// benchmark the depths stay within a nanometre of the direct solve's; see
    /// `docs/photometric-normals.md`).
    pub tolerance: f64,
    /// Most CG iterations (one V-cycle each). Default 200 (ours; the sphere views of the
    /// tests and the benchmark need 8–15).
    pub max_iterations: usize,
    /// Gauss–Seidel sweeps before and after each coarse correction. Default 1 (ours: on the
    /// 1024² sphere view of the benchmark, 2 sweeps save 2 of 13 iterations for 20 % more
    /// CPU time).
    pub smoothing_sweeps: usize,
    /// Scale of the coarse-grid correction (over-correction of piecewise-constant
    /// aggregation; in `(0, 1.99]`, below 2 the preconditioner stays positive definite). Default
    /// 1.8 (ours: on the 1024² sphere view, 1.0 needs 57 iterations, 1.6 19, 1.8 13, 1.9
    /// 11; 1.8 keeps a margin from 2).
    pub coarse_scale: f64,
    /// Coarse-grid visits per level: 1 is a V-cycle, 2 a W-cycle (still O(n) with 2 × 2
    /// aggregation: each level costs a quarter of the finer one, visited twice as often).
    /// Default 1 (ours).
    pub cycle_index: usize,
}

impl Default for MultigridParams {
    fn default() -> Self {
        Self {
            tolerance: 1e-7,
            max_iterations: 200,
            smoothing_sweeps: 1,
            coarse_scale: 1.8,
            cycle_index: 1,
        }
    }
}

impl MultigridParams {
    pub(crate) fn validate(&self) -> Result<()> {
        check::positive("multigrid tolerance", self.tolerance)?;
        check::nonzero("multigrid max_iterations", self.max_iterations)?;
        check::nonzero("multigrid smoothing_sweeps", self.smoothing_sweeps)?;
        check::positive("multigrid coarse_scale", self.coarse_scale)?;
        check::in_range("multigrid coarse_scale", self.coarse_scale, 0.0..=1.99)?;
        check::in_range("multigrid cycle_index", self.cycle_index as f64, 1.0..=2.0)?;
        Ok(())
    }
}

/// What the iterative solve reached.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct MultigridStats {
    /// CG iterations (V-cycles) run.
    pub(crate) iterations: usize,
    /// Final residual norm over the warm start's (scaled system).
    pub(crate) relative_residual: f64,
    /// Levels of the hierarchy, the finest included.
    pub(crate) levels: usize,
}

/// Neighbour directions of the 5-point stencil.
const LEFT: usize = 0;
const RIGHT: usize = 1;
const UP: usize = 2;
const DOWN: usize = 3;

/// A symmetric 5-point operator on the unknowns of a masked grid.
struct Level {
    width: usize,
    /// Grid cell (row-major) of each unknown.
    cell: Vec<usize>,
    diag: Vec<f64>,
    /// `1 / diag`, for the smoother.
    inv_diag: Vec<f64>,
    /// Neighbour unknown per direction (the unknown itself where there is none: its
    /// coefficient is 0).
    nbr: Vec<[u32; 4]>,
    coef: Vec<[f64; 4]>,
}

impl Level {
    fn new(
        width: usize,
        cell: Vec<usize>,
        diag: Vec<f64>,
        nbr: Vec<[u32; 4]>,
        coef: Vec<[f64; 4]>,
    ) -> Self {
        let inv_diag = diag.iter().map(|d| 1.0 / d).collect();
        Self {
            width,
            cell,
            diag,
            inv_diag,
            nbr,
            coef,
        }
    }

    fn len(&self) -> usize {
        self.diag.len()
    }

    fn apply(&self, x: &[f64], y: &mut [f64]) {
        for k in 0..self.len() {
            let (n, c) = (&self.nbr[k], &self.coef[k]);
            y[k] = self.diag[k] * x[k]
                + c[0] * x[n[0] as usize]
                + c[1] * x[n[1] as usize]
                + c[2] * x[n[2] as usize]
                + c[3] * x[n[3] as usize];
        }
    }

    #[inline(always)]
    fn relax(&self, k: usize, b: &[f64], x: &mut [f64]) {
        let (n, c) = (&self.nbr[k], &self.coef[k]);
        let off = c[0] * x[n[0] as usize]
            + c[1] * x[n[1] as usize]
            + c[2] * x[n[2] as usize]
            + c[3] * x[n[3] as usize];
        x[k] = (b[k] - off) * self.inv_diag[k];
    }

    /// The 2 × 2-aggregated Galerkin operator `Pᵀ A P` and each unknown's aggregate. An
    /// aggregate holds the unknowns of one block that belong to one connected region
    /// (`region`), so that every region keeps unknowns of its own down to the coarsest level
    /// (its scale mode, lifted only by α, stays representable there).
    fn coarsen(&self, height: usize, region: &[u32]) -> (Level, usize, Vec<u32>) {
        let (cw, ch) = (self.width.div_ceil(2), height.div_ceil(2));
        let block = |cell: usize| (cell / self.width / 2) * cw + (cell % self.width) / 2;
        let mut ids: HashMap<(usize, u32), u32> = HashMap::with_capacity(self.len() / 3 + 1);
        let mut cell = Vec::new();
        let agg: Vec<u32> = self
            .cell
            .iter()
            .zip(region)
            .map(|(&c, &r)| {
                let b = block(c);
                *ids.entry((b, r)).or_insert_with(|| {
                    cell.push(b);
                    (cell.len() - 1) as u32
                })
            })
            .collect();
        let nc = cell.len();
        let mut diag = vec![0.0; nc];
        let mut coef = vec![[0.0; 4]; nc];
        let mut nbr: Vec<[u32; 4]> = (0..nc as u32).map(|k| [k; 4]).collect();
        for k in 0..self.len() {
            let a = agg[k] as usize;
            diag[a] += self.diag[k];
            for d in 0..4 {
                let j = self.nbr[k][d] as usize;
                if j == k {
                    continue;
                }
                if agg[j] as usize == a {
                    diag[a] += self.coef[k][d];
                } else {
                    // The block next to `a` in direction `d`, same region: one aggregate.
                    coef[a][d] += self.coef[k][d];
                    nbr[a][d] = agg[j];
                }
            }
        }
        (Level::new(cw, cell, diag, nbr, coef), ch, agg)
    }

    /// The connected region of each unknown (union–find over the couplings).
    fn regions(&self) -> Vec<u32> {
        fn root(parent: &mut [u32], mut k: u32) -> u32 {
            while parent[k as usize] != k {
                let p = parent[parent[k as usize] as usize];
                parent[k as usize] = p;
                k = p;
            }
            k
        }
        let mut parent: Vec<u32> = (0..self.len() as u32).collect();
        for k in 0..self.len() {
            for &j in &self.nbr[k] {
                let (a, b) = (root(&mut parent, k as u32), root(&mut parent, j));
                if a != b {
                    parent[a.max(b) as usize] = a.min(b);
                }
            }
        }
        (0..self.len() as u32)
            .map(|k| root(&mut parent, k))
            .collect()
    }

    fn dense(&self) -> DMatrix<f64> {
        let n = self.len();
        let mut m = DMatrix::zeros(n, n);
        for k in 0..n {
            m[(k, k)] += self.diag[k];
            for d in 0..4 {
                m[(k, self.nbr[k][d] as usize)] += self.coef[k][d];
            }
        }
        m
    }
}

/// The V-cycle preconditioner: levels finest first, each coarser one's aggregation map.
struct Hierarchy {
    levels: Vec<Level>,
    /// `agg[l][k]`: the unknown of level `l + 1` that unknown `k` of level `l` belongs to.
    agg: Vec<Vec<u32>>,
    coarsest: nalgebra::Cholesky<f64, nalgebra::Dyn>,
    params: MultigridParams,
}

impl Hierarchy {
    fn new(fine: Level, height: usize, params: MultigridParams) -> Result<Self> {
        let mut region = fine.regions();
        let mut levels = vec![fine];
        let mut agg = Vec::new();
        let mut h = height;
        while let Some(last) = levels.last() {
            if last.len() <= COARSEST_UNKNOWNS || (last.width <= 1 && h <= 1) {
                break;
            }
            let (coarse, ch, map) = last.coarsen(h, &region);
            let mut next = vec![0; coarse.len()];
            for (k, &a) in map.iter().enumerate() {
                next[a as usize] = region[k];
            }
            region = next;
            h = ch;
            agg.push(map);
            levels.push(coarse);
        }
        let coarsest = levels
            .last()
            .map(Level::dense)
            .and_then(|m| m.cholesky())
            .ok_or(Error::InvalidParam {
                name: "integration system",
                reason: "the coarsest multigrid operator is not positive definite (a region \
                         without proxy depth, or alpha = 0)"
                    .into(),
            })?;
        Ok(Self {
            levels,
            agg,
            coarsest,
            params,
        })
    }

    /// `x ≈ A⁻¹ b` at level `l` by one V-cycle from `x = 0`.
    fn cycle(&self, l: usize, b: &[f64], x: &mut [f64]) {
        let a = &self.levels[l];
        if l + 1 == self.levels.len() {
            let s = self.coarsest.solve(&DVector::from_column_slice(b));
            x.copy_from_slice(s.as_slice());
            return;
        }
        x.fill(0.0);
        for _ in 0..self.params.smoothing_sweeps {
            for k in 0..a.len() {
                a.relax(k, b, x);
            }
        }
        let map = &self.agg[l];
        let mut r = vec![0.0; a.len()];
        let mut bc = vec![0.0; self.levels[l + 1].len()];
        let mut xc = vec![0.0; bc.len()];
        for _ in 0..self.params.cycle_index {
            a.apply(x, &mut r);
            bc.fill(0.0);
            for k in 0..a.len() {
                bc[map[k] as usize] += b[k] - r[k];
            }
            self.cycle(l + 1, &bc, &mut xc);
            for k in 0..a.len() {
                x[k] += self.params.coarse_scale * xc[map[k] as usize];
            }
        }
        for _ in 0..self.params.smoothing_sweeps {
            for k in (0..a.len()).rev() {
                a.relax(k, b, x);
            }
        }
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Eq. 3.3 on a masked image grid, as [`crate::integrate`] assembles it.
pub(crate) struct GridSystem<'a> {
    /// Image width and height, px.
    pub(crate) width: u32,
    pub(crate) height: u32,
    /// The row-major pixel of each unknown, ascending.
    pub(crate) pixels: &'a [usize],
    /// Normal constraints `(k_i, u, k_j, v)`: `u z_i + v z_j ≈ 0` between right or lower
    /// 4-neighbours.
    pub(crate) rows: &'a [(usize, f64, usize, f64)],
    /// Proxy depths `(k, z̄_k)`, weighted by `alpha`.
    pub(crate) anchors: &'a [(usize, f64)],
    pub(crate) alpha: f64,
}

/// Solves the normal equations of `system` by multigrid-preconditioned CG from the warm
/// start `z0` (positive and finite at every unknown).
///
/// # Errors
/// [`Error::InvalidParam`] for bad params or a singular system; [`Error::SizeMismatch`] for a
/// warm start of another length.
pub(crate) fn solve(
    system: &GridSystem<'_>,
    z0: &[f64],
    params: &MultigridParams,
) -> Result<(Vec<f64>, MultigridStats)> {
    params.validate()?;
    check::same_size("multigrid warm start", system.pixels.len(), z0.len())?;
    let (fine, b) = scaled_level(system, z0)?;
    let mg = Hierarchy::new(fine, system.height as usize, *params)?;
    let t0 = vec![1.0; z0.len()];
    let (t, iterations, relative_residual) =
        pcg(&mg, &b, t0, z0, params.tolerance, params.max_iterations);
    let stats = MultigridStats {
        iterations,
        relative_residual,
        levels: mg.levels.len(),
    };
    Ok((t.iter().zip(z0).map(|(t, z)| t * z).collect(), stats))
}

/// The fine level of `system` in the variables `t = z / scale` (`N' = D N D`, `D =
/// diag(scale)`) and its right-hand side `D α Cᵀ z̄`.
fn scaled_level(system: &GridSystem<'_>, scale: &[f64]) -> Result<(Level, Vec<f64>)> {
    let n = system.pixels.len();
    let mut diag = vec![0.0; n];
    let mut nbr: Vec<[u32; 4]> = (0..n as u32).map(|k| [k; 4]).collect();
    let mut coef = vec![[0.0; 4]; n];
    for &(i, u, j, v) in system.rows {
        let (su, sv) = (u * scale[i], v * scale[j]);
        diag[i] += su * su;
        diag[j] += sv * sv;
        let (fwd, back) = if system.pixels[j] == system.pixels[i] + 1 {
            (RIGHT, LEFT)
        } else {
            (DOWN, UP)
        };
        nbr[i][fwd] = j as u32;
        coef[i][fwd] += su * sv;
        nbr[j][back] = i as u32;
        coef[j][back] += su * sv;
    }
    let mut b = vec![0.0; n];
    for &(k, d) in system.anchors {
        diag[k] += system.alpha * scale[k] * scale[k];
        b[k] += system.alpha * scale[k] * d;
    }
    if diag.iter().any(|d| *d <= 0.0 || !d.is_finite()) {
        return Err(Error::InvalidParam {
            name: "integration system",
            reason: "an unknown has no constraint (zero diagonal of the normal matrix)".into(),
        });
    }
    let fine = Level::new(
        system.width as usize,
        system.pixels.to_vec(),
        diag,
        nbr,
        coef,
    );
    Ok((fine, b))
}

/// Preconditioned CG on the finest level of `mg` from `t`. Residuals are measured unscaled
/// (`r / scale`: the residual of the normal equations of the depths), relative to the
/// start's. Returns (t, iterations, relative residual).
fn pcg(
    mg: &Hierarchy,
    b: &[f64],
    mut t: Vec<f64>,
    scale: &[f64],
    tolerance: f64,
    max_iterations: usize,
) -> (Vec<f64>, usize, f64) {
    let n = b.len();
    let a = &mg.levels[0];
    let unscaled = |r: &[f64]| {
        r.iter()
            .zip(scale)
            .map(|(r, s)| (r / s).powi(2))
            .sum::<f64>()
            .sqrt()
    };
    let mut r = vec![0.0; n];
    a.apply(&t, &mut r);
    for (ri, bi) in r.iter_mut().zip(b) {
        *ri = bi - *ri;
    }
    let r0 = unscaled(&r);
    let mut iterations = 0;
    if r0 == 0.0 {
        return (t, iterations, 0.0);
    }
    let mut rel = 1.0;
    let mut zr = vec![0.0; n];
    mg.cycle(0, &r, &mut zr);
    let mut p = zr.clone();
    let mut rz = dot(&r, &zr);
    let mut ap = vec![0.0; n];
    while iterations < max_iterations {
        a.apply(&p, &mut ap);
        let pap = dot(&p, &ap);
        if pap <= 0.0 || !pap.is_finite() {
            break;
        }
        let step = rz / pap;
        for k in 0..n {
            t[k] += step * p[k];
            r[k] -= step * ap[k];
        }
        iterations += 1;
        rel = unscaled(&r) / r0;
        if rel <= tolerance {
            break;
        }
        mg.cycle(0, &r, &mut zr);
        let rz_next = dot(&r, &zr);
        let beta = rz_next / rz;
        rz = rz_next;
        for k in 0..n {
            p[k] = zr[k] + beta * p[k];
        }
    }
    (t, iterations, rel)
}
