//! Sub-pixel sampling of single-channel images (distance fields, depth maps): bilinear value and
//! gradient at a continuous image position.
//!
//! Silhouette fitting evaluates distance fields at projected model points (Vlasic 2010 §2.3.2)
//! and needs their gradient for Jacobians; bilinear interpolation of the exact distance
//! transform is continuous and piecewise smooth, which suits Gauss–Newton steps.
//! Pixel centres are at integer coordinates (see [`crate::image::Mask`]).

use serde::{Deserialize, Serialize};

use super::distance::GrayF32Image;
use crate::math::DVec2;

/// A bilinearly interpolated value with its gradient.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct BilinearSample {
    /// Interpolated value, in the image's units.
    pub value: f64,
    /// `(∂value/∂x, ∂value/∂y)`, image units per pixel (one-sided at cell borders).
    pub gradient: DVec2,
}

/// The four samples around `p` and the fractions `(fx, fy)`, read from the raw buffer (the
/// hot path of every bilinear look-up: no per-pixel accessor); `None` as for
/// [`sample_bilinear_with_gradient`].
#[inline]
fn corners(image: &GrayF32Image, p: DVec2) -> Option<([f64; 4], f64, f64)> {
    let (w, h) = image.dimensions();
    if w == 0 || h == 0 || !p.is_finite() {
        return None;
    }
    let (max_x, max_y) = (f64::from(w - 1), f64::from(h - 1));
    if p.x < 0.0 || p.y < 0.0 || p.x > max_x || p.y > max_y {
        return None;
    }
    // Cell corner: the last cell is [w−2, w−1] so that p.x = w−1 gives fx = 1. Truncation
    // equals the floor for the non-negative coordinates that passed the bounds test, without
    // the `floor` library call of the baseline x86-64 target (the visual hull's per-cell test
    // in photometric matching samples here).
    let x0 = (p.x as u32).min(w.saturating_sub(2));
    let y0 = (p.y as u32).min(h.saturating_sub(2));
    let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
    let (fx, fy) = (p.x - f64::from(x0), p.y - f64::from(y0));
    let data: &[f32] = image.as_raw();
    let at = |x: u32, y: u32| {
        data.get(y as usize * w as usize + x as usize)
            .map_or(f64::NAN, |v| f64::from(*v))
    };
    let v = [at(x0, y0), at(x1, y0), at(x0, y1), at(x1, y1)];
    if !v.iter().all(|v| v.is_finite()) {
        return None;
    }
    Some((v, fx, fy))
}

/// Bilinear value and gradient of `image` at `p` (pixels, centres at integers).
///
/// Returns `None` if `p` is not finite, lies outside `[0, w−1] × [0, h−1]`, or one of the four
/// samples used is NaN or infinite (e.g. "no data" in a depth map).
pub fn sample_bilinear_with_gradient(image: &GrayF32Image, p: DVec2) -> Option<BilinearSample> {
    let ([v00, v10, v01, v11], fx, fy) = corners(image, p)?;
    let value = v00 * (1.0 - fx) * (1.0 - fy)
        + v10 * fx * (1.0 - fy)
        + v01 * (1.0 - fx) * fy
        + v11 * fx * fy;
    let gradient = DVec2::new(
        (1.0 - fy) * (v10 - v00) + fy * (v11 - v01),
        (1.0 - fx) * (v01 - v00) + fx * (v11 - v10),
    );
    Some(BilinearSample { value, gradient })
}

/// Bilinear value of `image` at `p`; `None` as for [`sample_bilinear_with_gradient`].
#[inline]
pub fn sample_bilinear(image: &GrayF32Image, p: DVec2) -> Option<f64> {
    let ([v00, v10, v01, v11], fx, fy) = corners(image, p)?;
    Some(
        v00 * (1.0 - fx) * (1.0 - fy)
            + v10 * fx * (1.0 - fy)
            + v01 * (1.0 - fx) * fy
            + v11 * fx * fy,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use ::image::Luma;
    use proptest::prelude::*;

    fn bumpy() -> GrayF32Image {
        GrayF32Image::from_fn(9, 7, |x, y| Luma([((x * 7 + y * 13) % 11) as f32 * 0.3]))
    }

    #[test]
    fn reproduces_affine_functions_and_samples() {
        let img = GrayF32Image::from_fn(6, 5, |x, y| Luma([2.0 * x as f32 - 3.0 * y as f32 + 1.0]));
        for p in [
            DVec2::new(0.0, 0.0),
            DVec2::new(2.3, 1.7),
            DVec2::new(5.0, 4.0),
            DVec2::new(5.0, 0.2),
        ] {
            let s = sample_bilinear_with_gradient(&img, p).unwrap();
            assert!((s.value - (2.0 * p.x - 3.0 * p.y + 1.0)).abs() < 1e-9);
            assert!((s.gradient - DVec2::new(2.0, -3.0)).length() < 1e-9);
        }
        let b = bumpy();
        assert_eq!(
            sample_bilinear(&b, DVec2::new(3.0, 2.0)),
            Some(f64::from(b.get_pixel(3, 2).0[0]))
        );
    }

    #[test]
    fn outside_nan_and_degenerate_inputs_give_none() {
        let mut b = bumpy();
        assert_eq!(sample_bilinear(&b, DVec2::new(-0.01, 1.0)), None);
        assert_eq!(sample_bilinear(&b, DVec2::new(8.01, 1.0)), None);
        assert_eq!(sample_bilinear(&b, DVec2::new(f64::NAN, 1.0)), None);
        b.put_pixel(4, 4, Luma([f32::NAN]));
        assert_eq!(sample_bilinear(&b, DVec2::new(3.5, 3.5)), None);
        assert!(sample_bilinear(&b, DVec2::new(1.5, 1.5)).is_some());
        assert_eq!(sample_bilinear(&GrayF32Image::new(0, 0), DVec2::ZERO), None);
        // A single pixel image is sampled at its centre only, with zero gradient.
        let one = GrayF32Image::from_pixel(1, 1, Luma([4.0]));
        let s = sample_bilinear_with_gradient(&one, DVec2::ZERO).unwrap();
        assert_eq!((s.value, s.gradient), (4.0, DVec2::ZERO));
    }

    proptest! {
        #[test]
        fn gradient_matches_finite_differences(x in 0.05f64..7.95, y in 0.05f64..5.95) {
            let b = bumpy();
            let p = DVec2::new(x, y);
            // Stay inside one cell so the interpolant is smooth.
            prop_assume!((x.fract() - 0.5).abs() < 0.45 && (y.fract() - 0.5).abs() < 0.45);
            let s = sample_bilinear_with_gradient(&b, p).unwrap();
            let h = 1e-6;
            let f = |q: DVec2| sample_bilinear(&b, q).unwrap();
            let gx = (f(p + DVec2::X * h) - f(p - DVec2::X * h)) / (2.0 * h);
            let gy = (f(p + DVec2::Y * h) - f(p - DVec2::Y * h)) / (2.0 * h);
            prop_assert!((gx - s.gradient.x).abs() < 1e-5 && (gy - s.gradient.y).abs() < 1e-5);
        }
    }
}
