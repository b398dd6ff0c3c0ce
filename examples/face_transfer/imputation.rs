//! Missing data (§5.3.4): held-out faces filled by the default imputation (the model chosen
//! by cross-validation on the known faces), by the thesis's PPCA alone and by the averaging
//! baseline; the sweep over the number of people and the generator's identity rank at 50 %
//! held out (`impute_rel_error_50_by_identities`); the `.npy` files for TensorLy
//! (`masked_tucker_face.py`, run by hand).

use std::io::Write;
use std::path::Path;
use std::time::Instant;

use serde_json::{json, Value};

use dynamic_shapes::core::math::DVec3;
use dynamic_shapes::face::validation::{
    feature_vertices, hold_out, impute_rel_error, trilinear_face_set, FaceSet, FaceSetParams,
    IctBasis,
};
use dynamic_shapes::face::{
    impute, impute_by_averaging, impute_ppca, FaceTensor, ImputeModel, ImputeParams, KnownFaces,
    PpcaParams,
};
use dynamic_shapes_studio::{preview, Paint, PreviewPanel};
use example_kit::plot::{error_colour, Chart, ColourBar, Series, Style};
use example_kit::Run;

use crate::{colours, mesh};

type Res<T> = Result<T, Box<dyn std::error::Error>>;

/// Top of the imputation error colour scale, mm.
const IMPUTE_MAX_MM: f64 = 3.0;

/// Writes a float64 C-order `.npy` file.
fn write_npy(path: &Path, shape: &[usize], data: &[f64]) -> std::io::Result<()> {
    let dims: Vec<String> = shape.iter().map(|d| d.to_string()).collect();
    let tuple = if dims.len() == 1 {
        format!("({},)", dims[0])
    } else {
        format!("({})", dims.join(", "))
    };
    let mut header = format!("{{'descr': '<f8', 'fortran_order': False, 'shape': {tuple}, }}");
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(' ');
    }
    header.push('\n');
    let mut f = std::io::BufWriter::new(std::fs::File::create(path)?);
    f.write_all(b"\x93NUMPY\x01\x00")?;
    f.write_all(&(header.len() as u16).to_le_bytes())?;
    f.write_all(header.as_bytes())?;
    for x in data {
        f.write_all(&x.to_le_bytes())?;
    }
    f.flush()
}

/// A short name of an imputation model for the figures.
fn model_name(m: &ImputeModel) -> String {
    match m {
        ImputeModel::Averaging => "averaging".into(),
        ImputeModel::Ppca(p) if *p == PpcaParams::default() => "thesis PPCA".into(),
        ImputeModel::Ppca(p) => format!("PPCA {:?} / {}", p.ranks, p.energy),
    }
}

/// One hold-out: the errors of the default, the thesis's PPCA and averaging.
struct ImputeRow {
    fraction: f64,
    seed: u64,
    ours: f64,
    thesis: f64,
    averaging: f64,
    model: String,
    iterations: usize,
    ms: f64,
    thesis_ms: f64,
}

impl ImputeRow {
    fn json(&self) -> Value {
        json!({
            "fraction": self.fraction, "seed": self.seed, "ours": self.ours,
            "thesis": self.thesis, "averaging": self.averaging, "model": self.model,
            "iterations": self.iterations, "ms": self.ms, "thesis_ms": self.thesis_ms,
        })
    }
}

/// The filled tensors of one hold-out (for the pictures and TensorLy).
struct Filled {
    known: KnownFaces,
    ours: FaceTensor,
    averaging: FaceTensor,
}

/// Holds out `fraction` of the faces (seed) and fills them three ways. When the default
/// chooses the thesis's PPCA its fill is the thesis's (the same computation), so it is not
/// run twice; its time is then the final fill's share, not measured separately.
fn impute_run(faces: &FaceTensor, fraction: f64, seed: u64) -> Res<(ImputeRow, Filled)> {
    let known = hold_out(faces.attribute_sizes(), fraction, seed)?;
    let t0 = Instant::now();
    let ours = impute(faces, &known, &ImputeParams::default())?;
    let ms = 1e3 * t0.elapsed().as_secs_f64();
    let t0 = Instant::now();
    let (thesis, thesis_ms) = if ours.model == ImputeModel::Ppca(PpcaParams::default()) {
        (impute_rel_error(faces, &ours.faces, &known)?, f64::NAN)
    } else {
        let t = impute_ppca(faces, &known, &PpcaParams::default())?;
        let ms = 1e3 * t0.elapsed().as_secs_f64();
        (impute_rel_error(faces, &t.faces, &known)?, ms)
    };
    let averaging = impute_by_averaging(faces, &known)?;
    let row = ImputeRow {
        fraction,
        seed,
        ours: impute_rel_error(faces, &ours.faces, &known)?,
        thesis,
        averaging: impute_rel_error(faces, &averaging, &known)?,
        model: model_name(&ours.model),
        iterations: ours.iterations,
        ms,
        thesis_ms,
    };
    Ok((
        row,
        Filled {
            known,
            ours: ours.faces,
            averaging,
        },
    ))
}

/// Known-face flags as 0/1 for TensorLy.
fn flags(known: &KnownFaces, count: usize) -> Vec<f64> {
    (0..count)
        .map(|f| if known.is_known(f) { 1.0 } else { 0.0 })
        .collect()
}

/// Writes a set's tensor, and per hold-out its mask and the averaging baseline's fill (the
/// start of our PPCA, for TensorLy to start from the same values), under `dir`.
fn write_tensorly(dir: &Path, name: &str, faces: &FaceTensor, runs: &[(f64, &Filled)]) -> Res<()> {
    let t = faces.tensor();
    write_npy(&dir.join(format!("{name}.npy")), t.shape(), t.data())?;
    for (p, filled) in runs {
        let pct = (100.0 * p).round();
        write_npy(
            &dir.join(format!("{name}_known_{pct:02}.npy")),
            faces.attribute_sizes(),
            &flags(&filled.known, faces.face_count()),
        )?;
        let start = filled.averaging.tensor();
        write_npy(
            &dir.join(format!("{name}_start_{pct:02}.npy")),
            start.shape(),
            start.data(),
        )?;
    }
    Ok(())
}

/// People, then the mean errors of the default, the thesis's PPCA and averaging.
type SweepPoint = (f64, f64, f64, f64);

/// The sweep over people: 50 % held out of trilinear sets (5 visemes × 5 expressions × P
/// people, all 6,706 vertices) for P people and identity rank r (the generator's identity
/// modes + 1; full = P), per hold-out seed. Returns the rows and every hold-out's row.
fn identities_sweep(run: &mut Run, basis: &IctBasis, quick: bool) -> Res<(Value, Vec<ImputeRow>)> {
    let people: &[usize] = if quick { &[16] } else { &[16, 32, 64] };
    let seeds: &[u64] = if quick { &[7] } else { &[7, 8, 9] };
    let palette = [[40, 160, 80], [40, 90, 200], [200, 60, 60]];
    let mut rows = Vec::new();
    let mut all = Vec::new();
    let mut by_rank: Vec<(String, Vec<SweepPoint>)> = Vec::new();
    for &p in people {
        let ranks = if quick { vec![11, p] } else { vec![6, 11, p] };
        for (ri, &r) in ranks.iter().enumerate() {
            let params = FaceSetParams::default()
                .with_identities(p)
                .with_identity_modes(r - 1);
            let set = trilinear_face_set(basis, &params)?;
            let (mut ours, mut thesis, mut avg, mut models, mut per_seed) =
                (0.0, 0.0, 0.0, Vec::new(), Vec::new());
            for &seed in seeds {
                let (row, _) = impute_run(&set.faces, 0.5, seed)?;
                ours += row.ours / seeds.len() as f64;
                thesis += row.thesis / seeds.len() as f64;
                avg += row.averaging / seeds.len() as f64;
                models.push(row.model.clone());
                per_seed.push(row.json());
                all.push(row);
            }
            let label = if r == p {
                "full".to_string()
            } else {
                r.to_string()
            };
            eprintln!(
                "  {p} people, identity rank {label}: default {ours:.4} thesis {thesis:.4} averaging {avg:.4} ({models:?})"
            );
            rows.push(json!({
                "identities": p, "identity_rank": r, "full_rank": r == p,
                "default": ours, "thesis": thesis, "averaging": avg, "models": models,
                "per_seed": per_seed,
            }));
            let key = if quick { ri + 1 } else { ri };
            let name = ["rank 6", "rank 11", "full rank"][key].to_string();
            match by_rank.iter_mut().find(|(n, _)| *n == name) {
                Some((_, v)) => v.push((p as f64, ours, thesis, avg)),
                None => by_rank.push((name, vec![(p as f64, ours, thesis, avg)])),
            }
        }
    }
    let mut chart = Chart::new(
        "Imputation at 50 % held out vs people (trilinear sets, mean of the hold-out seeds)",
        "people in the data set",
        "‖error‖ / ‖held-out faces − mean face‖ (%)",
    );
    chart.log_x = true;
    for (i, (name, pts)) in by_rank.iter().enumerate() {
        let c = palette[(i + if quick { 1 } else { 0 }) % palette.len()];
        let series = |f: fn(&SweepPoint) -> f64| -> Vec<(f64, f64)> {
            pts.iter().map(|q| (q.0, 100.0 * f(q))).collect()
        };
        chart = chart
            .with(Series::new(
                format!("default, identity {name}"),
                c,
                Style::LineMarkers,
                series(|q| q.1),
            ))
            .with(Series::new(
                format!("thesis PPCA, {name}"),
                c,
                Style::Dashed,
                series(|q| q.2),
            ))
            .with(Series::new(
                format!("averaging, {name}"),
                c,
                Style::Markers,
                series(|q| q.3),
            ));
    }
    run.save_picture(
        "imputation_by_identities.png",
        &chart.draw()?,
        "Relative error of the held-out faces at 50 % missing against the number of people, \
         for the generator's identity rank 6, 11 (the ICT basis) and full (as many identity \
         modes as people): the default imputation (solid), the thesis's PPCA alone (dashed) \
         and the averaging baseline (markers), mean over the hold-out seeds",
    )?;
    Ok((Value::Array(rows), all))
}

/// The imputation stage: the hold-outs of the trilinear, bilinear, ICT and subsampled sets,
/// the sweep over people and identity rank, the pictures; returns the figures.
pub(crate) fn imputation(
    run: &mut Run,
    basis: &IctBasis,
    sets: [&FaceSet; 3],
    quick: bool,
) -> Res<Value> {
    let [tri, bi, ict] = sets;
    let stage = run.stage("imputation", None);
    let fractions: Vec<f64> = if quick {
        vec![0.15, 0.5]
    } else {
        vec![0.1, 0.15, 0.2, 0.3, 0.4, 0.5]
    };
    let tensorly_dir = run.path("tensorly");
    std::fs::create_dir_all(&tensorly_dir)?;
    let mut tri_rows = Vec::new();
    let mut tri_filled = Vec::new();
    for &p in &fractions {
        let (row, filled) = impute_run(&tri.faces, p, 7)?;
        tri_rows.push(row);
        tri_filled.push((p, filled));
    }
    let keep: Vec<(f64, &Filled)> = tri_filled
        .iter()
        .filter(|(p, _)| [0.15, 0.5].iter().any(|q| (p - q).abs() < 1e-9))
        .map(|(p, f)| (*p, f))
        .collect();
    write_tensorly(&tensorly_dir, "trilinear", &tri.faces, &keep)?;
    let mut bi_rows = Vec::new();
    let mut bi_filled = Vec::new();
    for &p in &[0.15, 0.5] {
        let (row, filled) = impute_run(&bi.faces, p, 7)?;
        bi_rows.push(row);
        bi_filled.push((p, filled));
    }
    let runs: Vec<(f64, &Filled)> = bi_filled.iter().map(|(p, f)| (*p, f)).collect();
    write_tensorly(&tensorly_dir, "bilinear", &bi.faces, &runs)?;
    // A 500-vertex subsample of the trilinear set (farthest-point vertices) for TensorLy,
    // whose masked Tucker takes ≈ 35 s per sweep on the full tensor here; ours and the
    // baseline on the same subsample.
    let sub = tri
        .faces
        .vertex_subset(&feature_vertices(basis.neutral(), 500)?)?;
    let mut sub_rows = Vec::new();
    let mut sub_filled = Vec::new();
    for &p in &[0.15, 0.5] {
        let (row, filled) = impute_run(&sub, p, 7)?;
        sub_rows.push(row);
        sub_filled.push((p, filled));
    }
    let runs: Vec<(f64, &Filled)> = sub_filled.iter().map(|(p, f)| (*p, f)).collect();
    write_tensorly(&tensorly_dir, "trilinear_sub500", &sub, &runs)?;
    // The ICT shapes: additive, so the averaging baseline is exact there.
    let (ict_row, _) = impute_run(&ict.faces, 0.15, 7)?;
    eprintln!("  sweep over people and identity rank, 50 % held out");
    let (by_identities, sweep_rows) = identities_sweep(run, basis, quick)?;
    let pct = |rows: &[ImputeRow], f: fn(&ImputeRow) -> f64| -> Vec<(f64, f64)> {
        rows.iter()
            .map(|r| (100.0 * r.fraction, 100.0 * f(r)))
            .collect()
    };
    let chart = Chart::new(
        "Imputation of held-out faces (trilinear set, 5 × 5 × 16)",
        "faces held out (%)",
        "‖error‖ / ‖held-out faces − mean face‖ (%)",
    )
    .with(Series::new(
        "default (model chosen by cross-validation)",
        [40, 90, 200],
        Style::LineMarkers,
        pct(&tri_rows, |r| r.ours),
    ))
    .with(Series::new(
        "thesis PPCA alone",
        [120, 40, 160],
        Style::Markers,
        pct(&tri_rows, |r| r.thesis),
    ))
    .with(Series::new(
        "averaging baseline",
        [220, 120, 40],
        Style::LineMarkers,
        pct(&tri_rows, |r| r.averaging),
    ))
    .with(Series::new(
        "default, bilinear set",
        [40, 90, 200],
        Style::Dashed,
        pct(&bi_rows, |r| r.ours),
    ))
    .with(Series::new(
        "averaging, bilinear set",
        [220, 120, 40],
        Style::Dashed,
        pct(&bi_rows, |r| r.averaging),
    ))
    .with(Series::new(
        "goals (15 %: 5 %, 50 %: 9 %)",
        [230, 30, 30],
        Style::Markers,
        vec![(15.0, 5.0), (50.0, 9.0)],
    ));
    run.save_picture(
        "imputation.png",
        &chart.draw()?,
        "Relative error of the imputed faces vs the fraction held out: the default imputation \
         (model chosen by cross-validation on the known faces), the thesis's PPCA alone and \
         the averaging baseline, trilinear (solid) and bilinear (dashed) sets; red: the goals",
    )?;
    // Figure 5-6: a few held-out faces, ours / truth / averaging, coloured by error.
    if let Some((_, shown)) = tri_filled.iter().find(|(p, _)| (p - 0.15).abs() < 1e-9) {
        let picks: Vec<usize> = shown
            .known
            .missing()
            .into_iter()
            .step_by(12)
            .take(4)
            .collect();
        let mut rows = Vec::new();
        for which in 0..3 {
            let mut ms = Vec::new();
            let mut cs = Vec::new();
            for &f in &picks {
                let truth = tri.faces.face(f)?;
                let est: Vec<DVec3> = match which {
                    0 => shown.ours.face(f)?,
                    1 => truth.clone(),
                    _ => shown.averaging.face(f)?,
                };
                cs.push(colours(&est, &truth, IMPUTE_MAX_MM));
                ms.push(mesh(tri, est));
            }
            let panels: Vec<PreviewPanel> = ms
                .iter()
                .zip(&cs)
                .map(|(m, c)| PreviewPanel {
                    mesh: m,
                    paint: if which == 1 {
                        Paint::Flat([200, 200, 200])
                    } else {
                        Paint::PerVertex(c)
                    },
                })
                .collect();
            rows.push(preview(&panels, 260)?);
        }
        let img = example_kit::plot::label_rows(
            &example_kit::plot::stacked(&rows)?,
            &["ours (default)", "truth", "averaging"],
            130,
        )?;
        let ramp = |x: f64| error_colour(Some(x * IMPUTE_MAX_MM), IMPUTE_MAX_MM);
        let img = example_kit::plot::with_colour_bar(
            &img,
            &ColourBar {
                label: "distance to the true vertex (mm)",
                min: 0.0,
                max: IMPUTE_MAX_MM,
                ramp: &ramp,
                note: Some("top: ≥ 3 mm"),
            },
        )?;
        let names: Vec<String> = picks
            .iter()
            .map(|&f| {
                let a = [f / 80, (f / 16) % 5, f % 16];
                format!(
                    "{} / {} / p{}",
                    tri.value_names[0][a[0]], tri.value_names[1][a[1]], a[2]
                )
            })
            .collect();
        let img = example_kit::plot::titled(
            &img,
            "Held-out faces, 15 % missing (like Vlasic 2010 Figure 5-6)",
            Some(&format!("columns: {}", names.join("; "))),
        )?;
        run.save_picture(
            "imputed_faces.png",
            &img,
            "Four held-out faces of the trilinear set (15 % missing): our default imputation, \
             the truth, the averaging baseline, coloured by the distance to the true vertex (mm)",
        )?;
    }
    let at = |rows: &[ImputeRow], p: f64, f: fn(&ImputeRow) -> f64| {
        rows.iter()
            .find(|r| (r.fraction - p).abs() < 1e-9)
            .map(f)
            .unwrap_or(f64::NAN)
    };
    stage.finish(format!(
        "trilinear 15 %: ours {:.4} thesis {:.4} averaging {:.4}; ICT 15 %: ours {:.1e} thesis {:.4}",
        at(&tri_rows, 0.15, |r| r.ours),
        at(&tri_rows, 0.15, |r| r.thesis),
        at(&tri_rows, 0.15, |r| r.averaging),
        ict_row.ours,
        ict_row.thesis,
    ));
    // Every hold-out of this stage: how often the default did worse than averaging.
    let all: Vec<&ImputeRow> = tri_rows
        .iter()
        .chain(&bi_rows)
        .chain(&sub_rows)
        .chain(std::iter::once(&ict_row))
        .chain(&sweep_rows)
        .collect();
    let worse = all
        .iter()
        .filter(|r| r.ours > r.averaging * (1.0 + 1e-9) + 1e-12)
        .count();
    Ok(json!({
        "impute_rel_error_15": at(&tri_rows, 0.15, |r| r.ours),
        "impute_rel_error_50": at(&tri_rows, 0.5, |r| r.ours),
        "thesis_impute_rel_error_15": at(&tri_rows, 0.15, |r| r.thesis),
        "thesis_impute_rel_error_50": at(&tri_rows, 0.5, |r| r.thesis),
        "averaging_impute_rel_error_15": at(&tri_rows, 0.15, |r| r.averaging),
        "averaging_impute_rel_error_50": at(&tri_rows, 0.5, |r| r.averaging),
        "impute_model_15": tri_rows.iter().find(|r| (r.fraction - 0.15).abs() < 1e-9).map(|r| r.model.clone()),
        "impute_model_50": tri_rows.iter().find(|r| (r.fraction - 0.5).abs() < 1e-9).map(|r| r.model.clone()),
        "impute_iterations_15": at(&tri_rows, 0.15, |r| r.iterations as f64),
        "impute_iterations_50": at(&tri_rows, 0.5, |r| r.iterations as f64),
        "impute_ms_15": at(&tri_rows, 0.15, |r| r.ms),
        "impute_ms_50": at(&tri_rows, 0.5, |r| r.ms),
        "bilinear_impute_rel_error_15": bi_rows[0].ours,
        "bilinear_impute_rel_error_50": bi_rows[1].ours,
        "bilinear_thesis_impute_rel_error_15": bi_rows[0].thesis,
        "bilinear_thesis_impute_rel_error_50": bi_rows[1].thesis,
        "bilinear_averaging_impute_rel_error_15": bi_rows[0].averaging,
        "bilinear_averaging_impute_rel_error_50": bi_rows[1].averaging,
        "ict_impute_rel_error_15": ict_row.ours,
        "ict_thesis_impute_rel_error_15": ict_row.thesis,
        "ict_averaging_impute_rel_error_15": ict_row.averaging,
        "ict_impute_model_15": ict_row.model,
        "sub500_impute_rel_error_15": sub_rows[0].ours,
        "sub500_impute_rel_error_50": sub_rows[1].ours,
        "sub500_thesis_impute_rel_error_15": sub_rows[0].thesis,
        "sub500_thesis_impute_rel_error_50": sub_rows[1].thesis,
        "sub500_averaging_impute_rel_error_15": sub_rows[0].averaging,
        "sub500_averaging_impute_rel_error_50": sub_rows[1].averaging,
        "impute_worse_than_averaging": worse,
        "impute_hold_outs": all.len(),
        "imputation_sweep": tri_rows.iter().map(ImputeRow::json).collect::<Vec<_>>(),
        "impute_rel_error_50_by_identities": by_identities,
    }))
}
