//! Times the volumetric merge (§3.3.3, `merge_views`) at the thesis's 2 mm voxels and 6 cm
//! ramps: eight ring cameras around a bumpy sphere of radius 0.4 m (about the surface area
//! of a torso), their true depth maps at 256² and 512². First one line of JSON per size
//! under `cargo bench` (wall and CPU seconds of one merge, this process's threads; the
//! stages' wall times; the mesh's vertex and face counts and a hash of its vertices and
//! faces: the same hash before and after a change means the same mesh, bit for bit), then
//! criterion's timings.
//!
//! `cargo bench -p photometric-normals --bench merge`
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)] // not library code

// criterion_group!/criterion_main! generate undocumented public functions.
#![allow(missing_docs)]

use std::hash::{DefaultHasher, Hash, Hasher};
use std::hint::black_box;
use std::time::Instant;

mod common;
use common::cpu_seconds;

use criterion::Criterion;
use photometric_normals::{merge_views, DepthMap, MergeParams, MergeView};
use skin_core::camera::{Camera, Intrinsics, Rig};
use skin_core::math::DVec3;
use skin_core::mesh::shapes::uv_sphere;
use skin_core::raster::{Buffers, Rasterizer, RenderParams};

/// The ring of eight cameras 2.5 m from the centre and their true depth maps.
fn scene(size: u32) -> (Vec<Camera>, Vec<DepthMap>) {
    let k = Intrinsics::from_horizontal_fov(0.45, size, size).unwrap();
    let cameras = Rig::ring(8, 2.5, 0.3, DVec3::ZERO, DVec3::Y, k)
        .unwrap()
        .cameras;
    let mut mesh = uv_sphere(DVec3::ZERO, 0.4, 256, 512).unwrap();
    for v in &mut mesh.vertices {
        *v *= 1.0 + 0.05 * (9.0 * v.x).sin() * (7.0 * v.y).cos() * (5.0 * v.z).sin();
    }
    let params = RenderParams::default().with_buffers(Buffers {
        depth: true,
        ..Buffers::MASK_ONLY
    });
    let maps = cameras
        .iter()
        .map(|c| DepthMap::from_view(&Rasterizer::new(c).render(&mesh, &params).unwrap()).unwrap())
        .collect();
    (cameras, maps)
}

fn merge(cameras: &[Camera], maps: &[DepthMap]) -> photometric_normals::MergedSurface {
    let views: Vec<MergeView> = cameras
        .iter()
        .zip(maps)
        .map(|(c, d)| MergeView::new(c, d))
        .collect();
    merge_views(&views, &MergeParams::default()).unwrap()
}

fn main() {
    let sizes = [256u32, 512];
    let scenes: Vec<_> = sizes.iter().map(|&s| scene(s)).collect();
    // Under `cargo bench` (not `cargo test --benches`, which runs each benchmark once).
    if std::env::args().any(|a| a == "--bench") {
        for (size, (cameras, maps)) in sizes.iter().zip(&scenes) {
            let (t, c) = (Instant::now(), cpu_seconds());
            let out = merge(cameras, maps);
            let (wall, cpu) = (t.elapsed().as_secs_f64(), cpu_seconds() - c);
            let mut h = DefaultHasher::new();
            for v in &out.mesh.vertices {
                v.to_array().map(f64::to_bits).hash(&mut h);
            }
            out.mesh.faces.hash(&mut h);
            let s = &out.times;
            println!(
                "{{\"size\":{size},\"wall_s\":{wall:.3},\"cpu_s\":{cpu:.2},\"prepare_s\":{:.3},\
                 \"blocks_s\":{:.3},\"fill_s\":{:.3},\"cells_s\":{:.3},\"march_s\":{:.3},\
                 \"blocks\":{},\"vertices\":{},\"faces\":{},\"mesh_hash\":\"{:016x}\"}}",
                s.prepare_s,
                s.blocks_s,
                s.fill_s,
                s.cells_s,
                s.march_s,
                out.stats.blocks,
                out.mesh.vertex_count(),
                out.mesh.face_count(),
                h.finish()
            );
        }
    }
    let mut c = Criterion::default().configure_from_args();
    for (size, (cameras, maps)) in sizes.iter().zip(&scenes) {
        let mut g = c.benchmark_group(format!("merge_ring_{size}"));
        g.sample_size(10);
        g.bench_function("merge_views", |b| {
            b.iter(|| merge(black_box(cameras), black_box(maps)))
        });
        g.finish();
    }
    c.final_summary();
}
