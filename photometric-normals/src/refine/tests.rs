use super::*;

const N: usize = 41;
const SPACING: f64 = 0.025;

/// The true height: a broad bump with a 20 cm ripple of 3 mm on it.
fn bump(x: f64, y: f64) -> f64 {
    0.05 * (-((x - 0.5).powi(2) + (y - 0.5).powi(2)) / 0.1).exp()
}
fn ripple(x: f64, y: f64) -> f64 {
    let k = std::f64::consts::TAU / 0.2;
    0.003 * (k * x).sin() * (k * y).sin()
}
fn truth(x: f64, y: f64) -> f64 {
    bump(x, y) + ripple(x, y)
}
/// The true surface's unit normal (upward) from the analytic gradient.
fn truth_normal(x: f64, y: f64) -> DVec3 {
    let h = 1e-6;
    let gx = (truth(x + h, y) - truth(x - h, y)) / (2.0 * h);
    let gy = (truth(x, y + h) - truth(x, y - h)) / (2.0 * h);
    DVec3::new(-gx, -gy, 1.0).normalize()
}

/// A grid mesh over [0, 1]² with heights `z(x, y)`, faces counter-clockwise from above.
fn grid(z: impl Fn(f64, f64) -> f64) -> TriMesh {
    let mut vertices = Vec::new();
    for j in 0..N {
        for i in 0..N {
            let (x, y) = (i as f64 * SPACING, j as f64 * SPACING);
            vertices.push(DVec3::new(x, y, z(x, y)));
        }
    }
    let mut faces = Vec::new();
    for j in 0..N - 1 {
        for i in 0..N - 1 {
            let v = (j * N + i) as u32;
            let n = N as u32;
            faces.push([v, v + 1, v + n + 1]);
            faces.push([v, v + n + 1, v + n]);
        }
    }
    TriMesh::new(vertices, faces).unwrap()
}

/// The true surface's normal at each vertex of `mesh` (every vertex targeted).
fn exact_targets(mesh: &TriMesh) -> Vec<Option<DVec3>> {
    mesh.vertices
        .iter()
        .map(|p| Some(truth_normal(p.x, p.y)))
        .collect()
}

/// RMS vertical distance of the mesh's vertices to the true surface, mm.
fn rms_to_truth_mm(mesh: &TriMesh) -> f64 {
    let s: f64 = mesh
        .vertices
        .iter()
        .map(|p| (p.z - truth(p.x, p.y)).powi(2))
        .sum();
    1e3 * (s / mesh.vertices.len() as f64).sqrt()
}

#[test]
fn exact_normals_restore_a_ripple_that_the_positions_lost() {
    // Input: the positions without the ripple (the smooth low frequencies), 1.5 mm RMS
    // off the truth; the exact normals of the true surface at each input vertex.
    let input = grid(bump);
    let targets = exact_targets(&input);
    let before = rms_to_truth_mm(&input);
    let refined = refine_with_normals(&input, &targets, 0.1).unwrap();
    let after = rms_to_truth_mm(&refined.mesh);
    println!("ripple: input {before:.3} mm, refined {after:.3} mm RMS");
    assert!(
        before > 1.4,
        "the input must be off the truth ({before:.3} mm)"
    );
    // The baseline (the input) could win: the refinement must bring the vertices at
    // least 4× closer to the true surface.
    assert!(
        after < before / 4.0,
        "refined {after:.3} mm vs input {before:.3} mm"
    );
    assert_eq!(refined.report.targeted, N * N);
    assert_eq!(refined.report.faces, 2 * (N - 1) * (N - 1));
}

#[test]
fn vertices_without_a_target_stay_and_the_others_still_improve() {
    let input = grid(bump);
    // Targets only on the left half.
    let targets: Vec<Option<DVec3>> = input
        .vertices
        .iter()
        .map(|p| (p.x < 0.5).then(|| truth_normal(p.x, p.y)))
        .collect();
    let refined = refine_with_normals(&input, &targets, 0.1).unwrap();
    for ((a, b), t) in input
        .vertices
        .iter()
        .zip(&refined.mesh.vertices)
        .zip(&targets)
    {
        if t.is_none() {
            assert_eq!(a, b);
        }
    }
    let err = |m: &TriMesh| {
        let v: Vec<f64> = m
            .vertices
            .iter()
            .filter(|p| p.x < 0.45)
            .map(|p| (p.z - truth(p.x, p.y)).powi(2))
            .collect();
        (v.iter().sum::<f64>() / v.len() as f64).sqrt()
    };
    assert!(err(&refined.mesh) < err(&input) / 3.0);
}

#[test]
fn lambda_one_leaves_the_mesh_unchanged() {
    let input = grid(bump);
    let targets = exact_targets(&input);
    let refined = refine_with_normals(&input, &targets, 1.0).unwrap();
    assert_eq!(refined.mesh.vertices, input.vertices);
    assert_eq!(refined.mesh.faces, input.faces);
    // And a λ below 1 does move it (the solve is not a no-op).
    let moved = refine_with_normals(&input, &targets, 0.5).unwrap();
    assert!(moved.report.max_move_mm > 0.1);
}

/// A marching-cubes mesh (2 mm voxels, as the merge's) of a 10 cm sphere whose radius
/// carries a low-frequency error of up to 2 mm.
fn mc_sphere(noise_m: f64) -> TriMesh {
    let voxel = 0.002;
    // A deterministic pseudo-random value in [-1, 1] per grid node.
    let hash = |p: [i64; 3]| {
        let mut h = (p[0].wrapping_mul(73_856_093)
            ^ p[1].wrapping_mul(19_349_663)
            ^ p[2].wrapping_mul(83_492_791)) as u64;
        h ^= h >> 33;
        h = h.wrapping_mul(0xff51_afd7_ed55_8ccd);
        h ^= h >> 33;
        (h % 20_001) as f64 / 10_000.0 - 1.0
    };
    let r = 0.1;
    let wrong = |q: DVec3| 0.002 * (3.0 * q.x / r).sin() * (2.0 * q.z / r).cos();
    let n = (1.2 * r / voxel) as i64;
    let pos = |p: [i64; 3]| DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64) * voxel;
    let value = |p: [i64; 3]| {
        let q = pos(p);
        Some(q.length() - r - wrong(q) + noise_m * hash(p))
    };
    let mut cells = Vec::new();
    for k in -n..n {
        for j in -n..n {
            for i in -n..n {
                let c = pos([i, j, k]) + DVec3::splat(0.5 * voxel);
                if (c.length() - r).abs() < 3.0 * voxel {
                    cells.push([i, j, k]);
                }
            }
        }
    }
    crate::marching_cubes::march_cells(cells, value, 0.0, pos).unwrap()
}

/// Mean angle between neighbouring vertex normals and mean angle of the vertex normals to
/// the true sphere's, degrees.
fn roughness(mesh: &TriMesh) -> (f64, f64) {
    let normals = vertex_normals(mesh, NormalWeighting::Area).unwrap();
    let edges = unique_edges(mesh).unwrap();
    let ang = |a: DVec3, b: DVec3| {
        a.normalize()
            .dot(b.normalize())
            .clamp(-1.0, 1.0)
            .acos()
            .to_degrees()
    };
    let local = edges
        .iter()
        .map(|&[a, b]| ang(normals[a as usize], normals[b as usize]))
        .sum::<f64>()
        / edges.len() as f64;
    let dev = mesh
        .vertices
        .iter()
        .zip(&normals)
        .map(|(p, n)| ang(*p, *n))
        .sum::<f64>()
        / mesh.vertices.len() as f64;
    (local, dev)
}

#[test]
fn non_integrable_targets_roughen_the_mesh_unless_corrected() {
    // Smooth targets that no surface has: the sphere's normals rotated by 10° about one
    // axis (a bias like a view's calibration error). Without Nehab's first step the
    // irregular marching-cubes mesh absorbs the misfit as vertex-scale roughness.
    let rot = skin_core::math::DQuat::from_axis_angle(
        DVec3::new(1.0, 2.0, 0.5).normalize(),
        10f64.to_radians(),
    );
    let mesh = mc_sphere(0.0);
    let targets: Vec<Option<DVec3>> = mesh
        .vertices
        .iter()
        .map(|p| Some(rot * p.normalize()))
        .collect();
    let (l0, _) = roughness(&mesh);
    let plain = refine_with_normals(&mesh, &targets, 0.1).unwrap();
    let (l_plain, _) = roughness(&plain.mesh);
    let mut corrected = targets.clone();
    correct_low_frequencies(&mesh, &unique_edges(&mesh).unwrap(), &mut corrected, 8).unwrap();
    let fixed = refine_with_normals(&mesh, &corrected, 0.1).unwrap();
    let (l_fixed, d_fixed) = roughness(&fixed.mesh);
    println!(
        "tilted targets: neighbour angle input {l0:.3}°, plain {l_plain:.3}°, corrected \
         {l_fixed:.3}° (true dev {d_fixed:.3}°)"
    );
    // The old behaviour roughens the mesh (measured 1.08° → 2.29°); the corrected
    // targets must leave it within 0.15° of the input.
    assert!(l_plain > l0 + 0.5, "plain {l_plain:.3} vs input {l0:.3}");
    assert!(
        l_fixed < l0 + 0.15,
        "corrected {l_fixed:.3} vs input {l0:.3}"
    );

    // The correction keeps the targets' high frequencies: exact targets still remove
    // vertex-scale noise of the positions (0.3 mm on the distance field).
    let noisy = mc_sphere(0.0003);
    let mut exact: Vec<Option<DVec3>> =
        noisy.vertices.iter().map(|p| Some(p.normalize())).collect();
    correct_low_frequencies(&noisy, &unique_edges(&noisy).unwrap(), &mut exact, 8).unwrap();
    let (l_noisy, d_noisy) = roughness(&noisy);
    let (l_after, d_after) = roughness(&refine_with_normals(&noisy, &exact, 0.1).unwrap().mesh);
    println!(
        "noisy positions: neighbour angle {l_noisy:.3}° → {l_after:.3}°, true dev \
         {d_noisy:.3}° → {d_after:.3}°"
    );
    assert!(l_after < l_noisy / 2.0 && d_after < d_noisy / 2.0);
}

#[test]
fn bad_input_is_a_clear_error() {
    let input = grid(bump);
    let mut targets: Vec<Option<DVec3>> = vec![Some(DVec3::Z); input.vertices.len()];
    targets[7] = Some(DVec3::new(f64::NAN, 0.0, 1.0));
    assert!(matches!(
        refine_with_normals(&input, &targets, 0.1),
        Err(Error::NonFinite { .. })
    ));
    targets[7] = Some(DVec3::new(0.0, 0.0, 2.0));
    assert!(matches!(
        refine_with_normals(&input, &targets, 0.1),
        Err(Error::InvalidParam { .. })
    ));
    let good = vec![Some(DVec3::Z); input.vertices.len()];
    for lambda in [0.0, -0.1, 1.5, f64::NAN] {
        assert!(matches!(
            refine_with_normals(&input, &good, lambda),
            Err(Error::InvalidParam { .. })
        ));
    }
    assert!(matches!(
        refine_with_normals(&input, &good[1..], 0.1),
        Err(Error::Core(skin_core::Error::SizeMismatch { .. }))
    ));
    let empty = TriMesh::new(Vec::new(), Vec::new()).unwrap();
    assert!(matches!(
        refine_with_normals(&empty, &[], 0.1),
        Err(Error::Empty { .. })
    ));
    // No views: no camera to take a target normal from.
    assert!(matches!(
        refine_mesh(&[], &[], &[], &[], &input, &RefineParams::default()),
        Err(Error::Empty { .. })
    ));
    assert!(matches!(
        refine_mesh(&[], &[], &[], &[], &empty, &RefineParams::default()),
        Err(Error::Empty { .. })
    ));
}

#[test]
fn averaging_gathers_the_sums_a_scatter_over_the_edges_gives() {
    // The reference: each edge adds both ends' values to each other, in the sorted edges'
    // order. The gather must give the same field, bit for bit, with holes in it.
    let mesh = mc_sphere(0.002);
    let edges = unique_edges(&mesh).unwrap();
    let mut field: Vec<Option<DVec3>> = mesh
        .vertices
        .iter()
        .enumerate()
        .map(|(i, p)| (i % 7 != 3).then(|| (*p + DVec3::new(0.01, 0.0, 0.0)).normalize()))
        .collect();
    let mut reference = field.clone();
    for _ in 0..3 {
        let mut acc: Vec<DVec3> = reference.iter().map(|t| t.unwrap_or(DVec3::ZERO)).collect();
        for &[a, b] in &edges {
            let (a, b) = (a as usize, b as usize);
            if let (Some(ta), Some(tb)) = (reference[a], reference[b]) {
                acc[a] += tb;
                acc[b] += ta;
            }
        }
        for (t, a) in reference.iter_mut().zip(acc) {
            if t.is_some() {
                *t = a.try_normalize();
            }
        }
    }
    average_rounds(&edges, &mut field, 3);
    assert!(field.iter().filter(|t| t.is_none()).count() > 100);
    assert_eq!(field, reference);
}
