//! Small dense optimisers shared across the workspace.
//!
//! Sand 2003 (MS thesis §4.1) calibrates each camera and synchronises video with motion data by
//! "simultaneously optimiz\[ing\] the parameters using the downhill simplex method" of Nelder and
//! Mead (1965). This module provides that method ([`nelder_mead`]) and the usual faster
//! alternative for sum-of-squares problems, Levenberg–Marquardt ([`levenberg_marquardt`]), both
//! generic over a closure on `nalgebra` vectors so other crates (e.g. the video/motion-capture
//! synchronisation of `needle-model`) can reuse them.
//!
//! | file | holds |
//! | --- | --- |
//! | `lm.rs` | damped Gauss–Newton with Marquardt scaling and Nielsen's damping update |
//! | `numeric.rs` | central-difference Jacobians |
//! | `nelder_mead.rs` | downhill simplex with adaptive coefficients and restarts |

mod lm;
mod nelder_mead;
mod numeric;

pub use lm::{
    levenberg_marquardt, levenberg_marquardt_bounded, levenberg_marquardt_numeric, LmParams,
    LmReport, LmTermination,
};
pub use nelder_mead::{nelder_mead, nelder_mead_with_steps, NelderMeadParams, NelderMeadReport};
pub use numeric::numeric_jacobian;

#[cfg(test)]
pub(crate) mod test_problems;
