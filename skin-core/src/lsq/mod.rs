//! Sparse linear least squares with several right-hand sides and symbolic reuse.
//!
//! Solves
//!
//! ```text
//! min_X ‖A X − B‖² + Σ_k w_k ‖C_k X − D_k‖²
//! ```
//!
//! (Frobenius norms; `X` is n × r, one column per right-hand side, e.g. r = 3 for x, y, z
//! vertex coordinates) through the normal equations
//! `(AᵀA + Σ w_k C_kᵀ C_k) X = AᵀB + Σ w_k C_kᵀ D_k` with a sparse Cholesky factorisation.
//! This is the shape of every linear solve of the Vlasic 2010 thesis: the Laplacian
//! template molding of §2.4.1 (Eq. 2.1: `A = Δ`, `B = 0`, `C = C_LBS`, `w_C = 1000`;
//! Eq. 2.2: `B = w_L L'`, `C = C_SIL`), the normal integration of Eq. 3.3 and the thin-plate
//! offsets of Eq. 3.4.
//!
//! Normal equations square the condition number; for the mesh problems above (Laplacian plus
//! soft positional constraints, weights ≤ 10⁴) the factorisation stays accurate to about
//! 1e-12 relative, and it is an order of magnitude faster than sparse QR, which is why the
//! thesis' problem sizes (tens of thousands of vertices, one solve per iteration and frame)
//! are solved this way in practice (libigl, CHOLMOD users).
//!
//! The sparsity pattern of the normal matrix and a scatter map from the products
//! `M_ri M_rj` to its entries are computed once in [`LsqProblem::factor`], together with the
//! symbolic Cholesky analysis (AMD ordering, supernodes). [`LsqSolver::set_weights`] and
//! [`LsqSolver::set_values`] then only re-multiply values and refactorise numerically;
//! [`LsqSolver::solve`] solves all right-hand sides at once. [`SparseCholesky`] exposes the
//! same machinery for symmetric positive definite systems that are not in least-squares form
//! (e.g. the bone-heat system of [`crate::mesh::bone_heat_weights`]).
//!
//! Systems too large to factorise, or solved only approximately, go to [`pcg`]: matrix-free
//! preconditioned conjugate gradients with the operator and the preconditioner given as
//! closures (e.g. a multigrid cycle), its stopping rule and its order of summation chosen by
//! the caller ([`PcgParams`]).

mod cholesky;
mod normal;
mod pcg;
mod problem;

pub use cholesky::{CholeskyParams, CholeskyStats, FactorKind, FillOrdering, SparseCholesky};
pub use pcg::{
    pcg, LinearOperator, PcgParams, PcgStats, PcgStop, Preconditioner, Reduction, Reference,
    ResidualNorm,
};
pub use problem::{LsqDiagnostics, LsqParams, LsqProblem, LsqSolver, LsqStats};

#[cfg(test)]
mod test_util;
