//! Frame-range entry points for batch runs (a Ray cluster, a job array): each takes a capture
//! on disk, a range of its frames and an output prefix, and writes its outputs under the
//! prefix, so a worker needs nothing but paths and plain numbers (what a task scheduler can
//! pickle; PyO3 objects cannot be). The studio writes the inputs ([`write_photometric_capture`],
//! [`write_silhouette_capture`]).
//!
//! The module lives in the bindings crate, not in the method crates: the capture folder's
//! layout (NumPy `.npy` arrays, JSON cameras and skeleton) is a convention of the batch runs,
//! not of any method, and the four entry points share it; the method crates keep taking
//! values, never paths of a layout of their own. Everything here is plain Rust (no Python),
//! tested by `rust-tests/batch.rs` and bound in Python as `dynamic_shapes.batch`.
//!
//! **A capture folder**: `capture.json` (`kind`, `frames`, `width`, `height`, and per kind:
//! `white_level` for a photometric capture; `skeleton` and `thetas`, the mocap poses, for a
//! silhouette capture); `cameras/camC.json` (each camera in the crates' serde form);
//! `frames/NNNNNN/camC_mask.npy` (`(h, w)` uint8) and, photometric,
//! `frames/NNNNNN/camC_patterns.npy` (`(7, h, w)` float32, X, Y, Z, Full, X̄, Ȳ, Z̄);
//! photometric: `performance_centre.npy` (`(3,)` float64, m), `calibration/spheres.npy`
//! (`(k, 4)` float64: centre and radius of each grey sphere, m) and
//! `calibration/camC_sphereI.npy` (`(7, h, w)` float32, sphere `I` seen by camera `C`);
//! silhouette: `template.obj` (the template a user would rig). Geometry is binary or in a
//! file of its own so that every reader gets the same bits (a number in a shared JSON
//! document is parsed by each reader's own float parser).
//!
//! **Chunks with state**: tracking needs the pose of the frame before its first; a chunk is
//! given its first frame's pose ([`track_chunk`] returns the last pose, which the next chunk
//! takes: chunks of one sequence run in order, while photometric frames, needle chunks and
//! recordings are independent). Needle stores of chunks merge in frame order
//! ([`needle_merge`]) into the store a single run over all frames gives, bit for bit.

use std::fmt;
use std::ops::Range;
use std::path::{Path, PathBuf};

use dynamic_shapes_studio::{makehuman_performer, scan_outer_surface, Capture, ScanParams};
use glam::DVec3;
use needle_model::{BodyLayout, NeedleBody, ObservationStore, ObserveParams, Observer};
use photometric_normals::truth::{
    render_sphere_patterns, SensorNoise, StudioScene, SPHERE_ALBEDO, SPHERE_RADIUS_M,
};
use photometric_normals::{
    estimate_normals, reconstruct, CalibrationParams, CalibrationSphere, Exposure,
    HeightCalibration, LookupTable, NormalParams, PatternImages, PolygonalHull, ReconstructParams,
    PATTERNS,
};
use serde_json::{json, Value};
use skin_core::camera::{Camera, Intrinsics, Rig};
use skin_core::image::{GrayF32Image, Mask};
use skin_core::mesh::{self, bone_heat_weights, rest_bones, HeatWeightsParams, TriMesh};
use skin_core::skeleton::Skeleton;
use template_silhouette::{
    capture_sequence, ContourRayHullParams, FrameObservation, PoseParams, ShapeParams,
    SilhouetteParams, Template,
};

/// What went wrong in a batch entry point.
#[derive(Debug)]
pub enum BatchError {
    /// A file or folder could not be read or written.
    Io {
        /// The path.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// A file with contents that are not what the layout says.
    Format {
        /// The path.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// A bad argument (an empty range, a range past the capture's end, a wrong pose length).
    Input(String),
    /// An error of skin-core or the studio.
    Core(skin_core::Error),
    /// An error of needle-model.
    Needle(needle_model::Error),
    /// An error of template-silhouette.
    Template(template_silhouette::Error),
    /// An error of photometric-normals.
    Photometric(photometric_normals::Error),
    /// An error of inertial-acoustic.
    Inertial(inertial_acoustic::Error),
}

impl fmt::Display for BatchError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            BatchError::Io { path, source } => write!(f, "{}: {source}", path.display()),
            BatchError::Format { path, message } => write!(f, "{}: {message}", path.display()),
            BatchError::Input(m) => f.write_str(m),
            BatchError::Core(e) => e.fmt(f),
            BatchError::Needle(e) => e.fmt(f),
            BatchError::Template(e) => e.fmt(f),
            BatchError::Photometric(e) => e.fmt(f),
            BatchError::Inertial(e) => e.fmt(f),
        }
    }
}

impl std::error::Error for BatchError {}

macro_rules! from_error {
    ($($t:ty => $v:ident),*) => {$(
        impl From<$t> for BatchError {
            fn from(e: $t) -> Self {
                BatchError::$v(e)
            }
        }
    )*};
}
from_error!(skin_core::Error => Core, needle_model::Error => Needle,
    template_silhouette::Error => Template, photometric_normals::Error => Photometric,
    inertial_acoustic::Error => Inertial);

/// The result of a batch entry point.
pub type Result<T> = std::result::Result<T, BatchError>;

fn io(path: &Path) -> impl FnOnce(std::io::Error) -> BatchError + '_ {
    move |source| BatchError::Io {
        path: path.to_path_buf(),
        source,
    }
}

fn format_error(path: &Path, message: impl Into<String>) -> BatchError {
    BatchError::Format {
        path: path.to_path_buf(),
        message: message.into(),
    }
}

/// NumPy `.npy` files (format 1.0, little endian, C order) of the element types the capture
/// folders and the Python fixtures use.
pub mod npy {
    use super::{format_error, io, Result};
    use std::path::Path;

    /// Writes `bytes` (little-endian elements of NumPy type `descr`, e.g. `<f8`, `|u1`) as an
    /// array of `shape`.
    ///
    /// # Errors
    /// [`super::BatchError::Io`] when the file cannot be written.
    pub fn write(path: &Path, descr: &str, shape: &[usize], bytes: &[u8]) -> Result<()> {
        let dims: Vec<String> = shape.iter().map(ToString::to_string).collect();
        let shape = if dims.len() == 1 {
            format!("({},)", dims[0])
        } else {
            format!("({})", dims.join(", "))
        };
        let mut header =
            format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape}, }}");
        while (10 + header.len() + 1) % 64 != 0 {
            header.push(' ');
        }
        header.push('\n');
        let mut out = b"\x93NUMPY\x01\x00".to_vec();
        let len = u16::try_from(header.len()).map_err(|_| format_error(path, "header too long"))?;
        out.extend_from_slice(&len.to_le_bytes());
        out.extend_from_slice(header.as_bytes());
        out.extend_from_slice(bytes);
        std::fs::write(path, out).map_err(io(path))
    }

    /// Reads an array written by [`write()`]: its `descr`, shape and element bytes.
    ///
    /// # Errors
    /// [`super::BatchError::Io`] for a missing file, [`super::BatchError::Format`] for
    /// another format (not `.npy` 1.0, Fortran order, a size that does not match the shape).
    pub fn read(path: &Path) -> Result<(String, Vec<usize>, Vec<u8>)> {
        let bytes = std::fs::read(path).map_err(io(path))?;
        if bytes.len() < 10 || &bytes[..8] != b"\x93NUMPY\x01\x00" {
            return Err(format_error(path, "not a NumPy .npy file (format 1.0)"));
        }
        let len = usize::from(u16::from_le_bytes([bytes[8], bytes[9]]));
        let header = bytes
            .get(10..10 + len)
            .and_then(|h| std::str::from_utf8(h).ok())
            .ok_or_else(|| format_error(path, "truncated header"))?;
        let field = |key: &str| -> Option<&str> {
            let at = header.find(&format!("'{key}':"))? + key.len() + 3;
            Some(header[at..].trim_start())
        };
        let descr = field("descr")
            .and_then(|d| d.strip_prefix('\''))
            .and_then(|d| d.split('\'').next())
            .ok_or_else(|| format_error(path, "no descr"))?
            .to_string();
        if field("fortran_order").is_some_and(|f| f.starts_with("True")) {
            return Err(format_error(path, "Fortran order"));
        }
        let shape_text = field("shape")
            .and_then(|s| s.strip_prefix('('))
            .and_then(|s| s.split(')').next())
            .ok_or_else(|| format_error(path, "no shape"))?;
        let shape = shape_text
            .split(',')
            .map(str::trim)
            .filter(|s| !s.is_empty())
            .map(str::parse)
            .collect::<std::result::Result<Vec<usize>, _>>()
            .map_err(|e| format_error(path, format!("shape: {e}")))?;
        let data = bytes[10 + len..].to_vec();
        let size = match descr.as_str() {
            "<f8" => 8,
            "<f4" | "<u4" => 4,
            "|u1" => 1,
            other => return Err(format_error(path, format!("element type {other}"))),
        };
        if data.len() != size * shape.iter().product::<usize>() {
            return Err(format_error(path, "size does not match the shape"));
        }
        Ok((descr, shape, data))
    }
}

fn write_f32(path: &Path, shape: &[usize], v: impl IntoIterator<Item = f32>) -> Result<()> {
    let b: Vec<u8> = v.into_iter().flat_map(f32::to_le_bytes).collect();
    npy::write(path, "<f4", shape, &b)
}

fn write_f64(path: &Path, shape: &[usize], v: impl IntoIterator<Item = f64>) -> Result<()> {
    let b: Vec<u8> = v.into_iter().flat_map(f64::to_le_bytes).collect();
    npy::write(path, "<f8", shape, &b)
}

fn write_mask(path: &Path, m: &Mask) -> Result<()> {
    let b: Vec<u8> = m.iter().map(u8::from).collect();
    npy::write(path, "|u1", &[m.height() as usize, m.width() as usize], &b)
}

fn read_typed(path: &Path, descr: &str, shape: &[usize]) -> Result<Vec<u8>> {
    let (d, s, data) = npy::read(path)?;
    if d != descr || s != shape {
        return Err(format_error(
            path,
            format!("expected {descr} of shape {shape:?}, found {d} of shape {s:?}"),
        ));
    }
    Ok(data)
}

fn create_dir(path: &Path) -> Result<()> {
    std::fs::create_dir_all(path).map_err(io(path))
}

fn frame_dir(capture: &Path, frame: usize) -> PathBuf {
    capture.join("frames").join(format!("{frame:06}"))
}

/// `prefix` followed by `name` (a prefix ending in `/` is a folder, created if missing).
fn output(prefix: &str, name: &str) -> Result<PathBuf> {
    let path = PathBuf::from(format!("{prefix}{name}"));
    if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
        create_dir(parent)?;
    }
    Ok(path)
}

/// A capture folder's `capture.json`, read and checked.
struct CaptureInfo {
    json: Value,
    frames: usize,
    width: u32,
    height: u32,
    cameras: Vec<Camera>,
}

impl CaptureInfo {
    fn read(capture: &Path, kind: &str) -> Result<Self> {
        let path = capture.join("capture.json");
        let text = std::fs::read_to_string(&path).map_err(io(&path))?;
        let json: Value =
            serde_json::from_str(&text).map_err(|e| format_error(&path, e.to_string()))?;
        if json["kind"] != kind {
            return Err(format_error(
                &path,
                format!("a {} capture, expected {kind}", json["kind"]),
            ));
        }
        let get = |k: &str| -> Result<u64> {
            json[k]
                .as_u64()
                .ok_or_else(|| format_error(&path, format!("no {k}")))
        };
        let (frames, width, height) = (get("frames")?, get("width")?, get("height")?);
        let count = get("cameras")?;
        let cameras = (0..count)
            .map(|c| {
                let p = capture.join("cameras").join(format!("cam{c}.json"));
                let text = std::fs::read_to_string(&p).map_err(io(&p))?;
                serde_json::from_str(&text).map_err(|e| format_error(&p, e.to_string()))
            })
            .collect::<Result<Vec<Camera>>>()?;
        Ok(Self {
            frames: usize::try_from(frames).map_err(|_| format_error(&path, "frames"))?,
            width: u32::try_from(width).map_err(|_| format_error(&path, "width"))?,
            height: u32::try_from(height).map_err(|_| format_error(&path, "height"))?,
            cameras,
            json,
        })
    }

    /// `frames` checked: not empty and within the capture.
    fn check(&self, frames: &Range<usize>) -> Result<()> {
        if frames.is_empty() {
            return Err(BatchError::Input(format!(
                "frames {frames:?}: an empty range"
            )));
        }
        if frames.end > self.frames {
            return Err(BatchError::Input(format!(
                "frames {frames:?}: the capture has {} frames",
                self.frames
            )));
        }
        Ok(())
    }

    fn field<T: serde::de::DeserializeOwned>(&self, capture: &Path, key: &str) -> Result<T> {
        serde_json::from_value(self.json[key].clone())
            .map_err(|e| format_error(&capture.join("capture.json"), format!("{key}: {e}")))
    }

    fn mask(&self, capture: &Path, frame: usize, camera: usize) -> Result<Mask> {
        let path = frame_dir(capture, frame).join(format!("cam{camera}_mask.npy"));
        let (h, w) = (self.height as usize, self.width as usize);
        let data = read_typed(&path, "|u1", &[h, w])?;
        Ok(Mask::from_fn(self.width, self.height, |x, y| {
            data[y as usize * w + x as usize] != 0
        }))
    }

    fn masks(&self, capture: &Path, frame: usize) -> Result<Vec<Mask>> {
        (0..self.cameras.len())
            .map(|c| self.mask(capture, frame, c))
            .collect()
    }

    /// Seven pattern images `(7, h, w)` float32 at `path`.
    fn patterns(&self, path: &Path) -> Result<PatternImages> {
        let (h, w) = (self.height as usize, self.width as usize);
        let data = read_typed(path, "<f4", &[PATTERNS.len(), h, w])?;
        let values: Vec<f32> = data
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect();
        let list = PATTERNS
            .iter()
            .zip(values.chunks_exact(h * w))
            .map(|(&p, v)| {
                GrayF32Image::from_raw(self.width, self.height, v.to_vec())
                    .map(|im| (p, im))
                    .ok_or_else(|| format_error(path, "image size"))
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(PatternImages::new(list)?)
    }
}

fn write_cameras(out: &Path, cameras: &[Camera]) -> Result<()> {
    create_dir(&out.join("cameras"))?;
    for (c, cam) in cameras.iter().enumerate() {
        let path = out.join("cameras").join(format!("cam{c}.json"));
        let text = serde_json::to_string(cam).map_err(|e| format_error(&path, e.to_string()))?;
        std::fs::write(&path, text).map_err(io(&path))?;
    }
    Ok(())
}

fn read_f64(path: &Path, shape: &[usize]) -> Result<Vec<f64>> {
    Ok(read_typed(path, "<f8", shape)?
        .chunks_exact(8)
        .map(|c| f64::from_le_bytes([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]]))
        .collect())
}

fn patterns_f32(images: &PatternImages) -> impl Iterator<Item = f32> + '_ {
    PATTERNS
        .iter()
        .flat_map(|&p| images.image(p).as_raw().iter().copied())
}

/// Writes a photometric capture folder: the photometric validation's studio
/// ([`StudioScene`]: MakeHuman, `skirt` in the skirt, in the exercise under the 1,200-light
/// dome, no cast shadows, `cameras` ring cameras of `size` × `size` px) over the exercise's
/// `frames`, the seven pattern images read through the sensor model at `white_level` (seeded
/// per frame, camera and pattern), and per camera the grey spheres of the calibration.
///
/// # Errors
/// [`BatchError::Input`] for an empty range; the studio's errors (e.g. missing MakeHuman
/// files, a range past the motion); [`BatchError::Io`] when the folder cannot be written.
pub fn write_photometric_capture(
    makehuman_dir: &Path,
    out: &Path,
    frames: Range<usize>,
    cameras: usize,
    size: u32,
    skirt: bool,
    white_level: f32,
) -> Result<()> {
    if frames.is_empty() {
        return Err(BatchError::Input(format!(
            "frames {frames:?}: an empty range"
        )));
    }
    let subject = if skirt {
        photometric_normals::truth::skirt_subject()
    } else {
        dynamic_shapes_studio::DeformationParams::default()
    };
    let scene = StudioScene::new(makehuman_dir, &subject, cameras, size)?;
    let mut spec = scene.capture_spec(scene.ring.clone())?;
    if let Some(lighting) = &mut spec.lighting {
        lighting.shadows = false;
    }
    spec.noise = None;
    let noise = SensorNoise::default().with_white_level(white_level);
    create_dir(&out.join("calibration"))?;
    let first = frames.start;
    let capture = Capture::new(&scene.performer, &scene.motion, spec)?;
    let mut written = 0;
    for (k, frame) in capture.frames_in(frames.clone()).enumerate() {
        let mut frame = frame?;
        let dir = frame_dir(out, k);
        create_dir(&dir)?;
        for (c, obs) in frame.observations.iter_mut().enumerate() {
            for (p, im) in obs.patterns.iter_mut().enumerate() {
                let seed = ((first + k) * 64 + 8 * c + p) as u64;
                noise.apply(im, seed)?;
            }
            let images = photometric_normals::truth::pattern_images(obs)?;
            write_f32(
                &dir.join(format!("cam{c}_patterns.npy")),
                &[PATTERNS.len(), size as usize, size as usize],
                patterns_f32(&images),
            )?;
            write_mask(&dir.join(format!("cam{c}_mask.npy")), &obs.mask)?;
        }
        written += 1;
    }
    if written < frames.len() {
        return Err(BatchError::Input(format!(
            "frames {frames:?}: the motion has {} frames",
            frames.start + written
        )));
    }
    let spheres: Vec<CalibrationSphere> = scene
        .stage
        .sphere_heights_m()
        .iter()
        .map(|&h| CalibrationSphere {
            centre: DVec3::new(scene.root.x, h, scene.root.z),
            radius_m: SPHERE_RADIUS_M,
        })
        .collect();
    for (c, cam) in scene.ring.cameras.iter().enumerate() {
        for (i, s) in spheres.iter().enumerate() {
            let images = render_sphere_patterns(
                cam,
                s,
                &scene.stage.lights,
                scene.stage.centre,
                SPHERE_ALBEDO,
            )?;
            write_f32(
                &out.join("calibration")
                    .join(format!("cam{c}_sphere{i}.npy")),
                &[PATTERNS.len(), size as usize, size as usize],
                patterns_f32(&images),
            )?;
        }
    }
    write_f64(
        &out.join("calibration").join("spheres.npy"),
        &[spheres.len(), 4],
        spheres
            .iter()
            .flat_map(|s| [s.centre.x, s.centre.y, s.centre.z, s.radius_m]),
    )?;
    write_f64(
        &out.join("performance_centre.npy"),
        &[3],
        scene.root.to_array(),
    )?;
    write_cameras(out, &scene.ring.cameras)?;
    let info = json!({
        "kind": "photometric",
        "frames": frames.len(),
        "first_motion_frame": frames.start,
        "width": size,
        "height": size,
        "cameras": scene.ring.cameras.len(),
        "white_level": white_level,
    });
    let path = out.join("capture.json");
    std::fs::write(&path, info.to_string()).map_err(io(&path))
}

/// The camera pairs the reconstruction matches: neighbours around the ring (one pair for two
/// cameras).
fn ring_pairs(n: usize) -> Vec<(usize, usize)> {
    match n {
        0 | 1 => vec![],
        2 => vec![(0, 1)],
        _ => (0..n).map(|c| (c, (c + 1) % n)).collect(),
    }
}

/// The two-pass photometric reconstruction (§3.3) of each of a capture's `frames`: per camera
/// the grey-sphere calibration (§3.2.3, once per call), the normal map of the frame's pattern
/// images inside its mask (performance centre and exposure from `capture.json`), then the
/// visual-hull proxies, integration, matching of neighbouring cameras, merging and hole
/// filling (Poisson depth `poisson_depth`). Writes `{out_prefix}NNNNNN.ply` (binary, the
/// second pass's watertight surface) per frame and returns the paths.
///
/// # Errors
/// [`BatchError::Input`] for an empty range or one past the capture's end;
/// [`BatchError::Io`] / [`BatchError::Format`] for missing or malformed files; the method's
/// errors.
pub fn photometric_frames(
    capture: &Path,
    frames: Range<usize>,
    out_prefix: &str,
    poisson_depth: u32,
) -> Result<Vec<PathBuf>> {
    let info = CaptureInfo::read(capture, "photometric")?;
    info.check(&frames)?;
    let white_level: f32 = info.field(capture, "white_level")?;
    let centre = read_f64(&capture.join("performance_centre.npy"), &[3])?;
    let sphere_path = capture.join("calibration").join("spheres.npy");
    let (_, shape, _) = npy::read(&sphere_path)?;
    let k = shape.first().copied().unwrap_or(0);
    let spheres: Vec<CalibrationSphere> = read_f64(&sphere_path, &[k, 4])?
        .chunks_exact(4)
        .map(|s| CalibrationSphere {
            centre: DVec3::new(s[0], s[1], s[2]),
            radius_m: s[3],
        })
        .collect();
    let exposure = Exposure::default().with_white_level(white_level);
    let cal_params = CalibrationParams {
        exposure,
        ..Default::default()
    };
    let params = NormalParams::default()
        .with_exposure(exposure)
        .with_performance_centre(DVec3::new(centre[0], centre[1], centre[2]));
    let cals = info
        .cameras
        .iter()
        .enumerate()
        .map(|(c, cam)| {
            let tables = spheres
                .iter()
                .enumerate()
                .map(|(i, s)| {
                    let path = capture
                        .join("calibration")
                        .join(format!("cam{c}_sphere{i}.npy"));
                    let images = info.patterns(&path)?;
                    Ok(LookupTable::from_sphere(
                        cam,
                        s,
                        &images,
                        DVec3::Y,
                        &cal_params,
                    )?)
                })
                .collect::<Result<Vec<_>>>()?;
            Ok(HeightCalibration::new(tables)?)
        })
        .collect::<Result<Vec<_>>>()?;
    let rparams = ReconstructParams::default().with_poisson_depth(poisson_depth);
    let pairs = ring_pairs(info.cameras.len());
    let mut written = vec![];
    for f in frames {
        let dir = frame_dir(capture, f);
        let masks = info.masks(capture, f)?;
        let maps = info
            .cameras
            .iter()
            .enumerate()
            .map(|(c, cam)| {
                let images = info.patterns(&dir.join(format!("cam{c}_patterns.npy")))?;
                Ok(estimate_normals(
                    cam,
                    &cals[c],
                    &images,
                    Some(&masks[c]),
                    &params,
                )?)
            })
            .collect::<Result<Vec<_>>>()?;
        let hull = PolygonalHull::new(&info.cameras, &masks)?;
        let mesh = reconstruct(&info.cameras, &maps, &hull, &pairs, &rparams)?
            .pass2
            .filled
            .mesh;
        let path = output(out_prefix, &format!("{f:06}.ply"))?;
        mesh::write_ply(&path, &mesh, mesh::PlyEncoding::BinaryLittleEndian)?;
        written.push(path);
    }
    Ok(written)
}

/// Writes a silhouette capture folder: MakeHuman (no garment) in the studio's exercise from
/// motion frame `first`, `frames` frames, seen by a ring of `cameras` cameras of `width` ×
/// `height` px (55° field of view, 3.5 m around the first frame's root, 0.15 m above it); the
/// masks, the mocap poses (the needle model's input) and the template a user would rig (the
/// scanned outer surface decimated to `template_vertices`).
///
/// # Errors
/// [`BatchError::Input`] for no frames or a range past the motion; the studio's errors;
/// [`BatchError::Io`] when the folder cannot be written.
#[allow(clippy::too_many_arguments)]
pub fn write_silhouette_capture(
    makehuman_dir: &Path,
    out: &Path,
    first: usize,
    frames: usize,
    cameras: usize,
    width: u32,
    height: u32,
    template_vertices: usize,
) -> Result<()> {
    if frames == 0 {
        return Err(BatchError::Input("frames: none".into()));
    }
    let performer = makehuman_performer(makehuman_dir, &Default::default())?;
    let motion = dynamic_shapes_studio::exercise_motion(
        &performer.skeleton,
        &dynamic_shapes_studio::ExerciseParams::default(),
    )?;
    if first + frames > motion.frame_count() {
        return Err(BatchError::Input(format!(
            "frames {first}..{}: the motion has {} frames",
            first + frames,
            motion.frame_count()
        )));
    }
    let root = performer
        .skeleton
        .forward_kinematics(motion.frame(first))?
        .joint_positions()[0];
    let k = Intrinsics::from_horizontal_fov(55f64.to_radians(), width, height)?;
    let rig = Rig::ring(cameras, 3.5, root.y + 0.15, root, DVec3::Y, k)?;
    let cams = rig.cameras.clone();
    let spec = dynamic_shapes_studio::CaptureSpec::masks_only(rig)
        .with_frame_rate_hz(1.0 / motion.frame_time_s);
    let capture = Capture::new(&performer, &motion, spec)?;
    let mut thetas = vec![];
    for (k, frame) in capture.frames_in(first..first + frames).enumerate() {
        let frame = frame?;
        let dir = frame_dir(out, k);
        create_dir(&dir)?;
        for (c, obs) in frame.observations.iter().enumerate() {
            write_mask(&dir.join(format!("cam{c}_mask.npy")), &obs.mask)?;
        }
        thetas.push(frame.truth.theta.clone());
    }
    let scan = scan_outer_surface(
        &performer,
        &ScanParams {
            vertices: (template_vertices > 0).then_some(template_vertices),
            ..ScanParams::default()
        },
    )?;
    mesh::write_obj(out.join("template.obj"), &scan.mesh)?;
    write_cameras(out, &cams)?;
    let info = json!({
        "kind": "silhouette",
        "frames": frames,
        "first_motion_frame": first,
        "width": width,
        "height": height,
        "cameras": cams.len(),
        "skeleton": performer.skeleton,
        "thetas": thetas,
    });
    let path = out.join("capture.json");
    std::fs::write(&path, info.to_string()).map_err(io(&path))
}

/// Tracks a chunk of a silhouette capture (§2.2): the template (`template.obj`, rigged by
/// bone-heat weights) through the visual hulls of `frames` from `first_pose` (the pose of
/// the chunk's first frame: the user's fit for the first chunk, the previous chunk's last
/// pose after it), forward and reverse passes, then molding with the default parameters.
/// Writes `{out_prefix}poses_A_B.npy` `(frames, dofs)` and `{out_prefix}vertices_A_B.npy`
/// `(frames, n, 3)` (A..B the range, six digits) and returns the chunk's last pose.
///
/// # Errors
/// [`BatchError::Input`] for an empty range, one past the capture's end or a pose of the
/// wrong length; [`BatchError::Io`] / [`BatchError::Format`] for missing or malformed files;
/// the method's errors.
pub fn track_chunk(
    capture: &Path,
    frames: Range<usize>,
    first_pose: &[f64],
    out_prefix: &str,
) -> Result<Vec<f64>> {
    let info = CaptureInfo::read(capture, "silhouette")?;
    info.check(&frames)?;
    let skeleton: Skeleton = info.field(capture, "skeleton")?;
    if first_pose.len() != skeleton.dof_count() {
        return Err(BatchError::Input(format!(
            "first_pose: {} values, the skeleton has {} degrees of freedom",
            first_pose.len(),
            skeleton.dof_count()
        )));
    }
    let mesh: TriMesh = mesh::read_obj(capture.join("template.obj"))?;
    let weights = bone_heat_weights(
        &mesh,
        &rest_bones(&skeleton)?,
        &HeatWeightsParams::default(),
    )?;
    let template = Template::new(mesh, skeleton, weights)?;
    let obs = frames
        .clone()
        .map(|f| {
            Ok(FrameObservation::new(
                &info.cameras,
                &info.masks(capture, f)?,
                &ContourRayHullParams::default(),
                &SilhouetteParams::default(),
            )?)
        })
        .collect::<Result<Vec<_>>>()?;
    let seq = capture_sequence(
        &template,
        &obs,
        first_pose,
        &[],
        &PoseParams::default(),
        &ShapeParams::default(),
    )?;
    let dofs = template.skeleton().dof_count();
    let tag = format!("{:06}_{:06}", frames.start, frames.end);
    write_f64(
        &output(out_prefix, &format!("poses_{tag}.npy"))?,
        &[seq.poses.poses.len(), dofs],
        seq.poses.poses.concat(),
    )?;
    write_f64(
        &output(out_prefix, &format!("vertices_{tag}.npy"))?,
        &[seq.shapes.frames.len(), template.vertex_count(), 3],
        seq.shapes
            .frames
            .iter()
            .flat_map(|f| f.iter().flat_map(|p| p.to_array())),
    )?;
    seq.poses
        .poses
        .last()
        .cloned()
        .ok_or_else(|| BatchError::Input("no frames tracked".into()))
}

/// The needle observations (Sand 2003 §4) of a chunk of a silhouette capture: every needle
/// of Table 3.1's body walked through every camera's mask of `frames` at the capture's mocap
/// poses. Writes the store as `{out_prefix}store_A_B.json` and returns its path; stores of
/// consecutive chunks merge with [`needle_merge`].
///
/// # Errors
/// As [`track_chunk`] (ranges, files); the method's errors.
pub fn needle_accumulate(
    capture: &Path,
    frames: Range<usize>,
    out_prefix: &str,
) -> Result<PathBuf> {
    let info = CaptureInfo::read(capture, "silhouette")?;
    info.check(&frames)?;
    let skeleton: Skeleton = info.field(capture, "skeleton")?;
    let thetas: Vec<Vec<f64>> = info.field(capture, "thetas")?;
    let body = NeedleBody::new(&skeleton, &BodyLayout::table_3_1())?;
    let observer = Observer::new(
        body,
        skeleton,
        info.cameras.clone(),
        ObserveParams::default(),
    )?;
    let mut store = observer.empty_store()?;
    for f in frames.clone() {
        let theta = thetas
            .get(f)
            .ok_or_else(|| format_error(&capture.join("capture.json"), "thetas: too few"))?;
        observer.observe_frame(theta, &info.masks(capture, f)?, &mut store)?;
    }
    let path = output(
        out_prefix,
        &format!("store_{:06}_{:06}.json", frames.start, frames.end),
    )?;
    let text = serde_json::to_string(&store).map_err(|e| format_error(&path, e.to_string()))?;
    std::fs::write(&path, text).map_err(io(&path))?;
    Ok(path)
}

/// Merges needle stores (of consecutive chunks, in frame order) into `out` and returns the
/// number of observations.
///
/// # Errors
/// [`BatchError::Input`] for no stores; [`BatchError::Io`] / [`BatchError::Format`] for
/// missing or malformed files; [`needle_model::Error`] for stores of different bodies.
pub fn needle_merge(stores: &[PathBuf], out: &Path) -> Result<usize> {
    let read = |p: &PathBuf| -> Result<ObservationStore> {
        let text = std::fs::read_to_string(p).map_err(io(p))?;
        serde_json::from_str(&text).map_err(|e| format_error(p, e.to_string()))
    };
    let (first, rest) = stores
        .split_first()
        .ok_or_else(|| BatchError::Input("needle_merge: no stores".into()))?;
    let mut merged = read(first)?;
    for p in rest {
        merged.append(&read(p)?)?;
    }
    let text = serde_json::to_string(&merged).map_err(|e| format_error(out, e.to_string()))?;
    std::fs::write(out, text).map_err(io(out))?;
    Ok(merged.total_observations())
}

/// The inertial-acoustic pipeline (§4.4) of a recording folder (`Recording::read`) for the
/// skeleton in `skeleton_json` (the crates' serde form): the whole recording is filtered
/// (initialisation and noise tuning use all of it, and the EKF is sequential: recordings,
/// not frames, are what runs in parallel); the joint angles of `frames` are written as
/// `{out_prefix}theta_A_B.npy` `(frames, dofs)`, whose path is returned.
///
/// # Errors
/// [`BatchError::Input`] for an empty range or one past the recording's end;
/// [`BatchError::Io`] / [`BatchError::Format`] for missing or malformed files; the method's
/// errors.
pub fn inertial_recording(
    recording: &Path,
    skeleton_json: &Path,
    frames: Range<usize>,
    out_prefix: &str,
) -> Result<PathBuf> {
    let text = std::fs::read_to_string(skeleton_json).map_err(io(skeleton_json))?;
    let skeleton: Skeleton =
        serde_json::from_str(&text).map_err(|e| format_error(skeleton_json, e.to_string()))?;
    if frames.is_empty() {
        return Err(BatchError::Input(format!(
            "frames {frames:?}: an empty range"
        )));
    }
    let rec = inertial_acoustic::Recording::read(recording, &skeleton)?;
    let out = inertial_acoustic::pipeline::run(&skeleton, &rec, &Default::default())?;
    if frames.end > out.theta.len() {
        return Err(BatchError::Input(format!(
            "frames {frames:?}: the recording has {} frames",
            out.theta.len()
        )));
    }
    let path = output(
        out_prefix,
        &format!("theta_{:06}_{:06}.npy", frames.start, frames.end),
    )?;
    write_f64(
        &path,
        &[frames.len(), skeleton.dof_count()],
        out.theta[frames].concat(),
    )?;
    Ok(path)
}
