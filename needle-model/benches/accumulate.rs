//! Speed of needle-length accumulation (Sand 2003 §4.3): the Table 3.1 needle set (6 600
//! needles) walked through 720×480 silhouettes of the procedural performer from 3 cameras,
//! 4 frames of fast motion per iteration (12 camera-frames), parallel over frames.
//! Throughput is reported in camera-frames per second.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)] // not library code

// criterion_group!/criterion_main! generate undocumented public functions.
#![allow(missing_docs)]

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use dynamic_shapes_studio::{
    fast_motion, procedural_performer, studio_ring, Capture, CaptureFrame, CaptureSpec,
    FastMotionParams, ProceduralBodyParams,
};
use needle_model::{BodyLayout, FrameInput, NeedleBody, ObserveParams, Observer};

const FRAMES: usize = 4;

fn bench(c: &mut Criterion) {
    let performer = procedural_performer(&ProceduralBodyParams::default()).expect("performer");
    let motion = fast_motion(&performer.skeleton, &FastMotionParams::default()).expect("motion");
    let rig = studio_ring(3, 720, 480).expect("rig");
    let cameras = rig.cameras.clone();
    let spec = CaptureSpec::masks_only(rig).with_frame_rate_hz(1.0 / motion.frame_time_s);
    let capture = Capture::new(&performer, &motion, spec).expect("capture");
    let captured: Vec<CaptureFrame> = capture
        .frames_stepped(0..FRAMES * 15, 15)
        .collect::<Result<_, _>>()
        .expect("frames");
    let masks: Vec<_> = captured.iter().map(CaptureFrame::masks).collect();
    let thetas: Vec<_> = captured.iter().map(|f| f.truth.theta.clone()).collect();
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
