//! The crate's single error type, [`Error`]; an error inside a loop over frames, cameras,
//! vertices or joints says where ([`Error::At`] with a [`Context`], attached with
//! [`ResultExt::at`]). Declared by [`skin_core::method_error!`] like every method crate's.

pub use skin_core::Context;

skin_core::method_error!("template-silhouette", Context, {});
