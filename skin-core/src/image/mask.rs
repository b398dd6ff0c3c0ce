//! Binary masks (silhouettes): compact bit-packed storage, set operations, counts, bounding
//! boxes and the silhouette mismatch fraction of Sand et al. 2003 §6.2.
//!
//! Pixel convention (shared by the whole [`crate::image`] module): pixel `(x, y)` has its
//! centre at the continuous image coordinate `(x, y)`; `x` grows to the right, `y` downwards
//! (the OpenCV convention). Pixel `(x, y)` covers `[x − ½, x + ½] × [y − ½, y + ½]`.

use ::image::GrayImage;
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};

/// Number of pixels stored per storage word.
const BITS: usize = u64::BITS as usize;

/// Grey value written for foreground pixels by [`Mask::to_gray`].
pub const MASK_FOREGROUND_GREY: u8 = 255;

/// A binary image: each pixel is foreground (`true`, e.g. "performer") or background.
///
/// Stored row-major, one bit per pixel, in `u64` words, so set operations and counts work on
/// 64 pixels at a time. Bits past the last pixel are always zero (a class invariant that
/// [`Mask::count`] and equality rely on). Zero-sized masks are valid values; operations that
/// need pixels (distance transforms, background learning) reject them with a clear error.
///
/// Deserialisation validates the stored words (count and zero tail bits), so a malformed file
/// gives an error rather than a mask that panics later.
#[derive(Clone, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(try_from = "MaskRepr")]
pub struct Mask {
    width: u32,
    height: u32,
    words: Vec<u64>,
}

/// Unvalidated serialised form of [`Mask`].
#[derive(Deserialize)]
struct MaskRepr {
    width: u32,
    height: u32,
    words: Vec<u64>,
}

impl TryFrom<MaskRepr> for Mask {
    type Error = Error;
    fn try_from(r: MaskRepr) -> Result<Mask> {
        let mut m = Mask::new(r.width, r.height);
        if r.words.len() != m.words.len() {
            return Err(Error::SizeMismatch {
                what: "serialised mask words (ceil(width * height / 64))",
                expected: m.words.len(),
                got: r.words.len(),
            });
        }
        m.words = r.words;
        let before = m.count();
        m.clear_tail();
        if m.count() != before {
            return Err(Error::Degenerate {
                what: "serialised mask has bits set past its last pixel".into(),
            });
        }
        Ok(m)
    }
}

impl std::fmt::Debug for Mask {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Mask")
            .field("width", &self.width)
            .field("height", &self.height)
            .field("foreground", &self.count())
            .finish()
    }
}

/// An axis-aligned pixel rectangle with inclusive bounds (as returned by
/// [`Mask::bounding_box`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct PixelRect {
    /// Smallest column index, pixels.
    pub x_min: u32,
    /// Smallest row index, pixels.
    pub y_min: u32,
    /// Largest column index (inclusive), pixels.
    pub x_max: u32,
    /// Largest row index (inclusive), pixels.
    pub y_max: u32,
}

impl PixelRect {
    /// Width in pixels (`x_max − x_min + 1`; 0 if `x_max < x_min`).
    pub fn width(&self) -> u32 {
        self.x_max
            .checked_sub(self.x_min)
            .map_or(0, |d| d.saturating_add(1))
    }

    /// Height in pixels (`y_max − y_min + 1`; 0 if `y_max < y_min`).
    pub fn height(&self) -> u32 {
        self.y_max
            .checked_sub(self.y_min)
            .map_or(0, |d| d.saturating_add(1))
    }
}

impl Mask {
    /// An all-background mask of the given size (zero sizes allowed).
    pub fn new(width: u32, height: u32) -> Self {
        let n = width as usize * height as usize;
        Mask {
            width,
            height,
            words: vec![0; n.div_ceil(BITS)],
        }
    }

    /// A mask whose pixel `(x, y)` is `f(x, y)`.
    pub fn from_fn(width: u32, height: u32, mut f: impl FnMut(u32, u32) -> bool) -> Self {
        let mut m = Mask::new(width, height);
        for y in 0..height {
            for x in 0..width {
                if f(x, y) {
                    m.set_unchecked(m.index(x, y), true);
                }
            }
        }
        m
    }

    /// A mask from a grey image: pixels with value `> threshold` are foreground.
    ///
    /// `threshold = 0` reproduces the "non-zero is foreground" rule of `imageproc`.
    pub fn from_gray(image: &GrayImage, threshold: u8) -> Self {
        Mask::from_flags(
            image.width(),
            image.height(),
            image.as_raw().iter().map(|&v| v > threshold),
        )
    }

    /// Builds a mask from exactly `width · height` row-major flags, 64 at a time.
    pub(crate) fn from_flags(
        width: u32,
        height: u32,
        flags: impl IntoIterator<Item = bool>,
    ) -> Self {
        let mut m = Mask::new(width, height);
        let mut flags = flags.into_iter();
        for w in &mut m.words {
            for (b, f) in flags.by_ref().take(BITS).enumerate() {
                *w |= u64::from(f) << b;
            }
        }
        m
    }

    /// A grey image with foreground [`MASK_FOREGROUND_GREY`] (255) and background 0.
    #[allow(clippy::expect_used, reason = "one sample per pixel by construction")]
    pub fn to_gray(&self) -> GrayImage {
        let data = self.map_pixels(|f| if f { MASK_FOREGROUND_GREY } else { 0 });
        // `map_pixels` yields exactly width * height values.
        GrayImage::from_raw(self.width, self.height, data).expect("one sample per pixel")
    }

    /// Row-major per-pixel map over the flags (a plain loop over the words, which the
    /// compiler optimises better than the [`Mask::iter`] adaptor chain).
    fn map_pixels<T>(&self, f: impl Fn(bool) -> T) -> Vec<T> {
        let n = self.pixel_count();
        let mut out = Vec::with_capacity(n);
        for (k, &w) in self.words.iter().enumerate() {
            let bits = (n - k * BITS).min(BITS);
            for b in 0..bits {
                out.push(f((w >> b) & 1 == 1));
            }
        }
        out
    }

    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// `(width, height)` in pixels.
    pub fn dimensions(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// Number of pixels, `width · height`.
    pub fn pixel_count(&self) -> usize {
        self.width as usize * self.height as usize
    }

    /// Whether the mask has no pixels at all (zero width or height).
    pub fn is_zero_sized(&self) -> bool {
        self.pixel_count() == 0
    }

    #[inline]
    fn index(&self, x: u32, y: u32) -> usize {
        y as usize * self.width as usize + x as usize
    }

    #[inline]
    fn bit(&self, i: usize) -> bool {
        (self.words[i / BITS] >> (i % BITS)) & 1 == 1
    }

    #[inline]
    fn set_unchecked(&mut self, i: usize, value: bool) {
        let w = &mut self.words[i / BITS];
        let b = 1u64 << (i % BITS);
        if value {
            *w |= b;
        } else {
            *w &= !b;
        }
    }

    /// Whether pixel `(x, y)` is foreground; pixels outside the mask are background.
    #[inline]
    pub fn get(&self, x: u32, y: u32) -> bool {
        x < self.width && y < self.height && self.bit(self.index(x, y))
    }

    /// Like [`Mask::get`] with signed coordinates (convenient for neighbour look-ups);
    /// anything outside the mask is background.
    #[inline]
    pub fn get_i64(&self, x: i64, y: i64) -> bool {
        x >= 0
            && y >= 0
            && x < i64::from(self.width)
            && y < i64::from(self.height)
            && self.bit(self.index(x as u32, y as u32))
    }

    /// Sets pixel `(x, y)`.
    ///
    /// # Errors
    /// [`Error::IndexOutOfRange`] if `(x, y)` lies outside the mask.
    pub fn set(&mut self, x: u32, y: u32, value: bool) -> Result<()> {
        if x >= self.width {
            return Err(Error::IndexOutOfRange {
                what: "mask column",
                index: x as usize,
                len: self.width as usize,
            });
        }
        if y >= self.height {
            return Err(Error::IndexOutOfRange {
                what: "mask row",
                index: y as usize,
                len: self.height as usize,
            });
        }
        self.set_unchecked(self.index(x, y), value);
        Ok(())
    }

    /// Foreground flags in row-major order (`index = y · width + x`).
    pub fn iter(&self) -> impl Iterator<Item = bool> + '_ {
        self.words
            .iter()
            .flat_map(|&w| (0..BITS).map(move |b| (w >> b) & 1 == 1))
            .take(self.pixel_count())
    }

    /// Foreground flags as a row-major `Vec<bool>`.
    pub fn to_bools(&self) -> Vec<bool> {
        self.map_pixels(|f| f)
    }

    /// Builds a mask from row-major flags.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] if `flags.len() != width · height`.
    pub fn from_bools(width: u32, height: u32, flags: &[bool]) -> Result<Self> {
        let n = width as usize * height as usize;
        if flags.len() != n {
            return Err(Error::SizeMismatch {
                what: "mask flags (width * height)",
                expected: n,
                got: flags.len(),
            });
        }
        Ok(Mask::from_flags(width, height, flags.iter().copied()))
    }

    /// Number of foreground pixels.
    pub fn count(&self) -> usize {
        self.words.iter().map(|w| w.count_ones() as usize).sum()
    }

    /// Whether no pixel is foreground (true for zero-sized masks too).
    pub fn is_empty(&self) -> bool {
        self.words.iter().all(|&w| w == 0)
    }

    /// Whether every pixel is foreground (false for zero-sized masks).
    pub fn is_full(&self) -> bool {
        !self.is_zero_sized() && self.count() == self.pixel_count()
    }

    /// Smallest rectangle holding every foreground pixel, `None` if the mask is empty.
    pub fn bounding_box(&self) -> Option<PixelRect> {
        let mut r: Option<PixelRect> = None;
        for y in 0..self.height {
            for x in 0..self.width {
                if self.get(x, y) {
                    r = Some(match r {
                        None => PixelRect {
                            x_min: x,
                            y_min: y,
                            x_max: x,
                            y_max: y,
                        },
                        Some(r) => PixelRect {
                            x_min: r.x_min.min(x),
                            y_min: r.y_min,
                            x_max: r.x_max.max(x),
                            y_max: y,
                        },
                    });
                }
            }
        }
        r
    }

    fn check_same_size(&self, other: &Mask, what: &'static str) -> Result<()> {
        if self.width != other.width {
            return Err(Error::SizeMismatch {
                what,
                expected: self.width as usize,
                got: other.width as usize,
            });
        }
        if self.height != other.height {
            return Err(Error::SizeMismatch {
                what,
                expected: self.height as usize,
                got: other.height as usize,
            });
        }
        Ok(())
    }

    fn zip_words(
        &self,
        other: &Mask,
        what: &'static str,
        f: impl Fn(u64, u64) -> u64,
    ) -> Result<Mask> {
        self.check_same_size(other, what)?;
        Ok(Mask {
            width: self.width,
            height: self.height,
            words: self
                .words
                .iter()
                .zip(&other.words)
                .map(|(&a, &b)| f(a, b))
                .collect(),
        })
    }

    /// Pixel-wise intersection.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] if the masks differ in width or height.
    pub fn and(&self, other: &Mask) -> Result<Mask> {
        self.zip_words(other, "mask and (width/height)", |a, b| a & b)
    }

    /// Pixel-wise union.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] if the masks differ in width or height.
    pub fn or(&self, other: &Mask) -> Result<Mask> {
        self.zip_words(other, "mask or (width/height)", |a, b| a | b)
    }

    /// Pixel-wise exclusive or (the pixels where the masks disagree).
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] if the masks differ in width or height.
    pub fn xor(&self, other: &Mask) -> Result<Mask> {
        self.zip_words(other, "mask xor (width/height)", |a, b| a ^ b)
    }

    /// Pixel-wise difference `self ∧ ¬other`.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] if the masks differ in width or height.
    pub fn and_not(&self, other: &Mask) -> Result<Mask> {
        self.zip_words(other, "mask and_not (width/height)", |a, b| a & !b)
    }

    /// Pixel-wise complement (foreground ↔ background).
    #[allow(clippy::should_implement_trait)] // also provided as `std::ops::Not` below
    pub fn not(&self) -> Mask {
        let mut m = Mask {
            width: self.width,
            height: self.height,
            words: self.words.iter().map(|w| !w).collect(),
        };
        m.clear_tail();
        m
    }

    /// Re-establishes the invariant that bits past the last pixel are zero.
    fn clear_tail(&mut self) {
        let n = self.pixel_count();
        let rem = n % BITS;
        if rem != 0 {
            if let Some(last) = self.words.last_mut() {
                *last &= (1u64 << rem) - 1;
            }
        }
    }

    /// Fraction of pixels where `self` and `other` disagree: the *silhouette error* of
    /// Sand et al. 2003 §6.2 ("the fraction of pixels for which the predicted and observed
    /// silhouette do not match").
    ///
    /// With `region = Some(r)` only pixels of `r` are counted (numerator and denominator):
    /// Sand §6.2 considers "only pixels near the projected silhouette boundary" — pass
    /// [`Mask::boundary_band`] of the predicted silhouette. With `None` every pixel counts.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] if the sizes differ; [`Error::Empty`] if the region (or the
    /// whole mask) has no pixel, since the fraction is then undefined.
    pub fn mismatch_fraction(&self, other: &Mask, region: Option<&Mask>) -> Result<f64> {
        let diff = self.xor(other)?;
        let (bad, total) = match region {
            Some(r) => {
                self.check_same_size(r, "mismatch region (width/height)")?;
                (diff.and(r)?.count(), r.count())
            }
            None => (diff.count(), self.pixel_count()),
        };
        if total == 0 {
            return Err(Error::Empty {
                what: "mismatch region (no pixel to compare)",
            });
        }
        Ok(bad as f64 / total as f64)
    }

    /// Foreground pixels with at least one 4-neighbour in the background (pixels outside
    /// the image count as background, so foreground on the image border is boundary).
    pub fn inner_boundary(&self) -> Mask {
        let mut out = Mask::new(self.width, self.height);
        for y in 0..self.height {
            for x in 0..self.width {
                if !self.get(x, y) {
                    continue;
                }
                let (xi, yi) = (i64::from(x), i64::from(y));
                let edge = !self.get_i64(xi - 1, yi)
                    || !self.get_i64(xi + 1, yi)
                    || !self.get_i64(xi, yi - 1)
                    || !self.get_i64(xi, yi + 1);
                if edge {
                    out.set_unchecked(out.index(x, y), true);
                }
            }
        }
        out
    }
}

impl std::ops::Not for &Mask {
    type Output = Mask;
    fn not(self) -> Mask {
        Mask::not(self)
    }
}

impl From<&GrayImage> for Mask {
    /// Non-zero pixels are foreground (as in `imageproc`).
    fn from(image: &GrayImage) -> Self {
        Mask::from_gray(image, 0)
    }
}

impl From<&Mask> for GrayImage {
    fn from(mask: &Mask) -> Self {
        mask.to_gray()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn arb_mask() -> impl Strategy<Value = Mask> {
        (0u32..20, 0u32..20).prop_flat_map(|(w, h)| {
            proptest::collection::vec(any::<bool>(), (w * h) as usize)
                .prop_map(move |f| Mask::from_bools(w, h, &f).unwrap())
        })
    }

    fn pair() -> impl Strategy<Value = (Mask, Mask)> {
        (1u32..20, 1u32..20).prop_flat_map(|(w, h)| {
            let n = (w * h) as usize;
            (
                proptest::collection::vec(any::<bool>(), n),
                proptest::collection::vec(any::<bool>(), n),
            )
                .prop_map(move |(a, b)| {
                    (
                        Mask::from_bools(w, h, &a).unwrap(),
                        Mask::from_bools(w, h, &b).unwrap(),
                    )
                })
        })
    }

    proptest! {
        #[test]
        fn gray_round_trip_is_exact(m in arb_mask()) {
            let g = m.to_gray();
            prop_assert_eq!(Mask::from(&g), m.clone());
            prop_assert_eq!(Mask::from_bools(m.width(), m.height(), &m.to_bools()).unwrap(), m);
        }

        #[test]
        fn set_ops_match_pixelwise((a, b) in pair()) {
            let and = a.and(&b).unwrap();
            let or = a.or(&b).unwrap();
            let xor = a.xor(&b).unwrap();
            let not = a.not();
            for (i, (pa, pb)) in a.iter().zip(b.iter()).enumerate() {
                let x = (i % a.width() as usize) as u32;
                let y = (i / a.width() as usize) as u32;
                prop_assert_eq!(and.get(x, y), pa && pb);
                prop_assert_eq!(or.get(x, y), pa || pb);
                prop_assert_eq!(xor.get(x, y), pa != pb);
                prop_assert_eq!(not.get(x, y), !pa);
            }
            prop_assert_eq!(not.count() + a.count(), a.pixel_count());
            prop_assert_eq!(and.count() + or.count(), a.count() + b.count());
            let f = a.mismatch_fraction(&b, None).unwrap();
            prop_assert!((f - xor.count() as f64 / a.pixel_count() as f64).abs() < 1e-12);
        }

        #[test]
        fn bounding_box_contains_all_and_is_tight(m in arb_mask()) {
            match m.bounding_box() {
                None => prop_assert!(m.is_empty()),
                Some(r) => {
                    prop_assert!(r.width() >= 1 && r.width() <= m.width());
                    prop_assert!(r.height() >= 1 && r.height() <= m.height());
                    let mut touches = [false; 4];
                    for y in 0..m.height() {
                        for x in 0..m.width() {
                            if m.get(x, y) {
                                prop_assert!(x >= r.x_min && x <= r.x_max && y >= r.y_min && y <= r.y_max);
                                touches[0] |= x == r.x_min;
                                touches[1] |= x == r.x_max;
                                touches[2] |= y == r.y_min;
                                touches[3] |= y == r.y_max;
                            }
                        }
                    }
                    prop_assert!(touches.iter().all(|&t| t));
                }
            }
        }
    }

    #[test]
    fn serde_round_trip_and_malformed_input() {
        let m = Mask::from_fn(13, 7, |x, y| (x * y) % 3 == 1);
        let json = serde_json::to_string(&m).unwrap();
        assert_eq!(serde_json::from_str::<Mask>(&json).unwrap(), m);
        // Wrong word count and stray tail bits are rejected.
        assert!(serde_json::from_str::<Mask>(r#"{"width":13,"height":7,"words":[0]}"#).is_err());
        let tail = format!(r#"{{"width":13,"height":7,"words":[0,{}]}}"#, 1u64 << 40);
        assert!(serde_json::from_str::<Mask>(&tail).is_err());
    }

    #[test]
    fn size_mismatch_is_an_error() {
        let a = Mask::new(4, 3);
        let b = Mask::new(3, 4);
        assert!(matches!(a.and(&b), Err(Error::SizeMismatch { .. })));
        assert!(matches!(a.or(&b), Err(Error::SizeMismatch { .. })));
        assert!(matches!(a.xor(&b), Err(Error::SizeMismatch { .. })));
        assert!(matches!(
            a.mismatch_fraction(&b, None),
            Err(Error::SizeMismatch { .. })
        ));
        assert!(matches!(
            a.mismatch_fraction(&a, Some(&b)),
            Err(Error::SizeMismatch { .. })
        ));
    }

    #[test]
    fn set_out_of_range_is_an_error_and_get_outside_is_background() {
        let mut m = Mask::new(3, 2);
        assert!(matches!(
            m.set(3, 0, true),
            Err(Error::IndexOutOfRange { .. })
        ));
        assert!(matches!(
            m.set(0, 2, true),
            Err(Error::IndexOutOfRange { .. })
        ));
        m.set(2, 1, true).unwrap();
        assert!(m.get(2, 1));
        assert!(!m.get(3, 1));
        assert!(!m.get_i64(-1, 0));
        assert!(m.get_i64(2, 1));
    }

    #[test]
    fn zero_sized_masks_behave() {
        let m = Mask::new(0, 5);
        assert!(m.is_empty());
        assert!(!m.is_full());
        assert_eq!(m.count(), 0);
        assert_eq!(m.bounding_box(), None);
        assert_eq!(m.not().count(), 0);
        assert!(matches!(
            m.mismatch_fraction(&m, None),
            Err(Error::Empty { .. })
        ));
        assert!(matches!(
            Mask::from_bools(2, 2, &[true]),
            Err(Error::SizeMismatch { .. })
        ));
    }
}
