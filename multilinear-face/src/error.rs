//! The crate's single error type, [`Error`]; an error inside a loop over frames, cameras,
//! vertices or joints says where ([`Error::At`] with a [`Context`], attached with
//! [`ResultExt::at`]).

pub use skin_core::Context;

/// Errors of `multilinear-face`.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// An error from `skin-core` (tensors, meshes, least squares...).
    #[error(transparent)]
    Core(#[from] skin_core::Error),
    /// A parameter is outside its valid range.
    #[error("invalid parameter {name}: {reason}")]
    InvalidParam {
        /// Parameter name.
        name: &'static str,
        /// Valid range or reason.
        reason: String,
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
    /// An input that must not be empty is empty (e.g. no face at all, or an attribute value
    /// none of whose faces is known).
    #[error("empty input: {what}")]
    Empty {
        /// Which input.
        what: &'static str,
    },
    /// An index points outside its array (a vertex, joint or face index).
    #[error("index {index} out of range in {what} (length {len})")]
    IndexOutOfRange {
        /// Which index.
        what: &'static str,
        /// The offending index.
        index: usize,
        /// The valid length.
        len: usize,
    },
    /// An error that happened while handling one element (a frame, a camera, a vertex, a
    /// joint); nested contexts read outside in, e.g. "frame 3: camera 5: empty input: ...".
    #[error("{at}: {source}")]
    At {
        /// Which element was being handled.
        at: Context,
        /// What went wrong there.
        #[source]
        source: Box<Error>,
    },
}

impl Error {
    /// The innermost error, below every [`Error::At`] context.
    pub fn root(&self) -> &Error {
        match self {
            Error::At { source, .. } => source.root(),
            e => e,
        }
    }

    /// The contexts from the outside in, e.g. `[Frame(3), Camera(5)]`.
    pub fn contexts(&self) -> Vec<Context> {
        let mut out = Vec::new();
        let mut e = self;
        while let Error::At { at, source } = e {
            out.push(*at);
            e = source;
        }
        out
    }
}

/// Attaches a [`Context`] to the error of a [`Result`]: `cone(c).at(Context::Camera(c))?`.
/// Errors of `skin-core` are converted first.
pub trait ResultExt<T> {
    /// Wraps an error in [`Error::At`] with `at`; passes `Ok` through.
    ///
    /// # Errors
    /// The error of `self`, wrapped.
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

/// Result type of `multilinear-face`.
pub type Result<T> = std::result::Result<T, Error>;
