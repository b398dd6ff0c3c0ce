//! Rust errors as typed Python exceptions (defined in `dynamic_shapes/_errors.py`).
//!
//! Every crate's error is classified by its innermost cause (below the `At` contexts) and
//! raised with its full message, contexts included ("frame 3: camera 1: empty input: …").

use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::PyType;

/// The exception class an error becomes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Kind {
    /// Bad input: sizes, NaN, empty, out of range, degenerate (`InvalidInputError`).
    Input,
    /// A file that cannot be read or written (`FileError`, an `OSError`).
    File,
    /// Malformed file contents (`FormatError`).
    Format,
    /// A singular problem or no convergence (`NumericalError`).
    Numerical,
    /// Anything else (`DynamicShapesError`, the base class).
    Other,
}

impl Kind {
    fn class_name(self) -> &'static str {
        match self {
            Kind::Input => "InvalidInputError",
            Kind::File => "FileError",
            Kind::Format => "FormatError",
            Kind::Numerical => "NumericalError",
            Kind::Other => "DynamicShapesError",
        }
    }
}

/// An error of one of the Rust crates, with its exception class.
pub(crate) trait Classify: std::fmt::Display {
    /// The class of the innermost cause.
    fn kind(&self) -> Kind;
}

impl Classify for skin_core::Error {
    fn kind(&self) -> Kind {
        use skin_core::Error as E;
        match self.root() {
            E::Io { .. } => Kind::File,
            E::Parse { .. } | E::Image(_) => Kind::Format,
            E::Singular { .. } | E::NoConvergence { .. } => Kind::Numerical,
            E::SizeMismatch { .. }
            | E::NonFinite { .. }
            | E::IndexOutOfRange { .. }
            | E::Degenerate { .. }
            | E::Empty { .. }
            | E::InvalidParam { .. }
            | E::NotVisible { .. } => Kind::Input,
            _ => Kind::Other,
        }
    }
}

/// `Classify` for a method crate's `Error` (made by `skin_core::method_error!`): its common
/// variants, then the crate's own ones listed as `Variant => Kind`.
macro_rules! classify_method_error {
    ($krate:ident { $($variant:ident => $kind:ident),* $(,)? }) => {
        impl Classify for $krate::Error {
            fn kind(&self) -> Kind {
                use $krate::Error as E;
                match self {
                    E::Core(e) => e.kind(),
                    E::At { source, .. } => source.kind(),
                    E::InvalidParam { .. }
                    | E::SizeMismatch { .. }
                    | E::NonFinite { .. }
                    | E::Empty { .. }
                    | E::IndexOutOfRange { .. } => Kind::Input,
                    $(E::$variant { .. } => Kind::$kind,)*
                    _ => Kind::Other,
                }
            }
        }
    };
}

classify_method_error!(needle_model { NoObservations => Input });
classify_method_error!(template_silhouette {});
classify_method_error!(photometric_normals { MissingPattern => Input, OutOfView => Input });
classify_method_error!(inertial_acoustic { MissingBone => Input, Corrupted => Format, Hdf5 => Format });
classify_method_error!(multilinear_face { UnknownName => Input });

impl Classify for crate::batch::BatchError {
    fn kind(&self) -> Kind {
        use crate::batch::BatchError as E;
        match self {
            E::Io { .. } => Kind::File,
            E::Format { .. } => Kind::Format,
            E::Input(_) => Kind::Input,
            E::Core(e) => e.kind(),
            E::Needle(e) => e.kind(),
            E::Template(e) => e.kind(),
            E::Photometric(e) => e.kind(),
            E::Inertial(e) => e.kind(),
        }
    }
}

static ERRORS_MODULE: PyOnceLock<Py<PyModule>> = PyOnceLock::new();

/// The Python exception of `kind` with `message`.
pub(crate) fn raise(kind: Kind, message: impl Into<String>) -> PyErr {
    let message = message.into();
    Python::attach(|py| {
        let class = ERRORS_MODULE
            .get_or_try_init(py, || {
                PyModule::import(py, "dynamic_shapes._errors").map(Bound::unbind)
            })
            .and_then(|m| m.bind(py).getattr(kind.class_name()))
            .and_then(|c| c.cast_into::<PyType>().map_err(PyErr::from));
        match class {
            Ok(class) => PyErr::from_type(class, message),
            Err(e) => PyTypeError::new_err(format!(
                "{message} (and dynamic_shapes._errors could not be loaded: {e})"
            )),
        }
    })
}

/// A Rust error as its Python exception.
pub(crate) fn to_py<E: Classify>(e: E) -> PyErr {
    raise(e.kind(), e.to_string())
}

/// Bad input found by the bindings themselves (`InvalidInputError`).
pub(crate) fn invalid(message: impl Into<String>) -> PyErr {
    raise(Kind::Input, message)
}
