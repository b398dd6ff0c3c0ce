//! The ICT face basis behind the generated data sets (§5.3.1 stand-in): the generic neutral
//! face, identity modes and expression blendshapes, read from a directory — every shape it
//! holds, or the ones a caller names — with each mismatch a typed error.

use std::path::Path;

use skin_core::math::DVec3;
use skin_core::mesh::{read_obj, ObjFile, TriMesh};
use skin_core::Context;

use crate::{Error, Result, ResultExt};

/// The 16 ICT blendshapes shipped in `data/ict-face/expression/`, in file-name order (the
/// order [`IctBasis::read`] gives them).
pub const ICT_BLENDSHAPES: [&str; 16] = [
    "browDown_L",
    "browInnerUp_L",
    "browInnerUp_R",
    "cheekPuff_L",
    "eyeBlink_L",
    "eyeBlink_R",
    "jawLeft",
    "jawOpen",
    "mouthClose",
    "mouthFrown_L",
    "mouthFunnel",
    "mouthPucker",
    "mouthSmile_L",
    "mouthSmile_R",
    "mouthStretch_L",
    "noseSneer_L",
];

/// An attribute value made of blendshapes: its name and `(blendshape, weight)` pairs.
pub type Recipe = (&'static str, &'static [(&'static str, f64)]);

/// A named shape of the basis: its name (the OBJ file's stem) and its displacement from the
/// neutral face, one vector per vertex.
pub type NamedShape = (String, Vec<DVec3>);

/// The ICT basis as displacements from the neutral face, the stand-in for the thesis's scans
/// (§5.3.1): valid by construction (at least one
/// identity mode and one blendshape, every shape with the neutral face's vertex count, finite,
/// names unique within their kind).
#[derive(Clone, Debug, PartialEq)]
pub struct IctBasis {
    neutral: TriMesh,
    identity_names: Vec<String>,
    identity_modes: Vec<Vec<DVec3>>,
    blendshape_names: Vec<String>,
    blendshapes: Vec<Vec<DVec3>>,
}

/// A shape must have the neutral face's vertex count.
fn same_vertex_count(neutral: usize, got: usize) -> Result<()> {
    if neutral == got {
        Ok(())
    } else {
        Err(Error::SizeMismatch {
            what: "ICT shape vertex count (the neutral face's)",
            expected: neutral,
            got,
        })
    }
}

/// The stems of the `.obj` files in `dir`, sorted (byte order).
fn obj_stems(dir: &Path) -> Result<Vec<String>> {
    let entries = std::fs::read_dir(dir).map_err(|e| skin_core::Error::io(dir, e))?;
    let mut names = Vec::new();
    for entry in entries {
        let path = entry.map_err(|e| skin_core::Error::io(dir, e))?.path();
        if !path.is_file() || path.extension().and_then(|e| e.to_str()) != Some("obj") {
            continue;
        }
        let stem =
            path.file_stem()
                .and_then(|s| s.to_str())
                .ok_or_else(|| Error::InvalidParam {
                    name: "shape file name",
                    reason: format!("{} is not valid UTF-8", path.display()),
                })?;
        names.push(stem.to_string());
    }
    names.sort();
    Ok(names)
}

/// Reads `dir/<name>.obj` for each name as a displacement from `neutral` (the vertex count is
/// checked by [`IctBasis::new`]). Errors in [`Error::At`] with [`Context::Frame`] = `first +`
/// the name's position.
fn read_shapes(
    dir: &Path,
    names: &[impl AsRef<str>],
    neutral: &[DVec3],
    first: usize,
) -> Result<Vec<NamedShape>> {
    names
        .iter()
        .enumerate()
        .map(|(i, name)| {
            let name = name.as_ref();
            let v = ObjFile::read(dir.join(format!("{name}.obj")))
                .at(Context::Frame(first + i))?
                .vertices;
            same_vertex_count(neutral.len(), v.len()).at(Context::Frame(first + i))?;
            Ok((
                name.to_string(),
                v.iter().zip(neutral).map(|(a, b)| *a - *b).collect(),
            ))
        })
        .collect()
}

/// Splits named shapes into names and displacements, checking counts, finiteness and unique
/// names. `first` numbers the shapes in errors.
fn checked(
    what: &'static str,
    shapes: Vec<NamedShape>,
    vertices: usize,
    first: usize,
) -> Result<(Vec<String>, Vec<Vec<DVec3>>)> {
    if shapes.is_empty() {
        return Err(Error::Empty { what });
    }
    let mut names = Vec::with_capacity(shapes.len());
    let mut modes = Vec::with_capacity(shapes.len());
    for (i, (name, d)) in shapes.into_iter().enumerate() {
        let at = Context::Frame(first + i);
        same_vertex_count(vertices, d.len()).at(at)?;
        if d.iter().any(|p| !p.is_finite()) {
            return Err(Error::NonFinite {
                what: "ICT shape displacements",
            })
            .at(at);
        }
        if names.contains(&name) {
            return Err(Error::InvalidParam {
                name: "shape names",
                reason: format!("{name:?} appears twice among the {what}"),
            })
            .at(at);
        }
        names.push(name);
        modes.push(d);
    }
    Ok((names, modes))
}

impl IctBasis {
    /// A basis from its parts: the neutral face, the identity modes and the blendshapes, each
    /// a name and a displacement from the neutral face.
    ///
    /// # Errors
    /// [`Error::Empty`] for a neutral face without vertices, no identity mode or no
    /// blendshape; inside [`Error::At`] with [`Context::Frame`] = the shape's position
    /// (identities first, then blendshapes): [`Error::SizeMismatch`] for a vertex count that
    /// is not the neutral face's, [`Error::NonFinite`] for NaN or ±∞, [`Error::InvalidParam`]
    /// for a name that appears twice; [`Error::Core`] for a non-finite neutral face.
    pub fn new(
        neutral: TriMesh,
        identities: Vec<NamedShape>,
        blendshapes: Vec<NamedShape>,
    ) -> Result<Self> {
        let v = neutral.vertices.len();
        if v == 0 {
            return Err(Error::Empty {
                what: "neutral face vertices",
            });
        }
        let neutral = TriMesh::new(neutral.vertices, neutral.faces)?;
        let n_id = identities.len();
        let (identity_names, identity_modes) = checked("identity modes", identities, v, 0)?;
        let (blendshape_names, blendshapes) = checked("blendshapes", blendshapes, v, n_id)?;
        Ok(IctBasis {
            neutral,
            identity_names,
            identity_modes,
            blendshape_names,
            blendshapes,
        })
    }

    /// Reads every shape the directory holds: `dir/neutral_face.obj`, every
    /// `dir/identity/*.obj` and every `dir/expression/*.obj`, each kind sorted by file name
    /// (the shipped `data/ict-face/`: 10 identities `identity000…009` and the 16
    /// [`ICT_BLENDSHAPES`]).
    ///
    /// # Errors
    /// [`Error::Core`] for a missing or unreadable directory or file (with its path) and a
    /// malformed OBJ (with its line; NaN or ±∞ coordinates are malformed); [`Error::Empty`]
    /// for a folder without `.obj` files; otherwise as [`IctBasis::new`] (positions: the
    /// identities in name order, then the blendshapes).
    pub fn read(dir: impl AsRef<Path>) -> Result<Self> {
        let dir = dir.as_ref();
        let identities = obj_stems(&dir.join("identity"))?;
        let blendshapes = obj_stems(&dir.join("expression"))?;
        Self::read_named(dir, &identities, &blendshapes)
    }

    /// Reads `dir/neutral_face.obj`, `dir/identity/<name>.obj` for each of `identities` and
    /// `dir/expression/<name>.obj` for each of `blendshapes`, in the given orders.
    ///
    /// # Errors
    /// As [`IctBasis::read`]; a named file that does not exist is [`Error::Core`] (I/O, with
    /// its path) inside [`Error::At`] with its position.
    pub fn read_named(
        dir: impl AsRef<Path>,
        identities: &[impl AsRef<str>],
        blendshapes: &[impl AsRef<str>],
    ) -> Result<Self> {
        let dir = dir.as_ref();
        let neutral = read_obj(dir.join("neutral_face.obj"))?;
        let ids = read_shapes(&dir.join("identity"), identities, &neutral.vertices, 0)?;
        let exs = read_shapes(
            &dir.join("expression"),
            blendshapes,
            &neutral.vertices,
            identities.len(),
        )?;
        Self::new(neutral, ids, exs)
    }

    /// The generic neutral face.
    pub fn neutral(&self) -> &TriMesh {
        &self.neutral
    }

    /// The identity modes' names (file stems), in order.
    pub fn identity_names(&self) -> &[String] {
        &self.identity_names
    }

    /// The identity modes, as displacements from the neutral face.
    pub fn identity_modes(&self) -> &[Vec<DVec3>] {
        &self.identity_modes
    }

    /// The blendshapes' names (file stems), in order.
    pub fn blendshape_names(&self) -> &[String] {
        &self.blendshape_names
    }

    /// The blendshapes, as displacements from the neutral face.
    pub fn blendshapes(&self) -> &[Vec<DVec3>] {
        &self.blendshapes
    }

    /// Blendshape weights of a recipe, one per blendshape of this basis (in
    /// [`IctBasis::blendshape_names`] order).
    ///
    /// # Errors
    /// [`Error::UnknownName`] for a blendshape the basis does not hold; [`Error::NonFinite`]
    /// for a NaN or ±∞ weight.
    pub fn weights(&self, recipe: &Recipe) -> Result<Vec<f64>> {
        let mut w = vec![0.0; self.blendshapes.len()];
        for (name, x) in recipe.1 {
            skin_core::check::finite("recipe weight", *x)?;
            let b = self
                .blendshape_names
                .iter()
                .position(|n| n == name)
                .ok_or_else(|| Error::UnknownName {
                    what: "blendshape",
                    name: (*name).to_string(),
                    used_by: recipe.0,
                })?;
            w[b] += x;
        }
        Ok(w)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tiny() -> (TriMesh, Vec<NamedShape>, Vec<NamedShape>) {
        let neutral = TriMesh::new(vec![DVec3::ZERO, DVec3::X, DVec3::Y], vec![[0, 1, 2]]).unwrap();
        let shape = |s: f64| vec![DVec3::splat(s); 3];
        (
            neutral,
            vec![("a".into(), shape(1.0)), ("b".into(), shape(2.0))],
            vec![("smile".into(), shape(0.5))],
        )
    }

    #[test]
    fn a_basis_is_checked_when_built() {
        let (n, ids, exs) = tiny();
        let b = IctBasis::new(n.clone(), ids.clone(), exs.clone()).unwrap();
        assert_eq!(b.identity_names(), ["a", "b"]);
        assert_eq!(b.weights(&("s", &[("smile", 0.7)])).unwrap(), vec![0.7]);
        let e = b.weights(&("frown", &[("mouthFrown_L", 1.0)])).unwrap_err();
        assert!(matches!(e, Error::UnknownName { .. }), "{e}");
        assert!(b.weights(&("s", &[("smile", f64::NAN)])).is_err());

        let e = IctBasis::new(n.clone(), Vec::new(), exs.clone()).unwrap_err();
        assert!(matches!(e, Error::Empty { .. }));
        let e = IctBasis::new(n.clone(), ids.clone(), Vec::new()).unwrap_err();
        assert!(matches!(e, Error::Empty { .. }));
        let mut short = exs.clone();
        short[0].1.pop();
        let e = IctBasis::new(n.clone(), ids.clone(), short).unwrap_err();
        assert!(matches!(e.root(), Error::SizeMismatch { .. }));
        assert_eq!(e.contexts(), vec![Context::Frame(2)]);
        let mut nan = ids.clone();
        nan[1].1[0].y = f64::NAN;
        let e = IctBasis::new(n.clone(), nan, exs.clone()).unwrap_err();
        assert!(matches!(e.root(), Error::NonFinite { .. }));
        assert_eq!(e.contexts(), vec![Context::Frame(1)]);
        let mut twice = ids.clone();
        twice[1].0 = "a".into();
        let e = IctBasis::new(n.clone(), twice, exs.clone()).unwrap_err();
        assert!(matches!(e.root(), Error::InvalidParam { .. }));
        let mut bad = n;
        bad.vertices[0].x = f64::INFINITY;
        assert!(IctBasis::new(bad, ids, exs).is_err());
    }
}
