use super::*;
use crate::template::tests::bendy;

const DT: f64 = 1.0 / 30.0;

/// A synthetic performer on the two-joint template: the truth is skinning plus a
/// pose-driven bulge of the upper half (4 cm × sin(bend), along the normal) and a lower half
/// that swings along the root's x after its acceleration (a damped 0.8 Hz resonator), as
/// normal offsets.
/// `stops`: the root walks at 1 m/s and halts for a second every two.
fn performer(frames: usize, phase: f64, stops: bool) -> TrainingSequence {
    let t = bendy();
    let (rho, omega) = (0.95f64, 2.0 * std::f64::consts::PI * 0.8 * DT);
    let (a1, a2) = (2.0 * rho * omega.cos(), -rho * rho);
    let (mut s1, mut s2) = (0.0, 0.0);
    let mut x = 0.0;
    let mut v_prev = 0.0;
    let (mut poses, mut out) = (Vec::new(), Vec::new());
    for f in 0..frames {
        let time = f as f64 * DT;
        let v = if stops && (time % 3.0) >= 2.0 {
            0.0
        } else {
            1.0 + 0.5 * (1.3 * time + phase).sin()
        };
        x += v * DT;
        let acc = if f == 0 { 0.0 } else { (v - v_prev) / DT };
        v_prev = v;
        let s = a1 * s1 + a2 * s2 - 0.0005 * acc;
        (s2, s1) = (s1, s);
        let rz = 0.15 * (0.7 * time + phase).sin();
        let bend = 0.8 * (1.1 * time + 2.0 * phase).sin();
        let theta = vec![x, rz, bend];
        let fk = t.skeleton().forward_kinematics(&theta).unwrap();
        let (lbs, normals) = skinned(&t, &fk).unwrap();
        let to_world = fk.world_from_joint()[0].matrix3;
        let vertices = lbs
            .iter()
            .zip(&normals)
            .zip(&t.mesh().vertices)
            .map(|((l, n), r)| {
                let up = ((r.y - 0.5) / 0.5).clamp(0.0, 1.0);
                let low = ((0.5 - r.y) / 0.5).clamp(0.0, 1.0);
                // The surface moves along x (the root's) by the swing: along the normal,
                // the part of that move that changes the surface.
                let swing = s * low * low * n.dot(to_world * DVec3::X);
                *l + *n * (0.04 * bend.sin() * up + swing)
            })
            .collect();
        poses.push(theta);
        out.push(vertices);
    }
    TrainingSequence {
        poses,
        frames: out,
        frame_time_s: DT,
    }
}

fn rms(a: &[DVec3], b: &[DVec3]) -> f64 {
    (a.iter()
        .zip(b)
        .map(|(x, y)| x.distance_squared(*y))
        .sum::<f64>()
        / a.len() as f64)
        .sqrt()
}

/// Mean RMS over a sequence of LBS, the pose part alone and the full model.
fn errors(model: &ShapeModel, test: &TrainingSequence) -> [f64; 3] {
    let t = model.template();
    let mut driver = model.driver();
    let mut e = [0.0; 3];
    for (theta, truth) in test.poses.iter().zip(&test.frames) {
        e[0] += rms(&t.skin(theta).unwrap(), truth);
        e[1] += rms(&model.pose_shape(theta).unwrap(), truth);
        e[2] += rms(&driver.step(theta).unwrap(), truth);
    }
    e.map(|x| x / test.frames.len() as f64)
}

fn small() -> ShapeModelParams {
    ShapeModelParams {
        components: 8,
        cross_validate: false,
        ..ShapeModelParams::default()
    }
}

#[test]
fn the_pose_part_learns_the_bulge_and_the_dynamic_part_the_swing_on_an_unseen_stop_and_go() {
    let mut train = [performer(300, 0.0, false), performer(300, 1.7, true)];
    let model = ShapeModel::learn(&bendy(), &mut train[..], &small()).unwrap();
    assert_eq!(model.training_frames(), 600);
    // LBS misses both the bulge and the swing; the pose part alone takes some of it, the
    // whole model most, on an unseen walk and on an unseen stop-and-go walk.
    for stops in [false, true] {
        let [lbs, pose, full] = errors(&model, &performer(240, 0.9, stops));
        // On the stop-and-go walk the swing is most of the residual: the dynamic part must
        // take at least half of what the pose part leaves.
        let dynamic_share = if stops { 0.5 } else { 1.0 };
        assert!(
            pose < lbs && full < 0.3 * lbs && full < dynamic_share * pose,
            "stops {stops}: full {full}, pose part {pose}, LBS {lbs}"
        );
    }
}

#[test]
fn validation_over_many_sequences_groups_them_and_keeps_the_signal() {
    // Twelve short sequences: more than MAX_FOLDS, so groups of them are left out in turn.
    let mut train: Vec<TrainingSequence> = (0..12)
        .map(|i| performer(60, 0.5 * i as f64, i % 2 == 1))
        .collect();
    let params = ShapeModelParams {
        cross_validate: true,
        ..small()
    };
    let model = ShapeModel::learn(&bendy(), &mut train[..], &params).unwrap();
    let (ridge, validation) = model.ridge();
    assert!(validation.is_some_and(|e| e.is_finite() && e > 0.0));
    assert!(
        ridge[0] < RIDGE_GRID[RIDGE_GRID.len() - 1],
        "ridge {ridge:?}"
    );
    let [lbs, _, full] = errors(&model, &performer(240, 0.9, true));
    assert!(full < 0.5 * lbs, "full {full}, LBS {lbs}");
}

#[test]
fn a_folds_training_equations_are_the_whole_minus_its_own() {
    let x = DMatrix::from_fn(9, 3, |t, i| ((t * 3 + i) as f64 * 0.7).sin());
    let y = DMatrix::from_fn(9, 2, |t, j| ((t + 5 * j) as f64 * 1.3).cos());
    let (part, rest) = ([2, 3, 4], [0, 1, 5, 6, 7, 8]);
    let direct = Normal::of(&x.select_rows(&rest), &y.select_rows(&rest));
    let minus =
        Normal::of(&x, &y).without(&Normal::of(&x.select_rows(&part), &y.select_rows(&part)));
    assert!((direct.gram - minus.gram).norm() < 1e-12);
    assert!((direct.rhs - minus.rhs).norm() < 1e-12);
    assert!((direct.energy - minus.energy).abs() < 1e-12);
}

#[test]
fn a_saved_model_loads_equal_and_drives_the_same() {
    let mut train = [performer(120, 0.0, true)];
    let model = ShapeModel::learn(&bendy(), &mut train[..], &small()).unwrap();
    let dir = std::env::temp_dir().join(format!("shape-model-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("model.dssm");
    model.save(&path).unwrap();
    let loaded = ShapeModel::load(&path).unwrap();
    // The basis is binary (exact); the header's JSON numbers come back within an ulp or so.
    assert_eq!(loaded.basis, model.basis);
    assert_eq!(loaded.training_frames(), model.training_frames());
    let (mut a, mut b) = (model.driver(), loaded.driver());
    for theta in &train[0].poses[..20] {
        let (x, y) = (a.step(theta).unwrap(), b.step(theta).unwrap());
        assert!(rms(&x, &y) < 1e-12);
    }
    // Malformed files: another format, truncated, trailing bytes, missing.
    let bytes = std::fs::read(&path).unwrap();
    let bad = dir.join("bad.dssm");
    std::fs::write(&bad, b"not a model at all").unwrap();
    assert!(ShapeModel::load(&bad).is_err());
    std::fs::write(&bad, &bytes[..bytes.len() - 8]).unwrap();
    assert!(ShapeModel::load(&bad).is_err());
    let mut longer = bytes.clone();
    longer.push(0);
    std::fs::write(&bad, &longer).unwrap();
    assert!(ShapeModel::load(&bad).is_err());
    assert!(ShapeModel::load(dir.join("missing.dssm")).is_err());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn sequence_files_stream_what_was_written() {
    let seq = performer(40, 0.3, false);
    let dir = std::env::temp_dir().join(format!("shape-seq-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("a.dsmold");
    let n = seq.frames[0].len();
    let mut w = SequenceWriter::create(&path, n, 3, DT).unwrap();
    for (theta, v) in seq.poses.iter().zip(&seq.frames) {
        w.push(theta, v).unwrap();
    }
    assert!(w.push(&[0.0; 2], &seq.frames[0]).is_err());
    assert!(w.push(&seq.poses[0], &seq.frames[0][1..]).is_err());
    assert!(w.push(&[f64::NAN, 0.0, 0.0], &seq.frames[0]).is_err());
    assert_eq!(w.finish().unwrap(), 40);
    let mut files = SequenceFiles(vec![path.clone(), path.clone()]);
    assert_eq!(files.frame_time_s().unwrap(), DT);
    let mut count = [0usize; 2];
    files
        .for_each(&mut |f| {
            let k = count[f.sequence] % 40;
            assert_eq!(f.theta, seq.poses[k].as_slice());
            assert!(rms(f.vertices, &seq.frames[k]) < 1e-6);
            count[f.sequence] += 1;
            Ok(())
        })
        .unwrap();
    assert_eq!(count, [40, 40]);
    // A truncated frame is an error, not a shorter sequence.
    let bytes = std::fs::read(&path).unwrap();
    std::fs::write(&path, &bytes[..bytes.len() - 5]).unwrap();
    assert!(SequenceFiles(vec![path.clone()])
        .for_each(&mut |_| Ok(()))
        .is_err());
    assert!(SequenceFiles(vec![dir.join("missing")])
        .frame_time_s()
        .is_err());
    assert!(SequenceWriter::create(dir.join("x"), n, 3, 0.0).is_err());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_training_input_is_a_clear_error() {
    let t = bendy();
    let mut empty: [TrainingSequence; 0] = [];
    assert!(ShapeModel::learn(&t, &mut empty[..], &small()).is_err());
    let mut seq = [performer(10, 0.0, false)];
    seq[0].frames[3].pop();
    let e = ShapeModel::learn(&t, &mut seq[..], &small()).unwrap_err();
    assert!(e.to_string().contains("frame 3"), "{e}");
    let mut seq = [performer(10, 0.0, false)];
    seq[0].frames[2][0].x = f64::NAN;
    assert!(ShapeModel::learn(&t, &mut seq[..], &small()).is_err());
    let mut seq = [performer(10, 0.0, false)];
    for bad in [
        ShapeModelParams {
            components: 0,
            ..small()
        },
        ShapeModelParams {
            poles: vec![DynamicPole {
                decay_per_s: 0.0,
                frequency_hz: 1.0,
            }],
            ..small()
        },
        ShapeModelParams {
            poles: vec![DynamicPole {
                decay_per_s: 1.0,
                frequency_hz: 20.0,
            }],
            ..small()
        },
        ShapeModelParams {
            pose_ridge: f64::NAN,
            ..small()
        },
    ] {
        assert!(ShapeModel::learn(&t, &mut seq[..], &bad).is_err());
    }
    seq[0].frame_time_s = 0.0;
    assert!(ShapeModel::learn(&t, &mut seq[..], &small()).is_err());
}
