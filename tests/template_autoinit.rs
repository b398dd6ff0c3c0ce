//! Automatic first-frame initialisation of the template tracker (issue 12, "use it"): the
//! MakeHuman performer (body only) in the exercise motion, 8 cameras; `initialise_pose` from
//! the first frame's visual hull and contour rays only (no markers, no stereo points, no user
//! constraint), scored against the true pose and against the baseline that could have won
//! (the rest pose moved to the hull's centroid, then the same robust ellipsoid fit).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)] // not library code

use std::time::Instant;

use dynamic_shapes::core::camera::{Intrinsics, Rig};
use dynamic_shapes::core::math::DVec3;
use dynamic_shapes::core::skeleton::Skeleton;
use dynamic_shapes::core::stats::mean;
use dynamic_shapes::core::studio::{
    exercise_motion, makehuman_performer, Capture, CaptureSpec, DeformationParams, ExerciseParams,
};
use dynamic_shapes::template::{
    fit_ellipsoids, initial_pose_score, initialise_pose, AutoInitParams, EllipsoidModel,
    EllipsoidObservations, FrameObservation, SilhouetteParams, VisualHullParams,
};

/// Mean joint position error (mm) and mean bone direction error (degrees).
fn pose_errors(sk: &Skeleton, theta: &[f64], truth: &[f64]) -> (f64, f64, Vec<f64>) {
    let est = sk.forward_kinematics(theta).unwrap().joint_positions();
    let tru = sk.forward_kinematics(truth).unwrap().joint_positions();
    let joint: Vec<f64> = est
        .iter()
        .zip(&tru)
        .map(|(a, b)| 1e3 * a.distance(*b))
        .collect();
    let angles: Vec<f64> = sk
        .joints()
        .iter()
        .enumerate()
        .filter_map(|(j, joint)| {
            let p = joint.parent?;
            let (a, b) = (est[j] - est[p], tru[j] - tru[p]);
            Some(
                a.normalize()
                    .dot(b.normalize())
                    .clamp(-1.0, 1.0)
                    .acos()
                    .to_degrees(),
            )
        })
        .collect();
    (mean(&joint), mean(&angles), angles)
}

#[test]
fn automatic_first_pose_beats_the_rest_pose_start() {
    let performer = makehuman_performer(
        example_kit::data_path("makehuman").unwrap(),
        &DeformationParams::default(),
    )
    .unwrap();
    let motion = exercise_motion(&performer.skeleton, &ExerciseParams::default()).unwrap();
    let root = performer
        .skeleton
        .forward_kinematics(motion.frame(40))
        .unwrap()
        .joint_positions()[0];
    let k = Intrinsics::from_horizontal_fov(55f64.to_radians(), 480, 360).unwrap();
    let rig = Rig::ring(8, 3.5, root.y + 0.15, root, DVec3::Y, k).unwrap();
    let cameras = rig.cameras.clone();
    let spec = CaptureSpec::masks_only(rig).with_frame_rate_hz(1.0 / motion.frame_time_s);
    let capture = Capture::new(&performer, &motion, spec).unwrap();
    let sk = &performer.skeleton;
    let model = EllipsoidModel::with_end_sites(sk.clone(), 0.1).unwrap();
    let params = AutoInitParams::default();
    for f in [40usize, 60] {
        let frame = capture.frames_stepped(f..f + 1, 1).next().unwrap().unwrap();
        let truth = &frame.truth.theta;
        let obs = FrameObservation::new(
            &cameras,
            &frame.masks(),
            &VisualHullParams::default(),
            &SilhouetteParams::default(),
        )
        .unwrap();
        let t = Instant::now();
        let auto = initialise_pose(&model, &obs.hull, &obs.rays, &params).unwrap();
        let auto_s = t.elapsed().as_secs_f64();
        let v = &obs.hull.polygon().vertices;
        let points: Vec<DVec3> = v
            .iter()
            .step_by(v.len().div_ceil(params.points))
            .copied()
            .collect();
        let centroid = points.iter().fold(DVec3::ZERO, |a, p| a + *p) / points.len() as f64;
        let mut rest = sk.rest_pose();
        let r0 = sk.forward_kinematics(&rest).unwrap().joint_positions()[0];
        for (r, d) in rest.iter_mut().zip((centroid - r0).to_array()) {
            *r += d;
        }
        let rest_fit = fit_ellipsoids(
            &model,
            &model.initial_state(&rest, params.half_width_m).unwrap(),
            &EllipsoidObservations {
                points,
                markers: Vec::new(),
                rays: obs.rays.clone(),
            },
            &params.fit,
        )
        .unwrap();
        let (a_mm, a_deg, a_all) = pose_errors(sk, auto.theta(), truth);
        let (g_mm, g_deg, _) = pose_errors(sk, &auto.global.theta, truth);
        let (r_mm, r_deg, _) = pose_errors(sk, &rest_fit.state.theta, truth);
        println!(
            "frame {f}: automatic {a_mm:.0} mm {a_deg:.1} deg (global step {g_mm:.0} mm \
             {g_deg:.1} deg, {} candidates, {auto_s:.2} s); rest start {r_mm:.0} mm {r_deg:.1} deg",
            auto.evaluations
        );
        println!(
            "  headings {:?}; true pose scores {:.3}",
            auto.headings,
            initial_pose_score(&model, &obs.hull, truth, &params).unwrap()
        );
        println!("  truth root {:?}", &truth[..6]);
        println!("  auto  root {:?}", &auto.theta()[..6]);
        println!(
            "  per-bone deg {:?}",
            a_all.iter().map(|a| a.round()).collect::<Vec<_>>()
        );
        assert!(a_deg < r_deg && a_mm < r_mm);
    }
}
