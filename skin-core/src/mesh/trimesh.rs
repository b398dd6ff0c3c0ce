//! The indexed triangle mesh type.

use crate::math::DVec3;
use crate::{Error, Result};
use serde::{Deserialize, Serialize};

/// Axis-aligned bounding box of a point set.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BoundingBox {
    /// Component-wise minimum corner (mesh units).
    pub min: DVec3,
    /// Component-wise maximum corner (mesh units).
    pub max: DVec3,
}

impl BoundingBox {
    /// Edge lengths `max - min`.
    pub fn extent(&self) -> DVec3 {
        self.max - self.min
    }

    /// Centre `(min + max) / 2`.
    pub fn center(&self) -> DVec3 {
        0.5 * (self.min + self.max)
    }

    /// Length of the diagonal, a natural scale for tolerances.
    pub fn diagonal(&self) -> f64 {
        self.extent().length()
    }
}

/// The area of triangle `[a, b, c]` (zero for degenerate triangles).
pub fn triangle_area(tri: [DVec3; 3]) -> f64 {
    let [a, b, c] = tri;
    0.5 * (b - a).cross(c - a).length()
}

/// An indexed triangle mesh.
///
/// Invariants (checked by [`TriMesh::new`]): every coordinate is finite and every face index
/// is `< vertices.len()`. Degenerate (zero-area) faces are allowed in the container — real
/// scans have them — and each algorithm that cannot handle them says so in its `# Errors`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct TriMesh {
    /// Vertex positions, metres (or the file's unit when loaded).
    pub vertices: Vec<DVec3>,
    /// Triangles as vertex indices, counter-clockwise seen from outside.
    pub faces: Vec<[u32; 3]>,
}

impl TriMesh {
    /// Builds a mesh, validating coordinates and indices.
    ///
    /// # Errors
    /// [`Error::NonFinite`] for NaN/inf coordinates, [`Error::IndexOutOfRange`] for a face
    /// index past the vertex count.
    pub fn new(vertices: Vec<DVec3>, faces: Vec<[u32; 3]>) -> Result<Self> {
        let mesh = TriMesh { vertices, faces };
        mesh.validate()?;
        Ok(mesh)
    }

    /// Checks the invariants of [`TriMesh::new`] on a mesh whose fields were set directly.
    ///
    /// # Errors
    /// As [`TriMesh::new`].
    pub fn validate(&self) -> Result<()> {
        if !self.vertices.iter().all(|v| v.is_finite()) {
            return Err(Error::NonFinite {
                what: "mesh vertices",
            });
        }
        let n = self.vertices.len();
        for f in &self.faces {
            for &i in f {
                if i as usize >= n {
                    return Err(Error::IndexOutOfRange {
                        what: "mesh face",
                        index: i as usize,
                        len: n,
                    });
                }
            }
        }
        Ok(())
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.vertices.len()
    }

    /// Number of faces.
    pub fn face_count(&self) -> usize {
        self.faces.len()
    }

    /// Axis-aligned bounding box of all vertices (referenced or not).
    ///
    /// # Errors
    /// [`Error::Empty`] when there are no vertices, [`Error::NonFinite`] for NaN/inf coordinates.
    pub fn bounding_box(&self) -> Result<BoundingBox> {
        let first = *self.vertices.first().ok_or(Error::Empty {
            what: "mesh vertices (bounding box)",
        })?;
        if !self.vertices.iter().all(|v| v.is_finite()) {
            return Err(Error::NonFinite {
                what: "mesh vertices",
            });
        }
        let (min, max) = self
            .vertices
            .iter()
            .fold((first, first), |(lo, hi), &v| (lo.min(v), hi.max(v)));
        Ok(BoundingBox { min, max })
    }

    /// Total surface area (sum of triangle areas, mesh units squared; 0 for no faces).
    ///
    /// # Errors
    /// As [`TriMesh::validate`].
    pub fn surface_area(&self) -> Result<f64> {
        self.validate()?;
        Ok((0..self.face_count())
            .map(|f| triangle_area(self.triangle(f)))
            .sum())
    }

    /// The three corner positions of face `f`.
    ///
    /// # Panics
    /// If `f` is out of range (an indexing error in the caller).
    pub fn triangle(&self, f: usize) -> [DVec3; 3] {
        let [a, b, c] = self.faces[f];
        [
            self.vertices[a as usize],
            self.vertices[b as usize],
            self.vertices[c as usize],
        ]
    }
}

/// The vertices among `0..n` that `used` names (each any number of times), compacted in
/// their original order: `(new_index, original_index)` with `new_index[i]` the compact index
/// of vertex `i` (`u32::MAX` if unused) and `original_index[j]` the vertex of compact `j`.
pub(crate) fn compact_vertices(
    n: usize,
    used: impl IntoIterator<Item = u32>,
) -> (Vec<u32>, Vec<u32>) {
    let mut is_used = vec![false; n];
    for i in used {
        is_used[i as usize] = true;
    }
    let mut new_index = vec![u32::MAX; n];
    let mut original_index = Vec::new();
    for (i, _) in is_used.iter().enumerate().filter(|(_, u)| **u) {
        new_index[i] = original_index.len() as u32;
        original_index.push(i as u32);
    }
    (new_index, original_index)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rejects_bad_index_and_nan() {
        let v = vec![DVec3::ZERO, DVec3::X, DVec3::Y];
        assert!(TriMesh::new(v.clone(), vec![[0, 1, 2]]).is_ok());
        assert!(matches!(
            TriMesh::new(v.clone(), vec![[0, 1, 3]]),
            Err(Error::IndexOutOfRange { index: 3, .. })
        ));
        let mut bad = v;
        bad[1].x = f64::NAN;
        assert!(matches!(
            TriMesh::new(bad, vec![[0, 1, 2]]),
            Err(Error::NonFinite { .. })
        ));
    }

    #[test]
    fn bounding_box_and_area() {
        let m = TriMesh::new(
            vec![
                DVec3::new(-1.0, 2.0, 0.5),
                DVec3::new(3.0, -2.0, 0.5),
                DVec3::new(-1.0, -2.0, 0.5),
            ],
            vec![[0, 1, 2]],
        )
        .unwrap();
        let b = m.bounding_box().unwrap();
        assert_eq!(b.min, DVec3::new(-1.0, -2.0, 0.5));
        assert_eq!(b.max, DVec3::new(3.0, 2.0, 0.5));
        assert_eq!(b.center(), DVec3::new(1.0, 0.0, 0.5));
        assert!((m.surface_area().unwrap() - 8.0).abs() < 1e-12);
        assert!(matches!(
            TriMesh::default().bounding_box(),
            Err(Error::Empty { .. })
        ));
        assert_eq!(TriMesh::default().surface_area().unwrap(), 0.0);
    }
}
