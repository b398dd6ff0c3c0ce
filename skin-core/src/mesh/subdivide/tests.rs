//! Tests of the render-time refinement: edge bound, conformity, identity where unselected,
//! re-evaluation on posed vertices.

use super::*;
use crate::math::{DQuat, DVec3};
use crate::mesh::shapes::{icosphere, uv_sphere};
use crate::mesh::EdgeTopology;

/// A closed sphere of radius 5 cm with faces of varied shape (UV sphere: slivers at the
/// poles) — a limb-sized test surface.
fn sphere() -> TriMesh {
    uv_sphere(DVec3::new(0.1, 1.0, -0.2), 0.05, 14, 22).unwrap()
}

/// Faces with centroid on the +x side of the centre.
fn half(mesh: &TriMesh, centre_x: f64) -> Vec<bool> {
    (0..mesh.face_count())
        .map(|f| mesh.triangle(f).iter().map(|v| v.x).sum::<f64>() / 3.0 > centre_x)
        .collect()
}

fn longest_edge(mesh: &TriMesh, faces: impl Iterator<Item = usize>) -> f64 {
    faces
        .flat_map(|f| {
            let t = mesh.triangle(f);
            [
                t[0].distance(t[1]),
                t[1].distance(t[2]),
                t[2].distance(t[0]),
            ]
        })
        .fold(0.0, f64::max)
}

#[test]
fn selected_edges_meet_the_bound() {
    for (mesh, h) in [
        (sphere(), 0.003),
        (sphere(), 0.0071),
        (
            {
                let mut m = icosphere(1).unwrap();
                m.vertices.iter_mut().for_each(|v| *v *= 0.04);
                m
            },
            0.004,
        ),
    ] {
        let selected = half(&mesh, mesh.bounding_box().unwrap().center().x);
        for alpha in [0.0, RefineParams::DEFAULT_PHONG_ALPHA] {
            let r = Refinement::new(
                &mesh,
                &selected,
                &RefineParams::new(h).with_phong_alpha(alpha),
            )
            .unwrap();
            let fine = r.evaluate(&mesh.vertices).unwrap();
            let refined =
                (0..fine.face_count()).filter(|&f| selected[r.face_parents()[f] as usize]);
            let longest = longest_edge(&fine, refined);
            assert!(longest <= h * (1.0 + 1e-9), "{longest} > {h}");
            assert!(
                longest > 0.6 * h,
                "{longest} much shorter than {h}: over-refined"
            );
            // Unselected faces far from the selection keep their (long) edges.
            assert!(r.coarse_face_kinds().contains(&FaceRefinement::Kept));
            assert!(r.coarse_face_kinds().contains(&FaceRefinement::Transition));
        }
    }
}

#[test]
fn closed_mesh_stays_closed_manifold_and_oriented() {
    let mesh = sphere();
    assert!(EdgeTopology::new(&mesh).unwrap().is_closed());
    for selected in [half(&mesh, 0.1), vec![true; mesh.face_count()]] {
        let r = Refinement::new(&mesh, &selected, &RefineParams::new(0.003)).unwrap();
        let fine = r.evaluate(&mesh.vertices).unwrap();
        let topo = EdgeTopology::new(&fine).unwrap();
        assert!(topo.boundary_edges().is_empty());
        assert!(topo.non_manifold_edges().is_empty());
        assert!(topo.is_closed());
        // Consistent orientation: every directed edge once.
        let mut directed: Vec<(u32, u32)> = fine
            .faces
            .iter()
            .flat_map(|f| (0..3).map(move |k| (f[k], f[(k + 1) % 3])))
            .collect();
        let n = directed.len();
        directed.sort_unstable();
        directed.dedup();
        assert_eq!(directed.len(), n);
        // Every fine vertex is used, and the fine normals point outward like the coarse.
        let mut used = vec![false; fine.vertex_count()];
        fine.faces
            .iter()
            .flatten()
            .for_each(|&v| used[v as usize] = true);
        assert!(used.iter().all(|&u| u));
        let centre = DVec3::new(0.1, 1.0, -0.2);
        for f in 0..fine.face_count() {
            let t = fine.triangle(f);
            let n = (t[1] - t[0]).cross(t[2] - t[0]);
            assert!(
                n.dot(t[0] + t[1] + t[2] - 3.0 * centre) > 0.0,
                "face {f} flipped"
            );
        }
        // Euler characteristic of a sphere.
        let (v, e, f) = (fine.vertex_count(), topo.edges.len(), fine.face_count());
        assert_eq!(v as i64 - e as i64 + f as i64, 2);
    }
}

#[test]
fn flat_refinement_tiles_each_face_exactly() {
    let mesh = sphere();
    let selected = vec![true; mesh.face_count()];
    let r = Refinement::new(
        &mesh,
        &selected,
        &RefineParams::new(0.004).with_phong_alpha(0.0),
    )
    .unwrap();
    let fine = r.evaluate(&mesh.vertices).unwrap();
    let mut area = vec![0.0; mesh.face_count()];
    for (f, &p) in r.face_parents().iter().enumerate() {
        area[p as usize] += triangle_area(fine.triangle(f));
    }
    for (f, a) in area.iter().enumerate() {
        let coarse = triangle_area(mesh.triangle(f));
        assert!(
            (a - coarse).abs() <= 1e-9 * coarse.max(1e-12),
            "face {f}: {a} vs {coarse}"
        );
    }
}

#[test]
fn unselected_faces_are_kept_unchanged() {
    let mesh = sphere();
    let selected = half(&mesh, 0.1);
    let r = Refinement::new(&mesh, &selected, &RefineParams::new(0.003)).unwrap();
    let fine = r.evaluate(&mesh.vertices).unwrap();
    assert_eq!(&fine.vertices[..mesh.vertex_count()], &mesh.vertices[..]);
    let mut kept = 0;
    for (f, kind) in r.coarse_face_kinds().iter().enumerate() {
        let children: Vec<usize> = (0..fine.face_count())
            .filter(|&g| r.face_parents()[g] as usize == f)
            .collect();
        match kind {
            FaceRefinement::Kept => {
                assert!(!selected[f]);
                assert_eq!(children.len(), 1);
                assert_eq!(fine.faces[children[0]], mesh.faces[f]);
                kept += 1;
            }
            FaceRefinement::Transition => assert!(!selected[f] && children.len() > 1),
            FaceRefinement::Refined => assert!(selected[f] && children.len() > 1),
        }
    }
    assert!(kept > mesh.face_count() / 3, "{kept}");
    // Nothing selected: the fine mesh is the coarse mesh.
    let none = Refinement::new(
        &mesh,
        &vec![false; mesh.face_count()],
        &RefineParams::new(0.003),
    )
    .unwrap();
    assert_eq!(none.evaluate(&mesh.vertices).unwrap(), mesh);
}

#[test]
fn re_evaluation_equals_refining_the_posed_mesh() {
    let mesh = sphere();
    let selected = half(&mesh, 0.1);
    let params = RefineParams::new(0.003);
    let rest = Refinement::new(&mesh, &selected, &params).unwrap();
    // A rigid motion keeps every length: refining the moved mesh gives the same topology, and
    // its vertices are the rest refinement evaluated on the moved vertices. (A quarter turn,
    // exact in floating point, so that no edge count or zipper tie can round differently.)
    let q = DQuat::from_axis_angle(DVec3::Y, std::f64::consts::FRAC_PI_2);
    let moved = TriMesh {
        vertices: mesh
            .vertices
            .iter()
            .map(|&v| DVec3::new(v.z, v.y, -v.x))
            .collect(),
        faces: mesh.faces.clone(),
    };
    assert!(moved
        .vertices
        .iter()
        .zip(&mesh.vertices)
        .all(|(m, v)| m.distance(q * *v) < 1e-15));
    let direct = Refinement::new(&moved, &selected, &params).unwrap();
    assert!(direct.faces() == rest.faces());
    let a = direct.evaluate(&moved.vertices).unwrap();
    let b = rest.evaluate(&moved.vertices).unwrap();
    let err = a
        .vertices
        .iter()
        .zip(&b.vertices)
        .map(|(x, y)| x.distance(*y))
        .fold(0.0, f64::max);
    assert!(err < 1e-12, "{err}");
    // Each fine vertex is the Phong point of its coarse combination, for any deformation.
    let bent: Vec<DVec3> = mesh
        .vertices
        .iter()
        .map(|v| *v + DVec3::new(0.0, 0.3 * v.x * v.x, 0.1 * v.y))
        .collect();
    let normals = rest.coarse_normals(&bent).unwrap();
    let fine = rest.evaluate(&bent).unwrap();
    for i in [
        mesh.vertex_count(),
        rest.fine_vertex_count() / 2,
        rest.fine_vertex_count() - 1,
    ] {
        let p = rest.point(i).unwrap();
        let c = p.corners.map(|k| k as usize);
        let x = phong(c.map(|k| bent[k]), c.map(|k| normals[k]), p.bary, 0.75);
        assert!(x.distance(fine.vertices[i]) < 1e-15);
        assert!((p.bary.iter().sum::<f64>() - 1.0).abs() < 1e-12);
    }
    assert!(rest.point(rest.fine_vertex_count()).is_none());
    // Deterministic.
    assert_eq!(Refinement::new(&mesh, &selected, &params).unwrap(), rest);
}

#[test]
fn phong_points_lie_on_the_smooth_sphere() {
    // On a sphere, Phong tessellation with α = 3/4 moves the flat points towards the sphere.
    let mesh = sphere();
    let centre = DVec3::new(0.1, 1.0, -0.2);
    let selected = vec![true; mesh.face_count()];
    let dev = |alpha: f64| {
        let r = Refinement::new(
            &mesh,
            &selected,
            &RefineParams::new(0.004).with_phong_alpha(alpha),
        )
        .unwrap();
        let fine = r.evaluate(&mesh.vertices).unwrap();
        fine.vertices
            .iter()
            .map(|v| (v.distance(centre) - 0.05).abs())
            .fold(0.0, f64::max)
    };
    let (flat, smooth) = (dev(0.0), dev(RefineParams::DEFAULT_PHONG_ALPHA));
    assert!(smooth < 0.5 * flat, "Phong {smooth} vs flat {flat}");
}

#[test]
fn interpolates_attributes() {
    let mesh = sphere();
    let selected = half(&mesh, 0.1);
    let r = Refinement::new(
        &mesh,
        &selected,
        &RefineParams::new(0.004).with_phong_alpha(0.0),
    )
    .unwrap();
    let flat = r.interpolate(&mesh.vertices).unwrap();
    assert_eq!(flat, r.evaluate(&mesh.vertices).unwrap().vertices);
    let ones = r.interpolate(&vec![1.0; mesh.vertex_count()]).unwrap();
    assert!(ones.iter().all(|x| (x - 1.0).abs() < 1e-12));
    assert!(r.interpolate(&[1.0]).is_err());
}

#[test]
fn rejects_bad_input() {
    let mesh = sphere();
    let sel = vec![true; mesh.face_count()];
    assert!(matches!(
        Refinement::new(&mesh, &sel[1..], &RefineParams::new(0.003)),
        Err(Error::SizeMismatch { .. })
    ));
    for h in [0.0, -1.0, f64::NAN] {
        assert!(Refinement::new(&mesh, &sel, &RefineParams::new(h)).is_err());
    }
    assert!(Refinement::new(&mesh, &sel, &RefineParams::new(0.01).with_phong_alpha(1.5)).is_err());
    let mut bad = mesh.clone();
    bad.faces[0][0] = 1_000_000;
    assert!(Refinement::new(&bad, &sel, &RefineParams::new(0.01)).is_err());
    let r = Refinement::new(&mesh, &sel, &RefineParams::new(0.01)).unwrap();
    assert!(matches!(
        r.evaluate(&mesh.vertices[1..]),
        Err(Error::SizeMismatch { .. })
    ));
    let mut nan = mesh.vertices.clone();
    nan[3].y = f64::NAN;
    assert!(matches!(r.evaluate(&nan), Err(Error::NonFinite { .. })));
}
