//! The scanned, library-rigged template of the studio's performer and the two-way surface
//! scores, shared by the examples that mold it (`template_capture`) and learn from it
//! (`capture_anywhere`); included by `#[path]`, so each example uses what it needs.
#![allow(dead_code)]

use std::time::Instant;

use dynamic_shapes::core::math::DVec3;
use dynamic_shapes::core::mesh::{
    bone_heat_weights, decimate, evaluate_surface_points, points_to_surface, rest_bones,
    DistanceStats, HeatWeightsParams, MeshDistance, MeshQuery, SkinWeights, SurfacePoint, TriMesh,
    UvLayout,
};
use dynamic_shapes::core::stats::mean;
use dynamic_shapes::template::Template;
use dynamic_shapes_studio::{scan_outer_surface, Performer, ScanParams};

/// Height of the skirt's waistband, the part of it not marked loose, m.
pub(crate) const WAISTBAND_M: f64 = 0.04;

/// Mean over vertices of `Σ_bones |a − b|` (0: equal, 2: disjoint).
pub(crate) fn mean_abs_diff(a: &SkinWeights, b: &SkinWeights) -> f64 {
    let (a, b) = (a.to_dense(), b.to_dense());
    let per_vertex: Vec<f64> = (0..a.nrows())
        .map(|v| (a.row(v) - b.row(v)).abs().sum())
        .collect();
    mean(&per_vertex)
}

/// Two-way point-to-surface distances between a template-topology mesh and the true mesh,
/// m: over the whole surfaces, and over the skirt (the template's skirt vertices to the true
/// surface pooled with the true skirt's vertices to the template's surface). Unlike vertex
/// RMS these ignore sliding along the surface (§2.6's texture sliding) and twists no
/// silhouette sees.
pub(crate) struct SurfaceScore {
    pub(crate) whole: DistanceStats,
    pub(crate) skirt: Option<DistanceStats>,
}

impl SurfaceScore {
    pub(crate) fn new(
        mesh: &TriMesh,
        skirt: &[usize],
        truth: &MeshQuery,
        true_seen: &[DVec3],
        true_skirt: &[DVec3],
    ) -> Result<Self, Box<dyn std::error::Error>> {
        let query = MeshQuery::new(mesh)?;
        let whole = MeshDistance::from_sides(
            points_to_surface(&mesh.vertices, truth)?,
            points_to_surface(true_seen, &query)?,
        )?;
        let skirt = if skirt.is_empty() || true_skirt.is_empty() {
            None
        } else {
            let from_truth = points_to_surface(true_skirt, &query)?;
            let pooled: Vec<f64> = skirt
                .iter()
                .map(|&v| whole.a_to_b.per_vertex[v])
                .chain(from_truth.per_vertex)
                .collect();
            Some(DistanceStats::from_distances(&pooled)?)
        };
        Ok(Self {
            whole: whole.symmetric,
            skirt,
        })
    }
}

/// The template the tracker is given and where its vertices sit in the performer's rest mesh.
#[derive(Clone)]
pub(crate) struct TemplateEmbedding {
    /// The template rigged as a user's would be: skin weights computed by the library
    /// (bone heat with Pinocchio's visibility test, `skin_core::mesh::bone_heat_weights`)
    /// from the template mesh and the skeleton.
    pub(crate) template: Template,
    /// The same mesh with the performer's own weights, which generated the truth: an oracle.
    pub(crate) oracle_template: Template,
    /// The same mesh with bone-heat weights without the visibility test.
    pub(crate) no_visibility_template: Template,
    /// Mean over the template's vertices of `Σ_bones |w − w_performer|` (0: the performer's
    /// weights, 2: disjoint), for the library's weights and those without visibility.
    pub(crate) weights_mean_abs_diff: (f64, f64),
    /// Seconds to compute the library's weights.
    pub(crate) heat_weights_s: f64,
    /// Per template vertex, its fixed barycentric position in the performer's rest mesh (one
    /// corner at weight one for a decimated template, whose vertices are a subset; the
    /// closest point for a scanned one).
    pub(crate) points: Vec<SurfacePoint>,
    /// Per template vertex, the performer vertex it is (the nearest corner of its closest
    /// point for a scanned template).
    pub(crate) original: Vec<usize>,
    /// Per template vertex, whether it is on the skirt (for a scanned template: on the skirt's
    /// closed volume, its hem cap included).
    pub(crate) on_skirt: Vec<bool>,
    /// Per performer vertex, whether the template's surface cannot show it (a scanned
    /// template: the legs under the skirt); those are left out of the truth-to-result side
    /// of the surface distances.
    pub(crate) hidden: Vec<bool>,
    /// The template's texture coordinates (the performer's, on the kept vertices; none for a
    /// scanned template).
    pub(crate) uvs: Option<UvLayout>,
}

impl TemplateEmbedding {
    /// The template a user would have: the performer's rest mesh (`scan`: its outer surface
    /// as a scanner sees it, `scan_outer_surface`) decimated to `vertices` (0: kept whole),
    /// texture coordinates carried over, rigged by the library's bone-heat weights (the
    /// performer's own weights carried over for the oracle).
    pub(crate) fn new(
        performer: &Performer,
        vertices: usize,
        loose_skirt: bool,
        scan: bool,
    ) -> Result<Self, Box<dyn std::error::Error>> {
        let full = &performer.template;
        let garment = performer.garment_vertices();
        let scanned = scan
            .then(|| {
                scan_outer_surface(
                    performer,
                    &ScanParams {
                        vertices: (vertices > 0).then_some(vertices),
                        ..ScanParams::default()
                    },
                )
            })
            .transpose()?;
        let (mesh, kept): (TriMesh, Vec<usize>) = match &scanned {
            Some(s) => (s.mesh.clone(), (0..s.mesh.vertex_count()).collect()),
            None if vertices == 0 => (full.clone(), (0..full.vertex_count()).collect()),
            None => {
                let d = decimate(full, vertices)?;
                let kept = d.original_index.iter().map(|&i| i as usize).collect();
                (d.mesh, kept)
            }
        };
        let closest = MeshQuery::new(full)?.closest_points(&mesh.vertices)?;
        let points: Vec<SurfacePoint> = closest.iter().map(|c| c.point).collect();
        let (original, on_skirt): (Vec<usize>, Vec<bool>) = match &scanned {
            None => (
                kept.clone(),
                kept.iter().map(|o| garment.contains(o)).collect(),
            ),
            Some(s) => (
                points
                    .iter()
                    .map(|p| {
                        let k = (0..3).max_by(|&a, &b| p.bary[a].total_cmp(&p.bary[b]));
                        full.faces[p.face as usize][k.unwrap_or(0)] as usize
                    })
                    .collect(),
                kept.iter().map(|&k| s.on_garment[k]).collect(),
            ),
        };
        // The performer's weights at each template vertex (blended over the closest face's
        // corners for a scanned template).
        let lists: Vec<Vec<(u32, f64)>> = points
            .iter()
            .map(|p| {
                let mut acc = vec![0.0; performer.weights.bone_count()];
                for (k, &w) in p.bary.iter().enumerate() {
                    let corner = full.faces[p.face as usize][k] as usize;
                    for (b, bw) in performer.weights.influences(corner) {
                        acc[b as usize] += w * bw;
                    }
                }
                acc.into_iter()
                    .enumerate()
                    .filter(|&(_, w)| w > 0.0)
                    .map(|(b, w)| (b as u32, w))
                    .collect()
            })
            .collect();
        let oracle_weights = SkinWeights::from_lists(&lists, performer.weights.bone_count())?;
        let bones = rest_bones(&performer.skeleton)?;
        let t0 = Instant::now();
        let weights = bone_heat_weights(&mesh, &bones, &HeatWeightsParams::default())?;
        let heat_weights_s = t0.elapsed().as_secs_f64();
        let no_visibility_weights = bone_heat_weights(
            &mesh,
            &bones,
            &HeatWeightsParams::default().without_visibility(),
        )?;
        let weights_mean_abs_diff = (
            mean_abs_diff(&weights, &oracle_weights),
            mean_abs_diff(&no_visibility_weights, &oracle_weights),
        );
        let uvs = match (&scanned, &performer.uvs) {
            (None, Some(l)) => {
                let kept_u32: Vec<u32> = kept.iter().map(|&o| o as u32).collect();
                Some(l.for_vertex_subset(full, &mesh, &kept_u32)?)
            }
            _ => None,
        };
        let oracle_template =
            Template::new(mesh.clone(), performer.skeleton.clone(), oracle_weights)?;
        let no_visibility_template = Template::new(
            mesh.clone(),
            performer.skeleton.clone(),
            no_visibility_weights,
        )?;
        let mut template = Template::new(mesh, performer.skeleton.clone(), weights)?;
        if loose_skirt && !garment.is_empty() {
            // What a user marks: the skirt below its waistband (the top WAISTBAND_M of it).
            let top = garment
                .clone()
                .map(|v| full.vertices[v].y)
                .fold(f64::MIN, f64::max);
            let rest = &template.mesh().vertices;
            let loose = (0..rest.len())
                .map(|v| on_skirt[v] && rest[v].y < top - WAISTBAND_M)
                .collect();
            template = template.with_loose_vertices(loose)?;
        }
        let hidden = scanned.map_or_else(|| vec![false; full.vertex_count()], |s| s.hidden);
        Ok(Self {
            template,
            oracle_template,
            no_visibility_template,
            weights_mean_abs_diff,
            heat_weights_s,
            points,
            original,
            on_skirt,
            hidden,
            uvs,
        })
    }

    /// The true positions of the template's vertices on one frame's true mesh.
    pub(crate) fn truth(
        &self,
        true_mesh: &TriMesh,
    ) -> Result<Vec<DVec3>, Box<dyn std::error::Error>> {
        Ok(evaluate_surface_points(true_mesh, &self.points)?)
    }
}
