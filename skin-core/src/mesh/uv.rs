//! Texture coordinates of a triangle mesh: [`UvLayout`] keeps them per face corner, as OBJ
//! files and texture atlases do (a vertex on a seam has one coordinate per side), and
//! [`UvLayout::split_seams`] turns them into the per-vertex coordinates renderers and glTF
//! need, duplicating exactly the seam vertices.
//!
//! A mesh sequence in correspondence (every frame the template's vertices and faces, e.g. a
//! template-silhouette capture, Vlasic 2010 §2.5.3) keeps its template's layout in every
//! frame: [`UvSplit::gather`] maps each frame's vertices onto the split vertices.

use serde::{Deserialize, Serialize};

use super::TriMesh;
use crate::math::{DVec2, DVec3};
use crate::{check, Error, Result};

/// Texture coordinates per face corner: `faces[f][k]` indexes `coords` for corner `k` of
/// the mesh's face `f` (OBJ convention: `v` up, `[0, 1]²` the image).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct UvLayout {
    /// The distinct coordinates.
    pub coords: Vec<DVec2>,
    /// Per mesh face, the coordinate index of each corner.
    pub faces: Vec<[u32; 3]>,
}

/// A mesh's faces re-indexed over (vertex, coordinate) pairs, from [`UvLayout::split_seams`].
#[derive(Debug, Clone, PartialEq)]
pub struct UvSplit {
    /// Faces over the split vertices, in the mesh's face order.
    pub faces: Vec<[u32; 3]>,
    /// One coordinate per split vertex.
    pub uvs: Vec<DVec2>,
    /// `vertex[i]` is the mesh vertex of split vertex `i`.
    pub vertex: Vec<u32>,
}

impl UvLayout {
    /// Checks the layout against `mesh`: one entry per face, indices in range, finite
    /// coordinates.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`], [`Error::IndexOutOfRange`], [`Error::NonFinite`].
    pub fn validate(&self, mesh: &TriMesh) -> Result<()> {
        self.validate_for_faces(mesh.face_count())
    }

    /// [`UvLayout::validate`] against a mesh of `face_count` faces (the layout does not look
    /// at vertex positions).
    ///
    /// # Errors
    /// As [`UvLayout::validate`].
    pub fn validate_for_faces(&self, face_count: usize) -> Result<()> {
        check::same_size(
            "UV layout faces vs mesh faces",
            face_count,
            self.faces.len(),
        )?;
        check::all_finite(
            "texture coordinates",
            self.coords.iter().flat_map(|c| [&c.x, &c.y]),
        )?;
        for f in &self.faces {
            for &c in f {
                check::index("texture coordinate index", c as usize, self.coords.len())?;
            }
        }
        Ok(())
    }

    /// This layout followed by `other`'s for the faces appended after this layout's (as
    /// [`TriMesh`] faces are appended when a garment joins a body).
    pub fn concat(&self, other: &UvLayout) -> UvLayout {
        let n = self.coords.len() as u32;
        UvLayout {
            coords: self.coords.iter().chain(&other.coords).copied().collect(),
            faces: self
                .faces
                .iter()
                .copied()
                .chain(other.faces.iter().map(|f| f.map(|c| c + n)))
                .collect(),
        }
    }

    /// A cylindrical projection of `mesh` about the vertical line through `centre` (`+Y`):
    /// `u` the angle about it over a full turn, `v` the height between the mesh's lowest
    /// and highest vertex. Faces that straddle the `u = 0 / 1` seam get their own
    /// coordinates on the far side, so no face wraps across the texture. For a tube such as
    /// a skirt, which has no coordinates of its own.
    ///
    /// # Errors
    /// [`Error::Degenerate`] for a mesh without height; as [`TriMesh::validate`].
    pub fn cylindrical(mesh: &TriMesh, centre: DVec3) -> Result<UvLayout> {
        mesh.validate()?;
        let bb = mesh.bounding_box()?;
        let height = bb.max.y - bb.min.y;
        if height <= 0.0 {
            return Err(Error::Degenerate {
                what: "cylindrical texture coordinates of a mesh without height".into(),
            });
        }
        let uv = |p: DVec3| {
            let d = p - centre;
            let u = d.x.atan2(d.z) / std::f64::consts::TAU;
            DVec2::new(u.rem_euclid(1.0), (p.y - bb.min.y) / height)
        };
        let mut coords: Vec<DVec2> = mesh.vertices.iter().map(|p| uv(*p)).collect();
        let mut faces = Vec::with_capacity(mesh.face_count());
        for f in &mesh.faces {
            let us = f.map(|v| coords[v as usize].x);
            let span =
                us.iter().fold(0.0f64, |m, u| m.max(*u)) - us.iter().fold(1.0f64, |m, u| m.min(*u));
            if span <= 0.5 {
                faces.push(*f);
                continue;
            }
            // Across the seam: corners near u = 0 get a copy at u + 1.
            faces.push(f.map(|v| {
                let c = coords[v as usize];
                if c.x < 0.5 {
                    coords.push(DVec2::new(c.x + 1.0, c.y));
                    (coords.len() - 1) as u32
                } else {
                    v
                }
            }));
        }
        Ok(UvLayout { coords, faces })
    }

    /// The layout of a mesh whose vertices are a subset of `mesh`'s (a [`decimate`]d mesh:
    /// `coarse` with `original_index[i]` the original vertex of coarse vertex `i`). Each
    /// coarse corner takes one of the coordinates its original vertex has in `mesh`; on a
    /// seam, where it has several, the face takes the combination with the smallest perimeter
    /// in texture space (the copies on the face's own side of the seam).
    ///
    /// [`decimate`]: crate::mesh
    ///
    /// # Errors
    /// As [`UvLayout::validate`]; [`Error::IndexOutOfRange`] for an original index outside
    /// `mesh`; [`Error::Degenerate`] for a coarse vertex that no face of `mesh` uses.
    pub fn for_vertex_subset(
        &self,
        mesh: &TriMesh,
        coarse: &TriMesh,
        original_index: &[u32],
    ) -> Result<UvLayout> {
        self.validate(mesh)?;
        check::same_size(
            "original indices vs coarse vertices",
            coarse.vertex_count(),
            original_index.len(),
        )?;
        let mut candidates: Vec<Vec<u32>> = vec![Vec::new(); mesh.vertex_count()];
        for (f, c) in mesh.faces.iter().zip(&self.faces) {
            for k in 0..3 {
                let list = &mut candidates[f[k] as usize];
                if !list.contains(&c[k]) {
                    list.push(c[k]);
                }
            }
        }
        let mut faces = Vec::with_capacity(coarse.face_count());
        for f in &coarse.faces {
            let mut corner: [&[u32]; 3] = [&[]; 3];
            for k in 0..3 {
                let o = *original_index
                    .get(f[k] as usize)
                    .ok_or(Error::IndexOutOfRange {
                        what: "coarse face vertex",
                        index: f[k] as usize,
                        len: original_index.len(),
                    })? as usize;
                check::index("original vertex", o, mesh.vertex_count())?;
                corner[k] = &candidates[o];
                if corner[k].is_empty() {
                    return Err(Error::Degenerate {
                        what: format!("original vertex {o} has no texture coordinate"),
                    });
                }
            }
            let uv = |c: u32| self.coords[c as usize];
            let mut best = ([0u32; 3], f64::INFINITY);
            for &a in corner[0] {
                for &b in corner[1] {
                    for &c in corner[2] {
                        let p =
                            uv(a).distance(uv(b)) + uv(b).distance(uv(c)) + uv(c).distance(uv(a));
                        if p < best.1 {
                            best = ([a, b, c], p);
                        }
                    }
                }
            }
            faces.push(best.0);
        }
        Ok(UvLayout {
            coords: self.coords.clone(),
            faces,
        })
    }

    /// Splits the mesh's vertices where they carry more than one coordinate (UV seams): one
    /// split vertex per distinct (vertex, coordinate index) pair, in order of first use.
    ///
    /// # Errors
    /// As [`UvLayout::validate`].
    pub fn split_seams(&self, mesh: &TriMesh) -> Result<UvSplit> {
        self.validate(mesh)?;
        let mut index = std::collections::HashMap::new();
        let mut split = UvSplit {
            faces: Vec::with_capacity(mesh.face_count()),
            uvs: Vec::new(),
            vertex: Vec::new(),
        };
        for (f, c) in mesh.faces.iter().zip(&self.faces) {
            let mut out = [0u32; 3];
            for k in 0..3 {
                out[k] = *index.entry((f[k], c[k])).or_insert_with(|| {
                    split.uvs.push(self.coords[c[k] as usize]);
                    split.vertex.push(f[k]);
                    (split.vertex.len() - 1) as u32
                });
            }
            split.faces.push(out);
        }
        Ok(split)
    }
}

impl UvSplit {
    /// The split vertices' positions from the mesh's `vertices` (one frame of a sequence).
    ///
    /// # Errors
    /// [`Error::IndexOutOfRange`] if `vertices` is shorter than the mesh the split came from.
    pub fn gather(&self, vertices: &[DVec3]) -> Result<Vec<DVec3>> {
        self.vertex
            .iter()
            .map(|&v| {
                check::index("split vertex", v as usize, vertices.len())?;
                Ok(vertices[v as usize])
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::shapes;

    /// An open tube about the `+Y` axis.
    fn cylinder(radius: f64, length: f64, segments: u32, rings: u32) -> Result<TriMesh> {
        let mut tube = shapes::cylinder(radius, length, segments, rings)?;
        for v in &mut tube.vertices {
            *v = DVec3::new(v.x, v.z, v.y);
        }
        Ok(tube)
    }

    #[test]
    fn a_seam_duplicates_only_its_vertices() {
        // Two triangles sharing the edge 1-2; the second gives vertex 2 another coordinate.
        let mesh = TriMesh::new(
            vec![DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::new(1.0, 1.0, 0.0)],
            vec![[0, 1, 2], [1, 3, 2]],
        )
        .unwrap();
        let layout = UvLayout {
            coords: vec![
                DVec2::new(0.0, 0.0),
                DVec2::new(1.0, 0.0),
                DVec2::new(0.0, 1.0),
                DVec2::new(1.0, 1.0),
                DVec2::new(0.5, 0.5),
            ],
            faces: vec![[0, 1, 2], [1, 3, 4]],
        };
        let split = layout.split_seams(&mesh).unwrap();
        assert_eq!(split.vertex, vec![0, 1, 2, 3, 2]);
        assert_eq!(split.faces, vec![[0, 1, 2], [1, 3, 4]]);
        assert_eq!(split.uvs[4], DVec2::new(0.5, 0.5));
        let moved: Vec<DVec3> = mesh.vertices.iter().map(|v| *v * 2.0).collect();
        assert_eq!(split.gather(&moved).unwrap()[4], DVec3::new(0.0, 2.0, 0.0));
        assert!(split.gather(&moved[..2]).is_err());
    }

    #[test]
    fn a_cylinder_unrolls_without_a_face_across_the_texture() {
        let mesh = cylinder(0.5, 1.0, 24, 4).unwrap();
        let layout = UvLayout::cylindrical(&mesh, DVec3::ZERO).unwrap();
        layout.validate(&mesh).unwrap();
        for f in &layout.faces {
            let us = f.map(|c| layout.coords[c as usize].x);
            let span = us.iter().cloned().fold(f64::MIN, f64::max)
                - us.iter().cloned().fold(f64::MAX, f64::min);
            assert!(span < 0.2, "a face spans {span} of the turn");
        }
        let split = layout.split_seams(&mesh).unwrap();
        // Only vertices on the seam (one per ring and the caps' centres at most) split.
        assert!(split.vertex.len() > mesh.vertex_count());
        assert!(split.vertex.len() < mesh.vertex_count() + 24);
    }

    #[test]
    fn a_subset_keeps_each_face_on_its_side_of_the_seam() {
        let mesh = cylinder(0.5, 1.0, 24, 4).unwrap();
        let layout = UvLayout::cylindrical(&mesh, DVec3::ZERO).unwrap();
        // The "coarse" mesh is the mesh itself with its vertices reversed.
        let n = mesh.vertex_count() as u32;
        let original_index: Vec<u32> = (0..n).rev().collect();
        let coarse = TriMesh::new(
            original_index
                .iter()
                .map(|&o| mesh.vertices[o as usize])
                .collect(),
            mesh.faces.iter().map(|f| f.map(|v| n - 1 - v)).collect(),
        )
        .unwrap();
        let sub = layout
            .for_vertex_subset(&mesh, &coarse, &original_index)
            .unwrap();
        let coords = |l: &UvLayout, f: usize| l.faces[f].map(|c| l.coords[c as usize]);
        for f in 0..mesh.face_count() {
            assert_eq!(coords(&sub, f), coords(&layout, f), "face {f}");
        }
        assert!(layout
            .for_vertex_subset(&mesh, &coarse, &original_index[1..])
            .is_err());
    }

    #[test]
    fn bad_layouts_are_clear_errors() {
        let mesh = cylinder(0.5, 1.0, 8, 2).unwrap();
        let mut layout = UvLayout::cylindrical(&mesh, DVec3::ZERO).unwrap();
        layout.faces.pop();
        assert!(matches!(
            layout.validate(&mesh),
            Err(Error::SizeMismatch { .. })
        ));
        let mut layout = UvLayout::cylindrical(&mesh, DVec3::ZERO).unwrap();
        layout.faces[0][1] = 10_000;
        assert!(matches!(
            layout.split_seams(&mesh),
            Err(Error::IndexOutOfRange { .. })
        ));
        layout.faces[0][1] = 0;
        layout.coords[0].x = f64::NAN;
        assert!(matches!(
            layout.validate(&mesh),
            Err(Error::NonFinite { .. })
        ));
        let flat = TriMesh::new(vec![DVec3::ZERO, DVec3::X, DVec3::Z], vec![[0, 1, 2]]).unwrap();
        assert!(matches!(
            UvLayout::cylindrical(&flat, DVec3::ZERO),
            Err(Error::Degenerate { .. })
        ));
    }
}
