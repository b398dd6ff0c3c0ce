//! Speed of needle-length accumulation (Sand 2003 §4.3): the Table 3.1 needle set (6 600
//! needles) walked through 720×480 silhouettes of the procedural performer from 3 cameras,
//! 4 frames of fast motion per iteration (12 camera-frames), parallel over frames.
//! Throughput is reported in camera-frames per second.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)] // not library code

// criterion_group!/criterion_main! generate undocumented public functions.
#![allow(missing_docs)]

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use needle_model::{BodyLayout, FrameInput, NeedleBody, ObserveParams, Observer};
use skin_core::camera::{Intrinsics, Rig};
use skin_core::image::Mask;
use skin_core::math::DVec3;
use skin_core::raster::{Buffers, Rasterizer, RenderParams};
use skin_core::studio::{
    fast_motion, procedural_performer, DeformationState, FastMotionParams, ProceduralBodyParams,
};

const FRAMES: usize = 4;

fn bench(c: &mut Criterion) {
    let performer = procedural_performer(&ProceduralBodyParams::default()).expect("performer");
    let motion = fast_motion(&performer.skeleton, &FastMotionParams::default()).expect("motion");
    let k = Intrinsics::from_horizontal_fov(55f64.to_radians(), 720, 480).expect("intrinsics");
    let cameras = Rig::ring(3, 3.5, 1.1, DVec3::new(0.0, 0.95, 0.0), DVec3::Y, k)
        .expect("rig")
        .cameras;
    let params = RenderParams::default().with_buffers(Buffers::MASK_ONLY);
    let mut state = DeformationState::default();
    let mut thetas = vec![];
    let mut masks: Vec<Vec<Mask>> = vec![];
    for f in 0..FRAMES * 15 {
        let theta = motion.frame(f).to_vec();
        let posed = performer
            .pose(&theta, &mut state, motion.frame_time_s)
            .expect("pose");
        if f % 15 != 0 {
            continue;
        }
        let mesh = performer.mesh(posed.true_vertices);
        masks.push(
            cameras
                .iter()
                .map(|cam| {
                    let v = Rasterizer::new(cam).render(&mesh, &params).expect("render");
                    Mask::from_fn(v.width, v.height, |x, y| v.mask[v.index(x, y)] != 0)
                })
                .collect(),
        );
        thetas.push(theta);
    }
    let sk = performer.skeleton.clone();
    let body = NeedleBody::new(&sk, &BodyLayout::table_3_1()).expect("body");
    let observer =
        Observer::new(body, sk, cameras.clone(), ObserveParams::default()).expect("observer");
    let frames: Vec<FrameInput> = thetas
        .iter()
        .zip(&masks)
        .map(|(t, m)| FrameInput { theta: t, masks: m })
        .collect();
    let acc = observer.accumulate(&frames).expect("accumulate");
    eprintln!(
        "accumulate: {} observations from {} walks, {:.3} bytes/observation",
        acc.stats.accepted,
        acc.stats.walks,
        acc.store.bytes_per_observation()
    );
    let mut g = c.benchmark_group("accumulate");
    g.throughput(Throughput::Elements((FRAMES * cameras.len()) as u64));
    g.bench_function("table_3_1_720x480_camera_frames", |b| {
        b.iter(|| observer.accumulate(black_box(&frames)).expect("accumulate"))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
