//! Per-pixel Lambertian shading of a rendered view (radiometry in the module docs of
//! [`super`]).

use image::{Rgb, Rgb32FImage, RgbImage};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::lights::{Light, PreparedLight};
use super::visibility::{check_lights_outside, unoccluded, LightVisibility};
use crate::{AlbedoTexture, Material};
use skin_core::math::DVec3;
use skin_core::mesh::{vertex_normals, MeshQuery, NormalWeighting, TriMesh};
use skin_core::raster::{RenderedView, NO_TRIANGLE};
use skin_core::{Error, Result};

/// Surface reflectance `ρ` (linear RGB, each in `[0, 1]` for a physical surface), evaluated per
/// pixel at the visible surface point.
#[derive(Clone, Copy)]
pub enum Albedo<'a> {
    /// One albedo everywhere.
    Uniform([f32; 3]),
    /// One albedo per mesh vertex, interpolated with the perspective-correct barycentrics.
    PerVertex(&'a [[f32; 3]]),
    /// A texture evaluated per pixel at the rest-pose position of the visible point: the
    /// barycentric interpolation of `rest_positions` (one per vertex, the performer's rest
    /// pose). The texture then moves with the skin, as real skin texture does, which is what
    /// optical flow and photometric matching need.
    Procedural {
        /// Rest-pose position of every vertex, m.
        rest_positions: &'a [DVec3],
        /// Albedo at a rest-pose position.
        texture: &'a (dyn Fn(DVec3) -> [f32; 3] + Sync),
    },
    /// The studio's [`AlbedoTexture`] evaluated per pixel at the rest-pose position of the
    /// visible point (as [`Albedo::Procedural`]), with one [`Material`] per face (skin or
    /// printed garment; no blending across a material boundary).
    Textured {
        /// Rest-pose position of every vertex, m (e.g.
        /// [`crate::FineSurface::rest_positions`]).
        rest_positions: &'a [DVec3],
        /// Material of every face.
        face_materials: &'a [Material],
        /// The texture.
        texture: &'a AlbedoTexture,
    },
}

impl std::fmt::Debug for Albedo<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Albedo::Uniform(a) => f.debug_tuple("Uniform").field(a).finish(),
            Albedo::PerVertex(a) => write!(f, "PerVertex({} vertices)", a.len()),
            Albedo::Procedural { rest_positions, .. } => {
                write!(f, "Procedural({} rest positions)", rest_positions.len())
            }
            Albedo::Textured {
                rest_positions,
                face_materials,
                texture,
            } => write!(
                f,
                "Textured({} rest positions, {} faces, {:?})",
                rest_positions.len(),
                face_materials.len(),
                texture.params().print
            ),
        }
    }
}

/// How cast shadows are computed.
#[derive(Debug, Clone, Copy)]
pub enum Shadows<'a> {
    /// No cast shadows (attached shadows — lights below the tangent plane — remain).
    None,
    /// Per-vertex visibility (computed once per frame, shared by all cameras), interpolated
    /// with the barycentrics: soft shadow edges at mesh resolution.
    PerVertex(&'a LightVisibility),
    /// One shadow ray per pixel and light above its tangent plane: exact, slow (hundreds of
    /// millions of rays for a megapixel view under the 1,200-light dome).
    PerPixel {
        /// BVH of the posed mesh.
        query: &'a MeshQuery,
        /// Ray origin offset along the normal, m (e.g.
        /// [`super::LightVisibility::DEFAULT_SHADOW_BIAS_M`]).
        bias_m: f64,
    },
}

/// Reflected radiance per pixel of one view.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct ShadedView {
    /// Image width, px.
    pub width: u32,
    /// Image height, px.
    pub height: u32,
    /// Linear RGB radiance towards the camera, row-major; zero on background.
    pub radiance: Vec<[f32; 3]>,
}

impl ShadedView {
    /// The radiance as a float image.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] if the buffer does not match the size.
    pub fn to_image(&self) -> Result<Rgb32FImage> {
        let data = self.radiance.iter().flatten().copied().collect::<Vec<_>>();
        let len = data.len();
        Rgb32FImage::from_raw(self.width, self.height, data).ok_or(Error::SizeMismatch {
            what: "shaded radiance buffer",
            expected: 3 * self.width as usize * self.height as usize,
            got: len,
        })
    }
}

/// 8-bit sRGB picture of `radiance · exposure` (clamped to `[0, 1]`), for PNG.
pub fn srgb8(radiance: &Rgb32FImage, exposure: f32) -> RgbImage {
    let mut img = RgbImage::new(radiance.width(), radiance.height());
    for (p, c) in img.pixels_mut().zip(radiance.pixels()) {
        *p = Rgb(c.0.map(|v| {
            let v = (v * exposure).clamp(0.0, 1.0);
            let s = if v <= 0.003_130_8 {
                12.92 * v
            } else {
                1.055 * v.powf(1.0 / 2.4) - 0.055
            };
            (s * 255.0).round() as u8
        }));
    }
    img
}

/// Shades every covered pixel of `view` (rendered from `mesh` with [`skin_core::raster::Buffers`]
/// `triangle` on): `L_o = ρ/π Σ_l V_l E_l` at the visible point, with the smooth (area-weighted
/// vertex) normal interpolated by the barycentrics. Parallel over rows; identical for any
/// thread count.
///
/// # Errors
/// [`Error::Empty`] if the view has no triangle buffer or there are no lights;
/// [`Error::SizeMismatch`] for per-vertex data, a visibility table or a view that does not
/// match `mesh`/`lights`; [`Error::IndexOutOfRange`] for a triangle id outside `mesh`; errors of
/// [`Light::validate`]; with [`Shadows::PerPixel`], a light inside the mesh
/// ([`check_lights_outside`]).
pub fn shade(
    view: &RenderedView,
    mesh: &TriMesh,
    lights: &[Light],
    albedo: &Albedo<'_>,
    shadows: &Shadows<'_>,
) -> Result<ShadedView> {
    let mut out = shade_impl(view, mesh, lights, None, albedo, shadows)?;
    Ok(out.pop().unwrap_or_default())
}

/// As [`shade`], once per lighting pattern in a single pass over the pixels and lights:
/// pattern `p` scales light `l` by `patterns[p][l]` (a light stage switching its lights on
/// and off, e.g. the half-on patterns of Vlasic thesis Eq. 3.1). Cast shadows and the
/// geometry are shared, so `P` patterns cost little more than one [`shade`]. The result of
/// an all-ones pattern equals [`shade`] exactly.
///
/// # Errors
/// As [`shade`]; [`Error::Empty`] for no patterns; [`Error::SizeMismatch`] for a pattern
/// without one weight per light; [`Error::NonFinite`] / [`Error::InvalidParam`] for a weight
/// that is not finite or is negative.
pub fn shade_patterns(
    view: &RenderedView,
    mesh: &TriMesh,
    lights: &[Light],
    patterns: &[Vec<f32>],
    albedo: &Albedo<'_>,
    shadows: &Shadows<'_>,
) -> Result<Vec<ShadedView>> {
    if patterns.is_empty() {
        return Err(Error::Empty {
            what: "lighting patterns",
        });
    }
    check_patterns(patterns, lights.len())?;
    shade_impl(view, mesh, lights, Some(patterns), albedo, shadows)
}

/// Checks that every pattern has one finite, non-negative weight per light.
pub(crate) fn check_patterns(patterns: &[Vec<f32>], n_lights: usize) -> Result<()> {
    for w in patterns {
        skin_core::check::same_size("pattern weights vs lights", n_lights, w.len())?;
        for &x in w {
            skin_core::check::non_negative("pattern weight", f64::from(x))?;
        }
    }
    Ok(())
}

fn shade_impl(
    view: &RenderedView,
    mesh: &TriMesh,
    lights: &[Light],
    patterns: Option<&[Vec<f32>]>,
    albedo: &Albedo<'_>,
    shadows: &Shadows<'_>,
) -> Result<Vec<ShadedView>> {
    let n = view.pixel_count();
    if view.triangle.len() != n || view.bary.len() != n || n == 0 {
        return Err(Error::Empty {
            what: "triangle/barycentric buffers of the view (render with Buffers::triangle)",
        });
    }
    if lights.is_empty() {
        return Err(Error::Empty { what: "lights" });
    }
    for l in lights {
        l.validate()?;
    }
    let nv = mesh.vertex_count();
    let size = |what, got: usize| {
        if got == nv {
            Ok(())
        } else {
            Err(Error::SizeMismatch {
                what,
                expected: nv,
                got,
            })
        }
    };
    match albedo {
        Albedo::Uniform(_) => {}
        Albedo::PerVertex(a) => size("per-vertex albedo", a.len())?,
        Albedo::Procedural { rest_positions, .. } => size("rest positions", rest_positions.len())?,
        Albedo::Textured {
            rest_positions,
            face_materials,
            ..
        } => {
            size("rest positions", rest_positions.len())?;
            skin_core::check::same_size(
                "face materials vs mesh faces",
                mesh.face_count(),
                face_materials.len(),
            )?;
        }
    }
    match shadows {
        Shadows::None => {}
        Shadows::PerVertex(vis) => {
            size("visibility vertices", vis.vertex_count())?;
            if vis.light_count() != lights.len() {
                return Err(Error::SizeMismatch {
                    what: "visibility lights",
                    expected: lights.len(),
                    got: vis.light_count(),
                });
            }
        }
        Shadows::PerPixel { query, bias_m } => {
            skin_core::check::non_negative("shadow bias_m", *bias_m)?;
            check_lights_outside(query, lights)?;
        }
    }
    if let Some(&t) = view
        .triangle
        .iter()
        .find(|&&t| t != NO_TRIANGLE && t as usize >= mesh.face_count())
    {
        return Err(Error::IndexOutOfRange {
            what: "view triangle id",
            index: t as usize,
            len: mesh.face_count(),
        });
    }
    mesh.validate()?;
    let normals = vertex_normals(mesh, NormalWeighting::Area)?;
    let prepared: Vec<PreparedLight> = lights.iter().map(PreparedLight::new).collect();
    // Bit `l` set when some pattern gives light `l` a non-zero weight (every light without
    // patterns), in the words of `LightVisibility` rows.
    let mut active = vec![0u64; lights.len().div_ceil(64).max(1)];
    for l in 0..lights.len() {
        if patterns.is_none_or(|ps| ps.iter().any(|w| w[l] != 0.0)) {
            active[l / 64] |= 1 << (l % 64);
        }
    }
    let w = view.width as usize;
    let np = patterns.map_or(1, <[_]>::len);
    // Pixel-major: the `np` radiances of a pixel are adjacent.
    let mut radiance = vec![[0.0f32; 3]; n * np];
    radiance
        .par_chunks_mut(w * np)
        .zip(view.triangle.par_chunks(w).zip(view.bary.par_chunks(w)))
        .for_each(|(out, (tri, bary))| {
            let mut e = vec![0.0f64; np];
            for ((o, &t), b) in out.chunks_mut(np).zip(tri).zip(bary) {
                if t == NO_TRIANGLE {
                    continue;
                }
                let f = mesh.faces[t as usize].map(|i| i as usize);
                let lam = [1.0 - b[0] as f64 - b[1] as f64, b[0] as f64, b[1] as f64];
                let interp = |a: &[DVec3]| a[f[0]] * lam[0] + a[f[1]] * lam[1] + a[f[2]] * lam[2];
                let p = interp(&mesh.vertices);
                let Some(nrm) = interp(&normals).try_normalize() else {
                    continue;
                };
                let rho = match albedo {
                    Albedo::Uniform(a) => *a,
                    Albedo::PerVertex(a) => {
                        let mut s = [0.0f32; 3];
                        for (k, &fk) in f.iter().enumerate() {
                            for c in 0..3 {
                                s[c] += lam[k] as f32 * a[fk][c];
                            }
                        }
                        s
                    }
                    Albedo::Procedural {
                        rest_positions,
                        texture,
                    } => texture(interp(rest_positions)),
                    Albedo::Textured {
                        rest_positions,
                        face_materials,
                        texture,
                    } => texture.eval(face_materials[t as usize], interp(rest_positions)),
                };
                let rows = match shadows {
                    Shadows::PerVertex(vis) => f.map(|v| vis.row(v)),
                    _ => [&[][..]; 3],
                };
                e.fill(0.0);
                // Light `l` with weight `w` (visibility × irradiance) into every pattern.
                let mut add = |l: usize, w: f64| match patterns {
                    None => e[0] += w,
                    Some(ps) => {
                        for (ep, wp) in e.iter_mut().zip(ps) {
                            *ep += f64::from(wp[l]) * w;
                        }
                    }
                };
                // Barycentric share of the corners that see light `l`.
                let corners = |l: usize| {
                    let (word, bit) = (l / 64, l % 64);
                    rows.iter()
                        .zip(lam)
                        .filter(|(row, _)| row[word] >> bit & 1 == 1)
                        .map(|(_, w)| w)
                        .sum::<f64>()
                };
                if let Shadows::PerVertex(_) = shadows {
                    // Only lights some corner sees and some pattern uses contribute (the
                    // others add exactly zero): walk the set bits of their union, in light
                    // order, so the sums are the same as over every light.
                    for (word, active) in active.iter().enumerate() {
                        let mut bits = (rows[0][word] | rows[1][word] | rows[2][word]) & active;
                        while bits != 0 {
                            let l = word * 64 + bits.trailing_zeros() as usize;
                            bits &= bits - 1;
                            let el = prepared[l].irradiance(p, nrm);
                            if el > 0.0 {
                                add(l, corners(l) * el);
                            }
                        }
                    }
                } else {
                    for (l, (light, prep)) in lights.iter().zip(&prepared).enumerate() {
                        let el = prep.irradiance(p, nrm);
                        if el <= 0.0 {
                            continue;
                        }
                        let v = match shadows {
                            Shadows::None => 1.0,
                            Shadows::PerVertex(_) => corners(l),
                            Shadows::PerPixel { query, bias_m } => {
                                if unoccluded(query, p, nrm, light, *bias_m) {
                                    1.0
                                } else {
                                    0.0
                                }
                            }
                        };
                        add(l, v * el);
                    }
                }
                for (op, &ep) in o.iter_mut().zip(&e) {
                    let k = (ep * std::f64::consts::FRAC_1_PI) as f32;
                    *op = rho.map(|r| r * k);
                }
            }
        });
    Ok((0..np)
        .map(|p| ShadedView {
            width: view.width,
            height: view.height,
            radiance: radiance.iter().skip(p).step_by(np).copied().collect(),
        })
        .collect())
}

#[cfg(test)]
mod tests;
