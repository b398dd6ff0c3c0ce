//! needle-model (Sand 2003): needles on bones fitted to silhouettes, animated by NRBF.

use needle_model::{
    animate, merged_mesh, BodyLayout, FrameInput, NeedleBody, NeedleModel as RustModel,
    ObserveParams, Observer, ReconstructionParams,
};
use numpy::PyArray1;
use pyo3::prelude::*;
use pyo3::types::PyTuple;
use skin_core::skeleton::Skeleton as RustSkeleton;

use crate::arrays::{matrix_rows, owned1, vector};
use crate::core::{mesh_arrays, Camera, Skeleton};
use crate::errors::{invalid, to_py};

/// A reconstructed needle model: the body's primitives (one per bone, needles in rings
/// around its axis, Sand 2003 Table 3.1) and the NRBF of each primitive's needle lengths over
/// its pose configuration (§5).
#[pyclass(module = "dynamic_shapes.needle", frozen)]
pub(crate) struct NeedleModel {
    pub(crate) body: NeedleBody,
    skeleton: RustSkeleton,
    pub(crate) model: RustModel,
    observations: u64,
}

#[pymethods]
impl NeedleModel {
    /// Number of primitives.
    #[getter]
    fn primitive_count(&self) -> usize {
        self.body.primitives.len()
    }

    /// Primitive names, in order.
    #[getter]
    fn primitive_names(&self) -> Vec<String> {
        self.body
            .primitives
            .iter()
            .map(|p| p.name.clone())
            .collect()
    }

    /// Needle observations the model was built from (all frames, cameras and needles).
    #[getter]
    fn observation_count(&self) -> u64 {
        self.observations
    }

    /// Predicted needle lengths (m) of primitive `primitive` for pose `theta`.
    fn needle_lengths<'py>(
        &self,
        py: Python<'py>,
        primitive: usize,
        theta: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let t = vector(theta, "theta", Some(self.skeleton.dof_count()))?;
        let p = self.body.primitives.get(primitive).ok_or_else(|| {
            invalid(format!(
                "primitive {primitive} out of range (model has {})",
                self.body.primitives.len()
            ))
        })?;
        let lengths = py
            .detach(|| -> needle_model::Result<Vec<f32>> {
                let fk = self.skeleton.forward_kinematics(&t)?;
                let x = p.config.point_f32(&fk)?;
                self.model.needle_lengths(primitive, &x)
            })
            .map_err(to_py)?;
        Ok(owned1(py, lengths.into_iter().map(f64::from).collect()))
    }

    /// The animated surface for pose `theta`: every primitive's needle-tip mesh, merged.
    /// Returns `(vertices, faces)`: `(n, 3)` float64 (m) and `(m, 3)` uint32.
    fn surface<'py>(
        &self,
        py: Python<'py>,
        theta: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyTuple>> {
        let t = vector(theta, "theta", Some(self.skeleton.dof_count()))?;
        let mesh = py
            .detach(|| -> needle_model::Result<_> {
                let body = animate(&self.body, &self.model, &self.skeleton, &t)?;
                merged_mesh(&body)
            })
            .map_err(to_py)?;
        mesh_arrays(py, &mesh)
    }

    fn __repr__(&self) -> String {
        format!(
            "NeedleModel({} primitives, {} observations)",
            self.body.primitives.len(),
            self.observations
        )
    }
}

/// Builds a needle model from calibrated, synchronised silhouettes (Sand 2003 §4.3, §5):
/// walks every needle through every mask, then fits the prototypes and their shapes.
///
/// `thetas` `(frames, dof_count)` are the skeleton's poses; `masks` `(frames, cameras, h, w)`
/// uint8 silhouettes (non-zero inside), each camera's image size; `density` scales Table
/// 3.1's needle counts; `prototype_count` the NRBF's N (default the paper's); `seed` the
/// prototype selection's.
#[pyfunction]
#[pyo3(signature = (skeleton, cameras, thetas, masks, density = 1.0, prototype_count = None, seed = None))]
#[allow(clippy::too_many_arguments, reason = "Python keyword arguments")]
fn reconstruct(
    py: Python<'_>,
    skeleton: &Skeleton,
    cameras: Vec<Camera>,
    thetas: &Bound<'_, PyAny>,
    masks: &Bound<'_, PyAny>,
    density: f64,
    prototype_count: Option<usize>,
    seed: Option<u64>,
) -> PyResult<NeedleModel> {
    let s = skeleton.inner.clone();
    let thetas = matrix_rows(thetas, "thetas", Some(s.dof_count()))?;
    let (lead, cams, flat) = crate::core::views(cameras, masks, 2)?;
    if lead[0] != thetas.len() {
        return Err(invalid(format!(
            "masks has {} frames but thetas has {}",
            lead[0],
            thetas.len()
        )));
    }
    let mut params = ReconstructionParams::default();
    if let Some(n) = prototype_count {
        params = params.with_prototype_count_n(n);
    }
    if let Some(seed) = seed {
        params = params.with_seed(seed);
    }
    let per_frame = lead[1];
    py.detach(move || -> needle_model::Result<NeedleModel> {
        let body = NeedleBody::new(&s, &BodyLayout::table_3_1().with_density(density))?;
        let observer = Observer::new(body, s.clone(), cams, ObserveParams::default())?;
        let frames: Vec<FrameInput<'_>> = thetas
            .iter()
            .enumerate()
            .map(|(f, theta)| FrameInput {
                theta,
                masks: &flat[f * per_frame..(f + 1) * per_frame],
            })
            .collect();
        let acc = observer.accumulate(&frames)?;
        let rec = RustModel::reconstruct(&acc.store, observer.body(), &params)?;
        Ok(NeedleModel {
            body: observer.body().clone(),
            skeleton: s,
            model: rec.model,
            observations: acc.store.total_observations() as u64,
        })
    })
    .map_err(to_py)
}

pub(crate) fn register(parent: &Bound<'_, PyModule>) -> PyResult<()> {
    let m = PyModule::new(parent.py(), "needle")?;
    m.add_class::<NeedleModel>()?;
    m.add_function(wrap_pyfunction!(reconstruct, &m)?)?;
    parent.add_submodule(&m)
}
