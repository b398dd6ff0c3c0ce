//! Speed of the `skin_core::image` stages on a VGA (640×480) silhouette: exact signed distance
//! transform, contour extraction with normals, background classification of a colour frame,
//! and mask mismatch counting.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)] // not library code

// criterion_group!/criterion_main! generate undocumented public functions.
#![allow(missing_docs)]

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion};
use image::{Rgb, Rgb32FImage};
use skin_core::image::{
    distance_to_foreground, extract_contours, signed_distance, BackgroundModel, BackgroundParams,
    ContourParams, Mask,
};

const W: u32 = 640;
const H: u32 = 480;

/// A person-like silhouette: torso, head and two limbs as ellipses.
fn silhouette(shift: f64) -> Mask {
    let blobs = [
        (320.0 + shift, 260.0, 70.0, 130.0),
        (320.0 + shift, 110.0, 30.0, 38.0),
        (230.0 + shift, 250.0, 18.0, 110.0),
        (410.0 + shift, 250.0, 18.0, 110.0),
    ];
    Mask::from_fn(W, H, |x, y| {
        blobs.iter().any(|&(cx, cy, a, b)| {
            ((f64::from(x) - cx) / a).powi(2) + ((f64::from(y) - cy) / b).powi(2) <= 1.0
        })
    })
}

fn bench(c: &mut Criterion) {
    let m = silhouette(0.0);
    let m2 = silhouette(3.0);
    c.bench_function("signed_distance 640x480", |b| {
        b.iter(|| signed_distance(black_box(&m)).expect("non-empty silhouette"))
    });
    let params = ContourParams::default();
    c.bench_function("extract_contours 640x480", |b| {
        b.iter(|| extract_contours(black_box(&m), &params).expect("valid params"))
    });
    c.bench_function("mismatch_fraction 640x480", |b| {
        b.iter(|| {
            black_box(&m)
                .mismatch_fraction(&m2, None)
                .expect("same size")
        })
    });
    let backdrop = |x: u32, y: u32| Rgb([0.3 + 0.0004 * x as f32, 0.5 - 0.0003 * y as f32, 0.4]);
    let bg: Vec<Rgb32FImage> = (0..10)
        .map(|_| Rgb32FImage::from_fn(W, H, backdrop))
        .collect();
    let model = BackgroundModel::learn(&bg, &BackgroundParams::default()).expect("valid frames");
    let frame = Rgb32FImage::from_fn(W, H, |x, y| {
        let p = backdrop(x, y);
        if m.get(x, y) {
            Rgb([p.0[0] + 0.3, p.0[1], p.0[2]])
        } else {
            p
        }
    });
    c.bench_function("background classify 640x480 rgb", |b| {
        b.iter(|| model.classify(black_box(&frame)).expect("matching frame"))
    });
    let raw_model = BackgroundModel::learn(&bg, &BackgroundParams::default().without_cleanup())
        .expect("valid frames");
    c.bench_function("background classify 640x480 rgb, no clean-up", |b| {
        b.iter(|| {
            raw_model
                .classify(black_box(&frame))
                .expect("matching frame")
        })
    });
    c.bench_function("distance_to_foreground 640x480", |b| {
        b.iter(|| distance_to_foreground(black_box(&m)).expect("non-empty"))
    });
    c.bench_function("mask to_gray 640x480", |b| {
        b.iter(|| black_box(&m).to_gray())
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
