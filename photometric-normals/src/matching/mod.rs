//! Pairwise matching of neighbouring views (Vlasic 2010 §3.3.2): four matching metrics,
//! epipolar-plane grids of matching costs, and the lowest-cost path through each grid by a
//! four-state dynamic programme after Criminisi et al. [41], which also finds the depth
//! discontinuities that §3.3.1 removes from the integration.
//!
//! **Epipolar planes.** For a pair (left, right) the planes through both camera centres are
//! taken one per row of the left image (the plane through the ray of the row's centre pixel),
//! so neighbouring planes are about a pixel apart. Each plane meets each image in a line
//! (`l = K⁻ᵀ m` for the plane normal `m` in the camera frame; the cameras must be
//! undistorted — undistort images first); the line is sampled "one pixel at a time in each
//! view" at the integer pixels it crosses, keeping those where the view's integrated surface
//! exists. Samples are ordered by the angle between their ray and the baseline, which orders
//! the points of an opaque surface the same way in both views.
//!
//! **Grid.** Cell `(a, b)` pairs left sample `a` with right sample `b`; their rays meet (closest
//! approach) at a point `X`. The cell is evaluated only if `X` lies within
//! [`MatchingParams::band_m`] of both views' guide surfaces along their rays (pass 1: the
//! integrated surfaces themselves; pass 2: the proxy mesh, Figure 3-6c), the two rays pass
//! within two pixel footprints of each other, and `X` is inside the visual hull when one is
//! given (Figure 3-6's light blue). Other cells cost `∞`.
//!
//! **Metrics** ([`MatchMetric`]): the full-on image window, the stack of the six half-on
//! images, the surface-based metric (5 × 5 windows of surface points compared under their
//! optimal rigid alignment, rendered each way and the larger of the two mean distances taken
//! — the thesis' best) and the illumination stack projected through the aligned surface
//! windows. Image metrics are mean squared differences over the window.
//!
//! **Path.** States (Criminisi's four): a match reached by a step in the left view (diagonal
//! or left-slanted), a match reached by a step in the right view only (right-slanted), left
//! occluded, right occluded. A match costs its cell, an occluded sample costs
//! [`MatchingParams::occlusion_cost`] × the grid's median cost, and entering or leaving an
//! occlusion adds [`MatchingParams::discontinuity_penalty`] × that. Matches costing at most
//! [`MatchingParams::good_cost`] × the median are kept (Figure 3-6's green); jumps of the
//! matched depth above 1 cm per pixel ([`IntegrationParams::match_jump_m`](crate::IntegrationParams))
//! between consecutive matches are depth discontinuities (red).
//!
//! **Files**, in dependency order: `params.rs` (the knobs), `views.rs` (inputs and results),
//! `mesh.rs` (surfaces as points and meshes), `epipolar.rs` (per-view set-up, a plane's line
//! samples), `horn.rs` (the optimal rotation), `metrics.rs` (a cell's cost under each
//! metric), `batch.rs` (the surface metric of a row's cells at once, one per SIMD lane),
//! `epipolar_dp.rs` (the four-state programme), `plane.rs` (one plane: costs, path, sub-pixel
//! matches, breaks), `pair.rs` (a pair plane by plane), `coarse_to_fine.rs` (the entry point
//! [`match_pair`], with the half-resolution pass).

mod batch;
mod coarse_to_fine;
mod epipolar;
mod epipolar_dp;
mod horn;
mod mesh;
mod metrics;
mod pair;
mod params;
mod plane;
mod views;

pub use coarse_to_fine::match_pair;
pub(crate) use coarse_to_fine::match_pair_with_rays;
pub use mesh::depth_map_mesh;
pub use params::{MatchMetric, MatchingParams, SubPixel};
pub use views::{matching_images, MatchStats, MatchView, PairMatches, ViewMatches};

#[cfg(test)]
mod tests;
