//! `dynamic_shapes.batch`: the frame-range entry points of [`crate::batch`] with plain
//! arguments (paths as strings, ints, floats, lists), so a task scheduler (Ray) can ship them
//! to workers. Each releases the GIL.

use std::path::PathBuf;

use pyo3::prelude::*;

use crate::batch;
use crate::errors::to_py;

fn range(start: usize, stop: usize) -> std::ops::Range<usize> {
    start..stop
}

/// Writes a photometric capture folder (MakeHuman in the exercise under the dome, `cameras`
/// ring cameras at `size` × `size`, the motion's frames `start`..`stop`): pattern images,
/// masks, calibration spheres, `capture.json`.
#[pyfunction]
#[pyo3(signature = (makehuman_dir, out_dir, start, stop, cameras = 2, size = 128, skirt = false,
    white_level = 0.4))]
#[allow(clippy::too_many_arguments)]
fn write_photometric_capture(
    py: Python<'_>,
    makehuman_dir: PathBuf,
    out_dir: PathBuf,
    start: usize,
    stop: usize,
    cameras: usize,
    size: u32,
    skirt: bool,
    white_level: f32,
) -> PyResult<()> {
    py.detach(|| {
        batch::write_photometric_capture(
            &makehuman_dir,
            &out_dir,
            range(start, stop),
            cameras,
            size,
            skirt,
            white_level,
        )
    })
    .map_err(to_py)
}

/// Writes a silhouette capture folder (MakeHuman in the exercise from motion frame `first`,
/// `frames` frames, `cameras` ring cameras at `width` × `height`): masks, mocap poses, the
/// scanned template, `capture.json`.
#[pyfunction]
#[pyo3(signature = (makehuman_dir, out_dir, first = 40, frames = 8, cameras = 4, width = 240,
    height = 180, template_vertices = 3000))]
#[allow(clippy::too_many_arguments)]
fn write_silhouette_capture(
    py: Python<'_>,
    makehuman_dir: PathBuf,
    out_dir: PathBuf,
    first: usize,
    frames: usize,
    cameras: usize,
    width: u32,
    height: u32,
    template_vertices: usize,
) -> PyResult<()> {
    py.detach(|| {
        batch::write_silhouette_capture(
            &makehuman_dir,
            &out_dir,
            first,
            frames,
            cameras,
            width,
            height,
            template_vertices,
        )
    })
    .map_err(to_py)
}

/// The two-pass reconstruction of the capture's frames `start`..`stop`: writes
/// `{out_prefix}NNNNNN.ply` per frame; returns the paths.
#[pyfunction]
#[pyo3(signature = (capture_dir, start, stop, out_prefix, poisson_depth = 8))]
fn photometric_frames(
    py: Python<'_>,
    capture_dir: PathBuf,
    start: usize,
    stop: usize,
    out_prefix: String,
    poisson_depth: u32,
) -> PyResult<Vec<PathBuf>> {
    py.detach(|| {
        batch::photometric_frames(&capture_dir, range(start, stop), &out_prefix, poisson_depth)
    })
    .map_err(to_py)
}

/// Tracks the chunk `start`..`stop` from `first_pose` (the chunk's first frame's pose):
/// writes `{out_prefix}poses_A_B.npy` and `vertices_A_B.npy`; returns the last pose (the next
/// chunk's `first_pose`).
#[pyfunction]
fn track_chunk(
    py: Python<'_>,
    capture_dir: PathBuf,
    start: usize,
    stop: usize,
    first_pose: Vec<f64>,
    out_prefix: String,
) -> PyResult<Vec<f64>> {
    py.detach(|| batch::track_chunk(&capture_dir, range(start, stop), &first_pose, &out_prefix))
        .map_err(to_py)
}

/// The needle observations of the chunk `start`..`stop`: writes `{out_prefix}store_A_B.json`
/// and returns its path.
#[pyfunction]
fn needle_accumulate(
    py: Python<'_>,
    capture_dir: PathBuf,
    start: usize,
    stop: usize,
    out_prefix: String,
) -> PyResult<PathBuf> {
    py.detach(|| batch::needle_accumulate(&capture_dir, range(start, stop), &out_prefix))
        .map_err(to_py)
}

/// Merges the needle stores `stores` (in frame order) into `out`; returns the number of
/// observations.
#[pyfunction]
fn needle_merge(py: Python<'_>, stores: Vec<PathBuf>, out: PathBuf) -> PyResult<usize> {
    py.detach(|| batch::needle_merge(&stores, &out))
        .map_err(to_py)
}

/// The inertial pipeline of the recording folder for the skeleton in `skeleton_json`:
/// writes the joint angles of frames `start`..`stop` as `{out_prefix}theta_A_B.npy`; returns
/// its path.
#[pyfunction]
fn inertial_recording(
    py: Python<'_>,
    recording_dir: PathBuf,
    skeleton_json: PathBuf,
    start: usize,
    stop: usize,
    out_prefix: String,
) -> PyResult<PathBuf> {
    py.detach(|| {
        batch::inertial_recording(
            &recording_dir,
            &skeleton_json,
            range(start, stop),
            &out_prefix,
        )
    })
    .map_err(to_py)
}

pub(crate) fn register(parent: &Bound<'_, PyModule>) -> PyResult<()> {
    let m = PyModule::new(parent.py(), "batch")?;
    m.add_function(wrap_pyfunction!(write_photometric_capture, &m)?)?;
    m.add_function(wrap_pyfunction!(write_silhouette_capture, &m)?)?;
    m.add_function(wrap_pyfunction!(photometric_frames, &m)?)?;
    m.add_function(wrap_pyfunction!(track_chunk, &m)?)?;
    m.add_function(wrap_pyfunction!(needle_accumulate, &m)?)?;
    m.add_function(wrap_pyfunction!(needle_merge, &m)?)?;
    m.add_function(wrap_pyfunction!(inertial_recording, &m)?)?;
    parent.add_submodule(&m)
}
