//! The crate's single error type, [`Error`]; an error inside a loop over frames, cameras or
//! pixels says where ([`Error::At`] with a [`Context`], attached with [`ResultExt::at`]).
//! Declared by [`skin_core::method_error!`] like every method crate's.

pub use skin_core::Context;

skin_core::method_error!("photometric-normals", Context, {
    /// A lighting condition that the computation needs is missing (e.g. a dropped frame of
    /// the 8-frame cycle).
    #[error(
        "missing pattern image: {pattern:?}; give an image for every lighting condition the \
         computation uses (PATTERNS), e.g. skip a cycle that dropped a frame"
    )]
    MissingPattern {
        /// The missing pattern.
        pattern: crate::cycle::Pattern,
    },
    /// A calibration object does not lie entirely inside a camera's view.
    #[error(
        "calibration sphere partly out of view: {reason}; place the sphere so that its whole \
         outline is inside the image and in front of the camera"
    )]
    OutOfView {
        /// What is outside the image.
        reason: String,
    },
});
