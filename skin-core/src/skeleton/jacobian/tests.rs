//! Finite-difference checks of the analytic Jacobians, their derivatives and `J̇θ̇`, on random
//! skeletons (random trees, axes, rotation and translation DOFs) and on the human skeleton.

use crate::math::{DQuat, DVec3};
use crate::skeleton::*;
use crate::Error;
use nalgebra::{DMatrix, DVector};
use proptest::prelude::*;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

struct Case {
    skeleton: Skeleton,
    theta: Vec<f64>,
    theta_dot: Vec<f64>,
    points: Vec<AttachedPoint>,
    frames: Vec<AttachedFrame>,
}

fn unit(rng: &mut ChaCha8Rng) -> DVec3 {
    loop {
        let v = DVec3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        if v.length() > 0.2 {
            return v.normalize();
        }
    }
}

fn random_case(seed: u64) -> Case {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let skeleton = if seed.is_multiple_of(4) {
        human_skeleton(&HumanParams::default()).unwrap()
    } else {
        let n = rng.random_range(1..8usize);
        let joints = (0..n)
            .map(|i| {
                let n_dof = rng.random_range(0..4usize);
                let dofs = (0..n_dof)
                    .map(|k| {
                        let axis = if rng.random_bool(0.5) {
                            DVec3::AXES[rng.random_range(0..3usize)]
                        } else {
                            unit(&mut rng)
                        };
                        if rng.random_bool(0.2) {
                            Dof::translation(format!("j{i}.t{k}"), axis * 2.0, None)
                        } else {
                            Dof::rotation(format!("j{i}.r{k}"), axis, None)
                        }
                    })
                    .collect();
                let parent = (i > 0).then(|| rng.random_range(0..i));
                Joint::new(
                    format!("j{i}"),
                    parent,
                    unit(&mut rng) * rng.random_range(0.0..0.5),
                    dofs,
                )
            })
            .collect();
        Skeleton::new(joints).unwrap()
    };
    let n = skeleton.dof_count();
    let theta = (0..n).map(|_| rng.random_range(-1.5..1.5)).collect();
    let theta_dot = (0..n).map(|_| rng.random_range(-2.0..2.0)).collect();
    let nj = skeleton.joint_count();
    let points = (0..6)
        .map(|_| AttachedPoint {
            joint: rng.random_range(0..nj),
            offset: unit(&mut rng) * rng.random_range(0.0..0.3),
        })
        .collect();
    let frames = (0..6)
        .map(|_| AttachedFrame {
            joint: rng.random_range(0..nj),
            joint_from_frame: DQuat::from_scaled_axis(unit(&mut rng) * rng.random_range(0.0..3.0)),
        })
        .collect();
    Case {
        skeleton,
        theta,
        theta_dot,
        points,
        frames,
    }
}

fn axpy(theta: &[f64], t: f64, dir: &[f64]) -> Vec<f64> {
    theta.iter().zip(dir).map(|(a, b)| a + t * b).collect()
}

fn positions(s: &Skeleton, theta: &[f64], points: &[AttachedPoint]) -> Vec<DVec3> {
    let fk = s.forward_kinematics(theta).unwrap();
    points.iter().map(|p| fk.point(p).unwrap()).collect()
}

fn rotations(s: &Skeleton, theta: &[f64], frames: &[AttachedFrame]) -> Vec<DQuat> {
    let fk = s.forward_kinematics(theta).unwrap();
    frames
        .iter()
        .map(|f| fk.frame_rotation(f).unwrap())
        .collect()
}

fn block(m: &DMatrix<f64>, i: usize, col: usize) -> DVec3 {
    DVec3::new(m[(3 * i, col)], m[(3 * i + 1, col)], m[(3 * i + 2, col)])
}

fn mat_vec(m: &DMatrix<f64>, v: &[f64]) -> Vec<DVec3> {
    let r = m * DVector::from_column_slice(v);
    (0..m.nrows() / 3)
        .map(|i| DVec3::new(r[3 * i], r[3 * i + 1], r[3 * i + 2]))
        .collect()
}

fn close(a: DVec3, b: DVec3, tol: f64, what: &str) {
    assert!(
        (a - b).length() <= tol * (1.0 + b.length()),
        "{what}: analytic {a} vs numeric {b}"
    );
}

/// Angular velocity ω with R(t+h) R(t−h)ᵀ ≈ exp(2h [ω]×).
fn angular_rate(plus: DQuat, minus: DQuat, h: f64) -> DVec3 {
    let mut d = plus * minus.inverse();
    if d.w < 0.0 {
        d = -d;
    }
    d.to_scaled_axis() / (2.0 * h)
}

fn check_case(c: &Case) {
    let s = &c.skeleton;
    let n = s.dof_count();
    let fk = s.forward_kinematics(&c.theta).unwrap();
    let rates = s.rates(&c.theta, &c.theta_dot, &fk).unwrap();
    let jp = s.point_jacobians(&fk, &c.points).unwrap();
    let jw = s
        .frame_jacobians(&fk, &c.frames, AngularFrame::World)
        .unwrap();
    let jl = s
        .frame_jacobians(&fk, &c.frames, AngularFrame::Local)
        .unwrap();
    let rot0 = rotations(s, &c.theta, &c.frames);

    // J and J_ω column by column against central differences of FK.
    let h = 1e-6;
    for k in 0..n {
        let mut e = vec![0.0; n];
        e[k] = 1.0;
        let pp = positions(s, &axpy(&c.theta, h, &e), &c.points);
        let pm = positions(s, &axpy(&c.theta, -h, &e), &c.points);
        let rp = rotations(s, &axpy(&c.theta, h, &e), &c.frames);
        let rm = rotations(s, &axpy(&c.theta, -h, &e), &c.frames);
        for i in 0..c.points.len() {
            close(block(&jp, i, k), (pp[i] - pm[i]) / (2.0 * h), 1e-7, "J");
        }
        for i in 0..c.frames.len() {
            let w = angular_rate(rp[i], rm[i], h);
            close(block(&jw, i, k), w, 1e-7, "J_omega world");
            close(
                block(&jl, i, k),
                rot0[i].inverse() * w,
                1e-7,
                "J_omega local",
            );
        }
    }

    // Velocities agree with J θ̇.
    let v = mat_vec(&jp, &c.theta_dot);
    for (i, p) in c.points.iter().enumerate() {
        close(
            rates.point_velocity(&fk, p).unwrap(),
            v[i],
            1e-12,
            "point velocity",
        );
    }
    let w = mat_vec(&jl, &c.theta_dot);
    for (i, f) in c.frames.iter().enumerate() {
        close(
            rates
                .frame_angular_velocity(&fk, f, AngularFrame::Local)
                .unwrap(),
            w[i],
            1e-12,
            "gyro",
        );
    }

    // J̇θ̇ = d/dt (J(θ + tθ̇) θ̇) at t = 0, and J̇ = d/dt J(θ + tθ̇).
    let ht = 1e-5;
    let tp = axpy(&c.theta, ht, &c.theta_dot);
    let tm = axpy(&c.theta, -ht, &c.theta_dot);
    let (fkp, fkm) = (
        s.forward_kinematics(&tp).unwrap(),
        s.forward_kinematics(&tm).unwrap(),
    );
    let jp_dot_num = (s.point_jacobians(&fkp, &c.points).unwrap()
        - s.point_jacobians(&fkm, &c.points).unwrap())
        / (2.0 * ht);
    let mut jp_dot = DMatrix::zeros(3 * c.points.len(), n);
    s.point_jacobian_derivatives_into(&fk, &rates, &c.points, &mut jp_dot)
        .unwrap();
    let mut bias = vec![DVec3::ZERO; c.points.len()];
    s.point_bias_accelerations_into(&fk, &rates, &c.points, &mut bias)
        .unwrap();
    let bias_num = mat_vec(&jp_dot_num, &c.theta_dot);
    let bias_mat = mat_vec(&jp_dot, &c.theta_dot);
    for i in 0..c.points.len() {
        for k in 0..n {
            close(
                block(&jp_dot, i, k),
                block(&jp_dot_num, i, k),
                1e-6,
                "J dot",
            );
        }
        close(bias[i], bias_num[i], 1e-6, "J dot theta dot (point)");
        close(
            bias[i],
            bias_mat[i],
            1e-10,
            "recursive vs matrix J dot theta dot",
        );
    }
    // Independent of J: second difference of FK positions along θ(t) = θ + tθ̇.
    let h2 = 1e-4;
    let p0 = positions(s, &c.theta, &c.points);
    let p2p = positions(s, &axpy(&c.theta, h2, &c.theta_dot), &c.points);
    let p2m = positions(s, &axpy(&c.theta, -h2, &c.theta_dot), &c.points);
    for i in 0..c.points.len() {
        close(
            bias[i],
            (p2p[i] - 2.0 * p0[i] + p2m[i]) / (h2 * h2),
            1e-4,
            "FK second difference",
        );
    }

    for axes in [AngularFrame::World, AngularFrame::Local] {
        let jf_p = s.frame_jacobians(&fkp, &c.frames, axes).unwrap();
        let jf_m = s.frame_jacobians(&fkm, &c.frames, axes).unwrap();
        let num = (jf_p - jf_m) / (2.0 * ht);
        let mut ana = DMatrix::zeros(3 * c.frames.len(), n);
        s.frame_jacobian_derivatives_into(&fk, &rates, &c.frames, axes, &mut ana)
            .unwrap();
        let mut fb = vec![DVec3::ZERO; c.frames.len()];
        s.frame_bias_accelerations_into(&fk, &rates, &c.frames, axes, &mut fb)
            .unwrap();
        let num_b = mat_vec(&num, &c.theta_dot);
        for i in 0..c.frames.len() {
            for k in 0..n {
                close(block(&ana, i, k), block(&num, i, k), 1e-6, "J_omega dot");
            }
            close(fb[i], num_b[i], 1e-6, "J_omega dot theta dot");
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]
    #[test]
    fn jacobians_match_finite_differences(seed in any::<u64>()) {
        check_case(&random_case(seed));
    }
}

#[test]
fn human_skeleton_jacobians_match_finite_differences() {
    for seed in [0, 4, 8] {
        check_case(&random_case(seed));
    }
}

#[test]
fn fk_of_simple_chain() {
    // Two-link planar arm: rotate root by 90° about Z, elbow by -90°.
    let s = Skeleton::new(vec![
        Joint::new(
            "a",
            None,
            DVec3::ZERO,
            vec![Dof::rotation("a", DVec3::Z, None)],
        ),
        Joint::new(
            "b",
            Some(0),
            DVec3::X,
            vec![Dof::rotation("b", DVec3::Z, None)],
        )
        .with_end_site(DVec3::X),
    ])
    .unwrap();
    let fk = s
        .forward_kinematics(&[std::f64::consts::FRAC_PI_2, -std::f64::consts::FRAC_PI_2])
        .unwrap();
    close(
        fk.world_from_joint()[1].translation,
        DVec3::Y,
        1e-15,
        "elbow",
    );
    let tip = fk
        .point(&AttachedPoint {
            joint: 1,
            offset: DVec3::X,
        })
        .unwrap();
    close(tip, DVec3::new(1.0, 1.0, 0.0), 1e-15, "tip");
    let j = s
        .point_jacobians(
            &fk,
            &[AttachedPoint {
                joint: 1,
                offset: DVec3::X,
            }],
        )
        .unwrap();
    // d tip / d a = z × (1,1,0) = (-1,1,0); d tip / d b = z × (1,0,0) = (0,1,0).
    close(block(&j, 0, 0), DVec3::new(-1.0, 1.0, 0.0), 1e-15, "col a");
    close(block(&j, 0, 1), DVec3::new(0.0, 1.0, 0.0), 1e-15, "col b");
}

#[test]
fn bad_inputs_are_errors() {
    let s = human_skeleton(&HumanParams::default()).unwrap();
    let n = s.dof_count();
    assert!(matches!(
        s.forward_kinematics(&vec![0.0; n - 1]),
        Err(Error::SizeMismatch { .. })
    ));
    let mut theta = vec![0.0; n];
    theta[s.dof_index("l_knee.flexion").unwrap()] = f64::NAN;
    let msg = s.forward_kinematics(&theta).unwrap_err().to_string();
    assert!(msg.contains("l_knee"), "{msg}");
    let fk = s.forward_kinematics(&s.rest_pose()).unwrap();
    assert!(matches!(
        s.rates(&s.rest_pose(), &vec![0.0; n + 1], &fk),
        Err(Error::SizeMismatch { .. })
    ));
    let bad = AttachedPoint {
        joint: 99,
        offset: DVec3::ZERO,
    };
    assert!(matches!(
        s.point_jacobians(&fk, &[bad]),
        Err(Error::IndexOutOfRange { .. })
    ));
    let badf = AttachedFrame {
        joint: 99,
        joint_from_frame: DQuat::IDENTITY,
    };
    assert!(matches!(
        s.frame_jacobians(&fk, &[badf], AngularFrame::World),
        Err(Error::IndexOutOfRange { .. })
    ));
    let good = AttachedPoint {
        joint: 3,
        offset: DVec3::ZERO,
    };
    let mut wrong = DMatrix::zeros(3, n - 1);
    assert!(matches!(
        s.point_jacobians_into(&fk, &[good], &mut wrong),
        Err(Error::SizeMismatch { .. })
    ));
    let rates = s.rates(&s.rest_pose(), &s.rest_pose(), &fk).unwrap();
    let mut short = vec![DVec3::ZERO; 0];
    assert!(matches!(
        s.point_bias_accelerations_into(&fk, &rates, &[good], &mut short),
        Err(Error::SizeMismatch { .. })
    ));
    // Buffers of another skeleton.
    let other = Skeleton::new(vec![Joint::new("x", None, DVec3::ZERO, vec![])]).unwrap();
    let mut fk_other = ForwardKinematics::new(&other);
    assert!(matches!(
        s.forward_kinematics_into(&s.rest_pose(), &mut fk_other),
        Err(Error::SizeMismatch { .. })
    ));
    assert!(matches!(
        s.point_jacobians(&fk_other, &[]),
        Err(Error::SizeMismatch { .. })
    ));
}
