//! The mode-`n` product `𝒯 ×ₙ M` (Vlasic §5.2 "Mode-n Product") and products along
//! several modes (the chains of Eq. 5.1–5.3).

use nalgebra::DMatrix;
use rayon::prelude::*;

use super::dense::Tensor;
use super::unfold::{gemm, mode_mismatch, BLOCK_ELEMS, GEMM_WORK};
use crate::faer_bridge::{strided_mut, strided_ref};
use crate::{check, Result};

impl Tensor {
    /// The mode-`n` product `𝒴 = 𝒯 ×ₙ M` with an `m × dₙ` matrix `M`: every mode-`n` vector
    /// `v` of `𝒯` is replaced by `M v` (§5.2), so `𝒴` has shape `d` with `dₙ → m` and
    /// `Y₍ₙ₎ = M X₍ₙ₎`. Slab by slab (`Yₗ = M Xₗ` for the `dₙ × R` slabs, in parallel over
    /// `l`); large slabs go through faer's GEMM.
    ///
    /// # Errors
    /// [`Error::IndexOutOfRange`](crate::Error::IndexOutOfRange) if `n ≥ N`,
    /// [`Error::InvalidParam`](crate::Error::InvalidParam) if `M` has not `dₙ` columns,
    /// [`Error::NonFinite`](crate::Error::NonFinite) if `M` holds NaN or ±∞.
    pub fn mode_product(&self, n: usize, m: &DMatrix<f64>) -> Result<Tensor> {
        let (_, d, right) = self.split(n)?;
        if m.ncols() != d {
            return Err(mode_mismatch(n, d, m.ncols()));
        }
        check::all_finite("mode-n product matrix", m.as_slice())?;
        let rows = m.nrows();
        let mut shape = self.shape().to_vec();
        shape[n] = rows;
        if rows == 0 {
            return Err(crate::Error::Empty {
                what: "mode-n product matrix (0 rows)",
            });
        }
        let work = rows * d * right;
        let mut out = vec![0.0; shape.iter().product()];
        let slabs = (BLOCK_ELEMS / (d * right)).max(1);
        let mt = faer::MatRef::from_column_major_slice(m.as_slice(), rows, d).transpose();
        out.par_chunks_mut(slabs * rows * right)
            .zip(self.data().par_chunks(slabs * d * right))
            .for_each(|(y, x)| {
                let nb = x.len() / (d * right);
                if work >= GEMM_WORK {
                    // One GEMM per slab: Yₗ row-major (m × R) is Yₗᵀ column-major
                    // (R × m) = Xₗᵀ Mᵀ.
                    for (ys, xs) in y
                        .chunks_exact_mut(rows * right)
                        .zip(x.chunks_exact(d * right))
                    {
                        let xt = faer::MatRef::from_column_major_slice(xs, right, d);
                        let yt = faer::MatMut::from_column_major_slice_mut(ys, right, rows);
                        gemm(yt, faer::Accum::Replace, xt, mt);
                    }
                } else {
                    // Small slabs: one GEMM per trailing index r over the block's slabs,
                    // Y[·, ·, r] (nb × m) = X[·, ·, r] (nb × dₙ) Mᵀ, on strided views.
                    for r in 0..right {
                        let xr = strided_ref(x, r, (nb, d), (d * right, right));
                        let yr = strided_mut(y, r, (nb, rows), (rows * right, right));
                        gemm(yr, faer::Accum::Replace, xr, mt);
                    }
                }
            });
        Ok(Tensor::from_parts(shape, out))
    }

    /// `𝒯 ×ₙ₁ M₁ ×ₙ₂ M₂ ⋯` for the `(mode, matrix)` pairs, applied in the order that shrinks
    /// the tensor fastest (products along different modes commute, so the order changes the
    /// cost only). The reconstruction `𝒞 ×₁ U₁ ⋯ ×_N U_N` of Eq. 5.2–5.3 is this product
    /// with the factors.
    ///
    /// # Errors
    /// As [`Tensor::mode_product`]; [`Error::InvalidParam`](crate::Error::InvalidParam) if a
    /// mode appears twice.
    pub fn multi_mode_product(&self, products: &[(usize, &DMatrix<f64>)]) -> Result<Tensor> {
        let mut order: Vec<&(usize, &DMatrix<f64>)> = products.iter().collect();
        for (k, (n, _)) in products.iter().enumerate() {
            check::index("mode", *n, self.order())?;
            if products[..k].iter().any(|(p, _)| p == n) {
                return Err(crate::Error::InvalidParam {
                    name: "multi-mode product modes",
                    reason: format!("mode {n} appears twice"),
                });
            }
        }
        // Most shrinking (rows / columns smallest) first.
        order.sort_by(|(_, a), (_, b)| {
            let ra = a.nrows() as f64 / a.ncols().max(1) as f64;
            let rb = b.nrows() as f64 / b.ncols().max(1) as f64;
            ra.total_cmp(&rb)
        });
        let mut out: Option<Tensor> = None;
        for (n, m) in order {
            let next = out.as_ref().unwrap_or(self).mode_product(*n, m)?;
            out = Some(next);
        }
        Ok(out.unwrap_or_else(|| self.clone()))
    }
}
