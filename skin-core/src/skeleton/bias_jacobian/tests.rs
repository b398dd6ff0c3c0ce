//! Central finite differences of the existing `J̇θ̇`, `J` and `J_ω θ̇` against the analytic
//! pose derivatives, on the human skeleton and on a chain mixing oblique rotation axes with
//! translation DOFs (before, between and after rotations).

use crate::math::{DQuat, DVec3};
use crate::skeleton::*;
use crate::Error;
use nalgebra::DMatrix;
use proptest::prelude::*;

/// A 5-joint chain with a branch: translations at the root, between rotations and at a leaf.
fn mixed_chain() -> Skeleton {
    let axis = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
    Skeleton::new(vec![
        Joint::new(
            "root",
            None,
            axis(0.1, 0.9, 0.0),
            vec![
                Dof::translation("root.tx", DVec3::X, None),
                Dof::translation("root.ty", DVec3::Y, None),
                Dof::rotation("root.ry", DVec3::Y, None),
                Dof::rotation("root.rq", axis(0.3, -0.2, 0.9), None),
            ],
        ),
        Joint::new(
            "a",
            Some(0),
            axis(0.0, 0.3, 0.1),
            vec![
                Dof::rotation("a.rx", DVec3::X, None),
                Dof::translation("a.slide", axis(0.2, 1.0, -0.4), None),
                Dof::rotation("a.rz", DVec3::Z, None),
            ],
        ),
        Joint::new(
            "b",
            Some(1),
            axis(0.25, -0.05, 0.0),
            vec![Dof::rotation("b.ro", axis(-0.5, 0.4, 0.7), None)],
        ),
        Joint::new("c", Some(2), axis(0.0, -0.2, 0.15), vec![]),
        Joint::new(
            "d",
            Some(0),
            axis(-0.2, -0.1, 0.0),
            vec![
                Dof::rotation("d.rx", DVec3::X, None),
                Dof::translation("d.t", DVec3::Z, None),
            ],
        ),
    ])
    .unwrap()
}

struct Case {
    skeleton: Skeleton,
    theta: Vec<f64>,
    theta_dot: Vec<f64>,
    y: Vec<f64>,
    points: Vec<AttachedPoint>,
    frames: Vec<AttachedFrame>,
}

fn case(human: bool, values: &[f64]) -> Case {
    let skeleton = if human {
        human_skeleton(&HumanParams::default()).unwrap()
    } else {
        mixed_chain()
    };
    let n = skeleton.dof_count();
    let v = |i: usize| values[i % values.len()];
    let theta = (0..n).map(|i| 1.4 * v(i)).collect();
    let theta_dot = (0..n).map(|i| 2.0 * v(i + n)).collect();
    let y = (0..n).map(|i| 3.0 * v(i + 2 * n)).collect();
    let nj = skeleton.joint_count();
    let points = (0..nj)
        .map(|j| AttachedPoint {
            joint: j,
            offset: DVec3::new(v(j), v(j + 1), v(j + 2)) * 0.2,
        })
        .collect();
    let frames = (0..nj)
        .map(|j| AttachedFrame {
            joint: j,
            joint_from_frame: DQuat::from_scaled_axis(DVec3::new(v(j + 3), v(j), v(j + 5))),
        })
        .collect();
    Case {
        skeleton,
        theta,
        theta_dot,
        y,
        points,
        frames,
    }
}

fn shifted(v: &[f64], d: usize, h: f64) -> Vec<f64> {
    let mut out = v.to_vec();
    out[d] += h;
    out
}

/// J̇θ̇ of every point at (θ, θ̇), by the existing recursive sweep.
fn bias(c: &Case, theta: &[f64], theta_dot: &[f64]) -> Vec<DVec3> {
    let s = &c.skeleton;
    let fk = s.forward_kinematics(theta).unwrap();
    let rates = s.rates(theta, theta_dot, &fk).unwrap();
    let mut out = vec![DVec3::ZERO; c.points.len()];
    s.point_bias_accelerations_into(&fk, &rates, &c.points, &mut out)
        .unwrap();
    out
}

/// J y of every point at θ.
fn j_times(c: &Case, theta: &[f64]) -> Vec<DVec3> {
    let s = &c.skeleton;
    let fk = s.forward_kinematics(theta).unwrap();
    let j = s.point_jacobians(&fk, &c.points).unwrap();
    let r = j * nalgebra::DVector::from_column_slice(&c.y);
    (0..c.points.len())
        .map(|i| DVec3::new(r[3 * i], r[3 * i + 1], r[3 * i + 2]))
        .collect()
}

fn gyro(c: &Case, theta: &[f64], axes: AngularFrame) -> Vec<DVec3> {
    let s = &c.skeleton;
    let fk = s.forward_kinematics(theta).unwrap();
    let rates = s.rates(theta, &c.theta_dot, &fk).unwrap();
    c.frames
        .iter()
        .map(|f| rates.frame_angular_velocity(&fk, f, axes).unwrap())
        .collect()
}

fn col(m: &DMatrix<f64>, i: usize, d: usize) -> DVec3 {
    DVec3::new(m[(3 * i, d)], m[(3 * i + 1, d)], m[(3 * i + 2, d)])
}

fn assert_fd(analytic: &DMatrix<f64>, f: impl Fn(usize, f64) -> Vec<DVec3>, what: &str) {
    let h = 1e-6;
    for d in 0..analytic.ncols() {
        let (p, m) = (f(d, h), f(d, -h));
        for i in 0..p.len() {
            let num = (p[i] - m[i]) / (2.0 * h);
            let a = col(analytic, i, d);
            assert!(
                (a - num).length() <= 1e-5 * (1.0 + num.length()),
                "{what}: point {i}, DOF {d}: analytic {a} vs numeric {num}"
            );
        }
    }
}

fn check(c: &Case) {
    let s = &c.skeleton;
    let (rows, n) = (3 * c.points.len(), s.dof_count());
    let fk = s.forward_kinematics(&c.theta).unwrap();
    let mut dt = DMatrix::zeros(rows, n);
    let mut dd = DMatrix::zeros(rows, n);
    s.point_bias_acceleration_jacobians_into(&fk, &c.theta_dot, &c.points, &mut dt, &mut dd)
        .unwrap();
    assert_fd(
        &dt,
        |d, h| bias(c, &shifted(&c.theta, d, h), &c.theta_dot),
        "d(Jdot thetadot)/dtheta",
    );
    assert_fd(
        &dd,
        |d, h| bias(c, &c.theta, &shifted(&c.theta_dot, d, h)),
        "d(Jdot thetadot)/dthetadot",
    );
    let mut jy = DMatrix::zeros(rows, n);
    s.point_jacobian_product_jacobians_into(&fk, &c.y, &c.points, &mut jy)
        .unwrap();
    assert_fd(
        &jy,
        |d, h| j_times(c, &shifted(&c.theta, d, h)),
        "d(J y)/dtheta",
    );
    for axes in [AngularFrame::World, AngularFrame::Local] {
        let mut g = DMatrix::zeros(3 * c.frames.len(), n);
        s.frame_angular_velocity_jacobians_into(&fk, &c.theta_dot, &c.frames, axes, &mut g)
            .unwrap();
        assert_fd(
            &g,
            |d, h| gyro(c, &shifted(&c.theta, d, h), axes),
            "d(J_w thetadot)/dtheta",
        );
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]
    #[test]
    fn derivatives_match_finite_differences(
        human in any::<bool>(),
        values in proptest::collection::vec(-1.0f64..1.0, 7..31),
    ) {
        check(&case(human, &values));
    }
}

#[test]
fn bias_rate_jacobian_is_twice_jdot() {
    let c = case(true, &[0.3, -0.7, 0.5, 0.1, -0.9, 0.8, -0.2]);
    let s = &c.skeleton;
    let fk = s.forward_kinematics(&c.theta).unwrap();
    let rates = s.rates(&c.theta, &c.theta_dot, &fk).unwrap();
    let rows = 3 * c.points.len();
    let mut dt = DMatrix::zeros(rows, s.dof_count());
    let mut dd = DMatrix::zeros(rows, s.dof_count());
    s.point_bias_acceleration_jacobians_into(&fk, &c.theta_dot, &c.points, &mut dt, &mut dd)
        .unwrap();
    let mut jdot = DMatrix::zeros(rows, s.dof_count());
    s.point_jacobian_derivatives_into(&fk, &rates, &c.points, &mut jdot)
        .unwrap();
    assert!((dd - 2.0 * jdot).amax() < 1e-12);
}

#[test]
fn bad_sizes_and_values_are_errors() {
    let c = case(false, &[0.5, -0.5, 0.25]);
    let s = &c.skeleton;
    let fk = s.forward_kinematics(&c.theta).unwrap();
    let n = s.dof_count();
    let mut ok = DMatrix::zeros(3 * c.points.len(), n);
    let mut bad = DMatrix::zeros(3, n);
    let r = s.point_bias_acceleration_jacobians_into(
        &fk,
        &c.theta_dot,
        &c.points,
        &mut ok.clone(),
        &mut bad,
    );
    assert!(matches!(r, Err(Error::SizeMismatch { .. })));
    let mut nan = c.theta_dot.clone();
    nan[0] = f64::NAN;
    let r = s.point_jacobian_product_jacobians_into(&fk, &nan, &c.points, &mut ok);
    assert!(r.is_err());
    let far = [AttachedPoint {
        joint: 99,
        offset: DVec3::ZERO,
    }];
    let mut one = DMatrix::zeros(3, n);
    let r = s.point_jacobian_product_jacobians_into(&fk, &c.y, &far, &mut one);
    assert!(matches!(r, Err(Error::IndexOutOfRange { .. })));
}
