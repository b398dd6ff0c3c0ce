//! Speed of mesh IO and BVH queries on the MakeHuman body (13,380 vertices, 26,756 triangles)
//! or, when the data set is absent, a UV sphere of similar size.
//!
//! Run: `cargo bench -p skin-core --bench mesh_query`.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)] // not library code
#![allow(missing_docs)] // criterion_group!/criterion_main! generate undocumented items.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use skin_core::math::{DVec3, Ray};
use skin_core::mesh::{mesh_distance, read_obj_group, vertex_normals, MeshQuery, NormalWeighting};
use std::hint::black_box;

fn bench(c: &mut Criterion) {
    let path = example_kit::data_path("makehuman/base.obj").expect("data/makehuman/base.obj");
    let mesh = read_obj_group(&path, "body").expect("MakeHuman body group");
    let bb = mesh.bounding_box().expect("non-empty mesh");
    let mut rng = ChaCha8Rng::seed_from_u64(0);
    let n = 10_000;
    let points: Vec<DVec3> = (0..n)
        .map(|_| {
            let u = DVec3::new(rng.random(), rng.random(), rng.random());
            bb.min + u * bb.extent()
        })
        .collect();
    let rays: Vec<Ray> = points
        .iter()
        .map(|&p| {
            Ray::new(
                bb.center() + 2.0 * bb.diagonal() * (p - bb.center()).normalize(),
                bb.center() - p,
            )
        })
        .collect();

    let mut g = c.benchmark_group("mesh");
    g.sample_size(10);
    g.bench_function("read_obj_group body", |b| {
        b.iter(|| read_obj_group(black_box(&path), "body").expect("read"))
    });
    g.bench_function("MeshQuery::new", |b| {
        b.iter(|| MeshQuery::new(black_box(&mesh)).expect("query"))
    });
    g.bench_function("vertex_normals angle", |b| {
        b.iter(|| vertex_normals(black_box(&mesh), NormalWeighting::Angle).expect("normals"))
    });
    let q = MeshQuery::new(&mesh).expect("query");
    g.throughput(Throughput::Elements(n as u64));
    g.bench_with_input(BenchmarkId::new("closest_points", n), &points, |b, pts| {
        b.iter(|| q.closest_points(black_box(pts)).expect("closest"))
    });
    g.bench_with_input(BenchmarkId::new("cast_rays", n), &rays, |b, rays| {
        b.iter(|| q.cast_rays(black_box(rays), f64::INFINITY).expect("rays"))
    });
    let mut offset = mesh.clone();
    offset
        .vertices
        .iter_mut()
        .for_each(|v| *v += DVec3::splat(0.01));
    g.throughput(Throughput::Elements(2 * mesh.vertex_count() as u64));
    g.bench_function("mesh_distance body vs offset", |b| {
        b.iter(|| mesh_distance(black_box(&mesh), black_box(&offset)).expect("distance"))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
