//! inertial-acoustic (Vlasic 2010 Ch. 4): recordings, the pipeline, the one-board filter.

use glam::{DQuat, DVec3};
use inertial_acoustic::imu_log::{
    read_broad_hdf5, run_orientation as rust_orientation, ImuLog as RustLog,
};
use inertial_acoustic::pipeline::{run, PipelineParams};
use inertial_acoustic::{
    heading_inclination_rmse as rust_rmse, FilterParams, Recording as RustRecording, SensorSet,
};
use numpy::{PyArray1, PyArray2};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};
use std::path::PathBuf;

use crate::arrays::{from_points3, from_rows, owned1, view};
use crate::core::Skeleton;
use crate::errors::to_py;

/// What a suit records after the signal processing (§4.3): per frame each board's decoded
/// inertial reading and the detected distances, the suit, the rest hold and the known DOFs.
/// The file format is a directory of a JSON manifest and CSV streams (documented on the Rust
/// type `inertial_acoustic::Recording`).
#[pyclass(module = "dynamic_shapes.inertial", frozen)]
pub(crate) struct Recording {
    inner: RustRecording,
}

#[pymethods]
impl Recording {
    /// Reads a recording directory for `skeleton`.
    #[staticmethod]
    fn read(py: Python<'_>, path: PathBuf, skeleton: &Skeleton) -> PyResult<Self> {
        let inner = py
            .detach(|| RustRecording::read(&path, &skeleton.inner))
            .map_err(to_py)?;
        Ok(Recording { inner })
    }

    /// Writes the recording as a directory (created if missing).
    fn write(&self, py: Python<'_>, path: PathBuf, skeleton: &Skeleton) -> PyResult<()> {
        py.detach(|| self.inner.write(&path, &skeleton.inner))
            .map_err(to_py)
    }

    /// Frame rate, Hz.
    #[getter]
    fn rate_hz(&self) -> f64 {
        self.inner.rate_hz
    }

    /// Number of frames.
    #[getter]
    fn frame_count(&self) -> usize {
        self.inner.frames.len()
    }

    /// Duration, s.
    #[getter]
    fn duration_s(&self) -> f64 {
        self.inner.duration_s()
    }

    /// Number of sensor boards on the suit.
    #[getter]
    fn board_count(&self) -> usize {
        self.inner.suit.boards().len()
    }

    /// The pose θ held during the rest frames, `(dof_count,)`.
    #[getter]
    fn rest_pose<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        owned1(py, self.inner.rest_pose.clone())
    }

    fn __repr__(&self) -> String {
        format!(
            "Recording({} frames at {} Hz, {} boards)",
            self.inner.frames.len(),
            self.inner.rate_hz,
            self.inner.suit.boards().len()
        )
    }
}

/// Runs the pipeline on a recording (§4.4): initialisation, per-board noise from a first
/// pass, the skeletal EKF. Returns a dict: `theta` `(frames, dof_count)` joint angles (rad,
/// m), `mean_nis` `(3,)` (inertial, distance, known-DOF innovations), `diverged_frames`,
/// `seconds` (wall clock).
#[pyfunction]
#[pyo3(signature = (skeleton, recording, heading_fit = false))]
fn run_pipeline<'py>(
    py: Python<'py>,
    skeleton: &Skeleton,
    recording: &Recording,
    heading_fit: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let params = PipelineParams::default().with_heading_fit(heading_fit);
    let out = py
        .detach(|| run(&skeleton.inner, &recording.inner, &params))
        .map_err(to_py)?;
    let d = PyDict::new(py);
    d.set_item(
        "theta",
        crate::arrays::from_vec_rows(py, &out.theta, skeleton.inner.dof_count())?,
    )?;
    d.set_item("mean_nis", owned1(py, out.mean_nis().to_vec()))?;
    d.set_item("diverged_frames", out.diverged_frames)?;
    d.set_item("seconds", out.seconds)?;
    Ok(d)
}

/// One IMU's log: gyroscope and accelerometer per sample and, for a benchmark trial, the
/// optical reference orientation.
#[pyclass(module = "dynamic_shapes.inertial", frozen)]
pub(crate) struct ImuLog {
    inner: RustLog,
}

fn quats_xyzw<'py>(py: Python<'py>, q: &[DQuat]) -> Bound<'py, PyArray2<f64>> {
    from_rows(py, q.iter().map(|q| q.to_array()), q.len())
}

#[pymethods]
impl ImuLog {
    /// Reads a BROAD benchmark trial (HDF5: `imu_gyr`, `imu_acc`, `opt_quat`, `movement`).
    #[staticmethod]
    fn read_broad(py: Python<'_>, path: PathBuf) -> PyResult<Self> {
        let inner = py.detach(|| read_broad_hdf5(&path)).map_err(to_py)?;
        Ok(ImuLog { inner })
    }

    /// Sample times `(n,)`, s.
    #[getter]
    fn time_s<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        owned1(py, self.inner.time_s.clone())
    }

    /// Gyroscope `(n, 3)`, rad/s.
    #[getter]
    fn gyro_rad_s<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let g: Vec<DVec3> = self.inner.readings.iter().map(|r| r.gyro_rad_s).collect();
        from_points3(py, &g)
    }

    /// Accelerometer `(n, 3)`, m/s² (reads +g upwards at rest).
    #[getter]
    fn accel_m_s2<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let a: Vec<DVec3> = self.inner.readings.iter().map(|r| r.accel_m_s2).collect();
        from_points3(py, &a)
    }

    /// Reference board-to-world rotations `(n, 4)` as quaternions `(x, y, z, w)` (SciPy's
    /// order), NaN where unavailable.
    #[getter]
    fn reference<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        quats_xyzw(py, &self.inner.reference)
    }

    /// The samples the benchmark scores, `(n,)` uint8.
    #[getter]
    fn movement<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<u8>> {
        owned1(
            py,
            self.inner.movement.iter().map(|&b| u8::from(b)).collect(),
        )
    }

    fn __len__(&self) -> usize {
        self.inner.time_s.len()
    }
}

/// The filter of §4.4 for one board over a log (z up), started from its first `rest_s` s at
/// rest (§4.4.4). Sigmas default to the Rust `FilterParams` defaults: process (rad/s²),
/// accelerometer (m/s²), gyroscope (rad/s); `gyro_only` drops the accelerometer rows (the
/// gyroscope-integration baseline). Returns `(orientation, rate)`: `(n, 4)`
/// quaternions `(x, y, z, w)` board to world and `(n, 3)` rates (rad/s, board axes).
#[pyfunction]
#[pyo3(signature = (log, rest_s, process_sigma = None, accelerometer_sigma = None, gyroscope_sigma = None, gyro_only = false))]
fn run_orientation<'py>(
    py: Python<'py>,
    log: &ImuLog,
    rest_s: f64,
    process_sigma: Option<f64>,
    accelerometer_sigma: Option<f64>,
    gyroscope_sigma: Option<f64>,
    gyro_only: bool,
) -> PyResult<Bound<'py, PyTuple>> {
    let d = FilterParams::default();
    let mut params = FilterParams {
        process_sigma: process_sigma.unwrap_or(d.process_sigma),
        accelerometer_sigma: accelerometer_sigma.unwrap_or(d.accelerometer_sigma),
        gyroscope_sigma: gyroscope_sigma.unwrap_or(d.gyroscope_sigma),
        ..d
    };
    if gyro_only {
        params = params.with_sensors(SensorSet {
            accelerometers: false,
            gyroscopes: true,
            distances: false,
        });
    }
    let out = py
        .detach(|| rust_orientation(&log.inner, params, rest_s))
        .map_err(to_py)?;
    PyTuple::new(
        py,
        [
            quats_xyzw(py, &out.orientation),
            from_points3(py, &out.rate_rad_s),
        ],
    )
}

fn quats(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Vec<DQuat>> {
    let v = view::<f64>(obj, name, "float64", &[None, Some(4)])?;
    Ok(v.as_array()
        .outer_iter()
        .map(|r| DQuat::from_xyzw(r[0], r[1], r[2], r[3]))
        .collect())
}

/// Inclination and heading RMS errors (deg) of estimated against reference orientations
/// (both `(n, 4)` `(x, y, z, w)`; reference NaN rows are skipped) over the samples where
/// `use_sample` `(n,)` uint8 is non-zero, after removing the constant heading offset. Returns
/// a dict: `inclination_deg`, `heading_deg`, `heading_offset_deg`, `samples`.
#[pyfunction]
#[pyo3(signature = (estimate, reference, use_sample, up = (0.0, 0.0, 1.0)))]
fn heading_inclination_rmse<'py>(
    py: Python<'py>,
    estimate: &Bound<'py, PyAny>,
    reference: &Bound<'py, PyAny>,
    use_sample: &Bound<'py, PyAny>,
    up: (f64, f64, f64),
) -> PyResult<Bound<'py, PyDict>> {
    let e = quats(estimate, "estimate")?;
    let r = quats(reference, "reference")?;
    let u = view::<u8>(use_sample, "use_sample", "uint8", &[None])?;
    let u: Vec<bool> = u.as_array().iter().map(|&b| b != 0).collect();
    let out = py
        .detach(|| rust_rmse(&e, &r, &u, DVec3::new(up.0, up.1, up.2)))
        .map_err(to_py)?;
    let d = PyDict::new(py);
    d.set_item("inclination_deg", out.inclination_deg)?;
    d.set_item("heading_deg", out.heading_deg)?;
    d.set_item("heading_offset_deg", out.heading_offset_deg)?;
    d.set_item("samples", out.samples)?;
    Ok(d)
}

pub(crate) fn register(parent: &Bound<'_, PyModule>) -> PyResult<()> {
    let m = PyModule::new(parent.py(), "inertial")?;
    m.add_class::<Recording>()?;
    m.add_class::<ImuLog>()?;
    m.add_function(wrap_pyfunction!(run_pipeline, &m)?)?;
    m.add_function(wrap_pyfunction!(run_orientation, &m)?)?;
    m.add_function(wrap_pyfunction!(heading_inclination_rmse, &m)?)?;
    parent.add_submodule(&m)
}
