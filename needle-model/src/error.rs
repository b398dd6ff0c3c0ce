//! The crate's single error type.

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
    /// A needle or primitive has no usable observation (see §5.3 hole filling).
    #[error("no observations: {what}")]
    NoObservations {
        /// Which needle or primitive.
        what: String,
    },
}

/// Result type of `needle-model`.
pub type Result<T> = std::result::Result<T, Error>;
