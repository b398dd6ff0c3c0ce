//! Detection of bright retro-reflective markers in a grey image (Fua et al. §2.3): high-pass
//! filter (the image minus its box blur), threshold, 8-connected components, sub-pixel
//! intensity-weighted centroid of each component.

use ::image::{GrayImage, Luma};
use imageproc::filter::box_filter;
use imageproc::region_labelling::{connected_components, Connectivity};

use crate::math::DVec2;
use crate::{Error, Result};

impl MarkerDetectParams {
    /// Default half-width of the box blur whose subtraction is the high-pass filter, px. The box
    /// (2·7 + 1 = 15 px) is several times wider than a marker image (a few px across), so the blur
    /// estimates the local background around a marker.
    pub const DEFAULT_BLUR_RADIUS_PX: u32 = 7;

    /// Default high-pass threshold, grey levels of an 8-bit image (the paper's 8-bit frames).
    pub const DEFAULT_THRESHOLD: u8 = 40;

    /// Default largest accepted blob, px: larger bright regions (specular body parts) are not
    /// markers.
    pub const DEFAULT_MAX_AREA_PX: usize = 200;
}

/// Parameters of [`detect_markers`]. The paper gives no numbers ("high pass filter and then
/// thresholding ... centroid operations"); the defaults suit markers a few pixels across.
#[derive(Debug, Clone, PartialEq)]
pub struct MarkerDetectParams {
    /// Half-width of the box blur subtracted from the image, px (≥ 1).
    pub blur_radius_px: u32,
    /// Smallest high-passed value of a marker pixel, grey levels (≥ 1).
    pub threshold: u8,
    /// Smallest accepted component, px (≥ 1).
    pub min_area_px: usize,
    /// Largest accepted component, px (≥ `min_area_px`).
    pub max_area_px: usize,
}

impl Default for MarkerDetectParams {
    fn default() -> Self {
        Self {
            blur_radius_px: MarkerDetectParams::DEFAULT_BLUR_RADIUS_PX,
            threshold: MarkerDetectParams::DEFAULT_THRESHOLD,
            min_area_px: 1,
            max_area_px: MarkerDetectParams::DEFAULT_MAX_AREA_PX,
        }
    }
}

impl MarkerDetectParams {
    fn validate(&self) -> Result<()> {
        if self.blur_radius_px == 0 {
            return Err(Error::InvalidParam {
                name: "blur_radius_px",
                reason: "must be ≥ 1".into(),
            });
        }
        if self.threshold == 0 {
            return Err(Error::InvalidParam {
                name: "threshold",
                reason: "must be ≥ 1 (0 would accept every pixel)".into(),
            });
        }
        if self.min_area_px == 0 || self.max_area_px < self.min_area_px {
            return Err(Error::InvalidParam {
                name: "min_area_px/max_area_px",
                reason: format!(
                    "need 1 ≤ min ≤ max, got {} and {}",
                    self.min_area_px, self.max_area_px
                ),
            });
        }
        Ok(())
    }
}

/// A detected marker image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MarkerBlob {
    /// Sub-pixel centre, px (pixel centres at integers), weighted by the high-passed intensity.
    pub centre: DVec2,
    /// Number of pixels of the component.
    pub area_px: usize,
    /// Sum of the high-passed intensities of the component, grey levels.
    pub mass: f64,
}

/// High-passed image: `max(0, image − box_blur(image))`.
fn high_pass(image: &GrayImage, radius: u32) -> GrayImage {
    let blurred = box_filter(image, radius, radius);
    GrayImage::from_fn(image.width(), image.height(), |x, y| {
        let v = image.get_pixel(x, y).0[0];
        let b = blurred.get_pixel(x, y).0[0];
        Luma([v.saturating_sub(b)])
    })
}

/// Detects bright markers: high-pass, threshold, 8-connected components, centroid weighted by
/// the high-passed intensity. Blobs are returned in order of their first pixel (row-major).
///
/// # Errors
/// [`Error::Empty`] for an image with no pixels; [`Error::Degenerate`] for an image smaller
/// than 3 × 3 px; [`Error::InvalidParam`] for invalid parameters.
pub fn detect_markers(image: &GrayImage, params: &MarkerDetectParams) -> Result<Vec<MarkerBlob>> {
    params.validate()?;
    let (w, h) = image.dimensions();
    if w == 0 || h == 0 {
        return Err(Error::Empty {
            what: "marker image",
        });
    }
    if w < 3 || h < 3 {
        return Err(Error::Degenerate {
            what: format!("marker image of {w}×{h} px is smaller than 3×3 px"),
        });
    }
    let hp = high_pass(image, params.blur_radius_px);
    let binary = GrayImage::from_fn(w, h, |x, y| {
        Luma([u8::from(hp.get_pixel(x, y).0[0] >= params.threshold)])
    });
    let labels = connected_components(&binary, Connectivity::Eight, Luma([0u8]));
    // Accumulators per label: Σw, Σw·x, Σw·y, area; label 0 is background.
    let mut acc: Vec<(f64, f64, f64, usize)> = Vec::new();
    let mut order: Vec<u32> = Vec::new();
    for (x, y, l) in labels.enumerate_pixels() {
        let l = l.0[0];
        if l == 0 {
            continue;
        }
        let li = l as usize;
        if acc.len() <= li {
            acc.resize(li + 1, (0.0, 0.0, 0.0, 0));
        }
        let wgt = f64::from(hp.get_pixel(x, y).0[0]);
        let a = &mut acc[li];
        if a.3 == 0 {
            order.push(l);
        }
        a.0 += wgt;
        a.1 += wgt * f64::from(x);
        a.2 += wgt * f64::from(y);
        a.3 += 1;
    }
    Ok(order
        .into_iter()
        .filter_map(|l| {
            let (sw, sx, sy, area) = acc[l as usize];
            (area >= params.min_area_px && area <= params.max_area_px && sw > 0.0).then(|| {
                MarkerBlob {
                    centre: DVec2::new(sx / sw, sy / sw),
                    area_px: area,
                    mass: sw,
                }
            })
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A Gaussian spot of peak `amp` over a background `bg` with a horizontal ramp.
    fn spots(w: u32, h: u32, centres: &[DVec2], sigma: f64, amp: f64, bg: f64) -> GrayImage {
        GrayImage::from_fn(w, h, |x, y| {
            let p = DVec2::new(f64::from(x), f64::from(y));
            let mut v = bg + 0.2 * f64::from(x);
            for c in centres {
                v += amp * (-(p - *c).length_squared() / (2.0 * sigma * sigma)).exp();
            }
            Luma([v.round().clamp(0.0, 255.0) as u8])
        })
    }

    #[test]
    fn finds_sub_pixel_centres_better_than_the_brightest_pixel() {
        let centres = [
            DVec2::new(20.3, 15.7),
            DVec2::new(50.55, 40.2),
            DVec2::new(80.8, 12.4),
        ];
        let img = spots(100, 60, &centres, 1.2, 180.0, 40.0);
        let blobs = detect_markers(&img, &MarkerDetectParams::default()).unwrap();
        assert_eq!(blobs.len(), 3);
        for c in centres {
            let b = blobs
                .iter()
                .min_by(|a, b| (a.centre - c).length().total_cmp(&(b.centre - c).length()))
                .unwrap();
            let err = (b.centre - c).length();
            // Baseline: the nearest integer pixel (the brightest one) is off by up to 0.7 px.
            let baseline = (c.round() - c).length();
            assert!(err < 0.08, "centroid error {err} px at {c}");
            assert!(
                err < baseline,
                "centroid {err} not better than pixel {baseline}"
            );
        }
    }

    #[test]
    fn ignores_smooth_background_and_large_bright_regions() {
        // A bright 30×30 square (not a marker: too large) and a ramp, no spots.
        let img = GrayImage::from_fn(100, 60, |x, y| {
            let inside = (10..40).contains(&x) && (10..40).contains(&y);
            Luma([if inside { 250 } else { (40 + x) as u8 }])
        });
        let blobs = detect_markers(&img, &MarkerDetectParams::default()).unwrap();
        assert!(blobs
            .iter()
            .all(|b| b.area_px <= MarkerDetectParams::DEFAULT_MAX_AREA_PX));
        // Edges of the square pass the high-pass, but only as large connected rims.
        assert!(blobs.is_empty(), "{blobs:?}");
    }

    #[test]
    fn bad_input_is_an_error() {
        let p = MarkerDetectParams::default();
        assert!(matches!(
            detect_markers(&GrayImage::new(0, 0), &p),
            Err(Error::Empty { .. })
        ));
        assert!(matches!(
            detect_markers(&GrayImage::new(1, 1), &p),
            Err(Error::Degenerate { .. })
        ));
        let bad = MarkerDetectParams {
            threshold: 0,
            ..p.clone()
        };
        assert!(matches!(
            detect_markers(&GrayImage::new(8, 8), &bad),
            Err(Error::InvalidParam { .. })
        ));
        let bad = MarkerDetectParams {
            min_area_px: 5,
            max_area_px: 2,
            ..p
        };
        assert!(matches!(
            detect_markers(&GrayImage::new(8, 8), &bad),
            Err(Error::InvalidParam { .. })
        ));
    }
}
