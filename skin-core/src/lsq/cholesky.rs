//! Sparse Cholesky factorisation `N = L Lᵀ` of a symmetric positive definite matrix with the
//! symbolic analysis (fill-reducing ordering, elimination tree, supernodes) computed once per
//! sparsity pattern and reused by every numeric refactorisation (faer 0.24 supernodal or
//! simplicial LLT, behind the private `faer_bridge`).

use std::time::Instant;

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::solvers::LltError;
use faer::perm::PermRef;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, LltRef, SymbolicCholesky,
    SymbolicCholeskyRaw, SymmetricOrdering,
};
use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, Par, Side};
use nalgebra::DMatrix;
use nalgebra_sparse::CscMatrix;
use serde::{Deserialize, Serialize};

use crate::check::all_finite;
use crate::faer_bridge::{csc_as_faer, dmatrix_as_faer_mut};
use crate::{Error, Result};

/// Index type of the factorisation: 32-bit indices halve the index memory traffic of the
/// symbolic analysis and the supernodal kernels (patterns up to 4·10⁹ non-zeros).
type Ix = u32;

/// Fill-reducing ordering applied before the factorisation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum FillOrdering {
    /// Approximate minimum degree (Amestoy, Davis & Duff 1996), as CHOLMOD's default.
    #[default]
    Amd,
    /// No reordering (only sensible for banded matrices or tests).
    Natural,
}

/// Which numeric kernel factorises the matrix.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum FactorKind {
    /// faer decides from the flop count per non-zero of the factor.
    #[default]
    Auto,
    /// Always supernodal (dense blocks; best for meshes and grids).
    Supernodal,
    /// Always simplicial (column by column; best for very sparse factors).
    Simplicial,
}

/// Knobs of the sparse Cholesky factorisation.
///
/// These are solver engineering choices, not paper constants: the thesis (Vlasic 2010 §2.4)
/// only requires a direct solve of the normal equations.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CholeskyParams {
    /// Fill-reducing ordering. Default: [`FillOrdering::Amd`].
    pub ordering: FillOrdering,
    /// Numeric kernel. Default: [`FactorKind::Auto`] (supernodal on mesh Laplacians).
    pub kind: FactorKind,
    /// Use the global rayon pool inside the numeric factorisation and the solves. Off by
    /// default: single-threaded results are bit-reproducible for any thread count (DESIGN.md
    /// "Parallelism"), callers parallelise over frames instead, and on the shared 2-core
    /// benchmark machine the sequential kernel was faster (level-5 icosphere peer problem:
    /// factor + solve 123 ms sequential vs 203 ms with rayon under load). Default: `false`.
    pub parallel: bool,
}

impl Default for CholeskyParams {
    fn default() -> Self {
        Self {
            ordering: FillOrdering::Amd,
            kind: FactorKind::Auto,
            parallel: false,
        }
    }
}

/// Sizes and timings of the last analysis and factorisation.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
pub struct CholeskyStats {
    /// Order `n` of the matrix.
    pub n: usize,
    /// Stored non-zeros of the lower triangle of the input matrix.
    pub matrix_nnz_lower: usize,
    /// Stored values of the Cholesky factor (supernodal blocks count in full).
    pub factor_values: usize,
    /// Whether the supernodal kernel was chosen.
    pub supernodal: bool,
    /// Wall time of the symbolic analysis (ordering, elimination tree, supernodes), ms.
    pub symbolic_ms: f64,
    /// Wall time of the last numeric factorisation, ms.
    pub numeric_ms: f64,
}

/// A sparse `L Lᵀ` factorisation whose symbolic part is reused across numeric
/// refactorisations of matrices that share one sparsity pattern.
///
/// Only the lower triangle (`row ≥ column`) of the matrices given is read.
///
/// # Example
/// ```
/// use nalgebra::DMatrix;
/// use nalgebra_sparse::{CooMatrix, CscMatrix};
/// use skin_core::lsq::{CholeskyParams, SparseCholesky};
/// let mut coo = CooMatrix::new(2, 2);
/// coo.push(0, 0, 4.0);
/// coo.push(1, 0, 1.0);
/// coo.push(1, 1, 3.0);
/// let n = CscMatrix::from(&coo);
/// let chol = SparseCholesky::new(&n, &CholeskyParams::default())?;
/// let x = chol.solve(&DMatrix::from_column_slice(2, 1, &[1.0, 2.0]))?;
/// assert!((4.0 * x[0] + x[1] - 1.0).abs() < 1e-12);
/// # Ok::<(), skin_core::Error>(())
/// ```
pub struct SparseCholesky {
    /// The symbolic analysis, shared by clones (it is read-only after the analysis).
    symbolic: std::sync::Arc<SymbolicCholesky<Ix>>,
    /// Column pointers of the lower-triangle pattern the analysis was made for.
    col_ptr: Vec<Ix>,
    /// Row indices of that pattern.
    row_idx: Vec<Ix>,
    /// Numeric values of the factor (valid when `factored`).
    factor: Vec<f64>,
    factored: bool,
    par: Par,
    /// Workspace of the numeric factorisation, allocated once.
    scratch: MemBuffer,
    stats: CholeskyStats,
}

impl std::fmt::Debug for SparseCholesky {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SparseCholesky")
            .field("stats", &self.stats)
            .field("factored", &self.factored)
            .finish()
    }
}

/// A clone shares the symbolic analysis and gets its own factor and workspace, so clones can
/// refactorise matrices of the same pattern on different threads.
impl Clone for SparseCholesky {
    fn clone(&self) -> Self {
        let req = self
            .symbolic
            .factorize_numeric_llt_scratch::<f64>(self.par, Default::default());
        Self {
            symbolic: self.symbolic.clone(),
            col_ptr: self.col_ptr.clone(),
            row_idx: self.row_idx.clone(),
            factor: self.factor.clone(),
            factored: self.factored,
            par: self.par,
            scratch: MemBuffer::new(req),
            stats: self.stats,
        }
    }
}

impl SparseCholesky {
    /// Analyses the pattern of the lower triangle of `matrix` and factorises its values.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] if `matrix` is not square, [`Error::Empty`] if it is 0×0,
    /// [`Error::NonFinite`] for NaN/inf values, [`Error::Singular`] if it is not (numerically)
    /// positive definite.
    pub fn new(matrix: &CscMatrix<f64>, params: &CholeskyParams) -> Result<Self> {
        let lower = lower_pattern(matrix)?;
        let mut chol = Self::analyse(matrix.nrows(), lower.0, lower.1, params)?;
        let values = lower_values(matrix, chol.row_idx.len());
        chol.factor_values(&values)?;
        Ok(chol)
    }

    /// Symbolic analysis of a lower-triangular pattern given as CSC arrays with sorted rows
    /// (every row ≥ its column). Does not factorise.
    pub(crate) fn analyse(
        n: usize,
        col_ptr: Vec<usize>,
        row_idx: Vec<usize>,
        params: &CholeskyParams,
    ) -> Result<Self> {
        if n == 0 {
            return Err(Error::Empty {
                what: "matrix to factorise",
            });
        }
        let start = Instant::now();
        if row_idx.len() > Ix::MAX as usize || n > Ix::MAX as usize {
            return Err(Error::InvalidParam {
                name: "matrix",
                reason: format!(
                    "order or stored non-zeros above {} are not supported",
                    Ix::MAX
                ),
            });
        }
        // Every pointer is ≤ nnz and every row < n, both ≤ Ix::MAX as checked above.
        let col_ptr: Vec<Ix> = col_ptr.iter().map(|&x| x as Ix).collect();
        let row_idx: Vec<Ix> = row_idx.iter().map(|&x| x as Ix).collect();
        // SAFETY: `col_ptr`/`row_idx` come from `lower_pattern` or the normal-equation
        // assembly, which both emit CSC arrays with n + 1 non-decreasing pointers and strictly
        // increasing in-range rows per column.
        let pattern =
            unsafe { SymbolicSparseColMatRef::new_unchecked(n, n, &col_ptr, None, &row_idx) };
        // faer 0.24's `SymmetricOrdering::Identity` skips the conversion of a lower-triangle
        // input to the upper triangle its analysis reads, so the natural order is passed as
        // an explicit identity permutation instead.
        let identity: Vec<Ix> = (0..n as Ix).collect();
        let ordering = match params.ordering {
            FillOrdering::Amd => SymmetricOrdering::Amd,
            FillOrdering::Natural => {
                SymmetricOrdering::Custom(PermRef::new_checked(&identity, &identity, n))
            }
        };
        let threshold = match params.kind {
            FactorKind::Auto => SupernodalThreshold::AUTO,
            FactorKind::Supernodal => SupernodalThreshold::FORCE_SUPERNODAL,
            FactorKind::Simplicial => SupernodalThreshold::FORCE_SIMPLICIAL,
        };
        let symbolic_params = CholeskySymbolicParams {
            supernodal_flop_ratio_threshold: threshold,
            ..Default::default()
        };
        let symbolic = factorize_symbolic_cholesky(pattern, Side::Lower, ordering, symbolic_params)
            .map_err(|e| Error::Singular {
                what: format!("symbolic Cholesky analysis failed: {e:?}"),
            })?;
        let par = if params.parallel {
            Par::rayon(0)
        } else {
            Par::Seq
        };
        let req = symbolic.factorize_numeric_llt_scratch::<f64>(par, Default::default());
        let scratch = MemBuffer::try_new(req).map_err(|_| Error::InvalidParam {
            name: "matrix",
            reason: "out of memory for the Cholesky workspace".into(),
        })?;
        let stats = CholeskyStats {
            n,
            matrix_nnz_lower: row_idx.len(),
            factor_values: symbolic.len_val(),
            supernodal: matches!(symbolic.raw(), SymbolicCholeskyRaw::Supernodal(_)),
            symbolic_ms: start.elapsed().as_secs_f64() * 1e3,
            numeric_ms: 0.0,
        };
        let factor = vec![0.0; symbolic.len_val()];
        Ok(Self {
            symbolic: std::sync::Arc::new(symbolic),
            col_ptr,
            row_idx,
            factor,
            factored: false,
            par,
            scratch,
            stats,
        })
    }

    /// Numeric refactorisation of a matrix with the pattern of the analysis (only the lower
    /// triangle is read). The symbolic analysis is reused.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] if the size or the lower-triangle pattern differs from the
    /// analysed one, [`Error::NonFinite`], [`Error::Singular`] as in [`SparseCholesky::new`].
    pub fn refactor(&mut self, matrix: &CscMatrix<f64>) -> Result<()> {
        if matrix.nrows() != self.n() || matrix.ncols() != self.n() {
            return Err(Error::SizeMismatch {
                what: "matrix order vs analysed pattern",
                expected: self.n(),
                got: matrix.nrows().max(matrix.ncols()),
            });
        }
        let (col_ptr, row_idx) = lower_pattern(matrix)?;
        let same = |a: &[usize], b: &[Ix]| {
            a.len() == b.len() && a.iter().zip(b).all(|(&x, &y)| x == y as usize)
        };
        if !same(&col_ptr, &self.col_ptr) || !same(&row_idx, &self.row_idx) {
            return Err(Error::SizeMismatch {
                what: "lower-triangle non-zeros vs analysed pattern (pattern changed: build a new SparseCholesky)",
                expected: self.row_idx.len(),
                got: row_idx.len(),
            });
        }
        let values = lower_values(matrix, self.row_idx.len());
        self.factor_values(&values)
    }

    /// Numeric factorisation from values aligned with the analysed lower pattern.
    pub(crate) fn factor_values(&mut self, values: &[f64]) -> Result<()> {
        debug_assert_eq!(values.len(), self.row_idx.len());
        self.factored = false;
        all_finite("matrix values", values)?;
        let start = Instant::now();
        let n = self.n();
        // SAFETY: same arrays as validated when the analysis was built.
        let pattern = unsafe {
            SymbolicSparseColMatRef::new_unchecked(n, n, &self.col_ptr, None, &self.row_idx)
        };
        let a = SparseColMatRef::new(pattern, values);
        let result = self.symbolic.factorize_numeric_llt::<f64>(
            &mut self.factor,
            a,
            Side::Lower,
            Default::default(),
            self.par,
            MemStack::new(&mut self.scratch),
            Default::default(),
        );
        self.stats.numeric_ms = start.elapsed().as_secs_f64() * 1e3;
        match result {
            Ok(_) => {
                self.factored = true;
                Ok(())
            }
            Err(LltError::NonPositivePivot { index }) => Err(Error::Singular {
                what: format!(
                    "matrix is not positive definite (non-positive pivot at permuted index {index}): the least-squares system is rank deficient; add constraints or regularisation"
                ),
            }),
        }
    }

    /// Order `n` of the factorised matrix.
    pub fn n(&self) -> usize {
        self.col_ptr.len() - 1
    }

    /// Sizes and timings of the analysis and the last factorisation.
    pub fn stats(&self) -> CholeskyStats {
        self.stats
    }

    /// Solves `N X = B` for all columns of `rhs` (n × k).
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] if `rhs` has not `n` rows, [`Error::NonFinite`] for NaN/inf,
    /// [`Error::Singular`] if the last factorisation failed.
    pub fn solve(&self, rhs: &DMatrix<f64>) -> Result<DMatrix<f64>> {
        let mut x = rhs.clone();
        self.solve_in_place(&mut x)?;
        Ok(x)
    }

    /// Solves `N X = B` in place: `rhs` (n × k) is overwritten by `X`.
    ///
    /// # Errors
    /// As [`SparseCholesky::solve`].
    pub fn solve_in_place(&self, rhs: &mut DMatrix<f64>) -> Result<()> {
        if rhs.nrows() != self.n() {
            return Err(Error::SizeMismatch {
                what: "right-hand side rows vs matrix order",
                expected: self.n(),
                got: rhs.nrows(),
            });
        }
        all_finite("right-hand side", rhs.iter())?;
        if !self.factored {
            return Err(Error::Singular {
                what: "no valid factorisation (the last one failed)".into(),
            });
        }
        if rhs.ncols() == 0 {
            return Ok(());
        }
        let req = self
            .symbolic
            .solve_in_place_scratch::<f64>(rhs.ncols(), self.par);
        let mut mem = MemBuffer::try_new(req).map_err(|_| Error::InvalidParam {
            name: "rhs",
            reason: "out of memory for the solve workspace".into(),
        })?;
        LltRef::new(&self.symbolic, &self.factor).solve_in_place_with_conj(
            Conj::No,
            dmatrix_as_faer_mut(rhs),
            self.par,
            MemStack::new(&mut mem),
        );
        Ok(())
    }
}

/// Lower-triangle pattern (col_ptr, row_idx) of a square CSC matrix.
fn lower_pattern(m: &CscMatrix<f64>) -> Result<(Vec<usize>, Vec<usize>)> {
    if m.nrows() != m.ncols() {
        return Err(Error::SizeMismatch {
            what: "matrix rows vs columns (must be square)",
            expected: m.ncols(),
            got: m.nrows(),
        });
    }
    let v = csc_as_faer(m);
    let mut col_ptr = Vec::with_capacity(m.ncols() + 1);
    let mut row_idx = Vec::with_capacity(m.nnz() / 2 + m.ncols());
    col_ptr.push(0);
    for j in 0..m.ncols() {
        row_idx.extend(v.row_idx_of_col(j).filter(|&i| i >= j));
        col_ptr.push(row_idx.len());
    }
    Ok((col_ptr, row_idx))
}

/// Values of the lower triangle of `m`, aligned with `lower_pattern(m)`.
fn lower_values(m: &CscMatrix<f64>, nnz_lower: usize) -> Vec<f64> {
    let mut values = Vec::with_capacity(nnz_lower);
    for (j, col) in m.col_iter().enumerate() {
        for (&i, &v) in col.row_indices().iter().zip(col.values()) {
            if i >= j {
                values.push(v);
            }
        }
    }
    values
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra_sparse::CooMatrix;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// 1D Dirichlet Laplacian tridiag(-1, 2 + shift, -1), full storage.
    fn tridiag(n: usize, shift: f64) -> CscMatrix<f64> {
        let mut coo = CooMatrix::new(n, n);
        for i in 0..n {
            coo.push(i, i, 2.0 + shift);
            if i + 1 < n {
                coo.push(i, i + 1, -1.0);
                coo.push(i + 1, i, -1.0);
            }
        }
        CscMatrix::from(&coo)
    }

    #[test]
    fn solves_spd_system_with_several_rhs_and_refactors() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let n = 50;
        let a = tridiag(n, 0.0);
        for params in [
            CholeskyParams::default(),
            CholeskyParams {
                ordering: FillOrdering::Natural,
                kind: FactorKind::Simplicial,
                parallel: false,
            },
            CholeskyParams {
                kind: FactorKind::Supernodal,
                ..Default::default()
            },
        ] {
            let mut chol = SparseCholesky::new(&a, &params).unwrap();
            let b = DMatrix::from_fn(n, 3, |_, _| rng.random_range(-1.0..1.0));
            let x = chol.solve(&b).unwrap();
            let dense = DMatrix::from(&a);
            assert!((&dense * &x - &b).norm() < 1e-10 * b.norm());
            // Same pattern, new values: reuse the analysis.
            let a2 = tridiag(n, 0.5);
            chol.refactor(&a2).unwrap();
            let x2 = chol.solve(&b).unwrap();
            assert!((DMatrix::from(&a2) * &x2 - &b).norm() < 1e-10 * b.norm());
        }
    }

    #[test]
    fn errors_on_bad_input() {
        let a = tridiag(4, 0.0);
        let mut chol = SparseCholesky::new(&a, &CholeskyParams::default()).unwrap();
        // Wrong rhs size.
        assert!(matches!(
            chol.solve(&DMatrix::zeros(3, 1)),
            Err(Error::SizeMismatch { .. })
        ));
        // NaN rhs.
        assert!(matches!(
            chol.solve(&DMatrix::from_element(4, 1, f64::NAN)),
            Err(Error::NonFinite { .. })
        ));
        // Not square.
        let rect = CscMatrix::from(&CooMatrix::<f64>::new(3, 4));
        assert!(matches!(
            SparseCholesky::new(&rect, &CholeskyParams::default()),
            Err(Error::SizeMismatch { .. })
        ));
        // Empty.
        let empty = CscMatrix::from(&CooMatrix::<f64>::new(0, 0));
        assert!(matches!(
            SparseCholesky::new(&empty, &CholeskyParams::default()),
            Err(Error::Empty { .. })
        ));
        // Indefinite: the singular 1D Neumann Laplacian minus a shift.
        let indefinite = tridiag(4, -1.5);
        assert!(matches!(
            chol.refactor(&indefinite),
            Err(Error::Singular { .. })
        ));
        // After a failed factorisation solving is refused.
        assert!(matches!(
            chol.solve(&DMatrix::zeros(4, 1)),
            Err(Error::Singular { .. })
        ));
        // Pattern change.
        assert!(matches!(
            chol.refactor(&CscMatrix::identity(4)),
            Err(Error::SizeMismatch { .. })
        ));
        // NaN values.
        let mut nan = tridiag(4, 0.0);
        nan.values_mut()[0] = f64::NAN;
        assert!(matches!(chol.refactor(&nan), Err(Error::NonFinite { .. })));
    }
}
