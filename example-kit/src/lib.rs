//! Development support shared by the tests, examples and benches of `dynamic-shapes`. Not
//! published: the libraries never read it, they take every path from their caller.
//!
//! [`data_path`] locates the small real data sets that ship with the repository in `data/`
//! (meshes, motion capture, sensor and face recordings, each with its `SOURCE.md` and
//! licence).

use std::path::PathBuf;

/// The repository's `data/` folder.
pub fn data_dir() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../data"))
}

/// The path of `relative` (e.g. `"makehuman/base.obj"`) inside [`data_dir`].
///
/// # Errors
/// `NotFound` naming the path tried when the file does not exist (a checkout without its
/// `data/` folder).
pub fn data_path(relative: &str) -> std::io::Result<PathBuf> {
    let path = data_dir().join(relative);
    if path.exists() {
        Ok(path)
    } else {
        Err(std::io::Error::new(
            std::io::ErrorKind::NotFound,
            format!(
                "data file {} not found: the repository's data/ folder is incomplete",
                path.display()
            ),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_the_shipped_data_and_names_missing_files() {
        for rel in [
            "makehuman/base.obj",
            "mocap-cmu/131_01.bvh",
            "imu-broad/07_undisturbed_fast_rotation_B_first60s.csv",
            "imu-xio/sensor_data.csv",
            "ict-face/neutral_face.obj",
        ] {
            assert!(data_path(rel).is_ok(), "{rel}");
        }
        let err = data_path("no/such/file.txt").unwrap_err();
        assert!(err.to_string().contains("no/such/file.txt"));
    }
}
