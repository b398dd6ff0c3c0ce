//! Private bridge between the public linear-algebra vocabulary (`nalgebra` dense matrices,
//! `nalgebra_sparse::CscMatrix`) and `faer` 0.24, which the crate uses internally for sparse
//! Cholesky and large dense decompositions (DESIGN.md "Two vocabularies").
//!
//! Both libraries store column-major data with `usize` indices, so the views below are
//! zero-copy: no value or index is moved. Only the conversion *back* to a `CscMatrix`
//! ([`faer_to_csc`]) copies, because a `CscMatrix` owns its buffers.

// Some conversions are only used by tests or by later modules.
#![allow(dead_code)]

use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Accum, MatMut, MatRef, Par, Side};
use nalgebra::DMatrix;
use nalgebra_sparse::CscMatrix;

use crate::{Error, Result};

/// Zero-copy faer view of a `CscMatrix`.
///
/// nalgebra-sparse guarantees what faer requires of a sorted CSC matrix: `col_offsets` has
/// `ncols + 1` non-decreasing entries ending at `nnz`, and the row indices of each column
/// are strictly increasing and `< nrows`. The view is therefore built with faer's unchecked
/// constructor (the check would cost one pass over the indices per call).
pub(crate) fn csc_as_faer(m: &CscMatrix<f64>) -> SparseColMatRef<'_, usize, f64> {
    let (col_ptr, row_idx, values) = (m.col_offsets(), m.row_indices(), m.values());
    // SAFETY: the CscMatrix invariants listed above are exactly faer's invariants for a
    // `SymbolicSparseColMatRef` with sorted rows and no explicit column lengths.
    let symbolic = unsafe {
        SymbolicSparseColMatRef::new_unchecked(m.nrows(), m.ncols(), col_ptr, None, row_idx)
    };
    SparseColMatRef::new(symbolic, values)
}

/// Zero-copy faer view of a dense nalgebra matrix (both are column-major, contiguous).
pub(crate) fn dmatrix_as_faer(m: &DMatrix<f64>) -> MatRef<'_, f64> {
    MatRef::from_column_major_slice(m.as_slice(), m.nrows(), m.ncols())
}

/// Zero-copy mutable faer view of a dense nalgebra matrix.
pub(crate) fn dmatrix_as_faer_mut(m: &mut DMatrix<f64>) -> MatMut<'_, f64> {
    let (nrows, ncols) = (m.nrows(), m.ncols());
    MatMut::from_column_major_slice_mut(m.as_mut_slice(), nrows, ncols)
}

/// Copies a faer dense matrix (any strides) into a nalgebra `DMatrix`.
pub(crate) fn faer_to_dmatrix(m: MatRef<'_, f64>) -> DMatrix<f64> {
    DMatrix::from_fn(m.nrows(), m.ncols(), |i, j| m[(i, j)])
}

/// Copies a faer sparse column matrix into a `CscMatrix`, sorting the rows of each column
/// (faer allows unsorted columns and explicit column lengths; nalgebra-sparse does not).
///
/// # Panics
/// Never for matrices produced by faer: the only failure of `try_from_csc_data` is an
/// invariant violation (duplicate row in a column), which faer's own invariants exclude.
#[allow(
    clippy::expect_used,
    reason = "faer sparse matrices have sorted, unique entries per column"
)]
pub(crate) fn faer_to_csc(m: SparseColMatRef<'_, usize, f64>) -> CscMatrix<f64> {
    let ncols = m.ncols();
    let mut col_offsets = Vec::with_capacity(ncols + 1);
    let mut row_indices = Vec::new();
    let mut values = Vec::new();
    col_offsets.push(0);
    let mut column: Vec<(usize, f64)> = Vec::new();
    for j in 0..ncols {
        column.clear();
        column.extend(m.row_idx_of_col(j).zip(m.val_of_col(j).iter().copied()));
        column.sort_unstable_by_key(|&(i, _)| i);
        for &(i, v) in &column {
            row_indices.push(i);
            values.push(v);
        }
        col_offsets.push(row_indices.len());
    }
    CscMatrix::try_from_csc_data(m.nrows(), ncols, col_offsets, row_indices, values)
        .expect("faer sparse matrices have no duplicate entries in a column")
}

/// Eigenvectors of the symmetric matrix `g` for its `k` largest eigenvalues, largest first,
/// as the columns of an `n × k` matrix, with those eigenvalues (faer's self-adjoint
/// eigensolver; only the lower triangle of `g` is read).
///
/// # Errors
/// [`Error::NoConvergence`] if faer's eigensolver does not converge.
pub(crate) fn sym_top_eigen(g: &DMatrix<f64>, k: usize) -> Result<(DMatrix<f64>, Vec<f64>)> {
    let evd = dmatrix_as_faer(g)
        .self_adjoint_eigen(Side::Lower)
        .map_err(|_| Error::NoConvergence {
            what: "self-adjoint eigendecomposition",
            iterations: 0,
        })?;
    let (u, s) = (evd.U(), evd.S());
    let n = g.nrows();
    let k = k.min(n);
    // faer sorts eigenvalues in non-decreasing order: the largest are the last columns.
    let vectors = DMatrix::from_fn(n, k, |i, j| u[(i, n - 1 - j)]);
    let values = (0..k).map(|j| s[n - 1 - j]).collect();
    Ok((vectors, values))
}

/// The first `k` left singular vectors of `m` (faer's thin SVD), as an `nrows × k` matrix.
///
/// # Errors
/// [`Error::NoConvergence`] if faer's SVD does not converge.
pub(crate) fn thin_svd_left(m: &DMatrix<f64>, k: usize) -> Result<DMatrix<f64>> {
    let svd = dmatrix_as_faer(m)
        .thin_svd()
        .map_err(|_| Error::NoConvergence {
            what: "thin SVD",
            iterations: 0,
        })?;
    let u = svd.U();
    let k = k.min(u.ncols());
    Ok(DMatrix::from_fn(m.nrows(), k, |i, j| u[(i, j)]))
}

/// An orthonormal basis of the column space of the tall matrix `m` (`nrows ≥ ncols`): the
/// thin `Q` of faer's Householder QR.
pub(crate) fn thin_q(m: &DMatrix<f64>) -> DMatrix<f64> {
    faer_to_dmatrix(dmatrix_as_faer(m).qr().compute_thin_Q().as_ref())
}

/// `aᵀ b` or `a b` (by `transpose_a`) with faer's matrix product, single-threaded.
pub(crate) fn matmul(a: &DMatrix<f64>, transpose_a: bool, b: &DMatrix<f64>) -> DMatrix<f64> {
    let lhs = if transpose_a {
        dmatrix_as_faer(a).transpose()
    } else {
        dmatrix_as_faer(a)
    };
    let mut out = DMatrix::zeros(lhs.nrows(), b.ncols());
    faer::linalg::matmul::matmul(
        dmatrix_as_faer_mut(&mut out),
        Accum::Replace,
        lhs,
        dmatrix_as_faer(b),
        1.0,
        Par::Seq,
    );
    out
}

/// Panics unless the strided view is non-empty and its last element lies inside `len`.
fn check_strided(
    len: usize,
    offset: usize,
    (nrows, ncols): (usize, usize),
    (row_stride, col_stride): (usize, usize),
) {
    assert!(nrows > 0 && ncols > 0, "strided view: empty");
    let last = offset + (nrows - 1) * row_stride + (ncols - 1) * col_stride;
    assert!(last < len, "strided view out of bounds");
}

/// The `nrows × ncols` faer view of `s` whose element `(i, j)` is
/// `s[offset + i·row_stride + j·col_stride]` (e.g. one `r`-slice of a row-major tensor block).
///
/// # Panics
/// If the view would reach past the end of `s` (a caller bug; checked because the view is
/// built from raw parts).
pub(crate) fn strided_ref(
    s: &[f64],
    offset: usize,
    (nrows, ncols): (usize, usize),
    (row_stride, col_stride): (usize, usize),
) -> MatRef<'_, f64> {
    check_strided(s.len(), offset, (nrows, ncols), (row_stride, col_stride));
    let (rs, cs) = (row_stride as isize, col_stride as isize);
    // SAFETY: every element (i, j), i < nrows, j < ncols, is at offset + i·rs + j·cs, at
    // most the last element, which `check_strided` put inside the borrowed slice, whose
    // lifetime the view carries; strides fit isize as they are bounded by the slice length.
    unsafe { MatRef::from_raw_parts(s.as_ptr().add(offset), nrows, ncols, rs, cs) }
}

/// Mutable version of [`strided_ref`]; the view must not alias itself, which holds when
/// `col_stride · ncols ≤ row_stride` (the columns of a row do not reach the next row).
///
/// # Panics
/// If the view would reach past the end of `s` or could alias itself.
pub(crate) fn strided_mut(
    s: &mut [f64],
    offset: usize,
    (nrows, ncols): (usize, usize),
    (row_stride, col_stride): (usize, usize),
) -> MatMut<'_, f64> {
    assert!(col_stride >= 1, "strided view: zero column stride");
    assert!(
        nrows == 1 || col_stride * ncols <= row_stride,
        "strided view would alias itself"
    );
    check_strided(s.len(), offset, (nrows, ncols), (row_stride, col_stride));
    let (rs, cs) = (row_stride as isize, col_stride as isize);
    // SAFETY: in bounds as in `strided_ref`; distinct (i, j) map to distinct offsets because
    // j·cs < ncols·cs ≤ rs, and the exclusive borrow of `s` is carried by the view.
    unsafe { MatMut::from_raw_parts_mut(s.as_mut_ptr().add(offset), nrows, ncols, rs, cs) }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra_sparse::CooMatrix;

    fn sample() -> CscMatrix<f64> {
        let mut coo = CooMatrix::new(4, 3);
        coo.push(0, 0, 1.0);
        coo.push(3, 0, -2.0);
        coo.push(1, 1, 3.5);
        coo.push(2, 2, 4.0);
        coo.push(0, 2, 0.5);
        CscMatrix::from(&coo)
    }

    #[test]
    fn sparse_view_is_zero_copy_and_round_trips() {
        let a = sample();
        let v = csc_as_faer(&a);
        assert_eq!(v.nrows(), 4);
        assert_eq!(v.ncols(), 3);
        assert!(std::ptr::eq(v.val().as_ptr(), a.values().as_ptr()));
        let back = faer_to_csc(v);
        assert_eq!(back, a);
        let dense_a: DMatrix<f64> = DMatrix::from(&a);
        let dense_v = v.to_dense();
        assert_eq!(faer_to_dmatrix(dense_v.as_ref()), dense_a);
    }

    #[test]
    fn dense_views_share_memory() {
        let mut m = DMatrix::from_fn(3, 2, |i, j| (i * 10 + j) as f64);
        let v = dmatrix_as_faer(&m);
        assert_eq!(v[(2, 1)], 21.0);
        assert_eq!(faer_to_dmatrix(v), m);
        dmatrix_as_faer_mut(&mut m)[(1, 0)] = -7.0;
        assert_eq!(m[(1, 0)], -7.0);
    }
}
