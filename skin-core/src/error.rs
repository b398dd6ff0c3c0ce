//! The crate's single error type. Every fallible public function returns [`Result`].

use std::path::PathBuf;

/// Errors of `skin-core`. Each variant says what went wrong and, where possible, what to do.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// A file could not be read or written.
    #[error("I/O error on {path}: {source}")]
    Io {
        /// The file concerned.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// A file or string is malformed.
    #[error("malformed {format} input at line {line}: {message}")]
    Parse {
        /// Format name, e.g. "OBJ", "PLY", "BVH".
        format: &'static str,
        /// 1-based line number (0 when not applicable, e.g. binary data).
        line: usize,
        /// What was wrong.
        message: String,
    },
    /// Two inputs that must agree in size do not.
    #[error("size mismatch in {what}: expected {expected}, got {got}")]
    SizeMismatch {
        /// What was being compared.
        what: &'static str,
        /// The expected size.
        expected: usize,
        /// The size given.
        got: usize,
    },
    /// An input contained NaN or infinity.
    #[error("non-finite value in {what}")]
    NonFinite {
        /// Which input.
        what: &'static str,
    },
    /// An index points outside its array.
    #[error("index {index} out of range in {what} (length {len})")]
    IndexOutOfRange {
        /// Which index array.
        what: &'static str,
        /// The offending index.
        index: usize,
        /// The valid length.
        len: usize,
    },
    /// Geometry is degenerate (zero-area triangle, coincident points, zero-length axis...).
    #[error("degenerate input: {what}")]
    Degenerate {
        /// What is degenerate.
        what: String,
    },
    /// An input that must not be empty is empty (mask, point set, mesh...).
    #[error("empty input: {what}")]
    Empty {
        /// Which input.
        what: &'static str,
    },
    /// A linear system or calibration problem is singular or ill-posed.
    #[error("singular problem: {what}")]
    Singular {
        /// Why it is singular, e.g. "coplanar calibration points".
        what: String,
    },
    /// A parameter is outside its valid range.
    #[error("invalid parameter {name}: {reason}")]
    InvalidParam {
        /// Parameter name.
        name: &'static str,
        /// Valid range or reason.
        reason: String,
    },
    /// Nothing relevant is visible (a camera that sees no point, a ray that hits nothing...).
    #[error("nothing visible: {what}")]
    NotVisible {
        /// What could not be seen.
        what: String,
    },
    /// An iterative method failed to converge.
    #[error("no convergence in {what} after {iterations} iterations")]
    NoConvergence {
        /// Which method.
        what: &'static str,
        /// Iterations performed.
        iterations: usize,
    },
    /// An image could not be encoded or decoded.
    #[error("image error: {0}")]
    Image(#[from] ::image::ImageError),
}

/// Result type of `skin-core`.
pub type Result<T> = std::result::Result<T, Error>;

impl Error {
    /// Wraps an I/O error with the path it concerns.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            source,
        }
    }
}

/// Returns [`Error::NonFinite`] unless every value is finite.
pub fn ensure_finite<'a>(
    what: &'static str,
    values: impl IntoIterator<Item = &'a f64>,
) -> Result<()> {
    if values.into_iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(Error::NonFinite { what })
    }
}

/// Returns [`Error::InvalidParam`] naming `name` unless `v` is finite and > 0.
pub(crate) fn ensure_positive(name: &'static str, v: f64) -> Result<()> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(Error::InvalidParam {
            name,
            reason: format!("must be finite and positive, got {v}"),
        })
    }
}
