//! The crate's single error type. Every fallible public function returns [`Result`].

use std::path::PathBuf;

/// Errors of `skin-core`. Each variant says what went wrong and, where possible, what to do.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// A file could not be read or written.
    #[error("I/O error on {path}: {source}; check that the path exists and can be read (or its folder written)")]
    Io {
        /// The file concerned.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// A file or string is malformed.
    #[error("malformed {format} input at line {line}: {message}; correct the input there or export it again")]
    Parse {
        /// Format name, e.g. "OBJ", "PLY", "BVH".
        format: &'static str,
        /// 1-based line number (0 when not applicable, e.g. binary data).
        line: usize,
        /// What was wrong.
        message: String,
    },
    /// Two inputs that must agree in size do not.
    #[error(
        "size mismatch in {what}: expected {expected}, got {got}; give inputs whose sizes agree"
    )]
    SizeMismatch {
        /// What was being compared.
        what: &'static str,
        /// The expected size.
        expected: usize,
        /// The size given.
        got: usize,
    },
    /// An input contained NaN or infinity.
    #[error("non-finite value in {what}; replace NaN and infinite values with finite ones")]
    NonFinite {
        /// Which input.
        what: &'static str,
    },
    /// An index points outside its array.
    #[error("index {index} out of range in {what} (length {len}); use an index below {len}")]
    IndexOutOfRange {
        /// Which index array.
        what: &'static str,
        /// The offending index.
        index: usize,
        /// The valid length.
        len: usize,
    },
    /// Geometry is degenerate (zero-area triangle, coincident points, zero-length axis...).
    #[error("degenerate input: {what}; remove or repair the degenerate elements")]
    Degenerate {
        /// What is degenerate.
        what: String,
    },
    /// An input that must not be empty is empty (mask, point set, mesh...).
    #[error("empty input: {what}; give at least one element")]
    Empty {
        /// Which input.
        what: &'static str,
    },
    /// A linear system or calibration problem is singular or ill-posed.
    #[error("singular problem: {what}; add data that determines every unknown")]
    Singular {
        /// Why it is singular, e.g. "coplanar calibration points".
        what: String,
    },
    /// A parameter is outside its valid range.
    #[error("invalid parameter {name}: {reason}; set {name} within its documented range")]
    InvalidParam {
        /// Parameter name.
        name: &'static str,
        /// Valid range or reason.
        reason: String,
    },
    /// Nothing relevant is visible (a camera that sees no point, a ray that hits nothing...).
    #[error("nothing visible: {what}; point the cameras at the subject or move it into view")]
    NotVisible {
        /// What could not be seen.
        what: String,
    },
    /// An iterative method failed to converge.
    #[error("no convergence in {what} after {iterations} iterations; raise the iteration limit or start nearer the solution")]
    NoConvergence {
        /// Which method.
        what: &'static str,
        /// Iterations performed.
        iterations: usize,
    },
    /// An image could not be encoded or decoded.
    #[error("image error: {0}; check the image file's format, size and channels")]
    Image(#[from] ::image::ImageError),
    /// An error that happened while handling one element (a frame, a camera, a vertex...);
    /// nested contexts read outside in, e.g. "frame 12: camera 3: nothing visible: ...".
    #[error("{at}: {source}")]
    At {
        /// Which element was being handled.
        at: Context,
        /// What went wrong there.
        #[source]
        source: Box<Error>,
    },
}

/// The element an [`Error::At`] happened in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum Context {
    /// A frame of a sequence (capture, motion), by index.
    Frame(usize),
    /// A camera of a rig, by index.
    Camera(usize),
    /// A vertex of a mesh, by index.
    Vertex(usize),
    /// A face (triangle) of a mesh, by index.
    Face(usize),
    /// A joint of a skeleton, by index.
    Joint(usize),
}

impl std::fmt::Display for Context {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Context::Frame(i) => write!(f, "frame {i}"),
            Context::Camera(i) => write!(f, "camera {i}"),
            Context::Vertex(i) => write!(f, "vertex {i}"),
            Context::Face(i) => write!(f, "face {i}"),
            Context::Joint(i) => write!(f, "joint {i}"),
        }
    }
}

/// Attaches a [`Context`] to the error of a [`Result`]: `render(cam).at(Context::Camera(i))?`.
pub trait ResultExt<T> {
    /// Wraps an error in [`Error::At`] with `at`; passes `Ok` through.
    fn at(self, at: Context) -> Result<T>;
}

impl<T, E: Into<Error>> ResultExt<T> for std::result::Result<T, E> {
    fn at(self, at: Context) -> Result<T> {
        self.map_err(|e| Error::At {
            at,
            source: Box::new(e.into()),
        })
    }
}

/// Result type of `skin-core`.
pub type Result<T> = std::result::Result<T, Error>;

impl Error {
    /// The innermost error, below every [`Error::At`] context.
    pub fn root(&self) -> &Error {
        match self {
            Error::At { source, .. } => source.root(),
            e => e,
        }
    }

    /// Wraps an I/O error with the path it concerns.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            source,
        }
    }
}
