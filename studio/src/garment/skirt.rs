//! The skirt's sewing pattern: a flared tube of `rings × segments` vertices from a waistband
//! just above the waist joint to a hem below the knees, shaped around the body at rest.
//!
//! **Axis.** Ring centres run linearly from the centroid of the body's waist cross-section to
//! the midpoint of the knees (at the waist and hem heights).
//!
//! **Waistband** (ring 0, pinned): in each azimuth bin the body's radius at the waist (largest
//! distance from the axis of the trunk-and-leg vertices — those whose main joint is one of
//! [`SkirtParams::collider_joints`], the waist joint, its parents or its children — within
//! 2 cm of the waist height) plus [`SkirtParams::waist_ease_m`], or the circle
//! [`SkirtParams::waist_radius_m`]; pushed out of the colliders where they reach beyond it
//! (the pinned band must not sit inside them).
//!
//! **Below** (ring `k` at `t = k/(rings − 1)` of the length): in each azimuth the larger of
//! the waistband radius plus `t ×` [`SkirtParams::flare_m`] and the widest extent of the
//! colliders of the clear joints at this ring or any ring above plus [`SkirtParams::ease_m`]
//! — cloth hangs from the widest part of the hips, so the tube never narrows around the body.
//! A circular maximum then mean filter over ±1 bin smooths it without cutting into the
//! body. The hem ring may instead be the circle [`SkirtParams::hem_radius_m`].
//!
//! Faces are counter-clockwise seen from outside. The tube is the pattern: its edge lengths
//! and triangle areas are the cloth's rest lengths and masses; the garment's rest mesh is the
//! tube after settling under gravity ([`super::Garment::new`]).

use super::colliders::PosedColliders;
use super::{joint_named, SkirtParams, MAX_GARMENT_VERTICES};
use skin_core::check;
use skin_core::math::{DAffine3, DVec3};
use skin_core::mesh::{SkinWeights, TriMesh};
use skin_core::skeleton::Skeleton;
use skin_core::{Error, Result};
use std::f64::consts::TAU;

/// Half-height of the body slice measured for the waistband, metres.
const WAIST_SLICE_M: f64 = 0.02;
/// Farthest radius searched for colliders around the axis, metres.
const MAX_REACH_M: f64 = 1.0;
/// Radial step of that search, metres.
const REACH_STEP_M: f64 = 0.002;

/// The pattern and which vertices are pinned.
pub(super) struct SkirtPattern {
    pub(super) mesh: TriMesh,
    pub(super) pinned: Vec<bool>,
}

/// Checks the skirt's own parameters (not the cloth's).
fn check_params(p: &SkirtParams) -> Result<()> {
    check::finite("skirt.waist_above_joint_m", p.waist_above_joint_m)?;
    check::finite("skirt.hem_below_knee_m", p.hem_below_knee_m)?;
    check::non_negative("skirt.waist_ease_m", p.waist_ease_m)?;
    check::non_negative("skirt.ease_m", p.ease_m)?;
    check::non_negative("skirt.flare_m", p.flare_m)?;
    check::non_negative("skirt.settle_s", p.settle_s)?;
    if let Some(r) = p.waist_radius_m {
        check::positive("skirt.waist_radius_m", r)?;
    }
    if let Some(r) = p.hem_radius_m {
        check::positive("skirt.hem_radius_m", r)?;
    }
    if p.rings < 3 {
        return Err(Error::InvalidParam {
            name: "skirt.rings",
            reason: format!("need at least 3 rings, got {}", p.rings),
        });
    }
    if p.segments < 8 {
        return Err(Error::InvalidParam {
            name: "skirt.segments",
            reason: format!("need at least 8 segments, got {}", p.segments),
        });
    }
    let n = p.rings.saturating_mul(p.segments);
    if n > MAX_GARMENT_VERTICES {
        return Err(Error::InvalidParam {
            name: "skirt.rings × skirt.segments",
            reason: format!(
                "{} × {} = {n} vertices, more than the {MAX_GARMENT_VERTICES} a coarse garment may have",
                p.rings, p.segments
            ),
        });
    }
    if p.knee_joints.is_empty() || p.hip_joints.is_empty() {
        return Err(Error::InvalidParam {
            name: "skirt.knee_joints / skirt.hip_joints",
            reason: "need at least one knee and one hip joint".into(),
        });
    }
    Ok(())
}

/// Largest distance along `dir` from `centre` at which a point is within the margin of a
/// collider (0 when none is).
fn reach(colliders: &PosedColliders, margin: f64, centre: DVec3, dir: DVec3) -> f64 {
    let steps = (MAX_REACH_M / REACH_STEP_M) as usize;
    (0..=steps)
        .rev()
        .map(|k| k as f64 * REACH_STEP_M)
        .find(|&r| colliders.signed_distance(centre + dir * r) < margin)
        .unwrap_or(0.0)
}

/// Circular max filter then mean filter over ±1 bin: the result is ≥ the input everywhere.
fn smooth_up(r: &[f64]) -> Vec<f64> {
    let n = r.len();
    let at = |v: &[f64], i: isize| v[i.rem_euclid(n as isize) as usize];
    let m: Vec<f64> = (0..n as isize)
        .map(|i| at(r, i - 1).max(at(r, i)).max(at(r, i + 1)))
        .collect();
    (0..n as isize)
        .map(|i| (at(&m, i - 1) + at(&m, i) + at(&m, i + 1)) / 3.0)
        .collect()
}

fn azimuth_dir(phi: f64) -> DVec3 {
    DVec3::new(phi.sin(), 0.0, phi.cos())
}

/// Builds the skirt pattern around the body at rest. `profile` holds the rest colliders of
/// the clear joints (with the cloth's margin `margin`).
///
/// # Errors
/// [`Error::InvalidParam`] for bad parameters or joint names, a hem above the crotch, an
/// explicit waist smaller than the body's waist or an explicit hem that leg colliders reach
/// through; [`Error::Empty`] when the body has no vertices at the waist height.
#[allow(clippy::too_many_arguments)]
pub(super) fn pattern(
    p: &SkirtParams,
    skeleton: &Skeleton,
    frames: &[DAffine3],
    body: &TriMesh,
    weights: &SkinWeights,
    profile: &PosedColliders,
    clear: &[usize],
    margin: f64,
) -> Result<SkirtPattern> {
    check_params(p)?;
    let waist = joint_named(skeleton, &p.waist_joint, "skirt.waist_joint")?;
    let knees = p
        .knee_joints
        .iter()
        .map(|n| joint_named(skeleton, n, "skirt.knee_joints"))
        .collect::<Result<Vec<_>>>()?;
    let hips = p
        .hip_joints
        .iter()
        .map(|n| joint_named(skeleton, n, "skirt.hip_joints"))
        .collect::<Result<Vec<_>>>()?;
    let pos = |j: usize| frames[j].translation;
    let waist_y = pos(waist).y + p.waist_above_joint_m;
    let knee_mid = knees.iter().map(|&k| pos(k)).sum::<DVec3>() / knees.len() as f64;
    let hem_y = knee_mid.y - p.hem_below_knee_m;
    let crotch_y = hips.iter().map(|&h| pos(h).y).fold(f64::INFINITY, f64::min);
    if hem_y >= crotch_y {
        return Err(Error::InvalidParam {
            name: "skirt.hem_below_knee_m",
            reason: format!(
                "puts the hem at y = {hem_y:.3} m, above the crotch (hip joints at y = \
                 {crotch_y:.3} m): the skirt would not surround the legs"
            ),
        });
    }
    if waist_y <= crotch_y {
        return Err(Error::InvalidParam {
            name: "skirt.waist_above_joint_m",
            reason: format!(
                "puts the waist at y = {waist_y:.3} m, below the hip joints (y = {crotch_y:.3} m)"
            ),
        });
    }
    // The body's waist slice: vertices of the collider joints, the waist joint, its parents
    // and its children (the trunk, not the arms).
    let mut trunk = clear.to_vec();
    trunk.push(waist);
    trunk.extend(skeleton.children(waist));
    let mut up = skeleton.joints()[waist].parent;
    while let Some(j) = up {
        trunk.push(j);
        up = skeleton.joints()[j].parent;
    }
    let slice: Vec<DVec3> = body
        .vertices
        .iter()
        .enumerate()
        .filter(|(v, x)| {
            (x.y - waist_y).abs() < WAIST_SLICE_M
                && weights
                    .influences(*v)
                    .max_by(|a, b| a.1.total_cmp(&b.1))
                    .is_some_and(|(j, _)| trunk.contains(&(j as usize)))
        })
        .map(|(_, x)| *x)
        .collect();
    if slice.is_empty() {
        return Err(Error::Empty {
            what: "body vertices at the skirt's waist height",
        });
    }
    let mut c0 = slice.iter().sum::<DVec3>() / slice.len() as f64;
    c0.y = waist_y;
    let c1 = DVec3::new(knee_mid.x, hem_y, knee_mid.z);
    let s_n = p.segments;
    let bin_of = |d: DVec3| -> usize {
        let phi = d.x.atan2(d.z).rem_euclid(TAU);
        ((phi / TAU * s_n as f64).round() as usize) % s_n
    };
    let mut body_waist = vec![0.0f64; s_n];
    for x in &slice {
        let d = *x - c0;
        let r = (d.x * d.x + d.z * d.z).sqrt();
        let b = bin_of(d);
        body_waist[b] = body_waist[b].max(r);
    }
    // Fill bins no vertex fell in from their neighbours.
    while body_waist.contains(&0.0) {
        let prev = body_waist.clone();
        for (i, r) in body_waist.iter_mut().enumerate() {
            if *r == 0.0 {
                *r = prev[(i + s_n - 1) % s_n].max(prev[(i + 1) % s_n]);
            }
        }
    }
    let body_waist = smooth_up(&body_waist);
    let r0: Vec<f64> = match p.waist_radius_m {
        Some(r) => {
            let (worst, b) = body_waist
                .iter()
                .enumerate()
                .map(|(b, &w)| (w, b))
                .fold((0.0, 0), |m, x| if x.0 > m.0 { x } else { m });
            if r < worst {
                return Err(Error::InvalidParam {
                    name: "skirt.waist_radius_m",
                    reason: format!(
                        "{r} m is smaller than the body's waist, which reaches {worst:.3} m from \
                         the skirt's axis at azimuth {:.0}°",
                        360.0 * b as f64 / s_n as f64
                    ),
                });
            }
            vec![r; s_n]
        }
        None => body_waist.iter().map(|w| w + p.waist_ease_m).collect(),
    };
    // The pinned waistband must not sit inside a collider.
    let r0: Vec<f64> = smooth_up(
        &r0.iter()
            .enumerate()
            .map(|(s, r)| {
                r.max(reach(
                    profile,
                    margin,
                    c0,
                    azimuth_dir(TAU * s as f64 / s_n as f64),
                ))
            })
            .collect::<Vec<_>>(),
    );
    let rings = p.rings;
    let dirs: Vec<DVec3> = (0..s_n)
        .map(|s| azimuth_dir(TAU * s as f64 / s_n as f64))
        .collect();
    let mut widest = vec![0.0f64; s_n];
    let mut vertices = Vec::with_capacity(rings * s_n);
    vertices.extend(dirs.iter().zip(&r0).map(|(d, r)| c0 + *d * *r));
    for k in 1..rings {
        let t = k as f64 / (rings - 1) as f64;
        let c = c0.lerp(c1, t);
        for (w, d) in widest.iter_mut().zip(&dirs) {
            *w = w.max(reach(profile, margin, c, *d));
        }
        let last = k == rings - 1;
        let r: Vec<f64> = match (last, p.hem_radius_m) {
            (true, Some(h)) => {
                if let Some((b, w)) = dirs
                    .iter()
                    .map(|d| reach(profile, margin, c, *d))
                    .enumerate()
                    .find(|(_, w)| *w > h)
                {
                    return Err(Error::InvalidParam {
                        name: "skirt.hem_radius_m",
                        reason: format!(
                            "{h} m: the leg colliders reach {w:.3} m from the skirt's axis at \
                             the hem (azimuth {:.0}°), outside the hem ring",
                            360.0 * b as f64 / s_n as f64
                        ),
                    });
                }
                vec![h; s_n]
            }
            _ => {
                let raw: Vec<f64> = r0
                    .iter()
                    .zip(&widest)
                    .map(|(r, w)| {
                        let flared = match p.hem_radius_m {
                            Some(h) => r + (h - r) * t,
                            None => r + p.flare_m * t,
                        };
                        flared.max(w + p.ease_m)
                    })
                    .collect();
                smooth_up(&raw)
            }
        };
        vertices.extend(dirs.iter().zip(&r).map(|(d, r)| c + *d * *r));
    }
    let mut faces = Vec::with_capacity(2 * (rings - 1) * s_n);
    let id = |k: usize, s: usize| (k * s_n + s % s_n) as u32;
    for k in 0..rings - 1 {
        for s in 0..s_n {
            faces.push([id(k, s), id(k + 1, s), id(k + 1, s + 1)]);
            faces.push([id(k, s), id(k + 1, s + 1), id(k, s + 1)]);
        }
    }
    let mut pinned = vec![false; vertices.len()];
    pinned[..s_n].iter_mut().for_each(|x| *x = true);
    Ok(SkirtPattern {
        mesh: TriMesh::new(vertices, faces)?,
        pinned,
    })
}
