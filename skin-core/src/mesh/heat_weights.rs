//! Automatic skinning weights by bone heat diffusion (Baran & Popović 2007, "Automatic
//! Rigging and Animation of 3D Characters" — Pinocchio, §4), which the Vlasic 2010 thesis
//! uses to attach its templates to their skeletons (§2.5.1).
//!
//! Pinocchio treats the mesh as a heat-conducting body, bone `i` held at temperature 1 and
//! the others at 0, and takes the equilibrium temperature as weight `w_i`:
//!
//! ```text
//! (−Δ + H) w_i = H p_i
//! ```
//!
//! with `Δ` the discrete surface Laplacian, `H_jj = c / d_j²` (`d_j` = distance from vertex
//! `j` to its nearest bone), `p_i^j = 1` if bone `i` is nearest to vertex `j` (shared as
//! `1/k` among `k` equidistant bones, with `H_jj = k c / d_j²`). With the cotangent
//! Laplacian `L` and lumped mass `M` (`Δ = M⁻¹ L`) the system is multiplied by `M` to make it
//! symmetric positive definite: `(−L + M H) w_i = M H p_i`. One sparse Cholesky
//! factorisation serves all bones as one multi-right-hand-side solve.
//!
//! **Visibility** (on by default, [`VisibilityParams`]). Pinocchio sets `H_jj = 0` when the
//! segment from vertex `j` to the closest point of its nearest bone leaves the character's
//! volume, so that a surface point closer to an unrelated bone across a gap (an arm hanging
//! against the torso, the inner thighs, a skirt's hem between the legs) takes its weights by
//! diffusion from its neighbours instead of from that bone. Its reference implementation
//! (`attachment.cpp`) also requires the direction from the bone to the vertex to lie within
//! 60° of the vertex normal, and accepts a segment that leaves the volume by less than 0.002
//! of the (unit-normalised) model's size. Both are kept, as [`VisibilityParams`]' defaults.
//!
//! "Inside the volume" is decided by the generalised winding number (`w ≥ ½`, Jacobson et al.
//! 2013; [`WindingNumber`]), because the meshes this library attaches are open (MakeHuman's
//! body has holes at the eyes and mouth; a skirt is a tube open at waist and hem) and a
//! ray-parity test is undefined there. The segment is sampled every
//! [`VisibilityParams::step_rel`] of the model's size; a sample outside by less than the
//! tolerance (its distance to the surface) still counts as inside.
//!
//! Two choices where Pinocchio has none, each logged:
//! * Pinocchio assumes one connected surface. A connected component none of whose vertices
//!   sees a bone (a garment whose every segment leaves the volume) would make the heat system
//!   singular; its vertices are heated by their nearest bones without the test.
//! * `visibility: None` restores heating every vertex by its nearest bone (the behaviour before
//!   the test was added; weights then bleed across gaps where limbs are close).

use nalgebra::DMatrix;
use nalgebra_sparse::CscMatrix;
use serde::{Deserialize, Serialize};

use rayon::prelude::*;

use crate::lsq::{CholeskyParams, SparseCholesky};
use crate::math::DVec3;
use crate::mesh::skinning::SkinWeights;
use crate::mesh::{
    cotangent_laplacian, mass_matrix, vertex_normals, EdgeTopology, LaplacianParams, MassKind,
    MeshQuery, NormalWeighting, TriMesh, WindingNumber,
};
use crate::skeleton::Skeleton;
use crate::{Error, Result};

/// A line segment of a [`Bone`], rest-pose coordinates.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BoneSegment {
    /// Joint at the head of the bone, mesh units.
    pub start: DVec3,
    /// Joint at the tail of the bone, mesh units (may equal `start` for a point bone).
    pub end: DVec3,
}

impl BoneSegment {
    /// The point of the segment closest to `p`.
    pub fn closest_point(&self, p: DVec3) -> DVec3 {
        let d = self.end - self.start;
        let len2 = d.length_squared();
        let t = if len2 > 0.0 {
            ((p - self.start).dot(d) / len2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        self.start + d * t
    }

    /// Euclidean distance from `p` to the segment.
    pub fn distance(&self, p: DVec3) -> f64 {
        (p - self.closest_point(p)).length()
    }
}

/// A bone of the heat system: the segments one joint frame moves. A joint with several
/// children (a pelvis with its spine and hips, a chest with its neck and clavicles) moves
/// the segments to each of them, as Pinocchio's bones run from every joint to each child
/// (Baran & Popović 2007 §3). The distance to a bone is to its nearest segment.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Bone {
    /// The bone's segments, rest-pose coordinates (at least one).
    pub segments: Vec<BoneSegment>,
}

impl Bone {
    /// A bone of one segment.
    pub fn segment(start: DVec3, end: DVec3) -> Self {
        Self {
            segments: vec![BoneSegment { start, end }],
        }
    }

    /// The point of the bone closest to `p` (of its nearest segment).
    pub fn closest_point(&self, p: DVec3) -> DVec3 {
        self.segments
            .iter()
            .map(|s| s.closest_point(p))
            .min_by(|a, b| {
                (*a - p)
                    .length_squared()
                    .total_cmp(&(*b - p).length_squared())
            })
            .unwrap_or(DVec3::NAN)
    }

    /// Euclidean distance from `p` to the bone (∞ for a bone without segments).
    pub fn distance(&self, p: DVec3) -> f64 {
        self.segments
            .iter()
            .map(|s| s.distance(p))
            .fold(f64::INFINITY, f64::min)
    }
}

/// One bone per joint of `skeleton` at its rest pose, in the frame of the rest mesh: joint
/// `j`'s bone is the segments from its rest position to each child's, or to its end site for
/// a leaf (a point for a leaf without one). Bone `j` is joint `j`, the convention of
/// [`SkinWeights`] (a vertex weighted to joint `j` moves with joint `j`'s frame).
///
/// # Errors
/// Errors of forward kinematics (a skeleton whose rest pose is invalid).
pub fn rest_bones(skeleton: &Skeleton) -> Result<Vec<Bone>> {
    let fk = skeleton.forward_kinematics(&skeleton.rest_pose())?;
    let frames = fk.world_from_joint();
    let joints = skeleton.joints();
    Ok((0..joints.len())
        .map(|j| {
            let start = frames[j].translation;
            let mut segments: Vec<BoneSegment> = (0..joints.len())
                .filter(|&c| joints[c].parent == Some(j))
                .map(|c| BoneSegment {
                    start,
                    end: frames[c].translation,
                })
                .collect();
            if let Some(e) = joints[j].end_site {
                segments.push(BoneSegment {
                    start,
                    end: frames[j].transform_point3(e),
                });
            }
            if segments.is_empty() {
                segments.push(BoneSegment { start, end: start });
            }
            Bone { segments }
        })
        .collect())
}

impl HeatWeightsParams {
    /// Default threshold below which weights are dropped before renormalising.
    pub const DEFAULT_PRUNE_BELOW: f64 = 0.01;

    /// Default maximum number of influences per vertex.
    pub const DEFAULT_MAX_INFLUENCES: usize = 4;

    /// Default heat constant `c` in this crate's `(−L + M H)` form: 3, Pinocchio's effective
    /// value. Baran & Popović 2007 §4 write `c = 1` for `−Δ + H`; their reference
    /// implementation (`attachment.cpp`) builds `Δ` from cotangent sums `Σ(cot α + cot β)`
    /// divided by the sum of the one-ring's `|e₁ × e₂|` (twice its area), which is one third of
    /// the cotangent operator `M⁻¹L` with barycentric mass used here (`L` with `½ Σ cot`, `M` a
    /// third of the one-ring area). Their `c = 1` is therefore `c = 3` here. Measured on the
    /// MakeHuman body (the skeleton's rest bones, visibility on), one studio exercise frame:
    /// LBS of the default against `c = 1` with Voronoi mass closer to the performer by
    /// frame (9.0 → 7.9 mm, both with barycentric mass here, Voronoi before), 1,257 more
    /// vertices nearly rigid (weight ≥ 0.95).
    pub const DEFAULT_HEAT_CONSTANT: f64 = 3.0;

    /// Default relative tolerance under which bones count as equidistant.
    pub const DEFAULT_TIE_TOLERANCE: f64 = 1e-9;

    /// Default distance floor as a fraction of the bounding-box diagonal.
    pub const DEFAULT_MIN_DISTANCE_REL: f64 = 1e-6;
}

impl VisibilityParams {
    /// Default tolerance of the visibility test, as a fraction of the model's largest extent
    /// (Pinocchio's `attachment.cpp`: 0.002 on its unit-normalised model).
    pub const DEFAULT_TOLERANCE_REL: f64 = 0.002;

    /// Default spacing of the visibility test's samples along a segment, as a fraction of the
    /// model's largest extent (ours: equal to the tolerance, so an excursion the tolerance would
    /// reject is about one sample wide).
    pub const DEFAULT_STEP_REL: f64 = 0.002;

    /// Default cosine of the cone about the vertex normal in which its bone must lie
    /// (Pinocchio's `attachment.cpp`: 0.5, i.e. within 60°).
    pub const DEFAULT_NORMAL_CONE_COS: f64 = 0.5;
}

/// Pinocchio's visibility test (module docs): a vertex is heated by its nearest bone only if
/// the segment to it stays inside the volume and points within a cone about the normal.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct VisibilityParams {
    /// A sample of the segment counts as inside when its generalised winding number is at
    /// least ½ or it lies within this fraction of the model's largest extent of the surface.
    /// Default: [`VisibilityParams::DEFAULT_TOLERANCE_REL`] = 0.002 (Pinocchio).
    pub tolerance_rel: f64,
    /// Spacing of the samples along the segment, fraction of the model's largest extent.
    /// Default: [`VisibilityParams::DEFAULT_STEP_REL`] = 0.002 (ours; 3.6 mm on a 1.8 m body).
    pub step_rel: f64,
    /// The direction from the bone's closest point to the vertex must have at least this
    /// cosine with the vertex normal (area-weighted); −1 switches the cone off. Default:
    /// [`VisibilityParams::DEFAULT_NORMAL_CONE_COS`] = 0.5 (Pinocchio).
    pub normal_cone_cos: f64,
}

impl Default for VisibilityParams {
    fn default() -> Self {
        Self {
            tolerance_rel: VisibilityParams::DEFAULT_TOLERANCE_REL,
            step_rel: VisibilityParams::DEFAULT_STEP_REL,
            normal_cone_cos: VisibilityParams::DEFAULT_NORMAL_CONE_COS,
        }
    }
}

fn default_visibility() -> Option<VisibilityParams> {
    Some(VisibilityParams::default())
}

/// Knobs of [`bone_heat_weights`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct HeatWeightsParams {
    /// Heat constant `c` in `H_jj = c / d_j²`, dimensionless (Baran & Popović 2007 §4).
    /// Default: [`HeatWeightsParams::DEFAULT_HEAT_CONSTANT`] = 3 (the paper's 1 in its
    /// implementation's discretisation).
    pub heat_constant: f64,
    /// Weights below this are dropped before renormalising (Pinocchio output is dense;
    /// sparse weights are what real-time skinning consumes). Default:
    /// [`HeatWeightsParams::DEFAULT_PRUNE_BELOW`] = 0.01.
    pub prune_below: f64,
    /// Maximum influences kept per vertex (GPU skinning convention). Default:
    /// [`HeatWeightsParams::DEFAULT_MAX_INFLUENCES`] = 4.
    pub max_influences: usize,
    /// Relative distance tolerance under which bones are equidistant and share the vertex.
    /// Default: [`HeatWeightsParams::DEFAULT_TIE_TOLERANCE`].
    pub tie_tolerance: f64,
    /// Distances are floored at this fraction of the bounding-box diagonal, so vertices on a
    /// bone get a large but finite `H`. Default: [`HeatWeightsParams::DEFAULT_MIN_DISTANCE_REL`].
    pub min_distance_rel: f64,
    /// Laplacian construction (degenerate triangles). Default: [`LaplacianParams::default`].
    pub laplacian: LaplacianParams,
    /// Mass lumping for `Δ = M⁻¹ L`. Default: [`MassKind::Barycentric`], the one-ring area
    /// Pinocchio's implementation uses.
    pub mass: MassKind,
    /// Sparse Cholesky settings. Default: [`CholeskyParams::default`].
    pub cholesky: CholeskyParams,
    /// Pinocchio's visibility test; `None` heats every vertex by its nearest bone. Default:
    /// `Some(VisibilityParams::default())` (Baran & Popović 2007 §4).
    #[serde(default = "default_visibility")]
    pub visibility: Option<VisibilityParams>,
}

impl Default for HeatWeightsParams {
    fn default() -> Self {
        Self {
            heat_constant: HeatWeightsParams::DEFAULT_HEAT_CONSTANT,
            prune_below: HeatWeightsParams::DEFAULT_PRUNE_BELOW,
            max_influences: HeatWeightsParams::DEFAULT_MAX_INFLUENCES,
            tie_tolerance: HeatWeightsParams::DEFAULT_TIE_TOLERANCE,
            min_distance_rel: HeatWeightsParams::DEFAULT_MIN_DISTANCE_REL,
            laplacian: LaplacianParams::default(),
            mass: MassKind::Barycentric,
            cholesky: CholeskyParams::default(),
            visibility: default_visibility(),
        }
    }
}

impl HeatWeightsParams {
    /// These parameters without the visibility test (every vertex heated by its nearest
    /// bone).
    pub fn without_visibility(mut self) -> Self {
        self.visibility = None;
        self
    }
}

/// Dense bone-heat weights (n × bones), before pruning; rows sum to one up to rounding.
///
/// # Errors
/// As [`bone_heat_weights`].
pub fn bone_heat_weights_dense(
    mesh: &TriMesh,
    bones: &[Bone],
    params: &HeatWeightsParams,
) -> Result<DMatrix<f64>> {
    if bones.is_empty() {
        return Err(Error::Empty { what: "bones" });
    }
    if bones.iter().any(|b| b.segments.is_empty()) {
        return Err(Error::Empty {
            what: "bone segments",
        });
    }
    if !bones
        .iter()
        .flat_map(|b| &b.segments)
        .all(|s| s.start.is_finite() && s.end.is_finite())
    {
        return Err(Error::NonFinite { what: "bones" });
    }
    crate::check::positive("heat_constant", params.heat_constant)?;
    crate::check::positive("min_distance_rel", params.min_distance_rel)?;
    crate::check::positive("tie_tolerance", params.tie_tolerance)?;
    let l = cotangent_laplacian(mesh, &params.laplacian)?;
    let mut mass = mass_matrix(mesh, params.mass, &params.laplacian)?;
    let n = mesh.vertices.len();
    // Vertices without area (unreferenced or only in skipped degenerate faces) would make the
    // system singular; a tiny mass makes their equation H w = H p (nearest bone wins, visible
    // or not: nothing else reaches them).
    let mean_mass = mass.sum() / n as f64;
    for m in mass.iter_mut() {
        *m = m.max(1e-12 * mean_mass);
    }
    let (lo, hi) = mesh.vertices.iter().fold(
        (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
        |(lo, hi), p| (lo.min(*p), hi.max(*p)),
    );
    let min_d = params.min_distance_rel * (hi - lo).length().max(f64::MIN_POSITIVE);
    let nearest = nearest_bones(mesh, bones, params.tie_tolerance, min_d);
    let mut heated: Vec<Vec<usize>> = match &params.visibility {
        None => nearest.iter().map(|(b, _)| b.clone()).collect(),
        Some(vis) => visible_nearest(mesh, bones, &nearest, vis, (hi - lo).max_element())?,
    };
    // Massless vertices have no Laplacian neighbours: each is its own component here.
    heat_unheated_components(&l, &nearest, &mut heated);
    let k = bones.len();
    let mut rhs = DMatrix::zeros(n, k);
    let mut diag_add = vec![0.0; n];
    for (j, ((_, d), hot)) in nearest.iter().zip(&heated).enumerate() {
        if hot.is_empty() {
            continue;
        }
        let h = hot.len() as f64 * params.heat_constant / (d * d);
        diag_add[j] = mass[j] * h;
        for &b in hot {
            rhs[(j, b)] = mass[j] * h / hot.len() as f64;
        }
    }
    // A = −L + M H on L's pattern (the Laplacian always stores its diagonal).
    let mut a = l;
    let offsets = a.col_offsets().to_vec();
    let rows = a.row_indices().to_vec();
    let values = a.values_mut();
    for j in 0..n {
        for p in offsets[j]..offsets[j + 1] {
            values[p] = -values[p];
            if rows[p] == j {
                values[p] += diag_add[j];
            }
        }
    }
    let chol = SparseCholesky::new(&a, &params.cholesky)?;
    chol.solve_in_place(&mut rhs)?;
    Ok(rhs)
}

/// Per vertex, its nearest bones (several when equidistant within `tie_tolerance`) and the
/// distance to them, floored at `min_d`.
fn nearest_bones(
    mesh: &TriMesh,
    bones: &[Bone],
    tie_tolerance: f64,
    min_d: f64,
) -> Vec<(Vec<usize>, f64)> {
    mesh.vertices
        .iter()
        .map(|p| {
            let dist: Vec<f64> = bones.iter().map(|b| b.distance(*p)).collect();
            let dmin = dist.iter().copied().fold(f64::INFINITY, f64::min);
            let cut = dmin * (1.0 + tie_tolerance) + min_d * tie_tolerance;
            let near = (0..bones.len()).filter(|&b| dist[b] <= cut).collect();
            (near, dmin.max(min_d))
        })
        .collect()
}

/// Per vertex, those of its nearest bones it sees (Pinocchio's test, module docs).
fn visible_nearest(
    mesh: &TriMesh,
    bones: &[Bone],
    nearest: &[(Vec<usize>, f64)],
    vis: &VisibilityParams,
    size: f64,
) -> Result<Vec<Vec<usize>>> {
    crate::check::positive("visibility.tolerance_rel", vis.tolerance_rel)?;
    crate::check::positive("visibility.step_rel", vis.step_rel)?;
    if !(-1.0..=1.0).contains(&vis.normal_cone_cos) {
        return Err(Error::InvalidParam {
            name: "visibility.normal_cone_cos",
            reason: format!("must be in [-1, 1], got {}", vis.normal_cone_cos),
        });
    }
    let winding = WindingNumber::new(mesh)?;
    let query = MeshQuery::new(mesh)?;
    let normals = vertex_normals(mesh, NormalWeighting::Area)?;
    let (tol, step) = (vis.tolerance_rel * size, vis.step_rel * size);
    // On a closed surface the winding number is constant off the surface, so a sample known
    // to be inside (w ≥ ½) at distance d from the surface vouches for every sample closer
    // than d: the walk jumps over them (a closest-point query instead of a winding number;
    // the same verdicts as testing every sample). On an open surface the ½ level set can
    // leave the surface across a hole, and every sample is tested.
    let closed = EdgeTopology::new(mesh)?.is_closed();
    let sees = |j: usize, b: usize| -> Result<bool> {
        let p = mesh.vertices[j];
        let q = bones[b].closest_point(p);
        let to_vertex = p - q;
        let len = to_vertex.length();
        if len <= tol {
            return Ok(true);
        }
        if normals[j].dot(to_vertex) < vis.normal_cone_cos * len * normals[j].length() {
            return Ok(false);
        }
        let samples = (len / step).ceil().max(1.0) as usize;
        let spacing = len / samples as f64;
        let at = |s: usize| p - to_vertex * (s as f64 / samples as f64);
        // A sample index known inside and its distance to the surface.
        let mut ball: Option<(usize, f64)> = None;
        let mut s = 1;
        while s <= samples {
            if let Some((k, r)) = ball {
                // The last sample strictly within the ball: (s' − k) · spacing < r.
                let last = (k + ((r / spacing).ceil() as usize).saturating_sub(1)).min(samples);
                if last >= s {
                    ball = Some((last, query.closest_point(at(last))?.distance));
                    s = last + 1;
                    continue;
                }
            }
            let y = at(s);
            let d = query.closest_point(y)?.distance;
            if d > tol {
                if winding.at(y)? < 0.5 {
                    return Ok(false);
                }
                ball = closed.then_some((s, d));
            } else {
                // Inside by the tolerance; which side is not known.
                ball = None;
            }
            s += 1;
        }
        Ok(true)
    };
    nearest
        .par_iter()
        .enumerate()
        .map(|(j, (near, _))| {
            let mut seen = Vec::with_capacity(near.len());
            for &b in near {
                if sees(j, b)? {
                    seen.push(b);
                }
            }
            Ok(seen)
        })
        .collect()
}

/// A connected component of the heat system none of whose vertices is heated would make it
/// singular: its vertices are heated by their nearest bones (module docs). Components are
/// those of the Laplacian `l` (its non-zero off-diagonal entries), which skips degenerate
/// faces: a vertex joined to the rest only through degenerate faces is its own component.
fn heat_unheated_components(
    l: &CscMatrix<f64>,
    nearest: &[(Vec<usize>, f64)],
    heated: &mut [Vec<usize>],
) {
    let n = heated.len();
    let mut parent: Vec<usize> = (0..n).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    for (j, col) in (0..l.ncols()).map(|j| (j, l.col(j))) {
        for (&i, &v) in col.row_indices().iter().zip(col.values()) {
            if i == j || v == 0.0 {
                continue;
            }
            let (a, b) = (root(&mut parent, i), root(&mut parent, j));
            if a != b {
                parent[a.max(b)] = a.min(b);
            }
        }
    }
    let roots: Vec<usize> = (0..n).map(|i| root(&mut parent, i)).collect();
    let mut component_heated = vec![false; n];
    for (j, hot) in heated.iter().enumerate() {
        component_heated[roots[j]] |= !hot.is_empty();
    }
    let unheated = heated.iter().filter(|h| h.is_empty()).count();
    let mut fallback = 0;
    for j in 0..n {
        if !component_heated[roots[j]] {
            heated[j] = nearest[j].0.clone();
            fallback += 1;
        }
    }
    if unheated > 0 {
        log::debug!(
            "bone heat: {unheated} of {n} vertices see no nearest bone; {fallback} of them in \
             components that see none, heated without the visibility test"
        );
    }
}

/// Sparse, normalised skinning weights by bone heat diffusion (module docs): one sparse
/// Cholesky factorisation and one solve with a right-hand side per bone, then weights below
/// `params.prune_below` dropped, at most `params.max_influences` kept, and renormalised.
///
/// # Errors
/// [`Error::Empty`] for no bones or an empty mesh, [`Error::NonFinite`] for NaN bones or
/// vertices, [`Error::InvalidParam`] for invalid params, [`Error::Degenerate`] for a
/// degenerate triangle under [`crate::mesh::DegenerateFaces::Error`], [`Error::Singular`] if
/// the heat system cannot be factorised.
///
/// # Example
/// ```
/// use skin_core::math::DVec3;
/// use skin_core::mesh::{bone_heat_weights, shapes, Bone, HeatWeightsParams};
/// let arm = shapes::cylinder(0.1, 2.0, 12, 20)?;
/// let bones = [
///     Bone::segment(DVec3::ZERO, DVec3::Z),
///     Bone::segment(DVec3::Z, 2.0 * DVec3::Z),
/// ];
/// let w = bone_heat_weights(&arm, &bones, &HeatWeightsParams::default())?;
/// assert_eq!(w.vertex_count(), arm.vertices.len());
/// # Ok::<(), skin_core::Error>(())
/// ```
pub fn bone_heat_weights(
    mesh: &TriMesh,
    bones: &[Bone],
    params: &HeatWeightsParams,
) -> Result<SkinWeights> {
    let dense = bone_heat_weights_dense(mesh, bones, params)?;
    SkinWeights::from_dense(&dense, params.prune_below, params.max_influences)
}

#[cfg(test)]
mod tests;
