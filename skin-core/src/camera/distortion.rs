//! First-order radial distortion about its own centre, `D_{c,r}` of Sand 2003 §4.1.
//!
//! Sand minimises `Σᵢ ‖pᵢ − D_{c,r}(P wᵢ)‖` where `D_{c,r}` "describes first-order radial
//! distortion (with center of distortion c and a distortion coefficient r)". The thesis gives no
//! formula; we use the standard first-order model, with the radius measured in focal-length
//! units so that `k1` is dimensionless and equals OpenCV's `k1` when `c` is the principal point:
//!
//! ```text
//! s = ((u − c_x)/f_x, (v − c_y)/f_y),   D(u, v) = c + (u − c, v − c_y)·(1 + k1·‖s‖²)
//! ```
//!
//! `(u, v)` is the undistorted (pinhole) pixel and `D(u, v)` the observed one. The distortion
//! centre `c` is a parameter separate from the principal point (real lenses are not centred on
//! the sensor). For `k1 < 0` (barrel) the map folds back at `‖s‖² = 1/(3|k1|)`; beyond it the
//! model is not invertible and [`RadialDistortion::distort`] reports the point as invalid.

use serde::{Deserialize, Serialize};

use super::intrinsics::Intrinsics;
use crate::error::{Error, Result};
use crate::math::DVec2;

/// Newton iterations for inverting the radial cubic (converges monotonically; 50 is far more
/// than the ~6 needed to reach rounding error).
const MAX_UNDISTORT_ITERATIONS: usize = 50;

/// First-order radial distortion with its own centre (Sand 2003 §4.1, model in the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct RadialDistortion {
    /// Dimensionless coefficient `k1` (Sand's `r`), radius in focal-length units; `< 0` barrel,
    /// `> 0` pincushion. Default: 0 (no distortion).
    pub k1: f64,
    /// Centre of distortion `c`, px (Sand's `c`). Irrelevant when `k1 = 0`. Default: (0, 0).
    pub centre: DVec2,
}

impl RadialDistortion {
    /// No distortion.
    pub const NONE: Self = Self {
        k1: 0.0,
        centre: DVec2::ZERO,
    };

    /// Distortion `k1` about `centre` (px).
    pub fn new(k1: f64, centre: DVec2) -> Self {
        Self { k1, centre }
    }

    /// Largest normalised radius `‖s‖` the model maps one-to-one: `1/√(3|k1|)` for `k1 < 0`,
    /// infinity otherwise.
    pub fn max_radius(&self) -> f64 {
        if self.k1 < 0.0 {
            1.0 / (3.0 * -self.k1).sqrt()
        } else {
            f64::INFINITY
        }
    }

    /// Distorted (observed) pixel of an undistorted pixel, or `None` beyond
    /// [`RadialDistortion::max_radius`] where the model folds back.
    pub fn distort(&self, k: &Intrinsics, undistorted: DVec2) -> Option<DVec2> {
        let d = undistorted - self.centre;
        let s = DVec2::new(d.x / k.fx, d.y / k.fy);
        let rho2 = s.length_squared();
        if self.k1 < 0.0 && rho2 * 3.0 * -self.k1 > 1.0 {
            return None;
        }
        Some(self.centre + d * (1.0 + self.k1 * rho2))
    }

    /// Undistorted pixel of an observed pixel: solves `t(1 + k1 t²) = ρ_d` for the undistorted
    /// normalised radius `t` by Newton's method (monotone convergence from `t = ρ_d`: the cubic
    /// is convex for `k1 > 0` and concave below the fold for `k1 < 0`).
    ///
    /// # Errors
    /// [`Error::NonFinite`] for a non-finite pixel; [`Error::NotVisible`] if the pixel lies
    /// beyond the largest distorted radius `⅔·max_radius` a barrel model can produce.
    pub fn undistort(&self, k: &Intrinsics, distorted: DVec2) -> Result<DVec2> {
        if !distorted.is_finite() {
            return Err(Error::NonFinite {
                what: "distorted pixel",
            });
        }
        let d = distorted - self.centre;
        let s = DVec2::new(d.x / k.fx, d.y / k.fy);
        let rho = s.length();
        if self.k1 == 0.0 || rho == 0.0 {
            return Ok(distorted);
        }
        let t_max = self.max_radius();
        if self.k1 < 0.0 && rho >= t_max * (1.0 + self.k1 * t_max * t_max) {
            return Err(Error::NotVisible {
                what: format!(
                    "pixel {distorted} is outside the range of the barrel distortion model"
                ),
            });
        }
        let mut t = rho;
        for _ in 0..MAX_UNDISTORT_ITERATIONS {
            let f = t * (1.0 + self.k1 * t * t) - rho;
            let step = f / (1.0 + 3.0 * self.k1 * t * t);
            t -= step;
            if step.abs() <= 1e-16 * t.abs().max(1e-300) {
                break;
            }
        }
        Ok(self.centre + d * (t / rho))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn k() -> Intrinsics {
        Intrinsics::new(900.0, 920.0, 640.0, 480.0, 1280, 960).unwrap()
    }

    proptest! {
        #[test]
        fn undistort_inverts_distort(k1 in -0.3f64..0.3, cx in 500.0f64..700.0, cy in 400.0f64..560.0,
                                     u in 0.0f64..1280.0, v in 0.0f64..960.0) {
            let d = RadialDistortion::new(k1, DVec2::new(cx, cy));
            let p = DVec2::new(u, v);
            if let Some(q) = d.distort(&k(), p) {
                let back = d.undistort(&k(), q).unwrap();
                prop_assert!((back - p).length() < 1e-8, "{p} -> {q} -> {back}");
            } else {
                prop_assert!(k1 < 0.0);
            }
        }
    }

    #[test]
    fn centre_is_fixed_and_k1_zero_is_identity() {
        let d = RadialDistortion::new(-0.2, DVec2::new(600.0, 500.0));
        assert_eq!(d.distort(&k(), d.centre), Some(d.centre));
        let p = DVec2::new(3.0, 7.0);
        assert_eq!(RadialDistortion::NONE.distort(&k(), p), Some(p));
        // Barrel: points move towards the centre.
        let q = d.distort(&k(), DVec2::new(1000.0, 500.0)).unwrap();
        assert!(q.x < 1000.0 && (q.y - 500.0).abs() < 1e-12);
    }

    #[test]
    fn beyond_the_fold_is_an_error() {
        let d = RadialDistortion::new(-0.5, DVec2::new(640.0, 480.0));
        assert_eq!(d.distort(&k(), DVec2::new(640.0 + 900.0, 480.0)), None);
        assert!(matches!(
            d.undistort(&k(), DVec2::new(640.0 + 900.0, 480.0)),
            Err(Error::NotVisible { .. })
        ));
        assert!(matches!(
            d.undistort(&k(), DVec2::new(f64::NAN, 0.0)),
            Err(Error::NonFinite { .. })
        ));
    }
}
