//! Procedural meshes of the peer benchmarks, so tests, benches and examples can regenerate
//! bit-identical inputs to the Python peers in `bench/peers/` (see its README, "Deterministic
//! inputs", and `laplacian.py`); their random inputs come from `skin_core::random::SplitMix64`.

use crate::math::DVec3;
use crate::mesh::TriMesh;
use crate::{Error, Result};
use std::collections::HashMap;

/// Golden ratio φ.
const PHI: f64 = 1.618_033_988_749_895;

/// Level-0 icosahedron vertices (before normalisation), as `ICO_V` in `laplacian.py`.
const ICO_V: [[f64; 3]; 12] = [
    [-1.0, PHI, 0.0],
    [1.0, PHI, 0.0],
    [-1.0, -PHI, 0.0],
    [1.0, -PHI, 0.0],
    [0.0, -1.0, PHI],
    [0.0, 1.0, PHI],
    [0.0, -1.0, -PHI],
    [0.0, 1.0, -PHI],
    [PHI, 0.0, -1.0],
    [PHI, 0.0, 1.0],
    [-PHI, 0.0, -1.0],
    [-PHI, 0.0, 1.0],
];

/// Level-0 icosahedron faces, as `ICO_F` in `laplacian.py`.
const ICO_F: [[u32; 3]; 20] = [
    [0, 11, 5],
    [0, 5, 1],
    [0, 1, 7],
    [0, 7, 10],
    [0, 10, 11],
    [1, 5, 9],
    [5, 11, 4],
    [11, 10, 2],
    [10, 7, 6],
    [7, 1, 8],
    [3, 9, 4],
    [3, 4, 2],
    [3, 2, 6],
    [3, 6, 8],
    [3, 8, 9],
    [4, 9, 5],
    [2, 4, 11],
    [6, 2, 10],
    [8, 6, 7],
    [9, 8, 1],
];

/// Largest supported subdivision level (level 9 already has 2.6 M vertices).
pub const MAX_ICOSPHERE_LEVEL: u32 = 9;

/// Unit icosphere with `level` subdivisions, vertex and face order exactly as `icosphere()` of
/// the peer benchmark `laplacian.py`: per level, faces are visited in order, edges
/// `(a,b), (b,c), (c,a)`; a midpoint (normalised to unit length) is appended the first time
/// an undirected edge is met; face `(a,b,c)` becomes `(a,ab,ca), (b,bc,ab), (c,ca,bc),
/// (ab,bc,ca)`. Level `l` has `10·4ˡ + 2` vertices and `20·4ˡ` faces, counter-clockwise seen
/// from outside.
///
/// # Errors
/// [`Error::InvalidParam`] if `level > MAX_ICOSPHERE_LEVEL`.
pub fn icosphere(level: u32) -> Result<TriMesh> {
    if level > MAX_ICOSPHERE_LEVEL {
        return Err(Error::InvalidParam {
            name: "level",
            reason: format!("must be <= {MAX_ICOSPHERE_LEVEL}, got {level}"),
        });
    }
    let mut vertices: Vec<DVec3> = ICO_V
        .iter()
        .map(|v| DVec3::from_array(*v).normalize())
        .collect();
    let mut faces: Vec<[u32; 3]> = ICO_F.to_vec();
    for _ in 0..level {
        let mut mid: HashMap<(u32, u32), u32> = HashMap::with_capacity(faces.len() * 3 / 2);
        let mut next = Vec::with_capacity(faces.len() * 4);
        let mut midpoint = |a: u32, b: u32, vertices: &mut Vec<DVec3>| -> u32 {
            let key = if a < b { (a, b) } else { (b, a) };
            *mid.entry(key).or_insert_with(|| {
                let p = vertices[a as usize] + vertices[b as usize];
                vertices.push(p / p.length());
                (vertices.len() - 1) as u32
            })
        };
        for &[a, b, c] in &faces {
            let ab = midpoint(a, b, &mut vertices);
            let bc = midpoint(b, c, &mut vertices);
            let ca = midpoint(c, a, &mut vertices);
            next.extend_from_slice(&[[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        faces = next;
    }
    Ok(TriMesh { vertices, faces })
}

/// The peers' "blob": the icosphere deformed by `deform()` of `laplacian.py`,
/// `r = 1 + 0.2 sin(3x) cos(2y) + 0.1 z²` applied radially, then scaled by `(1.0, 0.8, 0.6)`.
/// A smooth closed surface with non-uniform triangles, used as the Laplacian benchmark mesh.
///
/// # Errors
/// As [`icosphere`].
pub fn peer_blob(level: u32) -> Result<TriMesh> {
    let mut mesh = icosphere(level)?;
    for v in &mut mesh.vertices {
        let r = 1.0 + 0.2 * (3.0 * v.x).sin() * (2.0 * v.y).cos() + 0.1 * v.z * v.z;
        *v = *v * r * DVec3::new(1.0, 0.8, 0.6);
    }
    Ok(mesh)
}

/// An open cylinder around the z axis from `z = 0` to `z = length`, `rings + 1` rings of
/// `segments` vertices (ring-major order), radius `radius`; faces counter-clockwise seen from
/// outside. A standard test limb for skinning.
///
/// # Errors
/// [`Error::InvalidParam`] if `segments < 3`, `rings < 1`, or `radius`/`length` are not
/// positive and finite.
pub fn cylinder(radius: f64, length: f64, segments: u32, rings: u32) -> Result<TriMesh> {
    if segments < 3 || rings < 1 {
        return Err(Error::InvalidParam {
            name: "segments/rings",
            reason: format!("need segments >= 3 and rings >= 1, got {segments}, {rings}"),
        });
    }
    if !(radius > 0.0 && radius.is_finite() && length > 0.0 && length.is_finite()) {
        return Err(Error::InvalidParam {
            name: "radius/length",
            reason: "must be positive and finite".into(),
        });
    }
    let mut vertices = Vec::with_capacity(((rings + 1) * segments) as usize);
    for r in 0..=rings {
        let z = length * r as f64 / rings as f64;
        for s in 0..segments {
            let t = std::f64::consts::TAU * s as f64 / segments as f64;
            vertices.push(DVec3::new(radius * t.cos(), radius * t.sin(), z));
        }
    }
    let mut faces = Vec::with_capacity((2 * rings * segments) as usize);
    for r in 0..rings {
        for s in 0..segments {
            let a = r * segments + s;
            let b = r * segments + (s + 1) % segments;
            let c = a + segments;
            let d = b + segments;
            faces.push([a, b, d]);
            faces.push([a, d, c]);
        }
    }
    Ok(TriMesh { vertices, faces })
}

/// A closed latitude/longitude surface: vertices `point(θ, φ)` for polar angle θ ∈ [0, π] in
/// `n_lat` bands and azimuth φ ∈ [0, 2π) in `n_lon` segments, with one vertex at each pole
/// (θ = 0 first, θ = π last). Faces are counter-clockwise seen from outside when the
/// parametrisation is oriented like [`uv_sphere`]'s (pole on +y, φ turning from +x to +z);
/// star-shaped bodies such as bumpy ellipsoids are built by scaling that one.
///
/// # Errors
/// [`Error::InvalidParam`] if `n_lat < 2` or `n_lon < 3`; [`Error::NonFinite`] if `point`
/// returns NaN or infinity.
pub fn lat_long_surface(
    n_lat: usize,
    n_lon: usize,
    point: impl Fn(f64, f64) -> DVec3,
) -> Result<TriMesh> {
    if n_lat < 2 || n_lon < 3 {
        return Err(Error::InvalidParam {
            name: "n_lat/n_lon",
            reason: format!("need n_lat >= 2 and n_lon >= 3, got {n_lat}, {n_lon}"),
        });
    }
    let mut vertices = Vec::with_capacity((n_lat - 1) * n_lon + 2);
    vertices.push(point(0.0, 0.0));
    for i in 1..n_lat {
        let th = std::f64::consts::PI * i as f64 / n_lat as f64;
        for j in 0..n_lon {
            vertices.push(point(th, std::f64::consts::TAU * j as f64 / n_lon as f64));
        }
    }
    vertices.push(point(std::f64::consts::PI, 0.0));
    let ring = |i: usize, j: usize| (1 + (i - 1) * n_lon + j % n_lon) as u32;
    let south = (vertices.len() - 1) as u32;
    let mut faces = Vec::with_capacity(2 * n_lat * n_lon);
    for j in 0..n_lon {
        faces.push([0, ring(1, j + 1), ring(1, j)]);
        faces.push([south, ring(n_lat - 1, j), ring(n_lat - 1, j + 1)]);
    }
    for i in 1..n_lat - 1 {
        for j in 0..n_lon {
            faces.push([ring(i, j), ring(i, j + 1), ring(i + 1, j + 1)]);
            faces.push([ring(i, j), ring(i + 1, j + 1), ring(i + 1, j)]);
        }
    }
    TriMesh::new(vertices, faces)
}

/// A closed UV sphere of `radius` about `centre`, pole on the +y axis, faces counter-clockwise
/// seen from outside (see [`lat_long_surface`]).
///
/// # Errors
/// As [`lat_long_surface`]; [`Error::NonFinite`] for a non-finite centre or radius.
pub fn uv_sphere(centre: DVec3, radius: f64, n_lat: usize, n_lon: usize) -> Result<TriMesh> {
    lat_long_surface(n_lat, n_lon, |th, ph| {
        centre + DVec3::new(th.sin() * ph.cos(), th.cos(), th.sin() * ph.sin()) * radius
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uv_sphere_is_closed_outward_and_checks_its_sizes() {
        let m = uv_sphere(DVec3::new(0.1, 0.2, 0.3), 0.5, 6, 8).unwrap();
        assert_eq!(m.vertex_count(), 5 * 8 + 2);
        assert!(crate::mesh::EdgeTopology::new(&m).unwrap().is_closed());
        let c = DVec3::new(0.1, 0.2, 0.3);
        for f in 0..m.face_count() {
            let [a, b, d] = m.triangle(f);
            assert!(
                (b - a).cross(d - a).dot(a - c) > 0.0,
                "face {f} faces inward"
            );
        }
        assert!(uv_sphere(DVec3::ZERO, 1.0, 1, 8).is_err());
        assert!(uv_sphere(DVec3::ZERO, 1.0, 4, 2).is_err());
        assert!(uv_sphere(DVec3::ZERO, f64::NAN, 4, 8).is_err());
    }

    #[test]
    fn icosphere_sizes_and_geometry() {
        for level in 0..4 {
            let m = icosphere(level).unwrap();
            let n = 10 * 4usize.pow(level) + 2;
            assert_eq!(m.vertices.len(), n);
            assert_eq!(m.faces.len(), 20 * 4usize.pow(level));
            m.validate().unwrap();
            assert!(m.vertices.iter().all(|v| (v.length() - 1.0).abs() < 1e-12));
            // Outward orientation: every face normal points away from the origin.
            for f in 0..m.faces.len() {
                let [a, b, c] = m.triangle(f);
                assert!((b - a).cross(c - a).dot(a + b + c) > 0.0);
            }
        }
        // Level-1 order as in laplacian.py: the first face (0, 11, 5) creates vertices
        // 12 = mid(0, 11), 13 = mid(11, 5), 14 = mid(5, 0).
        let m = icosphere(1).unwrap();
        assert_eq!(m.faces[0], [0, 12, 14]);
        assert_eq!(m.faces[3], [12, 13, 14]);
        let v0 = DVec3::from_array(ICO_V[0]).normalize();
        let v11 = DVec3::from_array(ICO_V[11]).normalize();
        assert!((m.vertices[12] - (v0 + v11).normalize()).length() < 1e-15);
        assert!(icosphere(MAX_ICOSPHERE_LEVEL + 1).is_err());
    }

    #[test]
    fn blob_and_cylinder() {
        let b = peer_blob(2).unwrap();
        let s = icosphere(2).unwrap();
        let v = s.vertices[7];
        let r = 1.0 + 0.2 * (3.0 * v.x).sin() * (2.0 * v.y).cos() + 0.1 * v.z * v.z;
        assert!((b.vertices[7] - v * r * DVec3::new(1.0, 0.8, 0.6)).length() < 1e-15);
        let c = cylinder(0.1, 1.0, 8, 4).unwrap();
        assert_eq!(c.vertices.len(), 40);
        assert_eq!(c.faces.len(), 64);
        c.validate().unwrap();
        for f in 0..c.faces.len() {
            let [a, b, cc] = c.triangle(f);
            let centre = (a + b + cc) / 3.0;
            let radial = DVec3::new(centre.x, centre.y, 0.0);
            assert!((b - a).cross(cc - a).dot(radial) > 0.0);
        }
        assert!(cylinder(0.1, 1.0, 2, 4).is_err());
        assert!(cylinder(f64::NAN, 1.0, 8, 4).is_err());
    }
}
