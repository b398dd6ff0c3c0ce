//! Render-time refinement of a [`TriMesh`]: selected faces are split until every edge there
//! is at most `max_edge_m` long, so that a coarse simulation mesh can carry millimetre-scale
//! detail (wrinkles) at render time.
//!
//! **Conforming by shared edge counts.** Every edge of a selected face gets `n_e` segments,
//! decided once per edge (the least `n_e ≥ ⌈length / max_edge⌉` whose segments of the smooth
//! surface are all short enough) and shared by both faces on it, so the two faces place the
//! same points on it: no T-junctions, no cracks; a closed mesh stays closed and a manifold
//! stays manifold. Inside a selected face:
//!
//! * all three edge counts equal `n`: the regular grid of level `n` (`n²` triangles);
//! * otherwise the face's interior is the regular grid of level `n` restricted to the points
//!   with all three grid coordinates ≥ 1 (an inner triangle of level `n − 3`), and each side's
//!   ring strip between the edge's `n_e` segments and the inner triangle's side is zipped
//!   (each step adds the triangle with the shorter new diagonal). `n` starts at
//!   `max(n_e, 3)` and grows until every edge in the face is ≤ `max_edge_m`.
//!
//! An unselected face next to a selected one has points on its shared edge(s) only; it is
//! split into a fan around its centroid (a transition face: its own edges are not bounded).
//! Every other unselected face is copied unchanged, with its coarse vertex indices.
//!
//! **Re-evaluation.** Fine vertex `i < n` (the coarse vertex count) *is* coarse vertex `i`;
//! every further fine vertex is a [`FinePoint`]: barycentric coordinates on three coarse
//! vertices (a face's corners, or an edge's two ends). [`Refinement::evaluate`] places them
//! on any posed copy of the coarse mesh, so the refinement is built once (at rest) and
//! evaluated each frame in O(fine vertices).
//!
//! **Smooth evaluation.** Points are placed by Phong tessellation (Boubekeur & Alexa 2008):
//! with the flat point `p = Σ λᵢ Pᵢ` and the area-weighted vertex normals `nᵢ`,
//! `p* = (1 − α) p + α Σ λᵢ πᵢ(p)`, `πᵢ(p) = p − ((p − Pᵢ)·nᵢ) nᵢ`; `α` =
//! [`RefineParams::DEFAULT_PHONG_ALPHA`] as the paper recommends, 0 gives the flat facets. A point
//! on an edge depends only on that edge's two ends, so the evaluation is crack-free too.

use std::collections::HashMap;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::normals::triangle_normal;
use super::trimesh::triangle_area;
use super::TriMesh;
use crate::check;
use crate::math::DVec3;
use crate::{Error, Result};

impl RefineParams {
    /// Phong tessellation shape factor `α` of [`RefineParams::new`]: 3/4, the value Boubekeur &
    /// Alexa (2008) recommend.
    pub const DEFAULT_PHONG_ALPHA: f64 = 0.75;
}

/// Parameters of [`Refinement::new`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RefineParams {
    /// Longest edge allowed in the selected faces after refinement (measured on the smooth
    /// surface of the input mesh), metres (mesh units), finite and > 0.
    pub max_edge_m: f64,
    /// Phong tessellation shape factor `α` in `[0, 1]`: 0 flat, default
    /// [`RefineParams::DEFAULT_PHONG_ALPHA`].
    pub phong_alpha: f64,
}

impl RefineParams {
    /// Edges at most `max_edge_m`, Phong `α` = [`RefineParams::DEFAULT_PHONG_ALPHA`].
    pub fn new(max_edge_m: f64) -> Self {
        Self {
            max_edge_m,
            phong_alpha: RefineParams::DEFAULT_PHONG_ALPHA,
        }
    }

    /// The parameters with Phong factor `alpha`.
    pub fn with_phong_alpha(mut self, alpha: f64) -> Self {
        self.phong_alpha = alpha;
        self
    }

    /// Checks the ranges.
    ///
    /// # Errors
    /// [`Error::InvalidParam`] for a non-positive or non-finite `max_edge_m`, an `α` outside
    /// `[0, 1]`.
    pub fn validate(&self) -> Result<()> {
        check::positive("max_edge_m", self.max_edge_m)?;
        check::in_range("phong_alpha", self.phong_alpha, 0.0..=1.0)?;
        Ok(())
    }
}

/// A fine vertex as a combination of coarse vertices: `Σ bary[k] · coarse[corners[k]]`
/// (flat), or its Phong-tessellated counterpart. The weights are ≥ 0 and sum to 1.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FinePoint {
    /// Coarse vertex indices: a face's corners in its order, or `[a, b, a]` for a point on
    /// edge `a–b` (then `bary[2] = 0`).
    pub corners: [u32; 3],
    /// Barycentric weights of the corners.
    pub bary: [f64; 3],
}

/// How each coarse face appears in the fine mesh.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum FaceRefinement {
    /// Copied unchanged (same three vertex indices).
    Kept,
    /// A transition face: unselected, but with points on an edge it shares with a selected
    /// face; split into a fan around its centroid.
    Transition,
    /// Selected and refined to the edge bound.
    Refined,
}

/// A refinement of one coarse mesh: the fine topology and, per fine vertex, how to place it
/// on (posed) coarse vertices. Build with [`Refinement::new`]; evaluate with
/// [`Refinement::evaluate`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Refinement {
    coarse_vertex_count: usize,
    coarse_faces: Vec<[u32; 3]>,
    phong_alpha: f64,
    /// Fine vertices `coarse_vertex_count..`.
    points: Vec<FinePoint>,
    faces: Vec<[u32; 3]>,
    face_parent: Vec<u32>,
    coarse_face_kind: Vec<FaceRefinement>,
}

/// Phong tessellation of barycentric point `bary` on corners `p` with normals `n`.
fn phong(p: [DVec3; 3], n: [DVec3; 3], bary: [f64; 3], alpha: f64) -> DVec3 {
    let flat = p[0] * bary[0] + p[1] * bary[1] + p[2] * bary[2];
    if alpha == 0.0 {
        return flat;
    }
    let mut proj = DVec3::ZERO;
    for k in 0..3 {
        if bary[k] != 0.0 {
            proj += (flat - n[k] * (flat - p[k]).dot(n[k])) * bary[k];
        }
    }
    flat * (1.0 - alpha) + proj * alpha
}

/// Area-weighted unit vertex normals (zero for isolated vertices) of `faces` on `vertices`.
fn area_normals(vertices: &[DVec3], faces: &[[u32; 3]]) -> Vec<DVec3> {
    let mut acc = vec![DVec3::ZERO; vertices.len()];
    for f in faces {
        let tri = f.map(|i| vertices[i as usize]);
        if let Some(n) = triangle_normal(tri) {
            let w = triangle_area(tri);
            for &v in f {
                acc[v as usize] += n * w;
            }
        }
    }
    acc.into_iter()
        .map(|n| n.try_normalize().unwrap_or(DVec3::ZERO))
        .collect()
}

/// Local point of one face's triangulation: its barycentrics and where it lives.
#[derive(Debug, Clone, Copy)]
enum Local {
    Corner(usize),
    /// Point `i` (1..n_e) along local edge `e` (corner `e` → corner `e + 1`).
    Edge(usize, u32),
    Inner,
}

/// A triangulation of one face in barycentric space.
struct Patch {
    bary: Vec<[f64; 3]>,
    kind: Vec<Local>,
    tris: Vec<[usize; 3]>,
}

impl Patch {
    fn new() -> Self {
        let mut p = Patch {
            bary: Vec::new(),
            kind: Vec::new(),
            tris: Vec::new(),
        };
        for k in 0..3 {
            let mut b = [0.0; 3];
            b[k] = 1.0;
            p.push(b, Local::Corner(k));
        }
        p
    }

    fn push(&mut self, bary: [f64; 3], kind: Local) -> usize {
        self.bary.push(bary);
        self.kind.push(kind);
        self.bary.len() - 1
    }

    /// Adds triangle `t`, oriented like the face (positive in barycentric space).
    fn tri(&mut self, t: [usize; 3]) {
        let [a, b, c] = t.map(|i| self.bary[i]);
        let det = (b[1] - a[1]) * (c[2] - a[2]) - (b[2] - a[2]) * (c[1] - a[1]);
        if det > 0.0 {
            self.tris.push(t);
        } else if det < 0.0 {
            self.tris.push([t[0], t[2], t[1]]);
        }
    }

    /// The outer polyline of local edge `e` with `n_e` segments: corner, edge points, corner.
    fn outer(&mut self, e: usize, n_e: u32) -> Vec<usize> {
        let (a, b) = (e, (e + 1) % 3);
        let mut line = vec![a];
        for i in 1..n_e {
            let t = f64::from(i) / f64::from(n_e);
            let mut bary = [0.0; 3];
            bary[a] = 1.0 - t;
            bary[b] = t;
            line.push(self.push(bary, Local::Edge(e, i)));
        }
        line.push(b);
        line
    }
}

/// Grid point `(i, j, k)` (corner weights × n) of level `n` as barycentrics.
fn grid_bary(g: [u32; 3], n: u32) -> [f64; 3] {
    g.map(|x| f64::from(x) / f64::from(n))
}

/// The regular level-`n` grid on a face all of whose edges have `n` segments.
fn regular_patch(n: u32) -> Patch {
    let mut p = Patch::new();
    let mut ids: HashMap<[u32; 3], usize> = HashMap::new();
    let outer: Vec<Vec<usize>> = (0..3).map(|e| p.outer(e, n)).collect();
    for i in 0..=n {
        for j in 0..=n - i {
            let g = [i, j, n - i - j];
            // On edge e (corner e → e+1) the grid coordinate of corner e+2 is 0 and the index
            // along the edge is the weight of corner e+1.
            let id = (0..3)
                .find(|&e| g[(e + 2) % 3] == 0)
                .map(|e| outer[e][g[(e + 1) % 3] as usize])
                .unwrap_or_else(|| p.push(grid_bary(g, n), Local::Inner));
            ids.insert(g, id);
        }
    }
    grid_triangles(&mut p, &ids, n);
    p
}

/// Adds every triangle of the level-`n` grid whose three points are in `ids`.
fn grid_triangles(p: &mut Patch, ids: &HashMap<[u32; 3], usize>, n: u32) {
    let add = |p: &mut Patch, g: [[u32; 3]; 3]| {
        if let (Some(&a), Some(&b), Some(&c)) = (ids.get(&g[0]), ids.get(&g[1]), ids.get(&g[2])) {
            p.tri([a, b, c]);
        }
    };
    for i in 0..n {
        for j in 0..n - i {
            let k = n - 1 - i - j;
            add(p, [[i + 1, j, k], [i, j + 1, k], [i, j, k + 1]]);
            if k >= 1 {
                add(p, [[i, j + 1, k], [i + 1, j, k], [i + 1, j + 1, k - 1]]);
            }
        }
    }
}

/// The ring-and-inner-grid triangulation of a face with edge counts `counts` at level
/// `n ≥ 3`; `tri` (flat corner positions) picks the zipper's diagonals.
fn ring_patch(counts: [u32; 3], n: u32, tri: [DVec3; 3]) -> Patch {
    let mut p = Patch::new();
    let outer: Vec<Vec<usize>> = (0..3).map(|e| p.outer(e, counts[e])).collect();
    let mut ids: HashMap<[u32; 3], usize> = HashMap::new();
    for i in 1..=n - 2 {
        for j in 1..=n - 1 - i {
            let g = [i, j, n - i - j];
            if g[2] >= 1 {
                ids.insert(g, p.push(grid_bary(g, n), Local::Inner));
            }
        }
    }
    grid_triangles(&mut p, &ids, n);
    let pos = |p: &Patch, i: usize| {
        let b = p.bary[i];
        tri[0] * b[0] + tri[1] * b[1] + tri[2] * b[2]
    };
    for (e, outer) in outer.iter().enumerate() {
        let (a, b, c) = (e, (e + 1) % 3, (e + 2) % 3);
        let m = n - 3;
        let inner: Vec<usize> = (0..=m)
            .map(|t| {
                let mut g = [0; 3];
                g[a] = n - 2 - t;
                g[b] = 1 + t;
                g[c] = 1;
                ids[&g]
            })
            .collect();
        let (mut i, mut j) = (0, 0);
        let (na, nb) = (outer.len() - 1, inner.len() - 1);
        while i < na || j < nb {
            let advance_outer = if i == na {
                false
            } else if j == nb {
                true
            } else {
                let d_outer = pos(&p, outer[i + 1]).distance(pos(&p, inner[j]));
                let d_inner = pos(&p, outer[i]).distance(pos(&p, inner[j + 1]));
                d_outer <= d_inner
            };
            if advance_outer {
                p.tri([outer[i], outer[i + 1], inner[j]]);
                i += 1;
            } else {
                p.tri([outer[i], inner[j + 1], inner[j]]);
                j += 1;
            }
        }
    }
    p
}

impl Refinement {
    /// Refines the faces of `mesh` with `selected[f]` until every edge there is at most
    /// `params.max_edge_m` on the smooth (Phong) surface of `mesh` (see the module docs).
    /// Degenerate faces (a repeated vertex index) are kept unchanged. A face whose interior
    /// cannot meet the bound within a level of `4 n + 8` (a sliver) is left at that level.
    ///
    /// # Errors
    /// As [`TriMesh::validate`]; [`Error::SizeMismatch`] unless `selected` has one entry per
    /// face; as [`RefineParams::validate`].
    pub fn new(mesh: &TriMesh, selected: &[bool], params: &RefineParams) -> Result<Self> {
        mesh.validate()?;
        params.validate()?;
        check::same_size("selected faces", mesh.face_count(), selected.len())?;
        let h = params.max_edge_m;
        let alpha = params.phong_alpha;
        let normals = area_normals(&mesh.vertices, &mesh.faces);
        let nv = mesh.vertex_count();
        let degenerate = |f: &[u32; 3]| f[0] == f[1] || f[1] == f[2] || f[2] == f[0];
        // Segment count of every edge of a selected face, and its first fine vertex.
        let mut edges: HashMap<(u32, u32), (u32, u32)> = HashMap::new();
        let mut points = Vec::new();
        for (f, face) in mesh.faces.iter().enumerate() {
            if !selected[f] || degenerate(face) {
                continue;
            }
            for e in 0..3 {
                let (a, b) = (face[e], face[(e + 1) % 3]);
                let key = (a.min(b), a.max(b));
                if edges.contains_key(&key) {
                    continue;
                }
                let (u, v) = (key.0 as usize, key.1 as usize);
                let ends = [mesh.vertices[u], mesh.vertices[v], mesh.vertices[u]];
                let nrm = [normals[u], normals[v], normals[u]];
                let at = |t: f64| phong(ends, nrm, [1.0 - t, t, 0.0], alpha);
                let start = (ends[0].distance(ends[1]) / h).ceil().max(1.0) as u32;
                let mut n = start;
                while n < 4 * start + 8 {
                    let longest = (0..n)
                        .map(|i| {
                            at(f64::from(i) / f64::from(n))
                                .distance(at(f64::from(i + 1) / f64::from(n)))
                        })
                        .fold(0.0, f64::max);
                    if longest <= h {
                        break;
                    }
                    n += 1;
                }
                let first = (nv + points.len()) as u32;
                for i in 1..n {
                    let t = f64::from(i) / f64::from(n);
                    points.push(FinePoint {
                        corners: [key.0, key.1, key.0],
                        bary: [1.0 - t, t, 0.0],
                    });
                }
                edges.insert(key, (n, first));
            }
        }
        let mut faces = Vec::with_capacity(mesh.face_count());
        let mut face_parent = Vec::with_capacity(mesh.face_count());
        let mut kinds = Vec::with_capacity(mesh.face_count());
        for (f, face) in mesh.faces.iter().enumerate() {
            let counts: [u32; 3] = std::array::from_fn(|e| {
                let (a, b) = (face[e], face[(e + 1) % 3]);
                edges.get(&(a.min(b), a.max(b))).map_or(1, |x| x.0)
            });
            if degenerate(face) || counts == [1, 1, 1] {
                faces.push(*face);
                face_parent.push(f as u32);
                kinds.push(FaceRefinement::Kept);
                continue;
            }
            let tri = mesh.triangle(f);
            let nrm = face.map(|i| normals[i as usize]);
            let patch = if !selected[f] {
                kinds.push(FaceRefinement::Transition);
                ring_patch(counts, 3, tri)
            } else {
                kinds.push(FaceRefinement::Refined);
                let n_max = counts.into_iter().max().unwrap_or(1);
                let within = |p: &Patch| {
                    let pos: Vec<DVec3> =
                        p.bary.iter().map(|&b| phong(tri, nrm, b, alpha)).collect();
                    p.tris
                        .iter()
                        .all(|t| (0..3).all(|k| pos[t[k]].distance(pos[t[(k + 1) % 3]]) <= h))
                };
                let mut patch = if counts.iter().all(|&c| c == n_max) {
                    Some(regular_patch(n_max)).filter(within)
                } else {
                    None
                };
                let mut n = n_max.max(3);
                while patch.is_none() {
                    let p = ring_patch(counts, n, tri);
                    if n >= 4 * n_max + 8 || within(&p) {
                        patch = Some(p);
                    }
                    n += 1;
                }
                patch.unwrap_or_else(|| ring_patch(counts, n, tri))
            };
            // Local points to fine vertex ids.
            let ids: Vec<u32> = patch
                .kind
                .iter()
                .zip(&patch.bary)
                .map(|(k, &bary)| match *k {
                    Local::Corner(c) => face[c],
                    Local::Edge(e, i) => {
                        let (a, b) = (face[e], face[(e + 1) % 3]);
                        let (n, first) = edges.get(&(a.min(b), a.max(b))).map_or((1, 0), |x| *x);
                        let k = if a < b { i } else { n - i };
                        first + k - 1
                    }
                    Local::Inner => {
                        points.push(FinePoint {
                            corners: *face,
                            bary,
                        });
                        (nv + points.len() - 1) as u32
                    }
                })
                .collect();
            for t in &patch.tris {
                faces.push(t.map(|i| ids[i]));
                face_parent.push(f as u32);
            }
        }
        Ok(Refinement {
            coarse_vertex_count: nv,
            coarse_faces: mesh.faces.clone(),
            phong_alpha: alpha,
            points,
            faces,
            face_parent,
            coarse_face_kind: kinds,
        })
    }

    /// Number of coarse vertices (fine vertices `0..` this count are the coarse ones).
    pub fn coarse_vertex_count(&self) -> usize {
        self.coarse_vertex_count
    }

    /// Number of fine vertices.
    pub fn fine_vertex_count(&self) -> usize {
        self.coarse_vertex_count + self.points.len()
    }

    /// The fine faces (counter-clockwise like their coarse parents).
    pub fn faces(&self) -> &[[u32; 3]] {
        &self.faces
    }

    /// The coarse face each fine face lies in.
    pub fn face_parents(&self) -> &[u32] {
        &self.face_parent
    }

    /// The coarse faces.
    pub fn coarse_faces(&self) -> &[[u32; 3]] {
        &self.coarse_faces
    }

    /// How each coarse face was refined.
    pub fn coarse_face_kinds(&self) -> &[FaceRefinement] {
        &self.coarse_face_kind
    }

    /// The Phong factor `α` of the evaluation.
    pub fn phong_alpha(&self) -> f64 {
        self.phong_alpha
    }

    /// Fine vertex `i` as a combination of coarse vertices (a coarse vertex is itself with
    /// weight 1), or `None` past the fine vertex count.
    pub fn point(&self, i: usize) -> Option<FinePoint> {
        if i < self.coarse_vertex_count {
            let v = i as u32;
            Some(FinePoint {
                corners: [v, v, v],
                bary: [1.0, 0.0, 0.0],
            })
        } else {
            self.points.get(i - self.coarse_vertex_count).copied()
        }
    }

    fn check_coarse(&self, what: &'static str, len: usize) -> Result<()> {
        check::same_size(what, self.coarse_vertex_count, len)
    }

    /// Area-weighted unit vertex normals of the coarse faces on `coarse` vertices.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] for a wrong vertex count.
    pub fn coarse_normals(&self, coarse: &[DVec3]) -> Result<Vec<DVec3>> {
        self.check_coarse("coarse vertices", coarse.len())?;
        Ok(area_normals(coarse, &self.coarse_faces))
    }

    /// The fine mesh on (posed) coarse vertices `coarse`: Phong tessellation with their
    /// area-weighted normals.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] for a wrong vertex count; [`Error::NonFinite`] for non-finite
    /// vertices.
    pub fn evaluate(&self, coarse: &[DVec3]) -> Result<TriMesh> {
        let normals = self.coarse_normals(coarse)?;
        let vertices = self.evaluate_with_normals(coarse, &normals)?;
        Ok(TriMesh {
            vertices,
            faces: self.faces.clone(),
        })
    }

    /// The fine vertex positions on coarse vertices `coarse` with the given unit vertex
    /// `normals` (e.g. [`Refinement::coarse_normals`]).
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] for wrong sizes; [`Error::NonFinite`] for non-finite input.
    pub fn evaluate_with_normals(&self, coarse: &[DVec3], normals: &[DVec3]) -> Result<Vec<DVec3>> {
        self.check_coarse("coarse vertices", coarse.len())?;
        self.check_coarse("coarse normals", normals.len())?;
        if !coarse.iter().chain(normals).all(|v| v.is_finite()) {
            return Err(Error::NonFinite {
                what: "coarse vertices or normals",
            });
        }
        let mut out = Vec::with_capacity(self.fine_vertex_count());
        out.extend_from_slice(coarse);
        let alpha = self.phong_alpha;
        let fine: Vec<DVec3> = self
            .points
            .par_iter()
            .map(|q| {
                let c = q.corners.map(|i| i as usize);
                phong(c.map(|i| coarse[i]), c.map(|i| normals[i]), q.bary, alpha)
            })
            .collect();
        out.extend(fine);
        Ok(out)
    }

    /// Linear (barycentric) interpolation of a per-coarse-vertex attribute to the fine
    /// vertices (e.g. rest positions on the flat facets, normals, skin weights' shares).
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] for a wrong count.
    pub fn interpolate<T>(&self, values: &[T]) -> Result<Vec<T>>
    where
        T: Copy + Send + Sync + std::ops::Mul<f64, Output = T> + std::ops::Add<Output = T>,
    {
        self.check_coarse("per-vertex values", values.len())?;
        let mut out = Vec::with_capacity(self.fine_vertex_count());
        out.extend_from_slice(values);
        let fine: Vec<T> = self
            .points
            .par_iter()
            .map(|q| {
                let c = q.corners.map(|i| values[i as usize]);
                c[0] * q.bary[0] + c[1] * q.bary[1] + c[2] * q.bary[2]
            })
            .collect();
        out.extend(fine);
        Ok(out)
    }
}

#[cfg(test)]
mod tests;
