//! Input checks shared by every crate of `dynamic-shapes`: finite, positive, in range, index
//! in bounds. Each returns the checked value on success, so a constructor reads
//! `let sigma = check::positive("sigma_m", sigma)?;`, and a clear [`Error`] naming the input
//! otherwise. Method crates convert these errors with their `From<skin_core::Error>`.

use std::ops::RangeInclusive;

use crate::{Error, Result};

/// `v` if it is finite, else [`Error::NonFinite`] naming `what`.
pub fn finite(what: &'static str, v: f64) -> Result<f64> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(Error::NonFinite { what })
    }
}

/// `Ok` if every value is finite, else [`Error::NonFinite`] naming `what`.
pub fn all_finite<'a>(what: &'static str, values: impl IntoIterator<Item = &'a f64>) -> Result<()> {
    if values.into_iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(Error::NonFinite { what })
    }
}

/// `v` if it is finite and > 0, else [`Error::InvalidParam`] naming `name` and the value.
pub fn positive(name: &'static str, v: f64) -> Result<f64> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(invalid(
            name,
            format!("must be finite and positive, got {v}"),
        ))
    }
}

/// `v` if it is finite and ≥ 0, else [`Error::InvalidParam`] naming `name` and the value.
pub fn non_negative(name: &'static str, v: f64) -> Result<f64> {
    if v.is_finite() && v >= 0.0 {
        Ok(v)
    } else {
        Err(invalid(name, format!("must be finite and ≥ 0, got {v}")))
    }
}

/// `v` if it is finite and inside `range` (both ends included), else [`Error::InvalidParam`]
/// naming `name`, the range and the value.
pub fn in_range(name: &'static str, v: f64, range: RangeInclusive<f64>) -> Result<f64> {
    if v.is_finite() && range.contains(&v) {
        Ok(v)
    } else {
        Err(invalid(
            name,
            format!("must lie in [{}, {}], got {v}", range.start(), range.end()),
        ))
    }
}

/// `n` if it is at least 1, else [`Error::InvalidParam`] naming `name`.
pub fn nonzero(name: &'static str, n: usize) -> Result<usize> {
    if n > 0 {
        Ok(n)
    } else {
        Err(invalid(name, "must be ≥ 1, got 0".into()))
    }
}

/// `index` if it is `< len`, else [`Error::IndexOutOfRange`] naming `what`.
pub fn index(what: &'static str, index: usize, len: usize) -> Result<usize> {
    if index < len {
        Ok(index)
    } else {
        Err(Error::IndexOutOfRange { what, index, len })
    }
}

/// `Ok` if `got == expected`, else [`Error::SizeMismatch`] naming `what`.
pub fn same_size(what: &'static str, expected: usize, got: usize) -> Result<()> {
    if expected == got {
        Ok(())
    } else {
        Err(Error::SizeMismatch {
            what,
            expected,
            got,
        })
    }
}

fn invalid(name: &'static str, reason: String) -> Error {
    Error::InvalidParam { name, reason }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn accepts_good_values_and_names_bad_ones() {
        assert_eq!(finite("x", 1.5).ok(), Some(1.5));
        assert!(matches!(
            finite("x", f64::NAN),
            Err(Error::NonFinite { what: "x" })
        ));
        assert!(all_finite("v", &[1.0, 2.0]).is_ok());
        assert!(all_finite("v", &[1.0, f64::INFINITY]).is_err());
        assert_eq!(positive("s", 2.0).ok(), Some(2.0));
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let e = positive("s", bad).unwrap_err().to_string();
            assert!(e.contains("invalid parameter s"), "{e}");
        }
        assert!(non_negative("t", 0.0).is_ok());
        assert!(non_negative("t", -1e-9).is_err());
        assert!(in_range("p", 0.5, 0.0..=1.0).is_ok());
        assert!(in_range("p", 1.5, 0.0..=1.0)
            .unwrap_err()
            .to_string()
            .contains("[0, 1]"));
        assert!(in_range("p", f64::NAN, 0.0..=1.0).is_err());
        assert_eq!(nonzero("n", 3).ok(), Some(3));
        assert!(nonzero("n", 0).is_err());
        assert_eq!(index("faces", 2, 3).ok(), Some(2));
        assert!(matches!(
            index("faces", 3, 3),
            Err(Error::IndexOutOfRange {
                what: "faces",
                index: 3,
                len: 3
            })
        ));
        assert!(same_size("a", 2, 2).is_ok());
        assert!(same_size("a", 2, 3).is_err());
    }
}
