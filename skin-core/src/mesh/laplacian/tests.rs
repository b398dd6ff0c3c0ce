use super::*;
use crate::mesh::shapes;
use crate::random::SplitMix64;
use nalgebra::DMatrix;
use proptest::prelude::*;

fn dense(l: &CscMatrix<f64>) -> DMatrix<f64> {
    DMatrix::from(l)
}

/// Flat grid of k × k vertices in the plane z = 0 with jittered interior vertices.
fn flat_grid(k: u32, jitter: f64, seed: u64) -> TriMesh {
    let rng = SplitMix64::new(seed);
    let u = rng.uniform((2 * k * k) as usize);
    let mut vertices = Vec::new();
    for y in 0..k {
        for x in 0..k {
            let interior = x > 0 && y > 0 && x + 1 < k && y + 1 < k;
            let idx = (2 * (y * k + x)) as usize;
            let (dx, dy) = if interior {
                (jitter * (u[idx] - 0.5), jitter * (u[idx + 1] - 0.5))
            } else {
                (0.0, 0.0)
            };
            vertices.push(DVec3::new(x as f64 + dx, y as f64 + dy, 0.0));
        }
    }
    let mut faces = Vec::new();
    for y in 0..k - 1 {
        for x in 0..k - 1 {
            let a = y * k + x;
            faces.push([a, a + 1, a + k + 1]);
            faces.push([a, a + k + 1, a + k]);
        }
    }
    TriMesh::new(vertices, faces).unwrap()
}

#[test]
fn hand_computed_unit_square() {
    let m = TriMesh::new(
        vec![
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
        ],
        vec![[0, 1, 2], [0, 2, 3]],
    )
    .unwrap();
    let l = dense(&cotangent_laplacian(&m, &LaplacianParams::default()).unwrap());
    // Sides are opposite 45° angles (cot = 1): ½; the diagonal is opposite two right
    // angles: 0.
    let expect = DMatrix::from_row_slice(
        4,
        4,
        &[
            -1.0, 0.5, 0.0, 0.5, //
            0.5, -1.0, 0.5, 0.0, //
            0.0, 0.5, -1.0, 0.5, //
            0.5, 0.0, 0.5, -1.0,
        ],
    );
    assert!((&l - &expect).norm() < 1e-14, "{l}");
    let u = dense(&uniform_laplacian(&m).unwrap());
    assert_eq!(u[(0, 0)], -3.0);
    assert_eq!(u[(0, 2)], 1.0);
    assert_eq!(u[(1, 3)], 0.0);
    assert_eq!(u[(1, 1)], -2.0);
    for kind in [MassKind::Barycentric, MassKind::Voronoi] {
        let mm = mass_matrix(&m, kind, &LaplacianParams::default()).unwrap();
        assert!((mm.sum() - 1.0).abs() < 1e-14);
    }
    // Right triangles are not obtuse; the circumcentre is the hypotenuse midpoint, so the
    // corner shares are ½, ¼, ¼ of the area ½: vertex 1 (right angle of face 0 only) gets
    // ¼, vertex 0 (45° in both faces) gets ⅛ + ⅛.
    let mv = mass_matrix(&m, MassKind::Voronoi, &LaplacianParams::default()).unwrap();
    assert!((mv[1] - 0.25).abs() < 1e-14);
    assert!((mv[0] - 0.25).abs() < 1e-14);
}

#[test]
fn equilateral_triangle() {
    let m = TriMesh::new(
        vec![
            DVec3::ZERO,
            DVec3::X,
            DVec3::new(0.5, 3f64.sqrt() / 2.0, 0.0),
        ],
        vec![[0, 1, 2]],
    )
    .unwrap();
    let l = dense(&cotangent_laplacian(&m, &LaplacianParams::default()).unwrap());
    let w = 0.5 / 3f64.sqrt(); // ½ cot 60°
    assert!((l[(0, 1)] - w).abs() < 1e-15);
    assert!((l[(2, 2)] + 2.0 * w).abs() < 1e-15);
    let mv = mass_matrix(&m, MassKind::Voronoi, &LaplacianParams::default()).unwrap();
    let area = 3f64.sqrt() / 4.0;
    assert!((mv[0] - area / 3.0).abs() < 1e-15);
}

#[test]
fn linear_precision_on_flat_mesh() {
    let m = flat_grid(7, 0.4, 9);
    let l = cotangent_laplacian(&m, &LaplacianParams::default()).unwrap();
    let f = DMatrix::from_fn(m.vertices.len(), 1, |i, _| {
        let p = m.vertices[i];
        2.0 * p.x - 3.0 * p.y + 0.5
    });
    let lf = &l * &f;
    for y in 1..6 {
        for x in 1..6 {
            assert!(lf[(y * 7 + x, 0)].abs() < 1e-12);
        }
    }
    // The uniform Laplacian has no linear precision on the jittered grid (sanity check
    // that the test can fail).
    let u = uniform_laplacian(&m).unwrap();
    let uf = &u * &f;
    assert!((1..6).any(|y| (1..6).any(|x| uf[(y * 7 + x, 0)].abs() > 1e-3)));
}

#[test]
fn mean_curvature_on_sphere() {
    // On the unit sphere, L V ≈ −2 H n A_i with H = 1 and n = V: (L V)_i / M_ii ≈ −2 V_i.
    let m = shapes::icosphere(4).unwrap();
    let l = cotangent_laplacian(&m, &LaplacianParams::default()).unwrap();
    let mass = mass_matrix(&m, MassKind::Voronoi, &LaplacianParams::default()).unwrap();
    let v = DMatrix::from_fn(m.vertices.len(), 3, |i, c| m.vertices[i][c]);
    let lv = &l * &v;
    for i in (0..m.vertices.len()).step_by(97) {
        for c in 0..3 {
            assert!((lv[(i, c)] / mass[i] + 2.0 * v[(i, c)]).abs() < 2e-2);
        }
    }
    let total: f64 = mass.sum();
    assert!((total - 4.0 * std::f64::consts::PI).abs() < 0.05);
}

#[test]
fn degenerate_faces_and_bad_input() {
    let mut m = flat_grid(3, 0.0, 1);
    // Collapse a triangle: vertex 4 (centre) onto vertex 0... use a repeated index face.
    m.faces.push([0, 1, 1]);
    m.vertices.push(DVec3::new(0.5, 0.0, 0.0));
    m.faces.push([0, 1, 9]); // collinear corners
    let strict = LaplacianParams {
        degenerate_faces: DegenerateFaces::Error,
        ..Default::default()
    };
    assert!(matches!(
        cotangent_laplacian(&m, &strict),
        Err(Error::Degenerate { .. })
    ));
    let l = cotangent_laplacian(&m, &LaplacianParams::default()).unwrap();
    assert!(l.values().iter().all(|v| v.is_finite()));
    assert!(matches!(
        uniform_laplacian(&m),
        Err(Error::Degenerate { .. })
    ));
    let empty = TriMesh::default();
    assert!(matches!(
        cotangent_laplacian(&empty, &LaplacianParams::default()),
        Err(Error::Empty { .. })
    ));
    let mut nan = flat_grid(3, 0.0, 1);
    nan.vertices[0].x = f64::NAN;
    assert!(matches!(
        cotangent_laplacian(&nan, &LaplacianParams::default()),
        Err(Error::NonFinite { .. })
    ));
    let mut bad = flat_grid(3, 0.0, 1);
    bad.faces[0][0] = 99;
    assert!(matches!(
        uniform_laplacian(&bad),
        Err(Error::IndexOutOfRange { .. })
    ));
    let neg = LaplacianParams {
        degenerate_tol: -1.0,
        ..Default::default()
    };
    assert!(cotangent_laplacian(&flat_grid(3, 0.0, 1), &neg).is_err());
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(16))]
    /// Symmetry, zero row sums and negative semi-definiteness on random blobs.
    #[test]
    fn invariants(seed in 0u64..10_000, level in 0u32..3) {
        let mut m = shapes::peer_blob(level).unwrap();
        let u = SplitMix64::new(seed).normal(3 * m.vertices.len());
        for (i, v) in m.vertices.iter_mut().enumerate() {
            *v += 0.05 * DVec3::new(u[3 * i], u[3 * i + 1], u[3 * i + 2]);
        }
        for l in [
            cotangent_laplacian(&m, &LaplacianParams::default()).unwrap(),
            uniform_laplacian(&m).unwrap(),
        ] {
            let d = dense(&l);
            prop_assert!((&d - d.transpose()).norm() < 1e-12 * d.norm());
            let ones = DMatrix::from_element(d.nrows(), 1, 1.0);
            prop_assert!((&d * ones).norm() < 1e-12 * d.norm());
            let x = DMatrix::from_fn(d.nrows(), 1, |i, _| u[i]);
            // Negative semi-definite: xᵀ L x ≤ 0 (cotangent weights can be negative for
            // obtuse pairs, but the closed-mesh energy stays non-positive).
            prop_assert!((x.transpose() * &d * &x)[(0, 0)] <= 1e-12 * d.norm());
        }
    }
}
