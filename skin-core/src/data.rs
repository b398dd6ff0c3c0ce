//! Locating the project's small real data sets (meshes, motion capture, sensor data).
//!
//! The data live in `shared/data/` beside the workspace (each set with a `SOURCE.md`). Tests,
//! benches and examples find them through [`shared_data_path`]: the environment variable
//! [`DATA_DIR_ENV`] wins when set (e.g. when the crate is used from elsewhere), otherwise the
//! folder `../shared/data` next to the workspace this crate was built in.

use crate::{Error, Result};
use std::path::PathBuf;

/// Environment variable naming the data folder, overriding the default location.
pub const DATA_DIR_ENV: &str = "DYNAMIC_SHAPES_DATA";

/// The data folder: `$DYNAMIC_SHAPES_DATA`, else `<workspace>/../shared/data`.
pub fn shared_data_dir() -> PathBuf {
    match std::env::var_os(DATA_DIR_ENV) {
        Some(dir) => PathBuf::from(dir),
        None => PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/data")),
    }
}

/// The path of `relative` (e.g. `"makehuman/base.obj"`) inside the data folder.
///
/// # Errors
/// [`Error::Io`] with kind `NotFound` when the file does not exist, naming the path tried and
/// the environment variable that selects another folder.
pub fn shared_data_path(relative: &str) -> Result<PathBuf> {
    let path = shared_data_dir().join(relative);
    if path.exists() {
        Ok(path)
    } else {
        Err(Error::io(
            &path,
            std::io::Error::new(
                std::io::ErrorKind::NotFound,
                format!("data file not found; set {DATA_DIR_ENV} to the shared data folder"),
            ),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_makehuman_and_reports_missing_files() {
        assert!(shared_data_path("makehuman/base.obj").is_ok());
        let err = shared_data_path("no/such/file.txt").unwrap_err();
        assert!(err.to_string().contains(DATA_DIR_ENV));
    }
}
