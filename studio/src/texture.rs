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
mod tests {
    use super::*;

    /// Albedo samples on a `size`-metre square patch of the plane through `origin` with
    /// normal `n` (a 1 mm grid).
    fn patch(t: &AlbedoTexture, m: Material, origin: DVec3, size: f64) -> Vec<[f32; 3]> {
        let n = (size / 0.001) as usize;
        let mut out = Vec::with_capacity(n * n);
        for i in 0..n {
            for j in 0..n {
                let p = origin
                    + DVec3::new(1.0, 0.2, 0.1).normalize() * (i as f64 * 0.001)
                    + DVec3::new(-0.1, 1.0, 0.3).normalize() * (j as f64 * 0.001);
                out.push(t.eval(m, p));
            }
        }
        out
    }

    /// (mean, std) of the luminance-like mean of the channels.
    fn stats(v: &[[f32; 3]]) -> (f64, f64) {
        let l: Vec<f64> = v
            .iter()
            .map(|c| c.iter().map(|&x| f64::from(x)).sum::<f64>() / 3.0)
            .collect();
        let mean = l.iter().sum::<f64>() / l.len() as f64;
        let var = l.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / l.len() as f64;
        (mean, var.sqrt())
    }

    #[test]
    fn contrast_of_skin_and_print() {
        let t = AlbedoTexture::new(TextureParams::default()).unwrap();
        let mut skin_rel = Vec::new();
        let mut print_rel = Vec::new();
        for (k, origin) in [
            DVec3::new(0.1, 1.2, 0.05),
            DVec3::new(-0.3, 0.5, -0.1),
            DVec3::new(0.0, 0.9, 0.12),
        ]
        .into_iter()
        .enumerate()
        {
            let (m, s) = stats(&patch(&t, Material::Skin, origin, 0.10));
            skin_rel.push(s / m);
            assert!(
                (0.01..0.15).contains(&(s / m)),
                "skin patch {k}: std/mean {}",
                s / m
            );
            let (m, s) = stats(&patch(&t, Material::Garment, origin, 0.10));
            print_rel.push(s / m);
            assert!(s / m > 0.4, "print patch {k}: std/mean {}", s / m);
            // Everything physical.
            assert!(patch(&t, Material::Garment, origin, 0.02)
                .iter()
                .chain(&patch(&t, Material::Skin, origin, 0.02))
                .flatten()
                .all(|x| (0.0..=1.0).contains(x)));
        }
        eprintln!("texture contrast std/mean: skin {skin_rel:.3?}, print {print_rel:.3?}");
        // The skin varies smoothly (freckle edges aside): millimetre neighbours differ little.
        let s = patch(&t, Material::Skin, DVec3::new(0.1, 1.2, 0.05), 0.05);
        let mut steps: Vec<f32> = s
            .chunks(50)
            .flat_map(|row| row.windows(2).map(|w| (w[0][0] - w[1][0]).abs()))
            .collect();
        steps.sort_by(f32::total_cmp);
        let (median, max) = (steps[steps.len() / 2], steps[steps.len() - 1]);
        assert!(median < 0.01 && max < 0.2, "{median} {max}");
        // The check print is two colours.
        let check = AlbedoTexture::new(TextureParams {
            print: Print::Check,
            ..TextureParams::default()
        })
        .unwrap();
        let (m, s) = stats(&patch(
            &check,
            Material::Garment,
            DVec3::new(0.1, 1.2, 0.05),
            0.1,
        ));
        assert!(s / m > 0.5, "{}", s / m);
    }

    #[test]
    fn deterministic_and_seeded() {
        let a = AlbedoTexture::new(TextureParams::default()).unwrap();
        let b = AlbedoTexture::new(TextureParams::default()).unwrap();
        let c = AlbedoTexture::new(TextureParams {
            seed: 9,
            ..TextureParams::default()
        })
        .unwrap();
        let o = DVec3::new(0.05, 1.0, 0.1);
        for m in [Material::Skin, Material::Garment] {
            assert_eq!(patch(&a, m, o, 0.03), patch(&b, m, o, 0.03));
            assert_ne!(patch(&a, m, o, 0.03), patch(&c, m, o, 0.03));
        }
        let pos = vec![o, o + DVec3::X * 0.01];
        let v = a
            .per_vertex(&pos, &[Material::Skin, Material::Garment])
            .unwrap();
        assert_eq!(v[0], a.skin(pos[0]));
        assert_eq!(v[1], a.garment(pos[1]));
    }

    #[test]
    fn rejects_bad_input() {
        let d = TextureParams::default();
        for bad in [
            TextureParams {
                skin_albedo: [1.2, 0.5, 0.5],
                ..d
            },
            TextureParams {
                garment_inks: [[f32::NAN, 0.0, 0.0], [0.0; 3]],
                ..d
            },
            TextureParams {
                skin_variation: -0.1,
                ..d
            },
            TextureParams {
                print_period_m: 0.0,
                ..d
            },
            TextureParams {
                blotch_scale_m: f64::INFINITY,
                ..d
            },
        ] {
            assert!(matches!(
                AlbedoTexture::new(bad),
                Err(Error::InvalidParam { .. })
            ));
        }
        let t = AlbedoTexture::new(d).unwrap();
        assert!(matches!(
            t.per_vertex(&[DVec3::ZERO], &[]),
            Err(Error::SizeMismatch { .. })
        ));
        assert!(matches!(
            t.per_vertex(&[DVec3::NAN], &[Material::Skin]),
            Err(Error::NonFinite { .. })
        ));
    }
    #[test]
    fn shades_through_albedo_textured() {
        use crate::shading::{shade, Albedo, Light, Shadows};
        use skin_core::camera::{Camera, Intrinsics};
        use skin_core::raster::{Buffers, Rasterizer, RenderParams};
        let ball =
            skin_core::mesh::shapes::uv_sphere(DVec3::new(0.0, 1.0, 0.0), 0.15, 24, 36).unwrap();
        let k = Intrinsics::from_horizontal_fov(0.5, 96, 96).unwrap();
        let cam = Camera::look_at(
            k,
            DVec3::new(0.0, 1.0, 1.0),
            DVec3::new(0.0, 1.0, 0.0),
            DVec3::Y,
        )
        .unwrap();
        let params = RenderParams::default().with_buffers(Buffers {
            triangle: true,
            ..Buffers::default()
        });
        let view = Rasterizer::new(&cam).render(&ball, &params).unwrap();
        let lights = [Light::Area {
            position: DVec3::new(0.0, 1.0, 3.0),
            normal: DVec3::NEG_Z,
            area_m2: 0.01,
            radiance: 300.0,
        }];
        let t = AlbedoTexture::new(TextureParams::default()).unwrap();
        // Upper half printed cloth, lower half skin.
        let materials: Vec<Material> = (0..ball.face_count())
            .map(|f| {
                if ball.triangle(f).iter().map(|v| v.y).sum::<f64>() > 3.0 {
                    Material::Garment
                } else {
                    Material::Skin
                }
            })
            .collect();
        let albedo = Albedo::Textured {
            rest_positions: &ball.vertices,
            face_materials: &materials,
            texture: &t,
        };
        assert!(format!("{albedo:?}").contains("Textured"));
        let s = shade(&view, &ball, &lights, &albedo, &Shadows::None).unwrap();
        let lum = |r: &[f32; 3]| f64::from(r[0] + r[1] + r[2]);
        let half = |upper: bool| {
            let v: Vec<[f32; 3]> = (0..96 * 96)
                .filter(|&i| s.radiance[i][0] > 0.0 && ((i / 96) < 48) == upper)
                .map(|i| s.radiance[i])
                .collect();
            stats(&v)
        };
        let ((mg, sg), (ms, ss)) = (half(true), half(false));
        assert!(
            sg / mg > 2.0 * ss / ms,
            "print {} vs skin {}",
            sg / mg,
            ss / ms
        );
        assert!(s.radiance.iter().any(|r| lum(r) > 0.0));
        // Wrong sizes are errors.
        let bad = Albedo::Textured {
            rest_positions: &ball.vertices,
            face_materials: &materials[1..],
            texture: &t,
        };
        assert!(shade(&view, &ball, &lights, &bad, &Shadows::None).is_err());
        let bad = Albedo::Textured {
            rest_positions: &ball.vertices[1..],
            face_materials: &materials,
            texture: &t,
        };
        assert!(shade(&view, &ball, &lights, &bad, &Shadows::None).is_err());
    }
}
