//! Generalised winding numbers of triangle meshes (Jacobson, Kavan and Sorkine-Hornung 2013,
//! "Robust Inside-Outside Segmentation using Generalized Winding Numbers"), evaluated fast by
//! the far-field expansion of Barill, Dickson, Schmidt, Levin and Jacobson 2018 ("Fast Winding
//! Numbers for Soups and Clouds", §3–4, first order).
//!
//! The winding number of a point `q` is the signed solid angle the surface subtends at `q`,
//! divided by 4π: `w(q) = Σ_f Ω_f(q) / 4π`. For a closed, outward-oriented mesh it is 1
//! inside and 0 outside; for an open mesh (a body with holes at the eyes and mouth, a skirt
//! open at waist and hem) it varies smoothly across the holes, and `w ≥ ½` is the robust
//! "inside" Jacobson et al. recommend. One triangle's solid angle is the exact formula of van
//! Oosterom and Strackee 1983: `tan(Ω/2) = a·(b×c) / (|a||b||c| + (a·b)|c| + (b·c)|a| +
//! (c·a)|b|)` with `a, b, c` its corners relative to `q`.
//!
//! **Fast evaluation.** The triangles sit in a bounding-volume tree (median splits on the
//! longest axis of the centroids, at most `LEAF_TRIANGLES` per leaf). Each node stores its
//! area-weighted centroid `p̃`, its area vector `N = Σ_t a_t n_t` (`a_t n_t = ½ (b−a)×(c−a)`),
//! its second moment `M = Σ_t a_t n_t ⊗ (c_t − p̃)` (`c_t` the triangle's centroid; exact,
//! since the integrand is linear over a triangle) and the radius `ρ` of the ball about `p̃`
//! that holds its triangles. With `r = p̃ − q`, the solid angle `∫ (x − q)·n / |x − q|³ dA`
//! expanded about `p̃` to second order (Barill et al. §3.2, Eq. 11 up to the second term) is
//!
//! ```text
//! Ω ≈ N·r / |r|³ + tr(M) / |r|³ − 3 rᵀ M r / |r|⁵
//! ```
//!
//! used where `|r| > β ρ`; nearer nodes are opened and leaves summed exactly. The second term
//! matters: a ring of a tube (a sleeve, a skirt) has `N ≈ 0`, and at first order it would
//! vanish. Barill et al. take β = 2 with a third-order expansion; at second order β = 2
//! leaves errors of up to 0.05 in a winding number (measured on a 14k-triangle sphere, 400
//! points inside and out) and β = 4 ([`WindingNumber::DEFAULT_ACCURACY_BETA`]) 0.012 (0.004 on a
//! sleeve-like tube), a few microseconds a query either way — far from the ½ of an inside test.

use rayon::prelude::*;

use crate::math::{DMat3, DVec3};
use crate::mesh::TriMesh;
use crate::{Error, Result};

impl WindingNumber {
    /// Default far-field threshold β: a node is expanded beyond β × its radius (ours, for the
    /// second-order expansion: module docs; Barill et al. 2018 use 2 at third order).
    pub const DEFAULT_ACCURACY_BETA: f64 = 4.0;
}
/// Most triangles in a leaf of the tree.
const LEAF_TRIANGLES: usize = 8;

/// One node of the tree: a leaf holds `count > 0` triangles from `start`; an inner node has
/// children `left` and `left + 1`… stored at `left` and `right`.
#[derive(Debug, Clone)]
struct Node {
    centre: DVec3,
    area_vector: DVec3,
    moment: DMat3,
    radius: f64,
    start: u32,
    count: u32,
    left: u32,
    right: u32,
}

/// A triangle mesh prepared for fast generalised winding numbers (module docs).
#[derive(Debug, Clone)]
pub struct WindingNumber {
    triangles: Vec<[DVec3; 3]>,
    nodes: Vec<Node>,
    beta: f64,
}

impl WindingNumber {
    /// Builds the tree of `mesh`'s triangles with the default β
    /// ([`WindingNumber::DEFAULT_ACCURACY_BETA`]). Degenerate triangles are kept (they subtend no
    /// solid angle).
    ///
    /// # Errors
    /// [`Error::Empty`] for a mesh without faces; [`Error::NonFinite`] /
    /// [`Error::IndexOutOfRange`] for an invalid mesh.
    ///
    /// # Example
    /// ```
    /// use skin_core::math::DVec3;
    /// use skin_core::mesh::{shapes, WindingNumber};
    /// let sphere = shapes::uv_sphere(DVec3::ZERO, 1.0, 16, 32)?;
    /// let w = WindingNumber::new(&sphere)?;
    /// // The default second-order far field: within 1 % of the exact sum here (1.0014).
    /// assert!((w.at(DVec3::ZERO)? - 1.0).abs() < 0.01);
    /// assert!(w.at(DVec3::new(3.0, 0.0, 0.0))?.abs() < 0.01);
    /// // Every triangle summed exactly: 1 inside a closed surface to rounding.
    /// let exact = WindingNumber::with_beta(&sphere, f64::INFINITY)?;
    /// assert!((exact.at(DVec3::ZERO)? - 1.0).abs() < 1e-9);
    /// # Ok::<(), skin_core::Error>(())
    /// ```
    pub fn new(mesh: &TriMesh) -> Result<Self> {
        Self::with_beta(mesh, WindingNumber::DEFAULT_ACCURACY_BETA)
    }

    /// As [`WindingNumber::new`] with far-field threshold `beta` (larger: more exact, slower;
    /// `f64::INFINITY` sums every triangle exactly).
    ///
    /// # Errors
    /// As [`WindingNumber::new`]; [`Error::InvalidParam`] for `beta` not positive (or NaN).
    pub fn with_beta(mesh: &TriMesh, beta: f64) -> Result<Self> {
        mesh.validate()?;
        if mesh.faces.is_empty() {
            return Err(Error::Empty { what: "mesh faces" });
        }
        if beta.is_nan() || beta <= 0.0 {
            return Err(Error::InvalidParam {
                name: "beta",
                reason: format!("must be positive, got {beta}"),
            });
        }
        let mut triangles: Vec<[DVec3; 3]> =
            (0..mesh.faces.len()).map(|f| mesh.triangle(f)).collect();
        let mut nodes = Vec::with_capacity(2 * triangles.len() / LEAF_TRIANGLES + 1);
        build(&mut triangles, 0, &mut nodes);
        Ok(Self {
            triangles,
            nodes,
            beta,
        })
    }

    /// The generalised winding number at `q`: ≈ 1 inside a closed outward-oriented surface,
    /// ≈ 0 outside, ½ on the surface.
    ///
    /// # Errors
    /// [`Error::NonFinite`] for a non-finite `q`.
    pub fn at(&self, q: DVec3) -> Result<f64> {
        if !q.is_finite() {
            return Err(Error::NonFinite {
                what: "winding number query point",
            });
        }
        Ok(self.evaluate(q))
    }

    /// [`WindingNumber::at`] for many points, in parallel.
    ///
    /// # Errors
    /// [`Error::NonFinite`] if any point is not finite.
    pub fn at_points(&self, points: &[DVec3]) -> Result<Vec<f64>> {
        if !points.iter().all(|p| p.is_finite()) {
            return Err(Error::NonFinite {
                what: "winding number query point",
            });
        }
        Ok(points.par_iter().map(|&q| self.evaluate(q)).collect())
    }

    /// Whether `q` is inside (`w ≥ ½`, Jacobson et al. 2013 §3.3).
    ///
    /// # Errors
    /// [`Error::NonFinite`] for a non-finite `q`.
    pub fn contains(&self, q: DVec3) -> Result<bool> {
        Ok(self.at(q)? >= 0.5)
    }

    fn evaluate(&self, q: DVec3) -> f64 {
        let mut omega = 0.0;
        let mut stack: Vec<u32> = Vec::with_capacity(64);
        stack.push(0);
        while let Some(i) = stack.pop() {
            let node = &self.nodes[i as usize];
            let d = node.centre - q;
            let dist = d.length();
            if dist > self.beta * node.radius {
                let d3 = dist * dist * dist;
                let m = &node.moment;
                let trace = m.x_axis.x + m.y_axis.y + m.z_axis.z;
                omega += (node.area_vector.dot(d) + trace) / d3
                    - 3.0 * d.dot(*m * d) / (d3 * dist * dist);
            } else if node.count > 0 {
                let (s, n) = (node.start as usize, node.count as usize);
                omega += self.triangles[s..s + n]
                    .iter()
                    .map(|t| solid_angle(*t, q))
                    .sum::<f64>();
            } else {
                stack.push(node.left);
                stack.push(node.right);
            }
        }
        omega / (4.0 * std::f64::consts::PI)
    }
}

/// Signed solid angle of triangle `t` seen from `q` (van Oosterom and Strackee 1983):
/// positive when `q` is behind the triangle (on the side its counter-clockwise normal points
/// away from).
fn solid_angle(t: [DVec3; 3], q: DVec3) -> f64 {
    let (a, b, c) = (t[0] - q, t[1] - q, t[2] - q);
    let (la, lb, lc) = (a.length(), b.length(), c.length());
    let numerator = a.dot(b.cross(c));
    let denominator = la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb;
    2.0 * numerator.atan2(denominator)
}

/// Builds the subtree over `tris` (which it reorders), whose first triangle has global index
/// `offset`, appending nodes; returns the subtree's root index.
fn build(tris: &mut [[DVec3; 3]], offset: usize, nodes: &mut Vec<Node>) -> u32 {
    let index = nodes.len();
    let (mut area_vector, mut weighted, mut area_sum) = (DVec3::ZERO, DVec3::ZERO, 0.0);
    let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
    for t in tris.iter() {
        let n = 0.5 * (t[1] - t[0]).cross(t[2] - t[0]);
        let a = n.length();
        let centroid = (t[0] + t[1] + t[2]) / 3.0;
        area_vector += n;
        weighted += a * centroid;
        area_sum += a;
        lo = lo.min(centroid);
        hi = hi.max(centroid);
    }
    let centre = if area_sum > 0.0 {
        weighted / area_sum
    } else {
        0.5 * (lo + hi)
    };
    let radius = tris
        .iter()
        .flat_map(|t| t.iter())
        .map(|v| (*v - centre).length())
        .fold(0.0, f64::max);
    // M_ij = Σ_t (a_t n_t)_i (c_t − p̃)_j: column j is Σ_t a_t n_t (c_t − p̃)_j.
    let moment = tris.iter().fold(DMat3::ZERO, |m, t| {
        let n = 0.5 * (t[1] - t[0]).cross(t[2] - t[0]);
        let c = (t[0] + t[1] + t[2]) / 3.0 - centre;
        m + DMat3::from_cols(n * c.x, n * c.y, n * c.z)
    });
    nodes.push(Node {
        centre,
        area_vector,
        moment,
        radius,
        start: offset as u32,
        count: 0,
        left: 0,
        right: 0,
    });
    if tris.len() <= LEAF_TRIANGLES {
        nodes[index].count = tris.len() as u32;
        return index as u32;
    }
    let extent = hi - lo;
    let axis = if extent.x >= extent.y && extent.x >= extent.z {
        0
    } else if extent.y >= extent.z {
        1
    } else {
        2
    };
    let key = |t: &[DVec3; 3]| (t[0][axis] + t[1][axis] + t[2][axis]) / 3.0;
    let mid = tris.len() / 2;
    tris.select_nth_unstable_by(mid, |a, b| key(a).total_cmp(&key(b)));
    let (first, second) = tris.split_at_mut(mid);
    let left = build(first, offset, nodes);
    let right = build(second, offset + mid, nodes);
    nodes[index].left = left;
    nodes[index].right = right;
    index as u32
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::shapes;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn exact(mesh: &TriMesh, q: DVec3) -> f64 {
        (0..mesh.faces.len())
            .map(|f| solid_angle(mesh.triangle(f), q))
            .sum::<f64>()
            / (4.0 * std::f64::consts::PI)
    }

    #[test]
    fn closed_sphere_is_one_inside_and_zero_outside() {
        let sphere = shapes::uv_sphere(DVec3::new(0.1, -0.2, 0.3), 1.0, 24, 48).unwrap();
        let w = WindingNumber::new(&sphere).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        for _ in 0..300 {
            let dir = DVec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            )
            .normalize_or(DVec3::X);
            let r: f64 = rng.random_range(0.0..2.5);
            if (r - 1.0).abs() < 0.05 {
                continue;
            }
            let q = DVec3::new(0.1, -0.2, 0.3) + r * dir;
            let v = w.at(q).unwrap();
            let expected = if r < 1.0 { 1.0 } else { 0.0 };
            assert!((v - expected).abs() < 2e-2, "r {r} w {v}");
        }
    }

    #[test]
    fn the_far_field_matches_the_exact_sum() {
        // An open, bumpy surface: a cylinder without caps.
        let tube = shapes::cylinder(0.3, 1.5, 24, 30).unwrap();
        let fast = WindingNumber::new(&tube).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        for _ in 0..200 {
            let q = DVec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-0.5..2.0),
            );
            let (a, b) = (fast.at(q).unwrap(), exact(&tube, q));
            assert!((a - b).abs() < 1e-2, "{q}: fast {a} exact {b}");
        }
        let all = WindingNumber::with_beta(&tube, f64::INFINITY).unwrap();
        let q = DVec3::new(0.05, 0.02, 0.7);
        assert!((all.at(q).unwrap() - exact(&tube, q)).abs() < 1e-12);
    }

    #[test]
    fn an_open_tube_counts_its_middle_as_inside_and_its_ends_fade() {
        // A long tube open at both ends (a sleeve, a skirt): its axis is inside in the middle,
        // half inside at the open ends, and outside beyond them.
        let tube = shapes::cylinder(0.1, 2.0, 32, 40).unwrap();
        let w = WindingNumber::new(&tube).unwrap();
        let mid = w.at(DVec3::new(0.0, 0.0, 1.0)).unwrap();
        let end = w.at(DVec3::new(0.0, 0.0, 0.0)).unwrap();
        let beyond = w.at(DVec3::new(0.0, 0.0, -0.5)).unwrap();
        assert!(mid > 0.9, "mid {mid}");
        assert!((end - 0.5).abs() < 0.05, "end {end}");
        assert!(beyond < 0.05, "beyond {beyond}");
        assert!(w.contains(DVec3::new(0.0, 0.0, 1.0)).unwrap());
        assert!(!w.contains(DVec3::new(0.5, 0.0, 1.0)).unwrap());
    }

    #[test]
    fn bad_input_is_an_error() {
        assert!(matches!(
            WindingNumber::new(&TriMesh::default()),
            Err(Error::Empty { .. })
        ));
        let sphere = shapes::uv_sphere(DVec3::ZERO, 1.0, 8, 16).unwrap();
        assert!(matches!(
            WindingNumber::with_beta(&sphere, 0.0),
            Err(Error::InvalidParam { .. })
        ));
        assert!(matches!(
            WindingNumber::with_beta(&sphere, f64::NAN),
            Err(Error::InvalidParam { .. })
        ));
        let w = WindingNumber::new(&sphere).unwrap();
        assert!(matches!(w.at(DVec3::NAN), Err(Error::NonFinite { .. })));
        assert!(w.at_points(&[DVec3::ZERO, DVec3::INFINITY]).is_err());
        let mut bad = sphere.clone();
        bad.faces.push([0, 1, 9999]);
        assert!(matches!(
            WindingNumber::new(&bad),
            Err(Error::IndexOutOfRange { .. })
        ));
        // Degenerate triangles subtend nothing.
        let mut degenerate = sphere.clone();
        degenerate.faces.push([0, 0, 0]);
        let exact = WindingNumber::with_beta(&degenerate, f64::INFINITY).unwrap();
        assert!((exact.at(DVec3::ZERO).unwrap() - 1.0).abs() < 1e-12);
    }
}
