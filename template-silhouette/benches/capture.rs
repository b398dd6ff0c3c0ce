//! Speed of the stages of Vlasic 2010 Ch. 2 on one studio frame: the MakeHuman body (13,380
//! vertices) in the exercise motion, 8 ring cameras at 1600 × 1200 (the setting).
//!
//! * `observe_8x1600x1200`: the visual hull (cone distance transforms, polygonal hull) and the
//!   contour rays of one frame (§2.3.2, §2.4.2).
//! * `pose_fit_frame`: one frame's pose (§2.3.1) from the previous frame's, with the two
//!   refinement rounds and their shape solves (what the forward pass does per frame).
//! * `shape_refine_one_solve`: one Eq. 2.2 iteration (constraints from the rays, one numeric
//!   refactorisation and solve) at `w_L = 1` — Algorithm 1 makes six per frame.
//!
//! `cargo bench -p template-silhouette --bench capture -- --noplot`.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)] // not library code
#![allow(missing_docs)] // criterion_group! generates an undocumented public function

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion};
use dynamic_shapes_studio::{
    exercise_motion, makehuman_performer, Capture, CaptureSpec, DeformationParams, ExerciseParams,
};
use skin_core::camera::{Intrinsics, Rig};
use skin_core::math::DVec3;
use template_silhouette::{
    fit_frame, ContourRayHullParams, FrameObservation, PoseFrame, PoseModel, PoseParams,
    ShapeEstimator, ShapeParams, SilhouetteParams, Template, Temporal,
};

fn bench(c: &mut Criterion) {
    let performer = makehuman_performer(
        example_kit::data_path("makehuman").expect("data"),
        &DeformationParams::default(),
    )
    .expect("performer");
    let motion = exercise_motion(&performer.skeleton, &ExerciseParams::default()).expect("motion");
    let root = performer
        .skeleton
        .forward_kinematics(motion.frame(0))
        .expect("fk")
        .joint_positions()[0];
    let k = Intrinsics::from_horizontal_fov(55f64.to_radians(), 1600, 1200).expect("k");
    let rig = Rig::ring(8, 3.5, root.y + 0.15, root, DVec3::Y, k).expect("rig");
    let cameras = rig.cameras.clone();
    let spec = CaptureSpec::masks_only(rig).with_frame_rate_hz(1.0 / motion.frame_time_s);
    let capture = Capture::new(&performer, &motion, spec).expect("capture");
    let frames: Vec<_> = capture
        .frames_stepped(40..44, 2)
        .collect::<Result<_, _>>()
        .expect("frames");
    let masks = frames[1].masks();
    let (hull, sil) = (ContourRayHullParams::default(), SilhouetteParams::default());
    let obs = FrameObservation::new(&cameras, &masks, &hull, &sil).expect("observe");
    let template = Template::new(
        performer.template.clone(),
        performer.skeleton.clone(),
        performer.weights.clone(),
    )
    .expect("template");
    let params = PoseParams::default();
    let model = PoseModel::new(&template, &params).expect("model");
    let mut estimator = ShapeEstimator::new(template.clone(), ShapeParams::default()).expect("se");
    let previous = frames[0].truth.theta.clone();
    let frame = PoseFrame {
        hull: &obs.hull,
        rays: &obs.rays,
        user: &[],
    };
    let temporal = Temporal {
        previous: Some(&previous),
        next: None,
    };
    let theta = frames[1].truth.theta.clone();
    let lbs = template.skin(&theta).expect("skin");

    let mut g = c.benchmark_group("template_capture");
    g.sample_size(10);
    g.bench_function("observe_8x1600x1200", |b| {
        b.iter(|| FrameObservation::new(&cameras, black_box(&masks), &hull, &sil).expect("obs"))
    });
    g.bench_function("pose_fit_frame", |b| {
        b.iter(|| {
            fit_frame(
                &model,
                &frame,
                temporal,
                black_box(&previous),
                Some(&mut estimator),
                &params,
            )
            .expect("fit")
        })
    });
    g.bench_function("shape_refine_one_solve", |b| {
        b.iter(|| {
            estimator
                .refine(&theta, black_box(&lbs), 1.0, &obs.rays)
                .expect("refine")
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
