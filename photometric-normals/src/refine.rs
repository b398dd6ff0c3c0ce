//! Fusing the merged mesh with the measured normals (ours, beyond the thesis; issue 14).
//!
//! The thesis merges the per-view surfaces (§3.3.3) and stops there. Its related work (§3.1)
//! cites Nehab, Rusinkiewicz, Davis and Ramamoorthi 2005, "Efficiently combining positions
//! and normals for precise 3D geometry" (ref. \[104\]): positions are trusted for the low
//! frequencies, normals for the high ones, and one sparse linear least-squares solve
//! combines them. The thesis notes that the method needs "initial 3D geometry of reasonable
//! quality" and a single normal map. Our merged mesh is that geometry, and we have one normal
//! map per camera. This module applies Nehab's energy to the merged mesh before the metrics
//! and the hole filling.
//!
//! **Target normals.** Each vertex gets a target normal from the cameras that sample it.
//! The samples are those of Table 3.1's vertex normal deviation
//! ([`crate::vertex_normal_samples`]): the vertex projects onto covered pixels, it is the
//! surface the camera sees there, and the normal map is interpolated bilinearly. The target
//! is either the most frontal camera's sample ([`TargetNormals::MostFrontal`], as the metric
//! takes it) or the samples averaged with weights cos² of the view angle
//! ([`TargetNormals::CosineSquared`]). A vertex that no camera samples keeps its position.
//!
//! **Bias correction** (Nehab 2005's first step, [`RefineParams::correction_rounds`]): the
//! targets' low frequencies are replaced by the mesh's. Both fields are averaged over a
//! neighbourhood and each target is rotated by the rotation taking its average onto the
//! mesh's. Without it, a target field that no surface has (part 1's per-camera biases,
//! blended) roughens the mesh at the vertex scale and raised Table 3.1's local deviation
//! (docs: "Tenth session: the local deviation traced").
//!
//! **Energy** (Nehab 2005, Eq. 6–8, with the mesh's faces as the tangent stencil): each vertex
//! moves along its original area-weighted vertex normal `n̂_i` by a signed distance `d_i`,
//! `p_i = p⁰_i + d_i n̂_i`, and `d` minimises
//!
//! `λ Σ_i d_i² + (1 − λ) Σ_f Σ_{(a,b) ∈ edges(f)} (t_f · (p_a − p_b))²`,
//!
//! where `t_f` is the normalised sum of the face's three vertex targets. Only faces whose
//! three vertices all have a target contribute a normal term. Vertices without a target are
//! fixed, and their edges to vertices with a target still pull on those vertices. The
//! position weights are uniform (Nehab weighted them by the scanner's confidence; the merged
//! mesh carries no per-vertex confidence).
//!
//! **Why one unknown per vertex along its normal** (Nehab §4 does the same for range images,
//! moving each point along its line of sight): the normal term only constrains the surface's
//! orientation. With three free coordinates per vertex, the vertices could slide within the
//! surface without changing any `t_f · (p_a − p_b)`. Only the weak position term would hold
//! them, so the triangles could fold and bunch up. One unknown per vertex also makes the
//! system a third of the size. The system matrix is `λ I + (1 − λ) Σ gᵀ g`, which is
//! symmetric positive definite for λ > 0. It is solved by the workspace's sparse Cholesky
//! (`skin_core::lsq::SparseCholesky`, faer, AMD ordering).

use std::time::Instant;

use nalgebra::DMatrix;
use nalgebra_sparse::CscMatrix;
use skin_core::camera::Camera;
use skin_core::check;
use skin_core::image::Mask;
use skin_core::lsq::{CholeskyParams, SparseCholesky};
use skin_core::math::DVec3;
use skin_core::mesh::{unique_edges, vertex_normals, NormalWeighting, TriMesh};

use crate::{vertex_normal_samples, DepthMap, Error, MetricParams, NormalMap, Result};

/// How a vertex's target normal is chosen from the cameras that sample it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum TargetNormals {
    /// The sample of the camera that sees the vertex most frontally, as Table 3.1's vertex
    /// normal deviation takes it.
    MostFrontal,
    /// Every sample, weighted by the squared cosine of its view angle, then normalised (the
    /// default: at 512² its true-normal deviation and true local deviation were both lower
    /// than the most frontal sample's, 11.20° / 3.31° against 11.42° / 3.59°).
    #[default]
    CosineSquared,
}

/// Parameters of [`refine_mesh`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RefineParams {
    /// Weight λ ∈ (0, 1] of the position term; `1 − λ` weighs the normal term. λ = 1 leaves
    /// the mesh as it is. Default 0.1, as Nehab 2005. The balance is per vertex and edge, so
    /// with 2 mm edges the normals rule below a wavelength of about `e·√((1 − λ)/λ)` ≈ 6 mm.
    /// Measured at 512²: λ 0.01 lowered the normal deviation further (9.80°) but moved the
    /// merged median 3.29 → 3.55 mm, λ 0.001 drifted (moves up to 26 cm) (docs: "Fusing the
    /// merged mesh with the normals").
    pub lambda: f64,
    /// Which target normal each vertex gets. Default [`TargetNormals::CosineSquared`].
    pub targets: TargetNormals,
    /// Which samples count as measured (coverage `near_m`, visibility `near_m / 2`): the
    /// metric's. Default [`MetricParams::default`].
    pub sampling: MetricParams,
    /// A target farther than this from the vertex's own normal, degrees, is dropped (the
    /// vertex keeps its position): a guard against a wrong view's normal. `None`: every
    /// target is kept. Default `None` (20° at 512² left holes in the targets whose fixed
    /// vertices made the local deviation worse: 3.83° against 3.51°).
    pub max_angle_deg: Option<f64>,
    /// Rounds of averaging each vertex's target with its neighbours' (over the mesh's edges,
    /// renormalised) before the solve: the merged mesh's vertices (2 mm voxels) are denser
    /// than the normal maps' pixels, so the targets carry the pixels' noise at the vertex
    /// scale. Default 2 (at 512², 0 → 2 rounds: true local deviation 3.31 → 3.17°).
    pub smoothing: usize,
    /// Nehab 2005's first step, which corrects the measured normals' low-frequency bias
    /// against the positions: rounds of 1-ring averaging that define the low frequencies.
    /// Both the mesh's own vertex normals and the targets are averaged this many rounds, and
    /// each target is rotated by the rotation that takes its averaged value onto the averaged
    /// mesh normal: the targets keep their high frequencies and take the positions' low ones.
    /// 0: no correction (the ninth session's refinement). Default 8: about 5 edges (≈ 1 cm)
    /// on the merge's 2 mm voxels. Tenth session, 1024² skirt, pass 2: normal / local
    /// deviation 13.28° / 4.12° unrefined → 12.24° / 3.76° (exact-normal control 11.35° /
    /// 2.87° → 10.11° / 1.89°), where the refinement without it had raised the local figure
    /// (docs "Tenth session: the local deviation traced").
    ///
    /// Why it matters on our meshes: a target field that no surface has (part 1's per-camera
    /// biases blended, a rotation of the normals) cannot be met; the least-squares residual
    /// then lands on the merge's irregular marching-cubes triangles as vertex-scale roughness
    /// (test `non_integrable_targets_roughen_the_mesh_unless_corrected`).
    pub correction_rounds: usize,
}

impl Default for RefineParams {
    fn default() -> Self {
        Self {
            lambda: 0.1,
            targets: TargetNormals::CosineSquared,
            sampling: MetricParams::default(),
            max_angle_deg: None,
            smoothing: 2,
            correction_rounds: 8,
        }
    }
}

/// What a refinement did.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RefineReport {
    /// Vertices of the mesh.
    pub vertices: usize,
    /// Vertices with a target normal (the unknowns).
    pub targeted: usize,
    /// Faces whose three vertices have a target (the normal terms).
    pub faces: usize,
    /// Mean |d_i| over the unknowns, mm.
    pub mean_move_mm: f64,
    /// Largest |d_i|, mm.
    pub max_move_mm: f64,
    /// Wall time of choosing the targets (rendering the mesh per camera), s.
    pub targets_s: f64,
    /// Wall time of the assembly and the solve, s.
    pub solve_s: f64,
}

/// A refined mesh and its report.
#[derive(Debug, Clone)]
pub struct RefinedMesh {
    /// The mesh with its vertices moved (same faces).
    pub mesh: TriMesh,
    /// What the refinement did.
    pub report: RefineReport,
}

/// Each vertex's target normal (world frame, unit length) from the cameras that sample it,
/// as `params.targets` chooses; `None` where no camera samples the vertex.
///
/// # Errors
/// [`Error::Empty`] without cameras; errors of [`vertex_normal_samples`].
pub fn target_normals(
    cameras: &[Camera],
    normals: &[NormalMap],
    silhouettes: &[Mask],
    surfaces: &[DepthMap],
    mesh: &TriMesh,
    params: &RefineParams,
) -> Result<Vec<Option<DVec3>>> {
    if cameras.is_empty() {
        return Err(Error::Empty {
            what: "cameras for the target normals",
        });
    }
    let n = mesh.vertices.len();
    let mut best: Vec<Option<(f64, DVec3)>> = vec![None; n];
    let mut sum = vec![DVec3::ZERO; n];
    vertex_normal_samples(
        cameras,
        normals,
        silhouettes,
        surfaces,
        mesh,
        &params.sampling,
        |v, s| match params.targets {
            TargetNormals::MostFrontal => {
                if best[v].is_none_or(|(c, _)| s.cosine > c) {
                    best[v] = Some((s.cosine, s.measured));
                }
            }
            TargetNormals::CosineSquared => sum[v] += s.cosine * s.cosine * s.measured,
        },
    )?;
    let mut targets: Vec<Option<DVec3>> = match params.targets {
        TargetNormals::MostFrontal => best.into_iter().map(|b| b.map(|(_, m)| m)).collect(),
        TargetNormals::CosineSquared => sum.into_iter().map(DVec3::try_normalize).collect(),
    };
    if let Some(max_deg) = params.max_angle_deg {
        check::positive("max_angle_deg", max_deg)?;
        let cos_max = max_deg.to_radians().cos();
        let own = vertex_normals(mesh, NormalWeighting::Area)?;
        for (t, n) in targets.iter_mut().zip(own) {
            // The vertex normal's orientation is the mesh's; compare without its sign.
            let keep = match (*t, n.try_normalize()) {
                (Some(t), Some(n)) => t.dot(n).abs() >= cos_max,
                _ => false,
            };
            if !keep {
                *t = None;
            }
        }
    }
    if params.correction_rounds > 0 {
        correct_low_frequencies(mesh, &mut targets, params.correction_rounds)?;
    }
    if params.smoothing > 0 {
        let edges = unique_edges(mesh)?;
        average_rounds(&edges, &mut targets, params.smoothing);
    }
    Ok(targets)
}

/// `rounds` of 1-ring averaging (renormalised) of a field over the vertices that have a value.
fn average_rounds(edges: &[[u32; 2]], field: &mut [Option<DVec3>], rounds: usize) {
    for _ in 0..rounds {
        let mut acc: Vec<DVec3> = field.iter().map(|t| t.unwrap_or(DVec3::ZERO)).collect();
        for &[a, b] in edges {
            let (a, b) = (a as usize, b as usize);
            if let (Some(ta), Some(tb)) = (field[a], field[b]) {
                acc[a] += tb;
                acc[b] += ta;
            }
        }
        for (t, a) in field.iter_mut().zip(acc) {
            if t.is_some() {
                *t = a.try_normalize();
            }
        }
    }
}

/// Nehab 2005's first step ([`RefineParams::correction_rounds`]): each target is rotated by
/// the rotation that takes the `rounds`-averaged targets onto the `rounds`-averaged mesh
/// normals (turned to agree with the target), so the targets keep only their high
/// frequencies. A vertex whose averaged fields vanish loses its target.
fn correct_low_frequencies(
    mesh: &TriMesh,
    targets: &mut [Option<DVec3>],
    rounds: usize,
) -> Result<()> {
    let edges = unique_edges(mesh)?;
    let own = vertex_normals(mesh, NormalWeighting::Area)?;
    // The mesh's normals where a target is, oriented as the target (the metric compares
    // without the mesh's orientation).
    let mut low_mesh: Vec<Option<DVec3>> = targets
        .iter()
        .zip(&own)
        .map(|(t, n)| {
            let (t, n) = ((*t)?, n.try_normalize()?);
            Some(if n.dot(t) < 0.0 { -n } else { n })
        })
        .collect();
    let mut low_targets: Vec<Option<DVec3>> = targets
        .iter()
        .zip(&low_mesh)
        .map(|(t, m)| m.and(*t))
        .collect();
    average_rounds(&edges, &mut low_mesh, rounds);
    average_rounds(&edges, &mut low_targets, rounds);
    for ((t, lt), lm) in targets.iter_mut().zip(low_targets).zip(low_mesh) {
        *t = match (*t, lt, lm) {
            (Some(t), Some(lt), Some(lm)) => {
                (skin_core::math::DQuat::from_rotation_arc(lt, lm) * t).try_normalize()
            }
            _ => None,
        };
    }
    Ok(())
}

/// Moves the vertices of `mesh` along their vertex normals so that the faces agree with the
/// per-vertex `targets` (Nehab 2005's energy with weight `lambda`; module docs). Vertices
/// whose target is `None` stay where they are.
///
/// # Errors
/// [`Error::Empty`] for a mesh without faces; [`Error::SizeMismatch`] if `targets` is not one
/// per vertex; [`Error::NonFinite`] for a target that is not a finite vector;
/// [`Error::InvalidParam`] for λ outside (0, 1] or a target that is not unit length; errors of
/// the mesh's validation and of the solve.
pub fn refine_with_normals(
    mesh: &TriMesh,
    targets: &[Option<DVec3>],
    lambda: f64,
) -> Result<RefinedMesh> {
    let t = Instant::now();
    if mesh.faces.is_empty() || mesh.vertices.is_empty() {
        return Err(Error::Empty {
            what: "mesh to refine",
        });
    }
    check::same_size(
        "target normals per vertex",
        mesh.vertices.len(),
        targets.len(),
    )?;
    if !(lambda > 0.0 && lambda <= 1.0) {
        return Err(Error::InvalidParam {
            name: "lambda",
            reason: format!("must lie in (0, 1], got {lambda}"),
        });
    }
    for t in targets.iter().flatten() {
        if !t.is_finite() {
            return Err(Error::NonFinite {
                what: "target normal",
            });
        }
        if (t.length() - 1.0).abs() > 1e-6 {
            return Err(Error::InvalidParam {
                name: "target normal",
                reason: format!("must be unit length, got length {}", t.length()),
            });
        }
    }
    let directions = vertex_normals(mesh, NormalWeighting::Area)?;
    // Unknowns: vertices with a target and a direction to move along.
    let mut unknown = vec![u32::MAX; mesh.vertices.len()];
    let mut n_unknowns = 0usize;
    let dirs: Vec<Option<DVec3>> = directions.iter().map(|d| d.try_normalize()).collect();
    for (v, (t, d)) in targets.iter().zip(&dirs).enumerate() {
        if t.is_some() && d.is_some() {
            unknown[v] = n_unknowns as u32;
            n_unknowns += 1;
        }
    }
    let mut report = RefineReport {
        vertices: mesh.vertices.len(),
        targeted: n_unknowns,
        ..RefineReport::default()
    };
    if n_unknowns == 0 {
        report.solve_s = t.elapsed().as_secs_f64();
        return Ok(RefinedMesh {
            mesh: mesh.clone(),
            report,
        });
    }
    // The unique edges between unknowns (lower triangle, by unknown index) and their values.
    let index = &unknown;
    let mut edges: Vec<(u32, u32)> = mesh
        .faces
        .iter()
        .flat_map(|f| {
            (0..3).map(move |k| {
                let (a, b) = (index[f[k] as usize], index[f[(k + 1) % 3] as usize]);
                (a.min(b), a.max(b))
            })
        })
        .filter(|&(a, b)| b != u32::MAX && a != b)
        .collect();
    edges.sort_unstable();
    edges.dedup();
    let mut off = vec![0.0; edges.len()];
    let mut diag = vec![lambda; n_unknowns];
    let mut rhs = vec![0.0; n_unknowns];
    let mu = 1.0 - lambda;
    for f in &mesh.faces {
        let ids = f.map(|v| v as usize);
        let Some(tf) = ids
            .iter()
            .map(|&v| targets[v])
            .sum::<Option<DVec3>>()
            .and_then(DVec3::try_normalize)
        else {
            continue;
        };
        report.faces += 1;
        for k in 0..3 {
            let (a, b) = (ids[k], ids[(k + 1) % 3]);
            // Residual c + α d_a − β d_b of t_f · (p_a − p_b); a fixed end has no term.
            let c = tf.dot(mesh.vertices[a] - mesh.vertices[b]);
            let (ua, ub) = (unknown[a], unknown[b]);
            let alpha = dirs[a].map_or(0.0, |d| tf.dot(d));
            let beta = dirs[b].map_or(0.0, |d| tf.dot(d));
            if ua != u32::MAX {
                diag[ua as usize] += mu * alpha * alpha;
                rhs[ua as usize] -= mu * alpha * c;
            }
            if ub != u32::MAX {
                diag[ub as usize] += mu * beta * beta;
                rhs[ub as usize] += mu * beta * c;
            }
            if ua != u32::MAX && ub != u32::MAX {
                let key = (ua.min(ub), ua.max(ub));
                if let Ok(e) = edges.binary_search(&key) {
                    off[e] -= mu * alpha * beta;
                }
            }
        }
    }
    // Lower triangle by columns: the diagonal, then each column's edges (already sorted).
    let mut col_offsets = Vec::with_capacity(n_unknowns + 1);
    let mut rows = Vec::with_capacity(n_unknowns + edges.len());
    let mut values = Vec::with_capacity(n_unknowns + edges.len());
    let mut e = 0;
    for (j, &dj) in diag.iter().enumerate() {
        col_offsets.push(rows.len());
        rows.push(j);
        values.push(dj);
        while e < edges.len() && edges[e].0 as usize == j {
            rows.push(edges[e].1 as usize);
            values.push(off[e]);
            e += 1;
        }
    }
    col_offsets.push(rows.len());
    let matrix = CscMatrix::try_from_csc_data(n_unknowns, n_unknowns, col_offsets, rows, values)
        .map_err(|e| Error::InvalidParam {
            name: "refinement system",
            reason: e.to_string(),
        })?;
    let chol = SparseCholesky::new(&matrix, &CholeskyParams::default())?;
    let d = chol.solve(&DMatrix::from_column_slice(n_unknowns, 1, &rhs))?;
    let mut vertices = mesh.vertices.clone();
    let (mut sum, mut max) = (0.0f64, 0.0f64);
    for (v, p) in vertices.iter_mut().enumerate() {
        let (u, Some(dir)) = (unknown[v], dirs[v]) else {
            continue;
        };
        if u == u32::MAX {
            continue;
        }
        let di = d[(u as usize, 0)];
        *p += di * dir;
        sum += di.abs();
        max = max.max(di.abs());
    }
    report.mean_move_mm = 1e3 * sum / n_unknowns as f64;
    report.max_move_mm = 1e3 * max;
    report.solve_s = t.elapsed().as_secs_f64();
    Ok(RefinedMesh {
        mesh: TriMesh::new(vertices, mesh.faces.clone())?,
        report,
    })
}

/// Refines `mesh` (a merged mesh) with the measured `normals` of `cameras`: the target
/// normals ([`target_normals`], visibility against the per-view `surfaces` inside the
/// `silhouettes`), then Nehab's energy ([`refine_with_normals`]; module docs).
///
/// # Errors
/// [`Error::Empty`] without cameras or for an empty mesh; errors of [`target_normals`] and
/// [`refine_with_normals`].
pub fn refine_mesh(
    cameras: &[Camera],
    normals: &[NormalMap],
    silhouettes: &[Mask],
    surfaces: &[DepthMap],
    mesh: &TriMesh,
    params: &RefineParams,
) -> Result<RefinedMesh> {
    if mesh.faces.is_empty() || mesh.vertices.is_empty() {
        return Err(Error::Empty {
            what: "mesh to refine",
        });
    }
    let t = Instant::now();
    let targets = target_normals(cameras, normals, silhouettes, surfaces, mesh, params)?;
    let targets_s = t.elapsed().as_secs_f64();
    let mut refined = refine_with_normals(mesh, &targets, params.lambda)?;
    refined.report.targets_s = targets_s;
    Ok(refined)
}

#[cfg(test)]
mod tests {
    use super::*;

    const N: usize = 41;
    const SPACING: f64 = 0.025;

    /// The true height: a broad bump with a 20 cm ripple of 3 mm on it.
    fn bump(x: f64, y: f64) -> f64 {
        0.05 * (-((x - 0.5).powi(2) + (y - 0.5).powi(2)) / 0.1).exp()
    }
    fn ripple(x: f64, y: f64) -> f64 {
        let k = std::f64::consts::TAU / 0.2;
        0.003 * (k * x).sin() * (k * y).sin()
    }
    fn truth(x: f64, y: f64) -> f64 {
        bump(x, y) + ripple(x, y)
    }
    /// The true surface's unit normal (upward) from the analytic gradient.
    fn truth_normal(x: f64, y: f64) -> DVec3 {
        let h = 1e-6;
        let gx = (truth(x + h, y) - truth(x - h, y)) / (2.0 * h);
        let gy = (truth(x, y + h) - truth(x, y - h)) / (2.0 * h);
        DVec3::new(-gx, -gy, 1.0).normalize()
    }

    /// A grid mesh over [0, 1]² with heights `z(x, y)`, faces counter-clockwise from above.
    fn grid(z: impl Fn(f64, f64) -> f64) -> TriMesh {
        let mut vertices = Vec::new();
        for j in 0..N {
            for i in 0..N {
                let (x, y) = (i as f64 * SPACING, j as f64 * SPACING);
                vertices.push(DVec3::new(x, y, z(x, y)));
            }
        }
        let mut faces = Vec::new();
        for j in 0..N - 1 {
            for i in 0..N - 1 {
                let v = (j * N + i) as u32;
                let n = N as u32;
                faces.push([v, v + 1, v + n + 1]);
                faces.push([v, v + n + 1, v + n]);
            }
        }
        TriMesh::new(vertices, faces).unwrap()
    }

    /// The true surface's normal at each vertex of `mesh` (every vertex targeted).
    fn exact_targets(mesh: &TriMesh) -> Vec<Option<DVec3>> {
        mesh.vertices
            .iter()
            .map(|p| Some(truth_normal(p.x, p.y)))
            .collect()
    }

    /// RMS vertical distance of the mesh's vertices to the true surface, mm.
    fn rms_to_truth_mm(mesh: &TriMesh) -> f64 {
        let s: f64 = mesh
            .vertices
            .iter()
            .map(|p| (p.z - truth(p.x, p.y)).powi(2))
            .sum();
        1e3 * (s / mesh.vertices.len() as f64).sqrt()
    }

    #[test]
    fn exact_normals_restore_a_ripple_that_the_positions_lost() {
        // Input: the positions without the ripple (the smooth low frequencies), 1.5 mm RMS
        // off the truth; the exact normals of the true surface at each input vertex.
        let input = grid(bump);
        let targets = exact_targets(&input);
        let before = rms_to_truth_mm(&input);
        let refined = refine_with_normals(&input, &targets, 0.1).unwrap();
        let after = rms_to_truth_mm(&refined.mesh);
        println!("ripple: input {before:.3} mm, refined {after:.3} mm RMS");
        assert!(
            before > 1.4,
            "the input must be off the truth ({before:.3} mm)"
        );
        // The baseline (the input) could win: the refinement must bring the vertices at
        // least 4× closer to the true surface.
        assert!(
            after < before / 4.0,
            "refined {after:.3} mm vs input {before:.3} mm"
        );
        assert_eq!(refined.report.targeted, N * N);
        assert_eq!(refined.report.faces, 2 * (N - 1) * (N - 1));
    }

    #[test]
    fn vertices_without_a_target_stay_and_the_others_still_improve() {
        let input = grid(bump);
        // Targets only on the left half.
        let targets: Vec<Option<DVec3>> = input
            .vertices
            .iter()
            .map(|p| (p.x < 0.5).then(|| truth_normal(p.x, p.y)))
            .collect();
        let refined = refine_with_normals(&input, &targets, 0.1).unwrap();
        for ((a, b), t) in input
            .vertices
            .iter()
            .zip(&refined.mesh.vertices)
            .zip(&targets)
        {
            if t.is_none() {
                assert_eq!(a, b);
            }
        }
        let err = |m: &TriMesh| {
            let v: Vec<f64> = m
                .vertices
                .iter()
                .filter(|p| p.x < 0.45)
                .map(|p| (p.z - truth(p.x, p.y)).powi(2))
                .collect();
            (v.iter().sum::<f64>() / v.len() as f64).sqrt()
        };
        assert!(err(&refined.mesh) < err(&input) / 3.0);
    }

    #[test]
    fn lambda_one_leaves_the_mesh_unchanged() {
        let input = grid(bump);
        let targets = exact_targets(&input);
        let refined = refine_with_normals(&input, &targets, 1.0).unwrap();
        assert_eq!(refined.mesh.vertices, input.vertices);
        assert_eq!(refined.mesh.faces, input.faces);
        // And a λ below 1 does move it (the solve is not a no-op).
        let moved = refine_with_normals(&input, &targets, 0.5).unwrap();
        assert!(moved.report.max_move_mm > 0.1);
    }

    /// A marching-cubes mesh (2 mm voxels, as the merge's) of a 10 cm sphere whose radius
    /// carries a low-frequency error of up to 2 mm.
    fn mc_sphere(noise_m: f64) -> TriMesh {
        let voxel = 0.002;
        // A deterministic pseudo-random value in [-1, 1] per grid node.
        let hash = |p: [i64; 3]| {
            let mut h = (p[0].wrapping_mul(73_856_093)
                ^ p[1].wrapping_mul(19_349_663)
                ^ p[2].wrapping_mul(83_492_791)) as u64;
            h ^= h >> 33;
            h = h.wrapping_mul(0xff51_afd7_ed55_8ccd);
            h ^= h >> 33;
            (h % 20_001) as f64 / 10_000.0 - 1.0
        };
        let r = 0.1;
        let wrong = |q: DVec3| 0.002 * (3.0 * q.x / r).sin() * (2.0 * q.z / r).cos();
        let n = (1.2 * r / voxel) as i64;
        let pos = |p: [i64; 3]| DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64) * voxel;
        let value = |p: [i64; 3]| {
            let q = pos(p);
            Some(q.length() - r - wrong(q) + noise_m * hash(p))
        };
        let mut cells = Vec::new();
        for k in -n..n {
            for j in -n..n {
                for i in -n..n {
                    let c = pos([i, j, k]) + DVec3::splat(0.5 * voxel);
                    if (c.length() - r).abs() < 3.0 * voxel {
                        cells.push([i, j, k]);
                    }
                }
            }
        }
        crate::marching_cubes::march_cells(cells, value, 0.0, pos).unwrap()
    }

    /// Mean angle between neighbouring vertex normals and mean angle of the vertex normals to
    /// the true sphere's, degrees.
    fn roughness(mesh: &TriMesh) -> (f64, f64) {
        let normals = vertex_normals(mesh, NormalWeighting::Area).unwrap();
        let edges = unique_edges(mesh).unwrap();
        let ang = |a: DVec3, b: DVec3| {
            a.normalize()
                .dot(b.normalize())
                .clamp(-1.0, 1.0)
                .acos()
                .to_degrees()
        };
        let local = edges
            .iter()
            .map(|&[a, b]| ang(normals[a as usize], normals[b as usize]))
            .sum::<f64>()
            / edges.len() as f64;
        let dev = mesh
            .vertices
            .iter()
            .zip(&normals)
            .map(|(p, n)| ang(*p, *n))
            .sum::<f64>()
            / mesh.vertices.len() as f64;
        (local, dev)
    }

    #[test]
    fn non_integrable_targets_roughen_the_mesh_unless_corrected() {
        // Smooth targets that no surface has: the sphere's normals rotated by 10° about one
        // axis (a bias like a view's calibration error). Without Nehab's first step the
        // irregular marching-cubes mesh absorbs the misfit as vertex-scale roughness.
        let rot = skin_core::math::DQuat::from_axis_angle(
            DVec3::new(1.0, 2.0, 0.5).normalize(),
            10f64.to_radians(),
        );
        let mesh = mc_sphere(0.0);
        let targets: Vec<Option<DVec3>> = mesh
            .vertices
            .iter()
            .map(|p| Some(rot * p.normalize()))
            .collect();
        let (l0, _) = roughness(&mesh);
        let plain = refine_with_normals(&mesh, &targets, 0.1).unwrap();
        let (l_plain, _) = roughness(&plain.mesh);
        let mut corrected = targets.clone();
        correct_low_frequencies(&mesh, &mut corrected, 8).unwrap();
        let fixed = refine_with_normals(&mesh, &corrected, 0.1).unwrap();
        let (l_fixed, d_fixed) = roughness(&fixed.mesh);
        println!(
            "tilted targets: neighbour angle input {l0:.3}°, plain {l_plain:.3}°, corrected \
             {l_fixed:.3}° (true dev {d_fixed:.3}°)"
        );
        // The old behaviour roughens the mesh (measured 1.08° → 2.29°); the corrected
        // targets must leave it within 0.15° of the input.
        assert!(l_plain > l0 + 0.5, "plain {l_plain:.3} vs input {l0:.3}");
        assert!(
            l_fixed < l0 + 0.15,
            "corrected {l_fixed:.3} vs input {l0:.3}"
        );

        // The correction keeps the targets' high frequencies: exact targets still remove
        // vertex-scale noise of the positions (0.3 mm on the distance field).
        let noisy = mc_sphere(0.0003);
        let mut exact: Vec<Option<DVec3>> =
            noisy.vertices.iter().map(|p| Some(p.normalize())).collect();
        correct_low_frequencies(&noisy, &mut exact, 8).unwrap();
        let (l_noisy, d_noisy) = roughness(&noisy);
        let (l_after, d_after) = roughness(&refine_with_normals(&noisy, &exact, 0.1).unwrap().mesh);
        println!(
            "noisy positions: neighbour angle {l_noisy:.3}° → {l_after:.3}°, true dev \
             {d_noisy:.3}° → {d_after:.3}°"
        );
        assert!(l_after < l_noisy / 2.0 && d_after < d_noisy / 2.0);
    }

    #[test]
    fn bad_input_is_a_clear_error() {
        let input = grid(bump);
        let mut targets: Vec<Option<DVec3>> = vec![Some(DVec3::Z); input.vertices.len()];
        targets[7] = Some(DVec3::new(f64::NAN, 0.0, 1.0));
        assert!(matches!(
            refine_with_normals(&input, &targets, 0.1),
            Err(Error::NonFinite { .. })
        ));
        targets[7] = Some(DVec3::new(0.0, 0.0, 2.0));
        assert!(matches!(
            refine_with_normals(&input, &targets, 0.1),
            Err(Error::InvalidParam { .. })
        ));
        let good = vec![Some(DVec3::Z); input.vertices.len()];
        for lambda in [0.0, -0.1, 1.5, f64::NAN] {
            assert!(matches!(
                refine_with_normals(&input, &good, lambda),
                Err(Error::InvalidParam { .. })
            ));
        }
        assert!(matches!(
            refine_with_normals(&input, &good[1..], 0.1),
            Err(Error::Core(skin_core::Error::SizeMismatch { .. }))
        ));
        let empty = TriMesh::new(Vec::new(), Vec::new()).unwrap();
        assert!(matches!(
            refine_with_normals(&empty, &[], 0.1),
            Err(Error::Empty { .. })
        ));
        // No views: no camera to take a target normal from.
        assert!(matches!(
            refine_mesh(&[], &[], &[], &[], &input, &RefineParams::default()),
            Err(Error::Empty { .. })
        ));
        assert!(matches!(
            refine_mesh(&[], &[], &[], &[], &empty, &RefineParams::default()),
            Err(Error::Empty { .. })
        ));
    }
}
