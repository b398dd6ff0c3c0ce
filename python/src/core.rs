//! skin-core: meshes, cameras, skeletons, skinning, the cotangent Laplacian.

use std::path::PathBuf;

use glam::{DAffine3, DVec2, DVec3};
use numpy::{PyArray1, PyArray2, PyArray3};
use pyo3::prelude::*;
use pyo3::types::PyTuple;
use skin_core::camera::{
    Camera as RustCamera, Intrinsics, OpenCvCalibration, OpenCvParams, RadialDistortion,
};
use skin_core::mesh::{self, LaplacianParams, PlyEncoding, SkinWeights, TriMesh};
use skin_core::skeleton::{self as sk, BvhParams, Motion, Skeleton as RustSkeleton};

use crate::arrays::{
    self, affine, affine_rows, faces, finite, from_points2, from_points3, owned1, owned2, owned3,
    points2, points3, vector,
};
use crate::errors::{invalid, raise, to_py, Classify};

/// A mesh from `(n, 3)` vertices (m) and `(m, 3)` `uint32` faces.
pub(crate) fn trimesh(vertices: &Bound<'_, PyAny>, tris: &Bound<'_, PyAny>) -> PyResult<TriMesh> {
    let v = points3(vertices, "vertices")?;
    let f = faces(tris, "faces", v.len())?;
    TriMesh::new(v, f).map_err(to_py)
}

/// `(vertices, faces)` of a mesh as NumPy arrays.
pub(crate) fn mesh_arrays<'py>(py: Python<'py>, m: &TriMesh) -> PyResult<Bound<'py, PyTuple>> {
    let f = arrays::from_rows(py, m.faces.iter().copied(), m.faces.len());
    PyTuple::new(py, [from_points3(py, &m.vertices).into_any(), f.into_any()])
}

/// Reads a triangle mesh from an OBJ file (polygons fan-triangulated).
///
/// Returns `(vertices, faces)`: `(n, 3)` float64 in the file's units and `(m, 3)` uint32.
/// Raises `FileError` for a file that cannot be read, `FormatError` for malformed contents.
#[pyfunction]
fn read_obj<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Bound<'py, PyTuple>> {
    let m = py.detach(|| mesh::read_obj(&path)).map_err(to_py)?;
    mesh_arrays(py, &m)
}

/// Reads a triangle mesh from a PLY file (ASCII or binary). Returns `(vertices, faces)`.
#[pyfunction]
fn read_ply<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Bound<'py, PyTuple>> {
    let m = py.detach(|| mesh::read_ply(&path)).map_err(to_py)?;
    mesh_arrays(py, &m)
}

/// Writes `(n, 3)` float64 vertices and `(m, 3)` uint32 faces to an OBJ file.
#[pyfunction]
fn write_obj(
    py: Python<'_>,
    path: PathBuf,
    vertices: &Bound<'_, PyAny>,
    faces: &Bound<'_, PyAny>,
) -> PyResult<()> {
    let m = trimesh(vertices, faces)?;
    py.detach(|| mesh::write_obj(&path, &m)).map_err(to_py)
}

/// Writes a mesh to a PLY file, binary little-endian by default (`binary=False`: ASCII).
#[pyfunction]
#[pyo3(signature = (path, vertices, faces, binary = true))]
fn write_ply(
    py: Python<'_>,
    path: PathBuf,
    vertices: &Bound<'_, PyAny>,
    faces: &Bound<'_, PyAny>,
    binary: bool,
) -> PyResult<()> {
    let m = trimesh(vertices, faces)?;
    let enc = if binary {
        PlyEncoding::BinaryLittleEndian
    } else {
        PlyEncoding::Ascii
    };
    py.detach(|| mesh::write_ply(&path, &m, enc)).map_err(to_py)
}

/// The cotangent Laplacian `L` (n × n, symmetric, negative semi-definite: `L[i, i] = −Σ_j
/// L[i, j]`, `L[i, j] = (cot α + cot β) / 2`) as a `scipy.sparse.csc_matrix`. Degenerate
/// triangles are skipped.
#[pyfunction]
fn cotangent_laplacian<'py>(
    py: Python<'py>,
    vertices: &Bound<'py, PyAny>,
    faces: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyAny>> {
    let m = trimesh(vertices, faces)?;
    let l = py
        .detach(|| mesh::cotangent_laplacian(&m, &LaplacianParams::default()))
        .map_err(to_py)?;
    let n = l.nrows();
    let (offsets, rows, values) = l.disassemble();
    let to_i64 = |v: Vec<usize>| -> PyResult<Vec<i64>> {
        v.into_iter()
            .map(|x| i64::try_from(x).map_err(|_| invalid("sparse index too large")))
            .collect()
    };
    let data = owned1(py, values);
    let indices = owned1(py, to_i64(rows)?);
    let indptr = owned1(py, to_i64(offsets)?);
    let csc = py.import("scipy.sparse")?.getattr("csc_matrix")?;
    csc.call1(((data, indices, indptr), (n, n)))
}

fn opencv_params() -> OpenCvParams {
    OpenCvParams::default()
}

/// A pinhole camera with first-order radial distortion about its own centre (Sand 2003
/// §4.1). Camera frame: x right, y down, z forward; pixels `(u, v)` with `v` downwards.
#[pyclass(module = "dynamic_shapes", frozen, from_py_object)]
#[derive(Clone)]
pub(crate) struct Camera {
    pub(crate) inner: RustCamera,
}

#[pymethods]
impl Camera {
    /// A camera from intrinsics (px) and its 4 × 4 `world_from_camera` pose (m); `k1` the
    /// radial distortion coefficient about `distortion_centre` (px; default the principal
    /// point).
    #[new]
    #[pyo3(signature = (fx, fy, cx, cy, width, height, world_from_camera, k1 = 0.0, distortion_centre = None))]
    #[allow(
        clippy::too_many_arguments,
        reason = "the camera's own parameters, named in Python"
    )]
    fn new(
        fx: f64,
        fy: f64,
        cx: f64,
        cy: f64,
        width: u32,
        height: u32,
        world_from_camera: &Bound<'_, PyAny>,
        k1: f64,
        distortion_centre: Option<(f64, f64)>,
    ) -> PyResult<Self> {
        let k = Intrinsics::new(fx, fy, cx, cy, width, height).map_err(to_py)?;
        let centre = distortion_centre.map_or(DVec2::new(cx, cy), |(x, y)| DVec2::new(x, y));
        let pose = affine(world_from_camera, "world_from_camera")?;
        let inner = RustCamera::new(k, RadialDistortion::new(k1, centre), pose).map_err(to_py)?;
        Ok(Camera { inner })
    }

    /// An undistorted camera at `eye` (m) looking at `target`, `up` pointing up in the image,
    /// with a horizontal field of view `horizontal_fov_rad` over `width` × `height` px.
    #[staticmethod]
    #[pyo3(signature = (eye, target, width, height, horizontal_fov_rad, up = (0.0, 1.0, 0.0)))]
    fn look_at(
        eye: (f64, f64, f64),
        target: (f64, f64, f64),
        width: u32,
        height: u32,
        horizontal_fov_rad: f64,
        up: (f64, f64, f64),
    ) -> PyResult<Self> {
        let k =
            Intrinsics::from_horizontal_fov(horizontal_fov_rad, width, height).map_err(to_py)?;
        let v = |t: (f64, f64, f64)| DVec3::new(t.0, t.1, t.2);
        let inner = RustCamera::look_at(k, v(eye), v(target), v(up)).map_err(to_py)?;
        Ok(Camera { inner })
    }

    /// Reads a camera from an OpenCV calibration file (YAML `FileStorage` with
    /// `camera_matrix`, `distortion_coefficients`, `rotation`/`rvec`, `translation`). OpenCV's
    /// distortion is fitted by this camera's one-coefficient model over the image.
    #[staticmethod]
    fn read_opencv(py: Python<'_>, path: PathBuf) -> PyResult<Self> {
        let cam = py.detach(|| -> skin_core::Result<RustCamera> {
            let text =
                std::fs::read_to_string(&path).map_err(|e| skin_core::Error::io(&path, e))?;
            Ok(OpenCvCalibration::from_yaml_str(&text)?
                .to_camera(&opencv_params())?
                .camera)
        });
        Ok(Camera {
            inner: cam.map_err(to_py)?,
        })
    }

    /// Writes the camera as an OpenCV calibration file (YAML).
    fn write_opencv(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        py.detach(|| -> skin_core::Result<()> {
            let export = OpenCvCalibration::from_camera(&self.inner, &opencv_params())?;
            std::fs::write(&path, export.calibration.to_yaml_string())
                .map_err(|e| skin_core::Error::io(&path, e))
        })
        .map_err(to_py)
    }

    /// Image width, px.
    #[getter]
    fn width(&self) -> u32 {
        self.inner.intrinsics.width
    }

    /// Image height, px.
    #[getter]
    fn height(&self) -> u32 {
        self.inner.intrinsics.height
    }

    /// The 3 × 3 intrinsic matrix `K`, px.
    #[getter]
    fn intrinsic_matrix<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let m = self.inner.intrinsics.matrix().transpose().to_cols_array();
        owned2(py, m.to_vec(), 3, 3)
    }

    /// The 4 × 4 pose `world_from_camera` (m).
    #[getter]
    fn world_from_camera<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        owned2(
            py,
            affine_rows(&self.inner.world_from_camera()).concat(),
            4,
            4,
        )
    }

    /// Radial distortion coefficient `k1`.
    #[getter]
    fn k1(&self) -> f64 {
        self.inner.distortion.k1
    }

    /// Projects `(n, 3)` world points (m) to `(n, 2)` distorted pixels. Raises
    /// `InvalidInputError` for a point behind the camera (the message names it).
    fn project<'py>(
        &self,
        py: Python<'py>,
        points: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let p = points3(points, "points")?;
        let px = py
            .detach(|| project_all(&self.inner, &p))
            .map_err(|(i, e)| raise(e.kind(), format!("point {i}: {e}")))?;
        Ok(from_points2(py, &px))
    }

    /// World rays through `(n, 2)` pixels: `(origins, directions)`, each `(n, 3)`; origins at
    /// the camera centre (m), unit directions.
    fn rays<'py>(
        &self,
        py: Python<'py>,
        pixels: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyTuple>> {
        let px = points2(pixels, "pixels")?;
        let rays = py
            .detach(|| {
                px.iter()
                    .enumerate()
                    .map(|(i, &p)| self.inner.ray(p).map_err(|e| (i, e)))
                    .collect::<Result<Vec<_>, _>>()
            })
            .map_err(|(i, e)| raise(e.kind(), format!("pixel {i}: {e}")))?;
        let o: Vec<DVec3> = rays.iter().map(|r| r.origin).collect();
        let d: Vec<DVec3> = rays.iter().map(|r| r.direction).collect();
        PyTuple::new(py, [from_points3(py, &o), from_points3(py, &d)])
    }

    /// The camera as JSON (the Rust crate's serde form).
    fn to_json(&self) -> PyResult<String> {
        serde_json::to_string(&self.inner).map_err(|e| invalid(e.to_string()))
    }

    /// A camera from `Camera.to_json`'s text.
    #[staticmethod]
    fn from_json(text: &str) -> PyResult<Self> {
        let inner = serde_json::from_str(text).map_err(|e| invalid(format!("camera JSON: {e}")))?;
        Ok(Camera { inner })
    }

    fn __repr__(&self) -> String {
        let c = self.inner.centre();
        format!(
            "Camera({} × {} px, centre ({:.3}, {:.3}, {:.3}) m)",
            self.inner.intrinsics.width, self.inner.intrinsics.height, c.x, c.y, c.z
        )
    }
}

/// Projects every point; the first failure with its index.
pub(crate) fn project_all(
    cam: &RustCamera,
    p: &[DVec3],
) -> Result<Vec<DVec2>, (usize, skin_core::Error)> {
    p.iter()
        .enumerate()
        .map(|(i, &x)| cam.project(x).map_err(|e| (i, e)))
        .collect()
}

/// Cameras and their silhouettes `(..., cameras, h, w)` uint8 with `leading` axes before
/// `h, w`, the last of them the cameras': the leading sizes, the cameras and the masks in
/// row-major order, after checking the camera axis against the cameras given.
pub(crate) fn views(
    cameras: Vec<Camera>,
    masks: &Bound<'_, PyAny>,
    leading: usize,
) -> PyResult<(Vec<usize>, Vec<RustCamera>, Vec<skin_core::image::Mask>)> {
    let (lead, masks) = arrays::masks(masks, "masks", leading)?;
    let cams: Vec<RustCamera> = cameras.into_iter().map(|c| c.inner).collect();
    if lead[leading - 1] != cams.len() {
        return Err(invalid(format!(
            "masks has {} cameras but {} cameras were given",
            lead[leading - 1],
            cams.len()
        )));
    }
    Ok((lead, cams, masks))
}

/// A joint tree with per-joint degrees of freedom (rotations in rad, translations in m).
#[pyclass(module = "dynamic_shapes", frozen, from_py_object)]
#[derive(Clone)]
pub(crate) struct Skeleton {
    pub(crate) inner: RustSkeleton,
}

#[pymethods]
impl Skeleton {
    /// The library's human skeleton (root translation and rotation, spine, neck, head, arms,
    /// legs) standing `height_m` tall at θ = 0.
    #[staticmethod]
    #[pyo3(signature = (height_m = 1.75))]
    fn human(height_m: f64) -> PyResult<Self> {
        let params = sk::HumanParams { height_m };
        Ok(Skeleton {
            inner: sk::human_skeleton(&params).map_err(to_py)?,
        })
    }

    /// Number of joints.
    #[getter]
    fn joint_count(&self) -> usize {
        self.inner.joint_count()
    }

    /// Number of degrees of freedom (the length of a pose θ).
    #[getter]
    fn dof_count(&self) -> usize {
        self.inner.dof_count()
    }

    /// Joint names, in joint order.
    #[getter]
    fn joint_names(&self) -> Vec<String> {
        self.inner.joints().iter().map(|j| j.name.clone()).collect()
    }

    /// Parent of each joint (`-1` for the root).
    #[getter]
    fn parents(&self) -> Vec<i64> {
        self.inner
            .joints()
            .iter()
            .map(|j| j.parent.map_or(-1, |p| p as i64))
            .collect()
    }

    /// Degree-of-freedom names, in θ order.
    #[getter]
    fn dof_names(&self) -> Vec<String> {
        self.inner.dofs().map(|d| d.name.clone()).collect()
    }

    /// The rest pose θ (zeros), `(dof_count,)`.
    fn rest_pose<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        owned1(py, self.inner.rest_pose())
    }

    /// Forward kinematics: the `(joint_count, 4, 4)` world-from-joint transforms for pose
    /// `theta` `(dof_count,)`.
    fn forward_kinematics<'py>(
        &self,
        py: Python<'py>,
        theta: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray3<f64>>> {
        let t = vector(theta, "theta", Some(self.inner.dof_count()))?;
        let fk = py
            .detach(|| self.inner.forward_kinematics(&t))
            .map_err(to_py)?;
        let flat: Vec<f64> = fk
            .world_from_joint()
            .iter()
            .flat_map(|a| affine_rows(a).concat())
            .collect();
        Ok(owned3(py, flat, (self.inner.joint_count(), 4, 4)))
    }

    /// Joint positions `(joint_count, 3)` (m) for pose `theta`.
    fn joint_positions<'py>(
        &self,
        py: Python<'py>,
        theta: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let t = vector(theta, "theta", Some(self.inner.dof_count()))?;
        let fk = py
            .detach(|| self.inner.forward_kinematics(&t))
            .map_err(to_py)?;
        Ok(from_points3(py, &fk.joint_positions()))
    }

    /// The skeleton as JSON (the Rust crate's serde form).
    fn to_json(&self) -> PyResult<String> {
        serde_json::to_string(&self.inner).map_err(|e| invalid(e.to_string()))
    }

    /// A skeleton from `Skeleton.to_json`'s text.
    #[staticmethod]
    fn from_json(text: &str) -> PyResult<Self> {
        let inner =
            serde_json::from_str(text).map_err(|e| invalid(format!("skeleton JSON: {e}")))?;
        Ok(Skeleton { inner })
    }

    fn __repr__(&self) -> String {
        format!(
            "Skeleton({} joints, {} DOFs)",
            self.inner.joint_count(),
            self.inner.dof_count()
        )
    }
}

/// Reads a BVH file: `(skeleton, motion, frame_time_s)` with `motion` `(frames, dof_count)`
/// (rad, and m after scaling the file's units by `metres_per_unit`).
#[pyfunction]
#[pyo3(signature = (path, metres_per_unit = 1.0))]
fn read_bvh<'py>(
    py: Python<'py>,
    path: PathBuf,
    metres_per_unit: f64,
) -> PyResult<Bound<'py, PyTuple>> {
    let bvh = py
        .detach(|| sk::read_bvh(&path, &BvhParams { metres_per_unit }))
        .map_err(to_py)?;
    let motion = motion_array(py, &bvh.motion);
    let skel = Bound::new(
        py,
        Skeleton {
            inner: bvh.skeleton,
        },
    )?;
    PyTuple::new(
        py,
        [
            skel.into_any(),
            motion.into_any(),
            bvh.motion.frame_time_s.into_pyobject(py)?.into_any(),
        ],
    )
}

fn motion_array<'py>(py: Python<'py>, m: &Motion) -> Bound<'py, PyArray2<f64>> {
    let (dofs, frames) = m.frames.shape();
    // Column k is frame k; nalgebra stores columns contiguously: row-major (frames, dofs).
    owned2(py, m.frames.as_slice().to_vec(), frames, dofs)
}

/// Writes a skeleton and a `(frames, dof_count)` motion to a BVH file.
#[pyfunction]
#[pyo3(signature = (path, skeleton, motion, frame_time_s, metres_per_unit = 1.0))]
fn write_bvh(
    py: Python<'_>,
    path: PathBuf,
    skeleton: &Skeleton,
    motion: &Bound<'_, PyAny>,
    frame_time_s: f64,
    metres_per_unit: f64,
) -> PyResult<()> {
    let v = finite(motion, "motion", &[None, Some(skeleton.inner.dof_count())])?;
    let a = v.as_array();
    let (frames, dofs) = (a.shape()[0], a.shape()[1]);
    let m = nalgebra::DMatrix::from_fn(dofs, frames, |d, f| a[[f, d]]);
    let motion = Motion::new(frame_time_s, m).map_err(to_py)?;
    py.detach(|| {
        sk::write_bvh(
            &path,
            &skeleton.inner,
            &motion,
            &BvhParams { metres_per_unit },
        )
    })
    .map_err(to_py)
}

/// Dense weights `(n, joint_count)` as sparse skinning weights (rows renormalised).
pub(crate) fn skin_weights(
    weights: &Bound<'_, PyAny>,
    n: usize,
    bones: usize,
) -> PyResult<SkinWeights> {
    let w = arrays::dmatrix(weights, "weights", &[Some(n), Some(bones)])?;
    SkinWeights::from_dense(&w, 0.0, bones.max(1)).map_err(to_py)
}

/// Linear blend skinning: the mesh `(vertices, faces)` bound at the skeleton's rest pose with
/// `weights` `(n, joint_count)` (each row renormalised to sum to one), posed by `theta`.
/// Returns the `(n, 3)` skinned vertices (m).
#[pyfunction]
fn linear_blend_skinning<'py>(
    py: Python<'py>,
    vertices: &Bound<'py, PyAny>,
    faces: &Bound<'py, PyAny>,
    skeleton: &Skeleton,
    weights: &Bound<'py, PyAny>,
    theta: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let m = trimesh(vertices, faces)?;
    let s = &skeleton.inner;
    let w = skin_weights(weights, m.vertex_count(), s.joint_count())?;
    let t = vector(theta, "theta", Some(s.dof_count()))?;
    let out = py
        .detach(|| -> skin_core::Result<Vec<DVec3>> {
            let binding = mesh::SkinBinding::new(&m, s, &w)?;
            let fk = s.forward_kinematics(&t)?;
            let world_from_rest: Vec<DAffine3> = binding.world_from_rest(fk.world_from_joint());
            mesh::skin(&m.vertices, &w, &world_from_rest)
        })
        .map_err(to_py)?;
    Ok(from_points3(py, &out))
}

/// Automatic skinning weights by bone heat (Baran & Popović 2007, Pinocchio), with its
/// visibility test unless `visibility=False`: `(n, joint_count)`, rows summing to one, at most
/// four influences per vertex. The mesh is at the skeleton's rest pose.
#[pyfunction]
#[pyo3(signature = (vertices, faces, skeleton, visibility = true))]
fn bone_heat_weights<'py>(
    py: Python<'py>,
    vertices: &Bound<'py, PyAny>,
    faces: &Bound<'py, PyAny>,
    skeleton: &Skeleton,
    visibility: bool,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let m = trimesh(vertices, faces)?;
    let mut params = mesh::HeatWeightsParams::default();
    if !visibility {
        params = params.without_visibility();
    }
    let w = py
        .detach(|| -> skin_core::Result<nalgebra::DMatrix<f64>> {
            let bones = mesh::rest_bones(&skeleton.inner)?;
            Ok(mesh::bone_heat_weights(&m, &bones, &params)?.to_dense())
        })
        .map_err(to_py)?;
    Ok(arrays::from_dmatrix(py, &w))
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("CMU_METRES_PER_UNIT", sk::CMU_METRES_PER_UNIT)?;
    m.add_class::<Camera>()?;
    m.add_class::<Skeleton>()?;
    m.add_function(wrap_pyfunction!(read_obj, m)?)?;
    m.add_function(wrap_pyfunction!(read_ply, m)?)?;
    m.add_function(wrap_pyfunction!(write_obj, m)?)?;
    m.add_function(wrap_pyfunction!(write_ply, m)?)?;
    m.add_function(wrap_pyfunction!(cotangent_laplacian, m)?)?;
    m.add_function(wrap_pyfunction!(read_bvh, m)?)?;
    m.add_function(wrap_pyfunction!(write_bvh, m)?)?;
    m.add_function(wrap_pyfunction!(linear_blend_skinning, m)?)?;
    m.add_function(wrap_pyfunction!(bone_heat_weights, m)?)?;
    Ok(())
}
