//! Background subtraction with a per-pixel threshold map (Sand 2003 thesis §4.2; Sand,
//! McMillan, Popović 2003 §4.2).
//!
//! Sand: "For each pixel, background subtraction finds the difference between the current frame
//! and an empty background frame and labels pixels with a high difference as part of the
//! foreground. Our system uses a large subtraction threshold to overcome shadows and video
//! compression artifacts. The threshold near the head is smaller [...]". The papers give no
//! numbers, so we use the standard statistical form of that scheme:
//!
//! * learn, from `N` frames of the empty scene, the per-pixel background mean `μᵢ` (a colour or
//!   grey vector) and the per-pixel deviation `σᵢ = sqrt(Σ_c s²ᵢ,c)` (sample standard deviation
//!   of each channel, combined over channels);
//! * per-pixel threshold `tᵢ = max(t_min, k·σᵢ)`: `k·σᵢ` rejects the camera noise of that pixel
//!   (flicker, compression), `t_min` is Sand's "large threshold" floor against shadows;
//! * pixel `i` of a frame `I` is foreground iff `‖Iᵢ − μᵢ‖₂ > tᵢ`.
//!
//! The threshold map can be edited after learning (Sand's smaller threshold near the head):
//! [`BackgroundModel::scale_thresholds_in`]. Optional clean-up ([`BackgroundParams`]) removes
//! specks and fills small holes (Vlasic 2010 §3.2.1, see
//! [`crate::image::remove_small_components`] and [`crate::image::fill_small_holes`]).
//!
//! Intensities are on a `[0, 1]` scale: `f32` images as given, `u8` images divided by 255.

use std::borrow::Cow;

use ::image::{GrayImage, Rgb32FImage, RgbImage};
use serde::{Deserialize, Serialize};

use super::cleanup::{fill_small_holes, remove_small_components};
use super::distance::GrayF32Image;
use super::mask::Mask;
use crate::error::{Error, Result};

impl BackgroundParams {
    /// Default multiple of the per-pixel deviation in the threshold. Not given by Sand; 3σ is the
    /// usual choice (it passes 99.7 % of Gaussian noise per channel; Stauffer–Grimson use 2.5σ,
    /// OpenCV MOG2 4σ).
    pub const DEFAULT_K_SIGMA: f32 = 3.0;

    /// Default floor of the per-pixel threshold, in intensity units on `[0, 1]` (≈ 25/255). Sand
    /// §4.2 uses "a large subtraction threshold to overcome shadows and video compression
    /// artifacts" without a value; 0.1 rejects 8-bit compression noise and soft shadows while
    /// keeping clothing that differs from the backdrop by a tenth of full scale.
    pub const DEFAULT_MIN_THRESHOLD: f32 = 0.1;

    /// Default minimum area of a kept foreground component, pixels (a 4×4 speck). Not in Sand.
    pub const DEFAULT_MIN_COMPONENT_PX: usize = 16;

    /// Default largest hole that is filled, pixels (Vlasic §3.2.1 fills "small gaps"; no value).
    pub const DEFAULT_MAX_HOLE_PX: usize = 16;
}

/// Knobs of background learning and classification.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct BackgroundParams {
    /// Multiple `k` of the per-pixel deviation σᵢ in the threshold `tᵢ = max(t_min, k·σᵢ)`,
    /// dimensionless. Source: standard practice (Sand §4.2 gives no value).
    /// Default: [`BackgroundParams::DEFAULT_K_SIGMA`] = 3.
    pub k_sigma: f32,
    /// Threshold floor `t_min`, intensity units on `[0, 1]`. Source: Sand §4.2 ("large
    /// subtraction threshold", no value). Default: [`BackgroundParams::DEFAULT_MIN_THRESHOLD`] =
    /// 0.1.
    pub min_threshold: f32,
    /// Foreground 8-connected components smaller than this many pixels are removed after
    /// classification; 0 disables. Default: [`BackgroundParams::DEFAULT_MIN_COMPONENT_PX`] = 16.
    pub min_component_px: usize,
    /// Enclosed 4-connected background holes of at most this many pixels are filled after
    /// classification (Vlasic 2010 §3.2.1); 0 disables. Default:
    /// [`BackgroundParams::DEFAULT_MAX_HOLE_PX`] = 16.
    pub max_hole_px: usize,
}

impl Default for BackgroundParams {
    fn default() -> Self {
        BackgroundParams {
            k_sigma: BackgroundParams::DEFAULT_K_SIGMA,
            min_threshold: BackgroundParams::DEFAULT_MIN_THRESHOLD,
            min_component_px: BackgroundParams::DEFAULT_MIN_COMPONENT_PX,
            max_hole_px: BackgroundParams::DEFAULT_MAX_HOLE_PX,
        }
    }
}

impl BackgroundParams {
    /// Sets [`BackgroundParams::k_sigma`].
    pub fn with_k_sigma(mut self, k: f32) -> Self {
        self.k_sigma = k;
        self
    }
    /// Sets [`BackgroundParams::min_threshold`].
    pub fn with_min_threshold(mut self, t: f32) -> Self {
        self.min_threshold = t;
        self
    }
    /// Sets [`BackgroundParams::min_component_px`] (0 disables speck removal).
    pub fn with_min_component_px(mut self, px: usize) -> Self {
        self.min_component_px = px;
        self
    }
    /// Sets [`BackgroundParams::max_hole_px`] (0 disables hole filling).
    pub fn with_max_hole_px(mut self, px: usize) -> Self {
        self.max_hole_px = px;
        self
    }
    /// Disables both clean-up steps (raw per-pixel classification).
    pub fn without_cleanup(self) -> Self {
        self.with_min_component_px(0).with_max_hole_px(0)
    }

    fn validate(&self) -> Result<()> {
        crate::check::non_negative("k_sigma", f64::from(self.k_sigma))?;
        crate::check::non_negative("min_threshold", f64::from(self.min_threshold))?;
        Ok(())
    }
}

/// An image usable as a video frame for background subtraction: any number of interleaved
/// channels, intensities on `[0, 1]`.
pub trait BackgroundFrame {
    /// `(width, height)` in pixels.
    fn frame_dimensions(&self) -> (u32, u32);
    /// Channels per pixel (1 grey, 3 colour).
    fn channels(&self) -> usize;
    /// Interleaved samples, row-major, on a `[0, 1]` scale.
    fn samples(&self) -> Cow<'_, [f32]>;
}

impl BackgroundFrame for Rgb32FImage {
    fn frame_dimensions(&self) -> (u32, u32) {
        self.dimensions()
    }
    fn channels(&self) -> usize {
        3
    }
    fn samples(&self) -> Cow<'_, [f32]> {
        Cow::Borrowed(self.as_raw())
    }
}

impl BackgroundFrame for GrayF32Image {
    fn frame_dimensions(&self) -> (u32, u32) {
        self.dimensions()
    }
    fn channels(&self) -> usize {
        1
    }
    fn samples(&self) -> Cow<'_, [f32]> {
        Cow::Borrowed(self.as_raw())
    }
}

/// Scale of 8-bit samples to `[0, 1]`.
const U8_SCALE: f32 = 1.0 / 255.0;

impl BackgroundFrame for RgbImage {
    fn frame_dimensions(&self) -> (u32, u32) {
        self.dimensions()
    }
    fn channels(&self) -> usize {
        3
    }
    fn samples(&self) -> Cow<'_, [f32]> {
        Cow::Owned(
            self.as_raw()
                .iter()
                .map(|&v| f32::from(v) * U8_SCALE)
                .collect(),
        )
    }
}

impl BackgroundFrame for GrayImage {
    fn frame_dimensions(&self) -> (u32, u32) {
        self.dimensions()
    }
    fn channels(&self) -> usize {
        1
    }
    fn samples(&self) -> Cow<'_, [f32]> {
        Cow::Owned(
            self.as_raw()
                .iter()
                .map(|&v| f32::from(v) * U8_SCALE)
                .collect(),
        )
    }
}

/// The learned background: per-pixel mean and threshold map (Sand §4.2).
///
/// Serialisable; deserialisation checks sizes and values, so a malformed file gives an error.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "BackgroundModelRepr")]
pub struct BackgroundModel {
    width: u32,
    height: u32,
    channels: usize,
    /// Per-pixel mean, interleaved like the frames, `[0, 1]` units.
    mean: Vec<f32>,
    /// Per-pixel deviation σᵢ (combined over channels), `[0, 1]` units.
    deviation: Vec<f32>,
    /// Per-pixel threshold tᵢ, `[0, 1]` units.
    threshold: Vec<f32>,
    params: BackgroundParams,
}

/// Unvalidated serialised form of [`BackgroundModel`].
#[derive(Deserialize)]
struct BackgroundModelRepr {
    width: u32,
    height: u32,
    channels: usize,
    mean: Vec<f32>,
    deviation: Vec<f32>,
    threshold: Vec<f32>,
    params: BackgroundParams,
}

impl TryFrom<BackgroundModelRepr> for BackgroundModel {
    type Error = Error;
    fn try_from(r: BackgroundModelRepr) -> Result<Self> {
        if r.width == 0 || r.height == 0 || r.channels == 0 {
            return Err(Error::Empty {
                what: "serialised background model (zero size or channels)",
            });
        }
        r.params.validate()?;
        let n = r.width as usize * r.height as usize;
        for (what, v, len) in [
            ("serialised background mean", &r.mean, n * r.channels),
            ("serialised background deviation", &r.deviation, n),
            ("serialised background threshold", &r.threshold, n),
        ] {
            if v.len() != len {
                return Err(Error::SizeMismatch {
                    what,
                    expected: len,
                    got: v.len(),
                });
            }
            if v.iter().any(|x| !x.is_finite()) {
                return Err(Error::NonFinite { what });
            }
        }
        Ok(BackgroundModel {
            width: r.width,
            height: r.height,
            channels: r.channels,
            mean: r.mean,
            deviation: r.deviation,
            threshold: r.threshold,
            params: r.params,
        })
    }
}

/// The result of classifying one frame: the foreground mask and what clean-up changed.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Segmentation {
    /// Final foreground mask (after clean-up).
    pub mask: Mask,
    /// Foreground pixels straight from thresholding, before clean-up.
    pub raw_foreground_px: usize,
    /// Pixels removed as small components.
    pub removed_px: usize,
    /// Pixels added by hole filling.
    pub filled_px: usize,
}

fn check_frame<F: BackgroundFrame>(
    frame: &F,
    width: u32,
    height: u32,
    channels: usize,
) -> Result<()> {
    let (w, h) = frame.frame_dimensions();
    if w != width {
        return Err(Error::SizeMismatch {
            what: "frame width vs background model",
            expected: width as usize,
            got: w as usize,
        });
    }
    if h != height {
        return Err(Error::SizeMismatch {
            what: "frame height vs background model",
            expected: height as usize,
            got: h as usize,
        });
    }
    if frame.channels() != channels {
        return Err(Error::SizeMismatch {
            what: "frame channels vs background model",
            expected: channels,
            got: frame.channels(),
        });
    }
    Ok(())
}

impl BackgroundModel {
    /// Learns the background mean and the threshold map `tᵢ = max(t_min, k·σᵢ)` from frames of
    /// the empty scene (Sand §4.2). With a single frame σᵢ = 0 and the threshold is `t_min`.
    ///
    /// # Errors
    /// [`Error::Empty`] for no frames or zero-sized frames; [`Error::SizeMismatch`] if the
    /// frames differ in size; [`Error::NonFinite`] if a sample is NaN or infinite;
    /// [`Error::InvalidParam`] for negative or non-finite parameters.
    pub fn learn<F: BackgroundFrame>(frames: &[F], params: &BackgroundParams) -> Result<Self> {
        params.validate()?;
        let first = frames.first().ok_or(Error::Empty {
            what: "background frames",
        })?;
        let (width, height) = first.frame_dimensions();
        let channels = first.channels();
        if width == 0 || height == 0 || channels == 0 {
            return Err(Error::Empty {
                what: "background frame (zero width, height or channels)",
            });
        }
        let n = width as usize * height as usize * channels;
        // Welford's running mean and sum of squared deviations, in f64 for stability.
        let mut mean = vec![0f64; n];
        let mut m2 = vec![0f64; n];
        for (k, frame) in frames.iter().enumerate() {
            check_frame(frame, width, height, channels)?;
            let s = frame.samples();
            if s.iter().any(|v| !v.is_finite()) {
                return Err(Error::NonFinite {
                    what: "background frame sample",
                });
            }
            let count = (k + 1) as f64;
            for ((m, q), &v) in mean.iter_mut().zip(m2.iter_mut()).zip(s.iter()) {
                let v = f64::from(v);
                let d = v - *m;
                *m += d / count;
                *q += d * (v - *m);
            }
        }
        let denom = (frames.len().max(2) - 1) as f64;
        let deviation: Vec<f32> = m2
            .chunks_exact(channels)
            .map(|q| (q.iter().sum::<f64>() / denom).sqrt() as f32)
            .collect();
        let threshold = deviation
            .iter()
            .map(|&s| params.min_threshold.max(params.k_sigma * s))
            .collect();
        Ok(BackgroundModel {
            width,
            height,
            channels,
            mean: mean.iter().map(|&m| m as f32).collect(),
            deviation,
            threshold,
            params: *params,
        })
    }

    /// `(width, height)` of the frames this model accepts.
    pub fn dimensions(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// Channels per pixel of the frames this model accepts.
    pub fn channels(&self) -> usize {
        self.channels
    }

    /// The parameters used for learning and clean-up.
    pub fn params(&self) -> &BackgroundParams {
        &self.params
    }

    /// Per-pixel threshold map `tᵢ` as an image, `[0, 1]` units.
    pub fn threshold_map(&self) -> GrayF32Image {
        self.single_channel_image(&self.threshold)
    }

    /// Per-pixel background deviation `σᵢ` as an image, `[0, 1]` units.
    pub fn deviation_map(&self) -> GrayF32Image {
        self.single_channel_image(&self.deviation)
    }

    /// Per-pixel background mean, interleaved with [`BackgroundModel::channels`] channels.
    pub fn mean(&self) -> &[f32] {
        &self.mean
    }

    #[allow(
        clippy::expect_used,
        reason = "the buffer is built from width × height values"
    )]
    fn single_channel_image(&self, v: &[f32]) -> GrayF32Image {
        // `v` has one value per pixel by construction.
        GrayF32Image::from_raw(self.width, self.height, v.to_vec())
            .expect("per-pixel map has width * height values")
    }

    fn check_region(&self, region: &Mask) -> Result<()> {
        if region.dimensions() != (self.width, self.height) {
            return Err(Error::SizeMismatch {
                what: "threshold region pixels vs background model",
                expected: self.width as usize * self.height as usize,
                got: region.pixel_count(),
            });
        }
        Ok(())
    }

    /// Multiplies the threshold of every pixel in `region` by `factor`, e.g. `factor < 1`
    /// around the projected head where skin is close to the background colour (Sand §4.2).
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] if `region` has another size; [`Error::InvalidParam`] if
    /// `factor` is negative or not finite.
    pub fn scale_thresholds_in(&mut self, region: &Mask, factor: f32) -> Result<()> {
        self.update_thresholds_in(region, "factor", factor, |t| t * factor)
    }

    /// Sets the threshold of every pixel in `region` to `threshold` (`[0, 1]` units).
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] if `region` has another size; [`Error::InvalidParam`] if
    /// `threshold` is negative or not finite.
    pub fn set_thresholds_in(&mut self, region: &Mask, threshold: f32) -> Result<()> {
        self.update_thresholds_in(region, "threshold", threshold, |_| threshold)
    }

    /// Replaces the threshold `t` of every pixel in `region` by `update(t)`, after checking
    /// the region's size and that the parameter `name = value` is finite and ≥ 0.
    fn update_thresholds_in(
        &mut self,
        region: &Mask,
        name: &'static str,
        value: f32,
        update: impl Fn(f32) -> f32,
    ) -> Result<()> {
        self.check_region(region)?;
        crate::check::non_negative(name, f64::from(value))?;
        for (t, inside) in self.threshold.iter_mut().zip(region.iter()) {
            if inside {
                *t = update(*t);
            }
        }
        Ok(())
    }

    /// Classifies a frame: pixel `i` is foreground iff `‖Iᵢ − μᵢ‖₂ > tᵢ`, followed by the
    /// optional clean-up of [`BackgroundParams`].
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] if the frame's width, height or channel count differ from the
    /// model's; [`Error::NonFinite`] if a sample is NaN or infinite.
    pub fn classify<F: BackgroundFrame>(&self, frame: &F) -> Result<Segmentation> {
        check_frame(frame, self.width, self.height, self.channels)?;
        let s = frame.samples();
        if s.iter().any(|v| !v.is_finite()) {
            return Err(Error::NonFinite {
                what: "frame sample",
            });
        }
        let flags: Vec<bool> = s
            .chunks_exact(self.channels)
            .zip(self.mean.chunks_exact(self.channels))
            .zip(&self.threshold)
            .map(|((px, mu), &t)| {
                let d2: f32 = px.iter().zip(mu).map(|(a, b)| (a - b) * (a - b)).sum();
                d2 > t * t
            })
            .collect();
        let raw = Mask::from_bools(self.width, self.height, &flags)?;
        let raw_foreground_px = raw.count();
        let specks_removed = remove_small_components(&raw, self.params.min_component_px)?;
        let removed_px = raw_foreground_px - specks_removed.count();
        let mask = fill_small_holes(&specks_removed, self.params.max_hole_px)?;
        let filled_px = mask.count() - specks_removed.count();
        log::debug!(
            "background subtraction: {raw_foreground_px} px above threshold, \
             {removed_px} removed as specks, {filled_px} filled as holes"
        );
        Ok(Segmentation {
            mask,
            raw_foreground_px,
            removed_px,
            filled_px,
        })
    }
}

#[cfg(test)]
mod tests;
