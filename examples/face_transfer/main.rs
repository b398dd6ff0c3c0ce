//! Validation of multilinear-face (Vlasic 2010 thesis, Chapter 5) on data sets generated from
//! the real ICT face basis (`data/ict-face/`, see `multilinear_face::validation`).
//!
//! * Decomposition (§5.2, §5.3.3): the bilinear set (6,706 vertices × 10 expressions × 15
//!   people) at the thesis's 6 × 9 knobs and the trilinear set (× 5 visemes × 5 expressions ×
//!   16 people) at 4 × 4 × 16, HOSVD then HOOI; the ICT shapes themselves (17 expressions ×
//!   11 identities) as a bilinear model, where the additivity of the ICT basis shows.
//! * Dial tuning (§5.4) and faces from attribute weights (Eq. 5.5): `model_faces.png`.
//! * Missing data (§5.3.4): 15 % and 50 % of the faces held out (full run: 10–50 %), the
//!   default imputation (model chosen by cross-validation on the known faces) against the
//!   thesis's PPCA alone and the averaging baseline (`impute_rel_error_15`, `_50`,
//!   `thesis_…`, `averaging_…`); the ICT shapes (additive); 50 % held out of trilinear sets
//!   with 16 people and identity rank 11 and full (full run: 16, 32, 64 people, rank 6, 11,
//!   full, three hold-out seeds: `impute_rel_error_50_by_identities`,
//!   `imputation_by_identities.png`); the tensors, masks and the averaging fills (our start)
//!   are written as `.npy` under `tensorly/` for `masked_tucker_face.py` (TensorLy, run by
//!   hand). See `imputation.rs`.
//! * Correspondence (§5.3.2): the generic ICT face fitted to a re-meshed noisy copy of a known
//!   face (`correspondence_rms_mm`).
//!
//! * Tracking (§5.4.1, Eq. 5.7–5.9) from synthetic 2D point tracks of 1,000 vertices of a
//!   person not in the model (0.5 px noise standing in for KLT error; no video, no KLT), and a
//!   geometry-only transfer of the tracked expression onto two training people.
//!
//! Writes under `out/face_transfer/`: `decomposition.png`, `imputation.png`,
//! `imputation_by_identities.png`, `imputed_faces.png`, `model_faces.png`, `correspondence.png`, `tracking.png`,
//! `transfer.png`, `figures.json`,
//! `manifest.json`; the last stdout line is one JSON object.
//!
//! `cargo run --release --example face_transfer [-- --quick] [-- --out DIR]` (`--quick`: two
//! hold-out fractions, a coarser decomposition sweep).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)] // not library code
#![recursion_limit = "256"]

use std::time::Instant;

use clap::Parser;
use nalgebra::DVector;
use serde_json::json;

use dynamic_shapes::core::math::DVec3;
use dynamic_shapes::core::mesh::{RefineParams, Refinement, TriMesh};
use dynamic_shapes::face::validation::{
    aligned_rms, bilinear_face_set, face_width, feature_vertices, hold_out, ict_face_set,
    impute_rel_error, point_track_sequence, remeshed_scan, trilinear_face_set, FaceSet,
    FaceSetParams, IctBasis,
};
use dynamic_shapes::face::{
    fit_template, impute, impute_ppca, mean_weights, track_points, CorrespondenceParams, Dials,
    FaceTensor, ImputeParams, ModelParams, MultilinearModel, PpcaParams, TrackParams,
};
use dynamic_shapes_studio::{preview, Paint, PreviewPanel};
use example_kit::plot::{error_colour, Chart, ColourBar, Series, Style};
use example_kit::{Goal, Headline, Run};

mod imputation;
mod video;

/// Data units (ICT: ≈ cm) to mm.
pub(crate) const MM: f64 = 10.0;
/// Top of the correspondence error colour scale, mm.
const CORR_MAX_MM: f64 = 5.0;

fn mesh(set: &FaceSet, v: Vec<DVec3>) -> TriMesh {
    TriMesh::new(v, set.triangles.clone()).unwrap()
}

/// Per-vertex distance colours, mm.
fn colours(a: &[DVec3], b: &[DVec3], max_mm: f64) -> Vec<[u8; 3]> {
    a.iter()
        .zip(b)
        .map(|(x, y)| error_colour(Some(MM * x.distance(*y)), max_mm))
        .collect()
}

fn rms_mm(a: &[DVec3], b: &[DVec3]) -> f64 {
    MM * (a
        .iter()
        .zip(b)
        .map(|(x, y)| x.distance_squared(*y))
        .sum::<f64>()
        / a.len() as f64)
        .sqrt()
}

/// `‖Y − row means − column means + grand mean‖ / ‖Y − grand mean‖` over the two attribute
/// modes of a bilinear data tensor, per vertex coordinate: 0 exactly when the faces are
/// additive in expression and identity.
fn interaction_energy(t: &FaceTensor) -> f64 {
    let (de, di) = (t.attribute_sizes()[0], t.attribute_sizes()[1]);
    let k = de * di;
    let (mut num, mut den) = (0.0, 0.0);
    for row in t.tensor().data().chunks_exact(k) {
        let g = row.iter().sum::<f64>() / k as f64;
        let re: Vec<f64> = (0..de)
            .map(|e| row[e * di..(e + 1) * di].iter().sum::<f64>() / di as f64)
            .collect();
        let ci: Vec<f64> = (0..di)
            .map(|i| (0..de).map(|e| row[e * di + i]).sum::<f64>() / de as f64)
            .collect();
        for e in 0..de {
            for i in 0..di {
                let x = row[e * di + i];
                num += (x - re[e] - ci[i] + g).powi(2);
                den += (x - g).powi(2);
            }
        }
    }
    (num / den).sqrt()
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = example_kit::cli::Args::parse();
    let quick = args.common.quick;
    let mut run = Run::start(
        "face_transfer",
        &args.common,
        "Multilinear face models from the ICT face basis with an identity-dependent expression \
         interaction: N-mode SVD / HOOI, dial tuning, PPCA imputation of held-out faces, \
         template correspondence (Vlasic 2010 Ch. 5)",
    )?;

    // --- Data sets.
    let stage = run.stage("data sets", None);
    let basis = IctBasis::read(example_kit::data_path("ict-face")?)?;
    let bi = bilinear_face_set(&basis, &FaceSetParams::default())?;
    let tri = trilinear_face_set(&basis, &FaceSetParams::default().with_identities(16))?;
    let ict = ict_face_set(&basis)?;
    stage.finish(format!(
        "{} vertices; interaction {:.3} (bilinear), {:.3} (trilinear)",
        basis.neutral().vertices.len(),
        bi.interaction_fraction,
        tri.interaction_fraction
    ));

    // --- Decomposition at the thesis's truncations.
    let stage = run.stage("decomposition", None);
    let (bi_model, bi_fit) = MultilinearModel::fit(&bi.faces, &ModelParams::thesis_bilinear())?;
    let (tri_model, tri_fit) = MultilinearModel::fit(&tri.faces, &ModelParams::thesis_trilinear())?;
    let (_, ict_fit) = MultilinearModel::fit(&ict.faces, &ModelParams::thesis_bilinear())?;
    let (_, ict_full) = MultilinearModel::fit(&ict.faces, &ModelParams::new(&[17, 11]))?;
    let bi_interaction = interaction_energy(&bi.faces);
    let ict_interaction = interaction_energy(&ict.faces);
    // Error vs identity knobs for a few expression knob counts (HOSVD, bilinear; ICT dashed).
    let expr_knobs: Vec<usize> = if quick {
        vec![2, 6, 10]
    } else {
        vec![2, 4, 6, 8, 10]
    };
    let id_knobs: Vec<usize> = if quick {
        vec![1, 3, 5, 7, 9, 11, 13, 15]
    } else {
        (1..=15).collect()
    };
    let palette = [
        [40, 90, 200],
        [220, 120, 40],
        [40, 160, 80],
        [160, 60, 160],
        [120, 120, 120],
    ];
    let mut chart = Chart::new(
        "Bilinear model: relative error of the truncated N-mode SVD",
        "identity knobs kept",
        "relative error ‖T − T̂‖ / ‖T‖",
    );
    let mut sweep = Vec::new();
    for (c, &e) in expr_knobs.iter().enumerate() {
        let mut pts = Vec::new();
        for &i in &id_knobs {
            let p = ModelParams::new(&[e, i]).with_refine(None);
            let (_, f) = MultilinearModel::fit(&bi.faces, &p)?;
            pts.push((i as f64, f.hosvd_rel_error));
            sweep.push(
                json!({"expression": e, "identity": i, "hosvd_rel_error": f.hosvd_rel_error}),
            );
        }
        chart = chart.with(Series::new(
            format!("{e} expression knobs"),
            palette[c % palette.len()],
            Style::LineMarkers,
            pts,
        ));
    }
    let mut ict_pts = Vec::new();
    for i in 1..=11 {
        let (_, f) =
            MultilinearModel::fit(&ict.faces, &ModelParams::new(&[17, i]).with_refine(None))?;
        ict_pts.push((i as f64, f.hosvd_rel_error));
    }
    chart = chart
        .with(Series::new(
            "ICT shapes (17 expr. × 11 id.), all expression knobs",
            [30, 30, 30],
            Style::Dashed,
            ict_pts,
        ))
        .with(Series::new(
            "thesis truncation 6 × 9 (HOOI)",
            [230, 30, 30],
            Style::Markers,
            vec![(9.0, bi_fit.hooi_rel_error)],
        ));
    run.save_picture(
        "decomposition.png",
        &chart.draw()?,
        "Relative reconstruction error of the bilinear data set vs identity knobs kept, per \
         number of expression knobs (HOSVD); the ICT shapes' own tensor dashed; the thesis's \
         6 × 9 truncation after HOOI in red",
    )?;
    stage.finish(format!(
        "bilinear 6×9: HOSVD {:.4} HOOI {:.4}; trilinear 4×4×16: HOSVD {:.4} HOOI {:.4}",
        bi_fit.hosvd_rel_error,
        bi_fit.hooi_rel_error,
        tri_fit.hosvd_rel_error,
        tri_fit.hooi_rel_error
    ));

    // --- Speed at ≈ 30k vertices (the thesis's scans): every face of the bilinear and the
    // trilinear set refined (Phong tessellation, edges ≤ the mean ICT edge), then HOOI at the
    // thesis's truncations and the 15 % imputation timed. Full run only.
    let stage = run.stage("30k vertices", None);
    let mut fine_figures = json!(null);
    if !quick {
        let mean_edge = {
            let m = basis.neutral();
            let (mut sum, mut n) = (0.0, 0usize);
            for f in &m.faces {
                for k in 0..3 {
                    sum += m.vertices[f[k] as usize].distance(m.vertices[f[(k + 1) % 3] as usize]);
                    n += 1;
                }
            }
            sum / n as f64
        };
        let refinement = Refinement::new(
            basis.neutral(),
            &vec![true; basis.neutral().faces.len()],
            &RefineParams::new(mean_edge),
        )?;
        let fine_run = |set: &FaceTensor,
                        params: &ModelParams|
         -> Result<serde_json::Value, Box<dyn std::error::Error>> {
            let fine_faces: Vec<Vec<DVec3>> = (0..set.face_count())
                .map(|f| Ok(refinement.evaluate(&set.face(f)?)?.vertices))
                .collect::<Result<_, Box<dyn std::error::Error>>>()?;
            let fine = FaceTensor::from_faces(set.attribute_sizes(), &fine_faces)?;
            drop(fine_faces);
            let (_, fine_fit) = MultilinearModel::fit(&fine, params)?;
            let fine_known = hold_out(fine.attribute_sizes(), 0.15, 7)?;
            let t0 = Instant::now();
            let fine_imp = impute(&fine, &fine_known, &ImputeParams::default())?;
            let fine_impute_ms = 1e3 * t0.elapsed().as_secs_f64();
            let fine_impute_err = impute_rel_error(&fine, &fine_imp.faces, &fine_known)?;
            let t0 = Instant::now();
            let thesis = impute_ppca(&fine, &fine_known, &PpcaParams::default())?;
            let thesis_ms = 1e3 * t0.elapsed().as_secs_f64();
            Ok(json!({
                "vertices": fine.vertex_count(),
                "tucker_ms": fine_fit.time_ms,
                "hooi_rel_error": fine_fit.hooi_rel_error,
                "impute_ms_15": fine_impute_ms,
                "impute_rel_error_15": fine_impute_err,
                "thesis_impute_ms_15": thesis_ms,
                "thesis_impute_rel_error_15": impute_rel_error(&fine, &thesis.faces, &fine_known)?,
            }))
        };
        fine_figures = json!({
            "bilinear": fine_run(&bi.faces, &ModelParams::thesis_bilinear())?,
            "trilinear": fine_run(&tri.faces, &ModelParams::thesis_trilinear())?,
        });
    }
    stage.finish(format!("{fine_figures}"));

    // --- Dial tuning and faces from weights (Figure 5-4).
    let stage = run.stage("dials", None);
    let dials = Dials::fit(&bi_model, 0, &bi.labels[0])?;
    let disgust_recipe: (&str, &[(&str, f64)]) = (
        "disgust",
        &[
            ("noseSneer_L", 1.0),
            ("mouthFrown_L", 0.6),
            ("browDown_L", 0.4),
        ],
    );
    let w_disgust = dials.weights(&basis.weights(&disgust_recipe)?)?;
    let w_smile_half = dials.weights(&basis.weights(&(
        "half smile",
        &[("mouthSmile_L", 0.5), ("mouthSmile_R", 0.5)],
    ))?)?;
    let id_w = |i: usize| bi_model.training_weights(1, i).unwrap();
    // Two novel people: mixtures of the training people's weights.
    let novel_a: DVector<f64> = id_w(0) * 0.5 + id_w(4) * 0.3 + id_w(9) * 0.2;
    let novel_b: DVector<f64> = id_w(2) * 0.6 + id_w(7) * 0.4;
    let surprise = bi_model.training_weights(0, 3)?;
    let faces5_4 = [
        bi_model.face(&[w_disgust.clone(), id_w(0)])?,
        bi_model.face(&[w_disgust.clone(), id_w(1)])?,
        bi_model.face(&[surprise.clone(), novel_a])?,
        bi_model.face(&[surprise, novel_b])?,
        bi_model.face(&[w_smile_half, id_w(1)])?,
    ];
    let meshes: Vec<TriMesh> = faces5_4.iter().map(|f| mesh(&bi, f.clone())).collect();
    let panels: Vec<PreviewPanel> = meshes
        .iter()
        .map(|m| PreviewPanel {
            mesh: m,
            paint: Paint::Flat([215, 180, 160]),
        })
        .collect();
    let img = example_kit::plot::titled(
        &preview(&panels, 300)?,
        "Faces from the bilinear model's weights (like Vlasic 2010 Figure 5-4)",
        Some(
            "left to right: disgust (not in the data, set by tuned dials) on persons 0 and 1; \
             surprise on two novel people; a half smile (tuned dials) on person 1",
        ),
    )?;
    run.save_picture(
        "model_faces.png",
        &img,
        "Faces generated from attribute weights (Eq. 5.5): an expression not in the data set \
         set through the tuned expression dials on two people, a training expression on two \
         novel identities, a half smile",
    )?;
    stage.finish(format!("dial fit residual {:.2e}", dials.residual()));

    // --- Missing data.
    let impute_figures = imputation::imputation(&mut run, &basis, [&tri, &bi, &ict], quick)?;

    // --- Correspondence.
    let stage = run.stage("correspondence", None);
    let f_truth = bi.faces.face_index(&[1, 3])?; // person 3 smiling
    let truth = bi.faces.face(f_truth)?;
    let truth_mesh = mesh(&bi, truth.clone());
    let scan = remeshed_scan(&truth_mesh, 0.1, 0.01, 3)?;
    let features = feature_vertices(basis.neutral(), 42)?;
    // The marked points: true positions with 0.5 mm marking noise (deterministic jitter).
    let marked: Vec<DVec3> = features
        .iter()
        .enumerate()
        .map(|(j, &f)| {
            let s = (j as f64 * 2.399).sin_cos();
            truth[f] + DVec3::new(s.0, s.1, (j as f64 * 1.3).sin()) * 0.05 / 3f64.sqrt()
        })
        .collect();
    let t0 = Instant::now();
    let fit = fit_template(
        basis.neutral(),
        &features,
        &scan,
        &marked,
        &CorrespondenceParams::default(),
    )?;
    let corr_ms = 1e3 * t0.elapsed().as_secs_f64();
    let corr_rms = rms_mm(&fit.vertices, &truth);
    let procrustes_rms = rms_mm(&fit.aligned, &truth);
    let aligned_mesh = mesh(&bi, fit.aligned.clone());
    let fit_mesh = mesh(&bi, fit.vertices.clone());
    let (ca, cf) = (
        colours(&fit.aligned, &truth, CORR_MAX_MM),
        colours(&fit.vertices, &truth, CORR_MAX_MM),
    );
    let img = preview(
        &[
            PreviewPanel {
                mesh: &scan,
                paint: Paint::Flat([200, 200, 200]),
            },
            PreviewPanel {
                mesh: &aligned_mesh,
                paint: Paint::PerVertex(&ca),
            },
            PreviewPanel {
                mesh: &fit_mesh,
                paint: Paint::PerVertex(&cf),
            },
        ],
        320,
    )?;
    let ramp = |x: f64| error_colour(Some(x * CORR_MAX_MM), CORR_MAX_MM);
    let img = example_kit::plot::with_colour_bar(
        &img,
        &ColourBar {
            label: "distance to the true vertex (mm)",
            min: 0.0,
            max: CORR_MAX_MM,
            ramp: &ramp,
            note: Some("top: ≥ 5 mm"),
        },
    )?;
    let img = example_kit::plot::titled(
        &img,
        "Template fitting to a re-meshed noisy scan (§5.3.2)",
        Some(&format!(
            "left: scan ({} vertices); middle: generic template after Procrustes on 42 features \
             (RMS {procrustes_rms:.2} mm); right: after the deformation (RMS {corr_rms:.2} mm)",
            scan.vertices.len()
        )),
    )?;
    run.save_picture(
        "correspondence.png",
        &img,
        "The generic ICT face fitted to a re-meshed, noisy copy of person 3 smiling: the scan, \
         the template after Procrustes alignment and after the minimal deformation, coloured \
         by the distance of each template vertex to its true position (mm)",
    )?;
    stage.finish(format!(
        "RMS {corr_rms:.2} mm (Procrustes only {procrustes_rms:.2} mm)"
    ));

    // --- Tracking from 2D point tracks (Eq. 5.7–5.9 with the point motion given) and a
    // geometry-only transfer.
    let stage = run.stage("tracking", None);
    let novel = bilinear_face_set(
        &basis,
        &FaceSetParams::default().with_identities(1).with_seed(99),
    )?;
    let tracked = feature_vertices(basis.neutral(), 1000)?;
    let order = [0, 1, 3, 5, 2, 7, 4, 9, 6, 8, 0];
    let frame_count = if quick { 60 } else { 120 };
    let seq = point_track_sequence(&novel.faces, &order, &tracked, frame_count, 0.5, 5)?;
    let track = track_points(
        &bi_model,
        &tracked,
        &seq.frames,
        &[false, true],
        &TrackParams::default(),
    )?;
    let track_fps = frame_count as f64 / track.seconds;
    let width = face_width(&seq.truth[0]);
    let mean_face = bi_model.face(&mean_weights(&bi_model)?)?;
    let (mut track_pct, mut mean_pct) = (Vec::new(), Vec::new());
    for (t, truth) in seq.truth.iter().enumerate() {
        let f = bi_model.face(&track.weights[t])?;
        track_pct.push(100.0 * aligned_rms(&f, truth)? / width);
        mean_pct.push(100.0 * aligned_rms(&mean_face, truth)? / width);
    }
    let avg = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let neutral_w = bi_model.training_weights(0, 0)?;
    let id_face = bi_model.face(&[neutral_w.clone(), track.weights[0][1].clone()])?;
    let identity_rms_mm = MM * aligned_rms(&id_face, &novel.faces.face(0)?)?;
    let mean_id_face = bi_model.face(&[neutral_w, mean_weights(&bi_model)?[1].clone()])?;
    let mean_identity_rms_mm = MM * aligned_rms(&mean_id_face, &novel.faces.face(0)?)?;
    let chart = Chart::new(
        "Tracking a person not in the model from 1,000 given 2D point tracks (0.5 px noise)",
        "frame",
        "vertex RMS after similarity alignment (% of face width)",
    )
    .with(Series::new(
        "tracked (bilinear 6 × 9)",
        [40, 90, 200],
        Style::Line,
        track_pct
            .iter()
            .enumerate()
            .map(|(t, v)| (t as f64, *v))
            .collect(),
    ))
    .with(Series::new(
        "mean face (no tracking)",
        [220, 120, 40],
        Style::Dashed,
        mean_pct
            .iter()
            .enumerate()
            .map(|(t, v)| (t as f64, *v))
            .collect(),
    ))
    .with(video::goal_line(frame_count));
    run.save_picture(
        "tracking.png",
        &chart.draw()?,
        "Per-frame 3D vertex error of the tracked faces (similarity-aligned, % of face width) \
         against the mean face; point tracks synthesised from the true faces (not from video)",
    )?;
    stage.finish(format!(
        "vertex RMS {:.2} % of face width (mean face {:.2} %), identity {identity_rms_mm:.2} mm, {track_fps:.1} fps",
        avg(&track_pct),
        avg(&mean_pct)
    ));

    let mut video_figures = video::video_tracking(&mut run, &basis, &bi, &bi_model, quick)?;
    let tri_video = video::trilinear_video(&mut run, &basis, &bi.triangles, &tri_model, quick)?;
    if let (Some(f), Some(v)) = (video_figures.as_object_mut(), tri_video.as_object()) {
        f.extend(v.clone());
    }

    for h in [
        Headline::new(
            "track_vertex_rms_pct",
            "tracking vertex RMS from rendered video",
            "%",
        )
        .goal(Goal::AtMost(1.0)),
        Headline::new(
            "track_fps",
            "video tracking speed, 1,000 vertices incl. KLT",
            "fps",
        )
        .paper("≈ 1 fps (\"averages at one frame per second\"), thesis §5.4.1")
        .goal(Goal::AtLeast(30.0)),
        Headline::new(
            "track_fps_cpu",
            "video tracking speed on one core (thread CPU time), 1,000 vertices incl. KLT",
            "fps",
        )
        .paper("≈ 1 fps (\"averages at one frame per second\"), thesis §5.4.1")
        .goal(Goal::AtLeast(60.0)),
        Headline::new("hosvd_rel_error", "bilinear 6×9 HOSVD relative error", ""),
        Headline::new("hooi_rel_error", "bilinear 6×9 HOOI relative error", ""),
        Headline::new(
            "hooi_rel_error_trilinear",
            "trilinear 4×4×16 HOOI relative error",
            "",
        ),
        Headline::new(
            "impute_rel_error_15",
            "imputation error, 15 % held out (trilinear)",
            "",
        )
        .paper("< 0.09 (9 %) for up to 50 % missing (ISVD, trilinear), thesis §5.3.4")
        .goal(Goal::AtMost(0.05)),
        Headline::new(
            "impute_rel_error_50",
            "imputation error, 50 % held out (trilinear)",
            "",
        )
        .paper("< 0.09 (9 %) for up to 50 % missing (ISVD, trilinear), thesis §5.3.4")
        .goal(Goal::AtMost(0.09)),
        Headline::new(
            "averaging_impute_rel_error_15",
            "averaging baseline, 15 %",
            "",
        )
        .baseline(),
        Headline::new(
            "averaging_impute_rel_error_50",
            "averaging baseline, 50 %",
            "",
        )
        .baseline(),
        Headline::new("correspondence_rms_mm", "correspondence vertex RMS", "mm"),
        Headline::new(
            "interaction_fraction",
            "interaction strength (bilinear set)",
            "",
        ),
    ] {
        run.headline(h);
    }
    let mut figures = json!({
        "vertices": basis.neutral().vertices.len(),
        "interaction_fraction": bi.interaction_fraction,
        "interaction_fraction_trilinear": tri.interaction_fraction,
        "interaction_energy_bilinear": bi_interaction,
        "interaction_energy_ict": ict_interaction,
        "hosvd_rel_error": bi_fit.hosvd_rel_error,
        "hooi_rel_error": bi_fit.hooi_rel_error,
        "hooi_sweeps": bi_fit.sweeps,
        "tucker_ms": bi_fit.time_ms,
        "hosvd_rel_error_trilinear": tri_fit.hosvd_rel_error,
        "hooi_rel_error_trilinear": tri_fit.hooi_rel_error,
        "tucker_ms_trilinear": tri_fit.time_ms,
        "ict_hosvd_rel_error": ict_fit.hosvd_rel_error,
        "ict_hooi_rel_error": ict_fit.hooi_rel_error,
        "ict_full_rank_rel_error": ict_full.hooi_rel_error,
        "dial_fit_residual": dials.residual(),
        "subdivided": fine_figures,
        "decomposition_sweep": sweep,
        "correspondence_rms_mm": corr_rms,
        "correspondence_procrustes_rms_mm": procrustes_rms,
        "correspondence_surface_rms_mm": fit.surface_rms.last().map(|s| s * MM),
        "correspondence_ms": corr_ms,
        "scan_vertices": scan.vertices.len(),
        "points_tracking": "from given 2D point tracks (0.5 px noise), no video",
        "points_track_vertex_rms_pct": avg(&track_pct),
        "points_track_mean_face_rms_pct": avg(&mean_pct),
        "points_track_identity_rms_mm": identity_rms_mm,
        "points_track_mean_identity_rms_mm": mean_identity_rms_mm,
        "points_track_fps": track_fps,
        "points_track_frames": frame_count,
        "points_track_points": tracked.len(),
        "points_track_reprojection_rms_px": avg(&track.reprojection_rms_px),
    });
    // The imputation and video figures at the top level (names compared across runs).
    for extra in [&impute_figures, &video_figures] {
        if let (Some(f), Some(v)) = (figures.as_object_mut(), extra.as_object()) {
            for (k, x) in v {
                f.insert(k.clone(), x.clone());
            }
        }
    }
    run.finish(figures)?;
    Ok(())
}
