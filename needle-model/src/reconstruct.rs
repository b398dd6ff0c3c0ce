//! Whole-body skin reconstruction from accumulated observations: the outer loop of the
//! algorithm box in Sand, McMillan and Popović 2003 §5.3 ("for each bone i …") and the
//! animation step of §5.4.
//!
//! The method is documented on [`NeedleModel`]; the module is private and
//! everything public is re-exported at the crate root.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::nrbf::Nrbf;
use crate::params::ReconstructionParams;
use crate::primitive::NeedleBody;
use crate::prototype_shapes::{grid_adjacency, NeighbourhoodStats};
use crate::store::{NeedleObservations, ObservationStore};
use crate::{Context, Error, Result, ResultExt};

/// The reconstructed deformable body: one NRBF per primitive (Sand 2003 §5.1).
///
/// Whole-body skin reconstruction from accumulated observations: the outer loop of the
/// algorithm box in Sand, McMillan and Popović 2003 §5.3 ("for each bone i …") and the
/// animation step of §5.4.
///
/// Each primitive of an [`ObservationStore`] is fitted independently
/// ([`Nrbf::fit`]: prototype locations §5.2, shapes §5.3), in parallel over primitives
/// (each fit is itself parallel over needles). The result is a [`NeedleModel`] that predicts
/// every needle length of a primitive from its configuration point (§5.1, §5.4).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct NeedleModel {
    /// Per-primitive models, indexed like the store's primitives.
    pub primitives: Vec<Nrbf>,
}

/// Diagnostics of one primitive's fit.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PrimitiveFitReport {
    /// Configuration samples of the primitive.
    pub samples: usize,
    /// Observations of the primitive.
    pub observations: usize,
    /// Sample indices chosen as prototype locations (§5.2).
    pub prototype_samples: Vec<usize>,
    /// Covering radius of the prototypes (configuration-space units).
    pub covering_radius: f32,
    /// Never-observed needles filled from neighbouring needles (§5.3).
    pub filled_needles: Vec<u32>,
    /// How the prototype neighbourhoods came out (cap radius, estimates, how often the
    /// `min_near` floor bound).
    #[serde(default)]
    pub neighbourhood: crate::NeighbourhoodStats,
}

/// Result of [`NeedleModel::reconstruct`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Reconstruction {
    /// The model.
    pub model: NeedleModel,
    /// One report per primitive.
    pub reports: Vec<PrimitiveFitReport>,
}

impl NeedleModel {
    /// Reconstructs every primitive of `store`, whose needles are laid out as in `body`
    /// (ring-major grids, used to fill never-observed needles from their neighbours).
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] if `body` and `store` disagree on the primitives or their
    /// needle counts; otherwise as [`NeedleModel::reconstruct_grids`].
    pub fn reconstruct(
        store: &ObservationStore,
        body: &NeedleBody,
        params: &ReconstructionParams,
    ) -> Result<Reconstruction> {
        Self::reconstruct_observations(store, body, params, |p| store.by_needle(p))
    }

    /// [`NeedleModel::reconstruct`] with each primitive's per-needle observations from
    /// `observations(p)` instead of the store's (the samples stay the store's): what the
    /// model over skinning fits its residuals with ([`crate::PoseSpaceModel`]).
    pub(crate) fn reconstruct_observations(
        store: &ObservationStore,
        body: &NeedleBody,
        params: &ReconstructionParams,
        observations: impl Fn(usize) -> Result<NeedleObservations> + Sync,
    ) -> Result<Reconstruction> {
        let grids: Vec<Grid> = body
            .primitives
            .iter()
            .map(|p| Grid {
                radial: p.radial,
                axial: p.axial,
                units_per_radian: p.config.units_per_radian,
            })
            .collect();
        Self::reconstruct_in(store, &grids, params, observations)
    }

    /// Reconstructs every primitive of `store`; `grids[p] = (radial, axial)` gives primitive
    /// `p`'s ring-major needle grid. Primitive `p` uses seed `params.seed + p` for its random
    /// first prototype, so results do not depend on the thread count. (Without the
    /// configuration spaces' rates the neighbourhood statistics in degrees and pose shares
    /// stay `None`; [`NeedleModel::reconstruct`] has them.)
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] if `grids` has the wrong length; [`Error::InvalidParam`] for
    /// invalid `params`. Per primitive, in [`Error::At`] with its [`Context::Primitive`]:
    /// [`Error::SizeMismatch`] if its grid's needle count differs from the store's,
    /// [`Error::NoObservations`] if it has no samples, and the errors of [`Nrbf::fit`]
    /// (NaN, unfillable needles, with their [`Context::Needle`]).
    pub fn reconstruct_grids(
        store: &ObservationStore,
        grids: &[(usize, usize)],
        params: &ReconstructionParams,
    ) -> Result<Reconstruction> {
        let grids: Vec<Grid> = grids
            .iter()
            .map(|&(radial, axial)| Grid {
                radial,
                axial,
                units_per_radian: None,
            })
            .collect();
        Self::reconstruct_in(store, &grids, params, |p| store.by_needle(p))
    }

    fn reconstruct_in(
        store: &ObservationStore,
        grids: &[Grid],
        params: &ReconstructionParams,
        observations: impl Fn(usize) -> Result<NeedleObservations> + Sync,
    ) -> Result<Reconstruction> {
        params.validate()?;
        let count = store.primitive_count();
        if grids.len() != count {
            return Err(Error::SizeMismatch {
                what: "needle grids (one per primitive)",
                expected: count,
                got: grids.len(),
            });
        }
        let fits: Vec<(Nrbf, PrimitiveFitReport)> = (0..count)
            .into_par_iter()
            .map(|p| {
                fit_primitive(store, grids[p], p, params, &observations).at(Context::Primitive(p))
            })
            .collect::<Result<_>>()?;
        let (primitives, reports) = fits.into_iter().unzip();
        Ok(Reconstruction {
            model: NeedleModel { primitives },
            reports,
        })
    }

    /// The model of primitive `p`, if it exists.
    pub fn primitive(&self, p: usize) -> Option<&Nrbf> {
        self.primitives.get(p)
    }

    /// Every needle length of primitive `p` (metres, like the store's lengths) at
    /// configuration point `config` (§5.4).
    ///
    /// # Errors
    /// [`Error::IndexOutOfRange`] for an unknown primitive; [`Error::SizeMismatch`] for a
    /// wrong-sized point; [`Error::NonFinite`] for NaN/∞ coordinates.
    pub fn needle_lengths(&self, p: usize, config: &[f32]) -> Result<Vec<f32>> {
        self.primitives
            .get(p)
            .ok_or(Error::IndexOutOfRange {
                what: "primitive",
                index: p,
                len: self.primitives.len(),
            })?
            .evaluate(config)
    }
}

/// What reconstruction needs of a primitive's layout: its needle grid and the rate of its
/// configuration space ([`crate::ConfigSpace::units_per_radian`]), if known.
#[derive(Clone, Copy)]
struct Grid {
    radial: usize,
    axial: usize,
    units_per_radian: Option<f64>,
}

/// Fits primitive `p` of `store` on its needle grid from `observations(p)` (the body of
/// [`NeedleModel::reconstruct_grids`]'s loop; errors get the primitive's context there).
fn fit_primitive(
    store: &ObservationStore,
    grid: Grid,
    p: usize,
    params: &ReconstructionParams,
    observations: impl Fn(usize) -> Result<NeedleObservations>,
) -> Result<(Nrbf, PrimitiveFitReport)> {
    let Grid {
        radial,
        axial,
        units_per_radian,
    } = grid;
    if radial * axial != store.needle_count(p) {
        return Err(Error::SizeMismatch {
            what: "needle grid radial × axial vs store needle count",
            expected: store.needle_count(p),
            got: radial * axial,
        });
    }
    if store.sample_count(p) == 0 {
        return Err(Error::NoObservations {
            what: "the primitive has no samples".into(),
        });
    }
    let obs = observations(p)?;
    let adjacency = grid_adjacency(radial, axial)?;
    let prim_params = params.with_seed(params.seed.wrapping_add(p as u64));
    let cell =
        units_per_radian.map(|u| (u * NeighbourhoodStats::POOL_POSE_CELL_DEG.to_radians()) as f32);
    let mut fit = Nrbf::fit_in_cells(
        store.samples(p),
        store.config_dim(p),
        &obs,
        &adjacency,
        &prim_params,
        cell,
    )?;
    if let (Some(u), Some(r)) = (units_per_radian, fit.neighbourhood.pool_radius_median) {
        fit.neighbourhood.pool_radius_deg_median = Some((r as f64 / u).to_degrees() as f32);
    }
    log::debug!(
        "primitive {p}: {} samples, {} observations, {} prototypes, {} filled needles, \
         min_near floor bound in {} of {} estimates",
        store.sample_count(p),
        obs.observation_count(),
        fit.model.num_prototypes(),
        fit.filled_needles.len(),
        fit.neighbourhood.floor_bound,
        fit.neighbourhood.estimates
    );
    let report = PrimitiveFitReport {
        samples: store.sample_count(p),
        observations: obs.observation_count(),
        prototype_samples: fit.prototype_samples,
        covering_radius: fit.covering_radius,
        filled_needles: fit.filled_needles,
        neighbourhood: fit.neighbourhood,
    };
    Ok((fit.model, report))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::store::PrimitiveShape;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// Two primitives (3-D and 6-D configuration spaces) with known smooth needle lengths,
    /// observed with one-sided noise; needle 0 of primitive 1 is never observed.
    fn synthetic_store() -> (ObservationStore, Vec<(usize, usize)>) {
        let grids = vec![(6usize, 2usize), (4, 3)];
        let shapes = [
            PrimitiveShape {
                config_dim: 3,
                needle_count: 12,
                max_length_m: 0.2,
            },
            PrimitiveShape {
                config_dim: 6,
                needle_count: 12,
                max_length_m: 0.2,
            },
        ];
        let mut store = ObservationStore::new(&shapes).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        for (p, shape) in shapes.iter().enumerate() {
            for _ in 0..3000 {
                let x = config(shape.config_dim, &mut rng, 1.0);
                let mut obs = Vec::new();
                for j in 0..shape.needle_count {
                    if (p == 1 && j == 0) || rng.random_range(0.0f32..1.0) > 0.5 {
                        continue;
                    }
                    let u: f32 = rng.random_range(f32::EPSILON..1.0);
                    let l = truth(j, &x) - 0.001 * u.ln();
                    obs.push((j as u16, l.min(0.2)));
                }
                store.push_sample(p, &x, &obs).unwrap();
            }
        }
        (store, grids)
    }

    /// A configuration point: 3 latent pose coordinates in `[-r, r]`, embedded in 6-D as
    /// correlated marker coordinates for the 6-D primitive (markers move together).
    fn config(dim: usize, rng: &mut ChaCha8Rng, r: f64) -> Vec<f64> {
        let u: [f64; 3] = std::array::from_fn(|_| rng.random_range(-r..r));
        if dim == 3 {
            u.to_vec()
        } else {
            vec![
                u[0],
                u[1],
                u[2],
                0.5 * (u[0] + u[1]),
                0.5 * (u[1] - u[2]),
                0.5 * u[2],
            ]
        }
    }

    fn truth(j: usize, x: &[f64]) -> f32 {
        (0.1 + 0.02 * (x[0] + 0.5 * x[1] + j as f64 * 0.3).sin()) as f32
    }

    #[test]
    fn reconstructs_every_primitive_and_fills_unobserved_needles() {
        let (store, grids) = synthetic_store();
        let params = ReconstructionParams::default().with_prototype_count_n(50);
        let rec = NeedleModel::reconstruct_grids(&store, &grids, &params).unwrap();
        assert_eq!(rec.model.primitives.len(), 2);
        assert_eq!(rec.reports[1].filled_needles, vec![0]);
        assert!(rec.reports[0].filled_needles.is_empty());
        let mut rng = ChaCha8Rng::seed_from_u64(10);
        for p in 0..2 {
            let dim = store.config_dim(p);
            let mut worst = 0f32;
            for _ in 0..100 {
                let x = config(dim, &mut rng, 0.7);
                let xf: Vec<f32> = x.iter().map(|&v| v as f32).collect();
                let l = rec.model.needle_lengths(p, &xf).unwrap();
                for (j, &lj) in l.iter().enumerate().skip(if p == 1 { 1 } else { 0 }) {
                    worst = worst.max((lj - truth(j, &x)).abs());
                }
            }
            // Amplitude 0.02 m; the robust minimum over a neighbourhood biases low a little.
            assert!(worst < 0.012, "primitive {p}: worst error {worst} m");
        }
        // Deterministic: a second run gives the same model.
        let again = NeedleModel::reconstruct_grids(&store, &grids, &params).unwrap();
        assert_eq!(again, rec);
    }

    #[test]
    fn bad_input_gives_clear_errors() {
        let (store, grids) = synthetic_store();
        let p = ReconstructionParams::default().with_prototype_count_n(5);
        assert!(matches!(
            NeedleModel::reconstruct_grids(&store, &grids[..1], &p),
            Err(Error::SizeMismatch { .. })
        ));
        let e = NeedleModel::reconstruct_grids(&store, &[(6, 2), (5, 3)], &p).unwrap_err();
        assert!(matches!(e.contexts()[..], [Context::Primitive(_)]), "{e}");
        assert!(matches!(e.root(), Error::SizeMismatch { .. }), "{e}");
        assert_eq!(
            NeedleModel::reconstruct_grids(&store, &grids, &p.with_f_min(2.0))
                .unwrap_err()
                .invalid_param_name(),
            Some("f_min")
        );
        let empty = ObservationStore::new(&[PrimitiveShape {
            config_dim: 3,
            needle_count: 4,
            max_length_m: 0.1,
        }])
        .unwrap();
        let e = NeedleModel::reconstruct_grids(&empty, &[(4, 1)], &p).unwrap_err();
        assert_eq!(e.contexts(), vec![Context::Primitive(0)]);
        assert!(matches!(e.root(), Error::NoObservations { .. }));
        assert_eq!(
            e.to_string(),
            "primitive 0: no observations: the primitive has no samples; capture more frames or \
             cameras that see it"
        );
        let rec = NeedleModel::reconstruct_grids(&store, &grids, &p).unwrap();
        assert!(matches!(
            rec.model.needle_lengths(2, &[0.0; 3]),
            Err(Error::IndexOutOfRange { index: 2, .. })
        ));
        assert!(matches!(
            rec.model.needle_lengths(0, &[0.0, f32::NAN, 0.0]),
            Err(Error::NonFinite { .. })
        ));
        let json = serde_json::to_string(&rec.model).unwrap();
        let back: NeedleModel = serde_json::from_str(&json).unwrap();
        assert_eq!(back, rec.model);
    }
}
