//! Articulated ellipsoid fitting after Fua, Gruen, Plänkers, D'Apuzzo, Thalmann, *Human Body
//! Modeling and Motion Analysis from Video Sequences* (paper `003_…`, §4.2 and §5).
//!
//! **Model (§4.2, Eq. 3).** The skeleton's DOFs θ, a length scale `s_b` per bone (the
//! variable coefficient `q` of `D_ini = (RX + qT)`, §4.2.1) and one ellipsoid per bone,
//! centred on the bone, symmetric about it: in the frame of the bone's parent joint `p`, with
//! `a` the unit bone direction, `z = u·a` and `ρ² = |u|² − z²`,
//! `F(u) = ρ²/w² + (z − l)²/h² − 1`, `l = s_b·L_b/2` (half the bone length, `L_b` the
//! default skeleton's; the centre), `w` the half-width (`part_w`) and `h` the ellipsoid's
//! half-length. Eq. 3 ties `h = l`; we keep `h` as its own unknown (half-length and
//! half-width are both unknowns), held near its start by a prior
//! ([`EllipsoidParams::sigma_half_length_prior_m`]). Measured on the studio (a limb's surface
//! reaches both joints with non-zero radius, unlike Eq. 3's ellipsoid): with `h = l` tied
//! the fit lowers its cost by lengthening the upper bones to the scale bound while their
//! children shrink; with `h` free of a strong prior the ellipsoids grow into long cylinders.
//! A bone's length is then observable where its chain bends (the joint is where two bone
//! axes meet), hence [`fit_ellipsoids_multi`] over frames of a motion; the length of a
//! chain's last bone (forearm, shin) only moves its ellipsoid along a nearly cylindrical limb
//! and stays weakly determined (see `docs/template-silhouette.md`).
//!
//! **Residual.** Eq. 9 writes `F(u_a) = 0 − ε` for an attractor `u_a`. `F` is unit-less; we
//! use `e = (w/2)·F`, which is ≈ the radial distance to the surface near it (`F ≈ 2d/w`), so
//! the a-priori σ of every observation type is in metres and Eq. 7 homogenises the weights
//! as `P = 1/σ²` (Eq. 8 is then `Σ P e²`).
//!
//! **Jacobians (analytic).** The attractor `X` is fixed in the world and the joint frame
//! moves: `u = R_pᵀ(X − o_p)`, so for a rotation DOF `k` on the chain of `p` (world axis
//! `ω_k` through `c_k`) `∂u/∂θ_k = −R_pᵀ(ω_k × (X − c_k))`, for a translation DOF
//! `−R_pᵀ t_k`; a bone scale `s_m` whose child joint is on the chain of `p` moves `o_p` by
//! `R_{parent}·offset_m`, so `∂u/∂s_m = −R_pᵀ R_{parent}·offset_m`. With
//! `g = ∂e/∂u = w·[(u − z a)/w² + (z − l) a/h²]`: `∂e/∂θ_k = −(R_p g)·v_k`. The own
//! scale also enters the centre `l`: `∂F/∂l = −2 (z − l)/h²`, `∂l/∂s_b = L_b/2`; the width:
//! `∂e/∂w = F/2 − ρ²/w²`; the half-length: `∂e/∂h = −w (z − l)²/h³`.
//!
//! **Silhouettes (§5.3, Eq. 11–17).** Eq. 14–17 add the tangent point `P^s` as three unknowns
//! per ray, constrained to the ray (collinearity, Eq. 15) and to the tangent plane (Eq. 12–13,
//! with the heavy pseudo-observation Eq. 17). We eliminate `P^s` exactly: in the ellipsoid's
//! normalised coordinates (the ellipsoid a unit sphere) `F` along the ray is a quadratic in
//! the ray parameter `t`, and the tangent point of the ray-plane is the ray's point of least
//! `F`, `t* = argmin F(c + t d)`. The residual is `e(c + t* d)`; by the envelope theorem
//! (`∂F/∂t = 0` at `t*`) its gradient w.r.t. the state is the attractor gradient at the fixed
//! point `c + t* d`. So a silhouette ray is an attractor re-placed every iteration.
//!
//! **Assignment and robustness (§5.2).** Each iteration every attractor and ray goes to the
//! ellipsoid with the smallest `|e|` (so the objective is `Σ P min_b e_b²`, one function),
//! chosen among the two bones of smallest `|e|` at the start of the IRLS round (pruning:
//! each round assigns among all bones);
//! markers stay on their bone with the high weight of their small σ. IRLS: the first round
//! weighs every observation equally (within its type); each later round gives
//! Tukey's biweight `(1 − (r/c)²)²` (0 beyond `c`) of the residual normalised by a robust
//! scale per type (`1.4826·median|e|`, not below the type's σ; over every observation of
//! the type, or over those the previous round kept when that round rejected a large
//! fraction of them: [`EllipsoidParams::kept_scale_min_rejected`]), `c = 4.685` —
//! the paper "weighs them inversely proportionally to their residuals"; Tukey's redescending weight
//! is the variant we chose because it gives gross outliers exactly zero weight.
//!
//! One deviation, measured: the paper's first round is an unweighted fit, and the weights
//! come from its residuals. With 30 % gross outliers that fit swells ellipsoids around the
//! outliers (half-widths of a metre in the unit test) and its residuals no longer separate
//! inliers from outliers, so when IRLS is on (`irls_rounds > 1`) the first weights come from
//! the residuals at the *starting* state (default proportions, approximate pose), and every
//! round reweights at the previous round's result. `irls_rounds = 1` is the plain,
//! unweighted least squares. The first [`EllipsoidParams::pose_only_rounds`] rounds hold the
//! lengths and widths (a pose a few degrees off would otherwise let ellipsoids swell over
//! their neighbours' points first).
//!
//! **Several frames (§5: the paper fits sequences).** [`fit_ellipsoids_multi`] shares the
//! length scales, widths and half-lengths between frames, each frame has its own θ.
//!
//! **Solver.** Levenberg–Marquardt on the normal equations, accumulated observation by
//! observation (no dense Jacobian) in fixed chunks in parallel, frames in parallel; the
//! normal equations are kept in blocks (a pose block per frame, the shared block, their
//! couplings) and solved by the Schur complement on the shared unknowns. A weak prior on the
//! starting state (a pseudo-observation type with its own σ, so DOFs without data stay put),
//! scales clamped to a box and widths to a floor.
//!
//! | file | what |
//! | --- | --- |
//! | `model.rs` | the bones, the state, the world ellipsoids, the residual of Eq. 9 and its derivatives; [`fit_half_width`] |
//! | `observations.rs` | one frame's points, markers and silhouette rays |
//! | `params.rs` | [`EllipsoidParams`] |
//! | `fit.rs` | assignment, block Levenberg–Marquardt, IRLS: [`fit_ellipsoids`], [`fit_ellipsoids_multi`] |
//! | `validation.rs` | (feature `validation`) the studio scenario and its scores |

mod fit;
mod model;
mod observations;
mod params;
#[cfg(test)]
mod tests;
#[cfg(feature = "validation")]
mod validation;

pub use fit::{fit_ellipsoids, fit_ellipsoids_multi, EllipsoidFit, EllipsoidMultiFit};
pub use model::{fit_half_width, Ellipsoid, EllipsoidBone, EllipsoidModel, EllipsoidState};
pub use observations::{EllipsoidObservations, MarkerObservation};
pub use params::EllipsoidParams;
#[cfg(feature = "validation")]
#[cfg_attr(docsrs, doc(cfg(feature = "validation")))]
pub use validation::{
    ellipsoid_scenario, score_ellipsoids, EllipsoidScenario, EllipsoidScenarioParams,
    EllipsoidScores, ScenarioFrame, ScenarioMotion,
};
