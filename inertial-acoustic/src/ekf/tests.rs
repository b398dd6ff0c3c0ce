use super::*;
use crate::params::GRAVITY_M_S2;
use skin_core::skeleton::{human_skeleton, HumanParams};

/// What the sensors see: world positions, orientations, velocities and angular
/// velocities of every board (and source positions).
fn sensed(ekf: &mut SkeletalEkf) -> Vec<[f64; 3]> {
    ekf.linearise().unwrap();
    let mut out = Vec::new();
    for p in &ekf.points {
        out.push(ekf.fk.point(p).unwrap().to_array());
        out.push(ekf.rates.point_velocity(&ekf.fk, p).unwrap().to_array());
    }
    for f in &ekf.frames {
        let q = ekf.fk.frame_rotation(f).unwrap();
        out.push((q * DVec3::X).to_array());
        out.push((q * DVec3::Y).to_array());
        let w = ekf
            .rates
            .frame_angular_velocity(&ekf.fk, f, AngularFrame::Local);
        out.push(w.unwrap().to_array());
    }
    out
}

/// Re-centring changes the chart, not the body: every sensor's pose and rates are the
/// same before and after, and the reported angles give the same joint rotations.
#[test]
fn recentring_keeps_what_the_sensors_see_and_the_reported_pose() {
    let skeleton = human_skeleton(&HumanParams::default()).unwrap();
    let suit = Suit::vlasic(&skeleton).unwrap();
    let mut pose = skeleton.rest_pose();
    let mut rates = vec![0.0; skeleton.dof_count()];
    for (i, name) in ["chest", "r_shoulder", "l_shoulder", "l_hip", "r_elbow"]
        .iter()
        .enumerate()
    {
        let j = skeleton.joint_index(name).unwrap();
        for (k, d) in skeleton.joint_dofs(j).enumerate() {
            pose[d] = 0.4 + 0.3 * (i + k) as f64 * if k == 1 { -1.0 } else { 1.0 };
            rates[d] = 0.5 - 0.4 * k as f64 + 0.2 * i as f64;
        }
    }
    let params = FilterParams::default().with_recentre_rad(0.3);
    let mut ekf = SkeletalEkf::new(skeleton.clone(), suit, &pose, params, &[]).unwrap();
    let nf = ekf.nf;
    for (d, s) in ekf.slot.clone().iter().enumerate() {
        ekf.x[nf + s.unwrap()] = rates[d];
    }
    let before = sensed(&mut ekf);
    ekf.symmetrise();
    ekf.recentre().unwrap();
    assert!(ekf.conj.iter().any(|g| *g != DMat3::IDENTITY));
    let after = sensed(&mut ekf);
    for (a, b) in before.iter().zip(&after) {
        for (x, y) in a.iter().zip(b) {
            assert!((x - y).abs() < 1e-9, "{a:?} vs {b:?}");
        }
    }
    ekf.sync_output();
    let fk_a = skeleton.forward_kinematics(&pose).unwrap();
    let fk_b = skeleton.forward_kinematics(ekf.theta()).unwrap();
    for (a, b) in fk_a.world_from_joint().iter().zip(fk_b.world_from_joint()) {
        assert!(a.abs_diff_eq(*b, 1e-9), "{a:?} vs {b:?}");
    }
}

/// Deferred block downdates (and the pending corrections of `P hᵀ`) give the textbook
/// sequential update `P ← P − P hᵀ h P / (h P hᵀ + r)` on a dense copy.
#[test]
fn deferred_downdates_match_dense_sequential_updates() {
    let skeleton = human_skeleton(&HumanParams::default()).unwrap();
    let suit = Suit::vlasic(&skeleton).unwrap();
    let rest = skeleton.rest_pose();
    let mut ekf = SkeletalEkf::new(skeleton, suit, &rest, FilterParams::default(), &[]).unwrap();
    let n = 3 * ekf.nf;
    // A correlated, symmetric positive definite P (two predictions from P0).
    ekf.predict().unwrap();
    ekf.predict().unwrap();
    ekf.symmetrise();
    let mut p = ekf.p.clone();
    let mut x = ekf.x.clone();
    ekf.x0.copy_from(&ekf.x);
    for k in 0..11 {
        ekf.row.clear();
        let mut h = DVector::<f64>::zeros(n);
        for j in 0..6 {
            let i = (17 * k + 29 * j + 3) % n;
            let v = 0.3 + 0.1 * j as f64 - 0.05 * k as f64;
            ekf.row.push(i, v);
            h[i] += v;
        }
        let (residual, r) = (0.01 * k as f64 - 0.02, 1e-3);
        // Dense reference: innovation at the linearisation point, corrected for the
        // updates so far (x − x0), as the filter's scalar updates do.
        let innov = residual - h.dot(&(&x - &ekf.x0));
        let ph = &p * &h;
        let s = h.dot(&ph) + r;
        x += &ph * (innov / s);
        p -= &ph * ph.transpose() / s;
        assert!(ekf.scalar_update(residual, r, 0.0, RobustLoss::None));
    }
    ekf.symmetrise();
    assert_eq!(ekf.npend, 0);
    let scale = p.amax();
    assert!(
        (&ekf.p - &p).amax() < 1e-12 * scale,
        "{}",
        (&ekf.p - &p).amax()
    );
    assert!((&ekf.x - &x).amax() < 1e-12);
}

#[test]
fn time_update_is_the_exact_constant_acceleration_transition() {
    let skeleton = human_skeleton(&HumanParams::default()).unwrap();
    let suit = Suit::vlasic(&skeleton).unwrap();
    let rest = skeleton.rest_pose();
    let params = FilterParams::default().with_process_sigma(0.3);
    for first_order in [false, true] {
        let p = params.with_first_order_step(first_order);
        let mut ekf = SkeletalEkf::new(skeleton.clone(), suit.clone(), &rest, p, &[]).unwrap();
        let (nf, n) = (ekf.nf, 3 * ekf.nf);
        // A correlated P and a moving state.
        ekf.predict().unwrap();
        ekf.predict().unwrap();
        ekf.symmetrise();
        for i in 0..n {
            ekf.x[i] = 0.01 * ((7 * i) % 13) as f64 - 0.05;
        }
        let (x, p0) = (ekf.x.clone(), ekf.p.clone());
        // Dense F: θ += Δt θ̇ + ½Δt² θ̈ (0 with the first-order step), θ̇ += Δt θ̈.
        let dt = p.frame_time_s;
        let h2 = if first_order { 0.0 } else { 0.5 * dt * dt };
        let mut f = DMatrix::<f64>::identity(n, n);
        for i in 0..nf {
            f[(i, nf + i)] = dt;
            f[(i, 2 * nf + i)] = h2;
            f[(nf + i, 2 * nf + i)] = dt;
        }
        let mut q = DMatrix::<f64>::zeros(n, n);
        for i in 0..nf {
            q[(2 * nf + i, 2 * nf + i)] = p.process_sigma.powi(2);
        }
        let x_ref = &f * x;
        let p_ref = &f * p0 * f.transpose() + q;
        ekf.predict().unwrap();
        assert!((&ekf.x - &x_ref).amax() < 1e-15, "{first_order}");
        assert!(
            (&ekf.p - &p_ref).amax() < 1e-12 * p_ref.amax(),
            "{first_order}: {}",
            (&ekf.p - &p_ref).amax()
        );
    }
}

/// With `skip_saturated`, flagged (saturated) channels are skipped row by row and counted;
/// without it they are used like any reading; unflagged readings are used either way.
#[test]
fn saturated_rows_are_skipped_unless_asked_for() {
    let skeleton = human_skeleton(&HumanParams::default()).unwrap();
    let suit = Suit::vlasic(&skeleton).unwrap();
    let rest = skeleton.rest_pose();
    let fk = skeleton.forward_kinematics(&rest).unwrap();
    let nb = suit.boards().len();
    let still: Vec<InertialReading> = suit
        .boards()
        .iter()
        .map(|b| {
            let q = fk.frame_rotation(&b.frame()).unwrap();
            InertialReading::new(DVec3::ZERO, q.inverse() * DVec3::Y * GRAVITY_M_S2)
        })
        .collect();
    let run = |flag: &dyn Fn(usize) -> [bool; crate::inertial::CHANNELS], skip| {
        let p = FilterParams::default().with_skip_saturated(skip);
        let mut ekf = SkeletalEkf::new(skeleton.clone(), suit.clone(), &rest, p, &[]).unwrap();
        let obs = FrameObservations {
            inertial: (0..nb)
                .map(|b| {
                    Some(InertialReading {
                        saturated: flag(b),
                        ..still[b]
                    })
                })
                .collect(),
            distances: vec![],
        };
        ekf.step(&obs, None).unwrap()
    };
    let none = |_| [false; crate::inertial::CHANNELS];
    // Board 0's gyroscope y and board 1's accelerometer z flagged.
    let some = |b: usize| {
        let mut f = [false; crate::inertial::CHANNELS];
        if b == 0 {
            f[1] = true;
        }
        if b == 1 {
            f[5] = true;
        }
        f
    };
    let clean = run(&none, true);
    assert_eq!(clean.inertial_saturated, 0);
    assert_eq!(clean.inertial_used, 6 * nb);
    let skipped = run(&some, true);
    assert_eq!(skipped.inertial_saturated, 2);
    assert_eq!(skipped.inertial_used, 6 * nb - 2);
    let used = run(&some, false);
    assert_eq!(used.inertial_saturated, 0);
    assert_eq!(used.inertial_used, 6 * nb);
}
