//! The model file and the molded-sequence files learning streams from.

use std::fs::File;
use std::io::{BufReader, BufWriter, Read, Write};
use std::path::{Path, PathBuf};

use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};
use skin_core::math::DVec3;

use super::{FrameStream, Parts, ShapeModel, TrainingFrame};
use crate::error::{Context, Error, Result, ResultExt};

const MODEL_MAGIC: &[u8; 8] = b"DSSHAPE2";
const SEQUENCE_MAGIC: &[u8; 8] = b"DSMOLD01";
/// Largest JSON header read, bytes (a template of a million vertices fits).
const MAX_HEADER_BYTES: u64 = 1 << 30;

fn io(path: &Path) -> impl Fn(std::io::Error) -> Error + '_ {
    move |e| skin_core::Error::io(path, e).into()
}

fn malformed(what: &'static str, message: String) -> Error {
    skin_core::Error::Parse {
        format: what,
        line: 0,
        message,
    }
    .into()
}

fn write_header(w: &mut impl Write, magic: &[u8; 8], json: &[u8]) -> std::io::Result<()> {
    w.write_all(magic)?;
    w.write_all(&(json.len() as u64).to_le_bytes())?;
    w.write_all(json)
}

/// Reads the magic and the JSON header; `Ok(None)` at a clean end of file is not allowed.
fn read_header<T: for<'de> Deserialize<'de>>(
    r: &mut impl Read,
    path: &Path,
    magic: &[u8; 8],
    what: &'static str,
) -> Result<T> {
    let mut head = [0u8; 16];
    r.read_exact(&mut head).map_err(io(path))?;
    if &head[..8] != magic {
        return Err(malformed(
            what,
            format!(
                "{} does not start with {:?}",
                path.display(),
                String::from_utf8_lossy(magic)
            ),
        ));
    }
    let len = u64::from_le_bytes(head[8..].try_into().unwrap_or_default());
    if len > MAX_HEADER_BYTES {
        return Err(malformed(what, format!("header of {len} bytes")));
    }
    let mut json = vec![0u8; len as usize];
    r.read_exact(&mut json).map_err(io(path))?;
    serde_json::from_slice(&json).map_err(|e| malformed(what, format!("header: {e}")))
}

/// Fills `buf`; `Ok(false)` at a clean end of file before its first byte (the end of a
/// sequence), an `UnexpectedEof` error in the middle of it.
fn fill_or_end(r: &mut impl Read, buf: &mut [u8]) -> std::io::Result<bool> {
    let mut got = 0;
    while got < buf.len() {
        match r.read(&mut buf[got..])? {
            0 if got == 0 => return Ok(false),
            0 => return Err(std::io::ErrorKind::UnexpectedEof.into()),
            n => got += n,
        }
    }
    Ok(true)
}

fn read_f64s(r: &mut impl Read, out: &mut [f64]) -> std::io::Result<()> {
    let mut buf = vec![0u8; 8 * out.len()];
    r.read_exact(&mut buf)?;
    for (x, b) in out.iter_mut().zip(buf.chunks_exact(8)) {
        *x = f64::from_le_bytes(b.try_into().unwrap_or_default());
    }
    Ok(())
}

impl ShapeModel {
    /// Writes the model to `path`. The format, little-endian:
    ///
    /// | bytes | content |
    /// |---|---|
    /// | 8 | `DSSHAPE2` |
    /// | 8 | `H`, the header's length (u64) |
    /// | `H` | the header, UTF-8 JSON: the template (mesh, skeleton, weights), the frame time, the parameters, the feature layout, the pose regression, the filters and the dynamic map |
    /// | `8 · n · k` | the residual basis `U` (f64), component after component, one normal offset per vertex |
    ///
    /// # Errors
    /// [`skin_core::Error::Io`] (in [`Error::Core`]) when the file cannot be written.
    pub fn save(&self, path: impl AsRef<Path>) -> Result<()> {
        let path = path.as_ref();
        let json = serde_json::to_vec(&self.parts)
            .map_err(|e| malformed("shape model", format!("cannot encode: {e}")))?;
        let mut w = BufWriter::new(File::create(path).map_err(io(path))?);
        write_header(&mut w, MODEL_MAGIC, &json).map_err(io(path))?;
        for x in self.basis.iter() {
            w.write_all(&x.to_le_bytes()).map_err(io(path))?;
        }
        w.flush().map_err(io(path))
    }

    /// Reads a model written by [`ShapeModel::save`].
    ///
    /// # Errors
    /// [`skin_core::Error::Io`] for a missing or short file; [`skin_core::Error::Parse`] for
    /// another format, a malformed header or trailing bytes; as
    /// [`crate::Template::new`]'s checks for a header whose parts disagree in size.
    pub fn load(path: impl AsRef<Path>) -> Result<ShapeModel> {
        let path = path.as_ref();
        let mut r = BufReader::new(File::open(path).map_err(io(path))?);
        let parts: Parts = read_header(&mut r, path, MODEL_MAGIC, "shape model")?;
        let n = parts.template.vertex_count();
        let nf = parts.feature_rest.len();
        let k = parts.pose_weights.len() / nf.max(1);
        let outputs = parts.params.poles.len() * parts.input_scale.len();
        let consistent = k > 0
            && parts.pose_weights.len() == nf * k
            && nf == parts.layout.pose_len()
            && parts.input_scale.len() == parts.layout.motion_len()
            && parts.dynamic_weights.len() == outputs * k
            && parts.frame_time_s > 0.0;
        if !consistent {
            return Err(malformed(
                "shape model",
                "header parts disagree in size".into(),
            ));
        }
        let mut data = vec![0.0; n * k];
        read_f64s(&mut r, &mut data).map_err(io(path))?;
        if r.read(&mut [0u8; 1]).map_err(io(path))? != 0 {
            return Err(malformed(
                "shape model",
                "trailing bytes after the basis".into(),
            ));
        }
        let parents = parts
            .template
            .skeleton()
            .joints()
            .iter()
            .map(|j| j.parent)
            .collect();
        Ok(ShapeModel {
            basis: DMatrix::from_vec(n, k, data),
            parts,
            parents,
        })
    }
}

/// A molded-sequence file's header.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
struct SequenceHeader {
    vertices: usize,
    dofs: usize,
    frame_time_s: f64,
}

/// Writes a sequence of posed frames (a capture's tracked poses and molded vertices) to a
/// file that [`SequenceFiles`] streams back, one frame at a time. The format, little-endian:
/// `DSMOLD01`, the header's length (u64), the header (JSON: `vertices`, `dofs`,
/// `frame_time_s`), then per frame θ (`dofs` f64) and the vertices (`3 · vertices` f32,
/// `x, y, z` per vertex: 30 µm at 1 m, far below any molding's error, at half the size).
#[derive(Debug)]
pub struct SequenceWriter {
    out: BufWriter<File>,
    path: PathBuf,
    header: SequenceHeader,
    frames: usize,
}

impl SequenceWriter {
    /// Creates the file.
    ///
    /// # Errors
    /// [`skin_core::Error::Io`] when it cannot be created; [`Error::InvalidParam`] for a
    /// non-positive frame time or no vertices.
    pub fn create(
        path: impl AsRef<Path>,
        vertices: usize,
        dofs: usize,
        frame_time_s: f64,
    ) -> Result<Self> {
        let path = path.as_ref().to_path_buf();
        if !(frame_time_s.is_finite() && frame_time_s > 0.0) || vertices == 0 || dofs == 0 {
            return Err(Error::InvalidParam {
                name: "sequence file",
                reason: format!(
                    "{vertices} vertices, {dofs} DOFs at {frame_time_s} s per frame: give a \
                     template, a skeleton and a positive frame time"
                ),
            });
        }
        let header = SequenceHeader {
            vertices,
            dofs,
            frame_time_s,
        };
        let json = serde_json::to_vec(&header)
            .map_err(|e| malformed("molded sequence", format!("cannot encode: {e}")))?;
        let mut out = BufWriter::new(File::create(&path).map_err(io(&path))?);
        write_header(&mut out, SEQUENCE_MAGIC, &json).map_err(io(&path))?;
        Ok(SequenceWriter {
            out,
            path,
            header,
            frames: 0,
        })
    }

    /// Appends one frame.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] for another vertex or DOF count; [`Error::NonFinite`];
    /// [`skin_core::Error::Io`].
    pub fn push(&mut self, theta: &[f64], vertices: &[DVec3]) -> Result<()> {
        let at = Context::Frame(self.frames);
        skin_core::check::same_size("pose DOFs", self.header.dofs, theta.len()).at(at)?;
        skin_core::check::same_size("frame vertices", self.header.vertices, vertices.len())
            .at(at)?;
        if theta.iter().any(|x| !x.is_finite()) || vertices.iter().any(|v| !v.is_finite()) {
            return Err(Error::NonFinite {
                what: "sequence frame",
            })
            .at(at);
        }
        let path = &self.path;
        for x in theta {
            self.out.write_all(&x.to_le_bytes()).map_err(io(path))?;
        }
        for v in vertices {
            for c in v.to_array() {
                self.out
                    .write_all(&(c as f32).to_le_bytes())
                    .map_err(io(path))?;
            }
        }
        self.frames += 1;
        Ok(())
    }

    /// Flushes the file; returns the frames written.
    ///
    /// # Errors
    /// [`skin_core::Error::Io`].
    pub fn finish(mut self) -> Result<usize> {
        self.out.flush().map_err(io(&self.path))?;
        Ok(self.frames)
    }
}

/// Sequence files written by [`SequenceWriter`], streamed as one [`FrameStream`] (each file
/// one sequence, in order).
#[derive(Debug, Clone, PartialEq)]
pub struct SequenceFiles(pub Vec<PathBuf>);

impl SequenceFiles {
    fn open(path: &Path) -> Result<(BufReader<File>, SequenceHeader)> {
        let mut r = BufReader::new(File::open(path).map_err(io(path))?);
        let header: SequenceHeader = read_header(&mut r, path, SEQUENCE_MAGIC, "molded sequence")?;
        Ok((r, header))
    }
}

impl FrameStream for SequenceFiles {
    fn frame_time_s(&mut self) -> Result<f64> {
        let mut time = None;
        for path in &self.0 {
            let (_, h) = Self::open(path)?;
            match time {
                None => time = Some(h.frame_time_s),
                Some(t) if t != h.frame_time_s => {
                    return Err(Error::InvalidParam {
                        name: "sequence files",
                        reason: format!(
                            "{} is at {} s per frame, the first at {t}",
                            path.display(),
                            h.frame_time_s
                        ),
                    })
                }
                Some(_) => {}
            }
        }
        time.ok_or(Error::Empty {
            what: "sequence files",
        })
    }

    fn for_each(&mut self, each: &mut dyn FnMut(TrainingFrame<'_>) -> Result<()>) -> Result<()> {
        for (sequence, path) in self.0.iter().enumerate() {
            let (mut r, h) = Self::open(path)?;
            let mut theta = vec![0.0; h.dofs];
            let mut raw = vec![0u8; 12 * h.vertices];
            let mut vertices = vec![DVec3::ZERO; h.vertices];
            let mut pose = vec![0u8; 8 * h.dofs];
            while fill_or_end(&mut r, &mut pose).map_err(io(path))? {
                for (x, b) in theta.iter_mut().zip(pose.chunks_exact(8)) {
                    *x = f64::from_le_bytes(b.try_into().unwrap_or_default());
                }
                r.read_exact(&mut raw).map_err(io(path))?;
                for (v, b) in vertices.iter_mut().zip(raw.chunks_exact(12)) {
                    let c = |i: usize| {
                        f64::from(f32::from_le_bytes(
                            b[4 * i..4 * i + 4].try_into().unwrap_or_default(),
                        ))
                    };
                    *v = DVec3::new(c(0), c(1), c(2));
                }
                each(TrainingFrame {
                    sequence,
                    theta: &theta,
                    vertices: &vertices,
                })?;
            }
        }
        Ok(())
    }
}
