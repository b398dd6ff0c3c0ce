//! §3.2.3 motion compensation: forward and backward flow from a central tracking frame to its
//! neighbouring tracking frames, linear motion between them, the six pattern frames warped to
//! the central frame, and per-pixel confidence from the warped tracking frames' error.

use serde::{Deserialize, Serialize};
use skin_core::image::{GrayF32Image, Mask};

use crate::cycle::Pattern;
use crate::flow::{dense_flow, warp, Flow, FlowParams};
use crate::patterns::PatternImages;
use crate::{Error, Result};

/// Options of [`compensate_motion`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MotionParams {
    /// The optical flow.
    pub flow: FlowParams,
    /// Largest error `|F_neighbour(x + u(x)) − F_centre(x)|` of a confident pixel, as a
    /// fraction of the central frame's intensity at the pixel (the thesis: "below some
    /// threshold", not given). Default: 0.1.
    pub max_relative_error: f32,
}

impl Default for MotionParams {
    fn default() -> Self {
        Self {
            flow: FlowParams::default(),
            max_relative_error: 0.1,
        }
    }
}

/// The pattern images of one tracking frame with the motion removed.
#[derive(Debug, Clone)]
pub struct CompensatedFrame {
    /// The six half-on images warped to the central tracking frame, and that frame as F.
    pub images: PatternImages,
    /// Pixels where both flows are confident (the others are to be marked invalid).
    pub confident: Mask,
    /// Flow from the central to the previous tracking frame.
    pub backward: Flow,
    /// Flow from the central to the next tracking frame.
    pub forward: Flow,
}

/// §3.2.3: nine consecutive frames centred on a tracking frame — `[F, P₁, P₂, P₃, F, Q₁,
/// Q₂, Q₃, F]` (e.g. frames 3–11 of two 8-frame cycles: `F X̄ Ȳ Z̄ F X Y Z F`) — to the
/// pattern images of the central frame: `P_d` (three quarters to one quarter of the interval
/// before the centre) is warped by `d/4` of the backward flow, `Q_d` by `d/4` of the forward
/// flow. The six `P`, `Q` must be the six half-on patterns, each once.
///
/// # Errors
/// [`Error::SizeMismatch`] for not nine frames or frames of different sizes;
/// [`Error::InvalidParam`] for a tracking position that is not [`Pattern::Full`] or a full
/// frame elsewhere; [`Error::MissingPattern`] when a half-on pattern is missing; flow errors.
pub fn compensate_motion(
    frames: &[(Pattern, &GrayF32Image)],
    params: &MotionParams,
) -> Result<CompensatedFrame> {
    if frames.len() != 9 {
        return Err(Error::SizeMismatch {
            what: "frames around a tracking frame",
            expected: 9,
            got: frames.len(),
        });
    }
    for (i, (p, _)) in frames.iter().enumerate() {
        if (i % 4 == 0) != (*p == Pattern::Full) {
            return Err(Error::InvalidParam {
                name: "frames",
                reason: format!(
                    "positions 0, 4 and 8 are the tracking frames (F) and only they; got {p:?} at {i}"
                ),
            });
        }
    }
    skin_core::check::non_negative("max_relative_error", f64::from(params.max_relative_error))?;
    let (prev, centre, next) = (frames[0].1, frames[4].1, frames[8].1);
    let backward = dense_flow(centre, prev, &params.flow)?;
    let forward = dense_flow(centre, next, &params.flow)?;
    let mut images = vec![(Pattern::Full, centre.clone())];
    for (i, (p, im)) in frames.iter().enumerate() {
        let (flow, d) = match i {
            1..=3 => (&backward, 4 - i),
            5..=7 => (&forward, i - 4),
            _ => continue,
        };
        images.push((*p, warp(im, flow, d as f32 / 4.0)?));
    }
    let images = PatternImages::new(images)?;
    let eb = warp(prev, &backward, 1.0)?;
    let ef = warp(next, &forward, 1.0)?;
    let tol = params.max_relative_error;
    let flags: Vec<bool> = centre
        .as_raw()
        .iter()
        .zip(eb.as_raw().iter().zip(ef.as_raw()))
        .map(|(&c, (&b, &f))| (b - c).abs() <= tol * c.abs() && (f - c).abs() <= tol * c.abs())
        .collect();
    let confident = Mask::from_bools(centre.width(), centre.height(), &flags)?;
    Ok(CompensatedFrame {
        images,
        confident,
        backward,
        forward,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cycle::PATTERNS;

    /// A textured surface under a pattern-dependent brightness, translated by `t` px.
    fn frame(p: Pattern, t: f32) -> GrayF32Image {
        let gain = 0.5 + 0.07 * p.index() as f32;
        GrayF32Image::from_fn(96, 96, |x, y| {
            let (x, y) = (x as f32 - t, y as f32 - 0.5 * t);
            let tex = 0.5
                + 0.15 * (0.31 * x + 0.17 * y).sin()
                + 0.1 * (0.23 * y - 0.11 * x).cos()
                + 0.05 * (0.47 * x).sin();
            image::Luma([gain * tex])
        })
    }

    #[test]
    fn warps_pattern_frames_to_the_central_tracking_frame() {
        use Pattern::*;
        let order = [Full, XBar, YBar, ZBar, Full, X, Y, Z, Full];
        // Linear motion: 0.75 px per frame.
        let moving: Vec<GrayF32Image> = order
            .iter()
            .enumerate()
            .map(|(i, &p)| frame(p, 0.75 * (i as f32 - 4.0)))
            .collect();
        let frames: Vec<(Pattern, &GrayF32Image)> =
            order.iter().copied().zip(moving.iter()).collect();
        let c = compensate_motion(&frames, &MotionParams::default()).unwrap();
        let inner = |im: &GrayF32Image, p: Pattern| {
            let still = frame(p, 0.0);
            let mut e = 0.0f32;
            for y in 16..80 {
                for x in 16..80 {
                    e += (im.get_pixel(x, y)[0] - still.get_pixel(x, y)[0]).abs();
                }
            }
            e / (64.0 * 64.0)
        };
        for p in PATTERNS {
            let raw = &moving[order.iter().position(|&q| q == p).unwrap()];
            let (after, before) = (inner(c.images.image(p), p), inner(raw, p));
            assert!(
                after < 0.2 * before.max(1e-6) || after < 1e-3,
                "{p:?}: {after} vs {before}"
            );
        }
        assert!(c.confident.count() > 90 * 90 / 2);
        // Errors: wrong count, a pattern where a tracking frame belongs.
        assert!(compensate_motion(&frames[..8], &MotionParams::default()).is_err());
        let mut bad = frames.clone();
        bad.swap(0, 1);
        assert!(matches!(
            compensate_motion(&bad, &MotionParams::default()),
            Err(Error::InvalidParam { .. })
        ));
    }
}
