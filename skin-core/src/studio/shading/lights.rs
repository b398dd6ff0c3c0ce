//! Point and area lights.

use serde::{Deserialize, Serialize};

use crate::math::DVec3;
use crate::{Error, Result};

/// A white light source at its real position (world frame, m).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum Light {
    /// Isotropic point light.
    Point {
        /// Position, world frame, m.
        position: DVec3,
        /// Radiant intensity, W/sr (any consistent unit).
        intensity: f64,
    },
    /// Small one-sided Lambertian emitter (an LED panel of the dome), treated in the
    /// small-source limit (module docs).
    Area {
        /// Centre, world frame, m.
        position: DVec3,
        /// Unit emitting direction, world frame (normalised on use).
        normal: DVec3,
        /// Emitting area, m².
        area_m2: f64,
        /// Radiance, W·m⁻²·sr⁻¹ (any consistent unit).
        radiance: f64,
    },
}

impl Light {
    /// Position, world frame, m.
    pub fn position(&self) -> DVec3 {
        match *self {
            Light::Point { position, .. } | Light::Area { position, .. } => position,
        }
    }

    /// Checks finiteness, non-negative power, positive area and a non-zero normal.
    ///
    /// # Errors
    /// [`Error::NonFinite`] or [`Error::InvalidParam`].
    pub fn validate(&self) -> Result<()> {
        let (pos, power) = match *self {
            Light::Point {
                position,
                intensity,
            } => (position, intensity),
            Light::Area {
                position,
                normal,
                area_m2,
                radiance,
            } => {
                if !(normal.is_finite() && area_m2.is_finite()) {
                    return Err(Error::NonFinite { what: "area light" });
                }
                if normal.length_squared() == 0.0 || area_m2 <= 0.0 {
                    return Err(Error::InvalidParam {
                        name: "area light",
                        reason: format!(
                            "needs a non-zero normal and area > 0, got {normal} and {area_m2}"
                        ),
                    });
                }
                (position, radiance)
            }
        };
        if !(pos.is_finite() && power.is_finite()) {
            return Err(Error::NonFinite { what: "light" });
        }
        if power < 0.0 {
            return Err(Error::InvalidParam {
                name: "light power",
                reason: format!("must be >= 0, got {power}"),
            });
        }
        Ok(())
    }

    /// Unshadowed irradiance at `p` on a surface with unit normal `n` (W/m²; module docs).
    /// Zero when the light is below the surface's tangent plane (or `p` behind an area light).
    pub fn irradiance(&self, p: DVec3, n: DVec3) -> f64 {
        let d = self.position() - p;
        let r2 = d.length_squared();
        if r2 == 0.0 {
            return 0.0;
        }
        let cos_s = n.dot(d);
        if cos_s <= 0.0 {
            return 0.0;
        }
        let r = r2.sqrt();
        let cos_s = cos_s / r;
        match *self {
            Light::Point { intensity, .. } => intensity * cos_s / r2,
            Light::Area {
                normal,
                area_m2,
                radiance,
                ..
            } => {
                let cos_l = -normal.normalize_or_zero().dot(d) / r;
                if cos_l <= 0.0 {
                    0.0
                } else {
                    radiance * area_m2 * cos_l * cos_s / r2
                }
            }
        }
    }
}
