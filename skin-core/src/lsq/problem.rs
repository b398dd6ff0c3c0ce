//! The weighted sparse least-squares problem `min_X ‖A X − B‖² + Σ_k w_k ‖C_k X − D_k‖²`,
//! solved through its normal equations `(AᵀA + Σ w_k C_kᵀC_k) X = AᵀB + Σ w_k C_kᵀ D_k`.

use std::time::Instant;

use nalgebra::DMatrix;
use nalgebra_sparse::CscMatrix;
use serde::{Deserialize, Serialize};

use super::cholesky::{CholeskyParams, CholeskyStats, SparseCholesky};
use super::normal::NormalPattern;
use crate::check::all_finite;
use crate::{Error, Result};

/// Builder of a least-squares problem: a data term `A` (weight 1) plus weighted terms `C_k`.
///
/// All matrices must have the same number of columns `n` (the unknowns per right-hand side).
///
/// # Example
/// Vlasic 2010 Eq. 2.1 (smooth interpolation of constrained vertices, `w_C = 1000`):
/// ```
/// # use nalgebra::DMatrix;
/// # use nalgebra_sparse::{CooMatrix, CscMatrix};
/// use skin_core::lsq::{LsqParams, LsqProblem};
/// // A: second differences on a path of 5 vertices; C: pin vertices 0 and 4.
/// let mut a = CooMatrix::new(3, 5);
/// for r in 0..3 { a.push(r, r, 1.0); a.push(r, r + 1, -2.0); a.push(r, r + 2, 1.0); }
/// let mut c = CooMatrix::new(2, 5);
/// c.push(0, 0, 1.0);
/// c.push(1, 4, 1.0);
/// let solver = LsqProblem::new(CscMatrix::from(&a))
///     .with_term(CscMatrix::from(&c), 1000.0)
///     .factor(&LsqParams::default())?;
/// let b = DMatrix::zeros(3, 1);
/// let d = DMatrix::from_column_slice(2, 1, &[0.0, 4.0]);
/// let x = solver.solve(&b, &[d])?;
/// assert!((x[2] - 2.0).abs() < 1e-9); // a straight line through the pins
/// # Ok::<(), skin_core::Error>(())
/// ```
#[derive(Debug, Clone)]
pub struct LsqProblem {
    a: CscMatrix<f64>,
    terms: Vec<(CscMatrix<f64>, f64)>,
}

/// Knobs of the least-squares solver.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
pub struct LsqParams {
    /// Sparse Cholesky settings. Default: [`CholeskyParams::default`] (AMD, automatic
    /// supernodal/simplicial choice, sequential).
    pub cholesky: CholeskyParams,
}

/// Sizes and timings of the last (re)factorisation.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
pub struct LsqStats {
    /// Unknowns per right-hand side.
    pub n: usize,
    /// Wall time to analyse the normal-matrix pattern and build the scatter map, ms.
    pub pattern_ms: f64,
    /// Wall time of the last numeric assembly of the normal matrix, ms.
    pub assemble_ms: f64,
    /// Cholesky sizes and timings.
    pub cholesky: CholeskyStats,
}

/// Quality of a solution, from [`LsqSolver::diagnostics`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LsqDiagnostics {
    /// `‖A X − B‖² + Σ w_k ‖C_k X − D_k‖²` (Frobenius norms over all right-hand sides).
    pub objective: f64,
    /// `‖N X − R‖_F / ‖R‖_F` with `N` the normal matrix and `R` the normal right-hand side
    /// (0 when `R = 0`); ≈ 1e-15 for a well-conditioned exact solve.
    pub normal_rel_residual: f64,
}

impl LsqProblem {
    /// Starts a problem with the data term `A` (m₀ × n, weight 1).
    pub fn new(a: CscMatrix<f64>) -> Self {
        Self {
            a,
            terms: Vec::new(),
        }
    }

    /// Adds a term `w ‖C X − D‖²` (`C` is m_k × n, `w ≥ 0`).
    pub fn with_term(mut self, c: CscMatrix<f64>, weight: f64) -> Self {
        self.terms.push((c, weight));
        self
    }

    /// Validates the problem, analyses the sparsity pattern of the normal matrix once and
    /// factorises it.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] if a term's column count differs from `A`'s,
    /// [`Error::Empty`] if there are no unknowns, [`Error::NonFinite`] for NaN/inf values or
    /// weights, [`Error::InvalidParam`] for a negative weight, [`Error::Singular`] if the
    /// normal matrix is not positive definite (the system is rank deficient, e.g. a
    /// Laplacian without enough constraints).
    pub fn factor(self, params: &LsqParams) -> Result<LsqSolver> {
        let n = self.a.ncols();
        if n == 0 {
            return Err(Error::Empty {
                what: "least-squares unknowns (A has no columns)",
            });
        }
        for (c, _) in &self.terms {
            if c.ncols() != n {
                return Err(Error::SizeMismatch {
                    what: "columns of a constraint matrix C_k vs columns of A",
                    expected: n,
                    got: c.ncols(),
                });
            }
        }
        let weights: Vec<f64> = std::iter::once(1.0)
            .chain(self.terms.iter().map(|t| t.1))
            .collect();
        check_weights(&weights)?;
        let mut matrices = Vec::with_capacity(self.terms.len() + 1);
        matrices.push(self.a);
        matrices.extend(self.terms.into_iter().map(|t| t.0));
        for m in &matrices {
            all_finite("least-squares matrix values", m.values())?;
        }
        let start = Instant::now();
        let refs: Vec<&CscMatrix<f64>> = matrices.iter().collect();
        let pattern = NormalPattern::new(n, &refs)?;
        let pattern_ms = start.elapsed().as_secs_f64() * 1e3;
        let chol = SparseCholesky::analyse(
            n,
            pattern.col_ptr.clone(),
            pattern.row_idx.clone(),
            &params.cholesky,
        )?;
        let mut solver = LsqSolver {
            values: vec![0.0; pattern.nnz()],
            matrices,
            weights,
            pattern,
            chol,
            stats: LsqStats {
                n,
                pattern_ms,
                ..Default::default()
            },
        };
        solver.refactor()?;
        Ok(solver)
    }
}

fn check_weights(weights: &[f64]) -> Result<()> {
    all_finite("least-squares weights", weights)?;
    if let Some(w) = weights.iter().find(|w| **w < 0.0) {
        return Err(Error::InvalidParam {
            name: "weight",
            reason: format!("must be >= 0, got {w}"),
        });
    }
    Ok(())
}

/// A factorised least-squares problem: holds the matrices, the normal-matrix pattern with its
/// scatter map, and the Cholesky factor whose symbolic analysis is reused by
/// [`LsqSolver::set_weights`] and [`LsqSolver::set_values`].
#[derive(Debug)]
pub struct LsqSolver {
    /// `[A, C_1, …, C_k]`.
    matrices: Vec<CscMatrix<f64>>,
    /// `[1, w_1, …, w_k]`.
    weights: Vec<f64>,
    pattern: NormalPattern,
    /// Lower-triangle values of the normal matrix.
    values: Vec<f64>,
    chol: SparseCholesky,
    stats: LsqStats,
}

impl LsqSolver {
    /// Number of unknowns per right-hand side.
    pub fn n(&self) -> usize {
        self.pattern.n
    }

    /// Number of weighted terms `C_k` (not counting `A`).
    pub fn term_count(&self) -> usize {
        self.matrices.len() - 1
    }

    /// The current weights `w_k` of the terms `C_k`.
    pub fn weights(&self) -> &[f64] {
        &self.weights[1..]
    }

    /// Sizes and timings of the analysis and the last refactorisation.
    pub fn stats(&self) -> LsqStats {
        LsqStats {
            cholesky: self.chol.stats(),
            ..self.stats
        }
    }

    /// The lower triangle of the normal matrix `AᵀA + Σ w_k C_kᵀ C_k` as a CSC matrix (for
    /// inspection and tests; the solver never materialises the upper triangle).
    #[allow(
        clippy::expect_used,
        reason = "the pattern was validated as CSC when it was built"
    )]
    pub fn normal_matrix_lower(&self) -> CscMatrix<f64> {
        let n = self.n();
        // The pattern arrays are valid sorted CSC (built by NormalPattern), so this cannot
        // fail.
        CscMatrix::try_from_csc_data(
            n,
            n,
            self.pattern.col_ptr.clone(),
            self.pattern.row_idx.clone(),
            self.values.clone(),
        )
        .expect("normal pattern is valid CSC")
    }

    /// Changes the weights `w_k` and refactorises numerically (the symbolic analysis is kept).
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] if `weights.len()` is not the number of terms, plus the errors
    /// of [`LsqProblem::factor`].
    pub fn set_weights(&mut self, weights: &[f64]) -> Result<()> {
        if weights.len() != self.term_count() {
            return Err(Error::SizeMismatch {
                what: "number of weights vs number of terms",
                expected: self.term_count(),
                got: weights.len(),
            });
        }
        check_weights(weights)?;
        self.weights[1..].copy_from_slice(weights);
        self.refactor()
    }

    /// Replaces the values of `A` and of the terms `C_k` by matrices with the *same sparsity
    /// patterns* and refactorises numerically (symbolic analysis and scatter map are kept).
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] if the number of matrices or any pattern differs (build a new
    /// problem then), [`Error::NonFinite`], [`Error::Singular`].
    pub fn set_values(&mut self, a: &CscMatrix<f64>, terms: &[&CscMatrix<f64>]) -> Result<()> {
        if terms.len() != self.term_count() {
            return Err(Error::SizeMismatch {
                what: "number of constraint matrices vs number of terms",
                expected: self.term_count(),
                got: terms.len(),
            });
        }
        let new = std::iter::once(a).chain(terms.iter().copied());
        for (old, m) in self.matrices.iter().zip(new.clone()) {
            if old.nrows() != m.nrows()
                || old.ncols() != m.ncols()
                || old.col_offsets() != m.col_offsets()
                || old.row_indices() != m.row_indices()
            {
                return Err(Error::SizeMismatch {
                    what: "sparsity pattern of a replaced matrix (must equal the analysed one)",
                    expected: old.nnz(),
                    got: m.nnz(),
                });
            }
            all_finite("least-squares matrix values", m.values())?;
        }
        for (old, m) in self.matrices.iter_mut().zip(new) {
            old.values_mut().copy_from_slice(m.values());
        }
        self.refactor()
    }

    /// Numeric assembly and factorisation with the current matrices and weights.
    fn refactor(&mut self) -> Result<()> {
        let start = Instant::now();
        let refs: Vec<&CscMatrix<f64>> = self.matrices.iter().collect();
        self.pattern
            .assemble(&refs, &self.weights, &mut self.values);
        self.stats.assemble_ms = start.elapsed().as_secs_f64() * 1e3;
        self.chol.factor_values(&self.values)
    }

    fn check_rhs(&self, b: &DMatrix<f64>, d: &[DMatrix<f64>]) -> Result<()> {
        if d.len() != self.term_count() {
            return Err(Error::SizeMismatch {
                what: "number of right-hand sides D_k vs number of terms",
                expected: self.term_count(),
                got: d.len(),
            });
        }
        for (m, r) in self.matrices.iter().zip(std::iter::once(b).chain(d)) {
            if r.nrows() != m.nrows() {
                return Err(Error::SizeMismatch {
                    what: "rows of a right-hand side vs rows of its matrix",
                    expected: m.nrows(),
                    got: r.nrows(),
                });
            }
            if r.ncols() != b.ncols() {
                return Err(Error::SizeMismatch {
                    what: "columns of D_k vs columns of B (number of right-hand sides)",
                    expected: b.ncols(),
                    got: r.ncols(),
                });
            }
            all_finite("least-squares right-hand side", r.iter())?;
        }
        Ok(())
    }

    /// The right side of the normal equations, `AᵀB + Σ w_k C_kᵀ D_k` (n × columns of `B`).
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] unless `B` has the rows of `A`, each `D_k` the rows of `C_k`,
    /// and all have the same column count; [`Error::NonFinite`].
    pub fn normal_rhs(&self, b: &DMatrix<f64>, d: &[DMatrix<f64>]) -> Result<DMatrix<f64>> {
        self.check_rhs(b, d)?;
        let mut r = DMatrix::zeros(self.n(), b.ncols());
        for ((m, w), rhs) in self
            .matrices
            .iter()
            .zip(&self.weights)
            .zip(std::iter::once(b).chain(d))
        {
            add_transpose_product(&mut r, *w, m, rhs);
        }
        Ok(r)
    }

    /// Solves the least-squares problem for the right-hand sides `B` (rows of `A`) and `D_k`
    /// (rows of `C_k`), all with the same number of columns; returns `X` (n × columns).
    ///
    /// # Errors
    /// As [`LsqSolver::normal_rhs`], and [`Error::Singular`] if the last refactorisation
    /// failed.
    pub fn solve(&self, b: &DMatrix<f64>, d: &[DMatrix<f64>]) -> Result<DMatrix<f64>> {
        let mut x = self.normal_rhs(b, d)?;
        self.chol.solve_in_place(&mut x)?;
        Ok(x)
    }

    /// Solves the normal equations `N X = R` for a right side already in normal form.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] if `rhs` has not `n` rows, [`Error::NonFinite`],
    /// [`Error::Singular`] if the last refactorisation failed.
    pub fn solve_normal(&self, rhs: &DMatrix<f64>) -> Result<DMatrix<f64>> {
        self.chol.solve(rhs)
    }

    /// Objective value and normal-equation residual of a solution `X`.
    ///
    /// # Errors
    /// As [`LsqSolver::normal_rhs`], plus [`Error::SizeMismatch`] if `X` is not n × columns.
    pub fn diagnostics(
        &self,
        x: &DMatrix<f64>,
        b: &DMatrix<f64>,
        d: &[DMatrix<f64>],
    ) -> Result<LsqDiagnostics> {
        let r = self.normal_rhs(b, d)?;
        if x.nrows() != self.n() || x.ncols() != b.ncols() {
            return Err(Error::SizeMismatch {
                what: "solution rows x columns vs unknowns x right-hand sides",
                expected: self.n() * b.ncols(),
                got: x.nrows() * x.ncols(),
            });
        }
        let mut objective = 0.0;
        for ((m, w), rhs) in self
            .matrices
            .iter()
            .zip(&self.weights)
            .zip(std::iter::once(b).chain(d))
        {
            objective += w * (m * x - rhs).norm_squared();
        }
        // N X from the lower triangle: N = L + Lᵀ − diag.
        let mut nx = DMatrix::zeros(self.n(), x.ncols());
        let (cp, ri, v) = (&self.pattern.col_ptr, &self.pattern.row_idx, &self.values);
        for c in 0..x.ncols() {
            for j in 0..self.n() {
                for p in cp[j]..cp[j + 1] {
                    let i = ri[p];
                    nx[(i, c)] += v[p] * x[(j, c)];
                    if i != j {
                        nx[(j, c)] += v[p] * x[(i, c)];
                    }
                }
            }
        }
        let rn = r.norm();
        let normal_rel_residual = if rn > 0.0 {
            (nx - &r).norm() / rn
        } else {
            (nx - &r).norm()
        };
        Ok(LsqDiagnostics {
            objective,
            normal_rel_residual,
        })
    }
}

/// `r += w · Mᵀ B` for a CSC matrix `M` (column dot products, no transpose materialised).
fn add_transpose_product(r: &mut DMatrix<f64>, w: f64, m: &CscMatrix<f64>, b: &DMatrix<f64>) {
    if w == 0.0 {
        return;
    }
    for c in 0..b.ncols() {
        let bc = b.column(c);
        for (j, col) in m.col_iter().enumerate() {
            let s: f64 = col
                .row_indices()
                .iter()
                .zip(col.values())
                .map(|(&i, &v)| v * bc[i])
                .sum();
            r[(j, c)] += w * s;
        }
    }
}

#[cfg(test)]
mod tests;
