//! Scratch: measurements.
#![allow(clippy::unwrap_used, clippy::print_stdout)]
use dynamic_shapes::face::validation::*;
use dynamic_shapes::face::*;
use dynamic_shapes::core::mesh::TriMesh;
use std::time::Instant;

#[test]
fn scratch() {
    let basis = IctBasis::read(example_kit::data_path("ict-face").unwrap()).unwrap();
    let bi = bilinear_face_set(&basis, &FaceSetParams::default()).unwrap();
    let truth = bi.faces.face(bi.faces.face_index(&[1, 3]).unwrap()).unwrap();
    let truth_mesh = TriMesh::new(truth.clone(), bi.triangles.clone()).unwrap();
    let t0 = Instant::now();
    let scan = remeshed_scan(&truth_mesh, 0.1, 0.01, 3).unwrap();
    let feats = feature_vertices(&basis.neutral, 42).unwrap();
    let marked: Vec<_> = feats.iter().map(|&f| truth[f]).collect();
    for stages in [vec![(10.0, 0.01), (1.0, 0.1), (0.1, 1.0), (0.01, 10.0)], vec![(10.0, 0.01), (1.0, 0.1), (1.0, 1.0)], vec![(100.0, 0.01), (10.0, 0.1), (10.0, 1.0)], vec![(100.0, 0.001), (100.0, 0.01), (100.0, 0.1)], vec![(100.0, 0.01),(100.0, 0.03), (100.0, 0.1), (100.0, 0.3)]] {
    for it in [3, 10] {
    let p = CorrespondenceParams { stages: stages.clone(), iterations_per_stage: it };
    let fit = fit_template(&basis.neutral, &feats, &scan, &marked, &p).unwrap();
    let rms = |x: &[dynamic_shapes::core::math::DVec3]| (x.iter().zip(&truth).map(|(a, b)| a.distance_squared(*b)).sum::<f64>() / x.len() as f64).sqrt() * 10.0;
    println!("scan v {} time {:?} aligned {:.3} mm fit {:.3} mm surf {:?}", scan.vertices.len(), t0.elapsed(), rms(&fit.aligned), rms(&fit.vertices), fit.surface_rms);
    println!("{stages:?} {it}");
    }}
}
