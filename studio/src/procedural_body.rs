//! The procedural performer: a smooth union of tapered capsules, one or two per bone of
//! [`human_skeleton`], meshed by [`marching_tetrahedra`], with skin weights from distance to the
//! bones. A second, simpler body than the MakeHuman mesh: closed, smooth, any size, no data
//! files — for fast tests and for methods that want a clean watertight surface.
//!
//! **Shape.** Each capsule's field is the distance to its axis segment minus a radius
//! interpolated along it; the fields are merged by the polynomial smooth minimum
//! `smin(a, b) = min(a, b) − h²·k/4`, `h = max(k − |a − b|, 0)/k` (Quílez), which blends limbs
//! into the trunk over the distance `k` ([`ProceduralBodyParams::blend_m`]).
//!
//! **Weights.** A vertex at surface distance `dⱼ` from joint j's capsules gets
//! `wⱼ ∝ exp(−(dⱼ − d_min)/σ)` for `dⱼ − d_min < 4σ`, normalised — smooth across joints and
//! rigid far from them. Bone-heat weights (Baran & Popović 2007) would be the production choice;
//! the exponential fall-off is what they reduce to on tube-like limbs and needs no solver.

use super::deformation::DeformationParams;
use super::performer::Performer;
use serde::{Deserialize, Serialize};
use skin_core::math::DVec3;
use skin_core::mesh::{marching_tetrahedra, ScalarGrid, SkinWeights};
use skin_core::skeleton::{human_skeleton, HumanParams, Skeleton};
use skin_core::{Error, Result};

/// Parameters of [`procedural_performer`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ProceduralBodyParams {
    /// Stature, metres; the skeleton and every radius scale with it. Default: 1.75.
    pub height_m: f64,
    /// Marching-tetrahedra grid spacing, metres (the mesh's edge length is about this). Default:
    /// 0.02 (≈ 10⁴ vertices).
    pub grid_spacing_m: f64,
    /// Smooth-union blend distance, metres. Default: 0.015.
    pub blend_m: f64,
    /// Weight fall-off σ, metres. Default: 0.02.
    pub weight_falloff_m: f64,
    /// The non-skinning deformation. Default: [`DeformationParams::default`].
    pub deformation: DeformationParams,
}

impl Default for ProceduralBodyParams {
    fn default() -> Self {
        ProceduralBodyParams {
            height_m: skin_core::skeleton::HumanParams::DEFAULT_HEIGHT_M,
            grid_spacing_m: 0.02,
            blend_m: 0.015,
            weight_falloff_m: 0.02,
            deformation: DeformationParams::default(),
        }
    }
}

/// A tapered capsule carried by one joint.
#[derive(Debug, Clone, Copy)]
struct Capsule {
    joint: usize,
    a: DVec3,
    b: DVec3,
    ra: f64,
    rb: f64,
}

impl Capsule {
    fn distance(&self, p: DVec3) -> f64 {
        let ab = self.b - self.a;
        let t = ((p - self.a).dot(ab) / ab.length_squared().max(1e-18)).clamp(0.0, 1.0);
        p.distance(self.a + ab * t) - (self.ra + (self.rb - self.ra) * t)
    }
}

fn smin(a: f64, b: f64, k: f64) -> f64 {
    if k <= 0.0 {
        return a.min(b);
    }
    let h = (k - (a - b).abs()).max(0.0) / k;
    a.min(b) - h * h * k * 0.25
}

/// Capsules of the body at rest, radii as fractions of the 1.75 m reference body.
fn capsules(s: &Skeleton, height_m: f64) -> Result<Vec<Capsule>> {
    let fk = s.forward_kinematics(&s.rest_pose())?;
    let w = fk.world_from_joint();
    let k = height_m / skin_core::skeleton::HumanParams::DEFAULT_HEIGHT_M;
    let j = |n: &str| {
        s.joint_index(n).ok_or_else(|| Error::InvalidParam {
            name: "skeleton",
            reason: format!("procedural body needs joint '{n}'"),
        })
    };
    let p = |n: &str| j(n).map(|i| w[i].translation);
    let tip = |n: &str| -> Result<DVec3> {
        let i = j(n)?;
        Ok(w[i].transform_point3(s.joints()[i].end_site.unwrap_or(DVec3::ZERO)))
    };
    let cap = |joint: &str, a: DVec3, b: DVec3, ra: f64, rb: f64| -> Result<Capsule> {
        Ok(Capsule {
            joint: j(joint)?,
            a,
            b,
            ra: ra * k,
            rb: rb * k,
        })
    };
    let up = DVec3::Y * k;
    let mut c = vec![
        cap(
            "pelvis",
            p("l_hip")? + up * 0.03,
            p("r_hip")? + up * 0.03,
            0.085,
            0.085,
        )?,
        cap("spine", p("spine")?, p("chest")?, 0.105, 0.10)?,
        cap("chest", p("chest")?, p("neck")? - up * 0.06, 0.11, 0.10)?,
        cap(
            "chest",
            p("l_shoulder")? - up * 0.02,
            p("r_shoulder")? - up * 0.02,
            0.055,
            0.055,
        )?,
        cap("neck", p("neck")?, p("head")?, 0.05, 0.05)?,
        cap(
            "head",
            p("head")? + up * 0.07,
            tip("head")? - up * 0.09,
            0.095,
            0.085,
        )?,
    ];
    for side in ["l", "r"] {
        let n = |b: &str| format!("{side}_{b}");
        c.push(cap(
            &n("shoulder"),
            p(&n("shoulder"))?,
            p(&n("elbow"))?,
            0.048,
            0.038,
        )?);
        c.push(cap(
            &n("elbow"),
            p(&n("elbow"))?,
            p(&n("wrist"))?,
            0.036,
            0.027,
        )?);
        c.push(cap(
            &n("wrist"),
            p(&n("wrist"))?,
            tip(&n("wrist"))?,
            0.028,
            0.02,
        )?);
        c.push(cap(&n("hip"), p(&n("hip"))?, p(&n("knee"))?, 0.075, 0.05)?);
        c.push(cap(
            &n("knee"),
            p(&n("knee"))?,
            p(&n("ankle"))?,
            0.05,
            0.035,
        )?);
        c.push(cap(
            &n("ankle"),
            p(&n("ankle"))?,
            tip(&n("ankle"))? + up * 0.02,
            0.035,
            0.022,
        )?);
    }
    Ok(c)
}

/// Builds the procedural performer on [`human_skeleton`] at `params.height_m`.
///
/// # Errors
/// [`Error::InvalidParam`] for a non-finite or non-positive height, spacing or fall-off, or
/// negative blend; as [`Performer::new`].
///
/// # Example
/// ```
/// use dynamic_shapes_studio::{procedural_performer, ProceduralBodyParams};
/// let p = procedural_performer(&ProceduralBodyParams { grid_spacing_m: 0.04, ..Default::default() })?;
/// assert_eq!(p.skeleton.dof_count(), 42);
/// # Ok::<(), skin_core::Error>(())
/// ```
pub fn procedural_performer(params: &ProceduralBodyParams) -> Result<Performer> {
    for (name, v) in [
        ("height_m", params.height_m),
        ("grid_spacing_m", params.grid_spacing_m),
        ("weight_falloff_m", params.weight_falloff_m),
    ] {
        skin_core::check::positive(name, v)?;
    }
    skin_core::check::non_negative("blend_m", params.blend_m)?;
    let skeleton = human_skeleton(&HumanParams {
        height_m: params.height_m,
    })?;
    let caps = capsules(&skeleton, params.height_m)?;
    let field = |p: DVec3| {
        caps.iter().fold(f64::INFINITY, |acc, c| {
            smin(acc, c.distance(p), params.blend_m)
        })
    };
    let h = params.grid_spacing_m;
    let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
    for c in &caps {
        let r = DVec3::splat(c.ra.max(c.rb));
        lo = lo.min(c.a.min(c.b) - r);
        hi = hi.max(c.a.max(c.b) + r);
    }
    lo -= DVec3::splat(2.0 * h);
    hi += DVec3::splat(2.0 * h);
    let dims = ((hi - lo) / h).ceil().to_array().map(|d| d as usize + 1);
    let grid = ScalarGrid::sample(lo, h, dims, field)?;
    let mesh = marching_tetrahedra(&grid, 0.0)?;
    let sigma = params.weight_falloff_m;
    let lists: Vec<Vec<(u32, f64)>> = mesh
        .vertices
        .iter()
        .map(|&v| {
            let mut per_joint = vec![f64::INFINITY; skeleton.joint_count()];
            for c in &caps {
                per_joint[c.joint] = per_joint[c.joint].min(c.distance(v));
            }
            let d_min = per_joint.iter().copied().fold(f64::INFINITY, f64::min);
            per_joint
                .iter()
                .enumerate()
                .filter(|(_, &d)| d - d_min < 4.0 * sigma)
                .map(|(j, &d)| (j as u32, (-(d - d_min) / sigma).exp()))
                .collect()
        })
        .collect();
    // `SkinWeights::from_lists` normalises each row.
    let weights = SkinWeights::from_lists(&lists, skeleton.joint_count())?;
    Performer::new("procedural", mesh, skeleton, weights, &params.deformation)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::DeformationState;

    pub(crate) fn coarse() -> Performer {
        procedural_performer(&ProceduralBodyParams {
            grid_spacing_m: 0.03,
            ..Default::default()
        })
        .unwrap()
    }

    #[test]
    fn body_is_closed_and_human_sized() {
        let p = coarse();
        let m = &p.template;
        assert!(m.vertex_count() > 2000);
        let mut uses = std::collections::HashMap::new();
        for f in &m.faces {
            for c in 0..3 {
                let (a, b) = (f[c], f[(c + 1) % 3]);
                *uses.entry((a.min(b), a.max(b))).or_insert(0) += 1;
            }
        }
        assert!(uses.values().all(|&u| u == 2), "watertight");
        let top = m.vertices.iter().map(|v| v.y).fold(f64::MIN, f64::max);
        let bottom = m.vertices.iter().map(|v| v.y).fold(f64::MAX, f64::min);
        assert!(
            (top - 1.75).abs() < 0.05 && bottom.abs() < 0.05,
            "{bottom}..{top}"
        );
        // At rest the performer equals its template.
        let f = p
            .pose(
                &p.skeleton.rest_pose(),
                &mut DeformationState::default(),
                1.0 / 30.0,
            )
            .unwrap();
        for (a, b) in f.true_vertices.iter().zip(&m.vertices) {
            assert!(a.distance(*b) < 1e-12);
        }
        assert!(f.max_nonskinning_m() == 0.0);
    }

    #[test]
    fn rejects_bad_params() {
        for p in [
            ProceduralBodyParams {
                height_m: -1.0,
                ..Default::default()
            },
            ProceduralBodyParams {
                grid_spacing_m: f64::NAN,
                ..Default::default()
            },
            ProceduralBodyParams {
                blend_m: -0.1,
                ..Default::default()
            },
            ProceduralBodyParams {
                weight_falloff_m: 0.0,
                ..Default::default()
            },
        ] {
            assert!(matches!(
                procedural_performer(&p),
                Err(Error::InvalidParam { .. })
            ));
        }
    }
}
