//! Tests of the capture builder: consistency with the performer and rasteriser, streaming,
//! determinism across thread counts and seeds, and bad input.

use super::*;
use crate::shading::Light;
use crate::{fast_motion, procedural_performer, FastMotionParams, ProceduralBodyParams};
use skin_core::camera::{Camera, Intrinsics, Rig};
use skin_core::math::DVec3;
use std::sync::OnceLock;

fn performer() -> &'static Performer {
    static P: OnceLock<Performer> = OnceLock::new();
    P.get_or_init(|| {
        procedural_performer(&ProceduralBodyParams {
            grid_spacing_m: 0.04,
            ..Default::default()
        })
        .unwrap()
    })
}

/// Six frames of brisk motion at 60 Hz (the flap's dynamics are active from frame 1).
fn motion() -> Motion {
    fast_motion(
        &performer().skeleton,
        &FastMotionParams {
            duration_s: 0.5,
            ramp_s: 0.05,
            ..Default::default()
        },
    )
    .unwrap()
}

fn intrinsics() -> Intrinsics {
    Intrinsics::from_horizontal_fov(0.7, 96, 128).unwrap()
}

fn rig(n: usize) -> Rig {
    Rig::ring(
        n,
        3.5,
        1.0,
        DVec3::new(0.0, 0.9, 0.0),
        DVec3::Y,
        intrinsics(),
    )
    .unwrap()
}

fn point_lights() -> Vec<Light> {
    [
        DVec3::new(2.0, 3.0, 2.0),
        DVec3::new(-2.5, 1.0, 1.0),
        DVec3::new(0.0, 2.0, -3.0),
    ]
    .map(|position| Light::Point {
        position,
        intensity: 10.0,
    })
    .to_vec()
}

fn shaded_spec(seed: u64) -> CaptureSpec {
    CaptureSpec::new(rig(3))
        .with_frame_rate_hz(60.0)
        .with_seed(seed)
        .with_lighting(CaptureLighting::new(point_lights()))
        .with_noise(PixelNoise { sigma: 0.01 })
}

fn collect(c: &Capture<'_>, range: std::ops::Range<usize>) -> Vec<CaptureFrame> {
    c.frames_in(range).collect::<Result<Vec<_>>>().unwrap()
}

#[test]
fn truth_matches_performer_and_observations_match_truth() {
    let p = performer();
    let m = motion();
    let c = Capture::new(p, &m, CaptureSpec::new(rig(4)).with_frame_rate_hz(60.0)).unwrap();
    assert_eq!(c.frame_count(), m.frame_count());
    let cm = c.motion().clone();
    let mut state = DeformationState::default();
    let mut n = 0;
    c.for_each_frame(|f| {
        assert_eq!(f.index, n);
        assert!((f.time_s - n as f64 / 60.0).abs() < 1e-12);
        let posed = p.pose(cm.frame(n), &mut state, cm.frame_time_s)?;
        assert_eq!(
            f.truth.posed, posed,
            "frame {n}: truth is the performer's pose"
        );
        assert_eq!(f.truth.theta, cm.frame(n));
        // Resampling at the motion's own rate keeps the poses (to rounding).
        for (a, b) in cm.frame(n).iter().zip(m.frame(n)) {
            assert!((a - b).abs() < 1e-9, "frame {n}: {a} vs {b}");
        }
        assert_eq!(f.observations.len(), 4);
        let mesh = f.truth.true_mesh(p);
        for (i, (o, v)) in f.observations.iter().zip(&f.truth.views).enumerate() {
            assert_eq!(o.camera, i);
            assert_eq!(o.mask.dimensions(), (96, 128));
            assert!(o.shaded.is_none());
            assert_eq!(
                v.depth_m.as_ref().unwrap().dimensions(),
                (96, 128),
                "truth has depth"
            );
            let normals = v.normals_camera.as_ref().unwrap();
            assert_eq!(normals.dimensions(), (96, 128), "truth has normals");
            assert!(
                v.triangle_ids.is_none() && v.barycentric.is_none(),
                "not asked for"
            );
            assert!(
                v.covered_pixels > 300,
                "camera {i} sees the body: {}",
                v.covered_pixels
            );
            // The truth views are the rasteriser's render of the true mesh.
            let direct = c.rasterizers()[i].render(&mesh, &c.spec().effective_render())?;
            assert_eq!(o.mask.count(), direct.covered_pixels);
            for (k, &m) in direct.mask.iter().enumerate() {
                let (x, y) = ((k % 96) as u32, (k / 96) as u32);
                assert_eq!(
                    o.mask.get(x, y),
                    m != 0,
                    "observed silhouette is the true one"
                );
            }
            assert_eq!(v.covered_pixels, direct.covered_pixels);
            assert_eq!(v.depth_m.as_ref().unwrap().as_raw(), &direct.depth_m);
            assert_eq!(v.camera_z_m.is_some(), !direct.camera_z_m.is_empty());
            let flat: Vec<f32> = direct.normal_camera.iter().flatten().copied().collect();
            assert_eq!(normals.as_raw(), &flat);
        }
        n += 1;
        Ok(())
    })
    .unwrap();
    assert_eq!(n, m.frame_count());
}

#[test]
fn resamples_the_motion_to_the_frame_rate() {
    let m = motion();
    let c = Capture::new(
        performer(),
        &m,
        CaptureSpec::new(rig(1)).with_frame_rate_hz(30.0),
    )
    .unwrap();
    assert!((c.motion().frame_time_s - 1.0 / 30.0).abs() < 1e-15);
    assert_eq!(
        c.frame_count(),
        (m.duration_s() * 30.0).floor() as usize + 1
    );
}

#[test]
fn identical_frames_for_one_and_two_threads() {
    let p = performer();
    let m = motion();
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                let c = Capture::new(p, &m, shaded_spec(11)).unwrap();
                collect(&c, 0..3)
            })
    };
    let one = run(1);
    let two = run(2);
    assert_eq!(one.len(), 3);
    assert!(one[2].observations[0].shaded.is_some());
    assert_eq!(one, two);
}

#[test]
fn any_range_streams_the_same_frames_as_a_full_run() {
    let p = performer();
    let m = motion();
    let c = Capture::new(p, &m, shaded_spec(5)).unwrap();
    let full = collect(&c, 0..c.frame_count());
    assert_eq!(full.len(), c.frame_count());
    let part = collect(&c, 3..5);
    assert_eq!(part.len(), 2);
    assert_eq!(part[0], full[3]);
    assert_eq!(part[1], full[4]);
    // The flap's dynamics are part of the truth: frame 4 posed from a fresh state differs.
    let fresh = p
        .pose(m.frame(4), &mut DeformationState::default(), m.frame_time_s)
        .unwrap();
    assert_ne!(fresh.true_vertices, full[4].truth.posed.true_vertices);
    // Ranges past the end are clipped.
    assert_eq!(c.frames_in(4..1000).count(), c.frame_count() - 4);
    assert_eq!(c.frames_in(1000..2000).count(), 0);
}

#[test]
fn noise_is_seeded_zero_mean_with_the_requested_sigma() {
    let p = performer();
    let m = motion();
    let frame = |spec: CaptureSpec| {
        let c = Capture::new(p, &m, spec).unwrap();
        c.frames_in(2..3).next().unwrap().unwrap()
    };
    let clean = {
        let mut s = shaded_spec(1);
        s.noise = None;
        frame(s)
    };
    let a = frame(shaded_spec(1));
    let b = frame(shaded_spec(1));
    let other = frame(shaded_spec(2));
    assert_eq!(a, b, "same seed, same frame");
    for cam in 0..3 {
        let img = |f: &CaptureFrame| {
            let s = f.observations[cam].shaded.clone().unwrap();
            s.pixels().map(|p| p.0).collect::<Vec<[f32; 3]>>()
        };
        let (c0, a0, o0) = (img(&clean), img(&a), img(&other));
        assert_ne!(a0, o0, "another seed, other noise");
        let d: Vec<f64> = a0
            .iter()
            .zip(&c0)
            .flat_map(|(x, y)| (0..3).map(move |k| f64::from(x[k] - y[k])))
            .collect();
        let n = d.len() as f64;
        let mean = d.iter().sum::<f64>() / n;
        let sd = (d.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n).sqrt();
        // 36,864 deviates: the mean is within 5 standard errors, the sd within 3 %.
        assert!(
            mean.abs() < 5.0 * 0.01 / n.sqrt(),
            "camera {cam}: mean {mean}"
        );
        assert!((sd / 0.01 - 1.0).abs() < 0.03, "camera {cam}: sd {sd}");
        // Different cameras of one frame get unrelated noise.
        if cam > 0 {
            let prev = a.observations[cam - 1].shaded.as_ref().unwrap();
            let prev_clean = clean.observations[cam - 1].shaded.as_ref().unwrap();
            let e0 = a0[0][0] - c0[0][0];
            let e1 = prev.get_pixel(0, 0)[0] - prev_clean.get_pixel(0, 0)[0];
            assert_ne!(e0, e1);
        }
    }
}

#[test]
fn shaded_images_are_lit_on_the_body_only() {
    let p = performer();
    let m = motion();
    let mut spec = shaded_spec(0);
    spec.noise = None;
    let c = Capture::new(p, &m, spec).unwrap();
    let f = c.frames().next().unwrap().unwrap();
    for o in &f.observations {
        let s = o.shaded.as_ref().unwrap();
        let lit = s
            .pixels()
            .zip(o.mask.iter())
            .filter(|(r, m)| *m && r[0] > 0.0)
            .count();
        let covered = o.mask.count();
        assert!(
            lit * 2 > covered,
            "most of the body is lit: {lit} of {covered}"
        );
        assert!(s
            .pixels()
            .zip(o.mask.iter())
            .all(|(r, m)| m || r.0 == [0.0; 3]));
    }
}

fn err_of(spec: CaptureSpec) -> Error {
    let m = motion();
    match Capture::new(performer(), &m, spec) {
        Err(e) => e,
        Ok(c) => c
            .frames()
            .find_map(|f| f.err())
            .expect("the capture should fail"),
    }
}

#[test]
fn camera_inside_the_body_is_named() {
    let mut r = rig(3);
    // Inside the torso, looking forward.
    r.cameras[1] = Camera::look_at(
        intrinsics(),
        DVec3::new(0.0, 1.2, 0.0),
        DVec3::new(0.0, 1.2, 1.0),
        DVec3::Y,
    )
    .unwrap();
    let e = err_of(CaptureSpec::new(r));
    assert!(
        matches!(e.root(), Error::InvalidParam { name: "rig", .. }),
        "{e}"
    );
    let text = e.to_string();
    assert!(
        text.starts_with("frame 0: camera 1: ") && text.contains("inside"),
        "{e}"
    );
    // The iterator stops after the error.
    let mut r = rig(2);
    r.cameras[0] = Camera::look_at(
        intrinsics(),
        DVec3::new(0.0, 1.2, 0.0),
        DVec3::new(0.0, 1.2, 1.0),
        DVec3::Y,
    )
    .unwrap();
    let m = motion();
    let c = Capture::new(performer(), &m, CaptureSpec::new(r)).unwrap();
    let mut it = c.frames();
    assert!(it.next().unwrap().is_err());
    assert!(it.next().is_none());
}

#[test]
fn camera_seeing_nothing_is_named() {
    let mut r = rig(3);
    // Outside, looking away from the performer.
    r.cameras[2] = Camera::look_at(
        intrinsics(),
        DVec3::new(0.0, 1.0, 4.0),
        DVec3::new(0.0, 1.0, 8.0),
        DVec3::Y,
    )
    .unwrap();
    let e = err_of(CaptureSpec::new(r.clone()));
    assert!(matches!(e.root(), Error::NotVisible { .. }), "{e}");
    assert!(
        e.to_string()
            .starts_with("frame 0: camera 2: nothing visible"),
        "{e}"
    );
    // Accepted when empty views are allowed.
    let m = motion();
    let spec = CaptureSpec::new(r).with_render(RenderParams::default().with_allow_empty(true));
    let c = Capture::new(performer(), &m, spec).unwrap();
    let f = c.frames().next().unwrap().unwrap();
    assert!(f.observations[2].mask.is_empty());
}

#[test]
fn light_inside_the_body_is_rejected() {
    let mut lights = point_lights();
    lights.push(Light::Point {
        position: DVec3::new(0.0, 1.2, 0.0),
        intensity: 1.0,
    });
    let e = err_of(CaptureSpec::new(rig(2)).with_lighting(CaptureLighting::new(lights)));
    assert!(
        matches!(&e, Error::InvalidParam { name: "lights", reason } if reason.contains("light 3")),
        "{e}"
    );
}

#[test]
fn bad_specs_and_motions_are_errors() {
    let p = performer();
    let m = motion();
    let e = |spec: CaptureSpec| Capture::new(p, &m, spec).unwrap_err();
    assert!(matches!(
        e(CaptureSpec::new(Rig::default())),
        Error::Empty { .. }
    ));
    for hz in [0.0, -30.0, f64::NAN, f64::INFINITY] {
        assert!(matches!(
            e(CaptureSpec::new(rig(1)).with_frame_rate_hz(hz)),
            Error::InvalidParam {
                name: "frame_rate_hz",
                ..
            }
        ));
    }
    assert!(matches!(
        e(CaptureSpec::new(rig(1)).with_lighting(CaptureLighting::new(vec![]))),
        Error::Empty { .. }
    ));
    let mut l = CaptureLighting::new(point_lights());
    l.albedo = [0.5, f32::NAN, 0.5];
    assert!(matches!(
        e(CaptureSpec::new(rig(1)).with_lighting(l)),
        Error::InvalidParam { name: "albedo", .. }
    ));
    let mut l = CaptureLighting::new(point_lights());
    l.shadow_bias_m = -1.0;
    assert!(matches!(
        e(CaptureSpec::new(rig(1)).with_lighting(l)),
        Error::InvalidParam { .. }
    ));
    assert!(matches!(
        e(CaptureSpec::new(rig(1)).with_noise(PixelNoise { sigma: -0.1 })),
        Error::InvalidParam { .. }
    ));
    let bad_light = Light::Point {
        position: DVec3::new(f64::NAN, 0.0, 0.0),
        intensity: 1.0,
    };
    assert!(Capture::new(
        p,
        &m,
        CaptureSpec::new(rig(1)).with_lighting(CaptureLighting::new(vec![bad_light]))
    )
    .is_err());
    // A motion of another skeleton.
    let wrong = Motion::new(1.0 / 30.0, nalgebra::DMatrix::zeros(3, 4)).unwrap();
    assert!(matches!(
        Capture::new(p, &wrong, CaptureSpec::new(rig(1))).unwrap_err(),
        Error::SizeMismatch { .. }
    ));
    let empty = Motion::new(
        1.0 / 30.0,
        nalgebra::DMatrix::zeros(p.skeleton.dof_count(), 0),
    )
    .unwrap();
    assert!(matches!(
        Capture::new(p, &empty, CaptureSpec::new(rig(1))).unwrap_err(),
        Error::Empty { .. }
    ));
}

#[test]
fn stepped_mask_only_frames_equal_those_of_a_full_run() {
    let p = performer();
    let m = motion();
    let c = Capture::new(p, &m, CaptureSpec::masks_only(rig(3))).unwrap();
    let all: Vec<CaptureFrame> = c.frames().collect::<Result<_>>().unwrap();
    let n = c.frame_count();
    assert!(n > 6);
    let it = c.frames_stepped(1..n, 3);
    assert_eq!(it.size_hint().1, Some((n - 1).div_ceil(3)));
    let stepped: Vec<CaptureFrame> = it.collect::<Result<_>>().unwrap();
    assert_eq!(stepped.len(), (n - 1).div_ceil(3));
    for f in &stepped {
        assert_eq!(f.index % 3, 1);
        assert_eq!(
            f, &all[f.index],
            "frame {}: same pose, dynamics and masks",
            f.index
        );
    }
    for f in &all {
        assert_eq!(f.masks().len(), 3);
        for v in &f.truth.views {
            assert!(
                v.depth_m.is_none() && v.normals_camera.is_none(),
                "masks only"
            );
        }
    }
}

#[test]
fn studio_ring_looks_at_the_performer_and_rejects_zero_sizes() {
    let rig = studio_ring(3, 96, 64).unwrap();
    assert_eq!(rig.cameras.len(), 3);
    for cam in &rig.cameras {
        let c = cam.centre();
        assert!((c.x.hypot(c.z) - STUDIO_RING_RADIUS_M).abs() < 1e-9);
        assert!((c.y - STUDIO_RING_HEIGHT_M).abs() < 1e-9);
    }
    assert!(studio_ring(0, 96, 64).is_err());
    assert!(studio_ring(3, 0, 64).is_err());
}

/// The procedural performer with render-time wrinkles, its left elbow bent to 90°.
fn wrinkled() -> (Performer, Motion) {
    let base = performer();
    let p = Performer::new(
        "wrinkled",
        base.template.clone(),
        base.skeleton.clone(),
        base.weights.clone(),
        &crate::DeformationParams::default().with_wrinkles(Some(crate::WrinkleParams::default())),
    )
    .unwrap();
    let mut theta = p.skeleton.rest_pose();
    theta[p.skeleton.dof_index("l_elbow.flexion").unwrap()] = std::f64::consts::FRAC_PI_2;
    let frames = nalgebra::DMatrix::from_fn(p.skeleton.dof_count(), 2, |d, _| theta[d]);
    let m = Motion::new(1.0 / 25.0, frames).unwrap();
    (p, m)
}

#[test]
fn wrinkled_performer_is_rendered_as_its_fine_surface() {
    let (p, m) = wrinkled();
    let spec = CaptureSpec::new(rig(2)).with_render(RenderParams::default().with_buffers(
        skin_core::raster::Buffers {
            triangle: true,
            ..Default::default()
        },
    ));
    let c = Capture::new(&p, &m, spec).unwrap();
    let f = c.frames().next().unwrap().unwrap();
    let fine = f.truth.fine.as_ref().expect("wrinkles give a fine surface");
    let w = p.wrinkles().unwrap();
    assert_eq!(fine.mesh.vertex_count(), w.fine_vertex_count());
    assert!(fine.mesh.face_count() > p.template.face_count());
    // The elbow crease carries folds; the rendered triangles are the fine faces.
    let max_mm = fine.max_wrinkle_m() * 1e3;
    assert!((0.5..=3.0).contains(&max_mm), "{max_mm} mm");
    let ids = f.truth.views[0].triangle_ids.as_ref().unwrap();
    let seen: Vec<u32> = ids
        .pixels()
        .map(|p| p[0])
        .filter(|&t| t != skin_core::raster::NO_TRIANGLE)
        .collect();
    assert!(!seen.is_empty());
    assert!(seen.iter().all(|&t| (t as usize) < fine.mesh.face_count()));
    assert_eq!(f.truth.rendered_mesh(&p), fine.mesh);
    // The same capture of the plain performer renders the template's faces.
    let plain = Capture::new(performer(), &m, CaptureSpec::new(rig(2))).unwrap();
    let g = plain.frames().next().unwrap().unwrap();
    assert!(g.truth.fine.is_none());
    assert_eq!(
        g.truth.rendered_mesh(performer()).face_count(),
        performer().template.face_count()
    );
}

#[test]
fn textured_lighting_varies_the_shading_on_the_body() {
    let lighting = CaptureLighting::new(point_lights()).with_shadows(false);
    let shaded = |lighting: CaptureLighting| {
        let spec = CaptureSpec::new(rig(1)).with_lighting(lighting);
        let c = Capture::new(performer(), &motion(), spec).unwrap();
        let f = c.frames().next().unwrap().unwrap();
        f.observations[0].shaded.clone().unwrap()
    };
    let uniform = shaded(lighting.clone());
    let textured = shaded(lighting.with_texture(Some(crate::TextureParams::default())));
    // Shading is linear in the albedo, so the ratio of the two images is the texture's skin
    // albedo over the uniform one, pixel by pixel: varying, by the skin's few per cent.
    let ratios: Vec<f64> = uniform
        .pixels()
        .zip(textured.pixels())
        .filter(|(u, _)| u[1] > 1e-4)
        .map(|(u, t)| f64::from(t[1] / u[1]))
        .collect();
    assert!(ratios.len() > 100, "{}", ratios.len());
    let mean = skin_core::stats::mean(&ratios);
    let sd = skin_core::stats::rms(&ratios.iter().map(|r| r - mean).collect::<Vec<_>>());
    assert!((0.02..0.3).contains(&(sd / mean)), "{sd} / {mean}");
    // A bad texture is refused when the capture is built.
    let bad = CaptureLighting::new(point_lights()).with_texture(Some(crate::TextureParams {
        print_period_m: -1.0,
        ..Default::default()
    }));
    assert!(Capture::new(
        performer(),
        &motion(),
        CaptureSpec::new(rig(1)).with_lighting(bad)
    )
    .is_err());
}

/// Light patterns: each light alone, then all on (weight 1) and a half-power pattern.
fn light_patterns(schedule: PatternSchedule) -> LightPatterns {
    let n = point_lights().len();
    let mut weights: Vec<Vec<f32>> = (0..n)
        .map(|i| (0..n).map(|l| if l == i { 1.0 } else { 0.0 }).collect())
        .collect();
    weights.push(vec![1.0; n]);
    weights.push(vec![0.5; n]);
    LightPatterns { weights, schedule }
}

#[test]
fn every_frame_patterns_add_up_and_all_on_equals_unpatterned() {
    let p = performer();
    let m = motion();
    let mut spec = shaded_spec(0);
    spec.noise = None;
    let plain = Capture::new(p, &m, spec.clone()).unwrap();
    let plain = plain.frames().next().unwrap().unwrap();
    let lighting = spec.lighting.take().unwrap();
    let spec = spec
        .with_lighting(lighting.with_patterns(Some(light_patterns(PatternSchedule::AllEachFrame))));
    let c = Capture::new(p, &m, spec).unwrap();
    let f = c.frames().next().unwrap().unwrap();
    for (o, q) in f.observations.iter().zip(&plain.observations) {
        assert_eq!(o.patterns.len(), 5);
        let full = q.shaded.as_ref().unwrap();
        assert_eq!(
            &o.patterns[3], full,
            "all-on pattern equals the unpatterned shading"
        );
        assert_eq!(o.shaded.as_ref(), Some(&o.patterns[0]));
        for (i, px) in full.pixels().enumerate() {
            let (x, y) = (i as u32 % full.width(), i as u32 / full.width());
            for ch in 0..3 {
                let sum: f32 = o.patterns[..3]
                    .iter()
                    .map(|im| im.get_pixel(x, y)[ch])
                    .sum();
                assert!((sum - px[ch]).abs() <= 1e-5 * (1.0 + px[ch]));
                let half = o.patterns[4].get_pixel(x, y)[ch];
                assert!((2.0 * half - px[ch]).abs() <= 1e-5 * (1.0 + px[ch]));
            }
        }
    }
}

#[test]
fn cycled_patterns_light_frame_k_with_pattern_k_mod_p() {
    let p = performer();
    let m = motion();
    let mut spec = shaded_spec(0);
    spec.noise = None;
    let lighting = spec.lighting.take().unwrap();
    let every = spec.clone().with_lighting(
        lighting
            .clone()
            .with_patterns(Some(light_patterns(PatternSchedule::AllEachFrame))),
    );
    let cycle =
        spec.with_lighting(lighting.with_patterns(Some(light_patterns(PatternSchedule::Cycle))));
    let every = collect(&Capture::new(p, &m, every).unwrap(), 0..7);
    let cycle = collect(&Capture::new(p, &m, cycle).unwrap(), 0..7);
    for (k, (e, c)) in every.iter().zip(&cycle).enumerate() {
        for (oe, oc) in e.observations.iter().zip(&c.observations) {
            assert!(oc.patterns.is_empty());
            assert_eq!(oc.shaded.as_ref(), Some(&oe.patterns[k % 5]), "frame {k}");
        }
    }
}

#[test]
fn bad_light_patterns_are_errors() {
    let spec = |weights: Vec<Vec<f32>>| {
        CaptureSpec::new(rig(1)).with_lighting(CaptureLighting::new(point_lights()).with_patterns(
            Some(LightPatterns {
                weights,
                schedule: PatternSchedule::Cycle,
            }),
        ))
    };
    assert!(matches!(spec(vec![]).validate(), Err(Error::Empty { .. })));
    assert!(matches!(
        spec(vec![vec![1.0; 2]]).validate(),
        Err(Error::SizeMismatch { .. })
    ));
    assert!(spec(vec![vec![-1.0; 3]]).validate().is_err());
    assert!(spec(vec![vec![f32::NAN; 3]]).validate().is_err());
    assert!(spec(vec![vec![1.0; 3]]).validate().is_ok());
}
