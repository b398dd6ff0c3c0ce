//! Dense tensor algebra for multilinear models (Vlasic thesis §5.2, after De Lathauwer):
//! N-mode tensors, unfolding and folding, the mode-`n` product, the truncated N-mode SVD
//! (HOSVD, Eq. 5.1–5.3, with modes left undecomposed as in Eq. 5.4) and its HOOI refinement
//! by alternating least squares.
//!
//! | item | computes | paper |
//! | --- | --- | --- |
//! | [`Tensor`] | row-major dense tensor, Frobenius norm, relative error | §5.2 "Tensors" |
//! | [`Tensor::unfold`], [`Tensor::fold`], [`Tensor::gram`] | `X₍ₙ₎` (columns: remaining indices row-major), its inverse, `X₍ₙ₎X₍ₙ₎ᵀ` | §5.2 "Mode Spaces", Fig. 5-2 |
//! | [`Tensor::mode_product`], [`Tensor::multi_mode_product`] | `𝒯 ×ₙ M`, chains of them | §5.2 "Mode-n Product" |
//! | [`hosvd`] → [`Tucker`] | `Ǔₙ` from each unfolding, `𝒞 = 𝒯 ×₁ Ǔ₁ᵀ ⋯` | Eq. 5.1–5.4 |
//! | [`hooi`] | ALS refinement of the HOSVD, error per sweep | §5.2 after Eq. 5.3 |
//!
//! Factors come from faer (through the crate's private `faer_bridge`): eigenvectors of the
//! small Gram matrix `X₍ₙ₎X₍ₙ₎ᵀ` (default for wide unfoldings), a thin SVD of the unfolding
//! (tall unfoldings), or a randomized range finder (a huge mode with a small rank); see
//! [`FactorMethod`].
//!
//! ```
//! use skin_core::tensor::{hosvd, FactorMethod, Tensor};
//! let x = Tensor::from_fn(vec![4, 3, 2], |i| (i[0] + 2 * i[1] * i[2]) as f64)?;
//! let t = hosvd(&x, &[None, Some(2), Some(2)], FactorMethod::Auto)?;
//! assert!(t.reconstruct()?.relative_error(&x)? < 1e-10);
//! # Ok::<(), skin_core::Error>(())
//! ```

mod dense;
mod hooi;
mod hosvd;
mod product;
mod unfold;

#[cfg(test)]
mod tests;

pub use dense::Tensor;
pub use hooi::{hooi, HooiParams, HooiResult};
pub use hosvd::{hosvd, FactorMethod, RandomizedParams, Tucker};
