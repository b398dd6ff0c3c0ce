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
mod tests;
