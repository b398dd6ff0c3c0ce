use super::assembly::*;
use super::cells::*;
use super::grid::*;
use super::samples::*;
use super::solve::*;
use super::*;
use skin_core::mesh::EdgeTopology;

/// The sample of the sphere of radius 0.4 at height `-0.4 + 0.7 u` (so without its cap
/// z > 0.3) and azimuth `phi`.
fn on_holed_sphere(u: f64, phi: f64) -> OrientedSample {
    let z = -0.4 + 0.7 * u;
    let rho = (0.16 - z * z).sqrt();
    let p = DVec3::new(rho * phi.cos(), rho * phi.sin(), z);
    OrientedSample {
        position: p,
        normal: p / 0.4,
        weight: 1.0,
    }
}

/// A Fibonacci lattice on the sphere of radius 0.4 without its cap z > 0.3.
fn holed_sphere(n: usize) -> Vec<OrientedSample> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|i| on_holed_sphere((i as f64 + 0.5) / n as f64, golden * i as f64))
        .collect()
}

#[test]
fn fills_the_hole_of_a_sphere_with_a_closed_sphere() {
    let samples = holed_sphere(20_000);
    let params = PoissonParams::default().with_depth(6);
    let s = screened_poisson(&samples, &params).unwrap();
    let topo = EdgeTopology::new(&s.mesh).unwrap();
    assert!(
        topo.is_closed(),
        "{} boundary edges",
        topo.boundary_edges().len()
    );
    assert!(topo.non_manifold_edges().is_empty());
    let edges = skin_core::mesh::unique_edges(&s.mesh).unwrap().len() as i64;
    let chi = s.mesh.vertex_count() as i64 - edges + s.mesh.face_count() as i64;
    assert_eq!(chi, 2);
    let err: Vec<f64> = s
        .mesh
        .vertices
        .iter()
        .filter(|v| v.z < 0.25)
        .map(|v| (v.length() - 0.4).abs())
        .collect();
    let mean = skin_core::stats::mean(&err);
    // One cell at depth 6 over the 0.88 m domain is 14 mm.
    assert!(mean < 0.004, "mean {mean}");
    // The filled cap stays near the sphere's top (z = 0.4) rather than a flat lid at 0.3.
    let top = s
        .mesh
        .vertices
        .iter()
        .fold(f64::NEG_INFINITY, |a, v| a.max(v.z));
    assert!(top > 0.33, "top {top}");
}

/// Samples uniform at random by area on the same holed sphere (workload 6b's recipe).
fn random_holed_sphere(n: usize) -> Vec<OrientedSample> {
    let us = skin_core::random::SplitMix64::new(80).uniform(n);
    let vs = skin_core::random::SplitMix64::new(81).uniform(n);
    us.iter()
        .zip(&vs)
        .map(|(&u, &v)| on_holed_sphere(u, std::f64::consts::TAU * v))
        .collect()
}

/// Mean distance of the vertices where the holed sphere is sampled (`z ≤ 0.25`, away from
/// the hole's rim) to the sphere, m.
fn error_where_sampled(mesh: &TriMesh) -> f64 {
    let err: Vec<f64> = mesh
        .vertices
        .iter()
        .filter(|v| v.z <= 0.25)
        .map(|v| (v.length() - 0.4).abs())
        .collect();
    skin_core::stats::mean(&err)
}

#[test]
fn random_samples_give_a_smooth_surface() {
    // About two samples per finest cell, placed at random: the trilinear flux splat (two
    // cells wide) follows their clustering; the quadratic one (three cells wide) averages it
    // out.
    let samples = random_holed_sphere(50_000);
    let error = |splat: FluxSplat| {
        let params = PoissonParams::default()
            .with_depth(7)
            .with_flux_splat(splat);
        error_where_sampled(&screened_poisson(&samples, &params).unwrap().mesh)
    };
    let (quadratic, trilinear) = (error(FluxSplat::Quadratic), error(FluxSplat::Trilinear));
    assert!(quadratic < 0.1e-3, "quadratic {quadratic}");
    assert!(trilinear > 1.2 * quadratic, "{trilinear} vs {quadratic}");
}

#[test]
fn quadratic_splat_weights_sum_to_one_about_the_point() {
    for t in [-0.5, -0.3, 0.0, 0.2, 0.5] {
        let w = quadratic(t);
        assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-15);
        let centroid = -w[0] + w[2];
        assert!((centroid - t).abs() < 1e-15, "{t}: {centroid}");
        assert!(w.iter().all(|&x| x >= 0.0));
    }
    // The stencil's unknowns are `Level::index` of the 27 nodes, x fastest.
    let level = Level::new(4, &[true; 125]);
    let c = [0, 3, 16];
    let got = level.stencil_indices(c);
    for (k, &i) in got.iter().enumerate() {
        let p = [
            c[0] + k as i64 % 3 - 1,
            c[1] + (k as i64 / 3) % 3 - 1,
            c[2] + k as i64 / 9 - 1,
        ];
        let want = level
            .in_domain(p)
            .then(|| level.index(p))
            .flatten()
            .map_or(NONE, |i| i as u32);
        assert_eq!(i, want, "{p:?}");
    }
}

#[test]
fn multigrid_on_the_bands_solves_the_same_system() {
    let samples = holed_sphere(8_000);
    let p = PoissonParams::default().with_depth(6);
    let jacobi = screened_poisson(&samples, &p).unwrap();
    let mg = screened_poisson(&samples, &p.with_multigrid_bands(true)).unwrap();
    // Same levels, each converged; V-cycles need fewer iterations on every level.
    for (a, b) in jacobi.levels.iter().zip(&mg.levels) {
        assert_eq!(a.nodes, b.nodes);
        assert!(a.residual <= p.tolerance && b.residual <= p.tolerance);
        assert!(b.iterations <= a.iterations, "{a:?} vs {b:?}");
    }
    // The complete levels are always multigrid: a handful of iterations.
    assert!(jacobi.levels[..4].iter().all(|l| l.iterations < 20));
    assert!((jacobi.iso_value - mg.iso_value).abs() < 1e-3);
    assert_eq!(jacobi.mesh.vertex_count(), mg.mesh.vertex_count());
}

/// The hierarchy of `screened_poisson` on `samples`, every level solved.
fn solved_levels(samples: &[OrientedSample], params: &PoissonParams) -> Vec<Level> {
    let (unit, _, _) = unit_samples(samples, params.scale, params.depth);
    solve_hierarchy(&unit, params).unwrap().0
}

#[test]
fn fused_jacobi_cg_follows_the_textbook_iteration() {
    // The fused Jacobi-preconditioned CG (three passes, `z` recomputed) against the
    // textbook loop written out serially, on a band level's operator, iteration for
    // iteration: the iterates agree up to the order of the sums.
    let samples = holed_sphere(8_000);
    let params = PoissonParams::default().with_depth(7);
    let levels = solved_levels(&samples, &params);
    let (top, coarser) = levels.split_last().unwrap();
    assert!(!top.complete);
    let n = top.nodes.len();
    let b: Vec<f64> = (0..n)
        .map(|i| ((i * 7919) % 1000) as f64 / 500.0 - 1.0)
        .collect();
    let apply = |x: &[f64]| -> Vec<f64> {
        (0..n)
            .map(|i| {
                let mut s = top.diag[i] * x[i];
                for &j in &top.nbr[i] {
                    if j != NONE {
                        s -= x[j as usize];
                    }
                }
                s
            })
            .collect()
    };
    let sdot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    for steps in [1usize, 5, 25] {
        let p = PoissonParams {
            max_iterations: steps,
            tolerance: 1e-30,
            ..params
        };
        let mut x = vec![0.0; n];
        let cg = level_cg(top, coarser, false, &b, &mut x, &p).unwrap();
        let (it, res) = (cg.iterations, cg.relative_residual);
        assert_eq!(it, steps);
        // Textbook PCG from the same start.
        let mut xr = vec![0.0; n];
        let mut r = b.clone();
        let mut z: Vec<f64> = r.iter().zip(&top.diag).map(|(r, d)| r / d).collect();
        let mut pv = z.clone();
        let mut rz = sdot(&r, &z);
        for _ in 0..steps {
            let q = apply(&pv);
            let alpha = rz / sdot(&pv, &q);
            for i in 0..n {
                xr[i] += alpha * pv[i];
                r[i] -= alpha * q[i];
            }
            z = r.iter().zip(&top.diag).map(|(r, d)| r / d).collect();
            let rz_new = sdot(&r, &z);
            let beta = rz_new / rz;
            rz = rz_new;
            for i in 0..n {
                pv[i] = z[i] + beta * pv[i];
            }
        }
        let res_ref = sdot(&r, &r).sqrt() / sdot(&b, &b).sqrt();
        assert!(
            (res - res_ref).abs() <= 1e-9 * res_ref,
            "{res} vs {res_ref}"
        );
        let scale = xr.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        let diff = x
            .iter()
            .zip(&xr)
            .fold(0.0f64, |a, (u, v)| a.max((u - v).abs()));
        assert!(diff <= 1e-9 * scale, "steps {steps}: {diff} of {scale}");
    }
}

#[test]
fn the_surface_does_not_depend_on_the_thread_count() {
    // The CG's sums are taken in a fixed order, so 1, 2 and 3 threads give the same mesh
    // bit for bit (rayon's `sum`, used before, added in an order that depends on how the
    // work was split), with either form of the screening.
    let samples = holed_sphere(20_000);
    for form in [ScreeningForm::Lumped, ScreeningForm::Consistent] {
        let params = PoissonParams::default()
            .with_depth(7)
            .with_screening_form(form);
        same_surface_on_any_thread_count(&samples, &params);
    }
}

fn same_surface_on_any_thread_count(samples: &[OrientedSample], params: &PoissonParams) {
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| screened_poisson(samples, params).unwrap())
    };
    let one = run(1);
    for threads in [2, 3] {
        let other = run(threads);
        assert_eq!(one.levels, other.levels, "{threads} threads");
        assert_eq!(one.iso_value.to_bits(), other.iso_value.to_bits());
        assert_eq!(one.mesh.faces, other.mesh.faces);
        assert!(one
            .mesh
            .vertices
            .iter()
            .zip(&other.mesh.vertices)
            .all(|(a, b)| a.to_array().map(f64::to_bits) == b.to_array().map(f64::to_bits)));
    }
}

#[test]
fn grid_kernel_areas_are_the_kd_trees() {
    // Dense and sparse patches (both of the grid's searches), a duplicated point, a
    // sample far from the others: the grid's neighbours give the kd-tree's areas, and both
    // the brute-force search's (up to the order of the sums).
    let rng = skin_core::random::SplitMix64::new(14);
    let u = rng.uniform(3 * 6000);
    let mut qs: Vec<DVec3> = (0..6000)
        .map(|i| {
            let (a, b, c) = (u[3 * i], u[3 * i + 1], u[3 * i + 2]);
            if i % 3 == 0 {
                // Sparse: a thin shell over the cube.
                DVec3::new(0.1 + 0.8 * a, 0.1 + 0.8 * b, 0.5 + 0.002 * c)
            } else {
                // Dense: a small wavy patch.
                let (x, y) = (0.4 + 0.05 * a, 0.4 + 0.05 * b);
                DVec3::new(x, y, 0.3 + 0.01 * (60.0 * x).sin() + 1e-4 * c)
            }
        })
        .collect();
    qs.extend([qs[7], qs[7], DVec3::splat(0.95)]);
    for depth in [6, 8, 9] {
        let grid = grid_kernel_areas(&qs, depth).unwrap();
        let tree = tree_kernel_areas(&qs, depth).unwrap();
        let r = DENSITY_RADIUS_CELLS / (1u64 << depth) as f64;
        for (i, (g, t)) in grid.iter().zip(&tree).enumerate() {
            // The reference: every sample's squared distance (brute force).
            let mut d2: Vec<f64> = qs.iter().map(|p| (*p - qs[i]).length_squared()).collect();
            let b = kernel_sum(&mut d2, r * r, DENSITY_NEIGHBOURS);
            assert!(
                (g - b).abs() <= 1e-12 * b,
                "depth {depth}, {i}: grid {g} vs {b}"
            );
            assert!(
                (t - b).abs() <= 1e-12 * b,
                "depth {depth}, {i}: tree {t} vs {b}"
            );
        }
    }
}

#[test]
fn kernel_areas_of_a_plane_match_its_density() {
    // A regular grid of samples on a tilted plane, 1 mm apart in unit-cube units: every
    // interior sample stands for 1 mm², whatever the plane's position in the grid.
    let (u, v) = (DVec3::new(1.0, 0.0, 0.3).normalize(), DVec3::Y);
    let qs: Vec<DVec3> = (0..200)
        .flat_map(|i| (0..200).map(move |j| (i, j)))
        .map(|(i, j)| DVec3::splat(0.3) + u * (i as f64 * 1e-3) + v * (j as f64 * 1e-3))
        .collect();
    let areas = kernel_areas(&qs, 8).unwrap();
    let inside = |q: &DVec3| {
        let d = *q - DVec3::splat(0.3);
        (0.03..0.17).contains(&d.dot(u)) && (0.03..0.17).contains(&d.dot(v))
    };
    let interior: Vec<f64> = qs
        .iter()
        .zip(&areas)
        .filter(|(q, _)| inside(q))
        .map(|(_, &a)| a / 1e-6)
        .collect();
    let (lo, hi) = interior
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(a, b), &x| (a.min(x), b.max(x)));
    assert!(lo > 0.97 && hi < 1.03, "{lo} .. {hi}");
    // The per-cell count (the baseline) spreads far more on the same samples.
    let fake: Vec<OrientedSample> = qs
        .iter()
        .map(|&q| OrientedSample {
            position: q,
            normal: u.cross(v),
            weight: 1.0,
        })
        .collect();
    let cells: Vec<f64> = cell_areas(&qs, &fake, 8)
        .into_iter()
        .zip(&qs)
        .filter(|(_, q)| inside(q))
        .map(|(a, _)| a / 1e-6)
        .collect();
    let spread = |a: &[f64]| {
        let m = skin_core::stats::mean(a);
        (a.iter().map(|x| (x - m).powi(2)).sum::<f64>() / a.len() as f64).sqrt() / m
    };
    assert!(
        spread(&cells) > 5.0 * spread(&interior),
        "{} vs {}",
        spread(&cells),
        spread(&interior)
    );
}

#[test]
fn cubic_edge_zero_finds_the_root() {
    // f(x) = x − 0.3 sampled at −1, 0, 1, 2: the cubic is the line.
    let t = crate::marching_cubes::tests_support::cubic_zero(-1.3, -0.3, 0.7, 1.7);
    assert!((t - 0.3).abs() < 1e-9, "{t}");
    // f(x) = tanh(2(x − 0.6)): closer to the true zero than linear interpolation.
    let f = |x: f64| (2.0 * (x - 0.6)).tanh();
    let t = crate::marching_cubes::tests_support::cubic_zero(f(-1.0), f(0.0), f(1.0), f(2.0));
    let linear = f(0.0) / (f(0.0) - f(1.0));
    assert!((t - 0.6).abs() < (linear - 0.6).abs(), "{t} vs {linear}");
}

#[test]
fn specks_are_dropped_and_kept_on_request() {
    // A large sphere and a far, tiny one (one sample cluster): the speck goes by default.
    let mut samples = holed_sphere(20_000);
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    let small = DVec3::new(0.3, 0.3, -0.3);
    samples.extend((0..300).map(|i| {
        let z = -1.0 + 2.0 * (i as f64 + 0.5) / 300.0;
        let rho = (1.0 - z * z).sqrt();
        let n = DVec3::new(
            rho * (golden * i as f64).cos(),
            rho * (golden * i as f64).sin(),
            z,
        );
        OrientedSample {
            position: small + n * 0.03,
            normal: n,
            weight: 1.0,
        }
    }));
    let p = PoissonParams::default().with_depth(6);
    let kept = screened_poisson(&samples, &p.with_min_component_fraction(0.0)).unwrap();
    let dropped = screened_poisson(&samples, &p.with_min_component_fraction(0.1)).unwrap();
    assert_eq!(kept.dropped_components, 0);
    assert_eq!(dropped.dropped_components, 1);
    assert!(kept
        .mesh
        .vertices
        .iter()
        .any(|v| (*v - small).length() < 0.05));
    assert!(dropped
        .mesh
        .vertices
        .iter()
        .all(|v| (*v - small).length() > 0.05));
    assert!(EdgeTopology::new(&dropped.mesh).unwrap().is_closed());
    assert!(screened_poisson(&samples, &p.with_min_component_fraction(1.5)).is_err());
}

#[test]
fn rejects_bad_samples() {
    let mut s = holed_sphere(100);
    let p = PoissonParams::default().with_depth(5);
    assert!(screened_poisson(&s[..3], &p).is_err());
    s[5].normal = DVec3::ZERO;
    assert!(screened_poisson(&s, &p).is_err());
    s[5].normal = DVec3::X;
    s[6].position.x = f64::NAN;
    assert!(matches!(
        screened_poisson(&s, &p),
        Err(Error::NonFinite { .. })
    ));
    s[6].position.x = 0.0;
    s[7].weight = 0.0;
    assert!(screened_poisson(&s, &p).is_err());
    s[7].weight = 1.0;
    assert!(screened_poisson(&s, &p.with_depth(12)).is_err());
    assert!(screened_poisson(&s, &p.with_screening(f64::NAN)).is_err());
}

#[test]
fn consistent_screening_is_the_point_values_quadratic_form() {
    // On a complete depth-3 level with random samples (several in some cells, none in
    // others) and random node values: `xᵀ S x` from the cells' diagonal and off-diagonal
    // parts is `α/h Σᵢ mᵢ χ(pᵢ)²` with `χ` trilinear, and `S` is symmetric.
    use super::screening::CellScreening;
    let depth = 3;
    let nb = (1i64 << depth) / B + 1;
    let level = Level::new(depth, &vec![true; (nb * nb * nb) as usize]);
    let nn = level.nodes.len();
    let random = skin_core::random::SplitMix64::new(7).uniform(4 * 300 + 2 * nn);
    let (coords, values) = random.split_at(4 * 300);
    let samples: Vec<UnitSample> = coords
        .chunks_exact(4)
        .enumerate()
        .map(|(k, u)| {
            // A third of the samples in one cell.
            let q = if k % 3 == 0 {
                DVec3::new(0.3 + 0.1 * u[0], 0.55 + 0.1 * u[1], 0.4 + 0.1 * u[2])
            } else {
                DVec3::new(u[0], u[1], u[2])
            };
            UnitSample {
                q,
                flux: DVec3::ZERO,
                mass: 0.5 + u[3],
                weight: 1.0,
            }
        })
        .collect();
    let alpha = 3.0;
    let points = samples.iter().map(|s| (s.q, s.mass));
    let screen = CellScreening::new(points, level.n, alpha, |p| level.index(p), nn);
    let apply = |x: &[f64]| -> Vec<f64> {
        let u = screen.products(x);
        (0..nn)
            .map(|i| screen.diagonal(i) * x[i] + screen.off_diagonal(i, &u))
            .collect()
    };
    let (x, y) = values.split_at(nn);
    let (sx, sy) = (apply(x), apply(y));
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(p, q)| p * q).sum::<f64>();
    let energy: f64 = samples
        .iter()
        .map(|s| {
            let (c, t) = cell_of(s.q, level.n);
            let chi: f64 = corners8()
                .map(|o| trilinear(t, o) * x[level.index(add(c, o, 1)).unwrap()])
                .sum();
            alpha * level.n as f64 * s.mass * chi * chi
        })
        .sum();
    let form = dot(x, &sx);
    assert!((form - energy).abs() < 1e-12 * energy, "{form} vs {energy}");
    let (xsy, ysx) = (dot(x, &sy), dot(y, &sx));
    assert!((xsy - ysx).abs() < 1e-12 * xsy.abs(), "{xsy} vs {ysx}");
}

#[test]
fn consistent_screening_pulls_to_the_samples_without_grid_artefacts() {
    // Workload 6b's recipe at depth 7 with Kazhdan's screening strength (his code scales
    // α = 4 by 2^depth): taken at the samples, the screening lowers the error where sampled
    // below the default's; lumped onto the nodes at the same strength, it raises it. The
    // complete levels' V-cycles converge (the l1-Jacobi smoother).
    let samples = random_holed_sphere(50_000);
    let alpha = 4.0 * 128.0;
    let run = |form: ScreeningForm, alpha: f64| {
        let params = PoissonParams::default()
            .with_depth(7)
            .with_screening(alpha)
            .with_screening_form(form);
        let s = screened_poisson(&samples, &params).unwrap();
        let complete_iterations = s
            .levels
            .iter()
            .filter(|l| l.depth <= params.dense_depth)
            .map(|l| l.iterations)
            .max()
            .unwrap();
        (error_where_sampled(&s.mesh), complete_iterations)
    };
    let (default, _) = run(ScreeningForm::Lumped, 4.0);
    let (lumped, _) = run(ScreeningForm::Lumped, alpha);
    let (consistent, iterations) = run(ScreeningForm::Consistent, alpha);
    assert!(consistent < 0.8 * default, "{consistent} vs {default}");
    assert!(lumped > default, "{lumped} vs {default}");
    // 14 with the plain diagonal as the smoother's.
    assert!(iterations <= 12, "{iterations} iterations");
}
