//! Mode-`n` unfolding (matricization), folding, and the Gram matrix of an unfolding.
//!
//! **Column ordering.** The mode-`n` unfolding `X₍ₙ₎` is the `dₙ × (L·R)` matrix whose
//! columns are the mode-`n` vectors of the tensor (Vlasic Fig. 5-2 b–d): element
//! `(i₀, …, i_{N−1})` goes to row `iₙ` and column `l · R + r`, where `l` is the row-major
//! index of `(i₀, …, i_{n−1})` and `r` that of `(i_{n+1}, …, i_{N−1})` — the remaining
//! indices in increasing mode order with the *last* varying fastest. This is NumPy/TensorLy's
//! `moveaxis(n, 0).reshape(dₙ, −1)`; Kolda & Bader (2009) order the same columns with the
//! *first* remaining index fastest and De Lathauwer (2000) cyclically from `n + 1`. The
//! orderings differ by a column permutation only, so the column space, the Gram matrix
//! `X₍ₙ₎ X₍ₙ₎ᵀ` and hence every HOSVD factor are the same under all three.

use nalgebra::DMatrix;
use rayon::prelude::*;

use super::dense::Tensor;
use crate::faer_bridge::strided_ref;
use crate::{check, Error, Result};

/// Above this many multiply–adds per slab, products and Gram matrices run one GEMM per slab;
/// below it, one strided GEMM per trailing index over a block of slabs.
pub(crate) const GEMM_WORK: usize = 1 << 15;

/// Elements per block of consecutive slabs handed to one rayon task (fits in L2 cache).
pub(crate) const BLOCK_ELEMS: usize = 1 << 16;

/// `dst (+)= lhs · rhs` with faer's sequential GEMM (parallelism is over blocks of slabs).
pub(crate) fn gemm(
    dst: faer::MatMut<'_, f64>,
    accum: faer::Accum,
    lhs: faer::MatRef<'_, f64>,
    rhs: faer::MatRef<'_, f64>,
) {
    faer::linalg::matmul::matmul(dst, accum, lhs, rhs, 1.0, faer::Par::Seq);
}

impl Tensor {
    /// The mode-`n` unfolding `X₍ₙ₎` (`dₙ × Π_{k≠n} dₖ`; column ordering in the module docs).
    ///
    /// # Errors
    /// [`Error::IndexOutOfRange`] if `n ≥ N`.
    pub fn unfold(&self, n: usize) -> Result<DMatrix<f64>> {
        let (left, d, right) = self.split(n)?;
        let data = self.data();
        let mut out = DMatrix::zeros(d, left * right);
        // Column `l·R + r` of the column-major output is contiguous: write it from the `d`
        // strided reads `data[l·d·R + i·R + r]`.
        for (col, column) in out.as_mut_slice().chunks_exact_mut(d).enumerate() {
            let (l, r) = (col / right, col % right);
            let base = l * d * right + r;
            for (i, v) in column.iter_mut().enumerate() {
                *v = data[base + i * right];
            }
        }
        Ok(out)
    }

    /// The tensor of the given `shape` whose mode-`n` unfolding is `m` (the inverse of
    /// [`Tensor::unfold`]).
    ///
    /// # Errors
    /// As [`Tensor::new`] for the shape and values, [`Error::IndexOutOfRange`] if `n ≥ N`,
    /// [`Error::SizeMismatch`] if `m` is not `dₙ × Π_{k≠n} dₖ`.
    pub fn fold(m: &DMatrix<f64>, n: usize, shape: Vec<usize>) -> Result<Tensor> {
        let zero = Tensor::zeros(shape)?;
        let (left, d, right) = zero.split(n)?;
        check::same_size("unfolding rows (mode size)", d, m.nrows())?;
        check::same_size(
            "unfolding columns (product of the other modes)",
            left * right,
            m.ncols(),
        )?;
        check::all_finite("unfolding", m.as_slice())?;
        let shape = zero.shape().to_vec();
        let mut data = zero.into_data();
        for (col, column) in m.as_slice().chunks_exact(d).enumerate() {
            let (l, r) = (col / right, col % right);
            let base = l * d * right + r;
            for (i, &v) in column.iter().enumerate() {
                data[base + i * right] = v;
            }
        }
        Ok(Tensor::from_parts(shape, data))
    }

    /// The Gram matrix `X₍ₙ₎ X₍ₙ₎ᵀ` (`dₙ × dₙ`) of the mode-`n` unfolding, without forming the
    /// unfolding: the sum over `l` of `Sₗ Sₗᵀ` for the contiguous `dₙ × R` slabs `Sₗ`.
    ///
    /// # Errors
    /// [`Error::IndexOutOfRange`] if `n ≥ N`.
    pub fn gram(&self, n: usize) -> Result<DMatrix<f64>> {
        let (_, d, right) = self.split(n)?;
        let slabs = (BLOCK_ELEMS / (d * right)).max(1);
        let lower = self
            .data()
            .par_chunks(slabs * d * right)
            .fold(
                || vec![0.0; d * d],
                |mut acc, x| {
                    let nb = x.len() / (d * right);
                    if d * d * right >= GEMM_WORK {
                        // One GEMM per slab: Sₗ Sₗᵀ with Sₗᵀ the column-major R × dₙ view.
                        for s in x.chunks_exact(d * right) {
                            let st = faer::MatRef::from_column_major_slice(s, right, d);
                            let g = faer::MatMut::from_column_major_slice_mut(&mut acc, d, d);
                            gemm(g, faer::Accum::Add, st.transpose(), st);
                        }
                    } else {
                        // Small slabs: Σ_r X[·, ·, r]ᵀ X[·, ·, r] over the block's slabs
                        // (strided views).
                        for r in 0..right {
                            let xr = strided_ref(x, r, (nb, d), (d * right, right));
                            let g = faer::MatMut::from_column_major_slice_mut(&mut acc, d, d);
                            gemm(g, faer::Accum::Add, xr.transpose(), xr);
                        }
                    }
                    acc
                },
            )
            .reduce(
                || vec![0.0; d * d],
                |mut a, b| {
                    a.iter_mut().zip(&b).for_each(|(x, y)| *x += y);
                    a
                },
            );
        // faer fills both triangles; symmetrise exactly from the lower one.
        Ok(DMatrix::from_fn(d, d, |i, j| {
            if i >= j {
                lower[j * d + i]
            } else {
                lower[i * d + j]
            }
        }))
    }
}

/// [`Error::InvalidParam`] for a matrix whose column count does not match a mode.
pub(crate) fn mode_mismatch(n: usize, expected: usize, got: usize) -> Error {
    Error::InvalidParam {
        name: "mode-n product matrix",
        reason: format!("mode {n} has size {expected}, but the matrix has {got} columns"),
    }
}
