//! Speed of the watertight union surface (Sand 2003 §3.2, [`needle_model::union_mesh`]) at the
//! default 5 mm grid: the Table 3.1 body on the default human skeleton, every needle's
//! length a smooth function of its index (3–5.5 cm), posed at the rest pose with the last
//! degree of freedom turned. One iteration is one body surface (figure `union_fps` of the
//! `needle_capture` example is its frame rate).
#![allow(clippy::unwrap_used, clippy::expect_used)] // not library code
#![allow(missing_docs)] // criterion_group! generates an undocumented public function

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion};
use needle_model::{
    animate, union_mesh, AnimatedBody, BodyLayout, NeedleBody, NeedleModel, ObservationStore,
    ReconstructionParams, SurfaceParams,
};
use skin_core::skeleton::{human_skeleton, HumanParams};

/// The posed Table 3.1 body of a static model with varying needle lengths.
fn posed_body() -> AnimatedBody {
    let sk = human_skeleton(&HumanParams::default()).unwrap();
    let body = NeedleBody::new(&sk, &BodyLayout::table_3_1()).unwrap();
    let mut store = ObservationStore::new(&body.store_shapes()).unwrap();
    let mut theta = sk.rest_pose();
    for s in 0..4 {
        theta[sk.dof_count() - 1] = 0.05 * s as f64;
        let fk = sk.forward_kinematics(&theta).unwrap();
        for (p, prim) in body.primitives.iter().enumerate() {
            let x = prim.config.point(&fk).unwrap();
            let obs: Vec<(u16, f32)> = (0..prim.needle_count())
                .map(|j| (j as u16, 0.0425 + 0.0125 * (0.7 * j as f32).sin()))
                .collect();
            store.push_sample(p, &x, &obs).unwrap();
        }
    }
    let params = ReconstructionParams::default()
        .with_prototype_count_n(2)
        .with_f_near(1.0);
    let model = NeedleModel::reconstruct(&store, &body, &params)
        .unwrap()
        .model;
    theta[sk.dof_count() - 1] = 0.3;
    animate(&body, &model, &sk, &theta).unwrap()
}

fn bench(c: &mut Criterion) {
    let posed = posed_body();
    let params = SurfaceParams::default();
    let mut g = c.benchmark_group("surface");
    g.sample_size(10);
    g.bench_function("union_mesh_5mm_table_3_1", |b| {
        b.iter(|| union_mesh(black_box(&posed), &params).unwrap())
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
