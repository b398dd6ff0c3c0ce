//! PNG input/output of masks, depth maps and normal maps.
//!
//! * Masks: 8-bit greyscale, foreground 255, background 0; read back with "grey ≥ 128 is
//!   foreground" (so anti-aliased or JPEG-recompressed masks still read sensibly).
//! * Depth, lossless: 16-bit greyscale, `value = round((depth_m − offset_m) / scale_m)`,
//!   **value 0 = no data**; see [`DepthEncoding`].
//! * Depth, for viewing: 8-bit RGB false colour over a given [`DepthRange`], no data black.
//! * Normals: camera-space unit normals `n` → RGB `(n + 1) / 2` (8 or 16 bits), no data black.
//!
//! Invalid depth is explicit everywhere: NaN, ±∞ and values ≤ 0 mean "no data" (a depth of 0
//! is the usual no-data marker of depth sensors). Invalid normals are NaN, non-finite or
//! (near-)zero vectors; they read back as NaN normals.
//!
//! Malformed or truncated files give [`Error::Image`] (decoding) or [`Error::Parse`] (wrong PNG
//! layout), missing files [`Error::Io`]; nothing here panics on file content.

use std::path::Path;

use ::image::{
    DynamicImage, ImageBuffer, ImageError, ImageFormat, ImageReader, Luma, Rgb, Rgb32FImage,
    RgbImage,
};
use serde::{Deserialize, Serialize};

use super::distance::GrayF32Image;
use super::mask::Mask;
use crate::error::{Error, Result};

/// Grey level at or above which a read mask pixel is foreground.
pub const MASK_READ_THRESHOLD: u8 = 128;
impl DepthEncoding {
    /// Default depth quantum, metres per 16-bit unit: 0.1 mm, so the 16-bit range covers
    /// 0.1 mm – 6.55 m, a capture volume with sub-millimetre steps.
    pub const DEFAULT_SCALE_M: f64 = 1e-4;
}
/// 16-bit value marking "no data" in depth PNGs.
pub const DEPTH_NO_DATA: u16 = 0;
/// Norm below which a normal is treated as missing.
const MIN_NORMAL_NORM: f32 = 1e-6;

/// A single-channel 16-bit image.
pub type Gray16Image = ImageBuffer<Luma<u16>, Vec<u16>>;
/// A three-channel 16-bit image.
pub type Rgb16Image = ImageBuffer<Rgb<u16>, Vec<u16>>;

/// Linear quantisation of depth into 16-bit PNG values: `depth_m = offset_m + value · scale_m`
/// for `value ∈ 1..=65535`, value 0 = no data. Encodable depths are
/// `[offset_m + scale_m/2, offset_m + 65535.5·scale_m)`; the round-trip error is at most
/// `scale_m / 2` (plus `f32` rounding).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct DepthEncoding {
    /// Metres per 16-bit unit. Default: [`DepthEncoding::DEFAULT_SCALE_M`] = 1e-4 (0.1 mm).
    pub scale_m: f64,
    /// Depth of value 0, metres (value 0 itself is reserved for no data). Default: 0.
    pub offset_m: f64,
}

impl Default for DepthEncoding {
    fn default() -> Self {
        DepthEncoding {
            scale_m: DepthEncoding::DEFAULT_SCALE_M,
            offset_m: 0.0,
        }
    }
}

impl DepthEncoding {
    /// Smallest and largest encodable depth, metres.
    pub fn range_m(&self) -> (f64, f64) {
        (
            self.offset_m + 0.5 * self.scale_m,
            self.offset_m + (f64::from(u16::MAX) + 0.5) * self.scale_m,
        )
    }

    fn validate(&self) -> Result<()> {
        crate::check::positive("scale_m", self.scale_m)?;
        if !self.offset_m.is_finite() {
            return Err(Error::InvalidParam {
                name: "offset_m",
                reason: format!("must be finite, got {}", self.offset_m),
            });
        }
        Ok(())
    }
}

/// Depth interval mapped onto the false-colour scale (near → blue, far → red).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct DepthRange {
    /// Depth drawn at the blue end, metres.
    pub near_m: f64,
    /// Depth drawn at the red end, metres.
    pub far_m: f64,
}

/// Bits per channel of a written normal map.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum NormalBits {
    /// 8 bits: for viewing (component step 2/255 ≈ 0.008, about 0.5°).
    Eight,
    /// 16 bits: for storage (component step 2/65535).
    Sixteen,
}

/// Whether a depth sample holds data: finite and > 0.
pub fn is_valid_depth(d: f32) -> bool {
    d.is_finite() && d > 0.0
}

fn map_image_error(path: &Path, e: ImageError) -> Error {
    match e {
        ImageError::IoError(source) => Error::io(path, source),
        other => Error::Image(other),
    }
}

fn require_pixels(width: u32, height: u32, what: &'static str) -> Result<()> {
    if width == 0 || height == 0 {
        return Err(Error::Empty { what });
    }
    Ok(())
}

fn read_png(path: &Path) -> Result<DynamicImage> {
    let mut reader = ImageReader::open(path).map_err(|e| Error::io(path, e))?;
    // Always decode as PNG, whatever the file name says. The default decoding limits
    // (512 MiB) guard against decompression bombs.
    reader.set_format(ImageFormat::Png);
    reader.decode().map_err(|e| map_image_error(path, e))
}

fn save_png<P, C>(image: &ImageBuffer<P, C>, path: &Path) -> Result<()>
where
    P: ::image::PixelWithColorType,
    [P::Subpixel]: ::image::EncodableLayout,
    C: std::ops::Deref<Target = [P::Subpixel]>,
{
    image
        .save_with_format(path, ImageFormat::Png)
        .map_err(|e| map_image_error(path, e))
}

/// Writes a mask as an 8-bit greyscale PNG (foreground 255, background 0).
///
/// # Errors
/// [`Error::Empty`] for a zero-sized mask (PNG cannot hold it); [`Error::Io`] /
/// [`Error::Image`] if writing fails.
pub fn write_mask_png(mask: &Mask, path: impl AsRef<Path>) -> Result<()> {
    require_pixels(
        mask.width(),
        mask.height(),
        "mask (zero-sized image cannot be a PNG)",
    )?;
    save_png(&mask.to_gray(), path.as_ref())
}

/// Reads a mask from any PNG (converted to grey; grey ≥ [`MASK_READ_THRESHOLD`] is
/// foreground).
///
/// # Errors
/// [`Error::Io`] if the file cannot be opened; [`Error::Image`] if it is not a valid PNG.
pub fn read_mask_png(path: impl AsRef<Path>) -> Result<Mask> {
    let img = read_png(path.as_ref())?.to_luma8();
    Ok(Mask::from_gray(&img, MASK_READ_THRESHOLD - 1))
}

/// Quantises a depth map (metres) into a 16-bit image with `encoding`; no data → 0.
///
/// # Errors
/// [`Error::InvalidParam`] for an invalid encoding or a valid depth outside
/// [`DepthEncoding::range_m`].
pub fn encode_depth_u16(depth_m: &GrayF32Image, encoding: &DepthEncoding) -> Result<Gray16Image> {
    encoding.validate()?;
    let (lo, hi) = encoding.range_m();
    let mut out = Gray16Image::new(depth_m.width(), depth_m.height());
    for (o, &d) in out.iter_mut().zip(depth_m.as_raw()) {
        if !is_valid_depth(d) {
            *o = DEPTH_NO_DATA;
            continue;
        }
        let d = f64::from(d);
        if d < lo || d >= hi {
            return Err(Error::InvalidParam {
                name: "depth_m",
                reason: format!(
                    "depth {d} m is outside the encodable range [{lo}, {hi}) m; \
                     choose a larger scale_m or another offset_m"
                ),
            });
        }
        // In 1..=65535 by the range check above.
        *o = ((d - encoding.offset_m) / encoding.scale_m).round() as u16;
    }
    Ok(out)
}

/// Converts a 16-bit depth image back to metres with `encoding`; 0 → NaN (no data).
///
/// # Errors
/// [`Error::InvalidParam`] for an invalid encoding.
#[allow(
    clippy::expect_used,
    reason = "the decoder yields width × height samples"
)]
pub fn decode_depth_u16(image: &Gray16Image, encoding: &DepthEncoding) -> Result<GrayF32Image> {
    encoding.validate()?;
    let data = image
        .as_raw()
        .iter()
        .map(|&v| {
            if v == DEPTH_NO_DATA {
                f32::NAN
            } else {
                (encoding.offset_m + f64::from(v) * encoding.scale_m) as f32
            }
        })
        .collect();
    // Same dimensions as `image`.
    Ok(GrayF32Image::from_raw(image.width(), image.height(), data)
        .expect("decoded depth has width * height samples"))
}

/// Writes a depth map (metres; NaN, ±∞ or ≤ 0 = no data) losslessly as a 16-bit greyscale
/// PNG with `encoding` (no data → 0). Read back with [`read_depth_png16`] and the same
/// encoding; the round-trip error is at most `scale_m / 2`.
///
/// # Errors
/// [`Error::Empty`] for a zero-sized image; [`Error::InvalidParam`] for an invalid encoding
/// or an unencodable depth; [`Error::Io`] / [`Error::Image`] if writing fails.
pub fn write_depth_png16(
    depth_m: &GrayF32Image,
    path: impl AsRef<Path>,
    encoding: &DepthEncoding,
) -> Result<()> {
    require_pixels(depth_m.width(), depth_m.height(), "depth map (zero-sized)")?;
    save_png(&encode_depth_u16(depth_m, encoding)?, path.as_ref())
}

/// Reads a 16-bit greyscale depth PNG written by [`write_depth_png16`]; no data → NaN.
///
/// # Errors
/// [`Error::Io`] / [`Error::Image`] for unreadable files; [`Error::Parse`] if the PNG is not
/// 16-bit greyscale (8-bit or colour files would silently change the scale);
/// [`Error::InvalidParam`] for an invalid encoding.
pub fn read_depth_png16(path: impl AsRef<Path>, encoding: &DepthEncoding) -> Result<GrayF32Image> {
    encoding.validate()?;
    match read_png(path.as_ref())? {
        DynamicImage::ImageLuma16(img) => decode_depth_u16(&img, encoding),
        other => Err(Error::Parse {
            format: "depth PNG",
            line: 0,
            message: format!("expected 16-bit greyscale, found {:?}", other.color()),
        }),
    }
}

/// Polynomial approximation of the "Turbo" colour map (A. Mikhailov, Google 2019; fit by
/// R. Du), `t ∈ [0, 1]` → RGB in `[0, 1]`. Perceptually ordered, never black.
fn turbo(t: f64) -> [f64; 3] {
    const R4: [f64; 4] = [0.135_721_38, 4.615_392_6, -42.660_322_58, 132.131_082_34];
    const G4: [f64; 4] = [0.091_402_61, 2.194_188_39, 4.842_966_58, -14.185_033_33];
    const B4: [f64; 4] = [0.106_673_3, 12.641_946_08, -60.582_048_36, 110.362_767_71];
    const R2: [f64; 2] = [-152.942_393_96, 59.286_379_43];
    const G2: [f64; 2] = [4.277_298_57, 2.829_566_04];
    const B2: [f64; 2] = [-89.903_109_12, 27.348_249_73];
    let x = t.clamp(0.0, 1.0);
    let v4 = [1.0, x, x * x, x * x * x];
    let v2 = [v4[2] * v4[2], v4[3] * v4[2]];
    let ch = |c4: &[f64; 4], c2: &[f64; 2]| {
        let s: f64 =
            c4.iter().zip(&v4).map(|(a, b)| a * b).sum::<f64>() + c2[0] * v2[0] + c2[1] * v2[1];
        s.clamp(0.0, 1.0)
    };
    [ch(&R4, &R2), ch(&G4, &G2), ch(&B4, &B2)]
}

/// Renders a depth map (metres) in false colour: `range.near_m` blue → `range.far_m` red
/// (Turbo colour map, values outside the range clamped), no data black.
///
/// # Errors
/// [`Error::InvalidParam`] unless `near_m < far_m`, both finite.
pub fn depth_false_colour(depth_m: &GrayF32Image, range: &DepthRange) -> Result<RgbImage> {
    if !(range.near_m.is_finite() && range.far_m.is_finite() && range.near_m < range.far_m) {
        return Err(Error::InvalidParam {
            name: "range",
            reason: format!(
                "need finite near_m < far_m, got [{}, {}]",
                range.near_m, range.far_m
            ),
        });
    }
    let span = range.far_m - range.near_m;
    Ok(RgbImage::from_fn(
        depth_m.width(),
        depth_m.height(),
        |x, y| {
            let d = depth_m.get_pixel(x, y).0[0];
            if !is_valid_depth(d) {
                return Rgb([0, 0, 0]);
            }
            let c = turbo((f64::from(d) - range.near_m) / span);
            Rgb(c.map(|v| (v * 255.0).round() as u8))
        },
    ))
}

/// Writes [`depth_false_colour`] as an 8-bit RGB PNG for viewing.
///
/// # Errors
/// As [`depth_false_colour`]; [`Error::Empty`] for a zero-sized image; [`Error::Io`] /
/// [`Error::Image`] if writing fails.
pub fn write_depth_false_colour_png(
    depth_m: &GrayF32Image,
    path: impl AsRef<Path>,
    range: &DepthRange,
) -> Result<()> {
    require_pixels(depth_m.width(), depth_m.height(), "depth map (zero-sized)")?;
    save_png(&depth_false_colour(depth_m, range)?, path.as_ref())
}

/// The unit normal at a pixel, or `None` if missing (non-finite or ~zero).
fn unit_normal(px: &Rgb<f32>) -> Option<[f32; 3]> {
    let n = px.0;
    if n.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let len = n.iter().map(|v| v * v).sum::<f32>().sqrt();
    (len > MIN_NORMAL_NORM).then(|| n.map(|v| v / len))
}

/// Encodes camera-space normals as colours `(n + 1) / 2` scaled to `max`; missing normals → 0.
/// Non-unit normals are normalised first.
fn encode_normals<T: Copy>(
    normals: &Rgb32FImage,
    max: f32,
    conv: impl Fn(f32) -> T,
    zero: T,
) -> Vec<T> {
    normals
        .pixels()
        .flat_map(|px| match unit_normal(px) {
            Some(n) => n.map(|v| conv(((v + 1.0) * 0.5 * max).round().clamp(0.0, max))),
            None => [zero; 3],
        })
        .collect()
}

/// Normals as an 8-bit RGB picture, `colour = (n + 1) / 2` (missing normals black), the
/// in-memory form of [`write_normal_png`] with [`NormalBits::Eight`].
#[allow(
    clippy::expect_used,
    reason = "the buffer holds 3 samples per pixel by construction"
)]
pub fn normals_rgb8(normals: &Rgb32FImage) -> RgbImage {
    let (w, h) = normals.dimensions();
    let data = encode_normals(normals, f32::from(u8::MAX), |v| v as u8, 0u8);
    RgbImage::from_raw(w, h, data).expect("3 samples per pixel")
}

/// Writes camera-space normals (any frame: components are mapped independently) as an RGB
/// PNG with `colour = (n + 1) / 2`; missing normals (NaN, ∞ or zero) are written black, which
/// no unit normal produces (the darkest, `−(1,1,1)/√3`, encodes to ≈ 0.21 per channel).
///
/// # Errors
/// [`Error::Empty`] for a zero-sized image; [`Error::Io`] / [`Error::Image`] if writing fails.
#[allow(
    clippy::expect_used,
    reason = "the buffer holds 3 samples per pixel by construction"
)]
pub fn write_normal_png(
    normals: &Rgb32FImage,
    path: impl AsRef<Path>,
    bits: NormalBits,
) -> Result<()> {
    let (w, h) = normals.dimensions();
    require_pixels(w, h, "normal map (zero-sized)")?;
    let path = path.as_ref();
    match bits {
        NormalBits::Eight => save_png(&normals_rgb8(normals), path),
        NormalBits::Sixteen => {
            let data = encode_normals(normals, f32::from(u16::MAX), |v| v as u16, 0u16);
            save_png(
                &Rgb16Image::from_raw(w, h, data).expect("3 samples per pixel"),
                path,
            )
        }
    }
}

fn decode_normals<T: Copy + Into<f32> + PartialEq + Default>(raw: &[T], max: f32) -> Vec<f32> {
    raw.chunks_exact(3)
        .flat_map(|c| {
            if c.iter().all(|v| *v == T::default()) {
                return [f32::NAN; 3];
            }
            let n = [0, 1, 2].map(|i| c[i].into() / max * 2.0 - 1.0);
            let len = n.iter().map(|v| v * v).sum::<f32>().sqrt();
            if len > MIN_NORMAL_NORM {
                n.map(|v| v / len)
            } else {
                [f32::NAN; 3]
            }
        })
        .collect()
}

/// Reads a normal map written by [`write_normal_png`] (8- or 16-bit RGB): `n = 2·colour − 1`,
/// renormalised; black pixels → NaN normals (missing).
///
/// # Errors
/// [`Error::Io`] / [`Error::Image`] for unreadable files; [`Error::Parse`] if the PNG is not
/// RGB.
#[allow(
    clippy::expect_used,
    reason = "the buffer holds 3 samples per pixel by construction"
)]
pub fn read_normal_png(path: impl AsRef<Path>) -> Result<Rgb32FImage> {
    let img = read_png(path.as_ref())?;
    let (w, h) = (img.width(), img.height());
    let data = match &img {
        DynamicImage::ImageRgb8(b) => decode_normals(b.as_raw(), f32::from(u8::MAX)),
        DynamicImage::ImageRgb16(b) => decode_normals(b.as_raw(), f32::from(u16::MAX)),
        other => {
            return Err(Error::Parse {
                format: "normal-map PNG",
                line: 0,
                message: format!("expected 8- or 16-bit RGB, found {:?}", other.color()),
            })
        }
    };
    // 3 samples per pixel by construction.
    Ok(Rgb32FImage::from_raw(w, h, data).expect("3 samples per pixel"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use std::path::PathBuf;

    fn tmp(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("skin_core_image_io_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir.join(name)
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(16))]
        #[test]
        fn mask_png_round_trip_is_exact(
            (w, h, flags) in (1u32..24, 1u32..24).prop_flat_map(|(w, h)| {
                (Just(w), Just(h), proptest::collection::vec(any::<bool>(), (w * h) as usize))
            }),
            id in 0u32..1_000_000,
        ) {
            let m = Mask::from_bools(w, h, &flags).unwrap();
            let p = tmp(&format!("mask_{id}.png"));
            write_mask_png(&m, &p).unwrap();
            prop_assert_eq!(read_mask_png(&p).unwrap(), m);
            std::fs::remove_file(&p).ok();
        }
    }

    #[test]
    fn depth_png16_round_trip_within_quantisation() {
        for enc in [
            DepthEncoding::default(),
            DepthEncoding {
                scale_m: 1e-3,
                offset_m: 0.5,
            },
        ] {
            let (lo, hi) = enc.range_m();
            let depth = GrayF32Image::from_fn(37, 23, |x, y| {
                let v = match (x + 3 * y) % 11 {
                    0 => f32::NAN,
                    1 => 0.0,
                    2 => f32::INFINITY,
                    3 => -1.0,
                    _ => (lo + (hi - lo) * 0.999 * f64::from(x * 23 + y) / (37.0 * 23.0)) as f32,
                };
                Luma([v])
            });
            let p = tmp(&format!("depth_{}.png", enc.scale_m));
            write_depth_png16(&depth, &p, &enc).unwrap();
            let back = read_depth_png16(&p, &enc).unwrap();
            assert_eq!(back.dimensions(), depth.dimensions());
            for (&a, &b) in depth.as_raw().iter().zip(back.as_raw()) {
                if is_valid_depth(a) {
                    let err = (f64::from(a) - f64::from(b)).abs();
                    // Half a quantum plus f32 rounding of values up to ~66 m.
                    assert!(err <= 0.5 * enc.scale_m + 1e-5 * f64::from(a), "{a} vs {b}");
                } else {
                    assert!(b.is_nan(), "no data must read back as NaN, got {b}");
                }
            }
        }
    }

    #[test]
    fn depth_out_of_range_and_bad_encodings_are_errors() {
        let d = GrayF32Image::from_pixel(2, 2, Luma([10.0]));
        let p = tmp("depth_bad.png");
        assert!(matches!(
            write_depth_png16(&d, &p, &DepthEncoding::default()),
            Err(Error::InvalidParam { .. })
        ));
        let bad = DepthEncoding {
            scale_m: 0.0,
            offset_m: 0.0,
        };
        assert!(matches!(
            write_depth_png16(&d, &p, &bad),
            Err(Error::InvalidParam { .. })
        ));
        assert!(matches!(
            write_depth_png16(&GrayF32Image::new(0, 2), &p, &DepthEncoding::default()),
            Err(Error::Empty { .. })
        ));
        // An 8-bit PNG is not a depth PNG.
        write_mask_png(&Mask::new(3, 3), &p).unwrap();
        assert!(matches!(
            read_depth_png16(&p, &DepthEncoding::default()),
            Err(Error::Parse { .. })
        ));
        assert!(matches!(read_normal_png(&p), Err(Error::Parse { .. })));
    }

    #[test]
    fn false_colour_depth_marks_no_data_black_and_orders_depth() {
        let d = GrayF32Image::from_fn(10, 1, |x, _| {
            Luma([if x == 0 {
                f32::NAN
            } else {
                1.0 + x as f32 * 0.1
            }])
        });
        let range = DepthRange {
            near_m: 1.1,
            far_m: 1.9,
        };
        let img = depth_false_colour(&d, &range).unwrap();
        assert_eq!(img.get_pixel(0, 0).0, [0, 0, 0]);
        for x in 1..10 {
            assert_ne!(img.get_pixel(x, 0).0, [0, 0, 0]);
        }
        // Near is bluer than far, far is redder than near.
        let (n, f) = (img.get_pixel(1, 0).0, img.get_pixel(9, 0).0);
        assert!(n[2] > f[2] && f[0] > n[0]);
        let p = tmp("depth_colour.png");
        write_depth_false_colour_png(&d, &p, &range).unwrap();
        assert_eq!(::image::open(&p).unwrap().to_rgb8(), img);
        let inverted = DepthRange {
            near_m: 2.0,
            far_m: 1.0,
        };
        assert!(matches!(
            depth_false_colour(&d, &inverted),
            Err(Error::InvalidParam { .. })
        ));
    }

    #[test]
    fn normal_png_round_trip() {
        let normals = Rgb32FImage::from_fn(19, 13, |x, y| {
            if (x + y) % 7 == 0 {
                return Rgb([f32::NAN, 0.0, 0.0]);
            }
            if (x + y) % 7 == 1 {
                return Rgb([0.0, 0.0, 0.0]);
            }
            let th = x as f32 * 0.31 + 0.1;
            let ph = y as f32 * 0.23 - 1.4;
            // Include non-unit input: it is normalised on write.
            let s = 1.0 + 0.5 * ((x % 3) as f32);
            Rgb([
                s * ph.cos() * th.cos(),
                s * ph.cos() * th.sin(),
                s * ph.sin(),
            ])
        });
        for (bits, tol) in [
            (NormalBits::Eight, 1.2 / 255.0),
            (NormalBits::Sixteen, 1e-4),
        ] {
            let p = tmp(&format!("normals_{bits:?}.png"));
            write_normal_png(&normals, &p, bits).unwrap();
            let back = read_normal_png(&p).unwrap();
            for (a, b) in normals.pixels().zip(back.pixels()) {
                match unit_normal(a) {
                    None => assert!(b.0.iter().all(|v| v.is_nan())),
                    Some(n) => {
                        for i in 0..3 {
                            assert!((n[i] - b.0[i]).abs() < 2.0 * tol, "{n:?} vs {:?}", b.0);
                        }
                    }
                }
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(48))]
        /// Randomly corrupted PNG bytes never panic: every reader returns a value or an error.
        #[test]
        fn corrupted_png_bytes_never_panic(
            edits in proptest::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..8),
            cut in any::<prop::sample::Index>(),
            id in 0u32..1_000_000,
        ) {
            let src = tmp(&format!("fuzz_src_{id}.png"));
            let depth = GrayF32Image::from_fn(9, 7, |x, y| Luma([0.5 + (x * y) as f32 * 0.01]));
            write_depth_png16(&depth, &src, &DepthEncoding::default()).unwrap();
            let mut bytes = std::fs::read(&src).unwrap();
            for (i, v) in &edits {
                let k = i.index(bytes.len());
                bytes[k] = *v;
            }
            bytes.truncate(cut.index(bytes.len()) + 1);
            let p = tmp(&format!("fuzz_{id}.png"));
            std::fs::write(&p, &bytes).unwrap();
            let _ = read_mask_png(&p);
            let _ = read_depth_png16(&p, &DepthEncoding::default());
            let _ = read_normal_png(&p);
            std::fs::remove_file(&p).ok();
            std::fs::remove_file(&src).ok();
        }
    }

    #[test]
    fn corrupt_and_missing_files_are_errors() {
        let p = tmp("corrupt.png");
        std::fs::write(&p, b"\x89PNG\r\n\x1a\nthis is not a png at all").unwrap();
        assert!(matches!(read_mask_png(&p), Err(Error::Image(_))));
        assert!(matches!(
            read_depth_png16(&p, &DepthEncoding::default()),
            Err(Error::Image(_))
        ));
        assert!(matches!(read_normal_png(&p), Err(Error::Image(_))));
        // A valid PNG cut in half.
        let good = tmp("good.png");
        write_mask_png(&Mask::from_fn(40, 40, |x, y| (x ^ y) & 1 == 1), &good).unwrap();
        let bytes = std::fs::read(&good).unwrap();
        std::fs::write(&p, &bytes[..bytes.len() / 2]).unwrap();
        assert!(read_mask_png(&p).is_err());
        std::fs::write(&p, b"").unwrap();
        assert!(read_mask_png(&p).is_err());
        let missing = tmp("does_not_exist.png");
        assert!(matches!(read_mask_png(&missing), Err(Error::Io { .. })));
        assert!(matches!(
            write_mask_png(&Mask::new(0, 0), &p),
            Err(Error::Empty { .. })
        ));
        let bad_dir = tmp("no_such_dir").join("x.png");
        assert!(matches!(
            write_mask_png(&Mask::new(2, 2), &bad_dir),
            Err(Error::Io { .. })
        ));
    }
}
