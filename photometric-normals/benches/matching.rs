//! Times pairwise matching (§3.3.2, `match_pair`) on two cameras 45° apart around a bumpy
//! sphere, at several image sizes, without and with the visual hull of eight ring cameras (and
//! with the hull and coarse-to-fine matching, [`MatchingParams::coarse_to_fine`]), and
//! prints one JSON line per case with the wall and CPU seconds per pair (best of the runs),
//! the cells evaluated and the match errors against the true depths.
//!
//! `cargo bench -p photometric-normals --bench matching [-- 256 512 1024]`

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)] // not library code

use std::time::Instant;

mod common;
use common::cpu_seconds;

use photometric_normals::{
    depth_errors, match_pair, mesh_proxy_depth, DepthMap, MatchView, MatchingParams, PolygonalHull,
};
use skin_core::camera::{Camera, Intrinsics, Rig};
use skin_core::image::Mask;
use skin_core::math::DVec3;
use skin_core::mesh::shapes::uv_sphere;

/// The ring of eight cameras and their true depth maps (the first two are matched; all
/// eight carve the visual hull).
fn scene(size: u32) -> (Vec<Camera>, Vec<DepthMap>) {
    let k = Intrinsics::from_horizontal_fov(0.5, size, size).expect("intrinsics");
    let rig = Rig::ring(8, 3.0, 0.0, DVec3::ZERO, DVec3::Y, k).expect("rig");
    let cams = rig.cameras;
    let mut mesh = uv_sphere(DVec3::ZERO, 0.4, 192, 384).expect("sphere");
    for v in &mut mesh.vertices {
        *v *= 1.0 + 0.05 * (5.0 * v.x).sin() * (5.0 * v.y).cos();
    }
    let depths = cams
        .iter()
        .map(|c| mesh_proxy_depth(c, &mesh).expect("render"))
        .collect();
    (cams, depths)
}

fn main() {
    let sizes: Vec<u32> = std::env::args()
        .skip(1)
        .filter_map(|a| a.parse().ok())
        .collect();
    let sizes = if sizes.is_empty() {
        vec![256, 512]
    } else {
        sizes
    };
    for size in sizes {
        let (cams, truth) = scene(size);
        let masks: Vec<Mask> = truth
            .iter()
            .map(|d| {
                Mask::from_fn(size, size, |x, y| {
                    !d.depth_m[(y * size + x) as usize].is_nan()
                })
            })
            .collect();
        let hull = PolygonalHull::new(&cams, &masks).expect("hull");
        for (with_hull, coarse_to_fine) in [(false, false), (true, false), (true, true)] {
            let view = |c: usize| MatchView {
                camera: &cams[c],
                surface: &truth[c],
                guide: None,
                images: None,
            };
            let params = MatchingParams {
                coarse_to_fine,
                ..MatchingParams::default()
            };
            let runs = if size >= 1024 { 1 } else { 3 };
            let mut best = f64::INFINITY;
            let mut best_cpu = f64::INFINITY;
            let mut result = None;
            for _ in 0..runs {
                let (t, cpu) = (Instant::now(), cpu_seconds());
                let m = match_pair(&view(0), &view(1), with_hull.then_some(&hull), &params)
                    .expect("match");
                best = best.min(t.elapsed().as_secs_f64());
                best_cpu = best_cpu.min(cpu_seconds() - cpu);
                result = Some(m);
            }
            let m = result.expect("one run");
            let err = depth_errors(&m.left.target, &truth[0], None).expect("errors");
            println!(
            "{{\"size_px\": {size}, \"hull\": {with_hull}, \"coarse_to_fine\": {coarse_to_fine}, \"seconds_per_pair\": {best:.4}, \"cpu_seconds_per_pair\": {best_cpu:.2}, \"cells_evaluated\": {}, \"good_matches\": {}, \"discontinuities\": {}, \"match_median_mm\": {:.4}, \"match_p95_mm\": {:.4}}}",
            m.stats.cells_evaluated,
            m.stats.good_matches,
            m.stats.discontinuities,
            err.median_mm,
            err.p95_mm
        );
        }
    }
}
