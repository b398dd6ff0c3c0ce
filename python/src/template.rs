//! template-silhouette (Vlasic 2010 Ch. 2): tracking a template through multi-view
//! silhouettes; deformation transfer of an edit.

use numpy::{PyArray2, PyArray3};
use pyo3::prelude::*;
use pyo3::types::PyTuple;
use template_silhouette::{
    capture_sequence, ContourRayHullParams, DeformationTransfer as RustTransfer, FrameObservation,
    PoseParams, ResultExt, ShapeParams, ShapeStart, SilhouetteParams, Template as RustTemplate,
};

use skin_core::mesh::{bone_heat_weights, rest_bones, HeatWeightsParams};

use crate::arrays::{from_points3, owned3, points3, vector};
use crate::core::{skin_weights, trimesh, Camera, Skeleton};
use crate::errors::to_py;

/// A template: a mesh (at the skeleton's rest pose) bound to a skeleton by skinning weights.
#[pyclass(module = "dynamic_shapes.template", frozen)]
pub(crate) struct Template {
    inner: RustTemplate,
}

#[pymethods]
impl Template {
    /// A template from `(n, 3)` vertices (m), `(m, 3)` uint32 faces, a skeleton and
    /// `(n, joint_count)` skinning weights (rows renormalised).
    #[new]
    fn new(
        vertices: &Bound<'_, PyAny>,
        faces: &Bound<'_, PyAny>,
        skeleton: &Skeleton,
        weights: &Bound<'_, PyAny>,
    ) -> PyResult<Self> {
        let mesh = trimesh(vertices, faces)?;
        let w = skin_weights(weights, mesh.vertex_count(), skeleton.inner.joint_count())?;
        let inner = RustTemplate::new(mesh, skeleton.inner.clone(), w).map_err(to_py)?;
        Ok(Template { inner })
    }

    /// A template rigged by the library's bone-heat weights (Pinocchio, with its visibility
    /// test unless `visibility` is false), computed and kept in Rust: the weights are not
    /// renormalised through a dense matrix as `Template(v, f, skeleton, weights)` does.
    #[staticmethod]
    #[pyo3(signature = (vertices, faces, skeleton, visibility = true))]
    fn rigged(
        py: Python<'_>,
        vertices: &Bound<'_, PyAny>,
        faces: &Bound<'_, PyAny>,
        skeleton: &Skeleton,
        visibility: bool,
    ) -> PyResult<Self> {
        let mesh = trimesh(vertices, faces)?;
        let params = if visibility {
            HeatWeightsParams::default()
        } else {
            HeatWeightsParams::default().without_visibility()
        };
        let inner = py
            .detach(|| -> template_silhouette::Result<RustTemplate> {
                let w = bone_heat_weights(&mesh, &rest_bones(&skeleton.inner)?, &params)?;
                RustTemplate::new(mesh, skeleton.inner.clone(), w)
            })
            .map_err(to_py)?;
        Ok(Template { inner })
    }

    /// Number of vertices.
    #[getter]
    fn vertex_count(&self) -> usize {
        self.inner.vertex_count()
    }

    /// The template skinned to pose `theta`: `(n, 3)` (m).
    fn skin<'py>(
        &self,
        py: Python<'py>,
        theta: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let t = vector(theta, "theta", Some(self.inner.skeleton().dof_count()))?;
        let v = py.detach(|| self.inner.skin(&t)).map_err(to_py)?;
        Ok(from_points3(py, &v))
    }
}

/// Captures a sequence (§2.2): per frame, the visual hull and contour rays of the silhouettes
/// `masks` `(frames, cameras, h, w)` uint8; pose tracking through the hulls from
/// `first_pose` (the first frame's fit, §2.3.3), forward and reverse passes; then Laplacian
/// molding to the silhouettes (Algorithm 1). Returns `(poses, vertices)`: `(frames,
/// dof_count)` and `(frames, n, 3)` (m). The keywords are `ShapeParams`' and `PoseParams`'
/// fields with their defaults: `shape_start` (`"skinning"`: each frame from Eq. 2.1, the
/// thesis; `"previous"`: from the previous frame's molded surface carried by the pose
/// change), `w_anchor`, `w_c`, `w_l_step`, `filter_sigma_m`, `filter_passes` (§2.4.2);
/// `w_d`, `w_t`, `w_r`, `w_u`, `samples_per_bone`, `refinement_rounds` (§2.3.1).
#[pyfunction]
#[pyo3(signature = (template, cameras, masks, first_pose, *, shape_start = "skinning",
    w_anchor = 0.0, w_c = 1000.0, w_l_step = 0.2, filter_sigma_m = 0.07, filter_passes = 2,
    w_d = 5.0, w_t = 1.0, w_r = 500.0, w_u = 5000.0, samples_per_bone = 4,
    refinement_rounds = 2))]
#[allow(clippy::too_many_arguments)]
fn track<'py>(
    py: Python<'py>,
    template: &Template,
    cameras: Vec<Camera>,
    masks: &Bound<'py, PyAny>,
    first_pose: &Bound<'py, PyAny>,
    shape_start: &str,
    w_anchor: f64,
    w_c: f64,
    w_l_step: f64,
    filter_sigma_m: f64,
    filter_passes: usize,
    w_d: f64,
    w_t: f64,
    w_r: f64,
    w_u: f64,
    samples_per_bone: usize,
    refinement_rounds: usize,
) -> PyResult<Bound<'py, PyTuple>> {
    let start = match shape_start {
        "skinning" => ShapeStart::Skinning,
        "previous" => ShapeStart::PreviousFrame,
        other => {
            return Err(crate::errors::invalid(format!(
                "shape_start {other:?}: give \"skinning\" or \"previous\""
            )))
        }
    };
    let shape = ShapeParams {
        start,
        w_anchor,
        w_c,
        w_l_step,
        filter_sigma_m,
        filter_passes,
        ..ShapeParams::default()
    };
    let pose = PoseParams {
        w_d,
        w_t,
        w_r,
        w_u,
        samples_per_bone,
        refinement_rounds,
        ..PoseParams::default()
    };
    let dofs = template.inner.skeleton().dof_count();
    let first = vector(first_pose, "first_pose", Some(dofs))?;
    let (lead, cams, masks) = crate::core::views(cameras, masks, 2)?;
    let per = lead[1];
    let out = py
        .detach(|| -> template_silhouette::Result<_> {
            let obs = (0..lead[0])
                .map(|f| {
                    FrameObservation::new(
                        &cams,
                        &masks[f * per..(f + 1) * per],
                        &ContourRayHullParams::default(),
                        &SilhouetteParams::default(),
                    )
                    .at(template_silhouette::Context::Frame(f))
                })
                .collect::<template_silhouette::Result<Vec<_>>>()?;
            capture_sequence(&template.inner, &obs, &first, &[], &pose, &shape)
        })
        .map_err(to_py)?;
    let n = template.inner.vertex_count();
    let frames = out.poses.poses.len();
    let poses = crate::arrays::from_vec_rows(py, &out.poses.poses, dofs)?;
    let verts: Vec<f64> = out
        .shapes
        .frames
        .iter()
        .flat_map(|f| f.iter().flat_map(|p| p.to_array()))
        .collect();
    let verts: Bound<'py, PyArray3<f64>> = owned3(py, verts, (out.shapes.frames.len(), n, 3));
    debug_assert_eq!(frames, out.shapes.frames.len());
    PyTuple::new(py, [poses.into_any(), verts.into_any()])
}

/// Deformation transfer (§2.5.3, Sumner & Popović 2004): the edit `template → edited` (same
/// faces) carried onto other poses of the template.
#[pyclass(module = "dynamic_shapes.template", frozen)]
pub(crate) struct DeformationTransfer {
    inner: RustTransfer,
}

#[pymethods]
impl DeformationTransfer {
    /// Prepares the transfer of the edit from `(n, 3)` template vertices with `(m, 3)` uint32
    /// faces to `edited` `(n, 3)`.
    #[new]
    fn new(
        py: Python<'_>,
        vertices: &Bound<'_, PyAny>,
        faces: &Bound<'_, PyAny>,
        edited: &Bound<'_, PyAny>,
    ) -> PyResult<Self> {
        let mesh = trimesh(vertices, faces)?;
        let e = points3(edited, "edited")?;
        let inner = py.detach(|| RustTransfer::new(&mesh, &e)).map_err(to_py)?;
        Ok(DeformationTransfer { inner })
    }

    /// The edit applied to `frame` `(n, 3)` (the template in another pose): `(n, 3)` (m).
    fn transfer<'py>(
        &self,
        py: Python<'py>,
        frame: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let f = points3(frame, "frame")?;
        let out = py.detach(|| self.inner.transfer(&f)).map_err(to_py)?;
        Ok(from_points3(py, &out))
    }
}

pub(crate) fn register(parent: &Bound<'_, PyModule>) -> PyResult<()> {
    let m = PyModule::new(parent.py(), "template")?;
    m.add_class::<Template>()?;
    m.add_class::<DeformationTransfer>()?;
    m.add_function(wrap_pyfunction!(track, &m)?)?;
    parent.add_submodule(&m)
}
