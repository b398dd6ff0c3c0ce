//! The accuracy measures of Table 2.1 (Vlasic 2010 §2.5.2): the silhouette error and the
//! edge error of a reconstructed mesh. Neither needs ground truth.

use skin_core::camera::Camera;
use skin_core::image::Mask;
use skin_core::math::DVec3;
use skin_core::mesh::{unique_edges, TriMesh};
use skin_core::raster::{Rasterizer, RenderParams};

use crate::error::{Context, Error, Result, ResultExt};
use crate::visual_hull::check_views;

/// The silhouette error of Table 2.1: "the percentage of the reconstructed silhouette that
/// did not agree with the captured silhouette", `|reconstructed XOR captured| /
/// |reconstructed|` in percent, per camera.
///
/// # Errors
/// [`Error::SizeMismatch`] if cameras and masks differ in number or a mask is not its
/// camera's size; [`Error::Empty`] for no camera; errors of the rasteriser (an empty mesh, or
/// a camera that does not see it) wrapped with the camera.
pub fn silhouette_error_pct(
    mesh: &TriMesh,
    cameras: &[Camera],
    masks: &[Mask],
) -> Result<Vec<f64>> {
    check_views(cameras, masks)?;
    cameras
        .iter()
        .zip(masks)
        .enumerate()
        .map(|(c, (camera, captured))| {
            let view = Rasterizer::new(camera)
                .render(mesh, &RenderParams::default())
                .at(Context::Camera(c))?;
            let reconstructed = view.silhouette();
            let disagree = reconstructed.xor(captured).at(Context::Camera(c))?.count();
            Ok(100.0 * disagree as f64 / reconstructed.count() as f64)
        })
        .collect()
}

/// The edge error of Table 2.1: "the percentage change in edge length as compared to the
/// template", the mean over edges of `|ℓ − ℓ₀| / ℓ₀` in percent.
///
/// # Errors
/// [`Error::SizeMismatch`] if `vertices` is not one per template vertex; [`Error::NonFinite`]
/// for non-finite vertices; [`Error::InvalidParam`] for a template edge of zero length;
/// errors of the template's topology.
pub fn edge_error_pct(template: &TriMesh, vertices: &[DVec3]) -> Result<f64> {
    if vertices.len() != template.vertex_count() {
        return Err(Error::SizeMismatch {
            what: "vertices vs template vertices (give one position per template vertex)",
            expected: template.vertex_count(),
            got: vertices.len(),
        });
    }
    if !vertices.iter().all(|v| v.is_finite()) {
        return Err(Error::NonFinite {
            what: "vertices (remove NaN or infinite positions)",
        });
    }
    let edges = unique_edges(template)?;
    if edges.is_empty() {
        return Err(Error::Empty {
            what: "template edges (give a template with faces)",
        });
    }
    let mut sum = 0.0;
    for [a, b] in &edges {
        let (a, b) = (*a as usize, *b as usize);
        let l0 = template.vertices[a].distance(template.vertices[b]);
        if l0 <= 0.0 {
            return Err(Error::InvalidParam {
                name: "template",
                reason: format!(
                    "edge ({a}, {b}) has zero length; merge or move apart its two vertices"
                ),
            });
        }
        sum += (vertices[a].distance(vertices[b]) - l0).abs() / l0;
    }
    Ok(100.0 * sum / edges.len() as f64)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::visual_hull::tests::ring;
    use skin_core::mesh::shapes;

    fn ball(r: f64) -> TriMesh {
        let mut m = shapes::icosphere(3).unwrap();
        for v in &mut m.vertices {
            *v = DVec3::new(0.0, 1.0, 0.0) + r * *v;
        }
        m
    }

    #[test]
    fn own_silhouettes_score_zero_and_a_grown_ball_scores_its_area_change() {
        let cams = ring(2, 160, 120);
        let m = ball(0.3);
        let masks: Vec<Mask> = cams
            .iter()
            .map(|c| {
                Rasterizer::new(c)
                    .render(&m, &RenderParams::default())
                    .unwrap()
                    .silhouette()
            })
            .collect();
        let e = silhouette_error_pct(&m, &cams, &masks).unwrap();
        assert!(e.iter().all(|&x| x == 0.0));
        // 10 % larger radius: about 1 − 1/1.21 = 17 % of the reconstructed disc disagrees.
        let e = silhouette_error_pct(&ball(0.33), &cams, &masks).unwrap();
        assert!(e.iter().all(|&x| (x - 17.4).abs() < 3.0), "{e:?}");
        assert!(silhouette_error_pct(&m, &cams, &masks[..1]).is_err());
    }

    #[test]
    fn edge_error_of_a_scaled_mesh_is_the_scale_change() {
        let m = ball(0.3);
        assert_eq!(edge_error_pct(&m, &m.vertices).unwrap(), 0.0);
        let grown: Vec<DVec3> = m.vertices.iter().map(|v| *v * 1.1).collect();
        assert!((edge_error_pct(&m, &grown).unwrap() - 10.0).abs() < 1e-9);
        assert!(edge_error_pct(&m, &grown[1..]).is_err());
        let mut bad = grown.clone();
        bad[0] = DVec3::NAN;
        assert!(edge_error_pct(&m, &bad).is_err());
    }
}
