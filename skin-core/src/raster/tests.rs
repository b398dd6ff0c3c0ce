//! Tests of the rasteriser against a brute-force f64 ray caster built on [`Camera::ray`].

use super::*;
use crate::camera::{Intrinsics, RadialDistortion};
use crate::math::{DVec2, DVec3};

/// A closed UV sphere, counter-clockwise seen from outside ([`crate::mesh::shapes::uv_sphere`]).
pub(crate) fn uv_sphere(centre: DVec3, radius: f64, n_lat: usize, n_lon: usize) -> TriMesh {
    crate::mesh::shapes::uv_sphere(centre, radius, n_lat, n_lon).unwrap()
}

/// Nearest hit `(t, face, front_facing)` of a ray with any face (both sides), f64.
pub(crate) fn brute_hit(mesh: &TriMesh, o: DVec3, d: DVec3) -> Option<(f64, usize, bool)> {
    let mut best: Option<(f64, usize, bool)> = None;
    for f in 0..mesh.face_count() {
        let [a, b, c] = mesh.triangle(f);
        let (e1, e2) = (b - a, c - a);
        let p = d.cross(e2);
        let det = e1.dot(p);
        if det.abs() < 1e-300 {
            continue;
        }
        let s = o - a;
        let u = s.dot(p) / det;
        let q = s.cross(e1);
        let v = d.dot(q) / det;
        let t = e2.dot(q) / det;
        if u >= 0.0 && v >= 0.0 && u + v <= 1.0 && t > 0.0 && best.is_none_or(|h| t < h.0) {
            best = Some((t, f, e1.cross(e2).dot(d) < 0.0));
        }
    }
    best
}

fn camera(w: u32, h: u32, eye: DVec3, k1: f64) -> Camera {
    let k = Intrinsics::new(
        0.9 * w as f64,
        0.92 * w as f64,
        0.5 * w as f64 + 1.3,
        0.5 * h as f64 - 0.7,
        w,
        h,
    )
    .unwrap();
    Camera::look_at(k, eye, DVec3::new(0.05, -0.03, 0.0), DVec3::Y)
        .unwrap()
        .with_distortion(RadialDistortion::new(
            k1,
            DVec2::new(0.47 * w as f64, 0.53 * h as f64),
        ))
}

/// Reference mask, boundary stability and nearest hit `(t, face)` per pixel.
type Reference = (Vec<u8>, Vec<bool>, Vec<Option<(f64, usize)>>);

/// Reference mask of the brute-force ray caster and, per pixel, whether it is stable under
/// perturbing the pixel by `eps` px in each axis direction.
fn reference(cam: &Camera, mesh: &TriMesh, eps: f64) -> Reference {
    let (w, h) = (cam.intrinsics.width, cam.intrinsics.height);
    let mut mask = Vec::new();
    let mut stable = Vec::new();
    let mut hits = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let px = DVec2::new(x as f64, y as f64);
            let hit_at = |p: DVec2| {
                cam.ray(p)
                    .ok()
                    .and_then(|r| brute_hit(mesh, r.origin, r.direction))
            };
            let h0 = hit_at(px);
            let m = h0.is_some();
            let st = [DVec2::X, DVec2::NEG_X, DVec2::Y, DVec2::NEG_Y]
                .iter()
                .all(|&o| hit_at(px + o * eps).is_some() == m);
            mask.push(m as u8);
            stable.push(st);
            hits.push(h0.map(|(t, f, _)| (t, f)));
        }
    }
    (mask, stable, hits)
}

#[test]
fn silhouette_and_depth_match_ray_casting_under_distortion() {
    let mesh = uv_sphere(DVec3::new(0.1, 0.0, 0.2), 0.6, 12, 16);
    for k1 in [0.0, -0.25, 0.3] {
        let cam = camera(48, 40, DVec3::new(0.4, 0.6, -2.2), k1);
        let view = Rasterizer::new(&cam)
            .render(&mesh, &RenderParams::default().with_buffers(Buffers::ALL))
            .unwrap();
        let (mask, stable, hits) = reference(&cam, &mesh, 1e-3);
        let mut mismatched = 0;
        for i in 0..mask.len() {
            if mask[i] != view.mask[i] {
                // Only rays passing within 1e-3 px of a silhouette edge may disagree.
                assert!(
                    !stable[i],
                    "k1 {k1}: pixel {i} differs away from the boundary"
                );
                mismatched += 1;
            }
            if let (Some((t, f)), 1) = (hits[i], view.mask[i]) {
                assert!(
                    (view.depth_m[i] as f64 - t).abs() < 2e-6 * t,
                    "depth {} vs {t}",
                    view.depth_m[i]
                );
                let _ = f;
            }
        }
        assert!(mismatched <= 1, "k1 {k1}: {mismatched} mismatched pixels");
        assert!(view.covered_pixels > 200);
    }
}

#[test]
fn large_triangle_edges_curve_exactly_under_distortion() {
    // One big quad filling most of a strongly distorted view: rasterising straight edges
    // between distorted corners would miss or add whole pixel rows.
    let mesh = TriMesh::new(
        vec![
            DVec3::new(-1.0, -0.8, 0.0),
            DVec3::new(-1.0, 0.8, 0.0),
            DVec3::new(1.0, 0.8, 0.0),
            DVec3::new(1.0, -0.8, 0.0),
        ],
        vec![[0, 1, 2], [0, 2, 3]],
    )
    .unwrap();
    let cam = camera(40, 30, DVec3::new(0.0, 0.0, -2.0), -0.3);
    let view = Rasterizer::new(&cam)
        .render(
            &mesh,
            &RenderParams::default().with_buffers(Buffers::MASK_ONLY),
        )
        .unwrap();
    let (mask, stable, _) = reference(&cam, &mesh, 1e-3);
    for i in 0..mask.len() {
        assert!(mask[i] == view.mask[i] || !stable[i], "pixel {i}");
    }
    // The distorted edges really are curved here: straight lines through the corner pixels
    // would disagree with the reference somewhere.
    let corner = |p: DVec3| cam.project(p).unwrap();
    let (a, b) = (corner(mesh.vertices[0]), corner(mesh.vertices[1]));
    let mid = cam
        .project((mesh.vertices[0] + mesh.vertices[1]) * 0.5)
        .unwrap();
    let chord = (a + b) * 0.5;
    assert!(
        (mid - chord).length() > 0.5,
        "test geometry is not distorted enough"
    );
}

#[test]
fn closed_mesh_has_no_cracks_and_split_quad_is_exact_union() {
    // Camera inside a closed sphere sees its inside everywhere: any crack is an empty pixel.
    let mesh = uv_sphere(DVec3::ZERO, 2.0, 9, 13);
    let cam = camera(64, 48, DVec3::new(0.1, 0.05, -0.2), 0.0);
    let params = RenderParams::default()
        .with_cull_back_faces(false)
        .with_buffers(Buffers::ALL);
    let view = Rasterizer::new(&cam).render(&mesh, &params).unwrap();
    assert_eq!(view.covered_pixels, 64 * 48);
    assert!(
        view.normal_camera.iter().all(|n| n[2] > 0.0),
        "inside faces face away"
    );
    // A quad whose diagonal and corners pass exactly through pixel centres (ties everywhere).
    // Dyadic focal length, centre and coordinates keep every edge value exact in f32.
    let k = Intrinsics::new(8.0, 8.0, 8.0, 8.0, 17, 17).unwrap();
    let cam = Camera::look_at(k, DVec3::new(0.0, 0.0, -1.0), DVec3::ZERO, DVec3::NEG_Y).unwrap();
    // Camera x = world x, camera y = world y with up = -Y; pixel = 8·(x, y) + 8.
    let p = |u: f64, v: f64| DVec3::new((u - 8.0) / 8.0, (v - 8.0) / 8.0, 0.0);
    let verts = vec![
        p(2.0, 2.0),
        p(14.0, 2.0),
        p(14.0, 14.0),
        p(2.0, 14.0),
        p(8.0, 8.0),
    ];
    let fans = [[0u32, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]];
    let render = |faces: Vec<[u32; 3]>| {
        Rasterizer::new(&cam)
            .render(
                &TriMesh::new(verts.clone(), faces).unwrap(),
                &RenderParams::default()
                    .with_cull_back_faces(false)
                    .with_allow_empty(true)
                    .with_buffers(Buffers::MASK_ONLY),
            )
            .unwrap()
            .mask
    };
    let whole = render(fans.to_vec());
    let mut count = vec![0u8; whole.len()];
    for f in fans {
        for (c, m) in count.iter_mut().zip(render(vec![f])) {
            *c += m;
        }
    }
    for (i, (&c, &m)) in count.iter().zip(&whole).enumerate() {
        assert!(c <= 1, "pixel {i} covered {c} times");
        assert_eq!(c, m, "pixel {i}");
    }
    // The closed square [2, 14]² has 13² pixel centres; the top-left rule keeps one row and
    // one column of its boundary.
    assert_eq!(whole.iter().map(|&m| m as usize).sum::<usize>(), 12 * 12);
}

#[test]
fn identical_for_one_and_two_threads() {
    let mesh = uv_sphere(DVec3::ZERO, 0.7, 20, 30);
    let cam = camera(120, 90, DVec3::new(0.3, 0.4, -2.5), -0.15);
    let ras = Rasterizer::new(&cam);
    let params = RenderParams::default().with_buffers(Buffers::ALL);
    let run = |t: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(t)
            .build()
            .unwrap()
            .install(|| ras.render(&mesh, &params).unwrap())
    };
    let (a, b) = (run(1), run(2));
    assert!(a.covered_pixels > 1000);
    assert_eq!(a, b);
}

/// The parallel binning against a serial counting sort: more faces than one binning task
/// takes, some without a set-up, each band's faces in face order.
#[test]
fn bins_hold_each_bands_faces_in_face_order() {
    use super::render::{bin_triangles, BAND_ROWS};
    use super::setup::TriSetup;
    let n_bands = 37;
    let rng = crate::random::SplitMix64::new(7);
    let tris: Vec<Option<TriSetup>> = (0..200_000u64)
        .map(|i| {
            let y0 = (rng.uniform_at(3 * i) * (n_bands * BAND_ROWS) as f64) as u32;
            let y1 = (y0 + (rng.uniform_at(3 * i + 1) * 3.0 * BAND_ROWS as f64) as u32)
                .min((n_bands * BAND_ROWS - 1) as u32);
            (rng.uniform_at(3 * i + 2) > 0.2).then_some(TriSetup {
                e: [[0.0; 3]; 3],
                top_left: [false; 3],
                w: [0.0; 3],
                x0: 0,
                x1: 0,
                y0,
                y1,
            })
        })
        .collect();
    let bins = bin_triangles(&tris, n_bands);
    let mut start = vec![0];
    let mut order = Vec::new();
    for b in 0..n_bands {
        for (f, t) in tris.iter().enumerate() {
            if let Some(t) = t {
                if (t.y0 as usize / BAND_ROWS..=t.y1 as usize / BAND_ROWS).contains(&b) {
                    order.push(f as u32);
                }
            }
        }
        start.push(order.len());
    }
    assert!(order.len() > tris.len());
    assert_eq!(bins.start, start);
    assert_eq!(bins.order, order);
}

#[test]
fn sphere_normals_depth_and_barycentrics_are_analytic() {
    let c = DVec3::new(0.0, 0.1, 0.0);
    let r = 0.5;
    let mesh = uv_sphere(c, r, 60, 90);
    let cam = camera(80, 60, DVec3::new(0.0, 0.3, -2.0), 0.1);
    let ras = Rasterizer::new(&cam);
    let all = RenderParams::default().with_buffers(Buffers::ALL);
    let smooth = ras.render(&mesh, &all).unwrap();
    let flat = ras
        .render(&mesh, &all.with_normals(NormalMode::Flat))
        .unwrap();
    let rot = cam.world_from_camera();
    let (mut worst_smooth, mut worst_flat) = (0.0f64, 0.0f64);
    for y in 0..60 {
        for x in 0..80 {
            let i = smooth.index(x, y);
            if smooth.mask[i] == 0 {
                continue;
            }
            let ray = cam.ray(DVec2::new(x as f64, y as f64)).unwrap();
            let p = ray.at(smooth.depth_m[i] as f64);
            // Surface point from triangle + barycentrics equals the point along the ray.
            let [a, b, cc] = mesh.triangle(smooth.triangle[i] as usize);
            let [l1, l2] = smooth.bary[i].map(f64::from);
            let q = a * (1.0 - l1 - l2) + b * l1 + cc * l2;
            assert!((p - q).length() < 2e-6, "{p} vs {q}");
            // Camera z and distance along the ray agree.
            let z = cam.camera_from_world().transform_point3(p).z;
            assert!((z - smooth.camera_z_m[i] as f64).abs() < 1e-5);
            // Analytic sphere normal at the hit (inscribed mesh: the point is slightly inside).
            let n_true = (p - c).normalize();
            let ang = |n: [f32; 3]| {
                let n = rot.transform_vector3(DVec3::from(n.map(f64::from)));
                n.dot(n_true).clamp(-1.0, 1.0).acos().to_degrees()
            };
            worst_smooth = worst_smooth.max(ang(smooth.normal_camera[i]));
            worst_flat = worst_flat.max(ang(flat.normal_camera[i]));
            assert!((p - c).length() < r + 1e-6 && (p - c).length() > r * 0.998);
        }
    }
    assert!(
        worst_smooth < 0.3,
        "smooth normals off by {worst_smooth} deg"
    );
    assert!(
        worst_flat < 3.0 && worst_flat > worst_smooth,
        "flat {worst_flat}"
    );
}

#[test]
fn mask_only_fast_path_equals_full_mask_and_culling_is_exact_for_closed_meshes() {
    let mesh = uv_sphere(DVec3::ZERO, 0.6, 16, 24);
    let cam = camera(70, 50, DVec3::new(0.5, 0.2, -2.0), -0.1);
    let ras = Rasterizer::new(&cam);
    let full = ras.render(&mesh, &RenderParams::default()).unwrap();
    let fast = ras
        .render(
            &mesh,
            &RenderParams::default().with_buffers(Buffers::MASK_ONLY),
        )
        .unwrap();
    let no_cull = ras
        .render(&mesh, &RenderParams::default().with_cull_back_faces(false))
        .unwrap();
    assert_eq!(full.mask, fast.mask);
    assert_eq!(full, no_cull);
    assert!(fast.depth_m.is_empty() && fast.normal_camera.is_empty());
    assert_eq!(full.depth_image().unwrap().dimensions(), (70, 50));
    assert_eq!(full.normal_image().unwrap().dimensions(), (70, 50));
    assert!(fast.depth_image().is_err() && fast.normal_image().is_err());
    let sil = full.silhouette();
    assert_eq!(sil.dimensions(), (70, 50));
    assert_eq!(sil.count(), full.covered_pixels);
    for (k, &m) in full.mask.iter().enumerate() {
        assert_eq!(sil.get((k % 70) as u32, (k / 70) as u32), m != 0);
    }
    assert_eq!(
        fast.silhouette(),
        sil,
        "the mask-only path gives the same silhouette"
    );
    // Reusing a view for another mesh overwrites every pixel.
    let mut reused = full.clone();
    let moved = uv_sphere(DVec3::new(0.3, 0.0, 0.0), 0.3, 16, 24);
    ras.render_into(&moved, &RenderParams::default(), &mut reused)
        .unwrap();
    assert_eq!(
        reused,
        ras.render(&moved, &RenderParams::default()).unwrap()
    );
}

#[test]
fn mesh_crossing_the_camera_plane_matches_ray_casting() {
    // A long strip passing beside and behind the camera: corners behind the camera take the
    // exact whole-image path.
    let mesh = TriMesh::new(
        vec![
            DVec3::new(-0.4, -0.3, -3.0),
            DVec3::new(-0.4, 0.3, -3.0),
            DVec3::new(-0.2, 0.3, 2.0),
            DVec3::new(-0.2, -0.3, 2.0),
        ],
        vec![[0, 1, 2], [0, 2, 3]],
    )
    .unwrap();
    let cam = camera(40, 30, DVec3::new(0.0, 0.0, -1.0), 0.0);
    let view = Rasterizer::new(&cam)
        .render(
            &mesh,
            &RenderParams::default()
                .with_cull_back_faces(false)
                .with_buffers(Buffers::ALL),
        )
        .unwrap();
    let (mask, stable, hits) = reference(&cam, &mesh, 1e-3);
    assert!(view.covered_pixels > 20);
    for i in 0..mask.len() {
        assert!(mask[i] == view.mask[i] || !stable[i], "pixel {i}");
        if let (Some((t, _)), 1) = (hits[i], view.mask[i]) {
            assert!((view.depth_m[i] as f64 - t).abs() < 2e-6 * t);
        }
    }
}

#[test]
fn bad_inputs_and_empty_views() {
    let cam = camera(32, 24, DVec3::new(0.0, 0.0, -2.0), 0.0);
    let ras = Rasterizer::new(&cam);
    let p = RenderParams::default();
    assert!(matches!(
        ras.render(&TriMesh::default(), &p),
        Err(Error::Empty { .. })
    ));
    // Behind the camera.
    let behind = uv_sphere(DVec3::new(0.0, 0.0, -4.0), 0.5, 8, 8);
    assert!(matches!(
        ras.render(&behind, &p),
        Err(Error::NotVisible { .. })
    ));
    // Outside the field of view.
    let aside = uv_sphere(DVec3::new(30.0, 0.0, 0.0), 0.5, 8, 8);
    assert!(matches!(
        ras.render(&aside, &p),
        Err(Error::NotVisible { .. })
    ));
    let empty = ras.render(&behind, &p.with_allow_empty(true)).unwrap();
    assert_eq!(empty.covered_pixels, 0);
    assert!(empty.mask.iter().all(|&m| m == 0));
    assert!(empty.depth_m.iter().all(|d| d.is_infinite()));
    let mut nan = uv_sphere(DVec3::ZERO, 0.5, 8, 8);
    nan.vertices[3].y = f64::NAN;
    assert!(matches!(ras.render(&nan, &p), Err(Error::NonFinite { .. })));
    let mut bad = uv_sphere(DVec3::ZERO, 0.5, 8, 8);
    bad.faces[0][1] = 10_000;
    assert!(matches!(
        ras.render(&bad, &p),
        Err(Error::IndexOutOfRange { .. })
    ));
    let nothing = Buffers {
        mask: false,
        depth: false,
        camera_z: false,
        normal: false,
        triangle: false,
    };
    let ok = uv_sphere(DVec3::ZERO, 0.5, 8, 8);
    assert!(matches!(
        ras.render(&ok, &p.with_buffers(nothing)),
        Err(Error::Empty { .. })
    ));
    // Degenerate faces only: nothing to see.
    let flat = TriMesh::new(vec![DVec3::ZERO, DVec3::X, DVec3::X * 2.0], vec![[0, 1, 2]]).unwrap();
    assert!(matches!(
        ras.render(&flat, &p),
        Err(Error::NotVisible { .. })
    ));
}
