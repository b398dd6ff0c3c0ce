//! The batch entry points (`dynamic_shapes_py::batch`) on small studio captures: outputs
//! written under their prefixes, chunks that agree with one run over all frames, and bad
//! input (an empty range, a range past the end, a missing file, a wrong pose).
#![allow(clippy::unwrap_used, clippy::expect_used)] // not library code

use std::path::{Path, PathBuf};

use dynamic_shapes_py::batch::{self, BatchError};
use inertial_acoustic::simulate::{prepare_motion, SimulationParams, SuitSimulator};
use skin_core::mesh;

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("batch")
        .join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn prefix(dir: &Path, sub: &str) -> String {
    format!("{}/{sub}/", dir.display())
}

fn is_input(e: &BatchError) -> bool {
    matches!(e, BatchError::Input(_))
}

#[test]
fn photometric_frames_by_range() {
    let dir = scratch("photometric");
    let capture = dir.join("capture");
    let makehuman = repo().join("data/makehuman");
    batch::write_photometric_capture(&makehuman, &capture, 60..62, 8, 80, false, 0.4).unwrap();
    let all = batch::photometric_frames(&capture, 0..2, &prefix(&dir, "all"), 5).unwrap();
    assert_eq!(all.len(), 2);
    let mesh1 = mesh::read_ply(&all[1]).unwrap();
    assert!(mesh1.faces.len() > 100, "{} faces", mesh1.faces.len());
    // A frame's output does not depend on the range it ran in.
    let one = batch::photometric_frames(&capture, 1..2, &prefix(&dir, "one"), 5).unwrap();
    assert_eq!(
        std::fs::read(&one[0]).unwrap(),
        std::fs::read(&all[1]).unwrap()
    );
    // Bad input.
    let p = prefix(&dir, "bad");
    assert!(is_input(
        &batch::photometric_frames(&capture, 1..1, &p, 6).unwrap_err()
    ));
    assert!(is_input(
        &batch::photometric_frames(&capture, 1..3, &p, 6).unwrap_err()
    ));
    assert!(matches!(
        batch::photometric_frames(&dir.join("nowhere"), 0..1, &p, 6).unwrap_err(),
        BatchError::Io { .. }
    ));
    std::fs::remove_file(capture.join("frames/000001/cam1_patterns.npy")).unwrap();
    assert!(matches!(
        batch::photometric_frames(&capture, 1..2, &p, 6).unwrap_err(),
        BatchError::Io { .. }
    ));
    assert!(is_input(
        &batch::write_photometric_capture(&makehuman, &dir.join("c2"), 3..3, 2, 96, false, 0.4)
            .unwrap_err()
    ));
}

#[test]
fn tracking_chunks_and_needle_stores() {
    let dir = scratch("silhouette");
    let capture = dir.join("capture");
    batch::write_silhouette_capture(
        &repo().join("data/makehuman"),
        &capture,
        40,
        4,
        4,
        160,
        120,
        1500,
    )
    .unwrap();
    let info: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(capture.join("capture.json")).unwrap())
            .unwrap();
    let thetas: Vec<Vec<f64>> = serde_json::from_value(info["thetas"].clone()).unwrap();
    // Two chunks, the second from the first's last pose.
    let p = prefix(&dir, "track");
    let last = batch::track_chunk(&capture, 0..2, &thetas[0], &p).unwrap();
    let next = batch::track_chunk(&capture, 2..4, &last, &p).unwrap();
    assert_eq!(next.len(), thetas[0].len());
    let (descr, shape, _) = batch::npy::read(&dir.join("track/poses_000002_000004.npy")).unwrap();
    assert_eq!((descr.as_str(), shape), ("<f8", vec![2, thetas[0].len()]));
    let (_, shape, _) = batch::npy::read(&dir.join("track/vertices_000000_000002.npy")).unwrap();
    assert_eq!(shape[0], 2);
    assert!(is_input(
        &batch::track_chunk(&capture, 0..2, &thetas[0][..3], &p).unwrap_err()
    ));
    assert!(is_input(
        &batch::track_chunk(&capture, 2..2, &thetas[0], &p).unwrap_err()
    ));
    assert!(is_input(
        &batch::track_chunk(&capture, 3..5, &thetas[0], &p).unwrap_err()
    ));

    // Needle stores of two chunks merge into the store of one run over all frames.
    let n = prefix(&dir, "needle");
    let a = batch::needle_accumulate(&capture, 0..2, &n).unwrap();
    let b = batch::needle_accumulate(&capture, 2..4, &n).unwrap();
    let whole = batch::needle_accumulate(&capture, 0..4, &n).unwrap();
    let merged = dir.join("needle/merged.json");
    let count = batch::needle_merge(&[a, b], &merged).unwrap();
    assert!(count > 0);
    assert_eq!(
        std::fs::read(&merged).unwrap(),
        std::fs::read(&whole).unwrap()
    );
    assert!(is_input(&batch::needle_merge(&[], &merged).unwrap_err()));
    assert!(is_input(
        &batch::needle_accumulate(&capture, 0..0, &n).unwrap_err()
    ));
    assert!(is_input(
        &batch::needle_accumulate(&capture, 0..9, &n).unwrap_err()
    ));
    // A missing template, a capture of the other kind.
    std::fs::remove_file(capture.join("template.obj")).unwrap();
    assert!(batch::track_chunk(&capture, 0..2, &thetas[0], &p).is_err());
    assert!(matches!(
        batch::photometric_frames(&capture, 0..1, &p, 6).unwrap_err(),
        BatchError::Format { .. }
    ));
}

#[test]
fn inertial_recording_range() {
    let dir = scratch("inertial");
    let human = skin_core::skeleton::human_skeleton(&Default::default()).unwrap();
    let sim_params = SimulationParams::default();
    let sim = SuitSimulator::new(&human, sim_params).unwrap();
    let cal = sim.calibrate_offsets(3).unwrap();
    let motion = dynamic_shapes_studio::exercise_motion(
        &human,
        &dynamic_shapes_studio::ExerciseParams::default().with_duration_s(4.0),
    )
    .unwrap();
    let smooth = prepare_motion(&human, &motion, &sim_params).unwrap();
    let recorded = sim.record(&smooth, &cal.offsets).unwrap().recording;
    let rec = dir.join("recording");
    recorded.write(&rec, &human).unwrap();
    let skel = dir.join("skeleton.json");
    std::fs::write(&skel, serde_json::to_string(&human).unwrap()).unwrap();
    // The pipeline on the recording and skeleton as read back (the files round the values).
    let human: skin_core::skeleton::Skeleton =
        serde_json::from_str(&std::fs::read_to_string(&skel).unwrap()).unwrap();
    let read = inertial_acoustic::Recording::read(&rec, &human).unwrap();
    let direct = inertial_acoustic::pipeline::run(&human, &read, &Default::default()).unwrap();
    let p = prefix(&dir, "out");
    let path = batch::inertial_recording(&rec, &skel, 10..20, &p).unwrap();
    let (_, shape, bytes) = batch::npy::read(&path).unwrap();
    assert_eq!(shape, vec![10, human.dof_count()]);
    let want: Vec<u8> = direct.theta[10..20]
        .concat()
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    assert_eq!(bytes, want);
    assert!(is_input(
        &batch::inertial_recording(&rec, &skel, 5..5, &p).unwrap_err()
    ));
    let n = direct.theta.len();
    assert!(is_input(
        &batch::inertial_recording(&rec, &skel, n - 1..n + 1, &p).unwrap_err()
    ));
    assert!(matches!(
        batch::inertial_recording(&rec, &dir.join("none.json"), 0..1, &p).unwrap_err(),
        BatchError::Io { .. }
    ));
}
