//! The body as the cloth's last word on contact: the posed body mesh itself.
//!
//! The capsules ([`super::colliders`]) are cheap and run every substep, but round cones fit a
//! flat trunk badly and linear blend skinning moves the surface away from them near bent
//! joints. So after the substeps of each frame every free garment vertex closer than the
//! collision margin to the posed body — or inside it — is projected onto the margin along the
//! body's outward direction at its closest surface point, and the part of its velocity that
//! moves into the body (relative to the body surface's own velocity there, from the previous
//! frame) is removed: an inelastic contact, the same rule the capsules apply.
//!
//! **Query.** A BVH rebuilt every frame costs more than the cloth step, so each frame the
//! used body vertices go into a dense uniform grid of [`BODY_CELL_M`] cells over their
//! bounding box (a counting sort); a garment vertex finds the nearest body vertex in the 27
//! cells around it (so anything within one cell is found), then the closest point on the
//! triangles around that vertex (Ericson's exact point–triangle test). Inside or outside is
//! the side of the body's smooth normal there (area-weighted vertex normals, interpolated
//! barycentrically). Everything runs serially in a fixed order.
//!
//! **Which faces.** The body faces whose corners all have their main joint (largest skin
//! weight) among the garment's collider joints: for the skirt the trunk and legs — arms are no
//! colliders (a hand swinging through the skirt would tear a coarse cloth apart, and a hand
//! passing through it is allowed); for the sheet the whole body. The faces and the body
//! vertices they use are stored at construction; each frame the integrator passes the posed
//! body vertices (all of them, in template order).

use super::cloth::Cloth;
use serde::{Deserialize, Serialize};
use skin_core::check;
use skin_core::math::DVec3;
use skin_core::mesh::{closest_point_on_triangle, SkinWeights, TriMesh};
use skin_core::{Error, Result};

/// Side of the grid cells of the body query, metres: the reach of the correction (a garment
/// vertex is corrected when a body vertex lies within the 27 cells around it — at least this
/// far). Deeper than this the capsules have failed anyway.
pub(super) const BODY_CELL_M: f64 = 0.04;

/// The body surface the garment collides with.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(super) struct BodySurface {
    /// Number of vertices of the full body template.
    pub(super) vertex_count: usize,
    /// Template indices of the vertices the faces use, ascending.
    used: Vec<u32>,
    /// The collision faces, indexing `used`.
    faces: Vec<[u32; 3]>,
    /// Faces around each used vertex (CSR: `ring_start[v]..ring_start[v + 1]` of `ring`).
    ring_start: Vec<u32>,
    ring: Vec<u32>,
}

/// The body posed in one frame, ready for queries.
pub(super) struct PosedBody<'a> {
    surface: &'a BodySurface,
    /// Used vertices, metres.
    pub(super) vertices: Vec<DVec3>,
    /// Unit area-weighted vertex normals (zero where undefined).
    normals: Vec<DVec3>,
    /// Grid origin (the vertices' lowest corner) and number of cells along each axis.
    origin: DVec3,
    dims: [usize; 3],
    /// Vertex indices sorted by cell (ascending within a cell), and each cell's start in it
    /// (`cell_start[c]..cell_start[c + 1]`).
    sorted: Vec<u32>,
    cell_start: Vec<u32>,
}

impl BodySurface {
    /// The faces of `body` whose corners' main joints are all in `joints`.
    ///
    /// # Errors
    /// [`Error::Empty`] when no face qualifies; [`Error::SizeMismatch`] for weights of
    /// another body.
    pub(super) fn new(body: &TriMesh, weights: &SkinWeights, joints: &[usize]) -> Result<Self> {
        check::same_size(
            "body skin weight rows vs body vertices",
            body.vertex_count(),
            weights.vertex_count(),
        )?;
        let collides: Vec<bool> = (0..body.vertex_count())
            .map(|v| {
                weights
                    .influences(v)
                    .max_by(|a, b| a.1.total_cmp(&b.1).then(b.0.cmp(&a.0)))
                    .is_some_and(|(j, _)| joints.contains(&(j as usize)))
            })
            .collect();
        let kept: Vec<[u32; 3]> = body
            .faces
            .iter()
            .filter(|f| f.iter().all(|&v| collides[v as usize]))
            .copied()
            .collect();
        if kept.is_empty() {
            return Err(Error::Empty {
                what: "body faces of the garment's collider joints",
            });
        }
        let mut is_used = vec![false; body.vertex_count()];
        for f in &kept {
            for &v in f {
                is_used[v as usize] = true;
            }
        }
        let mut index = vec![u32::MAX; body.vertex_count()];
        let mut used = Vec::new();
        for (v, _) in is_used.iter().enumerate().filter(|(_, &u)| u) {
            index[v] = used.len() as u32;
            used.push(v as u32);
        }
        let faces: Vec<[u32; 3]> = kept.iter().map(|f| f.map(|v| index[v as usize])).collect();
        let mut count = vec![0u32; used.len() + 1];
        for f in &faces {
            for &v in f {
                count[v as usize + 1] += 1;
            }
        }
        for k in 1..count.len() {
            count[k] += count[k - 1];
        }
        let ring_start = count.clone();
        let mut ring = vec![0u32; faces.len() * 3];
        for (fi, f) in faces.iter().enumerate() {
            for &v in f {
                ring[count[v as usize] as usize] = fi as u32;
                count[v as usize] += 1;
            }
        }
        Ok(BodySurface {
            vertex_count: body.vertex_count(),
            used,
            faces,
            ring_start,
            ring,
        })
    }

    /// The collision surface of the body template `body` (the one it was built from) as a mesh
    /// of its own, with the template index of each of its vertices.
    pub(super) fn submesh(&self, body: &TriMesh) -> (TriMesh, &[u32]) {
        (
            TriMesh {
                vertices: self.gather(&body.vertices),
                faces: self.faces.clone(),
            },
            &self.used,
        )
    }

    /// The used vertices of the posed body `body` (checked to have `vertex_count` entries).
    pub(super) fn gather(&self, body: &[DVec3]) -> Vec<DVec3> {
        self.used.iter().map(|&v| body[v as usize]).collect()
    }

    /// The body posed with the gathered vertices `vertices`: normals and grid.
    pub(super) fn pose(&self, vertices: Vec<DVec3>) -> PosedBody<'_> {
        let mut normals = vec![DVec3::ZERO; vertices.len()];
        for f in &self.faces {
            let [a, b, c] = f.map(|v| vertices[v as usize]);
            // Twice the area times the unit normal: area weighting.
            let n = (b - a).cross(c - a);
            for &v in f {
                normals[v as usize] += n;
            }
        }
        for n in &mut normals {
            *n = n.try_normalize().unwrap_or(DVec3::ZERO);
        }
        let (lo, hi) = vertices.iter().fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(lo, hi), &p| (lo.min(p), hi.max(p)),
        );
        let origin = if lo.is_finite() { lo } else { DVec3::ZERO };
        let extent = ((hi - origin) / BODY_CELL_M).max(DVec3::ZERO);
        let dims = [
            extent.x as usize + 1,
            extent.y as usize + 1,
            extent.z as usize + 1,
        ];
        let cell = |p: DVec3| -> usize {
            let c = ((p - origin) / BODY_CELL_M).max(DVec3::ZERO);
            let [i, j, k] = [
                (c.x as usize).min(dims[0] - 1),
                (c.y as usize).min(dims[1] - 1),
                (c.z as usize).min(dims[2] - 1),
            ];
            (i * dims[1] + j) * dims[2] + k
        };
        let keys: Vec<usize> = vertices.iter().map(|&p| cell(p)).collect();
        let mut cell_start = vec![0u32; dims[0] * dims[1] * dims[2] + 1];
        for &c in &keys {
            cell_start[c + 1] += 1;
        }
        for c in 1..cell_start.len() {
            cell_start[c] += cell_start[c - 1];
        }
        let mut fill = cell_start.clone();
        let mut sorted = vec![0u32; vertices.len()];
        for (v, &c) in keys.iter().enumerate() {
            sorted[fill[c] as usize] = v as u32;
            fill[c] += 1;
        }
        PosedBody {
            surface: self,
            vertices,
            normals,
            origin,
            dims,
            sorted,
            cell_start,
        }
    }
}

impl PosedBody<'_> {
    /// The body vertex nearest to `p` within the 27 cells around it.
    fn nearest_vertex(&self, p: DVec3) -> Option<usize> {
        let c = ((p - self.origin) / BODY_CELL_M).floor();
        if !c.is_finite() {
            return None;
        }
        let range = |x: f64, n: usize| -> std::ops::Range<usize> {
            let lo = (x - 1.0).max(0.0);
            let hi = (x + 2.0).min(n as f64);
            if hi <= lo {
                0..0
            } else {
                lo as usize..hi as usize
            }
        };
        let [nx, ny, nz] = self.dims;
        let mut best: Option<(f64, usize)> = None;
        for i in range(c.x, nx) {
            for j in range(c.y, ny) {
                let row = (i * ny + j) * nz;
                let ks = range(c.z, nz);
                let (a, b) = (
                    self.cell_start[row + ks.start] as usize,
                    self.cell_start[row + ks.end] as usize,
                );
                for &v in &self.sorted[a..b] {
                    let d = self.vertices[v as usize].distance_squared(p);
                    if best.is_none_or(|(bd, _)| d < bd) {
                        best = Some((d, v as usize));
                    }
                }
            }
        }
        best.map(|(_, v)| v)
    }

    /// `(closest point, face, barycentric weights, outward unit normal, signed distance)` of
    /// `p` on the triangles around its nearest body vertex, if any vertex is near.
    fn closest(&self, p: DVec3) -> Option<(DVec3, usize, [f64; 3], DVec3, f64)> {
        let v = self.nearest_vertex(p)?;
        let s = self.surface;
        let ring = &s.ring[s.ring_start[v] as usize..s.ring_start[v + 1] as usize];
        let mut best: Option<(f64, usize, [f64; 3], DVec3)> = None;
        for &f in ring {
            let tri = s.faces[f as usize].map(|k| self.vertices[k as usize]);
            let t = closest_point_on_triangle(p, tri);
            if best.is_none_or(|b| t.distance < b.0) {
                best = Some((t.distance, f as usize, t.bary, t.position));
            }
        }
        let (dist, f, bary, cp) = best?;
        let smooth: DVec3 = s.faces[f]
            .iter()
            .zip(&bary)
            .map(|(&k, &b)| self.normals[k as usize] * b)
            .sum();
        let smooth = smooth.try_normalize()?;
        let out = p - cp;
        let (n, sd) = match out.try_normalize() {
            Some(d) if dist > 1e-9 => {
                if out.dot(smooth) < 0.0 {
                    (-d, -dist)
                } else {
                    (d, dist)
                }
            }
            _ => (smooth, 0.0),
        };
        Some((cp, f, bary, n, sd))
    }
}

/// Projects the free vertices of `x` (velocities `v`) of `cloth` to at least its collision
/// margin outside the posed body `now`, removing the velocity into the body relative to the
/// surface's motion since `before` (same vertices `dt_s` earlier).
pub(super) fn project(
    cloth: &Cloth,
    now: &PosedBody<'_>,
    before: &[DVec3],
    dt_s: f64,
    x: &mut [DVec3],
    v: &mut [DVec3],
) {
    let margin = cloth.params.collision_margin_m;
    let faces = &now.surface.faces;
    for i in 0..x.len() {
        if cloth.is_pinned(i) {
            continue;
        }
        let Some((cp, f, bary, n, sd)) = now.closest(x[i]) else {
            continue;
        };
        if sd >= margin {
            continue;
        }
        x[i] = cp + n * margin;
        let moved: DVec3 = faces[f]
            .iter()
            .zip(&bary)
            .map(|(&k, &b)| (now.vertices[k as usize] - before[k as usize]) * b)
            .sum();
        let into = (v[i] - moved / dt_s).dot(n);
        if into < 0.0 {
            v[i] -= n * into;
        }
    }
}
