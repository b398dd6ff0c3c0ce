//! multilinear-face (Vlasic 2010 Ch. 5): multilinear models, imputation, tracking.

use glam::DVec3;
use multilinear_face::{
    impute as rust_impute, lift_texture, mean_weights, render_textured, track_points as rust_track,
    track_video as rust_video, FaceTensor, FeaturePoints, ImputeParams, KnownFaces, ModelParams,
    MultilinearModel, TrackParams, VideoTrackParams, WeakPerspective,
};
use nalgebra::DVector;
use numpy::{PyArray1, PyArray2, PyArray3};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};
use std::path::PathBuf;

use crate::arrays::{finite, from_dmatrix, from_points3, owned1, owned3, rows3, view};
use crate::errors::{invalid, to_py};

/// Faces `(faces, vertices, 3)` (m), in row-major order of the attribute modes (the last
/// attribute varies fastest), as the data tensor of Figure 5-3.
fn face_tensor(faces: &Bound<'_, PyAny>, attribute_sizes: &[usize]) -> PyResult<FaceTensor> {
    let count: usize = attribute_sizes.iter().product();
    let v = finite(faces, "faces", &[Some(count), None, Some(3)])?;
    let a = v.as_array();
    let list: Vec<Vec<DVec3>> = a.outer_iter().map(|f| rows3(&f)).collect();
    FaceTensor::from_faces(attribute_sizes, &list).map_err(to_py)
}

fn faces_array<'py>(py: Python<'py>, t: &FaceTensor) -> PyResult<Bound<'py, PyArray3<f64>>> {
    let (n, v) = (t.face_count(), t.vertex_count());
    let mut flat = Vec::with_capacity(n * v * 3);
    for f in 0..n {
        flat.extend(t.face(f).map_err(to_py)?.iter().flat_map(|p| p.to_array()));
    }
    Ok(owned3(py, flat, (n, v, 3)))
}

/// A multilinear face model (Eq. 5.4–5.5): a core tensor and one factor per attribute mode
/// (identity, expression, …), over the vertices.
#[pyclass(module = "dynamic_shapes.face", frozen)]
pub(crate) struct FaceModel {
    inner: MultilinearModel,
}

fn weights_list(
    model: &MultilinearModel,
    weights: Vec<Bound<'_, PyAny>>,
) -> PyResult<Vec<DVector<f64>>> {
    let ranks = model.ranks();
    if weights.len() != ranks.len() {
        return Err(invalid(format!(
            "weights: {} vectors given, the model has {} modes",
            weights.len(),
            ranks.len()
        )));
    }
    weights
        .iter()
        .zip(ranks)
        .enumerate()
        .map(|(i, (w, &r))| {
            crate::arrays::vector(w, &format!("weights[{i}]"), Some(r)).map(DVector::from_vec)
        })
        .collect()
}

#[pymethods]
impl FaceModel {
    /// Fits a model to `faces` `(faces, vertices, 3)` (m) over attribute modes of
    /// `attribute_sizes` (e.g. `[identities, expressions]`, product = faces), keeping `ranks`
    /// per mode (N-mode SVD, then HOOI). Returns `(model, fit)`; `fit` a dict with
    /// `hosvd_rel_error`, `hooi_rel_error`, `sweeps`.
    #[staticmethod]
    fn fit<'py>(
        py: Python<'py>,
        faces: &Bound<'py, PyAny>,
        attribute_sizes: Vec<usize>,
        ranks: Vec<usize>,
    ) -> PyResult<Bound<'py, PyTuple>> {
        let data = face_tensor(faces, &attribute_sizes)?;
        let (model, fit) = py
            .detach(|| MultilinearModel::fit(&data, &ModelParams::new(&ranks)))
            .map_err(to_py)?;
        let d = PyDict::new(py);
        d.set_item("hosvd_rel_error", fit.hosvd_rel_error)?;
        d.set_item("hooi_rel_error", fit.hooi_rel_error)?;
        d.set_item("sweeps", fit.sweeps)?;
        PyTuple::new(
            py,
            [
                Bound::new(py, FaceModel { inner: model })?.into_any(),
                d.into_any(),
            ],
        )
    }

    /// Number of vertices.
    #[getter]
    fn vertex_count(&self) -> usize {
        self.inner.vertex_count()
    }

    /// Kept rank per attribute mode.
    #[getter]
    fn ranks(&self) -> Vec<usize> {
        self.inner.ranks().to_vec()
    }

    /// The factor matrix of attribute `mode` `(size, rank)`: row `i` is training value `i`'s
    /// weights.
    fn factor<'py>(&self, py: Python<'py>, mode: usize) -> PyResult<Bound<'py, PyArray2<f64>>> {
        Ok(from_dmatrix(py, self.inner.factor(mode).map_err(to_py)?))
    }

    /// The weights `(rank,)` of training value `index` of attribute `mode`.
    fn training_weights<'py>(
        &self,
        py: Python<'py>,
        mode: usize,
        index: usize,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let w = self.inner.training_weights(mode, index).map_err(to_py)?;
        Ok(owned1(py, w.as_slice().to_vec()))
    }

    /// The mean weights of every mode (the model's average face), one `(rank,)` per mode.
    fn mean_weights<'py>(&self, py: Python<'py>) -> PyResult<Vec<Bound<'py, PyArray1<f64>>>> {
        let w = mean_weights(&self.inner).map_err(to_py)?;
        Ok(w.into_iter()
            .map(|v| owned1(py, v.as_slice().to_vec()))
            .collect())
    }

    /// Synthesises a face (Eq. 5.5) from one weight vector per mode: `(vertices, 3)` (m).
    fn synthesize<'py>(
        &self,
        py: Python<'py>,
        weights: Vec<Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let w = weights_list(&self.inner, weights)?;
        let face = py.detach(|| self.inner.face(&w)).map_err(to_py)?;
        Ok(from_points3(py, &face))
    }

    /// Tracks a face from 2-D point tracks (§5.4.1): `tracks` `(frames, len(tracked), 2)`
    /// pixels of the model vertices `tracked`; `constant[m]` keeps mode `m`'s weights the
    /// same over the sequence (e.g. identity). Returns a dict: `weights` (per mode a
    /// `(frames, rank)` array), `reprojection_rms_px` `(frames,)`, `scale` `(frames,)`,
    /// `rotation_rows` `(frames, 2, 3)`, `translation` `(frames, 2)` of the weak-perspective
    /// cameras.
    fn track_points<'py>(
        &self,
        py: Python<'py>,
        tracked: Vec<usize>,
        tracks: &Bound<'py, PyAny>,
        constant: Vec<bool>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let v = finite(tracks, "tracks", &[None, Some(tracked.len()), Some(2)])?;
        let frames: Vec<Vec<[f64; 2]>> = v
            .as_array()
            .outer_iter()
            .map(|f| f.outer_iter().map(|p| [p[0], p[1]]).collect())
            .collect();
        let t = py
            .detach(|| {
                rust_track(
                    &self.inner,
                    &tracked,
                    &frames,
                    &constant,
                    &TrackParams::default(),
                )
            })
            .map_err(to_py)?;
        track_dict(
            py,
            &self.inner,
            &t.weights,
            &t.cameras,
            t.reprojection_rms_px,
        )
    }

    /// Tracks a face through video frames (§5.4.1–5.4.2): `frames` `(frames, h, w, 3)` uint8
    /// RGB; the model's `triangles` `(m, 3)` uint32; KLT on the model vertices `tracked`,
    /// started from `feature_vertices` seen at `feature_pixels` `(k, 2)` in frame 0;
    /// `constant` as in `track_points`. Returns the dict of `track_points` plus
    /// `tracked_fraction` `(frames,)`. Raises `DynamicShapesError` with "face lost" when the
    /// face is lost (the message names the frame).
    #[allow(
        clippy::too_many_arguments,
        reason = "Python arguments, named at the call"
    )]
    fn track_video<'py>(
        &self,
        py: Python<'py>,
        frames: &Bound<'py, PyAny>,
        triangles: &Bound<'py, PyAny>,
        tracked: Vec<usize>,
        feature_vertices: Vec<usize>,
        feature_pixels: &Bound<'py, PyAny>,
        constant: Vec<bool>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let v = view::<u8>(frames, "frames", "uint8", &[None, None, None, Some(3)])?;
        let a = v.as_array();
        let (h, w) = (a.shape()[1], a.shape()[2]);
        let (hu, wu) = (
            u32::try_from(h).map_err(|_| invalid("frames: height too large"))?,
            u32::try_from(w).map_err(|_| invalid("frames: width too large"))?,
        );
        let images = a
            .outer_iter()
            .map(|f| {
                image::RgbImage::from_raw(wu, hu, f.iter().copied().collect())
                    .ok_or_else(|| invalid("frames: size does not match its shape"))
            })
            .collect::<PyResult<Vec<_>>>()?;
        let tris = crate::arrays::faces(triangles, "triangles", self.inner.vertex_count())?;
        let pixels = crate::arrays::points2(feature_pixels, "feature_pixels")?;
        let features = FeaturePoints {
            vertices: feature_vertices,
            pixels: pixels.iter().map(|p| p.to_array()).collect(),
        };
        let t = py
            .detach(|| {
                rust_video(
                    &self.inner,
                    &tris,
                    &tracked,
                    &images,
                    &features,
                    &constant,
                    &VideoTrackParams::default(),
                )
            })
            .map_err(to_py)?;
        let d = track_dict(
            py,
            &self.inner,
            &t.weights,
            &t.cameras,
            t.reprojection_rms_px,
        )?;
        d.set_item("tracked_fraction", owned1(py, t.tracked_fraction))?;
        Ok(d)
    }

    fn __repr__(&self) -> String {
        format!(
            "FaceModel({} vertices, ranks {:?})",
            self.inner.vertex_count(),
            self.inner.ranks()
        )
    }
}

/// A tracking result as a dict: per-mode weights `(frames, rank)`, RMS, weak-perspective cameras.
fn track_dict<'py>(
    py: Python<'py>,
    model: &MultilinearModel,
    weights: &[Vec<DVector<f64>>],
    cameras: &[WeakPerspective],
    rms: Vec<f64>,
) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    let n = weights.len();
    let per_mode = model
        .ranks()
        .iter()
        .enumerate()
        .map(|(m, &r)| {
            let flat: Vec<f64> = weights
                .iter()
                .flat_map(|w| w[m].as_slice().to_vec())
                .collect();
            crate::arrays::owned2(py, flat, n, r)
        })
        .collect::<Vec<_>>();
    d.set_item("weights", per_mode)?;
    d.set_item("reprojection_rms_px", owned1(py, rms))?;
    d.set_item(
        "scale",
        owned1(py, cameras.iter().map(|c| c.scale).collect()),
    )?;
    let rows: Vec<f64> = cameras.iter().flat_map(|c| c.rows.concat()).collect();
    d.set_item("rotation_rows", owned3(py, rows, (n, 2, 3)))?;
    let tr: Vec<f64> = cameras.iter().flat_map(|c| c.translation).collect();
    d.set_item("translation", crate::arrays::owned2(py, tr, n, 2))?;
    Ok(d)
}

/// A weak-perspective camera from its scale, `(2, 3)` rotation rows and `(2,)` translation (px).
fn weak_perspective(
    scale: f64,
    rows: &Bound<'_, PyAny>,
    translation: (f64, f64),
) -> PyResult<WeakPerspective> {
    let r = finite(rows, "rotation_rows", &[Some(2), Some(3)])?;
    let a = r.as_array();
    Ok(WeakPerspective {
        scale,
        rows: [
            [a[[0, 0]], a[[0, 1]], a[[0, 2]]],
            [a[[1, 0]], a[[1, 1]], a[[1, 2]]],
        ],
        translation: [translation.0, translation.1],
    })
}

fn rgb(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<image::RgbImage> {
    let v = view::<u8>(obj, name, "uint8", &[None, None, Some(3)])?;
    let a = v.as_array();
    let (h, w) = (a.shape()[0], a.shape()[1]);
    let (hu, wu) = (
        u32::try_from(h).map_err(|_| invalid(format!("{name}: height too large")))?,
        u32::try_from(w).map_err(|_| invalid(format!("{name}: width too large")))?,
    );
    image::RgbImage::from_raw(wu, hu, a.iter().copied().collect())
        .ok_or_else(|| invalid(format!("{name}: size does not match its shape")))
}

/// Face transfer (§5.5): the colours of `source_face` `(n, 3)` seen by its weak-perspective
/// camera (`source_scale`, `source_rows` `(2, 3)`, `source_translation` px) in
/// `source_frame` `(h, w, 3)` uint8 are lifted onto the vertices, then `target_face` (in
/// correspondence) is rendered with them under the target camera over `target_frame`.
/// Returns the composited `(h, w, 3)` uint8 frame.
#[pyfunction]
#[allow(
    clippy::too_many_arguments,
    reason = "Python arguments, named at the call"
)]
fn transfer<'py>(
    py: Python<'py>,
    triangles: &Bound<'py, PyAny>,
    source_face: &Bound<'py, PyAny>,
    source_scale: f64,
    source_rows: &Bound<'py, PyAny>,
    source_translation: (f64, f64),
    source_frame: &Bound<'py, PyAny>,
    target_face: &Bound<'py, PyAny>,
    target_scale: f64,
    target_rows: &Bound<'py, PyAny>,
    target_translation: (f64, f64),
    target_frame: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArray3<u8>>> {
    let src = crate::arrays::points3(source_face, "source_face")?;
    let dst = crate::arrays::points3(target_face, "target_face")?;
    let tris = crate::arrays::faces(triangles, "triangles", src.len())?;
    let (sc, tc) = (
        weak_perspective(source_scale, source_rows, source_translation)?,
        weak_perspective(target_scale, target_rows, target_translation)?,
    );
    let (sf, tf) = (
        rgb(source_frame, "source_frame")?,
        rgb(target_frame, "target_frame")?,
    );
    let out = py
        .detach(|| -> multilinear_face::Result<image::RgbImage> {
            let texture = lift_texture(&src, &tris, &sc, &sf)?;
            render_textured(&dst, &tris, &tc, &texture, &tf)
        })
        .map_err(to_py)?;
    let (w, h) = out.dimensions();
    Ok(owned3(py, out.into_raw(), (h as usize, w as usize, 3)))
}

/// Fills in missing faces (§5.3.4, per-mode PPCA solved jointly): `faces` `(faces, vertices,
/// 3)` over `attribute_sizes`, `known` `(faces,)` uint8 (non-zero = captured; the values of
/// the missing faces are ignored). Returns the completed `(faces, vertices, 3)`.
#[pyfunction]
fn impute<'py>(
    py: Python<'py>,
    faces: &Bound<'py, PyAny>,
    attribute_sizes: Vec<usize>,
    known: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArray3<f64>>> {
    let count: usize = attribute_sizes.iter().product();
    let k = view::<u8>(known, "known", "uint8", &[Some(count)])?;
    let k: Vec<bool> = k.as_array().iter().map(|&b| b != 0).collect();
    let data = face_tensor(faces, &attribute_sizes)?;
    let filled = py
        .detach(|| -> multilinear_face::Result<FaceTensor> {
            let known = KnownFaces::new(&attribute_sizes, k)?;
            Ok(rust_impute(&data, &known, &ImputeParams::default())?.faces)
        })
        .map_err(to_py)?;
    faces_array(py, &filled)
}

/// The bilinear face set of the validation (the `face_transfer` example's): faces from the ICT
/// face basis in `ict_dir` (the repository's `data/ict-face`), expressions × identities with
/// the basis's identity-dependent expression interaction. Returns `(faces, attribute_sizes,
/// triangles)`: `(faces, vertices, 3)` in the data's units (≈ cm), `[expressions,
/// identities]`, `(m, 3)` uint32.
#[pyfunction]
fn ict_bilinear_set<'py>(py: Python<'py>, ict_dir: PathBuf) -> PyResult<Bound<'py, PyTuple>> {
    use multilinear_face::validation::{bilinear_face_set, FaceSetParams, IctBasis};
    let set = py
        .detach(|| -> multilinear_face::Result<_> {
            bilinear_face_set(&IctBasis::read(&ict_dir)?, &FaceSetParams::default())
        })
        .map_err(to_py)?;
    let faces = faces_array(py, &set.faces)?;
    let sizes = set.faces.attribute_sizes().to_vec();
    let tris = crate::arrays::from_rows(py, set.triangles.iter().copied(), set.triangles.len());
    PyTuple::new(
        py,
        [
            faces.into_any(),
            sizes.into_pyobject(py)?.into_any(),
            tris.into_any(),
        ],
    )
}

pub(crate) fn register(parent: &Bound<'_, PyModule>) -> PyResult<()> {
    let m = PyModule::new(parent.py(), "face")?;
    m.add_class::<FaceModel>()?;
    m.add_function(wrap_pyfunction!(impute, &m)?)?;
    m.add_function(wrap_pyfunction!(ict_bilinear_set, &m)?)?;
    m.add_function(wrap_pyfunction!(transfer, &m)?)?;
    parent.add_submodule(&m)
}
