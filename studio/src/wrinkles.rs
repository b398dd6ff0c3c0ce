//! **Fine detail**: pose-dependent wrinkles as real geometry on a render-time refinement of
//! the performer's surface, so that rendered normals (and normal maps recovered from shaded
//! images) have millimetre-scale detail while the simulation stays coarse.
//!
//! [`WrinkleModel::new`] selects the coarse faces that can wrinkle — the joint creases of
//! [`WrinkleParams::creases`] and the garment's vertex range — and refines them once, at rest,
//! with [`Refinement`] until every edge there is at most `WRINKLE_EDGE_MARGIN` ·
//! [`WrinkleParams::max_edge_m`] long (the margin leaves room for the stretch of posing and
//! for the wrinkles' slope, so the posed, wrinkled edges stay within `max_edge_m`). The
//! refinement is crack-free and evaluated by Phong tessellation, so the fine surface is
//! smooth under the wrinkles. [`WrinkleModel::apply`] then, per frame, places the fine
//! vertices on the posed coarse vertices and moves each along the smooth surface normal
//! `n̂` (the interpolated coarse vertex normals) by a height `h`:
//!
//! * **Joint creases** (elbows, knees): `h = Σ_c a_c(θ) · A_c · e_c · sin(2π s / λ_c)`, with
//!   `a_c(θ) = smoothstep(θ_dof / θ_ref)` ([`activation_ramp`]: 0 at rest and for extension,
//!   1 from the reference flexion on, C¹), `s` the rest position along the crease's axis (the
//!   bisector of the two segments at the joint, as [`crate::EffectAxis::Joint`]), so
//!   the folds run around the limb — parallel to the flexion axis on the inner side — and
//!   `e_c = w_region · bump_along(|s| / L) · bump_around(φ)` the envelope: region skin
//!   weight, a [`Bump`] of the distance from the joint along the axis in lengths `L` of the
//!   crease's bone (mirrored about the joint: by default strongest ≈ 1.8 cm on either side
//!   of the crease line, on the upper arm and forearm (thigh and shank) faces of the bend
//!   where the skin bunches, ≈ 0.7 of that on the line itself, which linear blend skinning
//!   and the pose-driven crease tuck in out of the cameras' sight), and a [`Bump`] of the
//!   angle `φ = ∠(r̂, f̂)` around the axis from the inner side `f̂` ([`EffectSide`]; by
//!   default `cos²(90° · φ / 110°)`, [`CREASE_LOBE_RAD`], reaching the sides of the bend),
//!   evaluated at the coarse vertices and interpolated linearly, so it is exactly zero on
//!   every face that is not refined. Skin
//!   folds where it is compressed, not where it is stretched: each refined coarse face's
//!   largest principal stretch (rest → posed) scales the folds at its corners by 1 up to
//!   1.15, smoothly down to 0 at 1.3 (the lateral sides of a joint bent far past 90°), which
//!   also keeps the wrinkled edges within the bound where linear blend skinning stretches
//!   the coarse faces most.
//! * **Garment**: `h = A_g · (g_y cos(2π y / λ_g) + g_φ cos(N φ)) / max(1, g_y + g_φ)`, with
//!   `y` the rest height and `φ` the rest azimuth about the vertical through
//!   [`GarmentWrinkles::axis_joint`] (`N` folds around, `N = round(2π R̄ / λ_g)` for the
//!   garment's mean radius `R̄`, so the pattern closes), and `g_y`, `g_φ` the compression of
//!   the coarse garment along the vertical and around: per coarse vertex the mean strain
//!   `l/L − 1` of its edges weighted by `(ê·d̂)²` for direction `d̂`, mapped by
//!   `smoothstep(−strain / full_compression)`, interpolated to the fine vertices. A
//!   vertically compressed garment folds in horizontal ridges, a gathered one in vertical
//!   ones: folds perpendicular to the compression, zero when it is not compressed.
//!
//! The ground truth keeps the wrinkle displacement `h n̂` per fine vertex separately
//! ([`FineSurface::wrinkle_displacement`]), and the fine rest positions for textures.

use std::ops::Range;

use serde::{Deserialize, Serialize};

use super::muscles::{activation_ramp, Bump, EffectSide, Named};
use skin_core::check;
use skin_core::math::DVec3;
use skin_core::mesh::{
    unique_edges, FaceRefinement, RefineParams, Refinement, SkinWeights, TriMesh,
};
use skin_core::skeleton::Skeleton;
use skin_core::{Error, Result};

impl WrinkleParams {
    /// Default wrinkle amplitude (peak height of a fold above the smooth surface), metres: 2 mm,
    /// the middle of the 1–3 mm of skin creases and cloth folds.
    pub const DEFAULT_AMPLITUDE_M: f64 = 0.002;

    /// Default longest edge of the fine mesh where wrinkles are, metres: 3 mm, 6–7 edges per
    /// 2 cm fold.
    pub const DEFAULT_MAX_EDGE_M: f64 = 0.003;
}
impl CreaseWrinkles {
    /// Default crease wrinkle wavelength (fold to fold), metres: 2 cm, the middle of 1–3 cm.
    pub const DEFAULT_WAVELENGTH_M: f64 = 0.020;
}
impl GarmentWrinkles {
    /// Default garment fold wavelength, metres: 2.5 cm (cloth folds are a little wider than
    /// skin creases).
    pub const DEFAULT_WAVELENGTH_M: f64 = 0.025;

    /// Default garment compression (`1 − posed / rest` edge length) at which garment folds reach
    /// their full amplitude: 10 %.
    pub const DEFAULT_FULL_COMPRESSION: f64 = 0.10;
}
/// The rest refinement targets this share of [`WrinkleParams::max_edge_m`], so that the
/// stretch of posing (folds fade out from a principal stretch of 1.15) and the slope of the
/// folds (`2πA/λ ≈ 0.6` at the defaults, i.e. edges across a fold up to ≈ 17 % longer) keep
/// the posed wrinkled edges within the bound: `0.7 · 1.15 · 1.17 ≈ 0.94`.
pub(crate) const WRINKLE_EDGE_MARGIN: f64 = 0.7;

/// Default angular half-width of the crease folds around the limb, radians: 110° from the
/// inner side (`cos²(90° · φ / 110°)`, half strength at 55°), wider than the lobe
/// `max(0, r̂·f̂)²` (half strength at 45°, zero at 90°), so that the folds reach the sides
/// of the bend that cameras see.
pub const CREASE_LOBE_RAD: f64 = 110.0 * std::f64::consts::PI / 180.0;

/// Wrinkles at one joint crease, driven by one flexion DOF.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CreaseWrinkles {
    /// Name, unique within [`WrinkleParams::creases`] (e.g. `"l_elbow"`).
    pub name: String,
    /// Driving rotation DOF (e.g. `"l_elbow.flexion"`).
    pub dof: String,
    /// Flexion at which the folds reach full amplitude, radians, signed (the folds are off
    /// for the other sign), finite and non-zero. Default: 90°.
    pub reference_rad: f64,
    /// Fold amplitude at full activation and envelope, metres, finite and ≥ 0. Default:
    /// [`WrinkleParams::DEFAULT_AMPLITUDE_M`].
    pub amplitude_m: f64,
    /// Fold wavelength along the limb, metres, finite and > 0. Default:
    /// [`CreaseWrinkles::DEFAULT_WAVELENGTH_M`].
    pub wavelength_m: f64,
    /// Joint whose segment ends at the crease's joint (e.g. `"l_shoulder"` for the elbow: the
    /// upper arm); it must have exactly one child joint.
    pub bone: String,
    /// Joints whose summed skin weight scales the folds per vertex, not empty.
    pub region: Vec<String>,
    /// Profile of the distance `|s|` from the joint along the crease axis, in lengths of
    /// `bone`'s segment (mirrored about the joint, so a `peak > 0` puts the folds on both
    /// sides of the crease line).
    pub along: Bump,
    /// Profile of the angle `φ = ∠(r̂, f̂)` around the axis from the inner side, radians
    /// (`φ ∈ [0, π]`; `Bump { peak: 0, before: π/2, after: π/2 }` is the lobe
    /// `max(0, r̂·f̂)²`).
    pub around: Bump,
    /// The inner side of the joint (where the skin folds).
    pub side: EffectSide,
}

/// Folds of the garment, driven by its compression.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GarmentWrinkles {
    /// Fold amplitude at full compression, metres, finite and ≥ 0. Default:
    /// [`WrinkleParams::DEFAULT_AMPLITUDE_M`].
    pub amplitude_m: f64,
    /// Fold wavelength, metres, finite and > 0. Default: [`GarmentWrinkles::DEFAULT_WAVELENGTH_M`].
    pub wavelength_m: f64,
    /// Compression (`1 − l/L`) giving full amplitude, finite and > 0. Default:
    /// [`GarmentWrinkles::DEFAULT_FULL_COMPRESSION`].
    pub full_compression: f64,
    /// Joint whose rest vertical line is the garment's axis (azimuth of the vertical folds).
    /// Default: `"pelvis"`.
    pub axis_joint: String,
}

impl Default for GarmentWrinkles {
    fn default() -> Self {
        Self {
            amplitude_m: WrinkleParams::DEFAULT_AMPLITUDE_M,
            wavelength_m: GarmentWrinkles::DEFAULT_WAVELENGTH_M,
            full_compression: GarmentWrinkles::DEFAULT_FULL_COMPRESSION,
            axis_joint: "pelvis".into(),
        }
    }
}

/// Parameters of the fine detail: refinement and wrinkle regions.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WrinkleParams {
    /// Longest fine edge where wrinkles are, metres, finite and > 0. Default:
    /// [`WrinkleParams::DEFAULT_MAX_EDGE_M`].
    pub max_edge_m: f64,
    /// Phong tessellation factor of the smooth fine surface, in `[0, 1]`. Default:
    /// [`skin_core::mesh::RefineParams::DEFAULT_PHONG_ALPHA`].
    pub phong_alpha: f64,
    /// Joint creases.
    pub creases: Vec<CreaseWrinkles>,
    /// Garment folds (used when [`WrinkleModel::new`] gets a non-empty garment range).
    pub garment: GarmentWrinkles,
    /// Refine **every** face of the template to the edge bound, not only the wrinkle
    /// regions. Default: `false`. With it (and the amplitudes at 0 for a smooth surface
    /// without folds) the whole fine surface is the Phong-tessellated smooth surface, so its
    /// facets and its interpolated vertex normals agree to within a small angle everywhere —
    /// a truth whose geometry (depth, silhouettes) and shading normals are the same surface.
    /// The wrinkles themselves do not change (the same folds on the same smooth surface; the
    /// fine vertices are numbered differently).
    #[serde(default)]
    pub refine_all_faces: bool,
}

impl Default for WrinkleParams {
    /// Elbow and knee creases of both sides for the joint and DOF names of
    /// [`human_skeleton`](skin_core::skeleton::human_skeleton) (MakeHuman and procedural
    /// performers): 2 mm folds of 2 cm wavelength at 90° of flexion on the inner side (the
    /// flexor side of the elbow, the back of the knee), strongest ≈ 1.8 cm either side of
    /// the crease line (6 % of the upper arm, 4 % of the thigh; ≈ 0.7 of that on the line
    /// itself) and fading out ≈ 6 cm from the joint, on the faces of the bend where the skin
    /// bunches and cameras see it (the crease line itself is where linear blend skinning and
    /// the pose-driven crease tuck the skin in); around the limb over ±110° from the inner
    /// side ([`CREASE_LOBE_RAD`], half strength at ±55°); the garment's defaults; 3 mm edges.
    fn default() -> Self {
        let mut creases = Vec::new();
        for s in ["l", "r"] {
            for (joint, bone, region, (peak, before, after)) in [
                (
                    "elbow",
                    "shoulder",
                    ["shoulder", "elbow"],
                    (0.06, 0.16, 0.15),
                ),
                ("knee", "hip", ["hip", "knee"], (0.04, 0.10, 0.10)),
            ] {
                creases.push(CreaseWrinkles {
                    name: format!("{s}_{joint}"),
                    dof: format!("{s}_{joint}.flexion"),
                    reference_rad: 90f64.to_radians(),
                    amplitude_m: WrinkleParams::DEFAULT_AMPLITUDE_M,
                    wavelength_m: CreaseWrinkles::DEFAULT_WAVELENGTH_M,
                    bone: format!("{s}_{bone}"),
                    region: region.iter().map(|r| format!("{s}_{r}")).collect(),
                    along: Bump {
                        peak,
                        before,
                        after,
                    },
                    around: Bump {
                        peak: 0.0,
                        before: CREASE_LOBE_RAD,
                        after: CREASE_LOBE_RAD,
                    },
                    side: EffectSide::Towards(format!("{s}_{joint}.flexion")),
                });
            }
        }
        Self {
            max_edge_m: WrinkleParams::DEFAULT_MAX_EDGE_M,
            phong_alpha: skin_core::mesh::RefineParams::DEFAULT_PHONG_ALPHA,
            creases,
            garment: GarmentWrinkles::default(),
            refine_all_faces: false,
        }
    }
}

impl WrinkleParams {
    /// These parameters with every amplitude (creases and garment) set to `amplitude_m`;
    /// 0 switches the wrinkles off and leaves the smooth fine surface (same refinement).
    pub fn with_amplitude_m(mut self, amplitude_m: f64) -> Self {
        for c in &mut self.creases {
            c.amplitude_m = amplitude_m;
        }
        self.garment.amplitude_m = amplitude_m;
        self
    }

    /// These parameters with the longest fine edge `max_edge_m`.
    pub fn with_max_edge_m(mut self, max_edge_m: f64) -> Self {
        self.max_edge_m = max_edge_m;
        self
    }

    /// These parameters refining every face (`true`) or only the wrinkle regions (`false`,
    /// the default); see [`WrinkleParams::refine_all_faces`].
    pub fn with_refine_all_faces(mut self, all: bool) -> Self {
        self.refine_all_faces = all;
        self
    }

    /// A smooth fine surface without wrinkles: every face refined to edges of at most
    /// 0.7 · `max_edge_m` at rest (a margin for the stretch of posing), all amplitudes 0 — the
    /// performer's polygonal surface made smooth and consistent (facets close to the shading
    /// normals) at render time.
    pub fn smooth_surface(max_edge_m: f64) -> Self {
        Self::default()
            .with_amplitude_m(0.0)
            .with_max_edge_m(max_edge_m)
            .with_refine_all_faces(true)
    }
}

/// One crease, precomputed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct CreaseModel {
    dof: usize,
    reference_rad: f64,
    /// Origin (the joint), unit axis, unit inner side and bone length at rest.
    origin: DVec3,
    axis: DVec3,
    side: DVec3,
    /// (fine vertex, height at full activation, metres).
    heights: Vec<(u32, f64)>,
}

/// The garment, precomputed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct GarmentModel {
    amplitude_m: f64,
    full_compression: f64,
    /// Garment edges `(a, b, rest length)`.
    edges: Vec<(u32, u32, f64)>,
    /// Least-squares strain terms `(garment vertex − range.start, edge, vertical
    /// coefficient, around coefficient)`: the vertex's strain tensor components along the
    /// vertical and around are `Σ coefficient · strain(edge)` over its terms.
    strain_terms: Vec<(u32, u32, f64, f64)>,
    range: Range<usize>,
    /// (fine vertex, vertical pattern, around pattern).
    patterns: Vec<(u32, f64, f64)>,
}

/// The fine, wrinkled surface of one frame.
#[derive(Debug, Clone, PartialEq)]
pub struct FineSurface {
    /// The fine mesh, posed, with wrinkles, metres.
    pub mesh: TriMesh,
    /// Wrinkle displacement per fine vertex (already in `mesh`), metres; zero where there is
    /// none.
    pub wrinkle_displacement: Vec<DVec3>,
    /// Rest position of every fine vertex (on the smooth rest surface), metres: where
    /// textures are evaluated.
    pub rest_positions: Vec<DVec3>,
}

impl FineSurface {
    /// Largest wrinkle displacement, metres.
    pub fn max_wrinkle_m(&self) -> f64 {
        self.wrinkle_displacement
            .iter()
            .map(|d| d.length())
            .fold(0.0, f64::max)
    }
}

/// Pose-dependent wrinkles on a refined surface, precomputed for one template and skeleton.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WrinkleModel {
    params: WrinkleParams,
    dof_count: usize,
    refinement: Refinement,
    rest_positions: Vec<DVec3>,
    creases: Vec<CreaseModel>,
    garment: Option<GarmentModel>,
    /// Fine vertices some wrinkle can move, ascending.
    wrinkle_vertices: Vec<u32>,
    /// Per fine face: part of the garment.
    garment_faces: Vec<bool>,
    /// Refined body faces `(face, inverse of the rest edge matrix in the face's own 2-D
    /// frame)`, for the stretch that smooths creases out.
    stretch_faces: Vec<(u32, [[f64; 2]; 2])>,
}

/// Largest principal stretch of face `f` from rest to posed, given the inverse `r_inv` of its
/// rest edge matrix in 2-D.
fn principal_stretch(f: [DVec3; 3], r_inv: &[[f64; 2]; 2]) -> f64 {
    let (p1, p2) = (f[1] - f[0], f[2] - f[0]);
    // F = [p1 p2] · R⁻¹ (3×2), columns g1, g2.
    let g1 = p1 * r_inv[0][0] + p2 * r_inv[1][0];
    let g2 = p1 * r_inv[0][1] + p2 * r_inv[1][1];
    let (a, b, c) = (g1.dot(g1), g1.dot(g2), g2.dot(g2));
    let tr = a + c;
    let det = a * c - b * b;
    (0.5 * (tr + (tr * tr - 4.0 * det).max(0.0).sqrt())).sqrt()
}

/// Principal stretch up to which creases fold fully.
const FOLD_STRETCH_FULL: f64 = 1.15;
/// Principal stretch from which creases are smooth.
const FOLD_STRETCH_NONE: f64 = 1.3;

/// The [`Named`] of crease `name`.
fn crease(name: &str) -> Named<'_> {
    Named {
        list: "wrinkles.creases",
        kind: "crease",
        long_kind: "crease",
        name,
    }
}

impl WrinkleModel {
    /// Precomputes the wrinkles of `template` (rest pose of `skeleton`, skinned by `weights`)
    /// with the garment at template vertices `garment_vertices` (may be empty): selects and
    /// refines the wrinkle regions, places the fine rest surface, and tabulates every fold's
    /// pattern.
    ///
    /// # Errors
    /// [`Error::InvalidParam`] for an unknown or non-rotation DOF, an unknown joint, a
    /// negative or non-finite amplitude, a non-positive wavelength, edge bound or full
    /// compression, a zero reference angle, a bad profile, a duplicate crease name, a joint
    /// without exactly one child as a crease bone, a garment range past the template;
    /// [`Error::SizeMismatch`] for weights of another template or skeleton; as
    /// [`TriMesh::validate`] and [`Refinement::new`]; [`Error::Degenerate`] for a zero-length
    /// bone or a folded joint.
    pub fn new(
        params: WrinkleParams,
        skeleton: &Skeleton,
        template: &TriMesh,
        weights: &SkinWeights,
        garment_vertices: Range<usize>,
    ) -> Result<WrinkleModel> {
        template.validate()?;
        let nv = template.vertex_count();
        check::same_size(
            "skin weight rows vs template vertices",
            nv,
            weights.vertex_count(),
        )?;
        check::same_size(
            "skin weight bones vs skeleton joints",
            skeleton.joint_count(),
            weights.bone_count(),
        )?;
        check::positive("wrinkles.max_edge_m", params.max_edge_m)?;
        check::in_range("wrinkles.phong_alpha", params.phong_alpha, 0.0..=1.0)?;
        if garment_vertices.start > garment_vertices.end || garment_vertices.end > nv {
            return Err(Error::InvalidParam {
                name: "garment_vertices",
                reason: format!(
                    "{garment_vertices:?} is not a range of the template's {nv} vertices"
                ),
            });
        }
        let in_garment = |v: usize| garment_vertices.contains(&v);
        let rest = skeleton.forward_kinematics(&skeleton.rest_pose())?;
        let frames = rest.world_from_joint();

        // Crease geometry and the envelope at the coarse vertices.
        let mut envelopes = Vec::with_capacity(params.creases.len());
        let mut geometry = Vec::with_capacity(params.creases.len());
        for (i, c) in params.creases.iter().enumerate() {
            let n = crease(&c.name);
            let wrap = |e| n.wrap(e);
            if params.creases[..i].iter().any(|o| o.name == c.name) {
                return Err(n.invalid("duplicate crease name".into()));
            }
            let dof = n.dof(skeleton, &c.dof)?;
            check::non_negative("amplitude_m", c.amplitude_m).map_err(wrap)?;
            check::positive("wavelength_m", c.wavelength_m).map_err(wrap)?;
            check::positive("|reference_rad|", c.reference_rad.abs()).map_err(wrap)?;
            check::finite("along.peak", c.along.peak).map_err(wrap)?;
            check::positive("along.before", c.along.before).map_err(wrap)?;
            check::positive("along.after", c.along.after).map_err(wrap)?;
            check::finite("around.peak", c.around.peak).map_err(wrap)?;
            check::positive("around.before", c.around.before).map_err(wrap)?;
            check::positive("around.after", c.around.after).map_err(wrap)?;
            check::nonzero("region (count)", c.region.len()).map_err(wrap)?;
            let region = c
                .region
                .iter()
                .map(|j| n.joint(skeleton, j))
                .collect::<Result<Vec<_>>>()?;
            let bone = n.joint(skeleton, &c.bone)?;
            let segment = n.segment(skeleton, frames, bone)?;
            let length = segment.2;
            let (origin, axis) = n.joint_axis(skeleton, frames, bone, segment)?;
            let side = n.side(skeleton, &rest, &c.side, axis)?;
            let env: Vec<f64> = template
                .vertices
                .iter()
                .enumerate()
                .map(|(v, x)| {
                    if in_garment(v) {
                        return 0.0;
                    }
                    let w: f64 = weights
                        .influences(v)
                        .filter(|q| region.contains(&(q.0 as usize)))
                        .map(|q| q.1)
                        .sum();
                    let along = (*x - origin).dot(axis);
                    let radial = (*x - origin - axis * along).normalize_or_zero();
                    let phi = radial.dot(side).clamp(-1.0, 1.0).acos();
                    w * c.along.value(along.abs() / length) * c.around.value(phi)
                })
                .collect();
            envelopes.push(env);
            geometry.push(CreaseModel {
                dof,
                reference_rad: c.reference_rad,
                origin,
                axis,
                side,
                heights: Vec::new(),
            });
        }
        let g = &params.garment;
        let garment_on = !garment_vertices.is_empty();
        if garment_on {
            check::non_negative("garment.amplitude_m", g.amplitude_m)?;
            check::positive("garment.wavelength_m", g.wavelength_m)?;
            check::positive("garment.full_compression", g.full_compression)?;
        }

        // Refine every face touching a wrinkle region (or every face).
        let wrinkle_faces: Vec<bool> = template
            .faces
            .iter()
            .map(|f| {
                f.iter().any(|&v| {
                    let v = v as usize;
                    in_garment(v) || envelopes.iter().any(|e| e[v] > 0.0)
                })
            })
            .collect();
        let refine = RefineParams::new(params.max_edge_m * WRINKLE_EDGE_MARGIN)
            .with_phong_alpha(params.phong_alpha);
        let refinement = if params.refine_all_faces {
            Refinement::new(template, &vec![true; template.face_count()], &refine)?
        } else {
            Refinement::new(template, &wrinkle_faces, &refine)?
        };
        let rest_positions = refinement.evaluate(&template.vertices)?.vertices;
        let nf = refinement.fine_vertex_count();
        let mut moved = vec![false; nf];

        for (crease, (env, p)) in geometry
            .iter_mut()
            .zip(envelopes.iter().zip(&params.creases))
        {
            let fine_env = refinement.interpolate(env)?;
            let k = std::f64::consts::TAU / p.wavelength_m;
            for (i, (e, x)) in fine_env.iter().zip(&rest_positions).enumerate() {
                if *e > 0.0 {
                    let s = (*x - crease.origin).dot(crease.axis);
                    crease
                        .heights
                        .push((i as u32, p.amplitude_m * e * (k * s).sin()));
                    moved[i] = true;
                }
            }
        }

        let garment = if garment_on {
            let axis_joint =
                skeleton
                    .joint_index(&g.axis_joint)
                    .ok_or_else(|| Error::InvalidParam {
                        name: "garment.axis_joint",
                        reason: format!("the skeleton has no joint '{}'", g.axis_joint),
                    })?;
            let centre = frames[axis_joint].translation;
            let around = |x: DVec3| DVec3::Y.cross(x - centre).normalize_or_zero();
            let edges: Vec<(u32, u32, f64)> = unique_edges(template)?
                .into_iter()
                .filter(|e| in_garment(e[0] as usize) && in_garment(e[1] as usize))
                .map(|[a, b]| {
                    let len = template.vertices[a as usize].distance(template.vertices[b as usize]);
                    (a, b, len)
                })
                .filter(|e| e.2 > 0.0)
                .collect();
            // Per vertex, the strain tensor E (vertical, around) fitting ε_e ≈ uᵀ E u over its
            // edges by least squares: E = M⁻¹ Σ a_e ε_e with a_e = (u₁², 2u₁u₂, u₂²).
            let mut star: Vec<Vec<(u32, [f64; 3])>> = vec![Vec::new(); garment_vertices.len()];
            for (k, &(a, b, len)) in edges.iter().enumerate() {
                for v in [a, b] {
                    let x = template.vertices[v as usize];
                    let d = (template.vertices[(a + b - v) as usize] - x) / len;
                    let (u1, u2) = (d.y, d.dot(around(x)));
                    star[v as usize - garment_vertices.start]
                        .push((k as u32, [u1 * u1, 2.0 * u1 * u2, u2 * u2]));
                }
            }
            let mut strain_terms = Vec::new();
            for (v, terms) in star.iter().enumerate() {
                let mut m = nalgebra::Matrix3::<f64>::zeros();
                for (_, a) in terms {
                    let a = nalgebra::Vector3::from(*a);
                    m += a * a.transpose();
                }
                let Some(inv) = m.try_inverse() else {
                    continue;
                };
                for &(e, a) in terms {
                    let c = inv * nalgebra::Vector3::from(a);
                    strain_terms.push((v as u32, e, c[0], c[2]));
                }
            }
            let radius = garment_vertices
                .clone()
                .map(|v| {
                    let d = template.vertices[v] - centre;
                    (d.x * d.x + d.z * d.z).sqrt()
                })
                .sum::<f64>()
                / garment_vertices.len() as f64;
            let folds = (std::f64::consts::TAU * radius / g.wavelength_m)
                .round()
                .max(1.0);
            let mut garment_coarse = vec![0.0; nv];
            garment_vertices
                .clone()
                .for_each(|v| garment_coarse[v] = 1.0);
            let share = refinement.interpolate(&garment_coarse)?;
            let k = std::f64::consts::TAU / g.wavelength_m;
            let patterns = rest_positions
                .iter()
                .zip(&share)
                .enumerate()
                .filter(|(_, (_, s))| **s > 0.0)
                .map(|(i, (x, _))| {
                    moved[i] = true;
                    let phi = (x.x - centre.x).atan2(x.z - centre.z);
                    (i as u32, (k * x.y).cos(), (folds * phi).cos())
                })
                .collect();
            Some(GarmentModel {
                amplitude_m: g.amplitude_m,
                full_compression: g.full_compression,
                edges,
                strain_terms,
                range: garment_vertices.clone(),
                patterns,
            })
        } else {
            None
        };
        let garment_faces = refinement
            .faces()
            .iter()
            .zip(refinement.face_parents())
            .map(|(_, &p)| {
                template.faces[p as usize]
                    .iter()
                    .all(|&v| in_garment(v as usize))
            })
            .collect();
        let wrinkle_vertices = (0..nf as u32).filter(|&i| moved[i as usize]).collect();
        let stretch_faces = template
            .faces
            .iter()
            .enumerate()
            .filter(|(f, face)| wrinkle_faces[*f] && !face.iter().all(|&v| in_garment(v as usize)))
            .filter_map(|(f, face)| {
                let [x0, x1, x2] = face.map(|v| template.vertices[v as usize]);
                let (e1, e2) = (x1 - x0, x2 - x0);
                let a = e1.try_normalize()?;
                let b = (e2 - a * a.dot(e2)).try_normalize()?;
                // R = [[e1·a, e2·a], [0, e2·b]]; its inverse.
                let (r00, r01, r11) = (e1.dot(a), e2.dot(a), e2.dot(b));
                if r00 * r11 <= 1e-18 {
                    return None;
                }
                let inv = [[1.0 / r00, -r01 / (r00 * r11)], [0.0, 1.0 / r11]];
                Some((f as u32, inv))
            })
            .collect();
        Ok(WrinkleModel {
            params,
            dof_count: skeleton.dof_count(),
            refinement,
            rest_positions,
            creases: geometry,
            garment,
            wrinkle_vertices,
            garment_faces,
            stretch_faces,
        })
    }

    /// The parameters.
    pub fn params(&self) -> &WrinkleParams {
        &self.params
    }

    /// The refinement (fine topology and how fine vertices sit on coarse ones).
    pub fn refinement(&self) -> &Refinement {
        &self.refinement
    }

    /// Number of fine vertices.
    pub fn fine_vertex_count(&self) -> usize {
        self.refinement.fine_vertex_count()
    }

    /// The fine faces.
    pub fn fine_faces(&self) -> &[[u32; 3]] {
        self.refinement.faces()
    }

    /// Fine rest positions (the smooth refined template).
    pub fn rest_positions(&self) -> &[DVec3] {
        &self.rest_positions
    }

    /// The fine vertices some wrinkle can move (crease envelopes or garment), ascending.
    pub fn wrinkle_vertices(&self) -> &[u32] {
        &self.wrinkle_vertices
    }

    /// Per fine face: whether it lies on the garment (all corners of its coarse face are
    /// garment vertices) — the material of a texture.
    pub fn garment_faces(&self) -> &[bool] {
        &self.garment_faces
    }

    /// Per fine face: whether its coarse face was refined (a wrinkle region).
    pub fn refined_faces(&self) -> Vec<bool> {
        let kinds = self.refinement.coarse_face_kinds();
        self.refinement
            .face_parents()
            .iter()
            .map(|&p| kinds[p as usize] == FaceRefinement::Refined)
            .collect()
    }

    /// Activation of each crease at θ, in `[0, 1]` (crease order of the parameters).
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] for a pose of another skeleton; [`Error::NonFinite`].
    pub fn crease_activations(&self, theta: &[f64]) -> Result<Vec<f64>> {
        check::same_size("pose DOFs", self.dof_count, theta.len())?;
        check::all_finite("pose", theta)?;
        Ok(self
            .creases
            .iter()
            .map(|c| activation_ramp(theta[c.dof] / c.reference_rad))
            .collect())
    }

    /// Per coarse garment vertex `(vertical, around)` fold strength in `[0, 1]` from the
    /// compression of `coarse_posed` against the rest template (empty without a garment).
    fn garment_strength(&self, g: &GarmentModel, coarse_posed: &[DVec3]) -> Vec<[f64; 2]> {
        let strain: Vec<f64> = g
            .edges
            .iter()
            .map(|&(a, b, len)| {
                coarse_posed[a as usize].distance(coarse_posed[b as usize]) / len - 1.0
            })
            .collect();
        let mut tensor = vec![[0.0f64; 2]; g.range.len()];
        for &(v, e, cv, ca) in &g.strain_terms {
            let t = &mut tensor[v as usize];
            t[0] += cv * strain[e as usize];
            t[1] += ca * strain[e as usize];
        }
        tensor
            .iter()
            .map(|t| t.map(|x| activation_ramp(-x / g.full_compression)))
            .collect()
    }

    /// Per coarse vertex, the share of the crease folds that survives the local stretch: 1
    /// up to a principal stretch of 1.15 of every refined face around it, 0 from 1.3 on
    /// (stretched skin is smooth; compressed skin folds), smooth in between.
    fn fold_share(&self, coarse_posed: &[DVec3]) -> Vec<f64> {
        let mut share = vec![1.0f64; coarse_posed.len()];
        let faces = self.refinement.coarse_faces();
        for (f, r_inv) in &self.stretch_faces {
            let face = faces[*f as usize];
            let s = principal_stretch(face.map(|v| coarse_posed[v as usize]), r_inv);
            let k = 1.0
                - activation_ramp(
                    (s - FOLD_STRETCH_FULL) / (FOLD_STRETCH_NONE - FOLD_STRETCH_FULL),
                );
            for v in face {
                let x = &mut share[v as usize];
                *x = x.min(k);
            }
        }
        share
    }

    /// The fine, wrinkled surface at pose θ on the posed coarse vertices `coarse_posed` (one
    /// per template vertex, e.g. [`crate::PosedFrame::true_vertices`] with the
    /// simulated garment).
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] for a pose of another skeleton or vertices of another
    /// template; [`Error::NonFinite`] for non-finite input.
    pub fn apply(&self, theta: &[f64], coarse_posed: &[DVec3]) -> Result<FineSurface> {
        let activations = self.crease_activations(theta)?;
        let normals = self.refinement.coarse_normals(coarse_posed)?;
        let mut vertices = self
            .refinement
            .evaluate_with_normals(coarse_posed, &normals)?;
        let nf = vertices.len();
        let mut height = vec![0.0f64; nf];
        if activations.iter().any(|&a| a != 0.0) {
            let share = self.fold_share(coarse_posed);
            let fine_share = |i: u32| {
                self.refinement.point(i as usize).map_or(0.0, |p| {
                    (0..3)
                        .map(|k| share[p.corners[k] as usize] * p.bary[k])
                        .sum::<f64>()
                })
            };
            for (c, a) in self.creases.iter().zip(activations) {
                if a == 0.0 {
                    continue;
                }
                for &(i, h) in &c.heights {
                    height[i as usize] += a * h * fine_share(i);
                }
            }
        }
        if let Some(g) = &self.garment {
            let strength = self.garment_strength(g, coarse_posed);
            if strength.iter().any(|s| s[0] > 0.0 || s[1] > 0.0) {
                for &(i, pv, pa) in &g.patterns {
                    let Some(p) = self.refinement.point(i as usize) else {
                        continue;
                    };
                    let (mut gy, mut ga) = (0.0, 0.0);
                    for (c, b) in p.corners.iter().zip(p.bary) {
                        if let Some(s) = (*c as usize)
                            .checked_sub(g.range.start)
                            .and_then(|k| strength.get(k))
                        {
                            gy += b * s[0];
                            ga += b * s[1];
                        }
                    }
                    height[i as usize] += g.amplitude_m * (gy * pv + ga * pa) / (gy + ga).max(1.0);
                }
            }
        }
        let mut displacement = vec![DVec3::ZERO; nf];
        for &i in &self.wrinkle_vertices {
            let i = i as usize;
            let h = height[i];
            if h == 0.0 {
                continue;
            }
            let Some(p) = self.refinement.point(i) else {
                continue;
            };
            let n = (0..3)
                .map(|k| normals[p.corners[k] as usize] * p.bary[k])
                .sum::<DVec3>()
                .normalize_or_zero();
            let d = n * h;
            displacement[i] = d;
            vertices[i] += d;
        }
        Ok(FineSurface {
            mesh: TriMesh {
                vertices,
                faces: self.refinement.faces().to_vec(),
            },
            wrinkle_displacement: displacement,
            rest_positions: self.rest_positions.clone(),
        })
    }
}

#[cfg(test)]
mod tests;
