//! Cast shadows by ray casting through the mesh BVH ([`MeshQuery`]), and the check that no
//! light is inside the body.
//!
//! Visibility is computed per vertex and per light, once per frame (it does not depend on the
//! camera), and interpolated per pixel with the barycentrics in [`super::shade`]: the standard
//! trade-off of light-stage renderers. Shadow edges are then resolved to the mesh resolution
//! (~1–2 cm on a 13k-vertex body) instead of the pixel; [`super::Shadows::PerPixel`] casts
//! one ray per pixel and light instead, exactly and far more slowly. Lights below a vertex's
//! tangent plane are culled before any ray is cast (they contribute nothing), which halves
//! the rays of a surrounding dome.

use rayon::prelude::*;

use super::lights::Light;
use super::shadow_bvh::ShadowBvh;
use skin_core::math::{DVec3, Ray};
use skin_core::mesh::{vertex_normals, MeshQuery, NormalWeighting, TriMesh};
use skin_core::raster::{RenderedView, NO_TRIANGLE};
use skin_core::{Error, Result};

impl LightVisibility {
    /// Offset of shadow-ray origins along the surface normal, m: 0.1 mm, far above the f64
    /// rounding of body-sized meshes and far below the size of any feature that casts a shadow.
    pub const DEFAULT_SHADOW_BIAS_M: f64 = 1e-4;
}

/// Which lights each vertex sees: bit `l` of vertex `v` is set when light `l` is above the
/// vertex's tangent plane and the segment to it is unoccluded.
#[derive(Debug, Clone, PartialEq)]
pub struct LightVisibility {
    n_vertices: usize,
    n_lights: usize,
    words_per_vertex: usize,
    bits: Vec<u64>,
}

impl LightVisibility {
    /// Casts shadow rays from every vertex of `mesh` (posed, world frame) to every light above
    /// its tangent plane, in parallel over vertices (identical for any thread count). Rays
    /// start `bias_m` off the surface along the area-weighted vertex normal.
    ///
    /// # Errors
    /// Errors of [`Light::validate`]; [`Error::SizeMismatch`] if `query` was built from a mesh
    /// with a different face count; [`Error::InvalidParam`] for a negative or non-finite bias
    /// or a light inside the mesh (see [`check_lights_outside`]).
    pub fn compute(
        mesh: &TriMesh,
        query: &MeshQuery,
        lights: &[Light],
        bias_m: f64,
    ) -> Result<Self> {
        Self::compute_for(mesh, query, lights, bias_m, None)
    }

    /// As [`LightVisibility::compute`], casting rays only from the vertices with
    /// `needed[v] = true` (e.g. [`vertices_seen`] of the views to shade); the others are
    /// reported as seeing no light. One view needs about half the rays of the whole mesh.
    ///
    /// # Errors
    /// As [`LightVisibility::compute`]; [`Error::SizeMismatch`] if `needed` does not have one
    /// entry per vertex.
    pub fn compute_for(
        mesh: &TriMesh,
        query: &MeshQuery,
        lights: &[Light],
        bias_m: f64,
        needed: Option<&[bool]>,
    ) -> Result<Self> {
        Self::compute_binned(mesh, query, lights, bias_m, needed, None)
    }

    /// As [`LightVisibility::compute_for`], approximated: the lights are grouped into about
    /// `bins` direction bins ([`light_bins`]), and per vertex and bin one shadow ray — to the
    /// bin's light nearest the bin's mean direction among those above the vertex's tangent
    /// plane — decides for every light of the bin above the plane. About `lights / bins`
    /// times fewer rays; shadow edges are resolved to the bins' angular size (≈ 20° for 100
    /// bins on the 1,200-light dome) instead of the lights' spacing. `None` is exact.
    ///
    /// # Errors
    /// As [`LightVisibility::compute_for`]; [`Error::InvalidParam`] for `Some(0)` bins.
    pub fn compute_binned(
        mesh: &TriMesh,
        query: &MeshQuery,
        lights: &[Light],
        bias_m: f64,
        needed: Option<&[bool]>,
        bins: Option<usize>,
    ) -> Result<Self> {
        check_bias(bias_m)?;
        if bins == Some(0) {
            return Err(Error::InvalidParam {
                name: "bins",
                reason: "at least one light bin".into(),
            });
        }
        if let Some(n) = needed {
            if n.len() != mesh.vertex_count() {
                return Err(Error::SizeMismatch {
                    what: "needed-vertex flags",
                    expected: mesh.vertex_count(),
                    got: n.len(),
                });
            }
        }
        if query.face_count() != mesh.face_count() {
            return Err(Error::SizeMismatch {
                what: "mesh faces vs MeshQuery faces",
                expected: mesh.face_count(),
                got: query.face_count(),
            });
        }
        check_lights_outside(query, lights)?;
        let normals = vertex_normals(mesh, NormalWeighting::Area)?;
        // Shadow rays only ask whether anything is in the way: the any-hit hierarchy answers
        // as `MeshQuery::cast_ray` does, several times faster (see `shadow_bvh`).
        let bvh = ShadowBvh::new(mesh);
        let groups = bins.map(|b| light_bins(lights, b));
        let n_lights = lights.len();
        let words = n_lights.div_ceil(64).max(1);
        let mut bits = vec![0u64; words * mesh.vertex_count()];
        bits.par_chunks_mut(words)
            .zip(mesh.vertices.par_iter().zip(normals.par_iter()))
            .enumerate()
            .for_each(|(v, (row, (&p, &n)))| {
                if needed.is_some_and(|nd| !nd[v]) {
                    return;
                }
                let Some(groups) = &groups else {
                    for (l, light) in lights.iter().enumerate() {
                        if light.irradiance(p, n) > 0.0 && unoccluded_any(&bvh, p, n, light, bias_m)
                        {
                            row[l / 64] |= 1 << (l % 64);
                        }
                    }
                    return;
                };
                for group in groups {
                    // `group` is ordered by closeness to the bin's mean direction: the first
                    // light above the tangent plane represents the bin.
                    let mut lit: Option<bool> = None;
                    for &l in group {
                        if lights[l].irradiance(p, n) <= 0.0 {
                            continue;
                        }
                        let seen = *lit
                            .get_or_insert_with(|| unoccluded_any(&bvh, p, n, &lights[l], bias_m));
                        if seen {
                            row[l / 64] |= 1 << (l % 64);
                        }
                    }
                }
            });
        Ok(Self {
            n_vertices: mesh.vertex_count(),
            n_lights,
            words_per_vertex: words,
            bits,
        })
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.n_vertices
    }

    /// Number of lights.
    pub fn light_count(&self) -> usize {
        self.n_lights
    }

    /// True when vertex `v` sees light `l` (false for out-of-range indices).
    pub fn visible(&self, v: usize, l: usize) -> bool {
        v < self.n_vertices
            && l < self.n_lights
            && self.bits[v * self.words_per_vertex + l / 64] >> (l % 64) & 1 == 1
    }

    /// The visibility words of vertex `v` (bit `l % 64` of word `l / 64`); `v` must be in range
    /// (checked by the caller against [`LightVisibility::vertex_count`]).
    pub(crate) fn row(&self, v: usize) -> &[u64] {
        let w = self.words_per_vertex;
        &self.bits[v * w..(v + 1) * w]
    }

    /// Number of lights vertex `v` sees.
    pub fn visible_count(&self, v: usize) -> usize {
        if v >= self.n_vertices {
            return 0;
        }
        let w = self.words_per_vertex;
        self.bits[v * w..(v + 1) * w]
            .iter()
            .map(|b| b.count_ones() as usize)
            .sum()
    }
}

/// The lights grouped into about `bins` direction bins, as seen from the lights' centroid:
/// equal-area bands of the polar angle from +Y (`round(√(bins/2))` of them) times twice as
/// many azimuth sectors; empty bins dropped. Each group lists its lights by decreasing
/// cosine to the group's mean direction (ties by index).
pub fn light_bins(lights: &[Light], bins: usize) -> Vec<Vec<usize>> {
    if lights.is_empty() {
        return Vec::new();
    }
    let centroid = lights.iter().map(Light::position).sum::<DVec3>() / lights.len() as f64;
    let bands = ((bins.max(1) as f64 / 2.0).sqrt().round() as usize).max(1);
    let sectors = 2 * bands;
    let mut groups = vec![Vec::new(); bands * sectors];
    let dirs: Vec<DVec3> = lights
        .iter()
        .map(|l| {
            (l.position() - centroid)
                .try_normalize()
                .unwrap_or(DVec3::Y)
        })
        .collect();
    for (l, d) in dirs.iter().enumerate() {
        // Equal area: bands uniform in cos θ ∈ [−1, 1].
        let band = (((1.0 - d.y) / 2.0 * bands as f64) as usize).min(bands - 1);
        let phi = d.z.atan2(d.x) + std::f64::consts::PI;
        let sector = ((phi / std::f64::consts::TAU * sectors as f64) as usize).min(sectors - 1);
        groups[band * sectors + sector].push(l);
    }
    groups.retain(|g| !g.is_empty());
    for g in &mut groups {
        let mean = g
            .iter()
            .map(|&l| dirs[l])
            .sum::<DVec3>()
            .normalize_or_zero();
        g.sort_by(|&a, &b| {
            mean.dot(dirs[b])
                .total_cmp(&mean.dot(dirs[a]))
                .then(a.cmp(&b))
        });
    }
    groups
}

/// Flags of the vertices whose faces are visible in any of `views` (rendered from `mesh` with
/// [`skin_core::raster::Buffers`] `triangle` on): the vertices shading those views reads.
///
/// # Errors
/// [`Error::Empty`] if a view has no triangle buffer; [`Error::IndexOutOfRange`] for a
/// triangle id outside `mesh`.
pub fn vertices_seen(mesh: &TriMesh, views: &[&RenderedView]) -> Result<Vec<bool>> {
    let mut seen = vec![false; mesh.vertex_count()];
    for view in views {
        if view.triangle.is_empty() {
            return Err(Error::Empty {
                what: "triangle buffer of the view (render with Buffers::triangle)",
            });
        }
        let mut last = NO_TRIANGLE;
        for &t in &view.triangle {
            if t == NO_TRIANGLE || t == last {
                continue;
            }
            last = t;
            let face = mesh.faces.get(t as usize).ok_or(Error::IndexOutOfRange {
                what: "view triangle id",
                index: t as usize,
                len: mesh.face_count(),
            })?;
            for &i in face {
                // Face indices were validated against the vertex count when `mesh` was built
                // or rendered; `get_mut` keeps a corrupt mesh from panicking here.
                if let Some(s) = seen.get_mut(i as usize) {
                    *s = true;
                }
            }
        }
    }
    Ok(seen)
}

fn check_bias(bias_m: f64) -> Result<()> {
    skin_core::check::non_negative("shadow bias_m", bias_m)?;
    Ok(())
}

/// True when the segment from `p` (offset by `bias_m` along `n`) to the light is free.
pub(crate) fn unoccluded(
    query: &MeshQuery,
    p: DVec3,
    n: DVec3,
    light: &Light,
    bias_m: f64,
) -> bool {
    let o = p + n * bias_m;
    let d = light.position() - o;
    let dist = d.length();
    if dist <= bias_m {
        return true;
    }
    // Inputs are finite and the direction non-zero, so `cast_ray` cannot fail; treat a failure
    // as unoccluded rather than panic.
    !matches!(query.cast_ray(Ray::new(o, d), dist - bias_m), Ok(Some(_)))
}

/// [`unoccluded`] through the any-hit hierarchy: the same segment, the same answer.
fn unoccluded_any(bvh: &ShadowBvh, p: DVec3, n: DVec3, light: &Light, bias_m: f64) -> bool {
    let o = p + n * bias_m;
    let d = light.position() - o;
    let dist = d.length();
    if dist <= bias_m {
        return true;
    }
    !bvh.occluded(o, d, (dist - bias_m) / dist)
}

/// Checks that no light is inside the (closed, outward-oriented) mesh
/// ([`MeshQuery::contains`]).
///
/// # Errors
/// Errors of [`Light::validate`]; [`Error::InvalidParam`] naming the first light inside.
pub fn check_lights_outside(query: &MeshQuery, lights: &[Light]) -> Result<()> {
    for (i, light) in lights.iter().enumerate() {
        light.validate()?;
        let p = light.position();
        if query.contains(p)? {
            return Err(Error::InvalidParam {
                name: "lights",
                reason: format!("light {i} at {p} is inside the mesh; move it outside the body"),
            });
        }
    }
    Ok(())
}
