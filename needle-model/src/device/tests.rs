//! Tests of the calibration-device pipeline (§4.1) on a simulated device with known truth.

use super::*;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use skin_core::camera::{Camera, Intrinsics, RadialDistortion};
use std::f64::consts::TAU;

/// The true camera: 720×480, 3 m from the workspace, with barrel distortion.
fn true_camera() -> Camera {
    let k = Intrinsics::from_horizontal_fov(55f64.to_radians(), 720, 480).unwrap();
    let mut c = Camera::look_at(
        k,
        DVec3::new(0.4, 1.3, 3.0),
        DVec3::new(0.0, 1.0, 0.0),
        DVec3::Y,
    )
    .unwrap();
    c.distortion = RadialDistortion::new(-0.08, DVec2::new(362.0, 238.0));
    c
}

/// Device at time `t` (s): 6 s up and down in a plane parallel to the image, then 30 s of
/// free, smooth 3-D motion in a 1.2 m cube.
fn device(t: f64) -> DVec3 {
    if t < 6.0 {
        DVec3::new(
            0.1 * (0.3 * t).sin(),
            1.0 + 0.5 * (TAU * 0.5 * t).sin(),
            0.0,
        )
    } else {
        let u = t - 6.0;
        DVec3::new(
            0.6 * (0.41 * u).sin() + 0.1 * (1.3 * u).cos(),
            1.0 + 0.6 * (0.53 * u + 1.0).sin(),
            0.6 * (0.37 * u + 2.0).sin(),
        )
    }
}

/// Mocap at 120 Hz from t = 0; video at 30 fps whose clock runs `offset` ahead, σ = 0.5 px
/// detection noise, 5 % of frames without a detection.
fn recording(offset: f64, seed: u64) -> (DeviceTrack, DeviceVideo, Camera) {
    let cam = true_camera();
    let track = DeviceTrack {
        start_s: 0.0,
        rate_hz: 120.0,
        positions: (0..36 * 120).map(|i| device(i as f64 / 120.0)).collect(),
    };
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut noise = || {
        // Box–Muller, σ = 0.5 px.
        let (u1, u2): (f64, f64) = (rng.random_range(1e-12..1.0), rng.random_range(0.0..1.0));
        0.5 * (-2.0 * u1.ln()).sqrt() * (TAU * u2).cos()
    };
    let mut centres = vec![];
    for k in 0..35 * 30 {
        // Video time k/30 shows the device at mocap time k/30 − offset.
        let t = k as f64 / 30.0 - offset;
        let seen = (0.0..36.0).contains(&t) && k % 20 != 7;
        centres.push(seen.then(|| {
            let p = cam.project(device(t)).unwrap();
            p + DVec2::new(noise(), noise())
        }));
    }
    let video = DeviceVideo {
        start_s: 0.0,
        rate_hz: 30.0,
        width: 720,
        height: 480,
        centres,
    };
    (track, video, cam)
}

#[test]
fn recovers_offset_and_camera_of_a_simulated_device() {
    for (offset, seed) in [(0.4321, 1u64), (-1.237, 2)] {
        let (track, video, truth) = recording(offset, seed);
        let params = DeviceParams {
            sync_seconds: Some(6.0 + offset.max(0.0)),
            ..Default::default()
        };
        let cal = calibrate_device(&track, &video, &params).unwrap();
        let centre_err = cal.report.camera.centre().distance(truth.centre());
        eprintln!(
            "offset {offset}: estimated {:.5} s (score {:.4}), {} points, rms {:.3} px, centre {:.2} mm",
            cal.offset_s,
            cal.sync_score,
            cal.correspondences,
            cal.report.rms_px,
            centre_err * 1e3
        );
        // Sub-millisecond sync from 30 fps video (a frame is 33 ms).
        assert!((cal.offset_s - offset).abs() < 1e-3, "{}", cal.offset_s);
        assert!(cal.sync_score < -0.99, "image v falls as the device rises");
        assert!(cal.correspondences > 900);
        assert!(cal.report.rms_px < 0.6, "{}", cal.report.rms_px);
        // The centre is least certain along the optical axis (focal length against distance,
        // 1.2 m of depth at 3 m): 3–4 mm here; the calibrate example's random 3-D points get 1.
        assert!(centre_err < 0.01, "{centre_err} m");
    }
}

#[test]
fn bad_device_data_is_refused() {
    let (track, video, _) = recording(0.2, 3);
    let p = DeviceParams::default();
    let mut t = track.clone();
    t.positions.clear();
    assert!(matches!(
        calibrate_device(&t, &video, &p),
        Err(Error::Empty { .. })
    ));
    let mut t = track.clone();
    t.positions[5].y = f64::NAN;
    assert!(matches!(
        calibrate_device(&t, &video, &p),
        Err(Error::NonFinite { .. })
    ));
    let mut t = track.clone();
    t.rate_hz = 0.0;
    assert_eq!(
        calibrate_device(&t, &video, &p)
            .unwrap_err()
            .invalid_param_name(),
        Some("track rate_hz")
    );
    let mut v = video.clone();
    v.centres.iter_mut().for_each(|c| *c = None);
    assert!(matches!(
        calibrate_device(&track, &v, &p),
        Err(Error::Empty { .. })
    ));
    let mut v = video.clone();
    v.centres[3] = Some(DVec2::new(f64::INFINITY, 0.0));
    assert!(matches!(
        calibrate_device(&track, &v, &p),
        Err(Error::NonFinite { .. })
    ));
    for bad in [
        DeviceParams {
            up: Some(DVec3::ZERO),
            ..Default::default()
        },
        DeviceParams {
            sync_seconds: Some(-1.0),
            ..Default::default()
        },
    ] {
        let e = calibrate_device(&track, &video, &bad).unwrap_err();
        assert!(e.invalid_param_name().is_some(), "{e}");
    }
    // A device that never moves vertically cannot be synchronised: an error, not garbage.
    let flat = DeviceTrack {
        positions: track
            .positions
            .iter()
            .map(|p| DVec3::new(p.x, 1.0, p.z))
            .collect(),
        ..track.clone()
    };
    assert!(calibrate_device(&flat, &video, &p).is_err());
}

#[test]
fn gaps_are_interpolated_for_the_correlation() {
    let c = |v: f64| Some(DVec2::new(0.0, v));
    assert_eq!(
        fill_gaps(&[None, c(2.0), None, None, c(5.0), None]).unwrap(),
        vec![2.0, 2.0, 3.0, 4.0, 5.0, 5.0]
    );
    assert!(fill_gaps(&[None, None]).is_none());
    let track = DeviceTrack {
        start_s: 1.0,
        rate_hz: 10.0,
        positions: vec![DVec3::ZERO, DVec3::X],
    };
    let mid = track_at(&track, 1.05).unwrap();
    assert!(mid.distance(DVec3::new(0.5, 0.0, 0.0)) < 1e-12, "{mid}");
    assert_eq!(track_at(&track, 0.99), None);
    assert_eq!(track_at(&track, 1.2), None);
}
