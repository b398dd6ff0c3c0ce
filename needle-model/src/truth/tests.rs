use super::*;

fn needle(primitive: u32, true_m: f64, lbs_m: f64) -> NeedleTruth {
    NeedleTruth {
        primitive,
        needle: 0,
        true_m,
        lbs_m,
        near_joint: false,
    }
}

/// Three frames of two needles: needle 0's non-skinning length spans 6 mm (pose-deforming),
/// needle 1's 1 mm (not).
fn set(lbs_bias_m: f64) -> TestSet {
    let frames = [(0.000, 0.000), (0.003, 0.001), (0.006, 0.0005)]
        .iter()
        .map(|&(d0, d1)| TestFrame {
            theta: vec![],
            config: vec![],
            needles: vec![
                needle(0, 0.05 + d0, 0.05 + lbs_bias_m),
                needle(1, 0.04 + d1, 0.04),
            ],
        })
        .collect();
    TestSet { frames }
}

#[test]
fn pose_deforming_needles_and_their_r2() {
    let t = set(0.0);
    assert_eq!(t.pose_deforming(), HashSet::from([(0, 0)]));
    // The LBS predicts needle 0's mean-free part not at all: its constant prediction at
    // the first frame's length explains nothing (r2 < 0: it is also biased), and nothing
    // once its mean error is removed (r2_centred = 0).
    let e = t.lbs_errors();
    assert_eq!(e.all_mm.len(), 6);
    assert_eq!(e.samples.len(), 6);
    assert_eq!(e.samples[2].key, (0, 0));
    assert_eq!(e.samples[2].predicted_m, 0.05);
    assert_eq!(e.pose_deforming_mm.len(), 3);
    let r = e.pose_r2();
    // Truth 0, 3, 6 mm above 50 mm (mean 3): total = 9 + 0 + 9 = 18 mm²; errors 0, 3,
    // 6 mm: residual 45 mm², centred residual 18 mm².
    assert!((r.r2 - (1.0 - 45.0 / 18.0)).abs() < 1e-9, "{r:?}");
    assert!(r.r2_centred.abs() < 1e-9, "{r:?}");
    // Mean error 3 mm on needle 0: bias² + centred² = (9 + 9 + 9 + 18) / 3 = 15 mm²,
    // the mean squared error 45 / 3; the truth's pose RMS sqrt(18 / 3).
    assert!((r.bias_rms_mm - 3.0).abs() < 1e-9, "{r:?}");
    assert!((r.centred_rms_mm - 6f64.sqrt()).abs() < 1e-9, "{r:?}");
    assert!((r.pose_rms_mm - 6f64.sqrt()).abs() < 1e-9, "{r:?}");
    // A biased LBS (every length 10 mm long) moves r2 but not r2_centred.
    let b = set(0.010).lbs_errors().pose_r2();
    assert!(b.r2 < r.r2);
    assert!((b.r2_centred - r.r2_centred).abs() < 1e-9);
    // No pose-deforming needle: NaN, not a division by zero.
    let flat = TestSet {
        frames: vec![TestFrame {
            theta: vec![],
            config: vec![],
            needles: vec![needle(0, 0.05, 0.05)],
        }],
    };
    assert!(flat.pose_deforming().is_empty());
    assert!(flat.lbs_errors().pose_r2().r2.is_nan());
}

#[test]
fn coverage_counts_the_fallbacks_and_restriction_keeps_the_pose_deforming_needles() {
    let t = set(0.0);
    // A partial predictor that knew needle 0 in frames 0 and 2, needle 1 in frame 1.
    let seen = |k: usize, n: &NeedleTruth| (n.primitive == 0) == (k != 1);
    let c = t.coverage(seen);
    assert_eq!(
        c,
        Coverage {
            needle_frames: 6,
            observed: 3,
            pose_deforming_needle_frames: 3,
            pose_deforming_observed: 2,
        }
    );
    assert!((c.fallback_share() - 0.5).abs() < 1e-12);
    assert!((c.pose_deforming_fallback_share() - 1.0 / 3.0).abs() < 1e-12);
    assert!(Coverage::default().fallback_share().is_nan());
    // LBS errors of needle 0 are 0, 3, 6 mm; on the known frames 0 and 6 mm. Needle 0
    // stays pose-deforming although, alone, frames 0 and 2 of the subset would not make
    // needle 1 one either: the set is the whole test's.
    let e = t.lbs_errors().restricted(&t, seen).unwrap();
    assert_eq!(e.all_mm.len(), 3);
    assert_eq!(e.pose_samples.len(), 2);
    assert_eq!(e.pose_deforming_mm.len(), 2);
    assert!((e.pose_deforming_mm[0] - 0.0).abs() < 1e-9);
    assert!((e.pose_deforming_mm[1] - 6.0).abs() < 1e-9, "{e:?}");
    assert_eq!(e.samples[1].key, (1, 0));
    // LBS predicts needle 0 at 50 mm against 50, 53, 56 mm: 2 of 3 frames more than
    // 1.5 mm short, 1 of 3 more than 4 mm; needle 1 (40 mm against 40, 41, 40.5) never.
    let all = t.lbs_errors();
    assert!((all.pose_short_share(0.0015) - 2.0 / 3.0).abs() < 1e-12);
    assert!((all.pose_short_share(0.004) - 1.0 / 3.0).abs() < 1e-12);
    assert!((all.short_share(0.0015) - 2.0 / 6.0).abs() < 1e-12);
    assert!(Errors::default().short_share(0.0).is_nan());
    // Errors of another test set are refused.
    let other = TestSet {
        frames: t.frames[..2].to_vec(),
    };
    assert!(matches!(
        t.lbs_errors().restricted(&other, seen),
        Err(Error::SizeMismatch { .. })
    ));
    let mut swapped = t.clone();
    swapped.frames[0].needles.swap(0, 1);
    assert!(matches!(
        t.lbs_errors().restricted(&swapped, seen),
        Err(Error::InvalidParam { .. })
    ));
}

#[test]
fn the_effect_of_largest_span_dominates_a_needle() {
    let mut a = EffectAttribution::with_categories(
        ["l_biceps".to_string(), "l_elbow_crease".to_string()].into_iter(),
        vec![],
    );
    assert_eq!(
        a.categories(),
        [SKINNING_GEOMETRY, "l_biceps", "l_elbow_crease", FLAP]
    );
    // Values per frame: [LBS length, biceps, crease, flap], metres.
    let frames: [[[f64; 4]; 4]; 3] = [
        // (0, 0): skinning carries it rigidly, the biceps swells 8 mm, the crease 3 mm.
        // (0, 1): skinning moves it 4 cm, the crease 1 cm.
        // (0, 2): only the flap moves it.
        // (0, 3): skinning and the biceps tie at 7.8125 mm (exact in binary): skinning,
        // the earlier category.
        [
            [0.05, 0.000, 0.000, 0.0],
            [0.05, 0.000, 0.000, 0.0],
            [0.07, 0.0, 0.0, 0.0],
            [0.0625, 0.0, 0.0, 0.0],
        ],
        [
            [0.05, 0.004, -0.001, 0.0],
            [0.07, 0.000, -0.005, 0.0],
            [0.07, 0.0, 0.0, 0.004],
            [0.0703125, 0.00390625, 0.0, 0.0],
        ],
        [
            [0.05, 0.008, -0.003, 0.0],
            [0.09, 0.000, -0.010, 0.0],
            [0.07, 0.0, 0.0, -0.002],
            [0.0625, 0.0078125, 0.0, 0.0],
        ],
    ];
    for f in &frames {
        for (j, v) in f.iter().enumerate() {
            a.push((0, j as u32), v);
        }
    }
    let spans = a.spans((0, 0)).unwrap();
    assert!((spans[1] - 0.008).abs() < 1e-12 && (spans[2] - 0.003).abs() < 1e-12);
    assert!(spans[0].abs() < 1e-12 && spans[3] == 0.0);
    assert_eq!(a.dominant((0, 0)), Some(1));
    assert_eq!(a.dominant((0, 1)), Some(0));
    assert_eq!(a.dominant((0, 2)), Some(3));
    assert_eq!(a.dominant((0, 3)), Some(0));
    assert_eq!(a.dominant((1, 0)), None);
    // Errors: needle (0, 0) off by 2 and 4 mm, needle (0, 1) by 1 mm, needle (0, 3) by
    // 3 mm.
    let sample = |needle: u32, err_mm: f64| NeedleSample {
        key: (0, needle),
        predicted_m: 0.05 + err_mm * 1e-3,
        true_m: 0.05,
    };
    let errors = Errors {
        pose_samples: vec![
            sample(0, 2.0),
            sample(1, 1.0),
            sample(0, -4.0),
            sample(3, 3.0),
        ],
        ..Errors::default()
    };
    let b = a.breakdown(&errors).unwrap();
    let names: Vec<&str> = b.iter().map(|e| e.effect.as_str()).collect();
    assert_eq!(names, a.categories());
    assert_eq!((b[0].needles, b[0].needle_frames), (2, 2));
    assert!((b[0].mean_mm - 2.0).abs() < 1e-9, "{b:?}");
    assert_eq!((b[1].needles, b[1].needle_frames), (1, 2));
    assert!((b[1].mean_mm - 3.0).abs() < 1e-9, "{b:?}");
    assert_eq!((b[2].needles, b[2].needle_frames), (0, 0));
    assert!(b[2].mean_mm.is_nan());
    // A needle never pushed: errors of another test set.
    let stranger = Errors {
        pose_samples: vec![NeedleSample {
            key: (7, 7),
            predicted_m: 0.0,
            true_m: 0.0,
        }],
        ..Errors::default()
    };
    assert!(a.breakdown(&stranger).is_err());
}

#[test]
fn a_bent_elbow_is_attributed_to_skinning_and_the_elbow_effects() {
    use crate::primitive::BodyLayout;
    use dynamic_shapes_studio::{procedural_performer, ProceduralBodyParams};
    let deformation = DeformationParams::default().with_flap(None);
    let effects = deformation.pose.clone().unwrap();
    let p = procedural_performer(&ProceduralBodyParams {
        deformation,
        ..Default::default()
    })
    .unwrap();
    let body = NeedleBody::new(&p.skeleton, &BodyLayout::table_3_1().with_density(0.5)).unwrap();
    let elbow = p.skeleton.dof_index("l_elbow.flexion").unwrap();
    let mut set = TestSet::default();
    let mut a = EffectAttribution::new(&p, &effects).unwrap();
    let truth = |degrees: f64| {
        let mut theta = p.skeleton.rest_pose();
        theta[elbow] = degrees.to_radians();
        let posed = p
            .pose(&theta, &mut DeformationState::default(), 1.0)
            .unwrap();
        FrameTruth {
            theta,
            posed,
            fine: None,
            views: vec![],
        }
    };
    for degrees in [0.0, 30.0, 60.0, 90.0] {
        let t = truth(degrees);
        set.push_frame(&body, &p, &t).unwrap();
        let frame = set.frames.last().unwrap().clone();
        a.push_frame(&body, &p, &t, &frame).unwrap();
    }
    // Only the left elbow bent: every pose-deforming needle is skinning geometry's or one
    // of the effects the left elbow's flexion drives, and the biceps, which skinning
    // carries rigidly in the middle of the upper arm, has needles of its own there.
    let elbow_effects = [
        "l_biceps",
        "l_brachioradialis",
        "l_elbow_crease",
        "l_elbow_round",
    ];
    let mut count: HashMap<&str, usize> = HashMap::new();
    for key in set.pose_deforming() {
        let c = a.categories()[a.dominant(key).unwrap()].as_str();
        assert!(
            c == SKINNING_GEOMETRY || elbow_effects.contains(&c),
            "needle {key:?}: {c}"
        );
        *count.entry(c).or_default() += 1;
        let primitive = body.primitives[key.0 as usize].name.as_str();
        if c != SKINNING_GEOMETRY {
            // The biceps reaches the elbow, the brachioradialis starts there.
            assert!(
                ["left upper arm", "left forearm"].contains(&primitive),
                "needle {key:?} of {primitive}: {c}"
            );
        }
        if c == "l_biceps" && primitive == "left upper arm" {
            *count.entry("l_biceps on the upper arm").or_default() += 1;
        }
        // The flap is off and nothing else moves: their spans are zero.
        let spans = a.spans(key).unwrap();
        assert_eq!(spans[spans.len() - 1], 0.0);
    }
    eprintln!("dominant categories of the pose-deforming needles: {count:?}");
    assert!(
        count.get("l_biceps on the upper arm").copied().unwrap_or(0) > 0,
        "{count:?}"
    );
    // The effects must be the performer's: one missing is refused, as is a frame of
    // another pose.
    let t = truth(45.0);
    let mut missing = EffectAttribution::new(&p, &effects.clone().without("l_biceps")).unwrap();
    set.push_frame(&body, &p, &t).unwrap();
    let frame = set.frames.last().unwrap().clone();
    assert!(matches!(
        missing.push_frame(&body, &p, &t, &frame),
        Err(Error::InvalidParam {
            name: "effects",
            ..
        })
    ));
    assert!(matches!(
        a.push_frame(&body, &p, &truth(20.0), &frame),
        Err(Error::InvalidParam { name: "frame", .. })
    ));
}
