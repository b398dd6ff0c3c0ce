//! [`method_error!`](crate::method_error): the `Error` enum, `ResultExt` and `Result` every
//! method crate declares (ARCHITECTURE.md, "Errors"), written once.

/// Declares a method crate's error type in its `error.rs`: `Error` (`thiserror`) with
/// `Core(#[from] skin_core::Error)`, `InvalidParam`, `SizeMismatch`, `NonFinite`, `Empty`,
/// `IndexOutOfRange`, the crate's own variants, and `At { at, source }` locating an error in
/// a loop; `Error::root` and `Error::contexts`; the trait `ResultExt` with `.at(context)`; and
/// `Result<T>`. The context type is the crate's choice (skin-core's [`Context`](crate::Context)
/// or its own enum with a `Display`).
///
/// The calling crate must depend on `thiserror`.
///
/// For the workspace's method crates (hidden from the docs; not a stable API for others).
///
/// ```
/// mod error {
///     pub use skin_core::Context;
///     skin_core::method_error!("my-method", Context, {
///         /// The crate's own failure.
///         #[error("no signal: {what}")]
///         NoSignal {
///             /// Where.
///             what: &'static str,
///         },
///     });
/// }
/// use error::{Error, ResultExt};
/// let e = Err::<(), _>(Error::NoSignal { what: "source 2" }).at(skin_core::Context::Frame(7));
/// let e = e.unwrap_err();
/// assert_eq!(e.to_string(), "frame 7: no signal: source 2");
/// assert!(matches!(e.root(), Error::NoSignal { .. }));
/// assert_eq!(e.contexts(), [skin_core::Context::Frame(7)]);
/// ```
#[doc(hidden)]
#[macro_export]
macro_rules! method_error {
    ($krate:literal, $context:ty, { $($variants:tt)* }) => {
        #[doc = concat!("Errors of `", $krate, "`.")]
        #[derive(Debug, thiserror::Error)]
        #[non_exhaustive]
        pub enum Error {
            /// An error from `skin-core`.
            #[error(transparent)]
            Core(#[from] $crate::Error),
            /// A parameter is outside its valid range.
            #[error("invalid parameter {name}: {reason}; set {name} within its documented range")]
            InvalidParam {
                /// Parameter name.
                name: &'static str,
                /// Valid range or reason.
                reason: String,
            },
            /// Two inputs that must agree in size do not.
            #[error("size mismatch in {what}: expected {expected}, got {got}; give inputs whose sizes agree")]
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
            /// An input that must not be empty is empty.
            #[error("empty input: {what}; give at least one element")]
            Empty {
                /// Which input.
                what: &'static str,
            },
            /// An index points outside its array.
            #[error("index {index} out of range in {what} (length {len}); use an index below {len}")]
            IndexOutOfRange {
                /// Which index.
                what: &'static str,
                /// The offending index.
                index: usize,
                /// The valid length.
                len: usize,
            },
            $($variants)*
            /// An error that happened while handling one element of a loop; nested contexts
            /// read outside in, e.g. "frame 3: camera 5: empty input: ...; give at least one element".
            #[error("{at}: {source}")]
            At {
                /// Which element was being handled.
                at: $context,
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
            pub fn contexts(&self) -> Vec<$context> {
                let mut out = Vec::new();
                let mut e = self;
                while let Error::At { at, source } = e {
                    out.push(*at);
                    e = source;
                }
                out
            }
        }

        /// Attaches a context to the error of a [`Result`]: `step(i).at(Context::Frame(i))?`.
        /// Errors of `skin-core` are converted first.
        pub trait ResultExt<T> {
            /// Wraps an error in [`Error::At`] with `at`; passes `Ok` through.
            ///
            /// # Errors
            /// The error of `self`, wrapped.
            fn at(self, at: $context) -> Result<T>;
        }

        impl<T, E: Into<Error>> ResultExt<T> for std::result::Result<T, E> {
            fn at(self, at: $context) -> Result<T> {
                self.map_err(|e| Error::At {
                    at,
                    source: Box::new(e.into()),
                })
            }
        }

        #[doc = concat!("Result type of `", $krate, "`.")]
        pub type Result<T> = std::result::Result<T, Error>;
    };
}
