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
mod tests {
    use super::*;
    use rand::RngExt;

    const DIM: usize = 3;
    const NEEDLES: usize = 24;

    /// Synthetic primitive: needle `j`'s true length is a smooth function of a 3-D
    /// configuration point; observations overestimate it one-sidedly, like silhouette walks
    /// (small positive noise, and 15 % large "occluded" overestimates), and each needle is
    /// seen in about half of the samples.
    struct Synthetic {
        freq: Vec<[f32; 3]>,
        phase: Vec<f32>,
    }

    impl Synthetic {
        fn new(rng: &mut ChaCha8Rng) -> Self {
            let freq = (0..NEEDLES)
                .map(|_| std::array::from_fn(|_| rng.random_range(-1.2f32..1.2)))
                .collect();
            let phase = (0..NEEDLES)
                .map(|_| rng.random_range(0.0f32..std::f32::consts::TAU))
                .collect();
            Self { freq, phase }
        }

        fn truth(&self, x: &[f32], j: usize) -> f32 {
            let a = &self.freq[j];
            1.0 + 0.25 * (a[0] * x[0] + a[1] * x[1] + a[2] * x[2] + self.phase[j]).sin()
        }

        fn data(&self, rng: &mut ChaCha8Rng, count: usize) -> (Vec<f32>, NeedleObservations) {
            let samples: Vec<f32> = (0..count * DIM)
                .map(|_| rng.random_range(-1.0f32..1.0))
                .collect();
            self.observe(rng, samples)
        }

        /// Observations of every needle along given configuration samples.
        fn observe(
            &self,
            rng: &mut ChaCha8Rng,
            samples: Vec<f32>,
        ) -> (Vec<f32>, NeedleObservations) {
            let mut per_needle = vec![Vec::new(); NEEDLES];
            for (s, x) in samples.chunks_exact(DIM).enumerate() {
                for (j, list) in per_needle.iter_mut().enumerate() {
                    if rng.random_range(0.0f32..1.0) < 0.5 {
                        let u: f32 = rng.random_range(f32::EPSILON..1.0);
                        let mut l = self.truth(x, j) - 0.005 * u.ln();
                        if rng.random_range(0.0f32..1.0) < 0.15 {
                            l += rng.random_range(0.0f32..1.0);
                        }
                        list.push((s as u32, l));
                    }
                }
            }
            (
                samples,
                NeedleObservations::from_lists(&per_needle).unwrap(),
            )
        }

        /// RMS error over held-out interior points.
        fn rms_error(&self, model: &Nrbf, rng: &mut ChaCha8Rng) -> f32 {
            let pts: Vec<f32> = (0..400 * DIM)
                .map(|_| rng.random_range(-0.85f32..0.85))
                .collect();
            self.rms_error_at(model, &pts)
        }

        fn rms_error_at(&self, model: &Nrbf, pts: &[f32]) -> f32 {
            let count = pts.len() / DIM;
            let pred = model.evaluate_batch(pts).unwrap();
            let mut ss = 0.0f64;
            for (x, p) in pts.chunks_exact(DIM).zip(pred.chunks_exact(NEEDLES)) {
                for (j, &l) in p.iter().enumerate() {
                    ss += ((l - self.truth(x, j)) as f64).powi(2);
                }
            }
            (ss / (count * NEEDLES) as f64).sqrt() as f32
        }
    }

    fn ring_adjacency() -> Vec<Vec<u16>> {
        (0..NEEDLES as u16)
            .map(|j| {
                vec![
                    (j + 1) % NEEDLES as u16,
                    (j + NEEDLES as u16 - 1) % NEEDLES as u16,
                ]
            })
            .collect()
    }

    fn fit_error(params: &ReconstructionParams, count: usize, seed: u64) -> (f32, NrbfFit) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let syn = Synthetic::new(&mut rng);
        let (samples, obs) = syn.data(&mut rng, count);
        let fit = Nrbf::fit(&samples, DIM, &obs, &ring_adjacency(), params).unwrap();
        (syn.rms_error(&fit.model, &mut rng), fit)
    }

    #[test]
    fn recovers_true_function_on_held_out_points() {
        let params = ReconstructionParams::default();
        let (err, fit) = fit_error(&params, 16_000, 1);
        let (static_err, _) = fit_error(&params.with_f_near(1.0), 16_000, 1);
        eprintln!("held-out RMS: nrbf {err:.4}, static {static_err:.4}");
        assert_eq!(fit.model.num_prototypes(), 100);
        assert!(err < 0.05, "held-out RMS error {err} (amplitude 0.25)");
        assert!(err < 0.35 * static_err, "nrbf {err} vs static {static_err}");
    }

    #[test]
    fn error_falls_as_prototypes_are_added() {
        let errs: Vec<f32> = [10usize, 30, 100, 300]
            .iter()
            .map(|&n| {
                let p = ReconstructionParams::default().with_prototype_count_n(n);
                fit_error(&p, 16_000, 2).0
            })
            .collect();
        eprintln!("N = 10, 30, 100, 300 -> RMS {errs:?}");
        for w in errs.windows(2) {
            assert!(w[1] < w[0] * 1.05, "error should not grow with N: {errs:?}");
        }
        assert!(errs[3] < 0.65 * errs[0], "{errs:?}");
    }

    /// A performer's motion: a 3-D Lissajous path through configuration space at time `t`.
    fn motion_at(t: f32) -> [f32; 3] {
        const OMEGA: [f32; 3] = [0.5, 0.707, 0.866];
        OMEGA.map(|w| 0.9 * (w * t).sin())
    }

    /// `count` samples of the motion at a fixed rate: a longer capture covers more of the
    /// range of motion.
    fn motion(count: usize) -> Vec<f32> {
        const DT: f32 = 0.005;
        (0..count).flat_map(|i| motion_at(i as f32 * DT)).collect()
    }

    #[test]
    fn error_falls_with_more_training_data() {
        // As in Sand's thesis Figure 6-2 (30 s vs 3 min of motion): a longer capture covers
        // more of the range of motion, so unseen poses of the same motion (random times) are
        // predicted better. (With F_near fixed, the neighbourhood is a fixed fraction of the
        // data, so the robust-minimum bias inside a well-covered region does not shrink with
        // more data; coverage and noise do.)
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let syn = Synthetic::new(&mut rng);
        let held_out: Vec<f32> = (0..2_000)
            .flat_map(|_| motion_at(rng.random_range(0.0f32..10_000.0)))
            .collect();
        let errs: Vec<f32> = [1_000usize, 4_000, 16_000]
            .iter()
            .map(|&count| {
                let (samples, obs) = syn.observe(&mut rng, motion(count));
                let fit = Nrbf::fit(
                    &samples,
                    DIM,
                    &obs,
                    &ring_adjacency(),
                    &ReconstructionParams::default(),
                )
                .unwrap();
                syn.rms_error_at(&fit.model, &held_out)
            })
            .collect();
        eprintln!("S = 1000, 4000, 16000 -> RMS {errs:?}");
        for w in errs.windows(2) {
            assert!(w[1] < w[0], "error should fall with more data: {errs:?}");
        }
        assert!(errs[2] < 0.7 * errs[0], "{errs:?}");
    }

    #[test]
    fn f_near_one_gives_a_static_model() {
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        let syn = Synthetic::new(&mut rng);
        let (samples, obs) = syn.data(&mut rng, 2_000);
        let params = ReconstructionParams::default().with_f_near(1.0);
        let fit = Nrbf::fit(&samples, DIM, &obs, &ring_adjacency(), &params).unwrap();
        for j in 0..NEEDLES {
            let mut all = obs.needle(j).1.to_vec();
            all.sort_by(f32::total_cmp);
            let expect = all[crate::prototype_shapes::percentile_index(all.len(), params.f_min)];
            for k in 0..fit.model.num_prototypes() {
                assert_eq!(fit.model.shapes()[k * NEEDLES + j], expect);
            }
            for x in [[0.3f32, -0.2, 0.9], [5.0, 5.0, -5.0]] {
                let l = fit.model.evaluate(&x).unwrap()[j];
                assert!((l - expect).abs() < 1e-5 * expect);
            }
        }
    }

    #[test]
    fn weights_are_normalised_and_extrapolate_to_nearest_prototype() {
        let (_, fit) = fit_error(
            &ReconstructionParams::default().with_prototype_count_n(20),
            2_000,
            5,
        );
        let m = &fit.model;
        let w = m.weights(&[0.1, 0.2, -0.3]).unwrap();
        assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        assert!(w.iter().all(|&v| v >= 0.0));
        // Far away: the NRBF replicates the nearest prototype (§5.1), no 0/0.
        let far = [1e4f32, -3e3, 2e4];
        let nearest = m
            .prototypes()
            .chunks_exact(DIM)
            .enumerate()
            .map(|(k, p)| {
                (
                    k,
                    p.iter()
                        .zip(&far)
                        .map(|(a, b)| (a - b).powi(2))
                        .sum::<f32>(),
                )
            })
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .unwrap()
            .0;
        let l = m.evaluate(&far).unwrap();
        for (a, b) in l
            .iter()
            .zip(&m.shapes()[nearest * NEEDLES..(nearest + 1) * NEEDLES])
        {
            assert!((a - b).abs() < 1e-5);
        }
        // Batch evaluation equals single evaluation.
        let pts = [0.1f32, 0.2, -0.3, 0.5, 0.5, 0.5];
        let batch = m.evaluate_batch(&pts).unwrap();
        assert_eq!(&batch[..NEEDLES], &m.evaluate(&pts[..3]).unwrap()[..]);
        assert_eq!(&batch[NEEDLES..], &m.evaluate(&pts[3..]).unwrap()[..]);
    }

    #[test]
    fn serde_round_trip_preserves_predictions() {
        let (_, fit) = fit_error(
            &ReconstructionParams::default().with_prototype_count_n(15),
            1_000,
            6,
        );
        let json = serde_json::to_string(&fit.model).unwrap();
        let back: Nrbf = serde_json::from_str(&json).unwrap();
        assert_eq!(back, fit.model);
        let x = [0.2f32, -0.4, 0.1];
        assert_eq!(back.evaluate(&x).unwrap(), fit.model.evaluate(&x).unwrap());
    }

    #[test]
    fn bad_input_gives_clear_errors() {
        let (_, fit) = fit_error(
            &ReconstructionParams::default().with_prototype_count_n(5),
            500,
            7,
        );
        let m = &fit.model;
        assert!(matches!(
            m.evaluate(&[0.0, 0.0]),
            Err(Error::SizeMismatch { .. })
        ));
        assert!(matches!(
            m.evaluate(&[0.0, f32::NAN, 0.0]),
            Err(Error::NonFinite { .. })
        ));
        assert!(matches!(
            m.weights(&[f32::INFINITY, 0.0, 0.0]),
            Err(Error::NonFinite { .. })
        ));
        assert!(matches!(
            m.evaluate_batch(&[0.0; 4]),
            Err(Error::SizeMismatch { .. })
        ));
        assert!(matches!(
            m.evaluate_into(&[0.0; 3], &mut [0.0; 2]),
            Err(Error::SizeMismatch { .. })
        ));
        let shapes = |n: usize| PrototypeShapes {
            num_needles: 1,
            num_prototypes: n,
            lengths: vec![1.0; n],
            filled_needles: vec![],
            neighbourhood: NeighbourhoodStats {
                estimates: n,
                ..Default::default()
            },
        };
        assert!(matches!(
            Nrbf::new(1, vec![0.0, 1.0], shapes(3), 1.0, 7.0),
            Err(Error::SizeMismatch { .. })
        ));
        assert_eq!(
            Nrbf::new(1, vec![0.0], shapes(1), 0.0, 7.0)
                .unwrap_err()
                .invalid_param_name(),
            Some("config_scale")
        );
        assert_eq!(
            Nrbf::new(1, vec![0.0], shapes(1), 1.0, -1.0)
                .unwrap_err()
                .invalid_param_name(),
            Some("kernel_width_w")
        );
        assert!(matches!(
            Nrbf::new(1, vec![f32::NAN], shapes(1), 1.0, 7.0),
            Err(Error::NonFinite { .. })
        ));
        let mut nan_shape = shapes(1);
        nan_shape.lengths[0] = f32::NAN;
        assert!(matches!(
            Nrbf::new(1, vec![0.0], nan_shape, 1.0, 7.0),
            Err(Error::NonFinite { .. })
        ));
        let obs = NeedleObservations::from_lists(&[vec![(0, 1.0)]]).unwrap();
        let e = Nrbf::fit(
            &[0.0],
            1,
            &obs,
            &[vec![]],
            &ReconstructionParams::default().with_kernel_width_w(0.0),
        )
        .unwrap_err();
        assert_eq!(e.invalid_param_name(), Some("kernel_width_w"));
        assert!(matches!(
            config_scale(&[f32::NAN], 1),
            Err(Error::NonFinite { .. })
        ));
        assert_eq!(config_scale(&[2.0, 2.0], 1).unwrap(), 1.0);
    }
}

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
