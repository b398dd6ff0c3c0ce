//! Skeleton kinematics speed: FK + Jacobians of the 42-DOF human skeleton with 18 attached
//! sensors (the sensor count of Vlasic thesis §4.2), as one EKF measurement update needs.
//!
//! Cases: `fk_point_jacobians` (FK + 54×42 positional Jacobian), and
//! `fk_inertial_terms` (FK + rate sweep + positional and local orientational Jacobians +
//! `J̇θ̇` of 18 points + `J̇_ω θ̇` of 18 frames).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)] // not library code

// criterion_group!/criterion_main! generate undocumented public functions.
#![allow(missing_docs)]

use criterion::{criterion_group, criterion_main, Criterion};
use nalgebra::DMatrix;
use skin_core::math::{DQuat, DVec3};
use skin_core::skeleton::{
    human_skeleton, AngularFrame, AttachedFrame, AttachedPoint, ForwardKinematics, HumanParams,
    JointRates, Skeleton,
};
use std::hint::black_box;

/// 18 sensors: one mid-bone on each of the 17 joints with DOFs, plus one on the chest front.
fn sensors(s: &Skeleton) -> (Vec<AttachedPoint>, Vec<AttachedFrame>) {
    let mut points: Vec<AttachedPoint> = (0..s.joint_count())
        .filter(|&j| !s.joints()[j].dofs.is_empty())
        .map(|j| {
            let along = s.joints()[j]
                .end_site
                .or_else(|| s.children(j).next().map(|c| s.joints()[c].offset))
                .unwrap_or(DVec3::ZERO);
            AttachedPoint {
                joint: j,
                offset: along * 0.5 + DVec3::new(0.0, 0.0, 0.05),
            }
        })
        .collect();
    points.push(AttachedPoint {
        joint: s.joint_index("chest").unwrap_or(0),
        offset: DVec3::new(0.0, 0.1, 0.12),
    });
    let frames = points
        .iter()
        .enumerate()
        .map(|(i, p)| AttachedFrame {
            joint: p.joint,
            joint_from_frame: DQuat::from_rotation_y(0.3 * i as f64),
        })
        .collect();
    (points, frames)
}

fn bench(c: &mut Criterion) {
    let s = human_skeleton(&HumanParams::default()).expect("default human skeleton is valid");
    let (points, frames) = sensors(&s);
    assert_eq!(points.len(), 18);
    let n = s.dof_count();
    let theta: Vec<f64> = (0..n)
        .map(|d| 0.3 * ((d * 7 % 11) as f64 / 11.0 - 0.5))
        .collect();
    let theta_dot: Vec<f64> = (0..n).map(|d| (d * 5 % 13) as f64 / 13.0 - 0.5).collect();
    let mut fk = ForwardKinematics::new(&s);
    let mut rates = JointRates::new(&s);
    let mut jp = DMatrix::zeros(3 * points.len(), n);
    let mut jw = DMatrix::zeros(3 * frames.len(), n);
    let mut pb = vec![DVec3::ZERO; points.len()];
    let mut fb = vec![DVec3::ZERO; frames.len()];

    c.bench_function("skeleton/fk_point_jacobians_42dof_18pts", |b| {
        b.iter(|| {
            s.forward_kinematics_into(black_box(&theta), &mut fk)
                .expect("valid pose");
            s.point_jacobians_into(&fk, &points, &mut jp)
                .expect("sized buffers");
            black_box(&jp);
        })
    });
    c.bench_function("skeleton/fk_inertial_terms_42dof_18sensors", |b| {
        b.iter(|| {
            s.forward_kinematics_into(black_box(&theta), &mut fk)
                .expect("valid pose");
            s.rates_into(&theta, black_box(&theta_dot), &fk, &mut rates)
                .expect("valid rates");
            s.point_jacobians_into(&fk, &points, &mut jp)
                .expect("sized buffers");
            s.frame_jacobians_into(&fk, &frames, AngularFrame::Local, &mut jw)
                .expect("sized buffers");
            s.point_bias_accelerations_into(&fk, &rates, &points, &mut pb)
                .expect("sized buffers");
            s.frame_bias_accelerations_into(&fk, &rates, &frames, AngularFrame::Local, &mut fb)
                .expect("sized buffers");
            black_box((&jp, &jw, &pb, &fb));
        })
    });
    c.bench_function("skeleton/fk_only_42dof", |b| {
        b.iter(|| {
            s.forward_kinematics_into(black_box(&theta), &mut fk)
                .expect("valid pose");
            black_box(&fk);
        })
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
