//! The crate's single error type, [`Error`]; an error inside a loop over faces, modes or
//! frames says where ([`Error::At`] with a [`Context`], attached with [`ResultExt::at`]).
//! Declared by [`skin_core::method_error!`] like every method crate's.

pub use skin_core::Context;

skin_core::method_error!("multilinear-face", Context, {
    /// Video tracking lost the face: too few tracked vertices passed the KLT checks (the
    /// face left the frame, was covered, or the motion was too fast).
    #[error("face lost: {tracked_fraction:.2} of the visible tracked vertices followed (minimum {min}); restart tracking on a frame that shows the face, or lower min_tracked_fraction")]
    FaceLost {
        /// Fraction of the visible tracked vertices that passed the KLT checks.
        tracked_fraction: f64,
        /// The threshold ([`crate::VideoTrackParams::min_tracked_fraction`]).
        min: f64,
    },
    /// A name the data does not hold: a blendshape that an attribute recipe uses and the
    /// face basis lacks.
    #[error("{what} {name:?} (used by {used_by:?}) is not in the basis; add it to the basis or remove it from {used_by}")]
    UnknownName {
        /// What kind of name (e.g. "blendshape").
        what: &'static str,
        /// The name looked for.
        name: String,
        /// What needed it (e.g. the recipe's name).
        used_by: &'static str,
    },
});
