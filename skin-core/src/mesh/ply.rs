//! Stanford PLY reading and writing (ASCII, binary little endian, binary big endian) via
//! `ply-rs-bw`.
//!
//! Scans and reconstructions (the photometric-normal and visual-hull pipelines of Vlasic's
//! thesis, Ch. 2–3, and peer tools such as Open3D and MeshLab) exchange meshes as PLY. Only
//! geometry is read: the `vertex` element's `x`, `y`, `z` (any scalar type, converted to
//! `f64`) and the `face` element's `vertex_indices` (or `vertex_index`) list of any integer
//! type; polygons are fan-triangulated from their first corner like OBJ faces. Other
//! properties and elements (normals, colours, `edge`, `material`...) are skipped.
//!
//! Files are written with `double` coordinates and `uchar`/`uint` index lists, so a round trip
//! is bit-exact in all three encodings.

use crate::math::DVec3;
use crate::mesh::TriMesh;
use crate::{Error, Result};
use ply_rs_bw::parser::Parser;
use ply_rs_bw::ply::{
    Addable, ElementDef, Encoding, Ply, Property, PropertyAccess, PropertyDef, PropertyType,
    ScalarType,
};
use ply_rs_bw::writer::Writer;
use serde::{Deserialize, Serialize};
use std::io::{BufWriter, Read, Write};
use std::path::{Path, PathBuf};

/// The encoding of a PLY file's payload.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum PlyEncoding {
    /// Human-readable text.
    Ascii,
    /// Binary, little endian (the common choice; native on x86 and ARM). Default.
    #[default]
    BinaryLittleEndian,
    /// Binary, big endian.
    BinaryBigEndian,
}

impl From<PlyEncoding> for Encoding {
    fn from(e: PlyEncoding) -> Self {
        match e {
            PlyEncoding::Ascii => Encoding::Ascii,
            PlyEncoding::BinaryLittleEndian => Encoding::BinaryLittleEndian,
            PlyEncoding::BinaryBigEndian => Encoding::BinaryBigEndian,
        }
    }
}

/// The property names accepted for a face's corner list.
const FACE_LIST_NAMES: [&str; 2] = ["vertex_indices", "vertex_index"];

/// One parsed element of any kind; only the fields we use are kept.
#[derive(Debug, Default)]
struct ReadElement {
    xyz: [Option<f64>; 3],
    indices: Option<Vec<i64>>,
}

fn scalar_to_f64(p: &Property) -> Option<f64> {
    Some(match *p {
        Property::Char(v) => v.into(),
        Property::UChar(v) => v.into(),
        Property::Short(v) => v.into(),
        Property::UShort(v) => v.into(),
        Property::Int(v) => v.into(),
        Property::UInt(v) => v.into(),
        Property::Float(v) => v.into(),
        Property::Double(v) => v,
        _ => return None,
    })
}

fn list_to_i64(p: Property) -> Option<Vec<i64>> {
    fn conv<T: Into<i64>>(v: Vec<T>) -> Vec<i64> {
        v.into_iter().map(Into::into).collect()
    }
    Some(match p {
        Property::ListChar(v) => conv(v),
        Property::ListUChar(v) => conv(v),
        Property::ListShort(v) => conv(v),
        Property::ListUShort(v) => conv(v),
        Property::ListInt(v) => conv(v),
        Property::ListUInt(v) => conv(v),
        _ => return None,
    })
}

impl PropertyAccess for ReadElement {
    fn new() -> Self {
        ReadElement::default()
    }

    fn set_property(&mut self, name: &str, property: Property) {
        match name {
            "x" => self.xyz[0] = scalar_to_f64(&property),
            "y" => self.xyz[1] = scalar_to_f64(&property),
            "z" => self.xyz[2] = scalar_to_f64(&property),
            n if FACE_LIST_NAMES.contains(&n) => self.indices = list_to_i64(property),
            _ => {}
        }
    }
}

/// One element to write: a vertex or a triangle.
enum WriteElement {
    Vertex(DVec3),
    Face([u32; 3]),
}

impl PropertyAccess for WriteElement {
    fn new() -> Self {
        WriteElement::Vertex(DVec3::ZERO)
    }

    fn get_double(&self, name: &str) -> Option<f64> {
        match (self, name) {
            (WriteElement::Vertex(v), "x") => Some(v.x),
            (WriteElement::Vertex(v), "y") => Some(v.y),
            (WriteElement::Vertex(v), "z") => Some(v.z),
            _ => None,
        }
    }

    fn get_list_uint(&self, name: &str) -> Option<&[u32]> {
        match (self, name) {
            (WriteElement::Face(f), "vertex_indices") => Some(&f[..]),
            _ => None,
        }
    }
}

fn parse_error(line: usize, message: impl Into<String>) -> Error {
    Error::Parse {
        format: "PLY",
        line,
        message: message.into(),
    }
}

/// Turns a `ply-rs-bw` error into ours: malformed content becomes [`Error::Parse`] (with the
/// header/ASCII line when the message names one), anything else stays an I/O error.
fn convert_error(e: std::io::Error, path: &Path) -> Error {
    use std::io::ErrorKind;
    match e.kind() {
        ErrorKind::InvalidInput | ErrorKind::InvalidData | ErrorKind::UnexpectedEof => {
            let msg = e.to_string();
            // ASCII and header messages start with "Line N:"; binary ones count elements, not
            // lines, so they keep line 0.
            let line = if msg.contains("binary") {
                0
            } else {
                msg.strip_prefix("Line ")
                    .and_then(|r| r.split(':').next())
                    .and_then(|n| n.trim().parse().ok())
                    .unwrap_or(0)
            };
            let msg = msg.replace("\n\t", "; ");
            // Truncation inside a binary list arrives wrapped in an `InvalidInput` error.
            let truncated = if e.kind() == ErrorKind::UnexpectedEof || msg.contains("UnexpectedEof")
            {
                "unexpected end of file (truncated data or wrong element count): "
            } else {
                ""
            };
            parse_error(line, format!("{}: {truncated}{msg}", path.display()))
        }
        _ => Error::io(path, e),
    }
}

fn has_property(element: &ElementDef, name: &str) -> bool {
    element.properties.contains_key(name)
}

/// Reads a PLY mesh from any reader (the whole stream is consumed).
///
/// # Errors
/// [`Error::Parse`] for a malformed header, bad numbers, fewer elements than the header
/// declares (truncated ASCII or binary data), a missing `vertex` element or `x`/`y`/`z`
/// property, a face list that is missing or not of integer type, a face with fewer than three
/// corners, a negative index, or a non-finite coordinate; [`Error::IndexOutOfRange`] for a face
/// index past the vertex count; [`Error::Empty`] when there are no faces; [`Error::Io`] if
/// reading fails.
pub fn read_ply_from_reader<R: Read>(mut reader: R) -> Result<TriMesh> {
    read_impl(&mut reader, Path::new("<reader>"))
}

fn read_impl<R: Read>(reader: &mut R, path: &Path) -> Result<TriMesh> {
    let parser = Parser::<ReadElement>::new();
    let ply = parser
        .read_ply(reader)
        .map_err(|e| convert_error(e, path))?;
    let err = |m: String| parse_error(0, format!("{}: {m}", path.display()));

    let vdef = ply
        .header
        .elements
        .get("vertex")
        .ok_or_else(|| err("no 'vertex' element in header".into()))?;
    for axis in ["x", "y", "z"] {
        if !has_property(vdef, axis) {
            return Err(err(format!("'vertex' element has no '{axis}' property")));
        }
    }
    let raw_vertices = ply.payload.get("vertex").map(Vec::as_slice).unwrap_or(&[]);
    let mut vertices = Vec::with_capacity(raw_vertices.len());
    for (i, e) in raw_vertices.iter().enumerate() {
        let mut p = [0.0f64; 3];
        for (slot, value) in p.iter_mut().zip(e.xyz) {
            *slot = value
                .ok_or_else(|| err(format!("vertex {i}: coordinate is a list, not a number")))?;
        }
        if !p.iter().all(|c| c.is_finite()) {
            return Err(err(format!("vertex {i} has a non-finite coordinate {p:?}")));
        }
        vertices.push(DVec3::from_array(p));
    }
    if vertices.len() > u32::MAX as usize {
        return Err(err("more than 2^32 - 1 vertices".into()));
    }

    let mut faces = Vec::new();
    if let Some(fdef) = ply.header.elements.get("face") {
        let list_name = FACE_LIST_NAMES
            .iter()
            .find(|n| has_property(fdef, n))
            .ok_or_else(|| err("'face' element has no 'vertex_indices' list".into()))?;
        let list_ok = matches!(
            fdef.properties.get(*list_name).map(|p| &p.data_type),
            Some(PropertyType::List(
                _,
                ScalarType::Char
                    | ScalarType::UChar
                    | ScalarType::Short
                    | ScalarType::UShort
                    | ScalarType::Int
                    | ScalarType::UInt
            ))
        );
        if !list_ok {
            return Err(err(format!(
                "face property '{list_name}' must be a list of integers"
            )));
        }
        let n = vertices.len();
        for (fi, e) in ply.payload.get("face").into_iter().flatten().enumerate() {
            let idx = e.indices.as_deref().unwrap_or(&[]);
            if idx.len() < 3 {
                return Err(err(format!(
                    "face {fi} has {} corners, expected at least 3",
                    idx.len()
                )));
            }
            let mut corners = Vec::with_capacity(idx.len());
            for &i in idx {
                if i < 0 {
                    return Err(err(format!("face {fi} has negative vertex index {i}")));
                }
                if i as u64 >= n as u64 {
                    return Err(Error::IndexOutOfRange {
                        what: "PLY face",
                        index: usize::try_from(i).unwrap_or(usize::MAX),
                        len: n,
                    });
                }
                corners.push(i as u32);
            }
            for k in 1..corners.len() - 1 {
                faces.push([corners[0], corners[k], corners[k + 1]]);
            }
        }
    }
    if faces.is_empty() {
        return Err(Error::Empty {
            what: "PLY faces (no 'face' element or zero faces)",
        });
    }
    TriMesh::new(vertices, faces)
}

/// Reads a PLY file (ASCII or binary).
///
/// # Errors
/// [`Error::Io`] if the file cannot be opened; otherwise as [`read_ply_from_reader`], with the
/// path in the message.
pub fn read_ply(path: impl AsRef<Path>) -> Result<TriMesh> {
    let path = path.as_ref();
    let mut file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    read_impl(&mut file, path)
}

/// Writes `mesh` as PLY with the given encoding to `writer`.
///
/// # Errors
/// As [`TriMesh::validate`]; [`Error::Io`] if writing fails.
pub fn write_ply_to<W: Write>(mut writer: W, mesh: &TriMesh, encoding: PlyEncoding) -> Result<()> {
    write_impl(&mut writer, mesh, encoding, Path::new("<writer>"))
}

fn write_impl<W: Write>(
    writer: &mut W,
    mesh: &TriMesh,
    encoding: PlyEncoding,
    path: &Path,
) -> Result<()> {
    mesh.validate()?;
    let mut ply = Ply::<WriteElement>::new();
    ply.header.encoding = encoding.into();
    ply.header
        .comments
        .push("written by dynamic-shapes skin-core".to_string());
    let mut vdef = ElementDef::new("vertex".to_string());
    for axis in ["x", "y", "z"] {
        vdef.properties.add(PropertyDef::new(
            axis.to_string(),
            PropertyType::Scalar(ScalarType::Double),
        ));
    }
    ply.header.elements.add(vdef);
    let mut fdef = ElementDef::new("face".to_string());
    fdef.properties.add(PropertyDef::new(
        "vertex_indices".to_string(),
        PropertyType::List(ScalarType::UChar, ScalarType::UInt),
    ));
    ply.header.elements.add(fdef);
    ply.payload.insert(
        "vertex".to_string(),
        mesh.vertices
            .iter()
            .map(|&v| WriteElement::Vertex(v))
            .collect(),
    );
    ply.payload.insert(
        "face".to_string(),
        mesh.faces.iter().map(|&f| WriteElement::Face(f)).collect(),
    );
    Writer::new()
        .write_ply(writer, &mut ply)
        .map_err(|e| Error::io(PathBuf::from(path), e))?;
    Ok(())
}

/// Writes `mesh` to a PLY file with the given encoding.
///
/// # Errors
/// As [`write_ply_to`]; I/O errors carry `path`.
pub fn write_ply(path: impl AsRef<Path>, mesh: &TriMesh, encoding: PlyEncoding) -> Result<()> {
    let path = path.as_ref();
    mesh.validate()?;
    let file = std::fs::File::create(path).map_err(|e| Error::io(path, e))?;
    let mut w = BufWriter::new(file);
    write_impl(&mut w, mesh, encoding, path)?;
    w.flush().map_err(|e| Error::io(path, e))
}

#[cfg(test)]
mod tests;
