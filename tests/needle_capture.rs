//! Small end-to-end validation of the needle model on the studio (the CI-sized version of
//! `examples/needle_capture`): train on the free exercise while turning, test on an exercise
//! of another seed and on real motion capture it never saw (CMU 131_01, retargeted) against
//! the performer's true posed mesh, pose-driven shapes on and the hip flap off; beside the
//! static model, the fair skinning baseline (LBS of the captured shape, library weights) and,
//! on a third of the exercise frames, the pose-local visual-hull oracle with each needle's
//! error split by the studio effect that moves it most.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)] // not library code

use dynamic_shapes::core::image::Mask;
use dynamic_shapes::core::mesh::HeatWeightsParams;
use dynamic_shapes::core::skeleton::{BvhParams, Motion, CMU_METRES_PER_UNIT};
use dynamic_shapes::core::stats::{mean, median};
use dynamic_shapes::needle::baseline::SkinnedShape;
use dynamic_shapes::needle::truth::{
    EffectAttribution, EffectErrors, HullOracle, NeedleTruth, TestSet,
};
use dynamic_shapes::needle::{
    animate, union_mesh, BodyLayout, FrameInput, NeedleBody, NeedleModel, ObserveParams, Observer,
    ReconstructionParams, SurfaceParams,
};
use dynamic_shapes_studio::{
    exercise_motion, play_bvh, procedural_performer, studio_ring, Capture, CaptureFrame,
    CaptureSpec, DeformationParams, ExerciseParams, FrameTruth, Performer, ProceduralBodyParams,
    RetargetParams, STUDIO_RING_HFOV_DEG, STUDIO_RING_RADIUS_M,
};

/// Silhouettes of `motion` at its own frame rate.
fn capture_of<'a>(
    performer: &'a Performer,
    rig: &dynamic_shapes::core::camera::Rig,
    motion: &Motion,
) -> Capture<'a> {
    let spec = CaptureSpec::masks_only(rig.clone()).with_frame_rate_hz(1.0 / motion.frame_time_s);
    Capture::new(performer, motion, spec).unwrap()
}

/// Truth of every `step`-th frame of `motion`.
fn test_set(
    performer: &Performer,
    body: &NeedleBody,
    rig: &dynamic_shapes::core::camera::Rig,
    motion: &Motion,
    step: usize,
) -> TestSet {
    let mut test = TestSet::default();
    let capture = capture_of(performer, rig, motion);
    for frame in capture.frames_stepped(0..capture.frame_count(), step) {
        test.push_frame(body, performer, &frame.unwrap().truth)
            .unwrap();
    }
    test
}

#[test]
fn needle_model_follows_the_pose_on_unseen_motions() {
    let performer = procedural_performer(&ProceduralBodyParams {
        deformation: DeformationParams::default().with_flap(None),
        ..Default::default()
    })
    .unwrap();
    let sk = performer.skeleton.clone();
    let body = NeedleBody::new(&sk, &BodyLayout::table_3_1()).unwrap();
    let rig = studio_ring(3, 360, 240).unwrap();
    let observer = Observer::new(
        body.clone(),
        sk.clone(),
        rig.cameras.clone(),
        ObserveParams::default(),
    )
    .unwrap();

    // Training: the free exercise while turning, 30 fps, every 2nd frame observed.
    let exercise = ExerciseParams::default().with_duration_s(TRAIN_S);
    let train = exercise_motion(&sk, &exercise).unwrap();
    let training = capture_of(&performer, &rig, &train);
    let captured: Vec<CaptureFrame> = training
        .frames_stepped(0..training.frame_count(), 2)
        .collect::<Result<_, _>>()
        .unwrap();
    let thetas: Vec<Vec<f64>> = captured.iter().map(|f| f.truth.theta.clone()).collect();
    let masks: Vec<Vec<Mask>> = captured.iter().map(CaptureFrame::masks).collect();
    let frames: Vec<FrameInput> = thetas
        .iter()
        .zip(&masks)
        .map(|(t, m)| FrameInput { theta: t, masks: m })
        .collect();
    let store = observer.accumulate(&frames).unwrap().store;

    // Tests: an exercise of another seed (every 10th frame) and real motion capture (every
    // 20th frame of the walk at 30 fps).
    let other = exercise_motion(&sk, &exercise.with_duration_s(20.0).with_seed(23)).unwrap();
    let ex = test_set(&performer, &body, &rig, &other, 10);
    let walk = play_bvh(
        example_kit::data_path("mocap-cmu/131_01.bvh").unwrap(),
        &BvhParams {
            metres_per_unit: CMU_METRES_PER_UNIT,
        },
        &sk,
        1.0 / 30.0,
        &RetargetParams::default(),
    )
    .unwrap()
    .motion;
    let walk = test_set(&performer, &body, &rig, &walk, 20);
    for t in [&ex, &walk] {
        let scored: usize = t.frames.iter().map(|f| f.needles.len()).sum();
        assert!(scored > 50_000, "{scored} scored needles");
    }

    let params = ReconstructionParams::default();
    let model = NeedleModel::reconstruct(&store, &body, &params)
        .unwrap()
        .model;
    let stat = NeedleModel::reconstruct(&store, &body, &params.with_f_near(1.0))
        .unwrap()
        .model;
    // The fair skinning baseline: LBS of the model's own rest shape with the library's
    // bone-heat weights (Pinocchio's visibility test on).
    let rest = animate(&body, &model, &sk, &sk.rest_pose()).unwrap();
    let lbs = SkinnedShape::heat(
        &sk,
        union_mesh(&rest, &SurfaceParams::default()).unwrap(),
        &HeatWeightsParams::default(),
    )
    .unwrap();
    let lbs_of = |t: &TestSet| {
        t.surface_errors(&body, &sk, |th| {
            lbs.pose(&performer, sk.forward_kinematics(th)?.world_from_joint())
        })
        .unwrap()
    };
    // Per primitive, against the static model from the same observations: an estimate biased
    // to a few views shows up as one primitive far worse than static (ties in F_near once cut
    // by time made the calves 10 mm off where static was 1 mm; too few near observations made
    // calf needles 7 cm long). Concavities the silhouettes cannot see are bad for both, so the
    // bound is relative; it allows 1.5× because of one: the hips' crotch, seen only in the
    // few poses with the legs apart, which the static model borrows for every pose and a
    // pose-local neighbourhood does not (on this run the hips' median is 16.2 mm against
    // 13.0 on the exercise and 15.2 against 10.8 on the walk; docs/needle-model.md).
    let per_primitive = |t: &TestSet, model: &NeedleModel| {
        let mut e = vec![vec![]; body.primitives.len()];
        for f in &t.frames {
            for n in &f.needles {
                let p = n.primitive as usize;
                let l = model.needle_lengths(p, &f.config[p]).unwrap()[n.needle as usize];
                e[p].push((l as f64 - n.true_m).abs() * 1e3);
            }
        }
        e.iter_mut().map(|v| median(v)).collect::<Vec<f64>>()
    };
    for (name, t) in [("exercise", &ex), ("walk", &walk)] {
        let (m, s, b, x) = (
            t.errors(&model).unwrap(),
            t.errors(&stat).unwrap(),
            lbs_of(t),
            t.lbs_errors(),
        );
        let (mm, sm, bm, em) = (
            median(&m.all_mm),
            median(&s.all_mm),
            median(&b.all_mm),
            median(&x.all_mm),
        );
        let (md, sd, bd, ed) = (
            mean(&m.pose_deforming_mm),
            mean(&s.pose_deforming_mm),
            mean(&b.pose_deforming_mm),
            mean(&x.pose_deforming_mm),
        );
        let (mr, sr, br) = (m.pose_r2(), s.pose_r2(), b.pose_r2());
        let (pm, ps) = (per_primitive(t, &model), per_primitive(t, &stat));
        eprintln!(
            "{name}: median mm: model {mm:.2}, static {sm:.2}, captured-rest LBS {bm:.2}, \
             exact-rest LBS {em:.2}; pose-deforming mean mm ({} needles): model {md:.2}, static \
             {sd:.2}, LBS {bd:.2}, exact-rest LBS {ed:.2}; pose_r2_centred model {:.3} static \
             {:.3} LBS {:.3}; per primitive: model {pm:.1?}, static {ps:.1?}",
            t.pose_deforming().len(),
            mr.r2_centred,
            sr.r2_centred,
            br.r2_centred,
        );
        // Silhouettes bound the surface from outside (visual hull) at 360×240 (≈ 1 cm
        // pixels): the model lands within half a pixel of the truth on most needles...
        assert!(mm < 5.0, "{name}: model median {mm} mm");
        for ((m, s), p) in pm.iter().zip(&ps).zip(&body.primitives) {
            assert!(
                *m <= 1.5 * s + 1.0,
                "{name}: {}: model {m} mm, static {s} mm",
                p.name
            );
        }
        // ...is at least as accurate as the static model built from the same observations...
        assert!(mm < 1.05 * sm, "{name}: model {mm} mm vs static {sm} mm");
        // Ground-truth sanity: LBS of the exact rest shape matches the truth except where
        // the pose-driven shapes act.
        assert!(em < 1.0, "{name}: exact-rest lbs median {em} mm");
        assert!(
            t.pose_deforming().len() > 200,
            "{name}: too few pose-deforming needles"
        );
        // ...and, where the pose changes the shape, follows it: better than the static model.
        assert!(md < sd, "{name}: pose-deforming model {md} mm, static {sd}");
        assert!(
            mr.r2_centred > MIN_R2_CENTRED,
            "{name}: pose_r2_centred {:.3}",
            mr.r2_centred
        );
        // Against the fair skinning baseline, LBS of the captured shape with the library's
        // bone-heat weights: better on the exercise (on MakeHuman too: 7.03 vs 8.32 mm), as
        // good and no better on the walk (MakeHuman: 10.03 vs 9.70 mm, LBS ahead;
        // docs/needle-model.md).
        if name == "exercise" {
            assert!(
                md < 0.95 * bd,
                "{name}: pose-deforming model {md} mm, LBS {bd} mm"
            );
        } else {
            assert!(
                md > 0.9 * bd,
                "{name}: pose-deforming model {md} mm now clearly beats LBS {bd} mm: update the docs"
            );
        }
    }

    // The pose-local visual-hull oracle on every third exercise test frame (every 30th of
    // the motion): 24 cameras at three heights see the body at exactly these poses.
    let oracle_rig = HullOracle::rig(360, 240).unwrap();
    let oracle_observer = Observer::new(
        body.clone(),
        sk.clone(),
        oracle_rig.cameras.clone(),
        ObserveParams::default(),
    )
    .unwrap();
    let capture = capture_of(&performer, &oracle_rig, &other);
    let seen: Vec<CaptureFrame> = capture
        .frames_stepped(0..capture.frame_count(), 30)
        .collect::<Result<_, _>>()
        .unwrap();
    let sub = TestSet {
        frames: ex.frames.iter().step_by(3).cloned().collect(),
    };
    let masks: Vec<Vec<Mask>> = seen.iter().map(CaptureFrame::masks).collect();
    let inputs: Vec<FrameInput> = seen
        .iter()
        .zip(&masks)
        .map(|(f, m)| FrameInput {
            theta: &f.truth.theta,
            masks: m,
        })
        .collect();
    let mut oracle = HullOracle::default();
    oracle.push_frames(&oracle_observer, &inputs).unwrap();
    // Which studio effect moves each of these needles most.
    let effects = DeformationParams::default().pose.unwrap();
    let mut attribution = EffectAttribution::new(&performer, &effects).unwrap();
    for (f, k) in seen.iter().zip(&sub.frames) {
        attribution
            .push_frame(&body, &performer, &f.truth, k)
            .unwrap();
    }
    let coverage = oracle.coverage(&sub);
    let saw = |k: usize, n: &NeedleTruth| oracle.length(k, (n.primitive, n.needle)).is_some();
    let o = oracle
        .errors(&sub, &stat)
        .unwrap()
        .restricted(&sub, saw)
        .unwrap();
    let m = sub.errors(&model).unwrap().restricted(&sub, saw).unwrap();
    let (or, mr) = (o.pose_r2(), m.pose_r2());
    let (om, mm) = (mean(&o.pose_deforming_mm), mean(&m.pose_deforming_mm));
    // Where the oracle is no outer bound: shorter than the truth by more than a pixel's
    // footprint at the ring's distance (1 cm at 360 px).
    let pixel_m =
        2.0 * STUDIO_RING_RADIUS_M * (STUDIO_RING_HFOV_DEG.to_radians() / 2.0).tan() / 360.0;
    let (short, model_short) = (o.pose_short_share(pixel_m), m.pose_short_share(pixel_m));
    eprintln!(
        "hull oracle, {} frames: fallback on {:.3} of the pose-deforming needle-frames ({:.3} of \
         all); on the needle-frames it saw: pose-deforming mean model {mm:.2} mm, oracle \
         {om:.2} mm; pose_r2_centred model {:.3}, oracle {:.3}; short of the truth by more \
         than a pixel: oracle {short:.3}, model {model_short:.3}",
        sub.frames.len(),
        coverage.pose_deforming_fallback_share(),
        coverage.fallback_share(),
        mr.r2_centred,
        or.r2_centred,
    );
    let split = |e| attribution.breakdown(e).unwrap();
    let (bo, bm) = (split(&o), split(&m));
    for (o, m) in bo.iter().zip(&bm) {
        if o.needle_frames > 0 {
            eprintln!(
                "  {}: {} needles, {} needle-frames: model {:.2}, oracle {:.2} mm",
                o.effect, o.needles, o.needle_frames, m.mean_mm, o.mean_mm
            );
        }
    }
    // The oracle knows most pose-deforming needle-frames; where it falls back is counted.
    assert!(
        coverage.pose_deforming_fallback_share() < 0.1,
        "{coverage:?}"
    );
    // Where it saw a needle it is an outer bound, up to a pixel: the visual hull contains the
    // body. (Which of the model and the oracle follows the pose better depends on the
    // pixels: here, at 360×240, the model; at 720×480 on MakeHuman the oracle.)
    assert!(short < 0.05, "oracle short of the truth on {short:.3}");
    // On the needles a muscle's swelling moves most (outward, in view of some silhouette) the
    // model, pooling many poses, errs far less than the per-pose oracle (on MakeHuman too).
    let muscles = ["biceps", "brachioradialis", "deltoid", "calf", "hamstrings"];
    let pooled = |rows: &[EffectErrors]| {
        let (n, sum) = rows
            .iter()
            .filter(|r| muscles.iter().any(|m| r.effect.ends_with(m)) && r.needle_frames > 0)
            .fold((0, 0.0), |(n, sum), r| {
                (
                    n + r.needle_frames,
                    sum + r.mean_mm * r.needle_frames as f64,
                )
            });
        (n, sum / n as f64)
    };
    let ((n, om), (_, mm)) = (pooled(&bo), pooled(&bm));
    assert!(n > 500, "{n} muscle-dominated needle-frames");
    assert!(
        mm < 0.75 * om,
        "muscle-dominated needles: model {mm:.2} mm, oracle {om:.2} mm"
    );
}

/// Seconds of training exercise.
const TRAIN_S: f64 = 60.0;
/// Smallest share of the pose variance of the pose-deforming needles the model must explain
/// (with each needle's bias removed; the static model scores 0).
const MIN_R2_CENTRED: f64 = 0.05;

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
    let rest = performer
        .pose(&theta, &mut Default::default(), 0.1)
        .unwrap();
    let truth = |theta: &[f64], true_vertices: &[_], lbs_vertices: &[_]| FrameTruth {
        theta: theta.to_vec(),
        posed: dynamic_shapes_studio::PosedFrame {
            true_vertices: true_vertices.to_vec(),
            lbs_vertices: lbs_vertices.to_vec(),
            ..rest.clone()
        },
        fine: None,
        views: vec![],
    };
    let mut test = TestSet::default();
    assert!(test
        .push_frame(&body, &performer, &truth(&theta, &v[1..], &v))
        .is_err());
    assert!(test
        .push_frame(&body, &performer, &truth(&theta[1..], &v, &v))
        .is_err());
    assert!(test.frames.is_empty());
    // The rest pose: needles start inside the body and end within their maximum length.
    test.push_frame(&body, &performer, &truth(&theta, &v, &v))
        .unwrap();
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
    // Scoring a surface: the template itself at rest is the truth; a body of another layout
    // or a failing surface is an error, not a panic.
    let template = |_: &[f64]| Ok(performer.template.clone());
    let e = test
        .surface_errors(&body, &performer.skeleton, template)
        .unwrap();
    assert!(median(&e.all_mm) < 1e-6);
    let full = NeedleBody::new(&performer.skeleton, &BodyLayout::table_3_1()).unwrap();
    let mut big = TestSet::default();
    big.push_frame(&full, &performer, &truth(&theta, &v, &v))
        .unwrap();
    assert!(big
        .surface_errors(&body, &performer.skeleton, template)
        .is_err());
    let failing = |_: &[f64]| Err(dynamic_shapes::needle::Error::Empty { what: "surface" });
    assert!(test
        .surface_errors(&body, &performer.skeleton, failing)
        .is_err());
}
