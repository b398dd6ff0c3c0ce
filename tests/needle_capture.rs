//! Small end-to-end validation of the needle model on the studio (the CI-sized version of
//! `examples/needle_capture.rs`): train on a range of motion, test on an unseen fast motion
//! against the performer's true posed mesh.

use dynamic_shapes::core::mesh::TriMesh;
use dynamic_shapes::core::studio::{
    fast_motion, procedural_performer, range_of_motion, DeformationState, FastMotionParams,
    ProceduralBodyParams, RangeOfMotionParams,
};
use dynamic_shapes::needle::truth::{self, median, TestSet};
use dynamic_shapes::needle::{
    BodyLayout, FrameInput, NeedleBody, NeedleModel, ObserveParams, Observer, ReconstructionParams,
};

#[test]
fn needle_model_beats_static_model_on_unseen_motion() {
    let performer = procedural_performer(&ProceduralBodyParams::default()).unwrap();
    let sk = performer.skeleton.clone();
    let body = NeedleBody::new(&sk, &BodyLayout::table_3_1()).unwrap();
    let cameras = truth::ring_cameras(3, 360, 240).unwrap();
    let observer = Observer::new(
        body.clone(),
        sk.clone(),
        cameras.clone(),
        ObserveParams::default(),
    )
    .unwrap();

    // Training: range of motion at 30 fps, every 2nd frame observed.
    let rom = range_of_motion(
        &sk,
        &RangeOfMotionParams {
            seconds_per_dof: 0.6,
            ..Default::default()
        },
    )
    .unwrap();
    let mut state = DeformationState::default();
    let mut thetas = vec![];
    let mut masks = vec![];
    for k in 0..rom.frame_count() {
        let theta = rom.frame(k);
        let posed = performer.pose(theta, &mut state, rom.frame_time_s).unwrap();
        if k % 2 == 0 {
            let mesh = TriMesh {
                vertices: posed.true_vertices,
                faces: performer.template.faces.clone(),
            };
            masks.push(truth::render_masks(&cameras, &mesh).unwrap());
            thetas.push(theta.to_vec());
        }
    }
    let frames: Vec<FrameInput> = thetas
        .iter()
        .zip(&masks)
        .map(|(t, m)| FrameInput { theta: t, masks: m })
        .collect();
    let store = observer.accumulate(&frames).unwrap().store;

    // Test: a fast motion with another seed.
    let motion = fast_motion(
        &sk,
        &FastMotionParams {
            duration_s: 1.0,
            seed: 11,
            ..Default::default()
        },
    )
    .unwrap();
    let mut test = TestSet::default();
    let poses: Vec<&[f64]> = (0..motion.frame_count()).map(|k| motion.frame(k)).collect();
    truth::for_each_posed(
        &performer,
        poses,
        motion.frame_time_s,
        12,
        |_, th, tv, lv| test.push_frame(&body, &performer, th, tv, lv),
    )
    .unwrap();
    let scored: usize = test.frames.iter().map(|f| f.needles.len()).sum();
    assert!(scored > 10_000, "{scored} scored needles");

    let params = ReconstructionParams::default();
    let model = NeedleModel::reconstruct(&store, &body, &params)
        .unwrap()
        .model;
    let stat = NeedleModel::reconstruct(&store, &body, &params.with_f_near(1.0))
        .unwrap()
        .model;
    let mut m = test.errors(&model).unwrap();
    let mut s = test.errors(&stat).unwrap();
    let mut l = test.lbs_errors();
    assert!(!m.near_joints_mm.is_empty() && !m.deforming_mm.is_empty());
    let (mm, sm, lm) = (
        median(&mut m.all_mm),
        median(&mut s.all_mm),
        median(&mut l.all_mm),
    );
    let (md, sd, ld) = (
        median(&mut m.deforming_mm),
        median(&mut s.deforming_mm),
        median(&mut l.deforming_mm),
    );
    eprintln!(
        "median mm: model {mm:.2}, static {sm:.2}, lbs {lm:.2}; deforming needles: model {md:.2}, static {sd:.2}, lbs {ld:.2}"
    );
    // Silhouette lengths bound the surface from outside (visual hull); with 3 cameras the
    // pose-dependent model still lands within about a centimetre of the truth.
    assert!(mm < 10.0, "model median {mm} mm");
    assert!(mm < sm, "model {mm} mm not better than static {sm} mm");
    // Ground-truth sanity: LBS of the exact rest shape matches the truth except where the
    // non-skinning deformation acts.
    assert!(lm < 1.0, "lbs median {lm} mm");
    assert!(ld > 2.0, "deforming needles' lbs median {ld} mm");
}

#[test]
fn truth_rejects_bad_input() {
    let performer = procedural_performer(&ProceduralBodyParams::default()).unwrap();
    let body = NeedleBody::new(
        &performer.skeleton,
        &BodyLayout::table_3_1().with_density(0.25),
    )
    .unwrap();
    let theta = performer.skeleton.rest_pose();
    let v = performer.template.vertices.clone();
    let mut test = TestSet::default();
    assert!(test
        .push_frame(&body, &performer, &theta, &v[1..], &v)
        .is_err());
    assert!(test
        .push_frame(&body, &performer, &theta[1..], &v, &v)
        .is_err());
    let frames = [theta.as_slice()];
    assert!(truth::for_each_posed(&performer, frames, 0.1, 0, |_, _, _, _| Ok(())).is_err());
    assert!(median(&mut []).is_nan());
    assert!(truth::ring_cameras(3, 0, 240).is_err());
    // The rest pose: needles start inside the body and end within their maximum length.
    test.push_frame(&body, &performer, &theta, &v, &v).unwrap();
    let n = &test.frames[0].needles;
    assert!(
        n.len() > body.needle_count() / 2,
        "{} of {}",
        n.len(),
        body.needle_count()
    );
    assert!(n
        .iter()
        .all(|t| t.true_m > 0.0 && t.true_m <= body.primitives[t.primitive as usize].max_length_m));
}
