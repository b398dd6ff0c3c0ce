//! multilinear-face (Vlasic 2010 Ch. 5) end to end on data sets generated from the real ICT
//! face basis: decomposition, Eq. 5.5, dial tuning, imputation against the averaging baseline
//! (the thesis's PPCA, and the default that chooses its model by cross-validation),
//! correspondence against Procrustes alone, and bad input (including the face-data reader).
#![allow(clippy::unwrap_used, clippy::expect_used)]

use dynamic_shapes::core::math::DVec3;
use dynamic_shapes::core::mesh::TriMesh;
use dynamic_shapes::face::validation::{
    aligned_rms, bilinear_face_set, face_width, feature_vertices, hold_out, ict_face_set,
    impute_rel_error, point_track_sequence, remeshed_scan, trilinear_face_set, FaceSetParams,
    IctBasis, TrackingScenario,
};
use dynamic_shapes::face::{
    fit_template, impute, impute_by_averaging, impute_ppca, mean_weights, track_points,
    CorrespondenceParams, Dials, Error, FaceTensor, ImputeModel, ImputeParams, KnownFaces,
    ModelParams, MultilinearModel, PpcaParams, TrackParams,
};
use nalgebra::DVector;

fn basis() -> IctBasis {
    IctBasis::read(example_kit::data_path("ict-face").unwrap()).unwrap()
}

fn max_dist(a: &[DVec3], b: &[DVec3]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| x.distance(*y))
        .fold(0.0, f64::max)
}

#[test]
fn face_decomposition_and_dials() {
    let basis = basis();
    let bi = bilinear_face_set(&basis, &FaceSetParams::default()).unwrap();
    assert_eq!(bi.faces.tensor().shape(), &[3 * 6706, 10, 15]);
    assert!(bi.interaction_fraction > 0.2, "{}", bi.interaction_fraction);
    // Thesis truncation: small error, HOOI no worse than its HOSVD start.
    let (model, fit) = MultilinearModel::fit(&bi.faces, &ModelParams::thesis_bilinear()).unwrap();
    assert!(fit.hosvd_rel_error < 0.02, "{fit:?}");
    assert!(fit.hooi_rel_error <= fit.hosvd_rel_error + 1e-9, "{fit:?}");
    // The generator's multilinear rank is (10, 11): kept whole, Eq. 5.5 gives back every face.
    let (full, fit_full) = MultilinearModel::fit(&bi.faces, &ModelParams::new(&[10, 11])).unwrap();
    assert!(fit_full.hooi_rel_error < 1e-5, "{fit_full:?}");
    for f in [0, 37, 149] {
        let w = vec![
            full.training_weights(0, f / 15).unwrap(),
            full.training_weights(1, f % 15).unwrap(),
        ];
        assert!(max_dist(&full.face(&w).unwrap(), &bi.faces.face(f).unwrap()) < 1e-6);
    }
    // Dial tuning: the blendshape labels of a training expression give its weights back.
    let dials = Dials::fit(&model, 0, &bi.labels[0]).unwrap();
    let smile_labels: Vec<f64> = bi.labels[0].row(1).iter().copied().collect();
    let w = dials.weights(&smile_labels).unwrap();
    assert!((w - model.training_weights(0, 1).unwrap()).norm() < 1e-9);

    // The ICT shapes alone are additive: no interaction energy at all, while ours has some.
    let ict = ict_face_set(&basis).unwrap();
    let (_, ict_fit) = MultilinearModel::fit(&ict.faces, &ModelParams::new(&[17, 11])).unwrap();
    assert!(ict_fit.hooi_rel_error < 1e-5);
    // Trilinear shapes at the thesis's truncation.
    let tri = trilinear_face_set(&basis, &FaceSetParams::default().with_identities(16)).unwrap();
    assert_eq!(tri.faces.tensor().shape(), &[3 * 6706, 5, 5, 16]);
    let (_, tfit) = MultilinearModel::fit(&tri.faces, &ModelParams::thesis_trilinear()).unwrap();
    assert!(tfit.hooi_rel_error < 0.02 && tfit.hooi_rel_error <= tfit.hosvd_rel_error + 1e-9);
}

#[test]
fn face_imputation_beats_averaging() {
    // The thesis's PPCA (§5.3.4) as written.
    let basis = basis();
    let tri = trilinear_face_set(&basis, &FaceSetParams::default().with_identities(16)).unwrap();
    for (fraction, goal) in [(0.15, Some(0.05)), (0.5, None)] {
        let known = hold_out(tri.faces.attribute_sizes(), fraction, 7).unwrap();
        let ours = impute_ppca(&tri.faces, &known, &PpcaParams::default()).unwrap();
        let avg = impute_by_averaging(&tri.faces, &known).unwrap();
        let (e_ours, e_avg) = (
            impute_rel_error(&tri.faces, &ours.faces, &known).unwrap(),
            impute_rel_error(&tri.faces, &avg, &known).unwrap(),
        );
        assert!(
            e_ours < 0.75 * e_avg,
            "{fraction}: ours {e_ours} vs averaging {e_avg}"
        );
        if let Some(g) = goal {
            assert!(e_ours <= g, "{fraction}: ours {e_ours}");
        }
        // Known faces are returned untouched.
        let f = known.known()[0];
        assert_eq!(ours.faces.face(f).unwrap(), tri.faces.face(f).unwrap());
    }
    // Bilinear set, 15 %: under the goal and far below the baseline.
    let bi = bilinear_face_set(&basis, &FaceSetParams::default()).unwrap();
    let known = hold_out(bi.faces.attribute_sizes(), 0.15, 7).unwrap();
    let ours = impute_ppca(&bi.faces, &known, &PpcaParams::default()).unwrap();
    let avg = impute_by_averaging(&bi.faces, &known).unwrap();
    let e_ours = impute_rel_error(&bi.faces, &ours.faces, &known).unwrap();
    let e_avg = impute_rel_error(&bi.faces, &avg, &known).unwrap();
    assert!(
        e_ours <= 0.05 && e_ours < 0.2 * e_avg,
        "ours {e_ours} vs averaging {e_avg}"
    );
    // Without interaction the averaging baseline is exact (why the generator needs one).
    let ict = ict_face_set(&basis).unwrap();
    let known = hold_out(ict.faces.attribute_sizes(), 0.15, 7).unwrap();
    let avg = impute_by_averaging(&ict.faces, &known).unwrap();
    assert!(impute_rel_error(&ict.faces, &avg, &known).unwrap() < 1e-9);
}

/// The imputation error of a fill and of the averaging baseline on the held-out faces.
fn errors(faces: &FaceTensor, known: &KnownFaces, filled: &FaceTensor) -> (f64, f64) {
    let avg = impute_by_averaging(faces, known).unwrap();
    (
        impute_rel_error(faces, filled, known).unwrap(),
        impute_rel_error(faces, &avg, known).unwrap(),
    )
}

#[test]
fn face_imputation_chooses_its_model() {
    // The ICT shapes add (expression + identity): averaging fills them exactly, the thesis's
    // PPCA does not (both modes are full rank), and the default, choosing by
    // cross-validation on the known faces, fills them as averaging does.
    let basis = basis();
    let ict = ict_face_set(&basis).unwrap();
    let known = hold_out(ict.faces.attribute_sizes(), 0.15, 7).unwrap();
    let thesis = impute_ppca(&ict.faces, &known, &PpcaParams::default()).unwrap();
    let (e_thesis, e_avg) = errors(&ict.faces, &known, &thesis.faces);
    assert!(
        e_avg < 1e-9 && e_thesis > 0.05,
        "thesis {e_thesis} vs averaging {e_avg}"
    );
    let chosen = impute(&ict.faces, &known, &ImputeParams::default()).unwrap();
    let (e_chosen, _) = errors(&ict.faces, &known, &chosen.faces);
    assert_eq!(chosen.model, ImputeModel::Averaging, "{chosen:?}");
    assert!(e_chosen < 1e-9, "default {e_chosen}");
    assert!(chosen.validated_faces > 0 && chosen.validation_errors[0] < 1e-6);

    // The trilinear set has an identity-dependent interaction of low identity rank: the
    // multilinear model wins clearly, and the default takes it (averaging alone fails this).
    let tri = trilinear_face_set(&basis, &FaceSetParams::default().with_identities(16)).unwrap();
    let known = hold_out(tri.faces.attribute_sizes(), 0.15, 7).unwrap();
    let chosen = impute(&tri.faces, &known, &ImputeParams::default()).unwrap();
    let (e_chosen, e_avg) = errors(&tri.faces, &known, &chosen.faces);
    assert!(
        e_chosen <= 0.05 && e_chosen < 0.2 * e_avg,
        "default {e_chosen} vs averaging {e_avg}"
    );
    assert!(matches!(chosen.model, ImputeModel::Ppca(_)), "{chosen:?}");
    let f = known.known()[0];
    assert_eq!(chosen.faces.face(f).unwrap(), tri.faces.face(f).unwrap());
}

#[test]
fn face_imputation_rank_argument() {
    // Half the faces held out of the bilinear set (10 expressions, 500 farthest-point
    // vertices). PPCA constrains a missing value only while a mode's rank is below the known
    // values of its mode vectors: the generator's identity rank is 11, so 16 people (≈ 8
    // known per vector) leave the missing faces nearly free and 32 (≈ 16) pin them down;
    // with as many identity modes as people (full rank) nothing does, and the thesis's PPCA
    // falls behind averaging while the default does not.
    let basis = basis();
    let sub = feature_vertices(basis.neutral(), 500).unwrap();
    let run = |people: usize, modes: usize| {
        let params = FaceSetParams::default()
            .with_identities(people)
            .with_identity_modes(modes);
        let faces = bilinear_face_set(&basis, &params)
            .unwrap()
            .faces
            .vertex_subset(&sub)
            .unwrap();
        let known = hold_out(faces.attribute_sizes(), 0.5, 7).unwrap();
        let thesis = impute_ppca(&faces, &known, &PpcaParams::default()).unwrap();
        let chosen = impute(&faces, &known, &ImputeParams::default()).unwrap();
        let (e_thesis, e_avg) = errors(&faces, &known, &thesis.faces);
        let (e_chosen, _) = errors(&faces, &known, &chosen.faces);
        (faces, e_thesis, e_chosen, e_avg)
    };
    let (_, e16, _, _) = run(16, 10);
    let (_, e32, c32, a32) = run(32, 10);
    assert!(
        e32 < 0.25 * e16 && e32 < 0.2 * a32 && c32 < 0.2 * a32,
        "rank 11: 16 people {e16}, 32 people {e32} (default {c32}, averaging {a32})"
    );
    let (full, e_full, c_full, a_full) = run(32, 31);
    assert!(
        e_full > a_full && c_full <= a_full * (1.0 + 1e-9),
        "full rank: thesis {e_full}, default {c_full}, averaging {a_full}"
    );
    // The generator's identity rank: full with 31 modes for 32 people, 11 with the basis's 10.
    let fit = |f: &FaceTensor, r: usize| {
        let p = ModelParams::new(&[10, r]).with_refine(None);
        MultilinearModel::fit(f, &p).unwrap().1.hosvd_rel_error
    };
    assert!(fit(&full, 31) > 1e-4 && fit(&full, 32) < 1e-9);
}

#[test]
fn face_correspondence_to_a_remeshed_scan() {
    let basis = basis();
    let bi = bilinear_face_set(&basis, &FaceSetParams::default()).unwrap();
    let truth = bi
        .faces
        .face(bi.faces.face_index(&[1, 3]).unwrap())
        .unwrap();
    let scan = remeshed_scan(
        &TriMesh::new(truth.clone(), bi.triangles.clone()).unwrap(),
        0.1,
        0.01,
        3,
    )
    .unwrap();
    assert!(scan.vertices.len() > 3 * truth.len());
    let features = feature_vertices(basis.neutral(), 42).unwrap();
    let marked: Vec<DVec3> = features.iter().map(|&f| truth[f]).collect();
    let fit = fit_template(
        basis.neutral(),
        &features,
        &scan,
        &marked,
        &CorrespondenceParams::default(),
    )
    .unwrap();
    let rms = |v: &[DVec3]| {
        10.0 * (v
            .iter()
            .zip(&truth)
            .map(|(a, b)| a.distance_squared(*b))
            .sum::<f64>()
            / v.len() as f64)
            .sqrt()
    };
    let (fit_mm, rigid_mm) = (rms(&fit.vertices), rms(&fit.aligned));
    assert!(
        fit_mm < 2.0 && fit_mm < 0.4 * rigid_mm,
        "fit {fit_mm} mm, Procrustes only {rigid_mm} mm"
    );
    // Bad input: a feature index past the template.
    let mut bad = features.clone();
    bad[0] = 1_000_000;
    assert!(fit_template(
        basis.neutral(),
        &bad,
        &scan,
        &marked,
        &CorrespondenceParams::default()
    )
    .is_err());
}

#[test]
fn face_bad_input() {
    let v = |n: usize, s: f64| {
        (0..n)
            .map(|i| DVec3::new(i as f64, s, 0.0))
            .collect::<Vec<_>>()
    };
    // Ragged (non-corresponding) meshes.
    let mut faces: Vec<_> = (0..6).map(|f| v(5, f as f64)).collect();
    faces[4] = v(4, 0.0);
    let e = FaceTensor::from_faces(&[2, 3], &faces).unwrap_err();
    assert!(matches!(e.root(), Error::SizeMismatch { .. }));
    // An all-missing slice.
    let e = KnownFaces::new(&[2, 3], vec![true, false, true, true, false, true]).unwrap_err();
    assert!(matches!(e.root(), Error::Empty { .. }));
    // Ranks larger than a mode, of the wrong count.
    faces[4] = v(5, 4.0);
    let t = FaceTensor::from_faces(&[2, 3], &faces).unwrap();
    assert!(matches!(
        MultilinearModel::fit(&t, &ModelParams::new(&[3, 3])),
        Err(Error::InvalidParam { .. })
    ));
    assert!(MultilinearModel::fit(&t, &ModelParams::new(&[2])).is_err());
    let (m, _) = MultilinearModel::fit(&t, &ModelParams::new(&[2, 3])).unwrap();
    let nan = vec![DVector::from_element(2, f64::NAN), DVector::zeros(3)];
    assert!(m.face(&nan).is_err());
    // Imputation: a mask of another shape, PPCA ranks above a mode (alone or as a candidate),
    // no candidate, a fold fraction of 1.
    let known = KnownFaces::new(&[3, 2], vec![true; 6]).unwrap();
    assert!(impute(&t, &known, &ImputeParams::default()).is_err());
    assert!(impute_ppca(&t, &known, &PpcaParams::default()).is_err());
    let known = KnownFaces::new(&[2, 3], vec![true, true, true, false, true, true]).unwrap();
    let bad_ranks = PpcaParams::default().with_ranks(&[3, 1]);
    assert!(impute_ppca(&t, &known, &bad_ranks).is_err());
    let p = ImputeParams::default().with_candidates(vec![ImputeModel::Ppca(bad_ranks)]);
    assert!(matches!(
        impute(&t, &known, &p).unwrap_err(),
        Error::InvalidParam { .. }
    ));
    let p = ImputeParams::default().with_candidates(Vec::new());
    assert!(matches!(
        impute(&t, &known, &p).unwrap_err(),
        Error::Empty { .. }
    ));
    let p = ImputeParams {
        fold_fraction: 1.0,
        ..ImputeParams::default()
    };
    assert!(impute(&t, &known, &p).is_err());
    // Generator and data errors.
    assert!(hold_out(&[2, 3], 1.0, 0).is_err());
}

/// A scratch copy of part of the ICT folder: the neutral face, the named identities and
/// blendshapes (removed when dropped).
struct ScratchIct(std::path::PathBuf);

impl ScratchIct {
    fn new(tag: &str, identities: &[&str], blendshapes: &[&str]) -> Self {
        let src = example_kit::data_path("ict-face").unwrap();
        let dir = std::env::temp_dir().join(format!("ict-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        for sub in ["identity", "expression"] {
            std::fs::create_dir_all(dir.join(sub)).unwrap();
        }
        std::fs::copy(src.join("neutral_face.obj"), dir.join("neutral_face.obj")).unwrap();
        for (sub, names) in [("identity", identities), ("expression", blendshapes)] {
            for n in names {
                let name = format!("{n}.obj");
                std::fs::copy(src.join(sub).join(&name), dir.join(sub).join(&name)).unwrap();
            }
        }
        ScratchIct(dir)
    }

    fn write(&self, sub: &str, name: &str, text: &str) {
        std::fs::write(self.0.join(sub).join(format!("{name}.obj")), text).unwrap();
    }
}

impl Drop for ScratchIct {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

#[test]
fn face_data_reader_bad_input() {
    use dynamic_shapes::face::validation::ICT_BLENDSHAPES;
    use dynamic_shapes::face::Context;
    // The shipped folder: every shape it holds, blendshapes in file-name order.
    let full = basis();
    assert_eq!(full.identity_modes().len(), 10);
    assert_eq!(full.blendshape_names(), ICT_BLENDSHAPES);
    // A folder with 3 identities and 12 blendshapes (no smile, no jaw): read as it is; the
    // ICT set takes its counts from it (13 × 4, no panic); the generated sets need the
    // blendshapes their recipes name and say which one is missing.
    let ids = ["identity000", "identity003", "identity007"];
    let exs: Vec<&str> = ICT_BLENDSHAPES
        .iter()
        .copied()
        .filter(|n| !["mouthSmile_L", "mouthSmile_R", "jawLeft", "jawOpen"].contains(n))
        .collect();
    let dir = ScratchIct::new("twelve", &ids, &exs);
    let part = IctBasis::read(&dir.0).unwrap();
    assert_eq!(part.identity_names(), ids);
    assert_eq!(part.blendshapes().len(), 12);
    let ict = ict_face_set(&part).unwrap();
    assert_eq!(ict.faces.attribute_sizes(), &[13, 4]);
    assert_eq!(ict.labels[0].shape(), (13, 12));
    assert_eq!(ict.value_names[1][2], "identity003");
    for set in [
        bilinear_face_set(&part, &FaceSetParams::default()),
        trilinear_face_set(&part, &FaceSetParams::default()),
    ] {
        let e = set.unwrap_err();
        assert!(
            matches!(&e, Error::UnknownName { name, .. } if name.starts_with("mouthSmile") || name.starts_with("jaw")),
            "{e}"
        );
    }
    // Names from the caller: in the caller's order; a missing file says which.
    let named =
        IctBasis::read_named(&dir.0, &["identity007"], &["eyeBlink_R", "browDown_L"]).unwrap();
    assert_eq!(named.blendshape_names(), ["eyeBlink_R", "browDown_L"]);
    let e = IctBasis::read_named(&dir.0, &["identity007"], &["browDown_L", "jawOpen"]).unwrap_err();
    assert!(
        matches!(
            e.root(),
            Error::Core(dynamic_shapes::core::Error::Io { .. })
        ),
        "{e}"
    );
    assert_eq!(e.contexts(), vec![Context::Frame(2)]);
    let e =
        IctBasis::read_named(&dir.0, &["identity007", "identity007"], &["browDown_L"]).unwrap_err();
    assert!(matches!(e.root(), Error::InvalidParam { .. }), "{e}");
    // No identity, or no blendshape.
    let e = IctBasis::read_named(&dir.0, &[] as &[&str], &["browDown_L"]).unwrap_err();
    assert!(matches!(e, Error::Empty { .. }), "{e}");
    let empty = ScratchIct::new("empty", &ids, &[]);
    assert!(matches!(
        IctBasis::read(&empty.0).unwrap_err(),
        Error::Empty { .. }
    ));
    // A shape with another vertex count, a malformed OBJ, a NaN coordinate: typed, located.
    let bad = ScratchIct::new("bad", &ids, &exs[..2]);
    bad.write(
        "expression",
        "zz_short",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    );
    let e = IctBasis::read(&bad.0).unwrap_err();
    assert!(matches!(e.root(), Error::SizeMismatch { .. }), "{e}");
    assert_eq!(e.contexts(), vec![Context::Frame(5)]);
    bad.write("expression", "zz_short", "v 0 0 zero\n");
    let e = IctBasis::read(&bad.0).unwrap_err();
    assert!(
        matches!(
            e.root(),
            Error::Core(dynamic_shapes::core::Error::Parse { .. })
        ),
        "{e}"
    );
    bad.write("identity", "identity003", "v nan 0 0\n");
    let e = IctBasis::read(&bad.0).unwrap_err();
    assert!(
        matches!(
            e.root(),
            Error::Core(dynamic_shapes::core::Error::Parse { .. })
        ),
        "{e}"
    );
    assert_eq!(e.contexts(), vec![Context::Frame(1)]);
    // No folder at all, no neutral face.
    assert!(matches!(
        IctBasis::read("/nonexistent/ict-face").unwrap_err(),
        Error::Core(_)
    ));
    std::fs::remove_file(bad.0.join("neutral_face.obj")).unwrap();
    assert!(matches!(
        IctBasis::read(&bad.0).unwrap_err(),
        Error::Core(_)
    ));
    // Zero identity modes for the generator.
    let p = FaceSetParams::default().with_identity_modes(0);
    assert!(bilinear_face_set(&full, &p).is_err());
}

/// The tracking scenario with 1,000 tracked vertices.
fn tracking_setup() -> TrackingScenario {
    TrackingScenario::new(basis(), 1000).unwrap()
}

#[test]
fn face_tracking_from_point_tracks() {
    // A person the model never saw, 1,000 tracked vertices, 0.5 px noise.
    let TrackingScenario {
        model,
        novel,
        tracked,
        ..
    } = tracking_setup();
    let seq =
        point_track_sequence(&novel.faces, &[0, 1, 3, 5, 2, 7, 0], &tracked, 40, 0.5, 5).unwrap();
    let track = track_points(
        &model,
        &tracked,
        &seq.frames,
        &[false, true],
        &TrackParams::default(),
    )
    .unwrap();
    let width = face_width(&seq.truth[0]);
    let aligned = |f: &[DVec3], truth: &[DVec3]| aligned_rms(f, truth).unwrap();
    let mean_face = model.face(&mean_weights(&model).unwrap()).unwrap();
    let (mut ours, mut base) = (0.0, 0.0);
    for (t, truth) in seq.truth.iter().enumerate() {
        ours += aligned(&model.face(&track.weights[t]).unwrap(), truth) / width;
        base += aligned(&mean_face, truth) / width;
    }
    let (ours, base) = (100.0 * ours / 40.0, 100.0 * base / 40.0);
    assert!(
        ours <= 1.2 && ours < 0.5 * base,
        "tracked {ours} % vs mean face {base} %"
    );
    // Bad input: a frame with a missing point, NaN pixels, too few points.
    let mut frames = seq.frames.clone();
    frames[3].pop();
    let e = track_points(
        &model,
        &tracked,
        &frames,
        &[false, true],
        &TrackParams::default(),
    )
    .unwrap_err();
    assert_eq!(e.contexts(), vec![dynamic_shapes::face::Context::Frame(3)]);
    frames[3] = seq.frames[3].clone();
    frames[5][0][1] = f64::NAN;
    assert!(track_points(
        &model,
        &tracked,
        &frames,
        &[false, true],
        &TrackParams::default()
    )
    .is_err());
    assert!(track_points(
        &model,
        &tracked[..3],
        &[vec![[0.0; 2]; 3]],
        &[false, true],
        &TrackParams::default()
    )
    .is_err());
}

#[test]
fn face_tracking_from_video() {
    use dynamic_shapes::face::{track_video, FeaturePoints, VideoTrackParams};
    // A person the model never saw, 20 rendered 640 × 480 frames (neutral → smile → surprise
    // → neutral with head motion), 1,000 tracked vertices, 12 feature points (1 px noise).
    let scenario = tracking_setup();
    let n = 20;
    let video = scenario.video(&[0, 1, 3, 0], n, 12).unwrap();
    let TrackingScenario {
        training: bi,
        model,
        tracked,
        ..
    } = scenario;
    assert_eq!(video.frames[0].dimensions(), (640, 480));
    let run = |frames: &[image::RgbImage], f: &FeaturePoints| {
        track_video(
            &model,
            &bi.triangles,
            &tracked,
            frames,
            f,
            &[false, true],
            &VideoTrackParams::default(),
        )
    };
    let track = run(&video.frames, &video.features).unwrap();
    // Baselines: the mean face, and the first frame's fit (from the feature points) held.
    let init = run(&video.frames[..1], &video.features).unwrap();
    let width = face_width(&video.truth[0]);
    let mean_face = model.face(&mean_weights(&model).unwrap()).unwrap();
    let init_face = model.face(&init.weights[0]).unwrap();
    let (mut ours, mut mean, mut held) = (0.0, 0.0, 0.0);
    for (t, truth) in video.truth.iter().enumerate() {
        let f = model.face(&track.weights[t]).unwrap();
        ours += aligned_rms(&f, truth).unwrap() / width;
        mean += aligned_rms(&mean_face, truth).unwrap() / width;
        held += aligned_rms(&init_face, truth).unwrap() / width;
        assert!(track.tracked_fraction[t] > 0.8, "frame {t}: {track:?}");
    }
    let pct = |x: f64| 100.0 * x / n as f64;
    let (ours, mean, held) = (pct(ours), pct(mean), pct(held));
    eprintln!(
        "video tracking: {ours:.3} % (mean face {mean:.3} %, first frame held {held:.3} %), {:.1} fps",
        n as f64 / track.seconds
    );
    assert!(
        ours < 2.0 && ours < 0.6 * mean && ours < 0.9 * held,
        "tracked {ours} % vs mean face {mean} %, first frame held {held} %"
    );

    // The face leaves the picture in frame 12: reported, with the frame.
    let mut frames = video.frames[..14].to_vec();
    frames[12] = image::RgbImage::from_fn(640, 480, |x, y| {
        let n = ((x * 7 + y * 13) % 5) as u8;
        image::Rgb(video.background.map(|c| c + n))
    });
    let e = run(&frames, &video.features).unwrap_err();
    assert!(matches!(e.root(), Error::FaceLost { .. }), "{e}");
    assert_eq!(e.contexts(), vec![dynamic_shapes::face::Context::Frame(12)]);
    // A frame of the wrong size.
    frames[12] = image::RgbImage::new(320, 240);
    let e = run(&frames, &video.features).unwrap_err();
    assert!(
        matches!(
            e.root(),
            Error::Core(dynamic_shapes::core::Error::SizeMismatch { .. })
        ),
        "{e}"
    );
    assert_eq!(e.contexts(), vec![dynamic_shapes::face::Context::Frame(12)]);
    // Frames too small for the pyramid, NaN or missing feature pixels, no frame.
    let tiny = vec![image::RgbImage::new(40, 30); 2];
    assert!(matches!(
        run(&tiny, &video.features).unwrap_err().root(),
        Error::InvalidParam { .. }
    ));
    let mut bad = video.features.clone();
    bad.pixels[3][0] = f64::NAN;
    assert!(run(&video.frames[..2], &bad).is_err());
    bad.pixels.pop();
    assert!(matches!(
        run(&video.frames[..2], &bad).unwrap_err().root(),
        Error::Core(dynamic_shapes::core::Error::SizeMismatch { .. })
    ));
    assert!(matches!(
        run(&[], &video.features).unwrap_err().root(),
        Error::Empty { .. }
    ));
}
