//! The light-stage dome of Vlasic thesis §3.2.1: "the top two-thirds of an 8-meter,
//! 6th-frequency geodesic sphere with 1,200 regularly-spaced individually controllable light
//! sources, of which 901 are on the sphere and the rest are placed on the floor. A central area
//! is reserved for the subject, and therefore it does not contain any floor lights."
//!
//! The thesis gives no coordinates. The sphere lights sit on a Fibonacci lattice of the
//! spherical zone (area-uniform, as regular as a geodesic subdivision to within a few percent
//! of spacing, and available for any count) and the floor lights on a sunflower lattice of the
//! floor annulus between the reserved central area and the dome's rim. Each light is an area
//! light facing the dome centre (sphere) or straight up (floor) whose area is its share of the
//! surface, so the dome approximates a continuous emitter of the given radiance.

use serde::{Deserialize, Serialize};

use super::lights::Light;
use skin_core::math::DVec3;
use skin_core::{Error, Result};

/// Golden angle, rad.
const GOLDEN_ANGLE: f64 = 2.399_963_229_728_653;

/// Geometry and power of the dome.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct DomeParams {
    /// Sphere radius, m. Default: 4 (the 8-metre sphere of Vlasic §3.2.1).
    pub radius_m: f64,
    /// Lights on the sphere. Default: 901 (Vlasic §3.2.1).
    pub sphere_lights: usize,
    /// Lights on the floor. Default: 299 (1,200 − 901, Vlasic §3.2.1).
    pub floor_lights: usize,
    /// Fraction of the sphere's height kept above the floor. Default: 2/3 ("top two-thirds").
    pub height_fraction: f64,
    /// Radius of the floor area reserved for the subject (no floor lights), m. Default: 1.5
    /// (not given in the thesis; a performance area of about 3 m).
    pub clear_radius_m: f64,
    /// Centre of the performance area on the floor, world frame, m. Default: origin.
    pub floor_centre: DVec3,
    /// World up direction. Default: +Y.
    pub up: DVec3,
    /// Radiance of every light, W·m⁻²·sr⁻¹. Default: 1/π (a white patch facing up at the centre
    /// then reflects radiance ≈ 1/π·(irradiance from the upper sphere) ≈ 1/π).
    pub radiance: f64,
}

impl Default for DomeParams {
    fn default() -> Self {
        Self {
            radius_m: 4.0,
            sphere_lights: 901,
            floor_lights: 299,
            height_fraction: 2.0 / 3.0,
            clear_radius_m: 1.5,
            floor_centre: DVec3::ZERO,
            up: DVec3::Y,
            radiance: std::f64::consts::FRAC_1_PI,
        }
    }
}

/// The dome's lights: first the sphere lights from the top down, then the floor lights from
/// the inside out.
///
/// # Errors
/// [`Error::NonFinite`] for non-finite input; [`Error::InvalidParam`] for a non-positive
/// radius, a height fraction outside `(0, 1]`, a zero `up`, no lights, or a clear radius that
/// leaves no floor for floor lights.
pub fn dome_lights(p: &DomeParams) -> Result<Vec<Light>> {
    skin_core::check::all_finite(
        "dome params",
        [
            &p.radius_m,
            &p.height_fraction,
            &p.clear_radius_m,
            &p.radiance,
            &p.floor_centre.x,
            &p.floor_centre.y,
            &p.floor_centre.z,
            &p.up.x,
            &p.up.y,
            &p.up.z,
        ],
    )?;
    let bad = |name: &'static str, reason: String| Err(Error::InvalidParam { name, reason });
    if p.radius_m <= 0.0 {
        return bad("radius_m", format!("must be > 0, got {}", p.radius_m));
    }
    if !(p.height_fraction > 0.0 && p.height_fraction <= 1.0) {
        return bad(
            "height_fraction",
            format!("must be in (0, 1], got {}", p.height_fraction),
        );
    }
    if p.sphere_lights + p.floor_lights == 0 {
        return bad("sphere_lights", "the dome needs at least one light".into());
    }
    if p.radiance < 0.0 {
        return bad("radiance", format!("must be >= 0, got {}", p.radiance));
    }
    let Some(up) = p.up.try_normalize() else {
        return bad("up", "must be non-zero".into());
    };
    let r = p.radius_m;
    // Sphere heights (units of r, from its centre) run over [h_min, 1]; the floor is at h_min.
    let h_min = 1.0 - 2.0 * p.height_fraction;
    let centre = p.floor_centre - up * (h_min * r);
    let e1 = up.any_orthonormal_vector();
    let e2 = up.cross(e1);
    let mut lights = Vec::with_capacity(p.sphere_lights + p.floor_lights);
    let ns = p.sphere_lights;
    let zone_area = std::f64::consts::TAU * r * r * (1.0 - h_min);
    for i in 0..ns {
        let h = 1.0 - (i as f64 + 0.5) / ns as f64 * (1.0 - h_min);
        let s = (1.0 - h * h).max(0.0).sqrt();
        let phi = GOLDEN_ANGLE * i as f64;
        let dir = up * h + (e1 * phi.cos() + e2 * phi.sin()) * s;
        lights.push(Light::Area {
            position: centre + dir * r,
            normal: -dir,
            area_m2: zone_area / ns as f64,
            radiance: p.radiance,
        });
    }
    let nf = p.floor_lights;
    if nf > 0 {
        let rim = r * (1.0 - h_min * h_min).max(0.0).sqrt();
        if p.clear_radius_m < 0.0 || p.clear_radius_m >= rim {
            return bad(
                "clear_radius_m",
                format!(
                    "must be in [0, {rim}) (the dome's floor radius), got {}",
                    p.clear_radius_m
                ),
            );
        }
        let (a2, b2) = (p.clear_radius_m.powi(2), rim * rim);
        let area = std::f64::consts::PI * (b2 - a2);
        for i in 0..nf {
            let rad = (a2 + (b2 - a2) * (i as f64 + 0.5) / nf as f64).sqrt();
            let phi = GOLDEN_ANGLE * i as f64;
            lights.push(Light::Area {
                position: p.floor_centre + (e1 * phi.cos() + e2 * phi.sin()) * rad,
                normal: up,
                area_m2: area / nf as f64,
                radiance: p.radiance,
            });
        }
    }
    Ok(lights)
}
