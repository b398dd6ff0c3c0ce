//! Speed of face tracking from video (§5.4.1, `track_video`, KLT included): a person the
//! bilinear 6 × 9 model never saw, 12 rendered 640 × 480 frames (neutral → smile → surprise
//! → neutral under head motion), 1,000 tracked vertices, 12 feature points, the default
//! parameters (3 passes). Runs on one thread (a one-thread rayon pool, so the KLT's parallel
//! loop stays on it); throughput in frames per second of one core. The fit's vertex error and
//! the frames per second of thread CPU time are printed once (a speed change must leave the
//! error alone).
//!
//! `cargo bench -p multilinear-face --features validation --bench track_video`
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stderr)] // not library code

// criterion_group!/criterion_main! generate undocumented public functions.
#![allow(missing_docs)]

use std::hint::black_box;
use std::path::Path;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use multilinear_face::validation::{
    aligned_rms, bilinear_face_set, face_width, feature_vertices, render_face_video, FaceSetParams,
    FaceVideoParams, IctBasis,
};
use multilinear_face::{track_video, ModelParams, MultilinearModel, VideoTrackParams};

const FRAMES: usize = 12;

fn bench(c: &mut Criterion) {
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/ict-face");
    let basis = IctBasis::read(&data).expect("ICT face basis (data/ict-face)");
    let bi = bilinear_face_set(&basis, &FaceSetParams::default()).expect("face set");
    let (model, _) =
        MultilinearModel::fit(&bi.faces, &ModelParams::thesis_bilinear()).expect("model");
    let person = bilinear_face_set(
        &basis,
        &FaceSetParams::default().with_identities(1).with_seed(99),
    )
    .expect("person");
    let tracked = feature_vertices(basis.neutral(), 1000).expect("tracked vertices");
    let features = feature_vertices(basis.neutral(), 12).expect("feature vertices");
    let video = render_face_video(
        &person.faces,
        &[0, 1, 3, 0],
        FRAMES,
        &bi.triangles,
        &basis.neutral().vertices,
        &features,
        &FaceVideoParams::default(),
    )
    .expect("video");
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("one-thread pool");
    let params = VideoTrackParams::default();
    let run = || {
        pool.install(|| {
            track_video(
                &model,
                &bi.triangles,
                &tracked,
                black_box(&video.frames),
                &video.features,
                &[false, true],
                &params,
            )
            .expect("track")
        })
    };
    // Thread CPU time of the pool's one thread (where `install` runs the tracking).
    let (track, cpu_s) = pool.install(|| {
        let cpu = cpu_time::ThreadTime::now();
        (run(), cpu.elapsed().as_secs_f64())
    });
    let width = face_width(&video.truth[0]);
    let err: f64 = track
        .weights
        .iter()
        .zip(&video.truth)
        .map(|(w, truth)| aligned_rms(&model.face(w).unwrap(), truth).unwrap() / width)
        .sum::<f64>()
        * 100.0
        / FRAMES as f64;
    eprintln!(
        "track_video: {err:.4} % vertex RMS, {:.1} fps of one core's thread CPU time, KLT {:.0} % \
         of the wall time",
        FRAMES as f64 / cpu_s,
        100.0 * track.klt_seconds / track.seconds
    );
    let mut g = c.benchmark_group("track_video");
    g.sample_size(10);
    g.throughput(Throughput::Elements(FRAMES as u64));
    g.bench_function("640x480_1000_vertices_one_thread", |b| b.iter(run));
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
