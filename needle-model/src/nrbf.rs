//! Normalised radial basis function deformation model: Sand, McMillan and Popović 2003 §5.1
//! (thesis §5.1) and its fitting from observations (§5.2–5.3).
//!
//! The method is documented on [`Nrbf`]; the module is private and
//! everything public is re-exported at the crate root.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use skin_core::check;

use crate::config::{check_samples, config_scale};
use crate::params::ReconstructionParams;
use crate::prototype_locations::farthest_point_prototypes;
use crate::prototype_shapes::{prototype_shapes_in_cells, NeighbourhoodStats, PrototypeShapes};
use crate::store::NeedleObservations;
use crate::{Error, Result};

/// A fitted NRBF deformation model of one primitive (Sand 2003 §5.1).
///
/// Normalised radial basis function deformation model: Sand, McMillan and Popović 2003 §5.1
/// (thesis §5.1) and its fitting from observations (§5.2–5.3).
///
/// Each needle length of a primitive is a distance-weighted average of prototype shapes:
///
/// ```text
/// l_j(x) = Σ_k v_jk K(x, p_k) / Σ_k K(x, p_k)                       (§5.1)
/// ```
///
/// The paper uses the plain normalised kernel average ("interpolate prototype shapes via
/// distance-weighted averaging", after Broomhead and Lowe) — there is no linear solve for RBF
/// coefficients, and the model does not pass exactly through `v_jk` at `p_k` unless the
/// kernel is narrow compared with the prototype spacing. Far from all prototypes the weights
/// tend to the nearest prototype, which is the extrapolation the paper wants (§5.1).
///
/// ## The kernel and the meaning of `W`
///
/// The paper says only that `K` is Gaussian with "kernel width W" and that `W = 7` minimised
/// the silhouette error (§6.3); it gives neither the formula nor the units of the
/// configuration space (marker coordinates in the bone frame, §3.3), so a bare `W = 7` in
/// metres, centimetres or millimetres would mean a static model, a smooth one or
/// nearest-neighbour lookup. We make `W` dimensionless and the same for every primitive by
/// measuring distances in units of the training data's RMS radius
/// `s = sqrt(mean_i ‖x_i − x̄‖²)` (computed per primitive over its *distinct* configuration
/// points, so that a pose held for most of the capture does not shrink it; see
/// `config_scale` in `config.rs`):
///
/// ```text
/// K(x, p) = exp(−W · ‖x − p‖² / s²)     ⇔  Gaussian with σ = s / sqrt(2W)  (σ ≈ 0.27 s at W = 7)
/// ```
///
/// Why this reading: with `N = 100` farthest-point prototypes over a 3-D data cloud the
/// prototype spacing is ≈ 0.4 s, so σ ≈ 0.27 s gives each query a few prototypes with
/// non-negligible weight — a smooth blend, neither a static average (σ ≫ spacing) nor
/// nearest-neighbour lookup (σ ≪ spacing). In 9-D spaces `s` grows like √dim together with the
/// prototype spacing, so the same `W` stays sensible; this is why the paper could use one
/// `W` for all primitives. Larger `W` is a sharper kernel.
///
/// Evaluation subtracts the smallest exponent before `exp`, so the weights never underflow
/// to `0/0` however far `x` is from the data.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Nrbf {
    dim: usize,
    num_needles: usize,
    /// Prototype locations `p_k`, `N × dim` row-major (configuration-space units).
    prototypes: Vec<f32>,
    /// Prototype shapes `v_jk`, prototype-major `N × J` (needle length units).
    shapes: Vec<f32>,
    /// RMS radius `s` of the training configurations (configuration-space units).
    config_scale: f32,
    /// Kernel parameter `W` (dimensionless, see [`Nrbf`]).
    kernel_width_w: f64,
}

/// Result of [`Nrbf::fit`]: the model plus diagnostics.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct NrbfFit {
    /// The fitted model.
    pub model: Nrbf,
    /// Sample indices chosen as prototype locations (§5.2), in selection order.
    pub prototype_samples: Vec<usize>,
    /// Covering radius of the prototypes over the training configurations.
    pub covering_radius: f32,
    /// Needles without observations that were filled from neighbours (§5.3).
    pub filled_needles: Vec<u32>,
    /// How the prototype neighbourhoods came out ([`PrototypeShapes::neighbourhood`]).
    pub neighbourhood: NeighbourhoodStats,
}

impl Nrbf {
    /// Builds a model from prototype locations (`N × dim`), shapes and the kernel scale.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] if `shapes.num_prototypes` differs from the number of
    /// locations or `shapes.lengths` has the wrong size; [`Error::InvalidParam`] for
    /// `dim ∉ 1..=16`, an invalid-parameter [`Error::Core`] for `config_scale ≤ 0` or
    /// `kernel_width_w ≤ 0`; [`Error::NonFinite`] for
    /// NaN/∞ inputs; [`Error::Empty`] for no prototypes.
    pub fn new(
        dim: usize,
        prototypes: Vec<f32>,
        shapes: PrototypeShapes,
        config_scale: f32,
        kernel_width_w: f64,
    ) -> Result<Self> {
        let n = check_samples(&prototypes, dim)?;
        if shapes.num_prototypes != n {
            return Err(Error::SizeMismatch {
                what: "prototype shapes vs prototype locations",
                expected: n,
                got: shapes.num_prototypes,
            });
        }
        if shapes.lengths.len() != n * shapes.num_needles {
            return Err(Error::SizeMismatch {
                what: "prototype shape lengths (N × J)",
                expected: n * shapes.num_needles,
                got: shapes.lengths.len(),
            });
        }
        if shapes.lengths.iter().any(|v| !v.is_finite()) {
            return Err(Error::NonFinite {
                what: "prototype shapes",
            });
        }
        check::positive("config_scale", f64::from(config_scale))?;
        check::positive("kernel_width_w", kernel_width_w)?;
        Ok(Self {
            dim,
            num_needles: shapes.num_needles,
            prototypes,
            shapes: shapes.lengths,
            config_scale,
            kernel_width_w,
        })
    }

    /// Fits one primitive from its observations (Sand 2003 §5.2–5.3, the algorithm box of
    /// §5.3): farthest-point prototype locations from a seeded random start
    /// (`params.seed`), robust-minimum shapes, kernel scale from the samples.
    ///
    /// # Errors
    /// Those of [`farthest_point_prototypes`], [`crate::prototype_shapes()`] and
    /// [`ReconstructionParams::validate`].
    pub fn fit(
        samples: &[f32],
        dim: usize,
        observations: &NeedleObservations,
        adjacency: &[Vec<u16>],
        params: &ReconstructionParams,
    ) -> Result<NrbfFit> {
        Self::fit_in_cells(samples, dim, observations, adjacency, params, None)
    }

    /// [`Nrbf::fit`] with the pool pose-share diagnostic in cells of side `pose_cell`
    /// (configuration units), see [`crate::NeighbourhoodStats::pool_max_pose_share_median`].
    pub(crate) fn fit_in_cells(
        samples: &[f32],
        dim: usize,
        observations: &NeedleObservations,
        adjacency: &[Vec<u16>],
        params: &ReconstructionParams,
        pose_cell: Option<f32>,
    ) -> Result<NrbfFit> {
        params.validate()?;
        let mut rng = ChaCha8Rng::seed_from_u64(params.seed);
        let locs = farthest_point_prototypes(samples, dim, params.prototype_count_n, &mut rng)?;
        let shapes = prototype_shapes_in_cells(
            samples,
            dim,
            observations,
            &locs.points,
            adjacency,
            params,
            pose_cell,
        )?;
        let filled_needles = shapes.filled_needles.clone();
        let neighbourhood = shapes.neighbourhood;
        let scale = config_scale(samples, dim)?;
        let model = Self::new(dim, locs.points, shapes, scale, params.kernel_width_w)?;
        Ok(NrbfFit {
            model,
            prototype_samples: locs.sample_indices,
            covering_radius: locs.covering_radius,
            filled_needles,
            neighbourhood,
        })
    }

    /// Configuration-space dimension.
    pub fn dim(&self) -> usize {
        self.dim
    }
    /// Number of needles `J`.
    pub fn num_needles(&self) -> usize {
        self.num_needles
    }
    /// Number of prototypes `N`.
    pub fn num_prototypes(&self) -> usize {
        self.prototypes.len() / self.dim
    }
    /// Prototype locations, `N × dim` row-major.
    pub fn prototypes(&self) -> &[f32] {
        &self.prototypes
    }
    /// Prototype shapes, prototype-major `N × J`.
    pub fn shapes(&self) -> &[f32] {
        &self.shapes
    }
    /// Kernel distance unit `s` (configuration-space units).
    pub fn config_scale(&self) -> f32 {
        self.config_scale
    }
    /// Kernel parameter `W`.
    pub fn kernel_width_w(&self) -> f64 {
        self.kernel_width_w
    }

    fn check_point(&self, x: &[f32]) -> Result<()> {
        if x.len() != self.dim {
            return Err(Error::SizeMismatch {
                what: "configuration point dimension",
                expected: self.dim,
                got: x.len(),
            });
        }
        if x.iter().any(|v| !v.is_finite()) {
            return Err(Error::NonFinite {
                what: "configuration point",
            });
        }
        Ok(())
    }

    /// Normalised kernel weights `K(x, p_k) / Σ_l K(x, p_l)` of every prototype (§5.1).
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] if `x.len() ≠ dim`; [`Error::NonFinite`] for NaN/∞.
    pub fn weights(&self, x: &[f32]) -> Result<Vec<f64>> {
        self.check_point(x)?;
        let mut w = Vec::with_capacity(self.num_prototypes());
        self.weights_into(x, &mut w);
        Ok(w)
    }

    fn weights_into(&self, x: &[f32], w: &mut Vec<f64>) {
        let c = self.kernel_width_w / (self.config_scale as f64).powi(2);
        w.clear();
        w.extend(self.prototypes.chunks_exact(self.dim).map(|p| {
            c * p
                .iter()
                .zip(x)
                .map(|(&a, &b)| (a as f64 - b as f64).powi(2))
                .sum::<f64>()
        }));
        // Shift by the smallest exponent: the nearest prototype gets weight exp(0) = 1, so
        // the sum is ≥ 1 and the normalisation never divides by zero.
        let emin = w.iter().copied().fold(f64::INFINITY, f64::min);
        let mut sum = 0.0;
        for e in w.iter_mut() {
            *e = (emin - *e).exp();
            sum += *e;
        }
        w.iter_mut().for_each(|e| *e /= sum);
    }

    /// Needle lengths `l_j(x)` at configuration point `x` (Sand 2003 §5.1), into `out`.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] if `x.len() ≠ dim` or `out.len() ≠ J`; [`Error::NonFinite`].
    pub fn evaluate_into(&self, x: &[f32], out: &mut [f32]) -> Result<()> {
        self.check_point(x)?;
        if out.len() != self.num_needles {
            return Err(Error::SizeMismatch {
                what: "output needle lengths",
                expected: self.num_needles,
                got: out.len(),
            });
        }
        let mut w = Vec::with_capacity(self.num_prototypes());
        self.weights_into(x, &mut w);
        self.blend(&w, out);
        Ok(())
    }

    fn blend(&self, w: &[f64], out: &mut [f32]) {
        let mut acc = vec![0f64; self.num_needles];
        for (k, &wk) in w.iter().enumerate() {
            if wk < 1e-12 {
                continue; // negligible prototype (relative weight below f32 resolution)
            }
            let row = &self.shapes[k * self.num_needles..(k + 1) * self.num_needles];
            for (a, &v) in acc.iter_mut().zip(row) {
                *a += wk * v as f64;
            }
        }
        // Weights below the cut-off sum to < N·1e-12; renormalise to keep an exact average.
        let used: f64 = w.iter().filter(|&&wk| wk >= 1e-12).sum();
        for (o, a) in out.iter_mut().zip(acc) {
            *o = (a / used) as f32;
        }
    }

    /// Needle lengths `l_j(x)` at configuration point `x` (Sand 2003 §5.1).
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] if `x.len() ≠ dim`; [`Error::NonFinite`] for NaN/∞.
    ///
    /// # Example
    /// ```
    /// use needle_model::{Nrbf, PrototypeShapes};
    /// // Two 1-D prototypes at 0 and 1 with one needle of length 2 and 4.
    /// let shapes = PrototypeShapes { num_needles: 1, num_prototypes: 2,
    ///     lengths: vec![2.0, 4.0], filled_needles: vec![], neighbourhood: Default::default() };
    /// let model = Nrbf::new(1, vec![0.0, 1.0], shapes, 0.5, 7.0)?;
    /// let mid = model.evaluate(&[0.5])?;
    /// assert!((mid[0] - 3.0).abs() < 1e-6);
    /// // Far outside the data the NRBF replicates the nearest prototype (§5.1).
    /// assert!((model.evaluate(&[100.0])?[0] - 4.0).abs() < 1e-6);
    /// # Ok::<(), needle_model::Error>(())
    /// ```
    pub fn evaluate(&self, x: &[f32]) -> Result<Vec<f32>> {
        let mut out = vec![0f32; self.num_needles];
        self.evaluate_into(x, &mut out)?;
        Ok(out)
    }

    /// Evaluates many configuration points (`M × dim` row-major) in parallel; returns
    /// `M × J` row-major lengths.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] if `points.len()` is not a multiple of `dim`;
    /// [`Error::NonFinite`] for NaN/∞.
    pub fn evaluate_batch(&self, points: &[f32]) -> Result<Vec<f32>> {
        if !points.len().is_multiple_of(self.dim) {
            return Err(Error::SizeMismatch {
                what: "batch of configuration points (length must be a multiple of dim)",
                expected: points.len().div_ceil(self.dim) * self.dim,
                got: points.len(),
            });
        }
        let mut out = vec![0f32; points.len() / self.dim * self.num_needles];
        if self.num_needles == 0 {
            return Ok(out);
        }
        out.par_chunks_mut(self.num_needles)
            .zip(points.par_chunks_exact(self.dim))
            .try_for_each(|(o, x)| self.evaluate_into(x, o))?;
        Ok(out)
    }
}

#[cfg(test)]
mod tests;

#[cfg(test)]
mod proptests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(48))]

        /// The NRBF is a convex combination (§5.1): weights sum to 1, every predicted length
        /// lies between the needle's smallest and largest prototype length, and every
        /// prototype length is one of the needle's observations (a percentile, §5.3).
        #[test]
        fn predictions_are_convex_combinations_of_observations(
            seed in 0u64..1_000,
            f_near in 0.01f64..1.0,
            f_min in 0.0f64..1.0,
            w in 0.1f64..50.0,
            x in prop::array::uniform2(-3.0f32..3.0),
        ) {
            use rand::RngExt;
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let samples: Vec<f32> = (0..400).map(|_| rng.random_range(-1.0f32..1.0)).collect();
            let per_needle: Vec<Vec<(u32, f32)>> = (0..3)
                .map(|_| (0..200u32).map(|s| (s, rng.random_range(0.1f32..1.0))).collect())
                .collect();
            let obs = NeedleObservations::from_lists(&per_needle).unwrap();
            let params = ReconstructionParams::default()
                .with_f_near(f_near)
                .with_f_min(f_min)
                .with_kernel_width_w(w)
                .with_prototype_count_n(12)
                .with_seed(seed);
            let fit = Nrbf::fit(&samples, 2, &obs, &[vec![], vec![], vec![]], &params).unwrap();
            let m = &fit.model;
            let wts = m.weights(&x).unwrap();
            prop_assert!((wts.iter().sum::<f64>() - 1.0).abs() < 1e-9);
            let l = m.evaluate(&x).unwrap();
            for j in 0..3 {
                let col: Vec<f32> = (0..m.num_prototypes())
                    .map(|k| m.shapes()[k * 3 + j])
                    .collect();
                let lo = col.iter().copied().fold(f32::INFINITY, f32::min);
                let hi = col.iter().copied().fold(f32::NEG_INFINITY, f32::max);
                prop_assert!(l[j] >= lo - 1e-5 && l[j] <= hi + 1e-5);
                for v in col {
                    prop_assert!(per_needle[j].iter().any(|&(_, o)| o == v));
                }
            }
        }
    }
}
