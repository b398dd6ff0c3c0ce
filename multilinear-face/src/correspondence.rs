//! Correspondence (§5.3.2): template fitting to a scan — a similarity (Procrustes) alignment
//! from marked feature points, then a minimal deformation of the template balancing surface
//! smoothness, feature proximity and closest-point proximity, first weighting the features,
//! then the proximity.

use nalgebra::DMatrix;
use nalgebra_sparse::{CooMatrix, CscMatrix};
use skin_core::lsq::{LsqParams, LsqProblem};
use skin_core::math::{fit_similarity, Alignment, DVec3, Similarity};
use skin_core::mesh::{uniform_laplacian, MeshQuery, TriMesh};

use crate::{Error, Result};

/// Parameters of [`fit_template`]. The thesis names the terms and their order, not their
/// weights (it used gradient descent); ours are for a template in ≈ cm.
#[derive(Clone, Debug, PartialEq)]
pub struct CorrespondenceParams {
    /// `(w_feature, w_closest)` per stage, solved in order with the smoothness weight 1:
    /// features first, then proximity (the ratio `w_c / w_f` grows tenfold per stage).
    /// Default `[(100, 0.001), (100, 0.01), (100, 0.1)]` (tuned on the ICT validation: later
    /// stages with proximity dominating pull vertices to the surface but let them slide
    /// along it).
    pub stages: Vec<(f64, f64)>,
    /// Closest-point updates (re-solves) per stage. Default 10.
    pub iterations_per_stage: usize,
}

impl Default for CorrespondenceParams {
    fn default() -> Self {
        CorrespondenceParams {
            stages: vec![(100.0, 0.001), (100.0, 0.01), (100.0, 0.1)],
            iterations_per_stage: 10,
        }
    }
}

/// The result of [`fit_template`].
#[derive(Clone, Debug, PartialEq)]
pub struct TemplateFit {
    /// The deformed template's vertices (in the scan's frame).
    pub vertices: Vec<DVec3>,
    /// The Procrustes alignment of the template's features to the scan's.
    pub alignment: Similarity,
    /// The template's vertices after the alignment only.
    pub aligned: Vec<DVec3>,
    /// RMS distance of the deformed template's vertices to the scan surface after each
    /// stage (scan units).
    pub surface_rms: Vec<f64>,
}

/// Fits `template` to `scan` (§5.3.2): Procrustes from `template_features` (vertex indices)
/// to `scan_features` (marked points on the scan), then per stage and iteration the
/// least-squares deformation `X` minimising
/// `‖L (X − X₀)‖² + w_f Σ ‖X_f − q_f‖² + w_c Σᵢ ‖Xᵢ − cᵢ‖²` (`L` the uniform Laplacian of the
/// template, `X₀` the aligned template, `cᵢ` the closest scan point to the current `Xᵢ`),
/// one symbolic factorisation for all solves.
///
/// # Errors
/// [`Error::SizeMismatch`] for feature lists of different lengths; [`Error::IndexOutOfRange`]
/// for a feature index past the template; [`Error::InvalidParam`] for no stage or a negative
/// weight; the mesh and least-squares errors of `skin-core` (empty or degenerate meshes).
///
/// # Example
///
/// A unit icosphere as the template, fitted to a scan of the same sphere scaled by 2 and moved,
/// from six marked feature points: the fitted vertices lie on the scan.
///
/// ```
/// use multilinear_face::{fit_template, CorrespondenceParams};
/// use skin_core::math::DVec3;
/// use skin_core::mesh::{shapes::icosphere, TriMesh};
///
/// let template = icosphere(2)?;
/// let centre = DVec3::new(1.0, -2.0, 0.5);
/// let scan_vertices: Vec<DVec3> = template.vertices.iter().map(|&p| centre + 2.0 * p).collect();
/// let scan = TriMesh::new(scan_vertices, template.faces.clone())?;
/// let features = [0, 5, 17, 40, 80, 120];
/// let marked: Vec<DVec3> = features.iter().map(|&f| scan.vertices[f]).collect();
/// let fit = fit_template(&template, &features, &scan, &marked, &CorrespondenceParams::default())?;
/// assert!((fit.alignment.scale - 2.0).abs() < 1e-6);
/// assert!(*fit.surface_rms.last().unwrap() < 0.01);
/// # Ok::<(), multilinear_face::Error>(())
/// ```
pub fn fit_template(
    template: &TriMesh,
    template_features: &[usize],
    scan: &TriMesh,
    scan_features: &[DVec3],
    params: &CorrespondenceParams,
) -> Result<TemplateFit> {
    template.validate()?;
    scan.validate()?;
    let v = template.vertices.len();
    for &f in template_features {
        skin_core::check::index("template feature", f, v)?;
    }
    if params.stages.is_empty() {
        return Err(Error::InvalidParam {
            name: "stages",
            reason: "at least one stage is needed".into(),
        });
    }
    for &(wf, wc) in &params.stages {
        skin_core::check::non_negative("w_feature", wf)?;
        skin_core::check::non_negative("w_closest", wc)?;
    }
    let from: Vec<DVec3> = template_features
        .iter()
        .map(|&f| template.vertices[f])
        .collect();
    // Procrustes with scale (Umeyama), reflections excluded.
    let alignment = fit_similarity(&from, scan_features, None, Alignment::Similarity)?;
    let aligned: Vec<DVec3> = template
        .vertices
        .iter()
        .map(|p| alignment.apply(*p))
        .collect();
    let query = MeshQuery::new(scan)?;
    let aligned_mesh = TriMesh::new(aligned.clone(), template.faces.clone())?;
    let l = uniform_laplacian(&aligned_mesh)?;
    let mut cf = CooMatrix::new(template_features.len(), v);
    for (row, &f) in template_features.iter().enumerate() {
        cf.push(row, f, 1.0);
    }
    let mut cc = CooMatrix::new(v, v);
    for i in 0..v {
        cc.push(i, i, 1.0);
    }
    let (wf0, wc0) = params.stages[0];
    let mut solver = LsqProblem::new(l.clone())
        .with_term(CscMatrix::from(&cf), wf0.max(1e-12))
        .with_term(CscMatrix::from(&cc), wc0.max(1e-12))
        .factor(&LsqParams::default())?;
    let to_mat = |p: &[DVec3]| DMatrix::from_fn(p.len(), 3, |i, c| p[i][c]);
    let x0 = to_mat(&aligned);
    let b = &l * &x0;
    let d_f = to_mat(scan_features);
    let mut x = aligned.clone();
    let mut surface_rms = Vec::new();
    for &(wf, wc) in &params.stages {
        solver.set_weights(&[wf.max(1e-12), wc.max(1e-12)])?;
        for _ in 0..params.iterations_per_stage.max(1) {
            let closest = query.closest_points(&x)?;
            let targets: Vec<DVec3> = closest.iter().map(|c| c.position).collect();
            let sol = solver.solve(&b, &[d_f.clone(), to_mat(&targets)])?;
            x = (0..v)
                .map(|i| DVec3::new(sol[(i, 0)], sol[(i, 1)], sol[(i, 2)]))
                .collect();
        }
        let d: Vec<f64> = query
            .closest_points(&x)?
            .iter()
            .map(|c| c.distance)
            .collect();
        surface_rms.push(skin_core::stats::rms(&d));
    }
    Ok(TemplateFit {
        vertices: x,
        alignment,
        aligned,
        surface_rms,
    })
}
