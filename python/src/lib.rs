//! Python bindings of dynamic-shapes: the extension module `dynamic_shapes._native`.
//!
//! The Python package `dynamic_shapes` (in `python/dynamic_shapes`) re-exports everything
//! defined here, adds the exception classes (`_errors.py`), the type stubs and `py.typed`.
//! Arrays cross the boundary as NumPy `float64` (masks `uint8`), checked by the `arrays` module;
//! errors of the Rust crates become the typed Python exceptions of the `errors` module; every call
//! that does real work releases the GIL (`Python::detach`).

mod arrays;
pub mod batch;
mod batch_py;
mod core;
mod errors;
mod face;
mod inertial;
mod needle;
mod photometric;
mod studio;
mod template;

use pyo3::prelude::*;

/// The extension module: core, then one submodule per method crate.
#[pymodule]
#[pyo3(name = "_native")]
fn native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    core::register(m)?;
    needle::register(m)?;
    template::register(m)?;
    photometric::register(m)?;
    inertial::register(m)?;
    face::register(m)?;
    studio::register(m)?;
    batch_py::register(m)?;
    Ok(())
}
