//! Wavefront OBJ reading and writing, with group selection.
//!
//! Template meshes (the MakeHuman base mesh the methods of Sand 2003 and Vlasic 2008 are tested
//! on) and every mesh the examples write go through OBJ. Only geometry is read: `v` positions
//! and `f` polygons with their `g`/`o` group membership; texture coordinates, normals,
//! materials, lines and free-form directives are skipped.
//!
//! **Why a hand parser, not `tobj`:** `tobj` 4 reports errors without line numbers
//! (`LoadError::FaceParseError`), reads positions as `f32` unless a crate feature is enabled,
//! and splits a file into one model per group occurrence with its own compacted vertex buffer
//! and no map back to the file's vertex indices. We need errors that name the line, exact `f64`
//! round trips, groups that occur several times (the MakeHuman file repeats
//! `g helper-l-eyelashes-2`), and the compacted-to-original vertex map, because MakeHuman's
//! skin weights (`default_weights.mhw`) refer to the original vertex numbers.
//!
//! **Groups:** a face belongs to every name on the last `g` line (`g a b` puts it in both `a`
//! and `b`; a bare `g` means `default`) and to the name of the last `o` line. Faces before any
//! `g` are in `default`, as the OBJ specification says.
//!
//! Lines may end in `\n` or `\r\n`; `#` starts a comment; line continuations (`\`) are not
//! supported and are reported as errors.
//!
//! **Triangulation:** polygons are fanned from their first corner, `(0, i, i+1)`. This is exact
//! for the planar convex polygons OBJ exporters write (the MakeHuman quads) and keeps the
//! corner order, hence the outward orientation.

use crate::math::{DVec2, DVec3};
use crate::mesh::trimesh::compact_vertices;
use crate::mesh::{TriMesh, UvLayout};
use crate::{Error, Result};
use std::collections::HashMap;
use std::io::{BufRead, BufReader, BufWriter, Write};
use std::path::{Path, PathBuf};

impl ObjFile {
    /// Group name given to faces that precede any `g` line, and to a bare `g` line.
    pub const DEFAULT_GROUP: &str = "default";
}

/// A parsed OBJ file: all vertices and all polygons with their group membership.
///
/// Parse once with [`ObjFile::parse`] / [`ObjFile::read`], then take the whole mesh
/// ([`ObjFile::to_mesh`]) or one group ([`ObjFile::group_mesh`]).
#[derive(Debug, Clone)]
pub struct ObjFile {
    /// Every `v` position in file order (file index `i + 1` is `vertices[i]`).
    pub vertices: Vec<DVec3>,
    /// Every `vt` texture coordinate in file order (`u`, `v`; a third value is ignored).
    pub texcoords: Vec<DVec2>,
    /// Zero-based vertex indices of all polygons, concatenated.
    corners: Vec<u32>,
    /// Zero-based `vt` index of each corner, [`NO_TEXCOORD`] where the face gave none.
    corner_texcoords: Vec<u32>,
    /// Polygon `p` owns `corners[offsets[p]..offsets[p + 1]]`.
    offsets: Vec<usize>,
    /// Index into `group_sets` for each polygon.
    polygon_groups: Vec<u32>,
    /// Interned sets of group-name ids.
    group_sets: Vec<Vec<u32>>,
    /// Group names by id, in order of first appearance.
    group_names: Vec<String>,
}

/// One group of an OBJ file as a compact mesh, with the map back to the file's vertices.
#[derive(Debug, Clone, PartialEq)]
pub struct ObjGroupMesh {
    /// The group's triangles over only the vertices they use, re-indexed from 0.
    pub mesh: TriMesh,
    /// `original_index[i]` is the zero-based file vertex index (OBJ index minus one) of
    /// `mesh.vertices[i]`. Increasing, so the compacted order follows the file order.
    pub original_index: Vec<u32>,
    /// The group's texture coordinates per face corner, when every corner of the group has a
    /// `vt` reference (`None` otherwise).
    pub uvs: Option<UvLayout>,
}

/// Marks a face corner without a texture coordinate.
const NO_TEXCOORD: u32 = u32::MAX;

fn parse_error(line: usize, message: impl Into<String>) -> Error {
    Error::Parse {
        format: "OBJ",
        line,
        message: message.into(),
    }
}

/// Prefixes the path to a parse error so messages say which file is broken.
fn with_path(err: Error, path: &Path) -> Error {
    match err {
        Error::Parse {
            format,
            line,
            message,
        } => Error::Parse {
            format,
            line,
            message: format!("{}: {message}", path.display()),
        },
        other => other,
    }
}

/// The path recorded in I/O errors raised while reading from an anonymous reader.
fn reader_path() -> PathBuf {
    PathBuf::from("<reader>")
}

/// Group-tracking state of the parser.
#[derive(Default)]
struct GroupState {
    name_ids: HashMap<String, u32>,
    set_ids: HashMap<Vec<u32>, u32>,
    g: Vec<u32>,
    o: Option<u32>,
    current: Option<u32>,
}

impl GroupState {
    fn name_id(&mut self, name: &str, names: &mut Vec<String>) -> u32 {
        if let Some(&id) = self.name_ids.get(name) {
            return id;
        }
        let id = names.len() as u32;
        names.push(name.to_owned());
        self.name_ids.insert(name.to_owned(), id);
        id
    }

    /// The interned group set the next face belongs to.
    fn current_set(&mut self, sets: &mut Vec<Vec<u32>>, names: &mut Vec<String>) -> u32 {
        if let Some(id) = self.current {
            return id;
        }
        if self.g.is_empty() {
            let d = self.name_id(ObjFile::DEFAULT_GROUP, names);
            self.g.push(d);
        }
        let mut set = self.g.clone();
        set.extend(self.o);
        set.sort_unstable();
        set.dedup();
        let id = match self.set_ids.get(&set) {
            Some(&id) => id,
            None => {
                let id = sets.len() as u32;
                sets.push(set.clone());
                self.set_ids.insert(set, id);
                id
            }
        };
        self.current = Some(id);
        id
    }
}

/// The next `N` finite coordinates of a `kind` line (`"vertex"`, `"texture"`); extra ones
/// are ignored (a `w` or a third texture coordinate).
fn parse_numbers<'a, const N: usize>(
    tokens: &mut impl Iterator<Item = &'a str>,
    kind: &str,
    line: usize,
) -> Result<[f64; N]> {
    let mut out = [0.0f64; N];
    for (k, slot) in out.iter_mut().enumerate() {
        let tok = tokens.next().ok_or_else(|| {
            parse_error(
                line,
                format!("{kind} has {k} coordinates, expected at least {N}"),
            )
        })?;
        *slot = tok
            .parse()
            .map_err(|_| parse_error(line, format!("bad {kind} coordinate '{tok}'")))?;
        if !slot.is_finite() {
            return Err(parse_error(
                line,
                format!("non-finite {kind} coordinate '{tok}'"),
            ));
        }
    }
    Ok(out)
}

/// Resolves one OBJ index (1-based, or negative relative to the `defined` entries read so
/// far) of `kind` to a zero-based index; positive indices are range-checked after the file.
fn resolve_index(text: &str, defined: usize, kind: &str, line: usize) -> Result<(u32, bool)> {
    let idx: i64 = text
        .parse()
        .map_err(|_| parse_error(line, format!("bad {kind} index '{text}' in face")))?;
    if idx == 0 {
        return Err(parse_error(
            line,
            format!("{kind} index 0 in face (OBJ indices start at 1)"),
        ));
    }
    if idx < 0 {
        let resolved = defined as i64 + idx;
        if resolved < 0 {
            return Err(parse_error(
                line,
                format!("relative {kind} index {idx} reaches before the first {kind} ({defined} defined so far)"),
            ));
        }
        return Ok((resolved as u32, true));
    }
    let zero_based = u32::try_from(idx - 1)
        .map_err(|_| parse_error(line, format!("{kind} index {idx} is too large")))?;
    Ok((zero_based, false))
}

/// One corner of an `f` line (`v`, `v/vt`, `v//vn`, `v/vt/vn`): zero-based vertex index,
/// zero-based texture index ([`NO_TEXCOORD`] if none), and whether either index was positive
/// (so range-checked once the file is read).
fn parse_corner(
    token: &str,
    (n_vertices, n_texcoords): (usize, usize),
    line: usize,
) -> Result<(u32, u32, bool)> {
    let mut parts = token.split('/');
    let (v, v_relative) = resolve_index(parts.next().unwrap_or(""), n_vertices, "vertex", line)?;
    let (t, t_relative) = match parts.next() {
        Some(t) if !t.is_empty() => resolve_index(t, n_texcoords, "texture", line)?,
        _ => (NO_TEXCOORD, true),
    };
    Ok((v, t, !(v_relative && t_relative)))
}

impl ObjFile {
    /// Parses OBJ text from a buffered reader.
    ///
    /// # Errors
    /// [`Error::Parse`] (with the 1-based line) for a `v` line with fewer than three numbers or
    /// an unparsable or non-finite coordinate, a face with fewer than three corners, a bad,
    /// zero, or out-of-range vertex index (relative indices are resolved where they appear);
    /// [`Error::Io`] if reading fails.
    pub fn parse<R: BufRead>(mut reader: R) -> Result<ObjFile> {
        let mut obj = ObjFile {
            vertices: Vec::new(),
            texcoords: Vec::new(),
            corners: Vec::new(),
            corner_texcoords: Vec::new(),
            offsets: vec![0],
            polygon_groups: Vec::new(),
            group_sets: Vec::new(),
            group_names: Vec::new(),
        };
        let mut state = GroupState::default();
        // Line of each polygon with a forward (positive) index, for the final range check.
        let mut positive_refs: Vec<(usize, usize)> = Vec::new(); // (polygon, line)
        let mut buf = Vec::new();
        let mut line_no = 0usize;
        loop {
            buf.clear();
            let n = reader
                .read_until(b'\n', &mut buf)
                .map_err(|e| Error::io(reader_path(), e))?;
            if n == 0 {
                break;
            }
            line_no += 1;
            let text = String::from_utf8_lossy(&buf);
            let content = text.split('#').next().unwrap_or("");
            let mut tokens = content.split_whitespace();
            let Some(keyword) = tokens.next() else {
                continue;
            };
            match keyword {
                "v" => {
                    let xyz = parse_numbers::<3>(&mut tokens, "vertex", line_no)?;
                    if obj.vertices.len() >= u32::MAX as usize {
                        return Err(parse_error(line_no, "more than 2^32 - 1 vertices"));
                    }
                    obj.vertices.push(DVec3::from_array(xyz));
                }
                "f" => {
                    let start = obj.corners.len();
                    let mut has_positive = false;
                    let defined = (obj.vertices.len(), obj.texcoords.len());
                    for tok in tokens {
                        let (v, t, positive) = parse_corner(tok, defined, line_no)?;
                        has_positive |= positive;
                        obj.corners.push(v);
                        obj.corner_texcoords.push(t);
                    }
                    let count = obj.corners.len() - start;
                    if count < 3 {
                        return Err(parse_error(
                            line_no,
                            format!("face has {count} corners, expected at least 3"),
                        ));
                    }
                    if has_positive {
                        positive_refs.push((obj.offsets.len() - 1, line_no));
                    }
                    obj.offsets.push(obj.corners.len());
                    let set = state.current_set(&mut obj.group_sets, &mut obj.group_names);
                    obj.polygon_groups.push(set);
                }
                "g" => {
                    state.g.clear();
                    for name in tokens {
                        let id = state.name_id(name, &mut obj.group_names);
                        state.g.push(id);
                    }
                    state.current = None;
                }
                "o" => {
                    let name: Vec<&str> = tokens.collect();
                    state.o = if name.is_empty() {
                        None
                    } else {
                        Some(state.name_id(&name.join(" "), &mut obj.group_names))
                    };
                    state.current = None;
                }
                "vt" => {
                    let uv = parse_numbers::<2>(&mut tokens, "texture", line_no)?;
                    obj.texcoords.push(DVec2::from_array(uv));
                }
                // vn, vp, s, usemtl, mtllib, l, p and free-form directives: not geometry
                // we use. Skipped rather than rejected, so files from any exporter load.
                _ => {}
            }
        }
        let (n, n_tex) = (obj.vertices.len(), obj.texcoords.len());
        for (p, line) in positive_refs {
            if let Some(&bad) = obj.polygon(p).iter().find(|&&i| i as usize >= n) {
                return Err(parse_error(
                    line,
                    format!(
                        "vertex index {} out of range (file has {n} vertices)",
                        bad as u64 + 1
                    ),
                ));
            }
            let tex = &obj.corner_texcoords[obj.offsets[p]..obj.offsets[p + 1]];
            if let Some(&bad) = tex
                .iter()
                .find(|&&t| t != NO_TEXCOORD && t as usize >= n_tex)
            {
                return Err(parse_error(
                    line,
                    format!(
                        "texture index {} out of range (file has {n_tex} texture coordinates)",
                        bad as u64 + 1
                    ),
                ));
            }
        }
        Ok(obj)
    }

    /// Parses OBJ text held in a string.
    ///
    /// # Errors
    /// As [`ObjFile::parse`].
    pub fn parse_str(text: &str) -> Result<ObjFile> {
        Self::parse(text.as_bytes())
    }

    /// Reads and parses an OBJ file.
    ///
    /// # Errors
    /// [`Error::Io`] if the file cannot be opened or read; otherwise as [`ObjFile::parse`],
    /// with the path prefixed to the message.
    pub fn read(path: impl AsRef<Path>) -> Result<ObjFile> {
        let path = path.as_ref();
        let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
        Self::parse(BufReader::new(file)).map_err(|e| match e {
            Error::Io { source, .. } => Error::io(path, source),
            other => with_path(other, path),
        })
    }

    /// Number of polygons (before triangulation).
    pub fn polygon_count(&self) -> usize {
        self.offsets.len() - 1
    }

    /// Zero-based vertex indices of polygon `p`.
    ///
    /// # Panics
    /// If `p >= self.polygon_count()` (a caller indexing error).
    pub fn polygon(&self, p: usize) -> &[u32] {
        &self.corners[self.offsets[p]..self.offsets[p + 1]]
    }

    /// Names of the groups (`g` and `o`) that own at least one face, in order of first
    /// appearance, each once.
    pub fn group_names(&self) -> Vec<&str> {
        let mut used = vec![false; self.group_names.len()];
        for &s in &self.polygon_groups {
            for &g in &self.group_sets[s as usize] {
                used[g as usize] = true;
            }
        }
        self.group_names
            .iter()
            .zip(used)
            .filter(|(_, u)| *u)
            .map(|(n, _)| n.as_str())
            .collect()
    }

    fn push_triangles(poly: &[u32], out: &mut Vec<[u32; 3]>, map: impl Fn(u32) -> u32) {
        for i in 1..poly.len() - 1 {
            out.push([map(poly[0]), map(poly[i]), map(poly[i + 1])]);
        }
    }

    /// All polygons, fan-triangulated, over all file vertices (indices equal the file's
    /// vertex numbers minus one, unreferenced vertices kept).
    ///
    /// # Errors
    /// [`Error::Empty`] when the file has no faces.
    pub fn to_mesh(&self) -> Result<TriMesh> {
        if self.polygon_count() == 0 {
            return Err(Error::Empty {
                what: "OBJ faces (the file has no 'f' lines)",
            });
        }
        let mut faces = Vec::with_capacity(self.corners.len());
        for p in 0..self.polygon_count() {
            Self::push_triangles(self.polygon(p), &mut faces, |i| i);
        }
        TriMesh::new(self.vertices.clone(), faces)
    }

    /// The faces of group `name` (from `g` or `o` lines), fan-triangulated, over only the
    /// vertices they use, with the map back to the file's vertex indices.
    ///
    /// # Errors
    /// [`Error::InvalidParam`] listing the available groups when no face belongs to `name`.
    pub fn group_mesh(&self, name: &str) -> Result<ObjGroupMesh> {
        let id = self
            .group_names
            .iter()
            .position(|n| n == name)
            .map(|i| i as u32);
        let in_group: Vec<bool> = self
            .group_sets
            .iter()
            .map(|set| id.is_some_and(|id| set.contains(&id)))
            .collect();
        let polygons: Vec<usize> = (0..self.polygon_count())
            .filter(|&p| in_group[self.polygon_groups[p] as usize])
            .collect();
        if polygons.is_empty() {
            return Err(Error::InvalidParam {
                name: "group",
                reason: format!(
                    "no faces in OBJ group '{name}'; groups with faces: [{}]",
                    self.group_names().join(", ")
                ),
            });
        }
        let (new_index, original_index) = compact_vertices(
            self.vertices.len(),
            polygons
                .iter()
                .flat_map(|&p| self.polygon(p).iter().copied()),
        );
        let vertices = original_index
            .iter()
            .map(|&i| self.vertices[i as usize])
            .collect();
        let mut faces = Vec::new();
        let mut uv_faces = Vec::new();
        let mut textured = true;
        for &p in &polygons {
            Self::push_triangles(self.polygon(p), &mut faces, |i| new_index[i as usize]);
            let tex = &self.corner_texcoords[self.offsets[p]..self.offsets[p + 1]];
            textured &= tex.iter().all(|&t| t != NO_TEXCOORD);
            if textured {
                Self::push_triangles(tex, &mut uv_faces, |t| t);
            }
        }
        let uvs = textured.then(|| UvLayout {
            coords: self.texcoords.clone(),
            faces: uv_faces,
        });
        Ok(ObjGroupMesh {
            mesh: TriMesh::new(vertices, faces)?,
            original_index,
            uvs,
        })
    }
}

/// Reads an OBJ file as one triangle mesh over all its vertices (see [`ObjFile::to_mesh`]).
///
/// # Errors
/// As [`ObjFile::read`] and [`ObjFile::to_mesh`].
pub fn read_obj(path: impl AsRef<Path>) -> Result<TriMesh> {
    ObjFile::read(path)?.to_mesh()
}

/// Reads OBJ text from a reader as one triangle mesh (see [`ObjFile::to_mesh`]).
///
/// # Errors
/// As [`ObjFile::parse`] and [`ObjFile::to_mesh`].
pub fn read_obj_from_reader<R: BufRead>(reader: R) -> Result<TriMesh> {
    ObjFile::parse(reader)?.to_mesh()
}

/// Parses OBJ text as one triangle mesh (see [`ObjFile::to_mesh`]).
///
/// # Errors
/// As [`ObjFile::parse`] and [`ObjFile::to_mesh`].
///
/// # Example
/// ```
/// let mesh = skin_core::mesh::read_obj_from_str("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n")?;
/// assert_eq!(mesh.faces, vec![[0, 1, 2], [0, 2, 3]]);
/// # Ok::<(), skin_core::Error>(())
/// ```
pub fn read_obj_from_str(text: &str) -> Result<TriMesh> {
    ObjFile::parse_str(text)?.to_mesh()
}

/// Reads the faces of one group of an OBJ file, vertices compacted and re-indexed.
///
/// Use [`read_obj_group_with_map`] when you also need the original vertex numbers (e.g. to
/// apply MakeHuman skin weights, which refer to them).
///
/// # Errors
/// As [`ObjFile::read`]; [`Error::InvalidParam`] listing the available groups when `group` has
/// no faces.
///
/// # Example
/// ```no_run
/// let body = skin_core::mesh::read_obj_group("data/makehuman/base.obj", "body")?;
/// # Ok::<(), skin_core::Error>(())
/// ```
pub fn read_obj_group(path: impl AsRef<Path>, group: &str) -> Result<TriMesh> {
    Ok(read_obj_group_with_map(path, group)?.mesh)
}

/// As [`read_obj_group`], also returning the compacted-to-original vertex index map.
///
/// # Errors
/// As [`read_obj_group`].
pub fn read_obj_group_with_map(path: impl AsRef<Path>, group: &str) -> Result<ObjGroupMesh> {
    ObjFile::read(path)?.group_mesh(group)
}

/// Writes `mesh` as OBJ text (`v` and `f` lines, 1-based indices) to `writer`.
///
/// Coordinates are written in Rust's shortest round-trip form, so reading the file back gives
/// bit-identical positions.
///
/// # Errors
/// As [`TriMesh::validate`]; [`Error::Io`] if writing fails.
pub fn write_obj_to<W: Write>(mut writer: W, mesh: &TriMesh) -> Result<()> {
    mesh.validate()?;
    let io = |e| Error::io("<writer>", e);
    writeln!(writer, "# written by dynamic-shapes skin-core").map_err(io)?;
    writeln!(
        writer,
        "# {} vertices, {} triangles",
        mesh.vertex_count(),
        mesh.face_count()
    )
    .map_err(io)?;
    for v in &mesh.vertices {
        writeln!(writer, "v {:?} {:?} {:?}", v.x, v.y, v.z).map_err(io)?;
    }
    for f in &mesh.faces {
        writeln!(writer, "f {} {} {}", f[0] + 1, f[1] + 1, f[2] + 1).map_err(io)?;
    }
    writer.flush().map_err(io)
}

/// Writes `mesh` to an OBJ file (see [`write_obj_to`]).
///
/// # Errors
/// As [`write_obj_to`]; I/O errors carry `path`.
pub fn write_obj(path: impl AsRef<Path>, mesh: &TriMesh) -> Result<()> {
    let path = path.as_ref();
    mesh.validate()?;
    let file = std::fs::File::create(path).map_err(|e| Error::io(path, e))?;
    write_obj_to(BufWriter::new(file), mesh).map_err(|e| match e {
        Error::Io { source, .. } => Error::io(path, source),
        other => other,
    })
}

#[cfg(test)]
mod tests;
