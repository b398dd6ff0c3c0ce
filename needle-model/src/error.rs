//! The crate's single error type, [`Error`], and the [`Context`] that locates an error in a
//! loop over primitives, needles, cameras or frames ([`Error::At`], attached with
//! [`ResultExt::at`]).

/// Errors of `needle-model`.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// An error from `skin-core` (cameras, images, meshes...).
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
    /// An index points outside its array (a primitive, needle or sample index).
    #[error("index {index} out of range in {what} (length {len})")]
    IndexOutOfRange {
        /// Which index.
        what: &'static str,
        /// The offending index.
        index: usize,
        /// The valid length.
        len: usize,
    },
    /// A needle or primitive has no usable observation (see §5.3 hole filling).
    #[error("no observations: {what}")]
    NoObservations {
        /// Why, e.g. "never observed and no observed needle reachable through the adjacency";
        /// which needle or primitive is in the enclosing [`Error::At`].
        what: String,
    },
    /// An error that happened while handling one element (a primitive, a needle, a camera, a
    /// frame); nested contexts read outside in, e.g.
    /// "primitive 3: needle 17: no observations: ...".
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
    /// The innermost error, below every [`Error::At`] context. A `skin-core` error stays
    /// wrapped in [`Error::Core`]; its own [`skin_core::Error::root`] strips its contexts.
    pub fn root(&self) -> &Error {
        match self {
            Error::At { source, .. } => source.root(),
            e => e,
        }
    }

    /// The name of the invalid parameter if this is an invalid-parameter error, whether raised
    /// here ([`Error::InvalidParam`]) or by [`skin_core::check`] ([`Error::Core`]), below any
    /// contexts.
    pub fn invalid_param_name(&self) -> Option<&'static str> {
        match self.root() {
            Error::InvalidParam { name, .. } => Some(name),
            Error::Core(e) => match e.root() {
                skin_core::Error::InvalidParam { name, .. } => Some(name),
                _ => None,
            },
            _ => None,
        }
    }

    /// The contexts from the outside in, e.g. `[Primitive(3), Needle(17)]`.
    ///
    /// # Example
    /// ```
    /// use needle_model::{prototype_shapes, Context, Error, NeedleObservations};
    /// use needle_model::ReconstructionParams;
    /// // Needle 1 is never observed and has no neighbour to borrow a length from (§5.3).
    /// let obs = NeedleObservations::from_lists(&[vec![(0, 0.05)], vec![]])?;
    /// let adjacency = [vec![], vec![]];
    /// let params = ReconstructionParams::default();
    /// let e = prototype_shapes(&[0.0], 1, &obs, &[0.0], &adjacency, &params).unwrap_err();
    /// assert_eq!(e.contexts(), [Context::Needle(1)]);
    /// assert!(matches!(e.root(), Error::NoObservations { .. }));
    /// assert_eq!(
    ///     e.to_string(),
    ///     "needle 1: no observations: never observed and no observed needle reachable \
    ///      through the adjacency"
    /// );
    /// # Ok::<(), Error>(())
    /// ```
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
    /// A primitive of the body (index into [`crate::NeedleBody::primitives`]).
    Primitive(usize),
    /// A needle of a primitive (ring-major index within the primitive).
    Needle(usize),
    /// A camera of the rig, by index.
    Camera(usize),
    /// A frame of a sequence (capture, validation frames), by index.
    Frame(usize),
}

impl std::fmt::Display for Context {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Context::Primitive(i) => write!(f, "primitive {i}"),
            Context::Needle(i) => write!(f, "needle {i}"),
            Context::Camera(i) => write!(f, "camera {i}"),
            Context::Frame(i) => write!(f, "frame {i}"),
        }
    }
}

/// Attaches a [`Context`] to the error of a [`Result`]:
/// `fit(p).at(Context::Primitive(p))?`. Errors of `skin-core` are converted first.
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

/// Result type of `needle-model`.
pub type Result<T> = std::result::Result<T, Error>;
