//! glTF 2.0 export of a mesh sequence (feature `gltf`): one mesh whose per-frame shapes are
//! morph targets, played by an animation of the morph weights — the standard way to carry
//! captured vertex animation (a topology-constant sequence with no rig) into Blender, three.js
//! or any glTF viewer. Written as a self-contained binary `.glb`.
//!
//! **Layout.** The base mesh is the first frame (positions, optional `TEXCOORD_0`, indices);
//! frame `k` is morph target `k` holding `frame_k − frame_0`; the animation's sampler has one
//! key per frame at `k · frame_time_s` whose weight vector is one-hot on target `k`, with
//! linear interpolation (between keys a viewer blends two consecutive frames). Positions and
//! offsets are `f32` (glTF has no `f64` vertex data): metres keep about 0.1 µm near the origin,
//! far below any capture's error. Texture coordinates are written with glTF's `v` pointing
//! down (`v_gltf = 1 − v`), the convention of OBJ files flipped.

use std::io::Write;
use std::path::Path;

use gltf_json as json;
use json::validation::{Checked, USize64};

use crate::math::{DVec2, DVec3};
use crate::{Error, Result};

/// A mesh sequence to export: shared faces, one vertex list per frame.
#[cfg_attr(docsrs, doc(cfg(feature = "gltf")))]
#[derive(Debug, Clone, Copy)]
pub struct MeshSequence<'a> {
    /// Triangles (vertex indices, counter-clockwise from outside).
    pub faces: &'a [[u32; 3]],
    /// Vertex positions per frame, metres; every frame has the same count.
    pub frames: &'a [Vec<DVec3>],
    /// Time between frames, seconds.
    pub frame_time_s: f64,
    /// Optional texture coordinates per vertex (OBJ convention: `v` up), carried unchanged
    /// through the sequence.
    pub uvs: Option<&'a [DVec2]>,
    /// Name of the mesh, node and animation in the file.
    pub name: &'a str,
}

/// Writes `sequence` as a binary glTF (`.glb`) to `out`.
///
/// # Errors
/// [`Error::Empty`] for no frame or no face; [`Error::SizeMismatch`] for frames or texture
/// coordinates whose counts differ from the first frame's; [`Error::IndexOutOfRange`] for a
/// face index past the vertices; [`Error::NonFinite`] for NaN or infinite positions or
/// coordinates; [`Error::InvalidParam`] for a frame time that is not positive or a sequence
/// too large for glTF's 32-bit sizes; [`Error::Io`] from the writer.
#[cfg_attr(docsrs, doc(cfg(feature = "gltf")))]
pub fn write_gltf_animation(sequence: &MeshSequence<'_>, out: impl Write) -> Result<()> {
    let (json, bin) = encode(sequence)?;
    write_glb(&json, &bin, out)
}

/// [`write_gltf_animation`] into the file `path` (created or truncated).
///
/// # Errors
/// As [`write_gltf_animation`]; [`Error::Io`] when the file cannot be created.
#[cfg_attr(docsrs, doc(cfg(feature = "gltf")))]
pub fn save_gltf_animation(path: impl AsRef<Path>, sequence: &MeshSequence<'_>) -> Result<()> {
    let path = path.as_ref();
    let file = std::fs::File::create(path).map_err(|e| Error::io(path, e))?;
    let mut w = std::io::BufWriter::new(file);
    write_gltf_animation(sequence, &mut w)?;
    w.flush().map_err(|e| Error::io(path, e))
}

fn check(sequence: &MeshSequence<'_>) -> Result<usize> {
    let Some(first) = sequence.frames.first() else {
        return Err(Error::Empty {
            what: "mesh sequence frames",
        });
    };
    if sequence.faces.is_empty() {
        return Err(Error::Empty {
            what: "mesh sequence faces",
        });
    }
    crate::check::positive("frame_time_s", sequence.frame_time_s)?;
    let n = first.len();
    for f in sequence.frames {
        crate::check::same_size("vertices of a frame vs the first frame", n, f.len())?;
        if f.iter().any(|p| !p.is_finite()) {
            return Err(Error::NonFinite {
                what: "mesh sequence vertices",
            });
        }
    }
    if let Some(uv) = sequence.uvs {
        crate::check::same_size("texture coordinates vs vertices", n, uv.len())?;
        if uv.iter().any(|p| !p.is_finite()) {
            return Err(Error::NonFinite {
                what: "texture coordinates",
            });
        }
    }
    for face in sequence.faces {
        for &v in face {
            crate::check::index("face vertex", v as usize, n)?;
        }
    }
    // Everything the file addresses must fit glTF's u32 indices and byte lengths.
    let frames = sequence.frames.len();
    let bytes = 12 * n * frames + 4 * frames * (frames + 1) + 12 * sequence.faces.len() + 8 * n;
    if bytes > u32::MAX as usize {
        return Err(Error::InvalidParam {
            name: "mesh sequence",
            reason: format!("{bytes} bytes of data exceed glTF's 4 GiB binary chunk"),
        });
    }
    Ok(n)
}

/// Appends `data` to `bin` (4-byte aligned) and returns its view.
fn push_view(
    root: &mut json::Root,
    bin: &mut Vec<u8>,
    data: &[u8],
    target: Option<json::buffer::Target>,
) -> json::Index<json::buffer::View> {
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let offset = bin.len();
    bin.extend_from_slice(data);
    root.push(json::buffer::View {
        buffer: json::Index::new(0),
        byte_length: USize64::from(data.len()),
        byte_offset: Some(USize64::from(offset)),
        byte_stride: None,
        name: None,
        target: target.map(Checked::Valid),
        extensions: Default::default(),
        extras: Default::default(),
    })
}

fn accessor(
    root: &mut json::Root,
    view: json::Index<json::buffer::View>,
    count: usize,
    component: json::accessor::ComponentType,
    type_: json::accessor::Type,
    bounds: Option<([f32; 3], [f32; 3])>,
) -> json::Index<json::Accessor> {
    root.push(json::Accessor {
        buffer_view: Some(view),
        byte_offset: None,
        count: USize64::from(count),
        component_type: Checked::Valid(json::accessor::GenericComponentType(component)),
        extensions: Default::default(),
        extras: Default::default(),
        type_: Checked::Valid(type_),
        min: bounds.map(|(lo, _)| serde_json::json!(lo)),
        max: bounds.map(|(_, hi)| serde_json::json!(hi)),
        name: None,
        normalized: false,
        sparse: None,
    })
}

/// `f32` xyz triples and their bounds.
fn vec3_bytes(v: impl Iterator<Item = DVec3>) -> (Vec<u8>, ([f32; 3], [f32; 3])) {
    let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    let mut bytes = Vec::new();
    for p in v {
        let q = p.as_vec3().to_array();
        for a in 0..3 {
            lo[a] = lo[a].min(q[a]);
            hi[a] = hi[a].max(q[a]);
            bytes.extend_from_slice(&q[a].to_le_bytes());
        }
    }
    (bytes, (lo, hi))
}

fn f32_bytes(v: impl Iterator<Item = f32>) -> Vec<u8> {
    v.flat_map(f32::to_le_bytes).collect()
}

fn encode(sequence: &MeshSequence<'_>) -> Result<(Vec<u8>, Vec<u8>)> {
    use json::accessor::{ComponentType, Type};
    let n = check(sequence)?;
    let frames = sequence.frames;
    let base = &frames[0];
    let mut root = json::Root::default();
    let mut bin = Vec::new();
    let (bytes, bounds) = vec3_bytes(base.iter().copied());
    let view = push_view(
        &mut root,
        &mut bin,
        &bytes,
        Some(json::buffer::Target::ArrayBuffer),
    );
    let positions = accessor(
        &mut root,
        view,
        n,
        ComponentType::F32,
        Type::Vec3,
        Some(bounds),
    );
    let mut attributes = std::collections::BTreeMap::new();
    attributes.insert(Checked::Valid(json::mesh::Semantic::Positions), positions);
    if let Some(uv) = sequence.uvs {
        let bytes = f32_bytes(uv.iter().flat_map(|t| [t.x as f32, (1.0 - t.y) as f32]));
        let view = push_view(
            &mut root,
            &mut bin,
            &bytes,
            Some(json::buffer::Target::ArrayBuffer),
        );
        let uvs = accessor(&mut root, view, n, ComponentType::F32, Type::Vec2, None);
        attributes.insert(Checked::Valid(json::mesh::Semantic::TexCoords(0)), uvs);
    }
    let index_bytes: Vec<u8> = sequence
        .faces
        .iter()
        .flatten()
        .flat_map(|i| i.to_le_bytes())
        .collect();
    let view = push_view(
        &mut root,
        &mut bin,
        &index_bytes,
        Some(json::buffer::Target::ElementArrayBuffer),
    );
    let indices = accessor(
        &mut root,
        view,
        3 * sequence.faces.len(),
        ComponentType::U32,
        Type::Scalar,
        None,
    );
    // One morph target per frame (frame 0's is zero: it keeps target k = frame k).
    let mut targets = Vec::with_capacity(frames.len());
    for f in frames {
        let (bytes, bounds) = vec3_bytes(f.iter().zip(base).map(|(p, b)| *p - *b));
        let view = push_view(
            &mut root,
            &mut bin,
            &bytes,
            Some(json::buffer::Target::ArrayBuffer),
        );
        targets.push(json::mesh::MorphTarget {
            positions: Some(accessor(
                &mut root,
                view,
                n,
                ComponentType::F32,
                Type::Vec3,
                Some(bounds),
            )),
            normals: None,
            tangents: None,
        });
    }
    let k = frames.len();
    let mesh = root.push(json::Mesh {
        extensions: Default::default(),
        extras: Default::default(),
        name: Some(sequence.name.to_string()),
        primitives: vec![json::mesh::Primitive {
            attributes,
            extensions: Default::default(),
            extras: Default::default(),
            indices: Some(indices),
            material: None,
            mode: Checked::Valid(json::mesh::Mode::Triangles),
            targets: Some(targets),
        }],
        weights: Some((0..k).map(|i| if i == 0 { 1.0 } else { 0.0 }).collect()),
    });
    let node = root.push(json::Node {
        mesh: Some(mesh),
        name: Some(sequence.name.to_string()),
        ..Default::default()
    });
    let scene = root.push(json::Scene {
        extensions: Default::default(),
        extras: Default::default(),
        name: None,
        nodes: vec![node],
    });
    root.scene = Some(scene);
    // Keyframe times and one-hot weights.
    let times: Vec<f32> = (0..k)
        .map(|i| (i as f64 * sequence.frame_time_s) as f32)
        .collect();
    let (t0, t1) = (times[0], times[k - 1]);
    let view = push_view(&mut root, &mut bin, &f32_bytes(times.into_iter()), None);
    let input = root.push(json::Accessor {
        min: Some(serde_json::json!([t0])),
        max: Some(serde_json::json!([t1])),
        ..scalar_accessor(view, k)
    });
    let weights = (0..k).flat_map(|key| (0..k).map(move |t| if t == key { 1.0 } else { 0.0 }));
    let view = push_view(&mut root, &mut bin, &f32_bytes(weights), None);
    let output = root.push(scalar_accessor(view, k * k));
    let sampler = json::animation::Sampler {
        extensions: Default::default(),
        extras: Default::default(),
        input,
        interpolation: Checked::Valid(json::animation::Interpolation::Linear),
        output,
    };
    root.push(json::Animation {
        extensions: Default::default(),
        extras: Default::default(),
        channels: vec![json::animation::Channel {
            sampler: json::Index::new(0),
            target: json::animation::Target {
                extensions: Default::default(),
                extras: Default::default(),
                node,
                path: Checked::Valid(json::animation::Property::MorphTargetWeights),
            },
            extensions: Default::default(),
            extras: Default::default(),
        }],
        name: Some(sequence.name.to_string()),
        samplers: vec![sampler],
    });
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    root.push(json::Buffer {
        byte_length: USize64::from(bin.len()),
        name: None,
        uri: None,
        extensions: Default::default(),
        extras: Default::default(),
    });
    root.asset.generator = Some(format!(
        "dynamic-shapes skin-core {}",
        env!("CARGO_PKG_VERSION")
    ));
    let text = json::serialize::to_vec(&root).map_err(|e| Error::InvalidParam {
        name: "mesh sequence",
        reason: format!("glTF JSON could not be serialised: {e}"),
    })?;
    Ok((text, bin))
}

fn scalar_accessor(view: json::Index<json::buffer::View>, count: usize) -> json::Accessor {
    json::Accessor {
        buffer_view: Some(view),
        byte_offset: None,
        count: USize64::from(count),
        component_type: Checked::Valid(json::accessor::GenericComponentType(
            json::accessor::ComponentType::F32,
        )),
        extensions: Default::default(),
        extras: Default::default(),
        type_: Checked::Valid(json::accessor::Type::Scalar),
        min: None,
        max: None,
        name: None,
        normalized: false,
        sparse: None,
    }
}

/// The GLB container: 12-byte header, the JSON chunk padded with spaces, the binary chunk
/// padded with zeros (glTF 2.0 §4.4).
fn write_glb(json_text: &[u8], bin: &[u8], mut out: impl Write) -> Result<()> {
    let pad = |len: usize| (4 - len % 4) % 4;
    let json_len = json_text.len() + pad(json_text.len());
    let bin_len = bin.len() + pad(bin.len());
    let total = 12 + 8 + json_len + 8 + bin_len;
    let total = u32::try_from(total).map_err(|_| Error::InvalidParam {
        name: "mesh sequence",
        reason: "the file would exceed glTF's 4 GiB".into(),
    })?;
    let io = |e| Error::io(Path::new("<glb writer>"), e);
    let mut header = Vec::with_capacity(28);
    header.extend_from_slice(b"glTF");
    header.extend_from_slice(&2u32.to_le_bytes());
    header.extend_from_slice(&total.to_le_bytes());
    header.extend_from_slice(&(json_len as u32).to_le_bytes());
    header.extend_from_slice(b"JSON");
    out.write_all(&header).map_err(io)?;
    out.write_all(json_text).map_err(io)?;
    out.write_all(&vec![b' '; pad(json_text.len())])
        .map_err(io)?;
    out.write_all(&(bin_len as u32).to_le_bytes()).map_err(io)?;
    out.write_all(b"BIN\0").map_err(io)?;
    out.write_all(bin).map_err(io)?;
    out.write_all(&vec![0u8; pad(bin.len())]).map_err(io)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::shapes;

    fn wobble(frames: usize) -> (crate::mesh::TriMesh, Vec<Vec<DVec3>>) {
        let mesh = shapes::icosphere(2).unwrap();
        let seq = (0..frames)
            .map(|k| {
                mesh.vertices
                    .iter()
                    .map(|p| {
                        *p * (1.0 + 0.1 * (k as f64 * 0.7 + p.y * 3.0).sin())
                            + DVec3::X * k as f64 * 0.01
                    })
                    .collect()
            })
            .collect();
        (mesh, seq)
    }

    #[test]
    fn the_file_validates_and_loads_back_every_frame() {
        let (mesh, frames) = wobble(5);
        let uvs: Vec<DVec2> = mesh
            .vertices
            .iter()
            .map(|p| DVec2::new(0.5 + 0.5 * p.x, 0.5 + 0.5 * p.y))
            .collect();
        let mut glb = Vec::new();
        write_gltf_animation(
            &MeshSequence {
                faces: &mesh.faces,
                frames: &frames,
                frame_time_s: 1.0 / 30.0,
                uvs: Some(&uvs),
                name: "wobble",
            },
            &mut glb,
        )
        .unwrap();
        // The loader validates the document (indices, accessor bounds, required fields).
        let gltf = gltf::Gltf::from_slice(&glb).unwrap();
        let blob = gltf.blob.as_deref().unwrap();
        let m = gltf.meshes().next().unwrap();
        let prim = m.primitives().next().unwrap();
        let reader = prim.reader(|_| Some(blob));
        let base: Vec<[f32; 3]> = reader.read_positions().unwrap().collect();
        let idx: Vec<u32> = reader.read_indices().unwrap().into_u32().collect();
        assert_eq!(idx.len(), 3 * mesh.faces.len());
        assert_eq!(idx[..3], mesh.faces[0]);
        let tex: Vec<[f32; 2]> = reader.read_tex_coords(0).unwrap().into_f32().collect();
        assert!((tex[7][1] - (1.0 - uvs[7].y as f32)).abs() < 1e-6);
        let targets: Vec<_> = reader.read_morph_targets().collect();
        assert_eq!(targets.len(), frames.len());
        for (k, (pos, _, _)) in targets.into_iter().enumerate() {
            for (i, d) in pos.unwrap().enumerate() {
                let p = DVec3::new(
                    (base[i][0] + d[0]) as f64,
                    (base[i][1] + d[1]) as f64,
                    (base[i][2] + d[2]) as f64,
                );
                assert!(p.distance(frames[k][i]) < 1e-6, "frame {k} vertex {i}");
            }
        }
        let anim = gltf.animations().next().unwrap();
        let channel = anim.channels().next().unwrap();
        let r = channel.reader(|_| Some(blob));
        let times: Vec<f32> = r.read_inputs().unwrap().collect();
        assert_eq!(times.len(), 5);
        assert!((times[4] - 4.0 / 30.0).abs() < 1e-6);
        let Some(gltf::animation::util::ReadOutputs::MorphTargetWeights(w)) = r.read_outputs()
        else {
            panic!("morph weights expected");
        };
        let w: Vec<f32> = w.into_f32().collect();
        assert_eq!(w.len(), 25);
        assert_eq!(w[2 * 5 + 2], 1.0);
        assert_eq!(w.iter().sum::<f32>(), 5.0);
    }

    #[test]
    fn bad_sequences_are_errors() {
        let (mesh, mut frames) = wobble(3);
        let write = |frames: &[Vec<DVec3>], faces: &[[u32; 3]], dt: f64| {
            write_gltf_animation(
                &MeshSequence {
                    faces,
                    frames,
                    frame_time_s: dt,
                    uvs: None,
                    name: "bad",
                },
                Vec::new(),
            )
        };
        assert!(matches!(
            write(&[], &mesh.faces, 0.1),
            Err(Error::Empty { .. })
        ));
        assert!(matches!(write(&frames, &[], 0.1), Err(Error::Empty { .. })));
        assert!(write(&frames, &mesh.faces, 0.0).is_err());
        assert!(matches!(
            write(&frames, &[[0, 1, 100_000]], 0.1),
            Err(Error::IndexOutOfRange { .. })
        ));
        frames[1][3].x = f64::NAN;
        assert!(matches!(
            write(&frames, &mesh.faces, 0.1),
            Err(Error::NonFinite { .. })
        ));
        frames[1].pop();
        assert!(matches!(
            write(&frames, &mesh.faces, 0.1),
            Err(Error::SizeMismatch { .. })
        ));
    }
}
