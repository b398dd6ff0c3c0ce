//! The data tensor of Figure 5-3: faces in full correspondence arranged by attribute
//! (expression × identity, or viseme × expression × identity), the vertex coordinates as the
//! first mode; and which of its faces are known (§5.3.4).

use skin_core::math::DVec3;
use skin_core::tensor::Tensor;
use skin_core::Context;

use crate::{Error, Result, ResultExt};

/// A data tensor of faces in correspondence (Figure 5-3): mode 0 holds the `3V` vertex
/// coordinates (`x₀ y₀ z₀ x₁ …`), modes `1…N−1` the attributes (e.g. expression, identity).
///
/// Valid by construction: every face has the same vertex count, every value is finite, there is
/// at least one attribute mode.
#[derive(Clone, Debug, PartialEq)]
pub struct FaceTensor {
    vertex_count: usize,
    tensor: Tensor,
}

impl FaceTensor {
    /// Arranges `faces` (row-major over the attribute indices, last attribute fastest: for
    /// attribute sizes `[10, 15]`, face `e · 15 + i` is expression `e` of identity `i`) into
    /// the data tensor of shape `[3V, d₁, …]`.
    ///
    /// # Errors
    /// [`Error::Empty`] for no attribute mode, a zero attribute size or faces without
    /// vertices; [`Error::SizeMismatch`] if the number of faces is not `Π dₙ` or a face's
    /// vertex count differs from the first face's (ragged meshes, with [`Error::At`] naming
    /// the face by [`Context::Frame`]); [`Error::NonFinite`] for NaN or ±∞ coordinates.
    pub fn from_faces(attribute_sizes: &[usize], faces: &[Vec<DVec3>]) -> Result<Self> {
        if attribute_sizes.is_empty() || attribute_sizes.contains(&0) {
            return Err(Error::Empty {
                what: "attribute modes",
            });
        }
        let k: usize = attribute_sizes.iter().product();
        if faces.len() != k {
            return Err(Error::SizeMismatch {
                what: "faces (product of the attribute sizes)",
                expected: k,
                got: faces.len(),
            });
        }
        let v = faces[0].len();
        if v == 0 {
            return Err(Error::Empty {
                what: "face vertices",
            });
        }
        let mut data = vec![0.0; 3 * v * k];
        for (f, face) in faces.iter().enumerate() {
            if face.len() != v {
                return Err(Error::SizeMismatch {
                    what: "face vertex count (faces must be in correspondence)",
                    expected: v,
                    got: face.len(),
                })
                .at(Context::Frame(f));
            }
            for (i, p) in face.iter().enumerate() {
                for (c, x) in p.to_array().into_iter().enumerate() {
                    if !x.is_finite() {
                        return Err(Error::NonFinite {
                            what: "face coordinates",
                        })
                        .at(Context::Frame(f));
                    }
                    data[(3 * i + c) * k + f] = x;
                }
            }
        }
        let mut shape = vec![3 * v];
        shape.extend_from_slice(attribute_sizes);
        Ok(FaceTensor {
            vertex_count: v,
            tensor: Tensor::new(shape, data)?,
        })
    }

    /// Wraps a tensor of shape `[3V, d₁, …]` (at least one attribute mode).
    ///
    /// # Errors
    /// [`Error::Empty`] for an order below 2; [`Error::SizeMismatch`] if mode 0 is not a
    /// multiple of 3.
    pub fn from_tensor(tensor: Tensor) -> Result<Self> {
        if tensor.order() < 2 {
            return Err(Error::Empty {
                what: "attribute modes",
            });
        }
        let rows = tensor.shape()[0];
        if !rows.is_multiple_of(3) {
            return Err(Error::SizeMismatch {
                what: "vertex mode (3 coordinates per vertex)",
                expected: 3 * (rows / 3 + 1),
                got: rows,
            });
        }
        Ok(FaceTensor {
            vertex_count: rows / 3,
            tensor,
        })
    }

    /// Vertices per face `V`.
    pub fn vertex_count(&self) -> usize {
        self.vertex_count
    }

    /// The attribute sizes `[d₁, …]` (the tensor's shape without mode 0).
    pub fn attribute_sizes(&self) -> &[usize] {
        &self.tensor.shape()[1..]
    }

    /// Number of faces `Π dₙ`.
    pub fn face_count(&self) -> usize {
        self.attribute_sizes().iter().product()
    }

    /// The data tensor `[3V, d₁, …]`.
    pub fn tensor(&self) -> &Tensor {
        &self.tensor
    }

    /// Flat index of a face from its attribute indices (row-major, last fastest).
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] for the wrong number of indices, [`Error::IndexOutOfRange`].
    pub fn face_index(&self, attributes: &[usize]) -> Result<usize> {
        flat_index(self.attribute_sizes(), attributes)
    }

    /// The vertices of face `f` (flat index, see [`FaceTensor::face_index`]).
    ///
    /// # Errors
    /// [`Error::IndexOutOfRange`] for `f ≥` [`FaceTensor::face_count`].
    pub fn face(&self, f: usize) -> Result<Vec<DVec3>> {
        let k = self.face_count();
        skin_core::check::index("face", f, k)?;
        let d = self.tensor.data();
        Ok((0..self.vertex_count)
            .map(|i| {
                DVec3::new(
                    d[3 * i * k + f],
                    d[(3 * i + 1) * k + f],
                    d[(3 * i + 2) * k + f],
                )
            })
            .collect())
    }

    /// The same data tensor (Figure 5-3) restricted to the given vertices (in that order), e.g.
    /// a farthest-point subsample for a cheaper experiment.
    ///
    /// # Errors
    /// [`Error::Empty`] for no vertex; [`Error::IndexOutOfRange`] for a vertex past
    /// [`FaceTensor::vertex_count`].
    pub fn vertex_subset(&self, vertices: &[usize]) -> Result<FaceTensor> {
        if vertices.is_empty() {
            return Err(Error::Empty {
                what: "vertex subset",
            });
        }
        let k = self.face_count();
        let d = self.tensor.data();
        let mut data = Vec::with_capacity(3 * vertices.len() * k);
        for &v in vertices {
            skin_core::check::index("vertex", v, self.vertex_count)?;
            data.extend_from_slice(&d[3 * v * k..3 * (v + 1) * k]);
        }
        let mut shape = vec![3 * vertices.len()];
        shape.extend_from_slice(self.attribute_sizes());
        Ok(FaceTensor {
            vertex_count: vertices.len(),
            tensor: Tensor::new(shape, data)?,
        })
    }

    /// The mean of the given faces (flat indices), as a `3V` vector.
    pub(crate) fn mean_of(&self, faces: &[usize]) -> Vec<f64> {
        let k = self.face_count();
        let n = faces.len().max(1) as f64;
        self.tensor
            .data()
            .chunks_exact(k)
            .map(|row| faces.iter().map(|&f| row[f]).sum::<f64>() / n)
            .collect()
    }
}

/// Row-major flat index of `attributes` in a tensor of `sizes`.
pub(crate) fn flat_index(sizes: &[usize], attributes: &[usize]) -> Result<usize> {
    skin_core::check::same_size("attribute indices", sizes.len(), attributes.len())?;
    let mut f = 0;
    for (&d, &a) in sizes.iter().zip(attributes) {
        skin_core::check::index("attribute index", a, d)?;
        f = f * d + a;
    }
    Ok(f)
}

/// The attribute indices of flat index `f` (inverse of [`flat_index`]).
pub(crate) fn unflatten(sizes: &[usize], mut f: usize) -> Vec<usize> {
    let mut out = vec![0; sizes.len()];
    for (o, &d) in out.iter_mut().zip(sizes).rev() {
        *o = f % d;
        f /= d;
    }
    out
}

/// Which faces of a [`FaceTensor`] are known (§5.3.4). Valid by construction: every value of
/// every attribute keeps at least one known face (an all-missing slice cannot be imputed: no
/// data says what that expression or that person looks like).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct KnownFaces {
    sizes: Vec<usize>,
    known: Vec<bool>,
}

impl KnownFaces {
    /// `known[f]` for each face (flat index, row-major over `attribute_sizes`).
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] if `known.len() ≠ Π dₙ`; [`Error::Empty`] (inside
    /// [`Error::At`] with [`Context::Frame`]`(mode)`) if some attribute value has no known
    /// face — an all-missing slice.
    pub fn new(attribute_sizes: &[usize], known: Vec<bool>) -> Result<Self> {
        if attribute_sizes.is_empty() || attribute_sizes.contains(&0) {
            return Err(Error::Empty {
                what: "attribute modes",
            });
        }
        let k: usize = attribute_sizes.iter().product();
        skin_core::check::same_size("known-face flags", k, known.len())?;
        for (mode, &d) in attribute_sizes.iter().enumerate() {
            let mut seen = vec![false; d];
            for (f, &kn) in known.iter().enumerate() {
                if kn {
                    seen[unflatten(attribute_sizes, f)[mode]] = true;
                }
            }
            if seen.contains(&false) {
                return Err(Error::Empty {
                    what: "known faces of an attribute value (an all-missing slice)",
                })
                .at(Context::Frame(mode));
            }
        }
        Ok(KnownFaces {
            sizes: attribute_sizes.to_vec(),
            known,
        })
    }

    /// The attribute sizes.
    pub fn attribute_sizes(&self) -> &[usize] {
        &self.sizes
    }

    /// Whether face `f` (flat index) is known; `false` past the end.
    pub fn is_known(&self, f: usize) -> bool {
        self.known.get(f).copied().unwrap_or(false)
    }

    /// The flat indices of the known faces.
    pub fn known(&self) -> Vec<usize> {
        (0..self.known.len()).filter(|&f| self.known[f]).collect()
    }

    /// The flat indices of the missing faces.
    pub fn missing(&self) -> Vec<usize> {
        (0..self.known.len()).filter(|&f| !self.known[f]).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn face(v: usize, s: f64) -> Vec<DVec3> {
        (0..v).map(|i| DVec3::new(i as f64, s, -s)).collect()
    }

    #[test]
    fn faces_round_trip_through_the_tensor() {
        let faces: Vec<_> = (0..6).map(|f| face(4, f as f64)).collect();
        let t = FaceTensor::from_faces(&[2, 3], &faces).unwrap();
        assert_eq!(t.tensor().shape(), &[12, 2, 3]);
        assert_eq!(t.face_index(&[1, 2]).unwrap(), 5);
        for (f, want) in faces.iter().enumerate() {
            assert_eq!(&t.face(f).unwrap(), want);
        }
        assert_eq!(unflatten(&[2, 3], 5), vec![1, 2]);
    }

    #[test]
    fn a_vertex_subset_keeps_those_vertices() {
        let faces: Vec<_> = (0..6).map(|f| face(4, f as f64)).collect();
        let t = FaceTensor::from_faces(&[2, 3], &faces).unwrap();
        let sub = t.vertex_subset(&[3, 1]).unwrap();
        assert_eq!(sub.tensor().shape(), &[6, 2, 3]);
        for (f, want) in faces.iter().enumerate() {
            assert_eq!(sub.face(f).unwrap(), vec![want[3], want[1]]);
        }
        assert!(matches!(t.vertex_subset(&[]), Err(Error::Empty { .. })));
        assert!(t.vertex_subset(&[4]).is_err());
    }

    #[test]
    fn ragged_and_bad_faces_are_errors() {
        let mut faces: Vec<_> = (0..6).map(|f| face(4, f as f64)).collect();
        assert!(matches!(
            FaceTensor::from_faces(&[2, 2], &faces),
            Err(Error::SizeMismatch { .. })
        ));
        faces[3] = face(5, 0.0);
        let e = FaceTensor::from_faces(&[2, 3], &faces).unwrap_err();
        assert!(matches!(e.root(), Error::SizeMismatch { .. }));
        assert_eq!(e.contexts(), vec![Context::Frame(3)]);
        faces[3] = face(4, f64::NAN);
        assert!(matches!(
            FaceTensor::from_faces(&[2, 3], &faces).unwrap_err().root(),
            Error::NonFinite { .. }
        ));
    }

    #[test]
    fn an_all_missing_slice_is_an_error() {
        let mut known = vec![true; 6];
        known[2] = false;
        known[5] = false; // identity 2 (last mode) has no known face
        let e = KnownFaces::new(&[2, 3], known).unwrap_err();
        assert!(matches!(e.root(), Error::Empty { .. }));
        assert_eq!(e.contexts(), vec![Context::Frame(1)]);
        let k = KnownFaces::new(&[2, 3], vec![true, true, false, true, true, true]).unwrap();
        assert_eq!(k.missing(), vec![2]);
    }
}
