//! Surfaces of the animated body (Sand, McMillan and Popović 2003 §3.1–3.2 and §5.4).
//!
//! The method is documented on [`union_mesh`]; the module is private and
//! everything public is re-exported at the crate root.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use skin_core::check;
use skin_core::math::DVec3;
use skin_core::mesh::{marching_tetrahedra, ScalarGrid, TriMesh};

use crate::animate::{AnimatedBody, AnimatedPrimitive};
use crate::{Context, Error, Result, ResultExt};

/// Parameters of [`union_mesh`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SurfaceParams {
    /// Grid spacing of the implicit body, m. The paper's needle spacing is ≈ 1–2 cm (Table
    /// 3.1); 5 mm resolves that profile with ~2–4 samples per needle gap at moderate cost.
    /// Must be finite and > 0. Default: 0.005.
    pub voxel_m: f64,
    /// Empty voxels added around the body's bounding box on each side (so the surface never
    /// touches the grid border and stays closed). Must be ≥ 1. Default: 2.
    pub padding_voxels: usize,
}

impl Default for SurfaceParams {
    fn default() -> Self {
        Self {
            voxel_m: 0.005,
            padding_voxels: 2,
        }
    }
}

/// Checks that a primitive's arrays agree with its grid and are finite.
fn check_primitive(p: &AnimatedPrimitive) -> Result<()> {
    let n = p.radial * p.axial;
    for (what, got) in [
        ("animated primitive endpoints", p.endpoints.len()),
        ("animated primitive origins", p.origins.len()),
        ("animated primitive directions", p.directions.len()),
        ("animated primitive lengths", p.lengths.len()),
    ] {
        if got != n || n == 0 {
            return Err(Error::SizeMismatch {
                what,
                expected: n,
                got,
            });
        }
    }
    let finite = p
        .endpoints
        .iter()
        .chain(&p.origins)
        .chain(&p.directions)
        .all(|v| v.is_finite())
        && p.axis_start.is_finite()
        && p.axis_end.is_finite()
        && p.lengths.iter().all(|l| l.is_finite());
    if !finite {
        return Err(Error::NonFinite {
            what: "animated primitive",
        });
    }
    if p.axis_start.distance(p.axis_end) < 1e-9 {
        return Err(Error::InvalidParam {
            name: "axis",
            reason: "axis start and end coincide".into(),
        });
    }
    Ok(())
}

/// The closed triangle mesh of one primitive: quads between consecutive rings and needles,
/// closed around the axis, end caps fanned to the axis end points (outward-facing,
/// counter-clockwise). Vertices: the `radial · axial` endpoints (ring-major), then the axis
/// start and end.
///
/// # Errors
/// [`Error::InvalidParam`] if `radial < 3` (no closed ring) or the axis is degenerate;
/// [`Error::SizeMismatch`] / [`Error::NonFinite`] for inconsistent or non-finite input.
pub fn primitive_mesh(p: &AnimatedPrimitive) -> Result<TriMesh> {
    check_primitive(p)?;
    if p.radial < 3 {
        return Err(Error::InvalidParam {
            name: "radial",
            reason: format!("a closed ring needs ≥ 3 needles, got {}", p.radial),
        });
    }
    let (m, a) = (p.radial, p.axial);
    let mut vertices = p.endpoints.clone();
    let start = vertices.len() as u32;
    vertices.push(p.axis_start);
    vertices.push(p.axis_end);
    let end = start + 1;
    let id = |r: usize, k: usize| (r * m + k % m) as u32;
    let mut faces = Vec::with_capacity(2 * m * a);
    for r in 0..a.saturating_sub(1) {
        for k in 0..m {
            let (v00, v01, v11, v10) = (id(r, k), id(r, k + 1), id(r + 1, k + 1), id(r + 1, k));
            faces.push([v00, v01, v11]);
            faces.push([v00, v11, v10]);
        }
    }
    for k in 0..m {
        faces.push([start, id(0, k + 1), id(0, k)]);
        faces.push([end, id(a - 1, k), id(a - 1, k + 1)]);
    }
    Ok(TriMesh::new(vertices, faces)?)
}

/// [`primitive_mesh`] of every primitive.
///
/// # Errors
/// [`Error::Empty`] for a body without primitives; the errors of [`primitive_mesh`] in
/// [`Error::At`] with the [`Context::Primitive`].
pub fn primitive_meshes(body: &AnimatedBody) -> Result<Vec<TriMesh>> {
    if body.primitives.is_empty() {
        return Err(Error::Empty {
            what: "animated body primitives",
        });
    }
    body.primitives
        .iter()
        .enumerate()
        .map(|(i, p)| primitive_mesh(p).at(Context::Primitive(i)))
        .collect()
}

/// All primitive meshes concatenated into one mesh (overlapping closed shells).
///
/// # Errors
/// As [`primitive_meshes`].
pub fn merged_mesh(body: &AnimatedBody) -> Result<TriMesh> {
    let meshes = primitive_meshes(body)?;
    let mut vertices = Vec::new();
    let mut faces = Vec::new();
    for m in meshes {
        let base = vertices.len() as u32;
        vertices.extend(m.vertices);
        faces.extend(m.faces.iter().map(|f| f.map(|v| v + base)));
    }
    Ok(TriMesh::new(vertices, faces)?)
}

/// The implicit function of one primitive at world point `x` (see [`union_mesh`]): negative inside,
/// zero on the needle surface, in metres. Assumes a primitive accepted by [`primitive_mesh`]'s
/// checks (any `radial ≥ 1` is fine here).
pub fn primitive_implicit(p: &AnimatedPrimitive, x: DVec3) -> f64 {
    Implicit::new(p).value(x, f64::INFINITY)
}

/// [`primitive_implicit`] with the primitive's frame computed once.
struct Implicit<'a> {
    p: &'a AnimatedPrimitive,
    axis: DVec3,
    len: f64,
    /// Needle 0's direction and `axis × u`: the angle φ of a point is measured from `u`.
    u: DVec3,
    v: DVec3,
    /// The longest needle plus a margin that covers the rounding of the bilinear profile.
    max_radius: f64,
}

impl<'a> Implicit<'a> {
    fn new(p: &'a AnimatedPrimitive) -> Self {
        let axis_vec = p.axis_end - p.axis_start;
        let len = axis_vec.length();
        let axis = axis_vec / len;
        let u = p.directions[0];
        let max_radius = p.lengths.iter().fold(f64::NEG_INFINITY, |m, &l| m.max(l));
        Self {
            p,
            axis,
            len,
            u,
            v: axis.cross(u),
            max_radius: max_radius + 1e-9 * (1.0 + max_radius.abs()),
        }
    }

    /// The value at `x`, or any value `≥ above` when it is certainly `≥ above` (the profile
    /// is a convex combination of needle lengths, so `r − max length` bounds `r − R(φ, t)`
    /// from below without the angle).
    fn value(&self, x: DVec3, above: f64) -> f64 {
        let p = self.p;
        let (axis, len) = (self.axis, self.len);
        let rel = x - p.axis_start;
        let t = rel.dot(axis);
        let radial_vec = rel - axis * t;
        let r = radial_vec.length();
        let bound = (r - self.max_radius).max(-t).max(t - len);
        if bound >= above {
            return bound;
        }
        let phi = radial_vec
            .dot(self.v)
            .atan2(radial_vec.dot(self.u))
            .rem_euclid(std::f64::consts::TAU);
        let (m, a) = (p.radial, p.axial);
        let kf = phi / std::f64::consts::TAU * m as f64;
        let k0 = (kf.floor() as usize).min(m - 1);
        let k1 = (k0 + 1) % m;
        let wk = (kf - k0 as f64).clamp(0.0, 1.0);
        let sf = (t / len * a as f64 - 0.5).clamp(0.0, (a - 1) as f64);
        let r0 = (sf.floor() as usize).min(a - 1);
        let r1 = (r0 + 1).min(a - 1);
        let ws = sf - r0 as f64;
        let l = |r: usize, k: usize| p.lengths[r * m + k];
        let radius = (1.0 - ws) * ((1.0 - wk) * l(r0, k0) + wk * l(r0, k1))
            + ws * ((1.0 - wk) * l(r1, k0) + wk * l(r1, k1));
        (r - radius).max(-t).max(t - len)
    }
}

/// One watertight surface of the union of all primitives (§3.2), by marching tetrahedra over
/// `min_p f_p` (see below) on a grid of spacing `params.voxel_m`.
///
/// Surfaces of the animated body (Sand, McMillan and Popović 2003 §3.1–3.2 and §5.4).
///
/// Two renderings of an [`AnimatedBody`]:
///
/// * **Per-primitive meshes** ([`primitive_mesh`], [`merged_mesh`]): the needle endpoints of a
///   primitive form a ring-major grid; consecutive rings and consecutive needles of a ring are
///   joined by quads (two triangles), closed around the axis, and each end is capped by a fan
///   to the axis end point. This is the thesis's display of the deformable primitives
///   (Figure 3-1); the primitives overlap at the junctions (§3.2), so the merged mesh is a
///   union of closed shells, not one surface.
/// * **One watertight body surface** ([`union_mesh`]): §3.2 defines junctions as the *union* of
///   overlapping primitives. Each primitive gets an implicit function
///   `f(x) = max(r(x) − R(φ, t), −t, t − L)` where `r` is the distance of `x` from the axis, `t`
///   its position along the axis of length `L`, and `R(φ, t)` the needle radial profile
///   (bilinear in the needle angle and the ring coordinate, constant beyond the end rings).
///   `f < 0` inside. The body is `min_p f_p`, sampled on a regular grid and polygonised by
///   [`skin_core::mesh::marching_tetrahedra`] (watertight). `f` is a distance
///   in the radial and axial directions (not a Euclidean distance), which is all the linear
///   iso-surface interpolation needs near the surface.
///
/// # Errors
/// [`Error::Empty`] for a body without primitives; an invalid-parameter error
/// ([`Error::invalid_param_name`]) for a bad voxel size or padding, or a grid over 2³¹ nodes;
/// the input errors of [`primitive_mesh`] (except the `radial ≥ 3` requirement) in
/// [`Error::At`] with the [`Context::Primitive`].
pub fn union_mesh(body: &AnimatedBody, params: &SurfaceParams) -> Result<TriMesh> {
    check::positive("voxel_m", params.voxel_m)?;
    if params.padding_voxels == 0 {
        return Err(Error::InvalidParam {
            name: "padding_voxels",
            reason: "must be ≥ 1 so the surface stays closed".into(),
        });
    }
    if body.primitives.is_empty() {
        return Err(Error::Empty {
            what: "animated body primitives",
        });
    }
    // Bounding boxes (with one voxel margin) per primitive, to skip far primitives.
    let h = params.voxel_m;
    let mut boxes = Vec::with_capacity(body.primitives.len());
    for (i, p) in body.primitives.iter().enumerate() {
        check_primitive(p).at(Context::Primitive(i))?;
        let mut lo = p.axis_start.min(p.axis_end);
        let mut hi = p.axis_start.max(p.axis_end);
        for e in &p.endpoints {
            lo = lo.min(*e);
            hi = hi.max(*e);
        }
        boxes.push((lo - DVec3::splat(h), hi + DVec3::splat(h)));
    }
    let (mut lo, mut hi) = boxes[0];
    for (a, b) in &boxes {
        lo = lo.min(*a);
        hi = hi.max(*b);
    }
    let pad = params.padding_voxels as f64 * h;
    let origin = lo - DVec3::splat(pad);
    let extent = hi + DVec3::splat(pad) - origin;
    let count = |e: f64| (e / h).ceil() as usize + 1;
    let dims = [count(extent.x), count(extent.y), count(extent.z)];
    let total = dims
        .iter()
        .try_fold(1usize, |acc, &d| acc.checked_mul(d))
        .filter(|&n| n <= 1 << 31)
        .ok_or_else(|| Error::InvalidParam {
            name: "voxel_m",
            reason: format!("grid {dims:?} too large for voxel {h} m"),
        })?;
    // Each primitive is evaluated on the nodes of its box only: per row of nodes (j, k), the
    // primitives whose box the row crosses and the run of columns inside it (found with the
    // same comparisons a per-node box test makes).
    let implicits: Vec<Implicit<'_>> = body.primitives.iter().map(Implicit::new).collect();
    let xs: Vec<f64> = (0..dims[0])
        .map(|i| (origin + DVec3::new(i as f64, 0.0, 0.0) * h).x)
        .collect();
    let mut values = vec![0.0; total];
    let slab = dims[0] * dims[1];
    values
        .par_chunks_mut(slab)
        .enumerate()
        .for_each(|(k, out)| {
            out.fill(f64::INFINITY);
            for j in 0..dims[1] {
                let row = &mut out[dims[0] * j..dims[0] * (j + 1)];
                let yz = origin + DVec3::new(0.0, j as f64, k as f64) * h;
                for (imp, (a, b)) in implicits.iter().zip(&boxes) {
                    if !(yz.y >= a.y && yz.y <= b.y && yz.z >= a.z && yz.z <= b.z) {
                        continue;
                    }
                    let i0 = xs.partition_point(|&x| x < a.x);
                    let i1 = xs.partition_point(|&x| x <= b.x);
                    for (i, f) in row.iter_mut().enumerate().take(i1).skip(i0) {
                        let x = origin + DVec3::new(i as f64, j as f64, k as f64) * h;
                        *f = f.min(imp.value(x, *f));
                    }
                }
                // Outside every box: a positive value one voxel out (never interpolated
                // into a surface, since every box includes a one-voxel margin).
                for f in row.iter_mut() {
                    if !f.is_finite() {
                        *f = h;
                    }
                }
            }
        });
    let grid = ScalarGrid {
        origin,
        spacing_m: h,
        dims,
        values,
    };
    Ok(marching_tetrahedra(&grid, 0.0)?)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::animate::animate;
    use crate::animate::tests::constant_model;
    use skin_core::mesh::EdgeTopology;

    /// A straight primitive along +z from 0 to `len`, with constant needle length `radius`.
    fn cylinder(radial: usize, axial: usize, len: f64, radius: f64) -> AnimatedPrimitive {
        let mut origins = Vec::new();
        let mut directions = Vec::new();
        for r in 0..axial {
            let z = len * (r as f64 + 0.5) / axial as f64;
            for k in 0..radial {
                let phi = std::f64::consts::TAU * k as f64 / radial as f64;
                origins.push(DVec3::new(0.0, 0.0, z));
                directions.push(DVec3::new(phi.cos(), phi.sin(), 0.0));
            }
        }
        let endpoints = origins
            .iter()
            .zip(&directions)
            .map(|(o, d)| *o + *d * radius)
            .collect();
        AnimatedPrimitive {
            radial,
            axial,
            axis_start: DVec3::ZERO,
            axis_end: DVec3::new(0.0, 0.0, len),
            origins,
            directions,
            endpoints,
            lengths: vec![radius; radial * axial],
        }
    }

    #[test]
    fn constant_lengths_give_a_closed_outward_cylinder() {
        let c = cylinder(12, 5, 0.3, 0.04);
        let mesh = primitive_mesh(&c).unwrap();
        assert!(EdgeTopology::new(&mesh).unwrap().is_closed());
        for v in &mesh.vertices[..60] {
            assert!((v.truncate().length() - 0.04).abs() < 1e-12);
        }
        // Outward orientation: positive signed volume.
        let vol: f64 = mesh
            .faces
            .iter()
            .map(|f| {
                let [a, b, c] = f.map(|i| mesh.vertices[i as usize]);
                a.dot(b.cross(c)) / 6.0
            })
            .sum();
        assert!(vol > 0.0, "volume {vol}");
        // The union of a single primitive is the same cylinder (flat caps at the axis ends).
        let params = SurfaceParams {
            voxel_m: 0.01,
            ..Default::default()
        };
        let u = union_mesh(
            &AnimatedBody {
                primitives: vec![cylinder(16, 6, 0.3, 0.04)],
            },
            &params,
        )
        .unwrap();
        assert!(EdgeTopology::new(&u).unwrap().is_closed());
        for v in &u.vertices {
            let r = v.truncate().length();
            let on_side = (r - 0.04).abs() < 2e-3;
            let on_cap = v.z.abs() < 1e-3 || (v.z - 0.3).abs() < 1e-3;
            assert!(on_side || (on_cap && r < 0.041), "vertex {v}");
        }
    }

    #[test]
    fn union_of_the_body_is_closed_and_near_the_primitives() {
        let (sk, body, model) = constant_model(0.05);
        let mut theta = sk.rest_pose();
        theta[4] = 0.4;
        let a = animate(&body, &model, &sk, &theta).unwrap();
        let merged = merged_mesh(&a).unwrap();
        assert_eq!(
            merged.vertex_count(),
            a.needle_count() + 2 * a.primitives.len()
        );
        let params = SurfaceParams {
            voxel_m: 0.02,
            ..Default::default()
        };
        let u = union_mesh(&a, &params).unwrap();
        assert!(u.face_count() > 100);
        assert!(EdgeTopology::new(&u).unwrap().is_closed());
        for v in &u.vertices {
            let f = a
                .primitives
                .iter()
                .map(|p| primitive_implicit(p, *v))
                .fold(f64::INFINITY, f64::min);
            assert!(f.abs() < params.voxel_m, "vertex {v}: field {f}");
        }
    }

    #[test]
    fn bad_input_is_rejected() {
        let good = cylinder(6, 2, 0.2, 0.03);
        assert!(matches!(
            primitive_mesh(&cylinder(2, 2, 0.2, 0.03)),
            Err(Error::InvalidParam { name: "radial", .. })
        ));
        let mut bad = good.clone();
        bad.lengths.pop();
        assert!(matches!(
            primitive_mesh(&bad),
            Err(Error::SizeMismatch { .. })
        ));
        let mut bad = good.clone();
        bad.endpoints[3].x = f64::NAN;
        assert!(matches!(primitive_mesh(&bad), Err(Error::NonFinite { .. })));
        let mut bad = good.clone();
        bad.axis_end = bad.axis_start;
        assert!(primitive_mesh(&bad).is_err());
        let two = AnimatedBody {
            primitives: vec![good.clone(), bad],
        };
        let e = primitive_meshes(&two).unwrap_err();
        assert_eq!(e.contexts(), vec![Context::Primitive(1)]);
        assert_eq!(e.invalid_param_name(), Some("axis"));
        let empty = AnimatedBody { primitives: vec![] };
        assert!(matches!(merged_mesh(&empty), Err(Error::Empty { .. })));
        let d = SurfaceParams::default();
        assert!(matches!(union_mesh(&empty, &d), Err(Error::Empty { .. })));
        let one = AnimatedBody {
            primitives: vec![good],
        };
        for p in [
            SurfaceParams { voxel_m: 0.0, ..d },
            SurfaceParams {
                voxel_m: f64::NAN,
                ..d
            },
            SurfaceParams { voxel_m: 1e-7, ..d },
            SurfaceParams {
                padding_voxels: 0,
                ..d
            },
        ] {
            let e = union_mesh(&one, &p).unwrap_err();
            assert!(e.invalid_param_name().is_some(), "{e}");
        }
    }
}

#[cfg(test)]
mod proptests {
    use super::*;
    use proptest::prelude::*;
    use skin_core::math::DQuat;
    use skin_core::mesh::EdgeTopology;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(48))]

        /// For any needle lengths and any axis placement: the primitive mesh is closed, and
        /// every needle endpoint lies on the zero set of the primitive's implicit function
        /// (the union surface interpolates the needles exactly).
        #[test]
        fn endpoints_are_on_the_implicit_surface(
            radial in 3usize..10,
            axial in 1usize..6,
            lengths in proptest::collection::vec(0.01f64..0.2, 60),
            rot in proptest::array::uniform3(-3.0f64..3.0),
            shift in proptest::array::uniform3(-1.0f64..1.0),
        ) {
            let q = DQuat::from_scaled_axis(DVec3::from_array(rot));
            let t = DVec3::from_array(shift);
            let len = 0.4;
            let (mut origins, mut directions, mut endpoints, mut ls) =
                (Vec::new(), Vec::new(), Vec::new(), Vec::new());
            for r in 0..axial {
                let z = len * (r as f64 + 0.5) / axial as f64;
                for k in 0..radial {
                    let phi = std::f64::consts::TAU * k as f64 / radial as f64;
                    let o = q * DVec3::new(0.0, 0.0, z) + t;
                    let d = q * DVec3::new(phi.cos(), phi.sin(), 0.0);
                    let l = lengths[r * radial + k];
                    origins.push(o);
                    directions.push(d);
                    endpoints.push(o + d * l);
                    ls.push(l);
                }
            }
            let p = AnimatedPrimitive {
                radial,
                axial,
                axis_start: t,
                axis_end: q * DVec3::new(0.0, 0.0, len) + t,
                origins,
                directions,
                endpoints,
                lengths: ls,
            };
            let mesh = primitive_mesh(&p).unwrap();
            prop_assert!(EdgeTopology::new(&mesh).unwrap().is_closed());
            for e in &p.endpoints {
                prop_assert!(primitive_implicit(&p, *e).abs() < 1e-9);
            }
            // Points on the axis are inside, far points outside.
            prop_assert!(primitive_implicit(&p, p.origins[0]) < 0.0);
            prop_assert!(primitive_implicit(&p, p.axis_end + (p.axis_end - t)) > 0.0);
        }
    }
}
