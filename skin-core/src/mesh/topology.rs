//! Combinatorial structure of a triangle mesh: unique edges, one-ring adjacency, incident
//! faces, face adjacency, boundary and closedness.
//!
//! The one-ring ([`vertex_neighbors`]) is the stencil of the Laplacian of Vlasic's thesis
//! (§2.4.1, Eq. 2.1); boundaries and closedness decide whether signed distances and
//! inside/outside tests mean anything; face adjacency drives region growing and hole finding
//! (Ch. 3). Everything is built in O(F log F) from the face list and stored compactly
//! ([`Adjacency`], a CSR layout) so meshes of 10⁵–10⁶ faces are cheap.

use rayon::slice::ParallelSliceMut;

use crate::mesh::TriMesh;
use crate::Result;

/// A compressed sparse row (CSR) list of lists: row `i` is `values[offsets[i]..offsets[i+1]]`.
///
/// Used for vertex → neighbouring vertices and vertex → incident faces.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Adjacency {
    offsets: Vec<usize>,
    values: Vec<u32>,
}

impl Adjacency {
    /// Builds from `(row, value)` pairs over `rows` rows; each row's values are sorted and
    /// deduplicated.
    fn from_pairs(rows: usize, mut pairs: Vec<(u32, u32)>) -> Self {
        pairs.par_sort_unstable();
        pairs.dedup();
        let mut offsets = vec![0usize; rows + 1];
        for &(r, _) in &pairs {
            offsets[r as usize + 1] += 1;
        }
        for i in 0..rows {
            offsets[i + 1] += offsets[i];
        }
        let values = pairs.into_iter().map(|(_, v)| v).collect();
        Adjacency { offsets, values }
    }

    /// Number of rows (vertices).
    pub fn len(&self) -> usize {
        self.offsets.len() - 1
    }

    /// `true` when there are no rows.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Row `i` (sorted ascending), or an empty slice when `i` is out of range.
    pub fn row(&self, i: usize) -> &[u32] {
        match (self.offsets.get(i), self.offsets.get(i + 1)) {
            (Some(&s), Some(&e)) => &self.values[s..e],
            _ => &[],
        }
    }

    /// Row offsets (`len() + 1` entries, starting at 0).
    pub fn offsets(&self) -> &[usize] {
        &self.offsets
    }

    /// All values concatenated row after row.
    pub fn values(&self) -> &[u32] {
        &self.values
    }
}

/// The connected parts of a mesh (vertices joined by faces; a vertex in no face is a part of
/// its own): per vertex its part, numbered in the order of each part's first vertex, and the
/// vertex count of each part.
///
/// # Errors
/// As [`TriMesh::validate`].
///
/// # Example
/// ```
/// use skin_core::math::DVec3;
/// use skin_core::mesh::{connected_parts, TriMesh};
/// let v = vec![DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z, DVec3::ONE, DVec3::NEG_X, DVec3::NEG_Y];
/// let mesh = TriMesh::new(v, vec![[0, 1, 2], [3, 4, 5]])?;
/// let (part, sizes) = connected_parts(&mesh)?;
/// assert_eq!(part, [0, 0, 0, 1, 1, 1, 2]);
/// assert_eq!(sizes, [3, 3, 1]);
/// # Ok::<(), skin_core::Error>(())
/// ```
pub fn connected_parts(mesh: &TriMesh) -> Result<(Vec<u32>, Vec<usize>)> {
    mesh.validate()?;
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    let n = mesh.vertex_count();
    let mut parent: Vec<usize> = (0..n).collect();
    for f in &mesh.faces {
        let a = root(&mut parent, f[0] as usize);
        for &v in &f[1..] {
            let b = root(&mut parent, v as usize);
            if a != b {
                parent[b] = a;
            }
        }
    }
    let mut label = vec![u32::MAX; n];
    let mut sizes = Vec::new();
    let mut part = vec![0u32; n];
    for (v, p) in part.iter_mut().enumerate() {
        let r = root(&mut parent, v);
        if label[r] == u32::MAX {
            label[r] = sizes.len() as u32;
            sizes.push(0);
        }
        *p = label[r];
        sizes[label[r] as usize] += 1;
    }
    Ok((part, sizes))
}

/// Unique undirected edges as `[a, b]` with `a < b`, sorted. Degenerate edges of faces that
/// repeat a vertex (`a == b`) are left out.
///
/// # Errors
/// As [`TriMesh::validate`].
pub fn unique_edges(mesh: &TriMesh) -> Result<Vec<[u32; 2]>> {
    Ok(EdgeTopology::new(mesh)?.edges)
}

/// The one-ring of every vertex: the vertices sharing an edge with it (sorted, unique;
/// isolated vertices have an empty row).
///
/// # Errors
/// As [`TriMesh::validate`].
pub fn vertex_neighbors(mesh: &TriMesh) -> Result<Adjacency> {
    mesh.validate()?;
    let mut pairs = Vec::with_capacity(mesh.face_count() * 6);
    for f in &mesh.faces {
        for k in 0..3 {
            let (a, b) = (f[k], f[(k + 1) % 3]);
            if a != b {
                pairs.push((a, b));
                pairs.push((b, a));
            }
        }
    }
    Ok(Adjacency::from_pairs(mesh.vertex_count(), pairs))
}

/// The faces incident to every vertex (sorted, unique).
///
/// # Errors
/// As [`TriMesh::validate`].
pub fn vertex_faces(mesh: &TriMesh) -> Result<Adjacency> {
    mesh.validate()?;
    let mut pairs = Vec::with_capacity(mesh.face_count() * 3);
    for (fi, f) in mesh.faces.iter().enumerate() {
        for &v in f {
            pairs.push((v, fi as u32));
        }
    }
    Ok(Adjacency::from_pairs(mesh.vertex_count(), pairs))
}

/// Edges with the faces that use them, and the face-to-face adjacency derived from them.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct EdgeTopology {
    /// Unique undirected edges `[a, b]`, `a < b`, sorted.
    pub edges: Vec<[u32; 2]>,
    /// Number of faces using each edge (1: boundary, 2: interior manifold, ≥ 3: non-manifold).
    pub face_count: Vec<u32>,
    /// For face `f`, the face across its edge `k` (from corner `k` to corner `k + 1 mod 3`),
    /// or `None` when that edge is a boundary, non-manifold, or degenerate.
    pub face_neighbors: Vec<[Option<u32>; 3]>,
}

impl EdgeTopology {
    /// Builds the edge table of `mesh`.
    ///
    /// # Errors
    /// As [`TriMesh::validate`].
    pub fn new(mesh: &TriMesh) -> Result<Self> {
        mesh.validate()?;
        // (edge, face, local edge index) for every non-degenerate face edge.
        let mut half: Vec<([u32; 2], u32, u8)> = Vec::with_capacity(mesh.face_count() * 3);
        for (fi, f) in mesh.faces.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (f[k], f[(k + 1) % 3]);
                if a != b {
                    half.push(([a.min(b), a.max(b)], fi as u32, k as u8));
                }
            }
        }
        half.par_sort_unstable();
        let mut edges = Vec::new();
        let mut face_count = Vec::new();
        let mut face_neighbors = vec![[None; 3]; mesh.face_count()];
        let mut i = 0;
        while i < half.len() {
            let mut j = i + 1;
            while j < half.len() && half[j].0 == half[i].0 {
                j += 1;
            }
            edges.push(half[i].0);
            face_count.push((j - i) as u32);
            if j - i == 2 {
                let (e0, e1) = (half[i], half[i + 1]);
                face_neighbors[e0.1 as usize][e0.2 as usize] = Some(e1.1);
                face_neighbors[e1.1 as usize][e1.2 as usize] = Some(e0.1);
            }
            i = j;
        }
        Ok(EdgeTopology {
            edges,
            face_count,
            face_neighbors,
        })
    }

    /// Edges used by exactly one face.
    pub fn boundary_edges(&self) -> Vec<[u32; 2]> {
        self.edges_with(|c| c == 1)
    }

    /// Edges used by three or more faces.
    pub fn non_manifold_edges(&self) -> Vec<[u32; 2]> {
        self.edges_with(|c| c >= 3)
    }

    fn edges_with(&self, keep: impl Fn(u32) -> bool) -> Vec<[u32; 2]> {
        self.edges
            .iter()
            .zip(&self.face_count)
            .filter(|(_, &c)| keep(c))
            .map(|(e, _)| *e)
            .collect()
    }

    /// `true` when there is at least one edge and every edge is shared by exactly two faces
    /// (a closed 2-manifold surface away from its vertices). Orientation is not checked.
    pub fn is_closed(&self) -> bool {
        !self.edges.is_empty() && self.face_count.iter().all(|&c| c == 2)
    }
}

/// Edges used by exactly one face (the mesh boundary), `[a, b]` with `a < b`.
///
/// # Errors
/// As [`TriMesh::validate`].
pub fn boundary_edges(mesh: &TriMesh) -> Result<Vec<[u32; 2]>> {
    Ok(EdgeTopology::new(mesh)?.boundary_edges())
}

/// `true` when every edge of `mesh` is shared by exactly two faces (see
/// [`EdgeTopology::is_closed`]); `false` for a mesh without faces.
///
/// # Errors
/// As [`TriMesh::validate`].
pub fn is_closed(mesh: &TriMesh) -> Result<bool> {
    Ok(EdgeTopology::new(mesh)?.is_closed())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::DVec3;
    use crate::mesh::normals::tests::cube;
    use crate::Error;

    #[test]
    fn cube_is_closed_with_euler_characteristic_two() {
        let m = cube();
        let t = EdgeTopology::new(&m).unwrap();
        assert_eq!(t.edges.len(), 18);
        assert!(t.is_closed());
        assert!(t.boundary_edges().is_empty());
        let chi = m.vertex_count() as i64 - t.edges.len() as i64 + m.face_count() as i64;
        assert_eq!(chi, 2);
        // Every face has three neighbours, and adjacency is symmetric.
        for (f, nb) in t.face_neighbors.iter().enumerate() {
            for g in nb {
                let g = g.unwrap() as usize;
                assert!(t.face_neighbors[g].contains(&Some(f as u32)));
            }
        }
        let ring = vertex_neighbors(&m).unwrap();
        let degree_sum: usize = (0..ring.len()).map(|v| ring.row(v).len()).sum();
        assert_eq!(degree_sum, 2 * t.edges.len());
        let vf = vertex_faces(&m).unwrap();
        let incidences: usize = (0..vf.len()).map(|v| vf.row(v).len()).sum();
        assert_eq!(incidences, 3 * m.face_count());
    }

    #[test]
    fn open_quad_boundary_and_rings() {
        let m = TriMesh::new(
            vec![DVec3::ZERO, DVec3::X, DVec3::ONE, DVec3::Y, DVec3::Z],
            vec![[0, 1, 2], [0, 2, 3]],
        )
        .unwrap();
        let t = EdgeTopology::new(&m).unwrap();
        assert_eq!(t.edges, vec![[0, 1], [0, 2], [0, 3], [1, 2], [2, 3]]);
        assert_eq!(t.boundary_edges(), vec![[0, 1], [0, 3], [1, 2], [2, 3]]);
        assert!(!t.is_closed());
        assert_eq!(t.face_neighbors[0], [None, None, Some(1)]);
        assert_eq!(t.face_neighbors[1], [Some(0), None, None]);
        let ring = vertex_neighbors(&m).unwrap();
        assert_eq!(ring.row(0), &[1, 2, 3]);
        assert_eq!(ring.row(4), &[] as &[u32]);
        assert_eq!(ring.row(99), &[] as &[u32]);
        assert_eq!(ring.offsets().len(), 6);
    }

    #[test]
    fn non_manifold_and_degenerate_faces() {
        // Three faces on one edge, plus a face repeating a vertex.
        let m = TriMesh::new(
            vec![DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z, DVec3::NEG_Y],
            vec![[0, 1, 2], [1, 0, 3], [0, 1, 4], [2, 2, 3]],
        )
        .unwrap();
        let t = EdgeTopology::new(&m).unwrap();
        assert_eq!(t.non_manifold_edges(), vec![[0, 1]]);
        assert_eq!(t.face_neighbors[0][0], None);
        assert!(!t.edges.contains(&[2, 2]));
        assert!(!is_closed(&m).unwrap());
    }

    #[test]
    fn empty_and_invalid_meshes() {
        let empty = TriMesh::default();
        assert!(unique_edges(&empty).unwrap().is_empty());
        assert!(!is_closed(&empty).unwrap());
        assert!(vertex_neighbors(&empty).unwrap().is_empty());
        let bad = TriMesh {
            vertices: vec![DVec3::ZERO; 2],
            faces: vec![[0, 1, 2]],
        };
        assert!(matches!(
            boundary_edges(&bad),
            Err(Error::IndexOutOfRange { .. })
        ));
        assert!(matches!(
            vertex_faces(&bad),
            Err(Error::IndexOutOfRange { .. })
        ));
    }
}
