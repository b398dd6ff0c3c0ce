//! The crate's single error type, [`Error`]; an error inside a loop over faces, modes or
//! frames says where ([`Error::At`] with a [`Context`], attached with [`ResultExt::at`]).
//! Declared by [`skin_core::method_error!`] like every method crate's.

pub use skin_core::Context;

skin_core::method_error!("multilinear-face", Context, {});
