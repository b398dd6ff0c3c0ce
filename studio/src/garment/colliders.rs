//! The body as the cloth sees it: tapered capsules ("round cones") attached to the joint
//! frames, fitted at rest so that together they cover the body template, plus an optional
//! floor.
//!
//! **Segments.** Each joint owns one segment to each child joint, one between each pair of its
//! children (pelvis: hip to hip and hips to spine — the width of the hips; chest: across the
//! shoulders) and, for a leaf, one to its end site (head top, hand, toe). All move rigidly
//! with the owning joint's frame.
//!
//! **Radii.** Each body vertex is assigned to the nearest segment of the joint with its largest
//! skin weight; a segment's radius varies linearly from `r_a` to `r_b` along it and
//! `(r_a, r_b)` is the smallest pair (least `r_a + r_b`, over a grid of `r_a`) for which
//! *every* assigned vertex lies inside. So at rest the union of capsules contains the whole
//! template; posed, it contains the rigid part of each limb, and skinning's blends near the
//! joints shrink the surface inward (towards the capsules) rather than out of them — the
//! penetration test of `tests.rs` measures what is left against the skinned body mesh.
//!
//! **Contact.** Distances are exact for the round cone (the convex hull of the two end
//! spheres), with its outward normal. A vertex closer than `margin` to the surface is moved
//! out along that normal onto the margin, and its tangential motion relative to the capsule's
//! surface over the substep is cut by Coulomb friction (static below `μ·depth`, else
//! shortened by `μ·depth`), the usual position-based friction. (Pushing radially by "distance
//! to the axis minus the radius there" is no projection on a steep taper: a motion along the
//! axis came back amplified as a radial push.)
//!
//! The capsules are the cheap per-substep contact; the posed body mesh has the last word at
//! the end of each frame (module `body`).

use serde::{Deserialize, Serialize};
use skin_core::math::{DAffine3, DVec3};
use skin_core::mesh::{SkinWeights, TriMesh};
use skin_core::skeleton::Skeleton;
use skin_core::{Error, Result};

/// Number of `r_a` candidates tried when fitting a segment's radii.
const RADIUS_GRID: usize = 64;
/// Smallest capsule radius, metres (a segment with no vertices gets it).
const MIN_RADIUS_M: f64 = 0.01;

/// One tapered capsule in its joint's frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub(super) struct Capsule {
    /// Owning joint.
    pub(super) joint: u32,
    /// End points in the joint's frame, metres.
    pub(super) a: DVec3,
    pub(super) b: DVec3,
    /// Radius at `a` and at `b`, metres.
    pub(super) ra: f64,
    pub(super) rb: f64,
}

/// The body's colliders.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(super) struct Colliders {
    pub(super) capsules: Vec<Capsule>,
    /// Height of the floor (the lowest template vertex), metres; `None`: no floor.
    pub(super) floor_y: Option<f64>,
    /// Extra clearance kept between cloth and every collider, metres.
    pub(super) margin_m: f64,
}

/// A capsule in world coordinates at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct PosedCapsule {
    pub(super) a: DVec3,
    pub(super) b: DVec3,
    pub(super) ra: f64,
    pub(super) rb: f64,
    /// Bounding box inflated by the margin.
    lo: DVec3,
    hi: DVec3,
}

/// Parameter along `a → b` of the point of the segment closest to `p`, in `[0, 1]`.
fn segment_param(p: DVec3, a: DVec3, b: DVec3) -> f64 {
    let ab = b - a;
    let l2 = ab.length_squared();
    if l2 < 1e-18 {
        0.0
    } else {
        ((p - a).dot(ab) / l2).clamp(0.0, 1.0)
    }
}

impl PosedCapsule {
    fn new(a: DVec3, b: DVec3, ra: f64, rb: f64, margin: f64) -> Self {
        let r = ra.max(rb) + margin;
        PosedCapsule {
            a,
            b,
            ra,
            rb,
            lo: a.min(b) - DVec3::splat(r),
            hi: a.max(b) + DVec3::splat(r),
        }
    }

    /// `(signed distance to the surface, outward unit normal there, parameter along a → b of
    /// the closest surface point's projection on the axis)`: the exact distance to the round
    /// cone (convex hull of the spheres `(a, ra)` and `(b, rb)`), so pushing a point out by the
    /// depth along the normal lands it on the surface — the plain "linear radius at the
    /// closest axis point" is no distance for a steep taper (pushing radially by it amplifies
    /// any motion along the axis, which made the cloth jitter on the pelvis cones).
    pub(super) fn distance(&self, p: DVec3) -> (f64, DVec3, f64) {
        let ab = self.b - self.a;
        let l = ab.length();
        let (ra, rb) = (self.ra, self.rb);
        // One sphere holds the other (or the segment is a point): the larger sphere.
        if l < 1e-12 || (ra - rb).abs() >= l {
            let (c, r, s) = if ra >= rb {
                (self.a, ra, 0.0)
            } else {
                (self.b, rb, 1.0)
            };
            let n = (p - c).try_normalize().unwrap_or(DVec3::Y);
            return (p.distance(c) - r, n, s);
        }
        let e = ab / l;
        let pa = p - self.a;
        let u = pa.dot(e);
        let q = pa - e * u;
        let v = q.length();
        let w = if v > 1e-12 {
            q / v
        } else {
            e.any_orthonormal_vector()
        };
        // The side line in the (u, v) half-plane: normal (sin φ, cos φ), tangent to both
        // circles, at the points T_a = ra (sin φ, cos φ) and T_b = (l, 0) + rb (sin φ, cos φ).
        let sin = (ra - rb) / l;
        let cos = (1.0 - sin * sin).sqrt();
        // Position along the side line from T_a (direction (cos φ, −sin φ)).
        let along = (u - ra * sin) * cos - (v - ra * cos) * sin;
        if along <= 0.0 {
            let n = (p - self.a).try_normalize().unwrap_or(-e);
            (p.distance(self.a) - ra, n, 0.0)
        } else if along >= l * cos {
            let n = (p - self.b).try_normalize().unwrap_or(e);
            (p.distance(self.b) - rb, n, 1.0)
        } else {
            let d = u * sin + v * cos - ra;
            let n = e * sin + w * cos;
            // The surface point's axial parameter.
            let s = ((u - d * sin) / l).clamp(0.0, 1.0);
            (d, n, s)
        }
    }

    fn may_touch(&self, p: DVec3) -> bool {
        p.cmpge(self.lo).all() && p.cmple(self.hi).all()
    }
}

/// The colliders posed at one instant.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct PosedColliders {
    pub(super) capsules: Vec<PosedCapsule>,
    floor_y: Option<f64>,
    margin_m: f64,
}

impl Colliders {
    /// Keeps only the capsules owned by `joints`.
    pub(super) fn retain(&mut self, joints: &[usize]) {
        self.capsules
            .retain(|c| joints.contains(&(c.joint as usize)));
    }

    /// Poses every capsule with the joint frames `world_from_joint` (checked by the caller).
    pub(super) fn pose(&self, world_from_joint: &[DAffine3]) -> PosedColliders {
        let capsules = self
            .capsules
            .iter()
            .map(|c| {
                let t = &world_from_joint[c.joint as usize];
                PosedCapsule::new(
                    t.transform_point3(c.a),
                    t.transform_point3(c.b),
                    c.ra,
                    c.rb,
                    self.margin_m,
                )
            })
            .collect();
        PosedColliders {
            capsules,
            floor_y: self.floor_y,
            margin_m: self.margin_m,
        }
    }

    /// `a` of the way from `from` to `to` (end points interpolated linearly: for substeps of a
    /// frame the chord differs from the arc by well under a millimetre).
    pub(super) fn between(from: &PosedColliders, to: &PosedColliders, a: f64) -> PosedColliders {
        let capsules = from
            .capsules
            .iter()
            .zip(&to.capsules)
            .map(|(c0, c1)| {
                PosedCapsule::new(c0.a.lerp(c1.a, a), c0.b.lerp(c1.b, a), c0.ra, c0.rb, {
                    to.margin_m
                })
            })
            .collect();
        PosedColliders {
            capsules,
            floor_y: to.floor_y,
            margin_m: to.margin_m,
        }
    }
}

impl PosedColliders {
    /// Moves the predicted position `p` (vertex previously at `x`) out of every collider,
    /// with friction `mu` against the collider's motion since `before` (same colliders at the
    /// start of the substep).
    /// Capsule `k < 64` is skipped when bit `k` of `ignore` is set.
    pub(super) fn resolve(
        &self,
        x: DVec3,
        mut p: DVec3,
        before: &PosedColliders,
        mu: f64,
        ignore: u64,
    ) -> DVec3 {
        let m = self.margin_m;
        for (k, (c, c0)) in self.capsules.iter().zip(&before.capsules).enumerate() {
            if (k < 64 && ignore & (1 << k) != 0) || !c.may_touch(p) {
                continue;
            }
            let (d, n, s) = c.distance(p);
            let depth = m - d;
            if depth <= 0.0 {
                continue;
            }
            p += n * depth;
            if mu > 0.0 {
                let surface = (c.a - c0.a).lerp(c.b - c0.b, s);
                let rel = p - x - surface;
                let tangential = rel - n * rel.dot(n);
                let t = tangential.length();
                if t <= mu * depth {
                    p -= tangential;
                } else {
                    p -= tangential * (mu * depth / t);
                }
            }
        }
        if let Some(y0) = self.floor_y {
            let depth = y0 + m - p.y;
            if depth > 0.0 {
                p.y += depth;
                if mu > 0.0 {
                    let rel = DVec3::new(p.x - x.x, 0.0, p.z - x.z);
                    let t = rel.length();
                    if t <= mu * depth {
                        p -= rel;
                    } else {
                        p -= rel * (mu * depth / t);
                    }
                }
            }
        }
        p
    }

    /// For each point, the capsules (bits `k < 64`) it lies within the margin of: the cloth
    /// ignores those for that vertex, so a garment pinned inside a collider at rest (a
    /// waistband on a flat belly inside the round spine capsule) is not torn off it.
    pub(super) fn inside_masks(&self, points: &[DVec3]) -> Vec<u64> {
        points
            .iter()
            .map(|&p| {
                self.capsules
                    .iter()
                    .take(64)
                    .enumerate()
                    .filter(|(_, c)| c.distance(p).0 < self.margin_m)
                    .fold(0u64, |m, (k, _)| m | (1 << k))
            })
            .collect()
    }

    /// Smallest signed distance from `p` to any capsule surface, metres (negative inside).
    pub(super) fn signed_distance(&self, p: DVec3) -> f64 {
        self.capsules
            .iter()
            .map(|c| c.distance(p).0)
            .fold(f64::INFINITY, f64::min)
    }

    /// The posed capsules whose owning joint is in `joints` (by the order of `owners`).
    pub(super) fn subset(&self, owners: &[u32], joints: &[usize]) -> PosedColliders {
        PosedColliders {
            capsules: self
                .capsules
                .iter()
                .zip(owners)
                .filter(|(_, j)| joints.contains(&(**j as usize)))
                .map(|(c, _)| *c)
                .collect(),
            floor_y: None,
            margin_m: self.margin_m,
        }
    }
}

/// The segments of every joint at rest (world coordinates), with their owners.
fn segments(skeleton: &Skeleton, frames: &[DAffine3]) -> Vec<(usize, DVec3, DVec3)> {
    let mut out = Vec::new();
    for j in 0..skeleton.joint_count() {
        let pj = frames[j].translation;
        let children: Vec<usize> = skeleton.children(j).collect();
        for &c in &children {
            out.push((j, pj, frames[c].translation));
        }
        for (k, &c) in children.iter().enumerate() {
            for &d in &children[k + 1..] {
                out.push((j, frames[c].translation, frames[d].translation));
            }
        }
        if children.is_empty() {
            let tip = skeleton.joints()[j]
                .end_site
                .map_or(pj, |e| frames[j].transform_point3(e));
            out.push((j, pj, tip));
        }
    }
    out
}

/// Fits the capsules to the body template at rest (`frames` = rest joint frames).
///
/// # Errors
/// [`Error::SizeMismatch`] when the weights do not match the body or skeleton;
/// [`Error::Empty`] for a body without vertices.
pub(super) fn fit(
    skeleton: &Skeleton,
    frames: &[DAffine3],
    body: &TriMesh,
    weights: &SkinWeights,
    margin_m: f64,
    floor: bool,
) -> Result<Colliders> {
    skin_core::check::same_size(
        "body skin weight rows vs body vertices",
        body.vertex_count(),
        weights.vertex_count(),
    )?;
    skin_core::check::same_size(
        "body skin weight bones vs skeleton joints",
        skeleton.joint_count(),
        weights.bone_count(),
    )?;
    if body.vertices.is_empty() {
        return Err(Error::Empty {
            what: "garment body template",
        });
    }
    let segs = segments(skeleton, frames);
    // (parameter, distance) of each vertex assigned to each segment.
    let mut assigned: Vec<Vec<(f64, f64)>> = vec![Vec::new(); segs.len()];
    for (v, &p) in body.vertices.iter().enumerate() {
        let Some((j, _)) = weights
            .influences(v)
            .max_by(|a, b| a.1.total_cmp(&b.1).then(b.0.cmp(&a.0)))
        else {
            continue;
        };
        let best = segs
            .iter()
            .enumerate()
            .filter(|(_, s)| s.0 == j as usize)
            .map(|(k, s)| {
                let t = segment_param(p, s.1, s.2);
                (k, t, p.distance(s.1.lerp(s.2, t)))
            })
            .min_by(|a, b| a.2.total_cmp(&b.2));
        if let Some((k, t, d)) = best {
            assigned[k].push((t, d));
        }
    }
    let mut capsules = Vec::with_capacity(segs.len());
    for ((j, a, b), pts) in segs.iter().zip(&assigned) {
        let (ra, rb) = fit_radii(pts);
        let local = frames[*j].inverse();
        capsules.push(Capsule {
            joint: *j as u32,
            a: local.transform_point3(*a),
            b: local.transform_point3(*b),
            ra,
            rb,
        });
    }
    let floor_y = floor.then(|| {
        body.vertices
            .iter()
            .map(|v| v.y)
            .fold(f64::INFINITY, f64::min)
    });
    Ok(Colliders {
        capsules,
        floor_y,
        margin_m,
    })
}

/// Smallest `(r_a, r_b)` (least sum over a grid of `r_a`) with `r_a (1 − t) + r_b t ≥ d` for
/// every `(t, d)`.
fn fit_radii(pts: &[(f64, f64)]) -> (f64, f64) {
    let dmax = pts.iter().map(|p| p.1).fold(MIN_RADIUS_M, f64::max);
    let mut best = (dmax, dmax);
    for k in 0..=RADIUS_GRID {
        let ra = dmax * k as f64 / RADIUS_GRID as f64;
        let mut rb: f64 = MIN_RADIUS_M;
        let mut ok = true;
        for &(t, d) in pts {
            if t < 1e-9 {
                ok &= ra >= d;
            } else {
                rb = rb.max((d - ra * (1.0 - t)) / t);
            }
        }
        if ok && ra >= MIN_RADIUS_M && ra + rb < best.0 + best.1 {
            best = (ra, rb);
        }
    }
    best
}
