//! Rasteriser and shading speed on the MakeHuman body (13,380 vertices, 26,756 triangles; a
//! bumpy body-sized blob of similar size when the data set is absent): silhouette, depth and
//! normals at 1600×1200 (the `raster_ms_per_view` workload of the studio example), and the
//! 1,200-light dome with per-vertex shadows at 1024×1024 (`shade_ms_per_view_shadowed`), and
//! a dense mesh (a sphere of 1.2 M triangles, as many as a merged studio mesh at 512²) into a
//! 512 × 512 camera with depth and normals, both faces, as the reconstruction's coverage and
//! proxy renders do: there the per-triangle set-up and binning outweigh the scan conversion.
//!
//! Run: `cargo bench -p dynamic-shapes-studio --bench raster`.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)] // not library code
#![allow(missing_docs)] // criterion_group!/criterion_main! generate undocumented items.

use criterion::{criterion_group, criterion_main, Criterion};
use dynamic_shapes_studio::shading::{
    dome_lights, shade, vertices_seen, Albedo, DomeParams, LightVisibility, Shadows,
};
use skin_core::camera::{Camera, Intrinsics, RadialDistortion};
use skin_core::math::{DVec2, DVec3};
use skin_core::mesh::shapes::uv_sphere;
use skin_core::mesh::{read_obj_group, MeshQuery, TriMesh};
use skin_core::raster::{Buffers, Rasterizer, RenderParams};

/// The MakeHuman skin surface in metres with the feet at y = 0 (the repository's data).
fn makehuman_body() -> TriMesh {
    let path = example_kit::data_path("makehuman/base.obj").expect("data/makehuman/base.obj");
    let mut mesh = read_obj_group(path, "body").expect("MakeHuman body group");
    let min_y = mesh
        .vertices
        .iter()
        .map(|v| v.y)
        .fold(f64::INFINITY, f64::min);
    for v in &mut mesh.vertices {
        // Decimetres to metres, feet on the floor.
        *v = DVec3::new(v.x, v.y - min_y, v.z) * 0.1;
    }
    mesh
}

/// A closed, bumpy, person-sized ellipsoid (1.8 m tall) with `(n_lat − 1)·n_lon + 2` vertices.
fn camera(k1: f64) -> Camera {
    // 1.8 m body filling ~75% of the 1200-px height from 3 m.
    let k = Intrinsics::new(1500.0, 1500.0, 799.5, 599.5, 1600, 1200).expect("valid");
    Camera::look_at(
        k,
        DVec3::new(0.8, 1.2, 2.9),
        DVec3::new(0.0, 0.9, 0.0),
        DVec3::Y,
    )
    .expect("valid")
    .with_distortion(RadialDistortion::new(k1, DVec2::new(790.0, 610.0)))
}

/// Rasteriser benchmarks: pinhole and distorted cameras, three buffer sets.
fn bench_raster(c: &mut Criterion) {
    let mesh = makehuman_body();
    eprintln!(
        "body: {} vertices, {} faces",
        mesh.vertex_count(),
        mesh.face_count()
    );
    let mut g = c.benchmark_group("raster_1600x1200_13k");
    g.sample_size(20);
    for (name, k1) in [("pinhole", 0.0), ("distorted", -0.12)] {
        let ras = Rasterizer::new(&camera(k1));
        let mut view = Default::default();
        for (what, buffers) in [
            ("mask", Buffers::MASK_ONLY),
            ("mask_depth_normals", Buffers::default()),
            ("all", Buffers::ALL),
        ] {
            let params = RenderParams::default().with_buffers(buffers);
            g.bench_function(format!("{name}/{what}"), |b| {
                b.iter(|| ras.render_into(&mesh, &params, &mut view).expect("visible"))
            });
        }
        let params = RenderParams::default();
        g.bench_function(format!("{name}/mask_depth_normals_fresh_alloc"), |b| {
            b.iter(|| ras.render(&mesh, &params).expect("visible"))
        });
    }
    g.finish();
}

/// A 1.2 M-triangle sphere of 0.9 m radius seen from 3 m by a 512² camera, both faces
/// rendered: depth only (the coverage and proxy renders) and depth with normals.
fn bench_raster_dense(c: &mut Criterion) {
    let mesh = uv_sphere(DVec3::new(0.0, 0.9, 0.0), 0.9, 600, 1000).expect("valid");
    let k = Intrinsics::new(600.0, 600.0, 255.5, 255.5, 512, 512).expect("valid");
    let cam = Camera::look_at(
        k,
        DVec3::new(0.0, 1.2, 3.0),
        DVec3::new(0.0, 0.9, 0.0),
        DVec3::Y,
    )
    .expect("valid");
    let ras = Rasterizer::new(&cam);
    let mut g = c.benchmark_group("raster_512_dense_1m2");
    g.sample_size(10);
    let depth = Buffers {
        mask: false,
        depth: true,
        camera_z: false,
        normal: false,
        triangle: false,
    };
    for (what, buffers) in [("depth", depth), ("mask_depth_normals", Buffers::default())] {
        let params = RenderParams::default()
            .with_buffers(buffers)
            .with_cull_back_faces(false);
        g.bench_function(what, |b| {
            b.iter(|| ras.render(&mesh, &params).expect("visible"))
        });
    }
    g.finish();
}

/// Dome shading: per-vertex shadow rays (once per frame) and per-pixel shading of one view.
fn bench_shade(c: &mut Criterion) {
    let mesh = makehuman_body();
    let k = Intrinsics::new(1400.0, 1400.0, 511.5, 511.5, 1024, 1024).expect("valid");
    let cam = Camera::look_at(
        k,
        DVec3::new(0.5, 1.7, 3.0),
        DVec3::new(0.0, 0.85, 0.0),
        DVec3::Y,
    )
    .expect("valid");
    let view = Rasterizer::new(&cam)
        .render(&mesh, &RenderParams::default().with_buffers(Buffers::ALL))
        .expect("visible");
    let lights = dome_lights(&DomeParams::default()).expect("valid");
    let query = MeshQuery::new(&mesh).expect("valid mesh");
    let alb = Albedo::Uniform([0.8, 0.6, 0.5]);
    let mut g = c.benchmark_group("shade_dome1200_1024");
    g.sample_size(10);
    let seen = vertices_seen(&mesh, &[&view]).expect("triangle buffer");
    g.bench_function("visibility_per_vertex_seen_by_view", |b| {
        b.iter(|| {
            LightVisibility::compute_for(
                &mesh,
                &query,
                &lights,
                LightVisibility::DEFAULT_SHADOW_BIAS_M,
                Some(&seen),
            )
            .expect("lights outside")
        })
    });
    g.bench_function("shade_per_vertex_shadows", |b| {
        // Visibility is computed once per frame and shared by every camera.
        let vis = LightVisibility::compute(
            &mesh,
            &query,
            &lights,
            LightVisibility::DEFAULT_SHADOW_BIAS_M,
        )
        .expect("lights outside");
        b.iter(|| shade(&view, &mesh, &lights, &alb, &Shadows::PerVertex(&vis)).expect("ok"))
    });
    g.bench_function("shade_unshadowed", |b| {
        b.iter(|| shade(&view, &mesh, &lights, &alb, &Shadows::None).expect("ok"))
    });
    g.finish();
}

criterion_group!(benches, bench_raster, bench_raster_dense, bench_shade);
criterion_main!(benches);
