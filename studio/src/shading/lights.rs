//! Point and area lights.

use serde::{Deserialize, Serialize};

use skin_core::math::DVec3;
use skin_core::{Error, Result};

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
        PreparedLight::new(self).irradiance(p, n)
    }
}

/// A light with its constants folded for the per-pixel loop.
#[derive(Debug, Clone, Copy)]
pub(crate) struct PreparedLight {
    position: DVec3,
    /// Unit emitting direction (area lights), zero for point lights.
    normal: DVec3,
    /// Intensity (point) or radiance × area (area).
    power: f64,
    area: bool,
}

impl PreparedLight {
    pub(crate) fn new(light: &Light) -> Self {
        match *light {
            Light::Point {
                position,
                intensity,
            } => Self {
                position,
                normal: DVec3::ZERO,
                power: intensity,
                area: false,
            },
            Light::Area {
                position,
                normal,
                area_m2,
                radiance,
            } => Self {
                position,
                normal: normal.normalize_or_zero(),
                power: radiance * area_m2,
                area: true,
            },
        }
    }

    /// As [`Light::irradiance`].
    #[inline]
    pub(crate) fn irradiance(&self, p: DVec3, n: DVec3) -> f64 {
        let d = self.position - p;
        let cos_s = n.dot(d);
        if cos_s <= 0.0 {
            return 0.0;
        }
        let r2 = d.length_squared();
        let r = r2.sqrt();
        let mut e = self.power * cos_s / (r2 * r);
        if self.area {
            let cos_l = -self.normal.dot(d);
            if cos_l <= 0.0 {
                return 0.0;
            }
            e *= cos_l / r;
        }
        e
    }
}

#[cfg(test)]
impl Light {
    /// The formulas of the module docs written out directly (test oracle for the folded form).
    fn irradiance_reference(&self, p: DVec3, n: DVec3) -> f64 {
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

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn folded_irradiance_matches_reference(
            lx in -3.0f64..3.0, ly in -3.0f64..3.0, lz in -3.0f64..3.0,
            nx in -1.0f64..1.0, ny in -1.0f64..1.0, nz in 0.1f64..1.0,
            px in -1.0f64..1.0, area in prop::bool::ANY,
        ) {
            let pos = DVec3::new(lx, ly, lz);
            let light = if area {
                Light::Area { position: pos, normal: DVec3::new(ny, nx, -nz) * 2.0, area_m2: 0.02, radiance: 3.0 }
            } else {
                Light::Point { position: pos, intensity: 2.5 }
            };
            let n = DVec3::new(nx, nz, ny).normalize();
            let p = DVec3::new(px, 0.2, -px);
            let (a, b) = (light.irradiance(p, n), light.irradiance_reference(p, n));
            prop_assert!((a - b).abs() <= 1e-12 * b.abs().max(1e-12), "{a} vs {b}");
            prop_assert!(a >= 0.0);
        }
    }

    #[test]
    fn validation() {
        let ok = Light::Point {
            position: DVec3::ONE,
            intensity: 1.0,
        };
        assert!(ok.validate().is_ok());
        let neg = Light::Point {
            position: DVec3::ONE,
            intensity: -1.0,
        };
        assert!(matches!(neg.validate(), Err(Error::InvalidParam { .. })));
        let flat = Light::Area {
            position: DVec3::ONE,
            normal: DVec3::Y,
            area_m2: 0.0,
            radiance: 1.0,
        };
        assert!(matches!(flat.validate(), Err(Error::InvalidParam { .. })));
        let nan = Light::Area {
            position: DVec3::ONE,
            normal: DVec3::NAN,
            area_m2: 1.0,
            radiance: 1.0,
        };
        assert!(matches!(nan.validate(), Err(Error::NonFinite { .. })));
    }
}
