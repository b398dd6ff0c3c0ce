//! Tests of the scanned outer surface on the MakeHuman performer in its skirt.

use super::*;
use crate::tests::data;
use crate::{makehuman_performer, procedural_performer, DeformationParams, GarmentParams};
use crate::{ProceduralBodyParams, SkirtParams};
use skin_core::math::Ray;
use skin_core::mesh::is_closed;

const VOXEL_M: f64 = ScanParams::DEFAULT_VOXEL_M;

#[test]
fn the_skirt_is_scanned_as_one_closed_solid_with_the_legs_inside_hidden() {
    let p = makehuman_performer(
        data("makehuman"),
        &DeformationParams::none().with_garment(Some(GarmentParams::Skirt(SkirtParams::default()))),
    )
    .unwrap();
    let scan = scan_outer_surface(&p, &ScanParams::default()).unwrap();
    assert!(is_closed(&scan.mesh).unwrap());
    // Faces wound outwards: the enclosed volume is positive.
    let volume: f64 = scan
        .mesh
        .faces
        .iter()
        .map(|f| {
            let [a, b, c] = f.map(|v| scan.mesh.vertices[v as usize]);
            a.dot(b.cross(c)) / 6.0
        })
        .sum();
    assert!(volume > 0.04, "volume {volume} m³");
    assert_eq!(scan.on_garment.len(), scan.mesh.vertex_count());
    // About the template size, with near-equilateral triangles (the relaxation's purpose).
    let n = scan.mesh.vertex_count();
    assert!((9_000..=10_500).contains(&n), "{n} vertices");
    let sliver = |m: &TriMesh| {
        let thin = m
            .faces
            .iter()
            .filter(|f| {
                let [a, b, c] = f.map(|v| m.vertices[v as usize]);
                let angle = |p: DVec3, q: DVec3, r: DVec3| (q - p).angle_between(r - p);
                angle(a, b, c).min(angle(b, c, a)).min(angle(c, a, b)) < 10f64.to_radians()
            })
            .count();
        thin as f64 / m.face_count() as f64
    };
    let unrelaxed = scan_outer_surface(
        &p,
        &ScanParams {
            relax_iterations: 0,
            ..ScanParams::default()
        },
    )
    .unwrap();
    let (relaxed, raw) = (sliver(&scan.mesh), sliver(&unrelaxed.mesh));
    println!("triangles with an angle under 10°: relaxed {relaxed:.4}, not relaxed {raw:.4}");
    assert!(relaxed < 0.01 && relaxed < raw / 5.0, "{relaxed} vs {raw}");
    assert_eq!(scan.hidden.len(), p.template.vertex_count());
    // Every scanned vertex lies on the body or on the closed skirt, within a voxel.
    let (body, _) = p.body().unwrap();
    let garment = closed_garment(&p).unwrap().unwrap();
    let (qb, qg) = (
        MeshQuery::new(&body).unwrap(),
        MeshQuery::new(&garment).unwrap(),
    );
    let (db, dg) = (
        qb.closest_points(&scan.mesh.vertices).unwrap(),
        qg.closest_points(&scan.mesh.vertices).unwrap(),
    );
    let worst = db
        .iter()
        .zip(&dg)
        .map(|(b, g)| b.distance.min(g.distance))
        .fold(0.0, f64::max);
    assert!(
        worst < VOXEL_M,
        "farthest scan vertex {worst} m off the performer"
    );
    // The legs under the skirt are hidden, the head and the skirt itself are not.
    let garment_range = p.garment_vertices();
    let skirt_top = garment_range
        .clone()
        .map(|v| p.template.vertices[v].y)
        .fold(f64::MIN, f64::max);
    let hem = garment_range
        .clone()
        .map(|v| p.template.vertices[v].y)
        .fold(f64::MAX, f64::min);
    let hidden: Vec<usize> = (0..p.template.vertex_count())
        .filter(|&v| scan.hidden[v])
        .collect();
    assert!(hidden.len() > 200, "{} hidden vertices", hidden.len());
    assert!(hidden
        .iter()
        .all(|&v| v < garment_range.start && p.template.vertices[v].y < skirt_top + VOXEL_M));
    // The skirt's part of the scan is between its hem and its waistband.
    let on_garment: Vec<f64> = (0..scan.mesh.vertex_count())
        .filter(|&v| scan.on_garment[v])
        .map(|v| scan.mesh.vertices[v].y)
        .collect();
    assert!(on_garment.len() > 100);
    assert!(on_garment
        .iter()
        .all(|&y| y > hem - VOXEL_M && y < skirt_top + VOXEL_M));
    // The hem is closed: looking up between the legs from below, the scan is met at the hem,
    // not at the crotch.
    let q = MeshQuery::new(&scan.mesh).unwrap();
    let pelvis = p
        .skeleton
        .forward_kinematics(&p.skeleton.rest_pose())
        .unwrap()
        .joint_positions()[0];
    let below = DVec3::new(pelvis.x, hem - 0.3, pelvis.z);
    let hit = q.cast_ray(Ray::new(below, DVec3::Y), 2.0).unwrap().unwrap();
    let y = below.y + hit.t;
    assert!((y - hem).abs() < 0.05, "met at {y} m, hem at {hem} m");
}

#[test]
fn a_body_without_garment_is_scanned_as_itself_and_bad_spacings_are_rejected() {
    let p = procedural_performer(&ProceduralBodyParams {
        grid_spacing_m: 0.04,
        ..Default::default()
    })
    .unwrap();
    let params = ScanParams {
        voxel_m: 0.04,
        vertices: None,
        ..ScanParams::default()
    };
    let scan = scan_outer_surface(&p, &params).unwrap();
    assert!(is_closed(&scan.mesh).unwrap());
    assert!(scan.hidden.iter().all(|&h| !h) && scan.on_garment.iter().all(|&g| !g));
    for bad in [0.0, -0.01, f64::NAN] {
        let e = scan_outer_surface(
            &p,
            &ScanParams {
                voxel_m: bad,
                ..params.clone()
            },
        )
        .unwrap_err();
        assert!(e.to_string().contains("voxel_m"), "{e}");
    }
    let e = scan_outer_surface(
        &p,
        &ScanParams {
            voxel_m: 1e-4,
            ..params.clone()
        },
    )
    .unwrap_err();
    assert!(e.to_string().contains("coarser"), "{e}");
}
