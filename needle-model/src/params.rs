//! Reconstruction parameters of Sand, McMillan and Popović 2003, §6.3 (thesis §5.5).
//!
//! The method is documented on [`ReconstructionParams`]; the module is private and
//! everything public is re-exported at the crate root.

use serde::{Deserialize, Serialize};

use skin_core::check;

use crate::{Error, Result};

impl ReconstructionParams {
    /// Default `F_near`: fraction of a needle's observations used for each prototype.
    /// Sand 2003 §6.3 (thesis §5.5, Figure 5-4).
    pub const DEFAULT_F_NEAR: f64 = 0.022;

    /// Default `F_min`: percentile (as a fraction) taken as the robust minimum.
    /// Sand 2003 §6.3 (thesis §5.5, Figure 5-4).
    pub const DEFAULT_F_MIN: f64 = 0.10;

    /// Default kernel width `W` of the NRBF Gaussian (see [`crate::Nrbf`] for its exact meaning).
    /// Sand 2003 §6.3 (thesis §5.5, Figure 5-4).
    pub const DEFAULT_KERNEL_WIDTH_W: f64 = 7.0;

    /// Default number of prototypes per deformable primitive `N`. Sand 2003 §6.3.
    pub const DEFAULT_PROTOTYPE_COUNT_N: usize = 100;

    /// Default floor on the number of observations behind each prototype estimate (see
    /// [`ReconstructionParams::min_near`]).
    pub const DEFAULT_MIN_NEAR: usize = 50;

    /// Default seed of the random first prototype location (§5.2 picks it "at random").
    pub const DEFAULT_SEED: u64 = 0x5a4d_2003;
}
impl Neighbourhood {
    /// Default `radius_factor` of [`Neighbourhood::Capped`]: a prototype's neighbourhood reaches
    /// at most one prototype spacing (the median nearest-prototype distance) from it.
    pub const DEFAULT_RADIUS_FACTOR: f64 = 1.0;
}

/// Which observations a prototype's shape is estimated from (§5.3 and our departure from it).
///
/// * [`Neighbourhood::Fraction`] is the paper's rule: the `n = max(F_near · m, min_near)`
///   observations nearest the prototype, however far they are. §5.3 takes a fraction rather
///   than a distance so that far poses can fill holes in configuration space.
/// * [`Neighbourhood::Capped`] (the default, a documented departure from §5.3) is the same
///   nearest-first walk, stopped at a radius `R = radius_factor × spacing`, where `spacing` is
///   the median distance from a prototype to its nearest other prototype. Why: on a training
///   motion where a primitive sits at rest most of the time (a range of motion exercises one
///   DOF at a time), a needle has ≈ 3 650 observations of which ≈ 3 300 share the rest
///   configuration. The fraction walk of a prototype on a sweep runs through the sparse sweep,
///   reaches the rest pose and takes that tie group whole, so the `F_min` percentile falls
///   among rest-pose values and every prototype equals the static estimate. Capping the walk
///   at about one prototype spacing keeps a far tie group out: a prototype's shape comes from
///   observations near it in configuration space.
///
/// With the cap, `min_near` is a floor only: when the ball of radius `R` holds fewer than
/// `min(min_near, m)` observations of the needle (a rarely seen needle, or a prototype where
/// this needle was seldom visible), the estimate uses the `min(min_near, m)` nearest
/// observations instead, ignoring the cap; otherwise it uses `min(F_near · m, ball count)`, so
/// a small `F_near` keeps its meaning. An *empty* ball is the extreme case of the same floor:
/// it falls back to the `min_near` nearest observations (as the fraction rule would), not to
/// the needle's static estimate — nearest views are still the best evidence for this pose.
/// A fraction that takes every observation (`F_near = 1`) is the static model in both
/// variants: the cap limits a walk, and there is none. How often the floor binds is reported ([`crate::NeighbourhoodStats::floor_bound`],
/// [`crate::PrimitiveFitReport::neighbourhood`]). With a single prototype there is no spacing
/// and the cap is infinite.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum Neighbourhood {
    /// §5.3 as published: a fraction `F_near` of the needle's observations, floored at
    /// `min_near`, with no distance limit.
    Fraction,
    /// The fraction walk stopped at `radius_factor ×` the prototype spacing (median
    /// nearest-prototype distance); `min_near` a floor only for sparse balls. `radius_factor`
    /// must be finite and > 0. Default [`Neighbourhood::DEFAULT_RADIUS_FACTOR`].
    Capped {
        /// Cap radius in units of the prototype spacing.
        radius_factor: f64,
    },
}

impl Default for Neighbourhood {
    fn default() -> Self {
        Self::Capped {
            radius_factor: Neighbourhood::DEFAULT_RADIUS_FACTOR,
        }
    }
}

/// Parameters of prototype reconstruction (Sand 2003 §5.2–5.3) and NRBF evaluation (§5.1).
///
/// Reconstruction parameters of Sand, McMillan and Popović 2003, §6.3 (thesis §5.5).
///
/// The prototype estimation algorithm (§5.2–5.3) has four free parameters: the fraction of
/// nearby observations `F_near`, the percentile of the robust minimum `F_min`, the Gaussian
/// kernel width `W` of the NRBF (§5.1), and the number of prototypes per primitive `N`. The
/// paper selects them by minimising the silhouette error (§6.2) and reports
/// `F_near = 0.022`, `F_min = 0.10`, `W = 7`, `N = 100`; those are the defaults here. Two
/// parameters are ours: a floor `min_near` on the observations behind each estimate
/// ([`ReconstructionParams::min_near`]) and the [`Neighbourhood`] rule (default: capped at one
/// prototype spacing, a departure from §5.3; the paper's rule stays selectable).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ReconstructionParams {
    /// Fraction of a needle's observations, nearest in configuration space to a prototype
    /// location, from which the prototype's needle length is estimated (§5.3). Dimensionless,
    /// in (0, 1]; `1` uses every observation and so yields a static (pose-independent) model
    /// (thesis Figure 6-2c). Source: Sand 2003 §6.3. Default: 0.022.
    pub f_near: f64,
    /// Percentile of the selected lengths taken as the robust minimum (§5.3): `0` is the
    /// minimum, `1` the maximum. Dimensionless, in [0, 1]. Silhouette lengths only overestimate
    /// the true surface (visual-hull argument, §5), so a low percentile finds the maximal
    /// consistent geometry while ignoring a few outliers. Source: Sand 2003 §6.3. Default: 0.10.
    pub f_min: f64,
    /// Gaussian kernel parameter `W` of the NRBF (§5.1). Dimensionless: configuration-space
    /// distances are measured in units of the RMS radius `s` of the distinct training
    /// configurations, and the kernel is `K(x, p) = exp(−W‖x − p‖²/s²)` (derivation in [`crate::Nrbf`]). Larger `W` means a
    /// sharper, more local kernel. Must be > 0. Source: Sand 2003 §6.3. Default: 7.
    pub kernel_width_w: f64,
    /// Number of prototypes per deformable primitive (§5.2). Must be ≥ 1. If a primitive has
    /// fewer distinct configuration points, fewer prototypes are placed.
    /// Source: Sand 2003 §6.3. Default: 100.
    pub prototype_count_n: usize,
    /// Floor on the number of nearest observations behind each prototype's needle length.
    /// With [`Neighbourhood::Fraction`]: `n = max(F_near · m, min_near)` (capped at the `m`
    /// observations of the needle). With [`Neighbourhood::Capped`]: applied only when the
    /// capped ball holds fewer than `min_near` observations of the needle (see there).
    ///
    /// Not in the paper, which never needed it: with 8 minutes from 3 cameras every needle has
    /// thousands of observations and `F_near · m` is large. A needle seen rarely (a calf
    /// needle facing the other leg, whose walk runs on through the other leg's silhouette and
    /// is discarded) can have 150 observations, so `F_near = 0.022` leaves 3, and the "robust
    /// minimum" of 3 observations is whatever the nearest 3 happened to be — on the studio
    /// these needles came out 7 cm long where the truth is 6 cm. A percentile `F_min` only
    /// means something when `F_min · n ≫ 1`; 50 keeps 5 observations below the 10th
    /// percentile. Must be ≥ 1 (1 is the paper's rule). Default: 50.
    pub min_near: usize,
    /// Seed of the RNG that picks the first prototype location (§5.2). Default: 0x5a4d_2003.
    pub seed: u64,
    /// Which observations each prototype's shape comes from ([`Neighbourhood`]). Default:
    /// [`Neighbourhood::Capped`] with `radius_factor = 1` (ours; the paper's rule is
    /// [`Neighbourhood::Fraction`]).
    #[serde(default)]
    pub neighbourhood: Neighbourhood,
}

impl Default for ReconstructionParams {
    fn default() -> Self {
        Self {
            f_near: ReconstructionParams::DEFAULT_F_NEAR,
            f_min: ReconstructionParams::DEFAULT_F_MIN,
            kernel_width_w: ReconstructionParams::DEFAULT_KERNEL_WIDTH_W,
            prototype_count_n: ReconstructionParams::DEFAULT_PROTOTYPE_COUNT_N,
            min_near: ReconstructionParams::DEFAULT_MIN_NEAR,
            seed: ReconstructionParams::DEFAULT_SEED,
            neighbourhood: Neighbourhood::default(),
        }
    }
}

impl ReconstructionParams {
    /// Sets `f_near`.
    pub fn with_f_near(mut self, f_near: f64) -> Self {
        self.f_near = f_near;
        self
    }
    /// Sets `f_min`.
    pub fn with_f_min(mut self, f_min: f64) -> Self {
        self.f_min = f_min;
        self
    }
    /// Sets `kernel_width_w`.
    pub fn with_kernel_width_w(mut self, w: f64) -> Self {
        self.kernel_width_w = w;
        self
    }
    /// Sets `prototype_count_n`.
    pub fn with_prototype_count_n(mut self, n: usize) -> Self {
        self.prototype_count_n = n;
        self
    }
    /// Sets `min_near`.
    pub fn with_min_near(mut self, min_near: usize) -> Self {
        self.min_near = min_near;
        self
    }
    /// Sets `seed`.
    pub fn with_seed(mut self, seed: u64) -> Self {
        self.seed = seed;
        self
    }
    /// Sets `neighbourhood`.
    pub fn with_neighbourhood(mut self, neighbourhood: Neighbourhood) -> Self {
        self.neighbourhood = neighbourhood;
        self
    }

    /// Checks every field's range.
    ///
    /// # Errors
    /// An invalid-parameter error naming the field ([`Error::invalid_param_name`]):
    /// [`Error::InvalidParam`] when `f_near ∉ (0, 1]` or NaN; [`Error::Core`] (from
    /// [`skin_core::check`]) when `f_min ∉ [0, 1]`, `kernel_width_w ≤ 0`,
    /// `prototype_count_n = 0`, `min_near = 0`, a capped `radius_factor ≤ 0`, or a value is
    /// NaN / infinite.
    pub fn validate(&self) -> Result<()> {
        if !(self.f_near.is_finite() && self.f_near > 0.0 && self.f_near <= 1.0) {
            return Err(Error::InvalidParam {
                name: "f_near",
                reason: format!("must be in (0, 1], got {}", self.f_near),
            });
        }
        check::in_range("f_min", self.f_min, 0.0..=1.0)?;
        check::positive("kernel_width_w", self.kernel_width_w)?;
        check::nonzero("min_near", self.min_near)?;
        check::nonzero("prototype_count_n", self.prototype_count_n)?;
        if let Neighbourhood::Capped { radius_factor } = self.neighbourhood {
            check::positive("radius_factor", radius_factor)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_the_papers_and_valid() {
        let p = ReconstructionParams::default();
        assert_eq!(p.f_near, 0.022);
        assert_eq!(p.f_min, 0.10);
        assert_eq!(p.kernel_width_w, 7.0);
        assert_eq!(p.prototype_count_n, 100);
        assert_eq!(p.min_near, ReconstructionParams::DEFAULT_MIN_NEAR);
        assert_eq!(
            p.neighbourhood,
            Neighbourhood::Capped {
                radius_factor: Neighbourhood::DEFAULT_RADIUS_FACTOR
            }
        );
        p.validate().unwrap();
        p.with_neighbourhood(Neighbourhood::Fraction)
            .validate()
            .unwrap();
    }

    #[test]
    fn bad_values_name_the_field() {
        let d = ReconstructionParams::default();
        let cases = [
            (d.with_f_near(0.0), "f_near"),
            (d.with_f_near(1.5), "f_near"),
            (d.with_f_near(f64::NAN), "f_near"),
            (d.with_f_min(-0.1), "f_min"),
            (d.with_f_min(1.01), "f_min"),
            (d.with_f_min(f64::NAN), "f_min"),
            (d.with_kernel_width_w(0.0), "kernel_width_w"),
            (d.with_kernel_width_w(f64::INFINITY), "kernel_width_w"),
            (d.with_prototype_count_n(0), "prototype_count_n"),
            (d.with_min_near(0), "min_near"),
            (
                d.with_neighbourhood(Neighbourhood::Capped { radius_factor: 0.0 }),
                "radius_factor",
            ),
            (
                d.with_neighbourhood(Neighbourhood::Capped {
                    radius_factor: f64::NAN,
                }),
                "radius_factor",
            ),
        ];
        for (p, field) in cases {
            let e = p.validate().unwrap_err();
            assert_eq!(e.invalid_param_name(), Some(field), "{e}");
        }
        // Boundaries that are valid.
        d.with_f_near(1.0).with_f_min(0.0).validate().unwrap();
        d.with_f_min(1.0)
            .with_prototype_count_n(1)
            .with_min_near(1)
            .validate()
            .unwrap();
    }

    #[test]
    fn serde_round_trip() {
        let p = ReconstructionParams::default()
            .with_f_near(0.05)
            .with_seed(9);
        let s = serde_json::to_string(&p).unwrap();
        let q: ReconstructionParams = serde_json::from_str(&s).unwrap();
        assert_eq!(p, q);
        let f = p.with_neighbourhood(Neighbourhood::Fraction);
        let q: ReconstructionParams =
            serde_json::from_str(&serde_json::to_string(&f).unwrap()).unwrap();
        assert_eq!(f, q);
        // Parameters saved before the neighbourhood existed read as the default.
        let old = s.replace(
            ",\"neighbourhood\":{\"Capped\":{\"radius_factor\":1.0}}",
            "",
        );
        assert_ne!(old, s);
        let q: ReconstructionParams = serde_json::from_str(&old).unwrap();
        assert_eq!(p, q);
    }
}
