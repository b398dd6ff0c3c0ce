//! Missing data (§5.3.4): the thesis's PPCA imputation as written ([`impute_ppca`]), the
//! averaging baseline ([`impute_by_averaging`]), and the imputation that chooses between
//! them and PPCA at other ranks by cross-validation on the known faces ([`impute`], ours).
//! Every fill is affine in the known faces and costs `O(K³)` per iteration from their
//! moments (`moments.rs`).

mod averaging;
mod model_choice;
mod moments;
mod ppca;
mod spd;

#[cfg(feature = "validation")]
pub(crate) use averaging::averaging_can_fill;
pub use averaging::impute_by_averaging;
pub use model_choice::{impute, Imputation, ImputeModel, ImputeParams};
pub use ppca::{impute_ppca, PpcaImputation, PpcaParams};
