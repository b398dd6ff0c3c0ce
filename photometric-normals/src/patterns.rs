//! §3.2.2 illumination design: the weights the patterns of the cycle ([`crate::Pattern`])
//! give the lights, and one observation of a surface under the seven distinct conditions
//! ([`PatternImages`], valid by construction).

use image::{GrayImage, Rgb32FImage};
use serde::{Deserialize, Serialize};
use skin_core::image::GrayF32Image;
use skin_core::math::DVec3;

use crate::cycle::{Pattern, PATTERNS};
use crate::{Error, Result};

/// The on/off weight (1 or 0) of every light under `pattern`, for lights at their real
/// positions (world frame, m) and the dome centre `centre` that defines their directions.
///
/// # Errors
/// [`Error::Empty`] for no lights; [`Error::NonFinite`] for a non-finite position or centre.
pub fn pattern_weights(
    light_positions: &[DVec3],
    centre: DVec3,
    pattern: Pattern,
) -> Result<Vec<f32>> {
    if light_positions.is_empty() {
        return Err(Error::Empty {
            what: "light positions",
        });
    }
    skin_core::check::all_finite(
        "light positions and dome centre",
        light_positions
            .iter()
            .chain([&centre])
            .flat_map(|p| p.as_ref().iter()),
    )?;
    Ok(light_positions
        .iter()
        .map(|&p| f32::from(u8::from(pattern.lights(p - centre))))
        .collect())
}

/// The weights of [`pattern_weights`] for each pattern of `patterns` (e.g. [`CYCLE`](crate::CYCLE) for a
/// time-multiplexed capture, [`PATTERNS`] for a static one).
///
/// # Errors
/// As [`pattern_weights`].
pub fn patterns_weights(
    light_positions: &[DVec3],
    centre: DVec3,
    patterns: &[Pattern],
) -> Result<Vec<Vec<f32>>> {
    patterns
        .iter()
        .map(|&p| pattern_weights(light_positions, centre, p))
        .collect()
}

/// Grey intensity of a linear RGB image: the mean of the channels.
pub fn grey(image: &Rgb32FImage) -> GrayF32Image {
    GrayF32Image::from_fn(image.width(), image.height(), |x, y| {
        let p = image.get_pixel(x, y).0;
        image::Luma([(p[0] + p[1] + p[2]) / 3.0])
    })
}

/// Camera exposure: the linear intensity at which the sensor saturates (normalised
/// intensity one) and the range of normalised intensities trusted for normals (§3.2.3,
/// "Impact of Albedo").
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Exposure {
    /// Linear intensity of normalised intensity 1. Default: 1 (images delivered in `[0, 1]`).
    pub white_level: f32,
    /// Lowest normalised intensity of the full-on frame (dark, noise-dominated albedo).
    /// Default: 0.03 (§3.2.3).
    pub min_normalised: f32,
    /// Highest normalised intensity under any condition (saturation). Default: 0.97 (§3.2.3).
    pub max_normalised: f32,
}

impl Default for Exposure {
    fn default() -> Self {
        Self {
            white_level: 1.0,
            min_normalised: 0.03,
            max_normalised: 0.97,
        }
    }
}

impl Exposure {
    /// Returns the exposure with `white_level`.
    pub fn with_white_level(mut self, white_level: f32) -> Self {
        self.white_level = white_level;
        self
    }

    /// Checks the exposure.
    ///
    /// # Errors
    /// [`Error::Core`] for a non-positive white level or a range outside `[0, 1]` / empty.
    pub fn validate(&self) -> Result<()> {
        skin_core::check::positive("white_level", f64::from(self.white_level))?;
        skin_core::check::in_range("min_normalised", f64::from(self.min_normalised), 0.0..=1.0)?;
        skin_core::check::in_range(
            "max_normalised",
            f64::from(self.max_normalised),
            f64::from(self.min_normalised)..=1.0,
        )?;
        Ok(())
    }

    /// §3.2.3: whether a pixel with full-on intensity `full` and largest intensity under any
    /// condition `brightest` is trusted (neither dark nor saturated).
    pub fn trusted(&self, full: f32, brightest: f32) -> bool {
        full >= self.min_normalised * self.white_level
            && brightest <= self.max_normalised * self.white_level
    }

    /// The 8-bit picture of a linear intensity (clamped at saturation).
    pub fn to_gray8(&self, image: &GrayF32Image) -> GrayImage {
        GrayImage::from_fn(image.width(), image.height(), |x, y| {
            let v = image.get_pixel(x, y)[0] / self.white_level;
            image::Luma([(v.clamp(0.0, 1.0) * 255.0).round() as u8])
        })
    }
}

/// One view of a surface under the seven distinct conditions ([`PATTERNS`] order), grey
/// linear intensities, all of one size and finite.
#[derive(Debug, Clone, PartialEq)]
pub struct PatternImages {
    width: u32,
    height: u32,
    images: Vec<GrayF32Image>,
}

impl PatternImages {
    /// Collects `(pattern, image)` pairs (any order; each pattern at most once).
    ///
    /// # Errors
    /// [`Error::MissingPattern`] for a condition without an image; [`Error::InvalidParam`]
    /// for a pattern given twice; [`Error::SizeMismatch`] for images of different sizes;
    /// [`Error::Empty`] for zero-sized images; [`Error::NonFinite`] for NaN or infinite
    /// intensities.
    pub fn new(images: Vec<(Pattern, GrayF32Image)>) -> Result<Self> {
        let mut slots: Vec<Option<GrayF32Image>> = vec![None; PATTERNS.len()];
        for (p, im) in images {
            let slot = &mut slots[p.index()];
            if slot.is_some() {
                return Err(Error::InvalidParam {
                    name: "pattern images",
                    reason: format!("{p:?} given more than once; give each condition one image"),
                });
            }
            *slot = Some(im);
        }
        let mut out = Vec::with_capacity(PATTERNS.len());
        for (p, slot) in PATTERNS.iter().zip(slots) {
            out.push(slot.ok_or(Error::MissingPattern { pattern: *p })?);
        }
        let (width, height) = out[0].dimensions();
        if width == 0 || height == 0 {
            return Err(Error::Empty {
                what: "pattern images (zero-sized)",
            });
        }
        for im in &out {
            if im.dimensions() != (width, height) {
                return Err(Error::SizeMismatch {
                    what: "pattern image pixels",
                    expected: (width * height) as usize,
                    got: (im.width() * im.height()) as usize,
                });
            }
            if im.as_raw().iter().any(|v| !v.is_finite()) {
                return Err(Error::NonFinite {
                    what: "pattern image intensity",
                });
            }
        }
        Ok(Self {
            width,
            height,
            images: out,
        })
    }

    /// As [`PatternImages::new`] from linear RGB images ([`grey`]).
    ///
    /// # Errors
    /// As [`PatternImages::new`].
    pub fn from_rgb(images: &[(Pattern, &Rgb32FImage)]) -> Result<Self> {
        Self::new(images.iter().map(|(p, im)| (*p, grey(im))).collect())
    }

    /// Width, px.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height, px.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The image of `pattern`.
    pub fn image(&self, pattern: Pattern) -> &GrayF32Image {
        &self.images[pattern.index()]
    }

    /// The seven intensities of pixel `i` (row-major), [`PATTERNS`] order.
    pub(crate) fn pixel(&self, i: usize) -> [f32; 7] {
        std::array::from_fn(|p| self.images[p].as_raw()[i])
    }
}

/// The un-normalised key `k = [I_X − I_X̄, I_Y − I_Ȳ, I_Z − I_Z̄]` (§3.2.2) of seven
/// intensities in [`PATTERNS`] order.
pub(crate) fn key(i: &[f32; 7]) -> DVec3 {
    DVec3::new(
        f64::from(i[0] - i[4]),
        f64::from(i[1] - i[5]),
        f64::from(i[2] - i[6]),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eq_3_1_halves_are_complementary() {
        let lights: Vec<DVec3> = (0..50)
            .map(|i| {
                let t = i as f64 * 0.7;
                DVec3::new(t.cos(), (t * 1.3).sin(), (t * 0.4).cos() - 0.2) * 4.0
            })
            .collect();
        for (a, b) in [
            (Pattern::X, Pattern::XBar),
            (Pattern::Y, Pattern::YBar),
            (Pattern::Z, Pattern::ZBar),
        ] {
            let wa = pattern_weights(&lights, DVec3::ZERO, a).unwrap();
            let wb = pattern_weights(&lights, DVec3::ZERO, b).unwrap();
            assert!(wa.iter().zip(&wb).all(|(x, y)| x + y == 1.0));
            assert!(wa.contains(&1.0) && wb.contains(&1.0));
        }
        let full = pattern_weights(&lights, DVec3::ZERO, Pattern::Full).unwrap();
        assert!(full.iter().all(|&x| x == 1.0));
        assert!(pattern_weights(&[], DVec3::ZERO, Pattern::X).is_err());
        assert!(pattern_weights(&[DVec3::NAN], DVec3::ZERO, Pattern::X).is_err());
    }

    fn set(w: u32, h: u32, skip: Option<Pattern>) -> Vec<(Pattern, GrayF32Image)> {
        PATTERNS
            .iter()
            .filter(|p| Some(**p) != skip)
            .map(|&p| (p, GrayF32Image::from_pixel(w, h, image::Luma([0.2]))))
            .collect()
    }

    #[test]
    fn pattern_images_reject_missing_duplicate_mismatched_and_nan() {
        assert!(PatternImages::new(set(4, 3, None)).is_ok());
        assert!(matches!(
            PatternImages::new(set(4, 3, Some(Pattern::ZBar))),
            Err(Error::MissingPattern {
                pattern: Pattern::ZBar
            })
        ));
        let mut dup = set(4, 3, None);
        dup.push(dup[0].clone());
        assert!(matches!(
            PatternImages::new(dup),
            Err(Error::InvalidParam { .. })
        ));
        let mut odd = set(4, 3, None);
        odd[2].1 = GrayF32Image::new(5, 3);
        assert!(matches!(
            PatternImages::new(odd),
            Err(Error::SizeMismatch { .. })
        ));
        let mut nan = set(4, 3, None);
        nan[1].1.put_pixel(1, 1, image::Luma([f32::NAN]));
        assert!(matches!(
            PatternImages::new(nan),
            Err(Error::NonFinite { .. })
        ));
        assert!(matches!(
            PatternImages::new(set(0, 0, None)),
            Err(Error::Empty { .. })
        ));
    }

    #[test]
    fn exposure_trusts_the_papers_range_only() {
        let e = Exposure::default().with_white_level(2.0);
        assert!(e.validate().is_ok());
        assert!(e.trusted(1.0, 1.5));
        assert!(!e.trusted(0.05, 0.5), "dark: 0.025 normalised");
        assert!(!e.trusted(1.0, 1.95), "saturated: 0.975 normalised");
        assert!(Exposure::default()
            .with_white_level(0.0)
            .validate()
            .is_err());
    }
}
