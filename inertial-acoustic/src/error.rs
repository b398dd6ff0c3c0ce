//! The crate's single error type, [`Error`], and the [`Context`] that locates an error in a
//! loop over frames, sensor boards or ultrasonic sources ([`Error::At`], attached with
//! [`ResultExt::at`]).

/// Errors of `inertial-acoustic`.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// An error from `skin-core` (skeleton, checks...).
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
    /// An input that must not be empty is empty.
    #[error("empty input: {what}")]
    Empty {
        /// Which input.
        what: &'static str,
    },
    /// An index points outside its array (a sensor, source or joint index).
    #[error("index {index} out of range in {what} (length {len})")]
    IndexOutOfRange {
        /// Which index.
        what: &'static str,
        /// The offending index.
        index: usize,
        /// The valid length.
        len: usize,
    },
    /// A sensor or source is attached to a joint the skeleton does not have.
    #[error("missing bone: {what} '{name}' is not a joint of the skeleton")]
    MissingBone {
        /// Which attachment.
        what: &'static str,
        /// The joint name asked for.
        name: String,
    },
    /// An encoded inertial frame could not be decoded (more bit errors than the code
    /// corrects).
    #[error("corrupted inertial frame: {what}")]
    Corrupted {
        /// What failed.
        what: &'static str,
    },
    /// An error that happened while handling one element (a frame, a sensor board, a source);
    /// nested contexts read outside in, e.g. "frame 12: sensor 3: non-finite value in ...".
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

    /// The contexts from the outside in, e.g. `[Frame(12), Sensor(3)]`.
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

/// The element an [`Error::At`] happened in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum Context {
    /// A frame of a sequence (140 Hz inertial frames or 8 ms pulse slots), by index.
    Frame(usize),
    /// A sensor board of the suit, by index.
    Sensor(usize),
    /// An ultrasonic source of the suit, by index.
    Source(usize),
}

impl std::fmt::Display for Context {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Context::Frame(i) => write!(f, "frame {i}"),
            Context::Sensor(i) => write!(f, "sensor {i}"),
            Context::Source(i) => write!(f, "source {i}"),
        }
    }
}

/// Attaches a [`Context`] to the error of a [`Result`]: `step(k).at(Context::Frame(k))?`.
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

/// Result type of `inertial-acoustic`.
pub type Result<T> = std::result::Result<T, Error>;
