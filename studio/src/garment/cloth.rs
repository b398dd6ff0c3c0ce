//! The cloth solver: extended position-based dynamics (XPBD, Macklin, Müller & Chentanez 2016)
//! run as "small steps" (Macklin et al. 2019: many substeps of one constraint iteration each).
//!
//! Why XPBD: it is the position-level equivalent of a mass–spring system with second-order
//! (inertial) dynamics — each distance constraint with compliance `α` is a spring of stiffness
//! `1/α` — but it is unconditionally stable for any stiffness and step, so the cloth can be
//! nearly inextensible without the tiny explicit steps a stiff spring would need. Small steps
//! give stiffer, less damped cloth than many iterations of one large step at the same cost.
//!
//! Per substep of length `h`: gravity and exponential velocity damping, prediction
//! `p = x + h v`, pinned vertices moved onto their targets, one Gauss–Seidel pass over the
//! stretch constraints (mesh edges at their pattern length) then the bending constraints
//! (distance between the two vertices opposite each interior edge: a soft resistance to
//! folding), then collisions ([`super::colliders`]), and `v = (p − x)/h` (capped at
//! [`ClothParams::max_speed_m_per_s`] when set), `x = p`. Every loop
//! runs serially in a fixed order, so results are bit-identical whatever the thread count.
//!
//! **Compression.** A stretch edge shorter than its rest length resists with the bending
//! compliance, not the stretch one: fabric buckles rather than compresses, and below the
//! mesh's resolution a buckle is a fold. With stiff compression, wherever the pattern is wider
//! than where it hangs (the gathered cloth under the waistband, the flare over the belly) one
//! Gauss–Seidel sweep around a compressed ring shoved its vertices along the ring every
//! substep: a jitter at a fixed displacement per substep (so the finer the substeps, the
//! faster — up to 10 m/s), alternately stretched and crushed ring edges (the "column" at twice
//! its length), and a drape that never settled.

use super::colliders::PosedColliders;
use super::ClothParams;
use serde::{Deserialize, Serialize};
use skin_core::check;
use skin_core::math::DVec3;
use skin_core::mesh::{triangle_area, TriMesh};
use skin_core::{Error, Result};
use std::collections::BTreeMap;

// **The speed cap** ([`ClothParams::max_speed_m_per_s`]; the sheet's default 10 m/s, none
// for the skirt). Why (the Ghost blow-up): the sheet on the MakeHuman performer under the
// exercise motion (whose frame 0 is not the rest pose) diverged — farthest vertex 1.5 m from
// the root at frame 0, 33 m at frame 2, 4 km at frame 3. Traced: the first call starts the
// sheet on its skinned positions in that pose, where it lies up to 9.4 cm inside a collider
// capsule; the first substep's push-out became a 47 m/s velocity (9.4 cm in 2 ms). That kick
// at the top of the head travelled one grid row per substep down the nearly inextensible
// hanging sheet to its free edge, growing like the crack of a whip (the constraint
// corrections grew from 0.14 m to 7.5 m per substep): 2100 m/s at the edge by the next frame.
// Velocity `v = (p − x)/h` turns any position correction into speed, so one deep push-out is
// enough. The cap bounds that growth; it also fires while the sheet falls onto the body in
// `Garment::new`'s settling. It is off for the skirt so that the skirt's studio truth (and
// every figure measured on it) is unchanged.

/// A distance constraint between two vertices with its rest length (metres).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub(super) struct Link {
    pub(super) i: u32,
    pub(super) j: u32,
    pub(super) rest_m: f64,
}

/// The precomputed cloth: inverse masses, constraints and parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(super) struct Cloth {
    pub(super) params: ClothParams,
    /// Inverse mass per vertex, 1/kg; 0 for pinned vertices (they follow their targets).
    pub(super) inv_mass: Vec<f64>,
    pub(super) stretch: Vec<Link>,
    pub(super) bend: Vec<Link>,
    /// Per vertex, the colliders it ignores (bits of [`PosedColliders::resolve`]).
    pub(super) ignore: Vec<u64>,
}

/// Checks every field of [`ClothParams`].
pub(super) fn check_params(p: &ClothParams) -> Result<()> {
    check::positive("cloth.density_kg_per_m2", p.density_kg_per_m2)?;
    check::non_negative(
        "cloth.stretch_compliance_m_per_n",
        p.stretch_compliance_m_per_n,
    )?;
    check::non_negative("cloth.bend_compliance_m_per_n", p.bend_compliance_m_per_n)?;
    check::non_negative("cloth.damping_per_s", p.damping_per_s)?;
    check::finite("cloth.gravity_m_per_s2", p.gravity_m_per_s2)?;
    check::positive("cloth.max_substep_s", p.max_substep_s)?;
    check::nonzero("cloth.iterations", p.iterations)?;
    check::non_negative("cloth.collision_margin_m", p.collision_margin_m)?;
    check::non_negative("cloth.friction", p.friction)?;
    if let Some(cap) = p.max_speed_m_per_s {
        check::positive("cloth.max_speed_m_per_s", cap)?;
    }
    Ok(())
}

impl Cloth {
    /// Builds the cloth on its sewing pattern `pattern` (rest lengths and masses come from it:
    /// mass = areal density × triangle area, a third to each corner); `pinned` vertices get
    /// infinite mass.
    ///
    /// # Errors
    /// [`Error::Degenerate`] for a pattern of zero area or an edge of zero length; as
    /// [`check_params`].
    pub(super) fn new(params: &ClothParams, pattern: &TriMesh, pinned: &[bool]) -> Result<Self> {
        check_params(params)?;
        let n = pattern.vertex_count();
        check::same_size("pinned flags vs garment vertices", n, pinned.len())?;
        let mut mass = vec![0.0; n];
        for f in 0..pattern.face_count() {
            let a = triangle_area(pattern.triangle(f)) * params.density_kg_per_m2 / 3.0;
            for &i in &pattern.faces[f] {
                mass[i as usize] += a;
            }
        }
        let inv_mass = mass
            .iter()
            .zip(pinned)
            .enumerate()
            .map(|(i, (&m, &pin))| {
                if pin {
                    Ok(0.0)
                } else if m > 0.0 {
                    Ok(1.0 / m)
                } else {
                    Err(Error::Degenerate {
                        what: format!("garment vertex {i} belongs to no triangle of non-zero area"),
                    })
                }
            })
            .collect::<Result<Vec<f64>>>()?;
        // Edge → opposite vertices, in a BTreeMap so constraint order is fixed.
        let mut edges: BTreeMap<(u32, u32), Vec<u32>> = BTreeMap::new();
        for f in &pattern.faces {
            for k in 0..3 {
                let (a, b, c) = (f[k], f[(k + 1) % 3], f[(k + 2) % 3]);
                edges.entry((a.min(b), a.max(b))).or_default().push(c);
            }
        }
        let v = &pattern.vertices;
        let link = |i: u32, j: u32| -> Result<Link> {
            let rest_m = v[i as usize].distance(v[j as usize]);
            if rest_m > 0.0 {
                Ok(Link { i, j, rest_m })
            } else {
                Err(Error::Degenerate {
                    what: format!("garment vertices {i} and {j} coincide in the pattern"),
                })
            }
        };
        let mut stretch = Vec::with_capacity(edges.len());
        let mut bend = Vec::new();
        for (&(a, b), opposite) in &edges {
            stretch.push(link(a, b)?);
            if let [c, d] = opposite[..] {
                bend.push(link(c.min(d), c.max(d))?);
            }
        }
        Ok(Cloth {
            params: params.clone(),
            inv_mass,
            stretch,
            bend,
            ignore: vec![0; n],
        })
    }

    /// Whether vertex `i` is pinned.
    pub(super) fn is_pinned(&self, i: usize) -> bool {
        self.inv_mass[i] == 0.0
    }

    /// Advances `x`, `v` by `dt_s` in substeps; pinned vertices move linearly from
    /// `pins_from` to `pins_to` (their targets at the start and end of the interval);
    /// colliders move as `colliders(a)` says at fraction `a ∈ (0, 1]` of the interval.
    pub(super) fn advance(
        &self,
        x: &mut [DVec3],
        v: &mut [DVec3],
        pins_from: &[DVec3],
        pins_to: &[DVec3],
        dt_s: f64,
        mut colliders: impl FnMut(f64) -> PosedColliders,
    ) {
        let p = &self.params;
        let steps = (dt_s / p.max_substep_s).ceil().max(1.0);
        let h = dt_s / steps;
        let keep = (-p.damping_per_s * h).exp();
        let g = DVec3::new(0.0, -p.gravity_m_per_s2, 0.0);
        let n = x.len();
        let mut pred = vec![DVec3::ZERO; n];
        let mut lambda_s = vec![0.0; self.stretch.len()];
        let mut lambda_b = vec![0.0; self.bend.len()];
        let (alpha_s, alpha_b) = (
            p.stretch_compliance_m_per_n / (h * h),
            p.bend_compliance_m_per_n / (h * h),
        );
        // Compressed fabric buckles below the mesh's resolution: a stretch edge shorter than
        // its rest length resists like a fold, with the bending compliance.
        let alpha_c = alpha_s.max(alpha_b);
        let mut before = colliders(0.0);
        for s in 1..=steps as usize {
            let a = s as f64 / steps;
            let after = colliders(a);
            for i in 0..n {
                if self.inv_mass[i] == 0.0 {
                    pred[i] = pins_from[i].lerp(pins_to[i], a);
                } else {
                    v[i] = (v[i] + g * h) * keep;
                    pred[i] = x[i] + v[i] * h;
                }
            }
            lambda_s.iter_mut().for_each(|l| *l = 0.0);
            lambda_b.iter_mut().for_each(|l| *l = 0.0);
            for _ in 0..p.iterations {
                self.solve(&self.stretch, (alpha_s, alpha_c), &mut lambda_s, &mut pred);
                self.solve(&self.bend, (alpha_b, alpha_b), &mut lambda_b, &mut pred);
            }
            for i in 0..n {
                if self.inv_mass[i] > 0.0 {
                    pred[i] = after.resolve(x[i], pred[i], &before, p.friction, self.ignore[i]);
                }
            }
            for i in 0..n {
                let vi = (pred[i] - x[i]) / h;
                v[i] = match p.max_speed_m_per_s {
                    Some(cap) => vi.clamp_length_max(cap),
                    None => vi,
                };
                x[i] = pred[i];
            }
            before = after;
        }
    }

    /// One Gauss–Seidel pass over distance constraints with compliance `alpha` = (stretched,
    /// compressed), already divided by h²: `Δλ = (−C − α̃ λ) / (w_i + w_j + α̃)`.
    fn solve(&self, links: &[Link], alpha: (f64, f64), lambda: &mut [f64], p: &mut [DVec3]) {
        for (l, lam) in links.iter().zip(lambda.iter_mut()) {
            let (i, j) = (l.i as usize, l.j as usize);
            let (wi, wj) = (self.inv_mass[i], self.inv_mass[j]);
            let w = wi + wj;
            if w == 0.0 {
                continue;
            }
            let d = p[i] - p[j];
            let len = d.length();
            if len < 1e-12 {
                continue;
            }
            let c = len - l.rest_m;
            let alpha = if c < 0.0 { alpha.1 } else { alpha.0 };
            let dl = (-c - alpha * *lam) / (w + alpha);
            *lam += dl;
            let corr = d * (dl / len);
            p[i] += corr * wi;
            p[j] -= corr * wj;
        }
    }
}
