//! Seeded per-pixel sensor noise, reproducible for any subset of frames and cameras.

use rayon::prelude::*;

use super::spec::PixelNoise;
use crate::shading::ShadedView;
use skin_core::random::SplitMix64;

/// Key of the noise stream of one `(seed, frame, camera)`: the three mixed through
/// SplitMix64 so neighbouring frames and cameras get unrelated streams.
fn stream(seed: u64, frame: usize, camera: usize) -> SplitMix64 {
    let a = SplitMix64::new(seed).u64_at(frame as u64);
    SplitMix64::new(SplitMix64::new(a).u64_at(camera as u64))
}

/// Adds zero-mean Gaussian noise of `noise.sigma` to every pixel and channel of `view`;
/// deviate `3·pixel + channel` of the `(seed, frame, camera)` stream
/// ([`SplitMix64::normal_at`], counter-based), so the result does not depend on evaluation
/// order.
pub(super) fn add(
    view: &mut ShadedView,
    noise: &PixelNoise,
    seed: u64,
    frame: usize,
    camera: usize,
) {
    if noise.sigma == 0.0 {
        return;
    }
    let s = stream(seed, frame, camera);
    let row = (view.width as usize).max(1);
    view.radiance
        .par_chunks_mut(row)
        .enumerate()
        .for_each(|(y, pixels)| {
            for (x, px) in pixels.iter_mut().enumerate() {
                let p = (y * row + x) as u64;
                for (c, v) in px.iter_mut().enumerate() {
                    let g = s.normal_at(3 * p + c as u64);
                    *v += noise.sigma * g as f32;
                }
            }
        });
}
