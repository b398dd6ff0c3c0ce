//! The crate's single error type, [`Error`], and the [`Context`] that locates an error in a
//! loop over primitives, needles, cameras or frames ([`Error::At`], attached with
//! [`ResultExt::at`]).
//! Declared by [`skin_core::method_error!`] like every method crate's. A `skin-core` error
//! stays wrapped in [`Error::Core`] by [`Error::root`]; its own [`skin_core::Error::root`]
//! strips its contexts.
//!
//! # Example: where an error happened
//! ```
//! use needle_model::{prototype_shapes, Context, Error, NeedleObservations};
//! use needle_model::ReconstructionParams;
//! // Needle 1 is never observed and has no neighbour to borrow a length from (§5.3).
//! let obs = NeedleObservations::from_lists(&[vec![(0, 0.05)], vec![]])?;
//! let adjacency = [vec![], vec![]];
//! let params = ReconstructionParams::default();
//! let e = prototype_shapes(&[0.0], 1, &obs, &[0.0], &adjacency, &params).unwrap_err();
//! assert_eq!(e.contexts(), [Context::Needle(1)]);
//! assert!(matches!(e.root(), Error::NoObservations { .. }));
//! assert_eq!(
//!     e.to_string(),
//!     "needle 1: no observations: never observed and no observed needle reachable \
//!      through the adjacency; capture more frames or cameras that see it"
//! );
//! # Ok::<(), Error>(())
//! ```

skin_core::method_error!("needle-model", Context, {
    /// A needle or primitive has no usable observation (see §5.3 hole filling).
    #[error("no observations: {what}; capture more frames or cameras that see it")]
    NoObservations {
        /// Why, e.g. "never observed and no observed needle reachable through the adjacency";
        /// which needle or primitive is in the enclosing [`Error::At`].
        what: String,
    },
});

impl Error {
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
