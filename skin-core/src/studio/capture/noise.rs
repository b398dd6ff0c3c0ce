//! Seeded per-pixel sensor noise, reproducible for any subset of frames and cameras.

use rayon::prelude::*;

use super::spec::PixelNoise;
use crate::mesh::shapes::SplitMix64;
use crate::studio::shading::ShadedView;

/// Key of the noise stream of one `(seed, frame, camera)`: the three mixed through
/// SplitMix64 so neighbouring frames and cameras get unrelated streams.
fn stream(seed: u64, frame: usize, camera: usize) -> SplitMix64 {
    let a = SplitMix64::new(seed).u64_at(frame as u64);
    SplitMix64::new(SplitMix64::new(a).u64_at(camera as u64))
}

/// Adds zero-mean Gaussian noise of `noise.sigma` to every pixel and channel of `view`;
/// deviate `3·pixel + channel` of the `(seed, frame, camera)` stream (Box–Muller on two
/// counter-based uniforms), so the result does not depend on evaluation order.
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
    let unit = (-53f64).exp2();
    let row = (view.width as usize).max(1);
    view.radiance
        .par_chunks_mut(row)
        .enumerate()
        .for_each(|(y, pixels)| {
            for (x, px) in pixels.iter_mut().enumerate() {
                let p = (y * row + x) as u64;
                for (c, v) in px.iter_mut().enumerate() {
                    let i = 2 * (3 * p + c as u64);
                    let u1 = (s.u64_at(i) >> 11) as f64 * unit;
                    let u2 = (s.u64_at(i + 1) >> 11) as f64 * unit;
                    let g = (-2.0 * (1.0 - u1).ln()).sqrt() * (std::f64::consts::TAU * u2).cos();
                    *v += noise.sigma * g as f32;
                }
            }
        });
}
