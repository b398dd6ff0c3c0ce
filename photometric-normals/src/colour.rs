//! Photometric calibration: a 3 × 3 colour transfer matrix per camera from a colour chart
//! (Vlasic 2010 §3.2.1: "We photometrically calibrate the cameras by capturing a Macbeth Color
//! Checker under uniform illumination and then solve for the optimal color transfer matrix for
//! each camera").
//!
//! Given the chart's patches as a camera sees them (`o_i`, linear RGB, averaged over each
//! patch) and their known reference colours (`r_i`), the matrix `M` minimises
//! `Σ_i ‖M o_i − r_i‖²` (linear least squares, solved by SVD: `Mᵀ = O⁺ R` with the patches as
//! rows). A chart that does not span colour space (fewer than three patches, or patches on a
//! plane such as greys only) leaves `M` undetermined and is an error.

use image::Rgb32FImage;
use nalgebra::{DMatrix, Matrix3, Vector3};
use serde::{Deserialize, Serialize};

use crate::{Error, Result};

/// The 24 patches of the Macbeth ColorChecker as linear RGB (the published sRGB 8-bit values
/// of the chart, row by row from "dark skin" to "black", linearised with the sRGB transfer
/// curve). A reference for [`ColourTransfer::fit`].
pub fn macbeth_reference() -> Vec<[f64; 3]> {
    const SRGB8: [[u8; 3]; 24] = [
        [115, 82, 68],
        [194, 150, 130],
        [98, 122, 157],
        [87, 108, 67],
        [133, 128, 177],
        [103, 189, 170],
        [214, 126, 44],
        [80, 91, 166],
        [193, 90, 99],
        [94, 60, 108],
        [157, 188, 64],
        [224, 163, 46],
        [56, 61, 150],
        [70, 148, 73],
        [175, 54, 60],
        [231, 199, 31],
        [187, 86, 149],
        [8, 133, 161],
        [243, 243, 242],
        [200, 200, 200],
        [160, 160, 160],
        [122, 122, 121],
        [85, 85, 85],
        [52, 52, 52],
    ];
    let linear = |v: u8| {
        let c = f64::from(v) / 255.0;
        if c <= 0.04045 {
            c / 12.92
        } else {
            ((c + 0.055) / 1.055).powf(2.4)
        }
    };
    SRGB8.iter().map(|p| p.map(linear)).collect()
}

/// Parameters of [`ColourTransfer::fit`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ColourParams {
    /// Largest ratio of the observed patches' largest to smallest singular value (of the
    /// patches-by-channels matrix) accepted; a larger one means the chart does not span colour
    /// space and the matrix is undetermined. Default 1e4 (ours; the Macbeth chart has ≈ 10).
    pub max_condition: f64,
}

impl Default for ColourParams {
    fn default() -> Self {
        ColourParams { max_condition: 1e4 }
    }
}

/// A camera's 3 × 3 colour transfer matrix: reference colour ≈ `M` × observed colour.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ColourTransfer {
    /// Row-major `M`.
    matrix: [[f64; 3]; 3],
    /// RMS residual `‖M o_i − r_i‖` over the chart's patches.
    residual_rms: f64,
}

impl ColourTransfer {
    /// Fits `M` to a chart: `observed[i]` is patch `i` as the camera saw it, `reference[i]` its
    /// known colour (linear RGB).
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] if the lists differ in length; [`Error::Empty`] for fewer than
    /// three patches; [`Error::NonFinite`] for NaN or infinite colours;
    /// [`Error::InvalidParam`] if the observed patches do not span colour space (condition
    /// number above [`ColourParams::max_condition`]) or for a bad parameter.
    pub fn fit(
        observed: &[[f64; 3]],
        reference: &[[f64; 3]],
        params: &ColourParams,
    ) -> Result<Self> {
        skin_core::check::positive("max_condition", params.max_condition)?;
        skin_core::check::same_size("colour chart patches", observed.len(), reference.len())?;
        if observed.len() < 3 {
            return Err(Error::Empty {
                what: "colour chart (at least three patches)",
            });
        }
        skin_core::check::all_finite("observed patch colours", observed.iter().flatten())?;
        skin_core::check::all_finite("reference patch colours", reference.iter().flatten())?;
        let n = observed.len();
        let o = DMatrix::from_fn(n, 3, |i, c| observed[i][c]);
        let r = DMatrix::from_fn(n, 3, |i, c| reference[i][c]);
        let svd = o.clone().svd(true, true);
        let sv = &svd.singular_values;
        let (max, min) = (sv.max(), sv.min());
        if !(min > 0.0 && max / min <= params.max_condition) {
            return Err(Error::InvalidParam {
                name: "colour chart",
                reason: format!(
                    "the observed patches do not span colour space (singular values {:.3e} … \
                     {:.3e}); use a chart with saturated colours",
                    max, min
                ),
            });
        }
        let mt = svd.solve(&r, 0.0).map_err(|e| Error::InvalidParam {
            name: "colour chart",
            reason: e.to_string(),
        })?;
        let matrix = [0, 1, 2].map(|row| [0, 1, 2].map(|col| mt[(col, row)]));
        let fitted = &o * &mt;
        let residual_rms = ((&fitted - &r).norm_squared() / n as f64).sqrt();
        Ok(ColourTransfer {
            matrix,
            residual_rms,
        })
    }

    /// A transfer from a known matrix (row-major).
    ///
    /// # Errors
    /// [`Error::NonFinite`] for NaN or infinite entries.
    pub fn from_matrix(matrix: [[f64; 3]; 3]) -> Result<Self> {
        skin_core::check::all_finite("colour transfer matrix", matrix.iter().flatten())?;
        Ok(ColourTransfer {
            matrix,
            residual_rms: 0.0,
        })
    }

    /// The row-major matrix `M`.
    pub fn matrix(&self) -> [[f64; 3]; 3] {
        self.matrix
    }

    /// RMS residual over the chart it was fitted to (linear RGB units).
    pub fn residual_rms(&self) -> f64 {
        self.residual_rms
    }

    /// `M × rgb`.
    pub fn apply_rgb(&self, rgb: [f64; 3]) -> [f64; 3] {
        let m = Matrix3::from_fn(|r, c| self.matrix[r][c]);
        let v = m * Vector3::from(rgb);
        [v.x, v.y, v.z]
    }

    /// The image with every pixel mapped through `M`.
    pub fn apply(&self, image: &Rgb32FImage) -> Rgb32FImage {
        let m = self.matrix.map(|row| row.map(|v| v as f32));
        let mut out = image.clone();
        for p in out.pixels_mut() {
            let v = p.0;
            p.0 = [0, 1, 2].map(|r| m[r][0] * v[0] + m[r][1] * v[1] + m[r][2] * v[2]);
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A camera's mixing (crosstalk between channels, per-channel gains).
    const MIX: [[f64; 3]; 3] = [[0.9, 0.12, 0.03], [0.08, 1.1, 0.1], [0.02, 0.15, 0.75]];

    fn observe(reference: &[[f64; 3]], noise: f64) -> Vec<[f64; 3]> {
        reference
            .iter()
            .enumerate()
            .map(|(i, r)| {
                [0, 1, 2].map(|row| {
                    let wobble =
                        noise * (((i * 3 + row) as f64 * 12.9898).sin() * 43758.5453).fract();
                    MIX[row][0] * r[0] + MIX[row][1] * r[1] + MIX[row][2] * r[2] + wobble
                })
            })
            .collect()
    }

    #[test]
    fn the_inverse_mixing_is_recovered_from_a_macbeth_chart() {
        let reference = macbeth_reference();
        let observed = observe(&reference, 0.0);
        let t = ColourTransfer::fit(&observed, &reference, &ColourParams::default()).unwrap();
        let inv = Matrix3::from_fn(|r, c| MIX[r][c]).try_inverse().unwrap();
        for r in 0..3 {
            for c in 0..3 {
                assert!((t.matrix()[r][c] - inv[(r, c)]).abs() < 1e-9);
            }
        }
        assert!(t.residual_rms() < 1e-9);
        let back = t.apply_rgb(observed[6]);
        assert!((0..3).all(|c| (back[c] - reference[6][c]).abs() < 1e-9));
    }

    #[test]
    fn degenerate_charts_are_errors() {
        let reference = macbeth_reference();
        let observed = observe(&reference, 0.0);
        let p = ColourParams::default();
        assert!(matches!(
            ColourTransfer::fit(&observed[..2], &reference[..2], &p),
            Err(Error::Empty { .. })
        ));
        // The six greys only: every patch on the grey axis.
        let greys: Vec<[f64; 3]> = reference[18..].iter().map(|g| [g[0]; 3]).collect();
        assert!(matches!(
            ColourTransfer::fit(&greys, &reference[18..], &p),
            Err(Error::InvalidParam { .. })
        ));
        assert!(ColourTransfer::fit(&observed[..5], &reference[..4], &p).is_err());
        let mut nan = observed.clone();
        nan[3][1] = f64::NAN;
        assert!(matches!(
            ColourTransfer::fit(&nan, &reference, &p),
            Err(Error::NonFinite { .. }) | Err(Error::Core(_))
        ));
    }
}
