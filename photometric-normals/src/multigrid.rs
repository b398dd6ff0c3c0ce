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
//! **The hierarchy: smoothed aggregation.** Each coarse unknown aggregates the foreground
//! pixels of a 3 × 3 block of the finer grid that are joined by strong couplings
//! (`|a_ij| ≥ ε √(a_ii a_jj)`, [`MultigridParams::strength_threshold`]; a coupling never
//! crosses a connected region — a view splits into several at silhouettes and removed
//! discontinuities, each with its own scale mode, lifted only by α, which a coarse unknown
//! shared by two regions could not represent). The piecewise-constant prolongator `P₀` of the
//! aggregates is smoothed by one damped Jacobi step, `P = (I − ω/ρ D⁻¹ N') P₀`
//! ([`MultigridParams::prolongation_smoothing`] `ω`, `ρ` Gershgorin's bound on the spectral
//! radius of `D⁻¹ N'`; Vaněk, Mandel & Brezina 1996), so the coarse space holds smooth
//! ramps instead of staircases, and the coarse operator is Galerkin's `Pᵀ N' P` (sparse
//! rows; every level's operator is a 9-point stencil on the third-size grid, since a smoothed
//! 3 × 3 aggregate's support, 5 × 5 cells, meets only its 8 neighbours'). Each level costs
//! about a ninth of the finer one: O(n) memory and work per cycle. Galerkin operators respect
//! the mask exactly (no rediscretisation of boundaries or of the varying weights
//! `((n_i + n_j)ᵀ r)²`, which vanish at grazing angles). The coarsest level
//! (≤ [`COARSEST_UNKNOWNS`] unknowns, at the latest a 1 × 1 grid) is solved by dense
//! Cholesky. (Plain 2 × 2 aggregation needs 83–98 CG iterations on the studio's 1024² views
//! against 22–31 with this hierarchy; 2 × 2 blocks with a smoothed prolongator widen the
//! stencil level by level.)
//!
//! **The cycle and the Krylov method.** One V-cycle with symmetric Gauss–Seidel smoothing
//! (forward before the coarse correction, backward after) is a symmetric positive definite
//! preconditioner, so conjugate gradients apply (Tatebe 1993, "The multigrid preconditioned
//! conjugate gradient method"). The coarse correction is scaled by
//! [`MultigridParams::coarse_scale`] (1 for smoothed aggregation; plain aggregation needed an
//! over-correction of 1.8, Braess 1995); below 2 a two-grid preconditioner stays SPD (the CG
//! loop stops should a search direction lose positive curvature).
//!
//! **Where it stops paying.** On the studio's views at 1024² (75 k–87 k foreground pixels,
//! ragged masks) CG needs 22–31 cycles (14–19 with a W(2,2)-cycle) and costs about as much CPU
//! time as the direct solve (ratio 1.06, `benches/integrate_studio.rs`): at that size the
//! sparse Cholesky of a 2-D 5-point system is cheap, and
//! [`crate::IntegrationSolver::Direct`] stays the default. The multigrid wins on large
//! compact foregrounds (the 1024² sphere view of `benches/integrate.rs`).
//!
//! **Stopping.** CG ([`skin_core::lsq::pcg`], its sums serial) stops when the residual of
//! the normal equations (in depth units, i.e. the scaled residual divided by `z₀`) falls to
//! [`MultigridParams::tolerance`] times the warm start's residual (the proxy's disagreement
//! with the normals), or after [`MultigridParams::max_iterations`].

use nalgebra::{DMatrix, DVector};
use nalgebra_sparse::{CooMatrix, CsrMatrix};
use serde::{Deserialize, Serialize};
use skin_core::check;
use skin_core::lsq::{pcg, PcgParams, Preconditioner, Reduction, Reference, ResidualNorm};

use crate::{Error, Result};

/// Levels stop coarsening at this many unknowns; the coarsest is solved by dense Cholesky.
pub(crate) const COARSEST_UNKNOWNS: usize = 256;

/// Knobs of the multigrid-preconditioned conjugate gradients solve of Eq. 3.3.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MultigridParams {
    /// CG stops when the residual norm of the normal equations falls to this fraction of the
    /// warm start's. Default 10⁻⁷ (ours: on the 512² and 1024² sphere views of the
    /// benchmark the depths stay within a nanometre of the direct solve's, on the studio's
    /// 1024² views within 1.6 µm; see `docs/photometric-normals.md`).
    pub tolerance: f64,
    /// Most CG iterations (one V-cycle each). Default 200 (ours; the studio's 1024² views
    /// need 22–31).
    pub max_iterations: usize,
    /// Gauss–Seidel sweeps before and after each coarse correction. Default 1 (ours: on the
    /// studio's 1024² views 0 and 5, 2 sweeps take 22–27 iterations instead of 29–31, for
    /// more CPU time).
    pub smoothing_sweeps: usize,
    /// Scale of the coarse-grid correction (in `(0, 1.99]`, below 2 the preconditioner stays
    /// positive definite). Default 1.0 (ours: with the smoothed prolongator, on the studio's
    /// 1024² views 0 and 3, 1.0 needs 22–29 iterations, 1.4 21–28, and 1.8 was the worst
    /// with smoothed 2 × 2 aggregates, 31–34 against 14–20 at 1.0; plain aggregation needed
    /// the over-correction 1.8).
    pub coarse_scale: f64,
    /// Coarse-grid visits per level: 1 is a V-cycle, 2 a W-cycle (still O(n) with 3 × 3
    /// aggregation: each level costs a ninth of the finer one, visited twice as often).
    /// Default 1 (ours: on the studio's 1024² views 0 and 5 a W(1,1)-cycle takes 18–23
    /// iterations and a W(2,2)-cycle 14–19, instead of 29–31, for about the same CPU time).
    pub cycle_index: usize,
    /// Strength of connection `ε`: two unknowns of one 3 × 3 block share an aggregate only
    /// if their coupling `|a_ij| ≥ ε √(a_ii a_jj)` (weak links — grazing silhouettes, where
    /// `((n_i + n_j)ᵀ r)²` vanishes — are not aggregated across). In `[0, 1)`; 0 aggregates
    /// every coupled pair of a block. Default 0 (ours: on the studio's 1024² views 0.1 needs
    /// 30–31 iterations against 29, 0.25 33; a level that would not halve is aggregated
    /// with 0).
    pub strength_threshold: f64,
    /// Damping `ω` of the prolongator smoothing `P = (I − ω/ρ D⁻¹ A) P₀` of smoothed
    /// aggregation (Vaněk, Mandel & Brezina 1996; `ρ` Gershgorin's bound on the spectral
    /// radius of `D⁻¹ A`), in `[0, 2)`; 0 keeps the piecewise-constant `P₀` (plain
    /// aggregation). Default 4/3 (the usual choice, `ω = 4/(3ρ)`; on the studio's 1024² views
    /// 1.0 needs 33–34 iterations, 4/3 29, 1.6 27).
    pub prolongation_smoothing: f64,
    /// Side of the square blocks of cells aggregated into one coarse cell, 2 or 3. Default 3
    /// (ours: 3 keeps every level's operator a 9-point stencil under prolongator smoothing —
    /// a smoothed aggregate's support, 5 × 5 cells, meets only its 8 neighbours' — where
    /// smoothed 2 × 2 blocks widen the stencil level by level, 31 entries a row on the second
    /// level, over 100 on the fourth; 2 with `prolongation_smoothing` 0 and `coarse_scale`
    /// 1.8 is plain 2 × 2 aggregation, the faster choice on large compact foregrounds).
    pub aggregate_side: usize,
}

impl Default for MultigridParams {
    fn default() -> Self {
        Self {
            tolerance: 1e-7,
            max_iterations: 200,
            smoothing_sweeps: 1,
            coarse_scale: 1.0,
            cycle_index: 1,
            strength_threshold: 0.0,
            prolongation_smoothing: 4.0 / 3.0,
            aggregate_side: 3,
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
        check::in_range(
            "multigrid strength_threshold",
            self.strength_threshold,
            0.0..=0.99,
        )?;
        check::in_range(
            "multigrid aggregate_side",
            self.aggregate_side as f64,
            2.0..=3.0,
        )?;
        check::in_range(
            "multigrid prolongation_smoothing",
            self.prolongation_smoothing,
            0.0..=1.99,
        )?;
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

/// A symmetric sparse operator on the unknowns of a masked grid (compressed rows of the
/// off-diagonal couplings, the diagonal apart).
struct Level {
    width: usize,
    /// Grid cell (row-major) of each unknown.
    cell: Vec<usize>,
    diag: Vec<f64>,
    /// `1 / diag`, for the smoother.
    inv_diag: Vec<f64>,
    /// Row `k`'s couplings are `col[ptr[k]..ptr[k + 1]]`, `val[…]`.
    ptr: Vec<usize>,
    col: Vec<u32>,
    val: Vec<f64>,
}

/// A prolongator from a coarse level to a fine one, in compressed rows (one row a fine
/// unknown).
struct Prolongator {
    ptr: Vec<usize>,
    col: Vec<u32>,
    val: Vec<f64>,
}

impl Level {
    /// The level of the square matrix `m` (diagonal and off-diagonal entries, any order,
    /// duplicates summed) on the cells `cell` of a grid `width` wide.
    fn from_csr(width: usize, cell: Vec<usize>, m: &CsrMatrix<f64>) -> Self {
        let n = m.nrows();
        let mut diag = vec![0.0; n];
        let (mut ptr, mut col, mut val) = (Vec::with_capacity(n + 1), Vec::new(), Vec::new());
        ptr.push(0);
        for (k, row) in m.row_iter().enumerate() {
            for (&j, &v) in row.col_indices().iter().zip(row.values()) {
                if j == k {
                    diag[k] += v;
                } else if v != 0.0 {
                    col.push(j as u32);
                    val.push(v);
                }
            }
            ptr.push(col.len());
        }
        let inv_diag = diag.iter().map(|d| 1.0 / d).collect();
        Self {
            width,
            cell,
            diag,
            inv_diag,
            ptr,
            col,
            val,
        }
    }

    fn len(&self) -> usize {
        self.diag.len()
    }

    /// Row `k`'s couplings: (neighbour, coefficient).
    fn row(&self, k: usize) -> impl Iterator<Item = (usize, f64)> + '_ {
        let r = self.ptr[k]..self.ptr[k + 1];
        self.col[r.clone()]
            .iter()
            .zip(&self.val[r])
            .map(|(&j, &v)| (j as usize, v))
    }

    fn apply(&self, x: &[f64], y: &mut [f64]) {
        for (k, yk) in y.iter_mut().enumerate() {
            *yk = self.diag[k] * x[k] + self.row(k).map(|(j, v)| v * x[j]).sum::<f64>();
        }
    }

    #[inline(always)]
    fn relax(&self, k: usize, b: &[f64], x: &mut [f64]) {
        let off: f64 = self.row(k).map(|(j, v)| v * x[j]).sum();
        x[k] = (b[k] - off) * self.inv_diag[k];
    }

    fn csr(&self) -> CsrMatrix<f64> {
        let n = self.len();
        let mut coo = CooMatrix::new(n, n);
        for k in 0..n {
            coo.push(k, k, self.diag[k]);
            for (j, v) in self.row(k) {
                coo.push(k, j, v);
            }
        }
        CsrMatrix::from(&coo)
    }

    /// Each unknown's aggregate on the coarser grid (blocks of `side` × `side` cells): the unknowns of one block joined
    /// by strong couplings (`|a_kj| ≥ ε √(a_kk a_jj)`, `ε = strength`; a coupling is between
    /// unknowns of one connected region, so every region keeps unknowns of its own down to
    /// the coarsest level). Returns (aggregate of each unknown, cell of each aggregate).
    fn aggregate(&self, side: usize, strength: f64) -> (Vec<u32>, Vec<usize>) {
        let cw = self.width.div_ceil(side);
        let block = |cell: usize| (cell / self.width / side) * cw + (cell % self.width) / side;
        let n = self.len();
        let mut parent: Vec<u32> = (0..n as u32).collect();
        for k in 0..n {
            let bk = block(self.cell[k]);
            for (j, v) in self.row(k) {
                if block(self.cell[j]) == bk
                    && v.abs() >= strength * (self.diag[k] * self.diag[j]).sqrt()
                {
                    let (a, b) = (root(&mut parent, k as u32), root(&mut parent, j as u32));
                    if a != b {
                        parent[a.max(b) as usize] = a.min(b);
                    }
                }
            }
        }
        let mut id = vec![u32::MAX; n];
        let mut cells = Vec::new();
        let agg = (0..n)
            .map(|k| {
                let r = root(&mut parent, k as u32) as usize;
                if id[r] == u32::MAX {
                    id[r] = cells.len() as u32;
                    cells.push(block(self.cell[k]));
                }
                id[r]
            })
            .collect();
        (agg, cells)
    }

    /// The prolongator of the aggregates `agg` (`nc` of them): piecewise constant, then
    /// (for `omega > 0`) smoothed by one damped Jacobi step `(I − ω/ρ D⁻¹ A) P₀` with `ρ`
    /// Gershgorin's bound on the spectral radius of `D⁻¹ A` (Vaněk, Mandel & Brezina 1996).
    fn prolongator(&self, agg: &[u32], nc: usize, omega: f64) -> Prolongator {
        let n = self.len();
        if omega == 0.0 {
            return Prolongator {
                ptr: (0..=n).collect(),
                col: agg.to_vec(),
                val: vec![1.0; n],
            };
        }
        let rho = (0..n)
            .map(|k| 1.0 + self.row(k).map(|(_, v)| v.abs()).sum::<f64>() * self.inv_diag[k])
            .fold(0.0, f64::max);
        let w = omega / rho;
        let (mut ptr, mut col, mut val) = (vec![0], Vec::new(), Vec::new());
        let mut acc: Vec<f64> = vec![0.0; nc];
        let mut seen = vec![false; nc];
        let mut touched: Vec<u32> = Vec::new();
        for k in 0..n {
            let mut add = |c: u32, v: f64| {
                if !seen[c as usize] {
                    seen[c as usize] = true;
                    touched.push(c);
                }
                acc[c as usize] += v;
            };
            add(agg[k], 1.0 - w);
            for (j, v) in self.row(k) {
                add(agg[j], -w * v * self.inv_diag[k]);
            }
            touched.sort_unstable();
            for &c in &touched {
                col.push(c);
                val.push(acc[c as usize]);
                acc[c as usize] = 0.0;
                seen[c as usize] = false;
            }
            touched.clear();
            ptr.push(col.len());
        }
        Prolongator { ptr, col, val }
    }

    /// The Galerkin operator `Pᵀ A P` on the coarser grid.
    fn coarsen(&self, side: usize, p: &Prolongator, cells: Vec<usize>) -> Level {
        let (n, nc) = (self.len(), cells.len());
        let pm = CsrMatrix::try_from_csr_data(
            n,
            nc,
            p.ptr.clone(),
            p.col.iter().map(|&c| c as usize).collect(),
            p.val.clone(),
        );
        // The rows are built sorted and unique: the conversion cannot fail; fall back to
        // summing duplicates should it ever.
        let pm = pm.unwrap_or_else(|_| {
            let mut coo = CooMatrix::new(n, nc);
            for k in 0..n {
                for e in p.ptr[k]..p.ptr[k + 1] {
                    coo.push(k, p.col[e] as usize, p.val[e]);
                }
            }
            CsrMatrix::from(&coo)
        });
        let ap = &self.csr() * &pm;
        let coarse = &pm.transpose() * &ap;
        Level::from_csr(self.width.div_ceil(side), cells, &coarse)
    }

    fn dense(&self) -> DMatrix<f64> {
        let n = self.len();
        let mut m = DMatrix::zeros(n, n);
        for k in 0..n {
            m[(k, k)] += self.diag[k];
            for (j, v) in self.row(k) {
                m[(k, j)] += v;
            }
        }
        m
    }
}

/// Union–find root of `k`, halving the path.
fn root(parent: &mut [u32], mut k: u32) -> u32 {
    while parent[k as usize] != k {
        let p = parent[parent[k as usize] as usize];
        parent[k as usize] = p;
        k = p;
    }
    k
}

impl Prolongator {
    /// `bc = Pᵀ r`.
    fn restrict(&self, r: &[f64], bc: &mut [f64]) {
        bc.fill(0.0);
        for (k, rk) in r.iter().enumerate() {
            for e in self.ptr[k]..self.ptr[k + 1] {
                bc[self.col[e] as usize] += self.val[e] * rk;
            }
        }
    }

    /// `x += s P xc`.
    fn add(&self, s: f64, xc: &[f64], x: &mut [f64]) {
        for (k, xk) in x.iter_mut().enumerate() {
            let mut v = 0.0;
            for e in self.ptr[k]..self.ptr[k + 1] {
                v += self.val[e] * xc[self.col[e] as usize];
            }
            *xk += s * v;
        }
    }
}

/// The V-cycle preconditioner: levels finest first, each coarser one's prolongator.
struct Hierarchy {
    levels: Vec<Level>,
    /// `prolong[l]`: from level `l + 1` to level `l`.
    prolong: Vec<Prolongator>,
    coarsest: nalgebra::Cholesky<f64, nalgebra::Dyn>,
    params: MultigridParams,
}

impl Hierarchy {
    fn new(fine: Level, height: usize, params: MultigridParams) -> Result<Self> {
        let mut levels = vec![fine];
        let mut prolong = Vec::new();
        let mut h = height;
        while let Some(last) = levels.last() {
            if last.len() <= COARSEST_UNKNOWNS || (last.width <= 1 && h <= 1) {
                break;
            }
            let side = params.aggregate_side;
            let (mut agg, mut cells) = last.aggregate(side, params.strength_threshold);
            if cells.len() * 2 > last.len() {
                // Too many weak links to coarsen: aggregate this level's blocks whole.
                (agg, cells) = last.aggregate(side, 0.0);
            }
            let p = last.prolongator(&agg, cells.len(), params.prolongation_smoothing);
            let coarse = last.coarsen(side, &p, cells);
            h = h.div_ceil(side);
            prolong.push(p);
            levels.push(coarse);
        }
        let coarsest = levels
            .last()
            .map(Level::dense)
            .and_then(|m| m.cholesky())
            .ok_or(Error::InvalidParam {
                name: "integration system",
                reason: "the coarsest multigrid operator is not positive definite (a region \
                         without proxy depth, or alpha = 0); give every region a proxy depth \
                         and alpha > 0, or use IntegrationSolver::Direct"
                    .into(),
            })?;
        Ok(Self {
            levels,
            prolong,
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
        let p = &self.prolong[l];
        let mut r = vec![0.0; a.len()];
        let mut bc = vec![0.0; self.levels[l + 1].len()];
        let mut xc = vec![0.0; bc.len()];
        for _ in 0..self.params.cycle_index {
            a.apply(x, &mut r);
            for (rk, bk) in r.iter_mut().zip(b) {
                *rk = bk - *rk;
            }
            p.restrict(&r, &mut bc);
            self.cycle(l + 1, &bc, &mut xc);
            p.add(self.params.coarse_scale, &xc, x);
        }
        for _ in 0..self.params.smoothing_sweeps {
            for k in (0..a.len()).rev() {
                a.relax(k, b, x);
            }
        }
    }
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
    // CG on the finest level from t = 1, its residual measured unscaled (`r / z₀`: the
    // residual of the normal equations of the depths) relative to the start's, every sum
    // serial.
    let mut t = vec![1.0; z0.len()];
    let fine = &mg.levels[0];
    let mut cycle = |r: &[f64], z: &mut [f64]| mg.cycle(0, r, z);
    let cg = pcg(
        &|x: &[f64], y: &mut [f64]| fine.apply(x, y),
        Preconditioner::Apply(&mut cycle),
        &b,
        &mut t,
        ResidualNorm::DividedBy(z0),
        &PcgParams {
            tolerance: params.tolerance,
            max_iterations: params.max_iterations,
            reference: Reference::Start,
            reduction: Reduction::Serial,
        },
    )?;
    let stats = MultigridStats {
        iterations: cg.iterations,
        relative_residual: cg.relative_residual,
        levels: mg.levels.len(),
    };
    Ok((t.iter().zip(z0).map(|(t, z)| t * z).collect(), stats))
}

/// The fine level of `system` in the variables `t = z / scale` (`N' = D N D`, `D =
/// diag(scale)`) and its right-hand side `D α Cᵀ z̄`.
fn scaled_level(system: &GridSystem<'_>, scale: &[f64]) -> Result<(Level, Vec<f64>)> {
    let n = system.pixels.len();
    let mut coo = CooMatrix::new(n, n);
    for &(i, u, j, v) in system.rows {
        let (su, sv) = (u * scale[i], v * scale[j]);
        coo.push(i, i, su * su);
        coo.push(j, j, sv * sv);
        coo.push(i, j, su * sv);
        coo.push(j, i, su * sv);
    }
    let mut b = vec![0.0; n];
    for &(k, d) in system.anchors {
        coo.push(k, k, system.alpha * scale[k] * scale[k]);
        b[k] += system.alpha * scale[k] * d;
    }
    let fine = Level::from_csr(
        system.width as usize,
        system.pixels.to_vec(),
        &CsrMatrix::from(&coo),
    );
    if fine.diag.iter().any(|d| *d <= 0.0 || !d.is_finite()) {
        return Err(Error::InvalidParam {
            name: "integration system",
            reason:
                "an unknown has no constraint (zero diagonal of the normal matrix); give every \
                     foreground pixel a valid normal or a proxy depth"
                    .into(),
        });
    }
    Ok((fine, b))
}
