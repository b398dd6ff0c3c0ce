//! The crate's single error type, [`Error`], and the [`Context`] that locates an error in a
//! loop over frames, sensor boards or ultrasonic sources ([`Error::At`], attached with
//! [`ResultExt::at`]).

skin_core::method_error!("inertial-acoustic", Context, {
    /// A sensor or source is attached to a joint the skeleton does not have.
    #[error("missing bone: {what} '{name}' is not a joint of the skeleton; attach it to one of the skeleton's joints")]
    MissingBone {
        /// Which attachment.
        what: &'static str,
        /// The joint name asked for.
        name: String,
    },
    /// An encoded inertial frame could not be decoded (more bit errors than the code
    /// corrects).
    #[error("corrupted inertial frame: {what}; treat the frame as lost, or lower the link's bit error rate")]
    Corrupted {
        /// What failed.
        what: &'static str,
    },
    /// A file is not HDF5, or lacks a dataset or attribute BROAD's layout has (or has it in
    /// another shape or type), or its datasets disagree in length.
    #[error("cannot read {path} as a BROAD trial: {message}; give one of BROAD's HDF5 files or an excerpt in its layout (imu_gyr, imu_acc N × 3, opt_quat N × 4, movement N; root attribute sampling_rate)")]
    Hdf5 {
        /// The file.
        path: std::path::PathBuf,
        /// What is wrong with it.
        message: String,
    },
});

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
