//! Marching cubes over a **sparse** set of grid cells, shared by the volumetric merge (§3.3.3)
//! and the screened Poisson hole filling.
//!
//! `skin_core::mesh::marching_cubes` polygonises a dense [`skin_core::mesh::ScalarGrid`] by
//! marching tetrahedra; the merge's volume is a hash of 8³-voxel blocks and the Poisson
//! indicator lives on a hierarchy of sparse grids, so this module takes a list of cells and a
//! node → value function instead (`None` = unobserved: a cell with an unobserved corner emits
//! nothing, so the surface stops at the edge of the observed region).
//!
//! Rather than the 256-case table, each cell's polygons are built at run time by walking its
//! faces: on every face the iso-crossings of its edges are joined into segments, and the
//! segments chain into closed loops (one per surface sheet in the cell), fanned into triangles.
//! A face with four crossings is ambiguous; it is resolved by the **asymptotic decider**
//! (Nielson & Hamann 1991): the two inside corners are joined iff the bilinear interpolant's
//! saddle value is inside, i.e. iff `|f_in1 · f_in2| > |f_out1 · f_out2|` with `f = value − iso`.
//! A face's decision depends only on its four corner values, so the two cells that share it
//! draw the same segments: the output is **watertight and 2-manifold wherever all cells around
//! a surface are present**. Vertices sit on grid edges (keyed by edge, shared between cells),
//! placed by linear interpolation. Triangles face towards larger values ("outside").

use std::collections::{HashMap, HashSet};
use std::hash::{BuildHasherDefault, Hasher};

use skin_core::math::DVec3;
use skin_core::mesh::TriMesh;

use crate::Result;

/// Integer grid node (or cell, by its lowest corner).
pub(crate) type Node = [i64; 3];

/// A multiplicative hasher for integer grid keys (the std SipHash is several times slower
/// on the millions of node look-ups of the merge and the extraction; keys here are not
/// attacker-controlled).
#[derive(Default, Clone, Copy)]
pub(crate) struct NodeHasher(u64);

impl Hasher for NodeHasher {
    fn finish(&self) -> u64 {
        self.0
    }

    fn write(&mut self, bytes: &[u8]) {
        let mut chunks = bytes.chunks_exact(8);
        for c in &mut chunks {
            let mut word = [0u8; 8];
            word.copy_from_slice(c);
            self.write_u64(u64::from_le_bytes(word));
        }
        for &b in chunks.remainder() {
            self.write_u64(u64::from(b));
        }
    }

    fn write_u64(&mut self, v: u64) {
        self.0 = (self.0.rotate_left(5) ^ v).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }

    fn write_i64(&mut self, v: i64) {
        self.write_u64(v as u64);
    }

    fn write_u8(&mut self, v: u8) {
        self.write_u64(u64::from(v));
    }

    fn write_usize(&mut self, v: usize) {
        self.write_u64(v as u64);
    }
}

/// A `HashMap` keyed by grid nodes with [`NodeHasher`].
pub(crate) type NodeMap<K, V> = HashMap<K, V, BuildHasherDefault<NodeHasher>>;
/// A `HashSet` of grid nodes with [`NodeHasher`].
pub(crate) type NodeSet<K> = HashSet<K, BuildHasherDefault<NodeHasher>>;

/// Whether the cell at `cell` has all eight corners observed and corners on both sides of
/// `iso`: exactly the cells [`march_cells_par`] draws something in (a cheap test to run in
/// parallel before the polygonisation; the reference of the merge's `straddling_cells`).
#[cfg(test)]
pub(crate) fn cell_straddles(
    cell: Node,
    mut value: impl FnMut(Node) -> Option<f64>,
    iso: f64,
) -> bool {
    let (mut below, mut above) = (false, false);
    for c in 0..8 {
        let o = corner_offset(c);
        match value([cell[0] + o[0], cell[1] + o[1], cell[2] + o[2]]) {
            None => return false,
            Some(v) if v - iso < 0.0 => below = true,
            Some(_) => above = true,
        }
    }
    below && above
}

/// Cube corner `c` sits at offset `(c & 1, (c >> 1) & 1, (c >> 2) & 1)`.
const fn corner_offset(c: usize) -> [i64; 3] {
    [(c & 1) as i64, ((c >> 1) & 1) as i64, ((c >> 2) & 1) as i64]
}

/// The six faces, corners in counter-clockwise order seen from outside the cube.
const FACES: [[usize; 4]; 6] = [
    [0, 4, 6, 2],
    [1, 3, 7, 5],
    [0, 1, 5, 4],
    [2, 6, 7, 3],
    [0, 2, 3, 1],
    [4, 5, 7, 6],
];

/// Cube edge id of the corner pair `(a, b)` (adjacent corners): lower corner × 3 + axis.
fn edge_id(a: usize, b: usize) -> usize {
    let (lo, hi) = if a < b { (a, b) } else { (b, a) };
    let axis = match hi - lo {
        1 => 0,
        2 => 1,
        _ => 2,
    };
    lo * 3 + axis
}

/// Bit set of the cube faces (indices into [`FACES`]) that contain cube edge `e`.
fn edge_faces(e: usize) -> u8 {
    let mut bits = 0;
    for (i, face) in FACES.iter().enumerate() {
        if (0..4).any(|k| edge_id(face[k], face[(k + 1) % 4]) == e) {
            bits |= 1 << i;
        }
    }
    bits
}

/// A loop vertex from which a triangle fan draws no diagonal between two crossings on one
/// cube face (such a diagonal could be drawn by the neighbouring cell as well, making an
/// edge shared by four triangles); `None` if there is none.
fn fan_apex(poly: &[usize]) -> Option<usize> {
    let n = poly.len();
    (0..n).find(|&a| (2..n - 1).all(|i| edge_faces(poly[a]) & edge_faces(poly[(a + i) % n]) == 0))
}

/// Polygon loops (as cube-edge ids, in order) of one cell with corner values `f` (already
/// minus the iso value; `f < 0` is inside).
fn cell_loops(f: &[f64; 8]) -> Vec<Vec<usize>> {
    let inside: [bool; 8] = std::array::from_fn(|c| f[c] < 0.0);
    if inside.iter().all(|&b| b) || inside.iter().all(|&b| !b) {
        return Vec::new();
    }
    // next[e] = the crossing that follows crossing e along its loop.
    let mut next = [usize::MAX; 24];
    for face in FACES {
        // The face's crossings (at most 4), without an allocation per face.
        let mut crossings = [0usize; 4];
        let mut count = 0;
        for k in 0..4 {
            if inside[face[k]] != inside[face[(k + 1) % 4]] {
                crossings[count] = k;
                count += 1;
            }
        }
        let edge = |k: usize| edge_id(face[k % 4], face[(k + 1) % 4]);
        match count {
            2 => {
                // A segment runs from the out→in crossing to the in→out crossing.
                let (a, b) = (crossings[0], crossings[1]);
                let (from, to) = if inside[face[a]] { (b, a) } else { (a, b) };
                next[edge(from)] = edge(to);
            }
            4 => {
                // Corners alternate; k = the first inside corner, so edges k, k+2 are in→out.
                let k = if inside[face[0]] { 0 } else { 1 };
                let fin = f[face[k]] * f[face[k + 2]];
                let fout = f[face[(k + 1) % 4]] * f[face[(k + 3) % 4]];
                if fin.abs() > fout.abs() {
                    // Inside corners joined: cut off the two outside corners.
                    next[edge(k + 1)] = edge(k);
                    next[edge(k + 3)] = edge(k + 2);
                } else {
                    // Inside corners separated: cut off each inside corner.
                    next[edge(k + 1)] = edge(k + 2);
                    next[edge(k + 3)] = edge(k);
                }
            }
            _ => {}
        }
    }
    let mut loops = Vec::new();
    let mut used = [false; 24];
    for start in 0..24 {
        if next[start] == usize::MAX || used[start] {
            continue;
        }
        let mut poly = Vec::new();
        let mut e = start;
        while !used[e] && next[e] != usize::MAX {
            used[e] = true;
            poly.push(e);
            e = next[e];
        }
        if poly.len() >= 3 {
            loops.push(poly);
        }
    }
    loops
}

/// Polygonises the `iso` surface of `value` over `cells` (each by its lowest node); nodes map
/// to world points by `position`. Cells with an unobserved (`None`) corner are skipped.
///
/// # Errors
/// Errors of [`TriMesh::new`] (none for a valid field).
#[cfg(test)]
pub(crate) fn march_cells(
    cells: impl IntoIterator<Item = Node>,
    value: impl FnMut(Node) -> Option<f64>,
    iso: f64,
    position: impl Fn(Node) -> DVec3,
) -> Result<TriMesh> {
    march_cells_with(cells, value, iso, position, EdgeFit::Linear)
}

/// How a vertex is placed on a grid edge whose ends straddle the iso-value.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum EdgeFit {
    /// Linear interpolation between the edge's two node values (classic marching cubes).
    Linear,
    /// The zero, inside the edge, of the cubic through the values at the four collinear nodes
    /// around it (the edge's ends and one node beyond each, where observed; linear otherwise).
    /// For a smooth field whose profile across the surface is not linear over one cell (the
    /// Poisson indicator is a smoothed step a few cells wide) this removes most of the
    /// linear interpolation's error; the vertex stays on its edge, so the topology and
    /// watertightness are those of the linear placement.
    Cubic,
}

/// Zero in `[0, 1]` of the cubic through `(−1, f0) (0, f1) (1, f2) (2, f3)`, given that `f1` and
/// `f2` straddle zero: bisection on the Lagrange form (the cubic's ends have opposite signs).
fn cubic_edge_zero(f0: f64, f1: f64, f2: f64, f3: f64) -> f64 {
    let c = |x: f64| {
        -f0 * x * (x - 1.0) * (x - 2.0) / 6.0 + f1 * (x + 1.0) * (x - 1.0) * (x - 2.0) / 2.0
            - f2 * (x + 1.0) * x * (x - 2.0) / 2.0
            + f3 * (x + 1.0) * x * (x - 1.0) / 6.0
    };
    let (mut lo, mut hi) = (0.0, 1.0);
    let lo_neg = f1 < 0.0;
    for _ in 0..40 {
        let mid = 0.5 * (lo + hi);
        if (c(mid) < 0.0) == lo_neg {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

#[cfg(test)]
pub(crate) mod tests_support {
    /// The private cubic edge fit, for the Poisson tests.
    pub(crate) fn cubic_zero(f0: f64, f1: f64, f2: f64, f3: f64) -> f64 {
        super::cubic_edge_zero(f0, f1, f2, f3)
    }
}

/// One serial march (the reference of [`march_cells_par`]) with a choice of vertex placement
/// on the edges.
#[cfg(test)]
pub(crate) fn march_cells_with(
    cells: impl IntoIterator<Item = Node>,
    value: impl FnMut(Node) -> Option<f64>,
    iso: f64,
    position: impl Fn(Node) -> DVec3,
    fit: EdgeFit,
) -> Result<TriMesh> {
    let chunk = march_chunk(cells, value, iso, &position, fit);
    Ok(TriMesh::new(chunk.vertices, chunk.faces)?)
}

/// Cells marched apart: vertices, faces, and the grid edge of each vertex (`None` for a
/// loop's centroid).
struct Chunk {
    vertices: Vec<DVec3>,
    faces: Vec<[u32; 3]>,
    keys: Vec<Option<(Node, u8)>>,
}

/// Polygonises the `iso` surface of `value` over `cells` (each by its lowest node; cells with
/// an unobserved (`None`) corner are skipped), nodes mapped to world points by `position`,
/// vertices placed on the edges by `fit`:
/// over chunks of `cells` in parallel, each with its own value function
/// from `make_value` (e.g. with a cache of its own), stitched in order by shared grid edges:
/// the same mesh, vertex for vertex and face for face, as one serial march over `cells`.
pub(crate) fn march_cells_par<V: FnMut(Node) -> Option<f64>>(
    cells: &[Node],
    chunk_cells: usize,
    make_value: impl Fn() -> V + Sync,
    iso: f64,
    position: impl Fn(Node) -> DVec3 + Sync,
    fit: EdgeFit,
) -> Result<TriMesh> {
    use rayon::prelude::*;
    let chunks: Vec<Chunk> = cells
        .par_chunks(chunk_cells.max(1))
        .map(|c| march_chunk(c.iter().copied(), make_value(), iso, &position, fit))
        .collect();
    let mut vertices: Vec<DVec3> = Vec::new();
    let mut faces: Vec<[u32; 3]> = Vec::new();
    let mut edge_vertex: NodeMap<(Node, u8), u32> = NodeMap::default();
    for chunk in chunks {
        // Local vertex → global: an edge vertex made by an earlier chunk is that one (the
        // same edge, the same node values: the same position); others are appended in the
        // chunk's order, which is the serial march's order.
        let map: Vec<u32> = chunk
            .keys
            .iter()
            .zip(&chunk.vertices)
            .map(|(key, &p)| {
                let mut push = || {
                    vertices.push(p);
                    (vertices.len() - 1) as u32
                };
                match key {
                    Some(k) => *edge_vertex.entry(*k).or_insert_with(push),
                    None => push(),
                }
            })
            .collect();
        faces.extend(chunk.faces.iter().map(|f| f.map(|i| map[i as usize])));
    }
    Ok(TriMesh::new(vertices, faces)?)
}

/// One serial march over `cells`.
fn march_chunk(
    cells: impl IntoIterator<Item = Node>,
    mut value: impl FnMut(Node) -> Option<f64>,
    iso: f64,
    position: &impl Fn(Node) -> DVec3,
    fit: EdgeFit,
) -> Chunk {
    let mut vertices: Vec<DVec3> = Vec::new();
    let mut keys: Vec<Option<(Node, u8)>> = Vec::new();
    let mut faces: Vec<[u32; 3]> = Vec::new();
    let mut edge_vertex: NodeMap<(Node, u8), u32> = NodeMap::default();
    'cells: for cell in cells {
        let mut f = [0.0; 8];
        let mut nodes = [[0i64; 3]; 8];
        for (c, fc) in f.iter_mut().enumerate() {
            let o = corner_offset(c);
            let n = [cell[0] + o[0], cell[1] + o[1], cell[2] + o[2]];
            let Some(v) = value(n) else {
                continue 'cells;
            };
            nodes[c] = n;
            *fc = v - iso;
        }
        let loops = cell_loops(&f);
        if loops.is_empty() {
            continue;
        }
        let mut vertex =
            |e: usize, vertices: &mut Vec<DVec3>, keys: &mut Vec<Option<(Node, u8)>>| -> u32 {
                let (lo, axis) = (e / 3, e % 3);
                let hi = lo | (1 << axis);
                let key = (nodes[lo], axis as u8);
                *edge_vertex.entry(key).or_insert_with(|| {
                    let (a, b) = (f[lo], f[hi]);
                    // a and b straddle zero (one is < 0, the other ≥ 0), so a ≠ b.
                    let linear = (a / (a - b)).clamp(0.0, 1.0);
                    let t = match fit {
                        EdgeFit::Linear => linear,
                        EdgeFit::Cubic => {
                            let mut before = nodes[lo];
                            before[axis] -= 1;
                            let mut after = nodes[hi];
                            after[axis] += 1;
                            match (value(before), value(after)) {
                                (Some(f0), Some(f3)) => cubic_edge_zero(f0 - iso, a, b, f3 - iso),
                                _ => linear,
                            }
                        }
                    };
                    vertices.push(position(nodes[lo]).lerp(position(nodes[hi]), t));
                    keys.push(Some(key));
                    (vertices.len() - 1) as u32
                })
            };
        for poly in loops {
            let ids: Vec<u32> = poly
                .iter()
                .map(|&e| vertex(e, &mut vertices, &mut keys))
                .collect();
            match fan_apex(&poly) {
                Some(a) => {
                    let n = ids.len();
                    for i in 1..n - 1 {
                        faces.push([ids[a], ids[(a + i) % n], ids[(a + i + 1) % n]]);
                    }
                }
                None => {
                    // Every fan would draw a diagonal across a cube face, which the
                    // neighbouring cell may draw too: fan around the loop's centroid.
                    let c =
                        ids.iter().map(|&i| vertices[i as usize]).sum::<DVec3>() / ids.len() as f64;
                    vertices.push(c);
                    keys.push(None);
                    let ci = (vertices.len() - 1) as u32;
                    for i in 0..ids.len() {
                        faces.push([ci, ids[i], ids[(i + 1) % ids.len()]]);
                    }
                }
            }
        }
    }
    Chunk {
        vertices,
        faces,
        keys,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use skin_core::mesh::EdgeTopology;

    fn signed_volume(m: &TriMesh) -> f64 {
        m.faces
            .iter()
            .map(|f| {
                let [a, b, c] = f.map(|i| m.vertices[i as usize]);
                a.dot(b.cross(c)) / 6.0
            })
            .sum()
    }

    fn euler(m: &TriMesh) -> i64 {
        let e = skin_core::mesh::unique_edges(m).unwrap().len() as i64;
        m.vertex_count() as i64 - e + m.face_count() as i64
    }

    fn grid_cells(n: i64) -> Vec<Node> {
        let mut cells = Vec::new();
        for k in 0..n {
            for j in 0..n {
                for i in 0..n {
                    cells.push([i, j, k]);
                }
            }
        }
        cells
    }

    #[test]
    fn parallel_march_is_the_serial_mesh() {
        // Two touching blobs with a saddle (ambiguous faces, centroid fans), cubic edge fits
        // reading outside the cells, and a gap of unobserved nodes.
        let value = |p: Node| -> Option<f64> {
            if p[0] == 9 && p[1] < 4 {
                return None;
            }
            let q = DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64);
            let a = (q - DVec3::new(6.3, 7.1, 8.2)).length() - 5.2;
            let b = (q - DVec3::new(13.7, 8.4, 7.9)).length() - 4.9;
            Some(a.min(b) + 0.3 * (0.9 * q.x).sin() * (1.3 * q.y).cos())
        };
        let position = |p: Node| DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64) * 0.01;
        let cells = grid_cells(20);
        let serial = march_cells_with(cells.clone(), value, 0.0, position, EdgeFit::Cubic).unwrap();
        assert!(serial.face_count() > 1000);
        for chunk in [1, 7, 500, 100_000] {
            let par =
                march_cells_par(&cells, chunk, || value, 0.0, position, EdgeFit::Cubic).unwrap();
            assert_eq!(par.vertices, serial.vertices, "chunk {chunk}");
            assert_eq!(par.faces, serial.faces, "chunk {chunk}");
        }
    }

    #[test]
    fn sphere_is_closed_outward_and_on_the_surface() {
        let h = 0.05;
        let pos = |n: Node| DVec3::new(n[0] as f64, n[1] as f64, n[2] as f64) * h - 1.0;
        let mesh = march_cells(grid_cells(40), |n| Some(pos(n).length() - 0.6), 0.0, pos).unwrap();
        let topo = EdgeTopology::new(&mesh).unwrap();
        assert!(topo.is_closed() && topo.non_manifold_edges().is_empty());
        assert_eq!(euler(&mesh), 2);
        let exact = 4.0 / 3.0 * std::f64::consts::PI * 0.6f64.powi(3);
        assert!((signed_volume(&mesh) - exact).abs() < 0.02 * exact);
        assert!(mesh
            .vertices
            .iter()
            .all(|v| (v.length() - 0.6).abs() < 0.01));
    }

    #[test]
    fn ambiguous_random_fields_stay_watertight() {
        // Random values inside, positive on the border: every face case, ambiguous ones
        // included, occurs; the result must be closed and manifold.
        let rng = skin_core::random::SplitMix64::new(7);
        let mut draw = 0u64;
        let n = 12i64;
        let mut vals = HashMap::new();
        for k in 0..=n {
            for j in 0..=n {
                for i in 0..=n {
                    let border = [i, j, k].iter().any(|&c| c == 0 || c == n);
                    let v = if border {
                        1.0
                    } else {
                        {
                            draw += 1;
                            rng.uniform_at(draw) - 0.5
                        }
                    };
                    vals.insert([i, j, k], v);
                }
            }
        }
        let pos = |n: Node| DVec3::new(n[0] as f64, n[1] as f64, n[2] as f64);
        let mesh = march_cells(grid_cells(n), |p| vals.get(&p).copied(), 0.0, pos).unwrap();
        assert!(mesh.face_count() > 500);
        let topo = EdgeTopology::new(&mesh).unwrap();
        assert!(
            topo.is_closed(),
            "{} boundary edges",
            topo.boundary_edges().len()
        );
        assert!(topo.non_manifold_edges().is_empty());
    }

    #[test]
    fn unobserved_corners_leave_an_open_boundary() {
        let pos = |n: Node| DVec3::new(n[0] as f64, n[1] as f64, n[2] as f64) * 0.1 - 1.0;
        let field = |n: Node| (n[2] < 15).then(|| pos(n).length() - 0.6);
        let mesh = march_cells(grid_cells(20), field, 0.0, pos).unwrap();
        let topo = EdgeTopology::new(&mesh).unwrap();
        assert!(!topo.is_closed());
        assert!(topo.non_manifold_edges().is_empty());
        assert!(mesh.vertices.iter().all(|v| v.z < 0.45));
    }
}
