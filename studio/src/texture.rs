//! **Albedo texture**: a non-uniform reflectance for the shaded observations, so that optical
//! flow and photometric matching have something to lock on. Evaluated at rest-pose positions
//! (3-D solid textures: no UV map needed, and the pattern moves with the surface), with a
//! material per face ([`Material`]):
//!
//! * **Skin**: the base tone modulated by low-contrast smooth value noise (blotches of
//!   [`TextureParams::blotch_scale_m`], ±[`TextureParams::skin_variation`]) and sparse darker
//!   freckles ([`TextureParams::freckle_scale_m`]); std/mean of the albedo over a patch is a
//!   few per cent.
//! * **Garment**: a high-contrast print at [`TextureParams::print_period_m`]: jittered dots of
//!   varied size and two ink colours on a dark ground ([`Print::Dots`], the slice of random
//!   spheres by the surface, so dots differ in size like a floral print), or a 3-D check
//!   ([`Print::Check`]).
//!
//! Everything is a pure function of the position and [`TextureParams::seed`] (lattice values
//! hashed with [`SplitMix64`]): deterministic, thread-safe, no tables.

use serde::{Deserialize, Serialize};

use skin_core::check;
use skin_core::math::DVec3;
use skin_core::random::SplitMix64;
use skin_core::{Error, Result};

/// The material of a surface element.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Material {
    /// Skin: [`AlbedoTexture::skin`].
    Skin,
    /// The garment's printed cloth: [`AlbedoTexture::garment`].
    Garment,
}

/// The garment's print.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Print {
    /// Jittered dots (random radius, one of two inks) on the ground colour.
    Dots,
    /// A 3-D check of the ground and the first ink.
    Check,
}

/// Parameters of [`AlbedoTexture`]. Colours are linear RGB in `[0, 1]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TextureParams {
    /// Seed of the noise and the print's jitter. Default: 0.
    pub seed: u64,
    /// Mean skin albedo. Default: `[0.8, 0.6, 0.5]` (the capture's uniform default).
    pub skin_albedo: [f32; 3],
    /// Relative amplitude of the smooth skin blotches, in `[0, 1]`. Default: 0.10.
    pub skin_variation: f32,
    /// Size of the skin blotches (noise lattice spacing), m, > 0. Default: 0.04.
    pub blotch_scale_m: f64,
    /// Size of the freckles (noise lattice spacing), m, > 0. Default: 0.012.
    pub freckle_scale_m: f64,
    /// How much darker a freckle's centre is, in `[0, 1]`. Default: 0.2.
    pub freckle_darkening: f32,
    /// The garment's print. Default: [`Print::Dots`].
    pub print: Print,
    /// Print period (dot spacing, check size), m, > 0. Default: 0.035.
    pub print_period_m: f64,
    /// Ground colour of the cloth. Default: navy `[0.05, 0.07, 0.25]`.
    pub garment_ground: [f32; 3],
    /// Ink colours of the print. Default: cream `[0.85, 0.8, 0.6]` and red `[0.75, 0.12, 0.1]`.
    pub garment_inks: [[f32; 3]; 2],
}

impl Default for TextureParams {
    fn default() -> Self {
        Self {
            seed: 0,
            skin_albedo: [0.8, 0.6, 0.5],
            skin_variation: 0.10,
            blotch_scale_m: 0.04,
            freckle_scale_m: 0.012,
            freckle_darkening: 0.2,
            print: Print::Dots,
            print_period_m: 0.035,
            garment_ground: [0.05, 0.07, 0.25],
            garment_inks: [[0.85, 0.8, 0.6], [0.75, 0.12, 0.1]],
        }
    }
}

/// A validated albedo texture ([`TextureParams`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct AlbedoTexture {
    params: TextureParams,
}

fn colour(name: &'static str, c: [f32; 3]) -> Result<()> {
    for v in c {
        check::in_range(name, f64::from(v), 0.0..=1.0)?;
    }
    Ok(())
}

/// Quintic fade `6t⁵ − 15t⁴ + 10t³` (C² value-noise interpolation).
fn fade(t: f64) -> f64 {
    t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
}

fn smoothstep(x: f64) -> f64 {
    let x = x.clamp(0.0, 1.0);
    x * x * (3.0 - 2.0 * x)
}

impl AlbedoTexture {
    /// Checks and wraps the parameters.
    ///
    /// # Errors
    /// [`Error::InvalidParam`] for a colour or fraction outside `[0, 1]` (or NaN), a
    /// non-positive or non-finite scale or period.
    pub fn new(params: TextureParams) -> Result<Self> {
        colour("skin_albedo", params.skin_albedo)?;
        colour("garment_ground", params.garment_ground)?;
        for ink in params.garment_inks {
            colour("garment_inks", ink)?;
        }
        check::in_range(
            "skin_variation",
            f64::from(params.skin_variation),
            0.0..=1.0,
        )?;
        check::in_range(
            "freckle_darkening",
            f64::from(params.freckle_darkening),
            0.0..=1.0,
        )?;
        check::positive("blotch_scale_m", params.blotch_scale_m)?;
        check::positive("freckle_scale_m", params.freckle_scale_m)?;
        check::positive("print_period_m", params.print_period_m)?;
        Ok(Self { params })
    }

    /// The parameters.
    pub fn params(&self) -> &TextureParams {
        &self.params
    }

    /// Uniform in `[0, 1)` for lattice cell `c` and stream `k`.
    fn hash(&self, c: [i64; 3], k: u64) -> f64 {
        let i = (c[0] as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
            ^ (c[1] as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
            ^ (c[2] as u64).wrapping_mul(0x1656_67B1_9E37_79F9)
            ^ k.wrapping_mul(0xD6E8_FEB8_6659_FD93);
        SplitMix64::new(self.params.seed).uniform_at(i)
    }

    /// Smooth value noise in `[-1, 1]` on a lattice of spacing 1 (stream `k`).
    fn noise(&self, p: DVec3, k: u64) -> f64 {
        let f = p.floor();
        let t = (p - f).to_array().map(fade);
        let c = [f.x as i64, f.y as i64, f.z as i64];
        let mut acc = 0.0;
        for corner in 0..8 {
            let o = [corner & 1, (corner >> 1) & 1, (corner >> 2) & 1];
            let w: f64 = (0..3)
                .map(|a| if o[a] == 1 { t[a] } else { 1.0 - t[a] })
                .product();
            let v = self.hash([c[0] + o[0], c[1] + o[1], c[2] + o[2]], k);
            acc += w * (2.0 * v - 1.0);
        }
        acc
    }

    /// Skin albedo at rest position `p` (m).
    pub fn skin(&self, p: DVec3) -> [f32; 3] {
        let q = &self.params;
        let blotch = 0.7 * self.noise(p / q.blotch_scale_m, 1)
            + 0.3 * self.noise(p / (0.5 * q.blotch_scale_m), 2);
        let freckle = smoothstep((self.noise(p / q.freckle_scale_m, 3) - 0.35) / 0.25);
        let m = (1.0 + f64::from(q.skin_variation) * blotch) as f32;
        let dark = q.freckle_darkening * freckle as f32;
        // Freckles are brown: they darken blue most, red least.
        let tint = [0.8, 1.0, 1.2];
        std::array::from_fn(|c| (q.skin_albedo[c] * m * (1.0 - dark * tint[c])).clamp(0.0, 1.0))
    }

    /// Garment albedo at rest position `p` (m).
    pub fn garment(&self, p: DVec3) -> [f32; 3] {
        let q = &self.params;
        let x = p / q.print_period_m;
        let ground = q.garment_ground;
        match q.print {
            Print::Check => {
                let s = (std::f64::consts::PI * x).to_array().map(f64::sin);
                if s[0] * s[1] * s[2] >= 0.0 {
                    q.garment_inks[0]
                } else {
                    ground
                }
            }
            Print::Dots => {
                // Nearest jittered dot centre among the 27 cells around p (Worley).
                let f = x.floor();
                let c = [f.x as i64, f.y as i64, f.z as i64];
                let mut best = (f64::INFINITY, 0.0, 0usize);
                for dx in -1..=1 {
                    for dy in -1..=1 {
                        for dz in -1..=1 {
                            let cell = [c[0] + dx, c[1] + dy, c[2] + dz];
                            let centre = DVec3::new(
                                cell[0] as f64 + 0.2 + 0.6 * self.hash(cell, 10),
                                cell[1] as f64 + 0.2 + 0.6 * self.hash(cell, 11),
                                cell[2] as f64 + 0.2 + 0.6 * self.hash(cell, 12),
                            );
                            let radius = 0.25 + 0.2 * self.hash(cell, 13);
                            let d = x.distance(centre) - radius;
                            if d < best.0 {
                                let ink = usize::from(self.hash(cell, 14) >= 0.5);
                                best = (d, radius, ink);
                            }
                        }
                    }
                }
                // A 1 mm soft edge keeps the print free of staircase aliasing.
                let edge = (0.001 / q.print_period_m).max(1e-6);
                let t = smoothstep(0.5 - best.0 / edge) as f32;
                let ink = q.garment_inks[best.2];
                std::array::from_fn(|k| ground[k] + (ink[k] - ground[k]) * t)
            }
        }
    }

    /// Albedo of `material` at rest position `p` (m).
    pub fn eval(&self, material: Material, p: DVec3) -> [f32; 3] {
        match material {
            Material::Skin => self.skin(p),
            Material::Garment => self.garment(p),
        }
    }

    /// Per-vertex albedo (e.g. for [`crate::shading::Albedo::PerVertex`]).
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] unless there is one material per position;
    /// [`Error::NonFinite`] for a non-finite position.
    pub fn per_vertex(
        &self,
        rest_positions: &[DVec3],
        materials: &[Material],
    ) -> Result<Vec<[f32; 3]>> {
        check::same_size(
            "materials vs rest positions",
            rest_positions.len(),
            materials.len(),
        )?;
        if !rest_positions.iter().all(|p| p.is_finite()) {
            return Err(Error::NonFinite {
                what: "rest positions",
            });
        }
        Ok(rest_positions
            .iter()
            .zip(materials)
            .map(|(p, m)| self.eval(*m, *p))
            .collect())
    }
}

#[cfg(test)]
mod tests;
