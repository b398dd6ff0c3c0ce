//! A compact any-hit bounding-volume hierarchy for the shadow rays of [`super::LightVisibility`].
//!
//! A shadow ray only asks *whether* something lies between a surface point and a light, so
//! the traversal stops at the first triangle hit instead of searching for the closest one
//! (what [`skin_core::mesh::MeshQuery::cast_ray`] does through `parry`'s general-purpose tree),
//! and tests boxes with a precomputed inverse direction on 32-byte `f32` nodes. Boxes are
//! padded outwards so `f32` rounding never culls a box the `f64` ray enters; the triangle test
//! itself (Möller–Trumbore, two-sided, `0 ≤ t ≤ max_t`) runs in `f64`, so the answers are those
//! of an exact ray cast (the unit test compares them with `MeshQuery::cast_ray`).
//!
//! Built top-down with a binned surface-area heuristic (16 bins on the longest centroid
//! axis, leaves of at most 4 triangles) — the standard construction (Wald 2007).

use skin_core::math::DVec3;
use skin_core::mesh::{triangle_normal, TriMesh};

/// Triangles per leaf at most.
const LEAF_MAX: usize = 4;
/// Bins of the surface-area heuristic.
const BINS: usize = 16;
/// Traversal stack depth (the build's depth is bounded by the median fall-back well below).
const STACK: usize = 96;

#[derive(Debug, Clone, Copy)]
struct Node {
    min: [f32; 3],
    max: [f32; 3],
    /// Leaf: first triangle; inner: index of the left child (the right one follows it).
    first: u32,
    /// Leaf: triangle count (> 0); inner: 0.
    count: u32,
}

/// Any-hit shadow-ray hierarchy over the non-degenerate faces of a mesh.
#[derive(Debug, Clone)]
pub(crate) struct ShadowBvh {
    nodes: Vec<Node>,
    /// Per triangle in leaf order: `[v0, v1 − v0, v2 − v0]`.
    tris: Vec<[DVec3; 3]>,
}

#[derive(Clone, Copy)]
struct Bounds {
    min: DVec3,
    max: DVec3,
}

impl Bounds {
    const EMPTY: Bounds = Bounds {
        min: DVec3::splat(f64::INFINITY),
        max: DVec3::splat(f64::NEG_INFINITY),
    };
    fn grow(&mut self, p: DVec3) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }
    fn merge(&mut self, o: &Bounds) {
        self.min = self.min.min(o.min);
        self.max = self.max.max(o.max);
    }
    fn area(&self) -> f64 {
        let d = self.max - self.min;
        if d.x < 0.0 {
            return 0.0;
        }
        2.0 * (d.x * d.y + d.y * d.z + d.z * d.x)
    }
}

/// `f32` box enclosing the `f64` one, padded by a relative and an absolute margin.
fn to_f32(b: &Bounds) -> ([f32; 3], [f32; 3]) {
    let pad = |v: f64| 1e-6 * (1.0 + v.abs());
    let lo = |v: f64| (v - pad(v)) as f32;
    let hi = |v: f64| (v + pad(v)) as f32;
    (
        [lo(b.min.x), lo(b.min.y), lo(b.min.z)],
        [hi(b.max.x), hi(b.max.y), hi(b.max.z)],
    )
}

impl ShadowBvh {
    /// Builds the hierarchy over the non-degenerate faces of `mesh` (face indices are taken
    /// as valid: the callers validated the mesh).
    pub(crate) fn new(mesh: &TriMesh) -> Self {
        let corners: Vec<[DVec3; 3]> = (0..mesh.face_count())
            .map(|f| mesh.triangle(f))
            .filter(|t| triangle_normal(*t).is_some())
            .collect();
        let centroids: Vec<DVec3> = corners.iter().map(|t| (t[0] + t[1] + t[2]) / 3.0).collect();
        let bounds: Vec<Bounds> = corners
            .iter()
            .map(|t| {
                let mut b = Bounds::EMPTY;
                t.iter().for_each(|&p| b.grow(p));
                b
            })
            .collect();
        let mut order: Vec<u32> = (0..corners.len() as u32).collect();
        let mut nodes = vec![Node {
            min: [0.0; 3],
            max: [0.0; 3],
            first: 0,
            count: 0,
        }];
        if !order.is_empty() {
            build(&mut nodes, 0, &mut order, 0, &centroids, &bounds);
        }
        let tris = order
            .iter()
            .map(|&i| {
                let t = corners[i as usize];
                [t[0], t[1] - t[0], t[2] - t[0]]
            })
            .collect();
        ShadowBvh { nodes, tris }
    }

    /// True when a triangle meets the segment `origin + t·dir`, `0 ≤ t ≤ max_t` (`dir` need
    /// not be unit length; `t` is in its units).
    pub(crate) fn occluded(&self, origin: DVec3, dir: DVec3, max_t: f64) -> bool {
        if self.tris.is_empty() {
            return false;
        }
        let o = [origin.x as f32, origin.y as f32, origin.z as f32];
        let inv = [1.0 / dir.x as f32, 1.0 / dir.y as f32, 1.0 / dir.z as f32];
        // A little beyond max_t: the f32 box test must not cut off a hit at max_t.
        let t_far = (max_t * (1.0 + 1e-5) + 1e-6) as f32;
        let mut stack = [0u32; STACK];
        let mut top = 1usize;
        while top > 0 {
            top -= 1;
            let node = &self.nodes[stack[top] as usize];
            if !hits_box(node, o, inv, t_far) {
                continue;
            }
            if node.count > 0 {
                let first = node.first as usize;
                for tri in &self.tris[first..first + node.count as usize] {
                    if hits_triangle(tri, origin, dir, max_t) {
                        return true;
                    }
                }
            } else if top + 2 <= STACK {
                stack[top] = node.first;
                stack[top + 1] = node.first + 1;
                top += 2;
            }
        }
        false
    }
}

#[inline]
fn hits_box(node: &Node, o: [f32; 3], inv: [f32; 3], t_far: f32) -> bool {
    let (mut t0, mut t1) = (0.0f32, t_far);
    for a in 0..3 {
        let ta = (node.min[a] - o[a]) * inv[a];
        let tb = (node.max[a] - o[a]) * inv[a];
        // `min`/`max` drop a NaN (origin on a slab plane with a zero direction component).
        t0 = t0.max(ta.min(tb));
        t1 = t1.min(ta.max(tb));
    }
    t0 <= t1
}

/// Möller–Trumbore, two-sided, closed triangle, `0 ≤ t ≤ max_t`.
#[inline]
fn hits_triangle(tri: &[DVec3; 3], o: DVec3, d: DVec3, max_t: f64) -> bool {
    let [v0, e1, e2] = *tri;
    let p = d.cross(e2);
    let det = e1.dot(p);
    if det == 0.0 {
        return false;
    }
    let inv = 1.0 / det;
    let s = o - v0;
    let u = s.dot(p) * inv;
    if !(0.0..=1.0).contains(&u) {
        return false;
    }
    let q = s.cross(e1);
    let v = d.dot(q) * inv;
    if v < 0.0 || u + v > 1.0 {
        return false;
    }
    let t = e2.dot(q) * inv;
    (0.0..=max_t).contains(&t)
}

/// Fills `nodes[at]` for the triangles `order` (which start at `offset` in the final order),
/// splitting by the binned surface-area heuristic.
fn build(
    nodes: &mut Vec<Node>,
    at: usize,
    order: &mut [u32],
    offset: usize,
    centroids: &[DVec3],
    bounds: &[Bounds],
) {
    let mut bb = Bounds::EMPTY;
    let mut cb = Bounds::EMPTY;
    for &i in order.iter() {
        bb.merge(&bounds[i as usize]);
        cb.grow(centroids[i as usize]);
    }
    let (min, max) = to_f32(&bb);
    nodes[at] = Node {
        min,
        max,
        first: offset as u32,
        count: order.len() as u32,
    };
    if order.len() <= LEAF_MAX {
        return;
    }
    let ext = cb.max - cb.min;
    let axis = if ext.x >= ext.y && ext.x >= ext.z {
        0
    } else if ext.y >= ext.z {
        1
    } else {
        2
    };
    let (lo, span) = (cb.min[axis], ext[axis]);
    let sah = if span <= 0.0 {
        None
    } else {
        let bin_of = |i: u32| {
            (((centroids[i as usize][axis] - lo) / span * BINS as f64) as usize).min(BINS - 1)
        };
        let mut bins = [(Bounds::EMPTY, 0usize); BINS];
        for &i in order.iter() {
            let b = &mut bins[bin_of(i)];
            b.0.merge(&bounds[i as usize]);
            b.1 += 1;
        }
        // Cost of splitting after bin k: A_left·N_left + A_right·N_right.
        let mut right = [(0.0f64, 0usize); BINS];
        let (mut acc, mut n) = (Bounds::EMPTY, 0);
        for k in (1..BINS).rev() {
            acc.merge(&bins[k].0);
            n += bins[k].1;
            right[k] = (acc.area(), n);
        }
        let (mut acc, mut n) = (Bounds::EMPTY, 0);
        let mut best = (f64::INFINITY, 0usize);
        for k in 0..BINS - 1 {
            acc.merge(&bins[k].0);
            n += bins[k].1;
            let (ar, nr) = right[k + 1];
            if n == 0 || nr == 0 {
                continue;
            }
            let cost = acc.area() * n as f64 + ar * nr as f64;
            if cost < best.0 {
                best = (cost, k);
            }
        }
        if best.0.is_finite() {
            let k = best.1;
            let mut left = 0;
            for j in 0..order.len() {
                if bin_of(order[j]) <= k {
                    order.swap(j, left);
                    left += 1;
                }
            }
            Some(left).filter(|&l| l > 0 && l < order.len())
        } else {
            None
        }
    };
    let mid = match sah {
        Some(m) => m,
        None => {
            // Median fall-back: order by the centroid on the axis.
            order.sort_unstable_by(|&a, &b| {
                centroids[a as usize][axis].total_cmp(&centroids[b as usize][axis])
            });
            order.len() / 2
        }
    };
    let left = nodes.len();
    nodes.push(nodes[at]);
    nodes.push(nodes[at]);
    nodes[at].first = left as u32;
    nodes[at].count = 0;
    let (a, b) = order.split_at_mut(mid);
    build(nodes, left, a, offset, centroids, bounds);
    build(nodes, left + 1, b, offset + mid, centroids, bounds);
}

#[cfg(test)]
mod tests {
    use super::*;
    use skin_core::math::Ray;
    use skin_core::mesh::MeshQuery;
    use skin_core::random::SplitMix64;

    /// Two overlapping UV spheres: a mesh with concavities where rays graze and hit.
    fn scene() -> TriMesh {
        let sphere = |c: DVec3, r: f64| {
            let (nu, nv) = (24u32, 12u32);
            let mut vertices = vec![c + DVec3::Y * r, c - DVec3::Y * r];
            for j in 1..nv {
                let th = std::f64::consts::PI * f64::from(j) / f64::from(nv);
                for i in 0..nu {
                    let ph = std::f64::consts::TAU * f64::from(i) / f64::from(nu);
                    vertices.push(
                        c + DVec3::new(th.sin() * ph.cos(), th.cos(), th.sin() * ph.sin()) * r,
                    );
                }
            }
            let ring = |j: u32, i: u32| 2 + (j - 1) * nu + i % nu;
            let mut faces = Vec::new();
            for i in 0..nu {
                faces.push([0, ring(1, i + 1), ring(1, i)]);
                faces.push([1, ring(nv - 1, i), ring(nv - 1, i + 1)]);
                for j in 1..nv - 1 {
                    faces.push([ring(j, i), ring(j, i + 1), ring(j + 1, i + 1)]);
                    faces.push([ring(j, i), ring(j + 1, i + 1), ring(j + 1, i)]);
                }
            }
            (vertices, faces)
        };
        let (mut v, mut f) = sphere(DVec3::ZERO, 1.0);
        let (v2, f2) = sphere(DVec3::new(1.2, 0.3, 0.1), 0.7);
        let off = v.len() as u32;
        v.extend(v2);
        f.extend(f2.into_iter().map(|t| t.map(|i| i + off)));
        TriMesh::new(v, f).unwrap()
    }

    #[test]
    fn any_hit_agrees_with_the_exact_ray_cast() {
        let mesh = scene();
        let bvh = ShadowBvh::new(&mesh);
        let query = MeshQuery::new(&mesh).unwrap();
        let (mut hits, mut n) = (0, 0);
        for k in 0..4000 {
            let u = SplitMix64::new(5 + k).uniform(7);
            let o = DVec3::new(u[0] * 5.0 - 2.0, u[1] * 4.0 - 2.0, u[2] * 4.0 - 2.0);
            let target = DVec3::new(u[3] * 5.0 - 2.0, u[4] * 4.0 - 2.0, u[5] * 4.0 - 2.0);
            let d = target - o;
            let len = d.length();
            let max_t = len * u[6];
            let exact = query.cast_ray(Ray::new(o, d), max_t).unwrap().is_some();
            // `occluded` takes `t` in units of `d`: the same segment.
            let ours = bvh.occluded(o, d, max_t / len);
            assert_eq!(ours, exact, "ray from {o} towards {target}, max_t {max_t}");
            hits += usize::from(exact);
            n += 1;
        }
        // Both outcomes are exercised.
        assert!(hits > n / 10 && hits < n * 9 / 10, "{hits} of {n}");
    }

    #[test]
    fn binned_visibility_is_close_to_the_exact_one_on_the_dome() {
        use crate::shading::{dome_lights, light_bins, DomeParams, LightVisibility};
        // The two spheres standing in the dome (floor at y = -1.5).
        let mesh = scene();
        let query = MeshQuery::new(&mesh).unwrap();
        let dome = DomeParams {
            floor_centre: DVec3::new(0.0, -1.5, 0.0),
            ..Default::default()
        };
        let lights = dome_lights(&dome).unwrap();
        let groups = light_bins(&lights, 100);
        assert!((60..=130).contains(&groups.len()), "{} bins", groups.len());
        assert_eq!(groups.iter().map(Vec::len).sum::<usize>(), lights.len());
        let exact = LightVisibility::compute(&mesh, &query, &lights, 1e-4).unwrap();
        let binned =
            LightVisibility::compute_binned(&mesh, &query, &lights, 1e-4, None, Some(100)).unwrap();
        // Same lights above each tangent plane; the disagreements are shadow-edge lights.
        let normals =
            skin_core::mesh::vertex_normals(&mesh, skin_core::mesh::NormalWeighting::Area).unwrap();
        let (mut differ, mut total, mut cast) = (0usize, 0usize, 0usize);
        for (v, (&p, &n)) in mesh.vertices.iter().zip(&normals).enumerate() {
            for (l, light) in lights.iter().enumerate() {
                let (a, b) = (exact.visible(v, l), binned.visible(v, l));
                differ += usize::from(a != b);
                total += usize::from(a || b);
                // Above the tangent plane yet shadowed: the scene does cast shadows.
                let above = light.irradiance(p, n) > 0.0;
                cast += usize::from(above && !a);
            }
        }
        let frac = differ as f64 / total as f64;
        assert!(
            frac < 0.05,
            "{differ} of {total} visible bits differ ({frac})"
        );
        assert!(cast > 1000, "{cast} shadowed (vertex, light) pairs");
        let err = LightVisibility::compute_binned(&mesh, &query, &lights, 1e-4, None, Some(0));
        assert!(err.is_err());
    }

    #[test]
    fn an_empty_hierarchy_occludes_nothing() {
        let mesh = TriMesh::new(vec![DVec3::ZERO, DVec3::X, DVec3::X * 2.0], vec![[0, 1, 2]]);
        let Ok(mesh) = mesh else {
            return; // a mesh type that rejects degenerate faces has nothing to test here
        };
        let bvh = ShadowBvh::new(&mesh);
        assert!(bvh.tris.is_empty());
        assert!(!bvh.occluded(DVec3::new(0.0, 0.0, -1.0), DVec3::Z, 2.0));
    }
}
