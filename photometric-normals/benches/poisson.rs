//! Times the screened Poisson hole filling (`screened_poisson`) at depth 8 and 9 on a bumpy
//! sphere of radius 0.9 m with a hole (≈ 400 k oriented samples, the size of the studio's
//! merged surface plus proxy at 1024²) and prints one JSON line per depth: wall and CPU
//! seconds (this process, all threads), the mesh's vertex and face counts and a hash of its
//! vertices and faces (bit for bit: the same hash before and after a change means the same
//! mesh), the stages' wall times (`stages_s`: samples, solve, cells, march) and per level
//! `[depth, nodes, CG iterations]`.
//!
//! `cargo bench -p photometric-normals --bench poisson [-- DEPTH …]`
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)] // not library code

use std::hash::{DefaultHasher, Hash, Hasher};
use std::time::Instant;

mod common;
use common::cpu_seconds;

use photometric_normals::{screened_poisson, OrientedSample, PoissonParams};
use skin_core::math::DVec3;
use skin_core::mesh::shapes::uv_sphere;

fn main() {
    let depths: Vec<u32> = std::env::args()
        .skip(1)
        .filter_map(|a| a.parse().ok())
        .collect();
    let depths = if depths.is_empty() {
        vec![8, 9]
    } else {
        depths
    };
    let mut sphere = uv_sphere(DVec3::ZERO, 0.9, 400, 1000).unwrap();
    for v in &mut sphere.vertices {
        *v *= 1.0 + 0.03 * (7.0 * v.x).sin() * (5.0 * v.y).cos() * (3.0 * v.z).sin();
    }
    let mut samples = OrientedSample::from_mesh(&sphere, 1.0).unwrap();
    samples.retain(|s| s.position.y < 0.6);
    for depth in depths {
        let params = PoissonParams::default().with_depth(depth);
        let (t, c) = (Instant::now(), cpu_seconds());
        let out = screened_poisson(&samples, &params).unwrap();
        let (wall, cpu) = (t.elapsed().as_secs_f64(), cpu_seconds() - c);
        let mut h = DefaultHasher::new();
        for v in &out.mesh.vertices {
            v.to_array().map(f64::to_bits).hash(&mut h);
        }
        out.mesh.faces.hash(&mut h);
        let levels: Vec<String> = out
            .levels
            .iter()
            .map(|l| format!("[{},{},{}]", l.depth, l.nodes, l.iterations))
            .collect();
        let t = out.times;
        println!(
            "{{\"depth\":{depth},\"samples\":{},\"wall_s\":{wall:.2},\"cpu_s\":{cpu:.2},\
             \"vertices\":{},\"faces\":{},\"mesh_hash\":\"{:016x}\",\
             \"stages_s\":[{:.2},{:.2},{:.2},{:.2}],\"levels\":[{}]}}",
            samples.len(),
            out.mesh.vertex_count(),
            out.mesh.face_count(),
            h.finish(),
            t.samples_s,
            t.solve_s,
            t.cells_s,
            t.march_s,
            levels.join(",")
        );
    }
}
