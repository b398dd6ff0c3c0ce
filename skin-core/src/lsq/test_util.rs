//! Helpers shared by the lsq unit tests.

use nalgebra_sparse::{CooMatrix, CscMatrix};
use rand::RngExt;
use rand_chacha::ChaCha8Rng;

/// A random `m × n` sparse matrix with about `density · m · n` entries in [-1, 1).
pub(crate) fn random_sparse(
    rng: &mut ChaCha8Rng,
    m: usize,
    n: usize,
    density: f64,
) -> CscMatrix<f64> {
    let mut coo = CooMatrix::new(m, n);
    for i in 0..m {
        for j in 0..n {
            if rng.random_range(0.0..1.0) < density {
                coo.push(i, j, rng.random_range(-1.0..1.0));
            }
        }
    }
    CscMatrix::from(&coo)
}
