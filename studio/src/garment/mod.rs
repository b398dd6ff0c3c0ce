//! Loose garments with second-order dynamics: a **skirt** (waist to below the knee) and a
//! **sheet** draped over the standing figure (the thesis's "Ghost", for non-articulated
//! reconstruction). Each is its own surface, simulated as cloth and driven by the body: what
//! no skinned surface can show (lag, swing, folds pushed up by the legs).
//!
//! * Cloth ([`ClothParams`], module `cloth`): XPBD "small steps" — a mass–spring equivalent
//!   with inertia, gravity and damping that is unconditionally stable and deterministic
//!   (serial, fixed-order loops: bit-identical output for any thread count).
//! * Colliders (module `colliders`): tapered capsules on the joint frames, fitted at rest to
//!   cover the body template, with a margin and Coulomb friction; a floor for the sheet. Run
//!   every substep.
//! * Body surface (module `body`): after each frame's substeps every free vertex is put at
//!   least the margin outside the posed body mesh itself (trunk and legs for the skirt — arms
//!   are no colliders, a hand may pass through the skirt — the whole body for the sheet),
//!   with its velocity into the body removed. The capsules fit a flat trunk and a skinned
//!   bend only roughly; this makes the no-penetration guarantee exact.
//! * Skirt ([`SkirtParams`], module `skirt`): a flared tube shaped around the body's waist and
//!   hips, its waistband pinned to the skinned garment.
//! * Sheet ([`SheetParams`], module `sheet`): a square grid dropped onto the figure; where it
//!   rests on head and shoulders it is pinned.
//!
//! **Rest mesh = scan.** [`Garment::new`] builds the pattern and lets it settle under gravity
//! on the body at rest (θ = 0): the settled drape is [`Garment::rest_mesh`], the template a
//! method would have scanned. **Skinned reference.** [`Garment::weights`] attach the rest mesh
//! to the skeleton like any skinned template (see there); the integrator poses it with
//! [`skin_core::mesh::skin`] and passes the result, with the posed body's vertices, to
//! [`Garment::step`], which pins the pinned vertices to it and simulates the rest. The difference between the two is the garment's
//! non-skinning deformation.
//!
//! **Sizes.** Defaults: skirt 32 rings × 72 segments = 2,304 vertices, sheet 48 × 48 = 2,304
//! vertices; at most [`MAX_GARMENT_VERTICES`].

mod body;
mod cloth;
mod colliders;
mod sheet;
mod skirt;
#[cfg(test)]
pub(crate) mod tests;

use body::BodySurface;
use cloth::Cloth;
use colliders::Colliders;
use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};
use skin_core::check;
use skin_core::math::{DAffine3, DVec3};
use skin_core::mesh::{vertex_neighbors, MeshQuery, SkinWeights, TriMesh};
use skin_core::skeleton::Skeleton;
use skin_core::{Error, Result};

/// Most vertices a garment may have: the cloth is simulated coarse, so that its step fits the
/// studio's per-frame budget.
pub const MAX_GARMENT_VERTICES: usize = 5000;

/// Damping while a garment settles at construction, 1/s (at least this much, whatever
/// [`ClothParams::damping_per_s`] says): it only shortens the settling, the rest drape is the
/// same.
pub const SETTLE_DAMPING_PER_S: f64 = 4.0;

/// Jacobi smoothing passes over the garment's skin weights ([`Garment::weights`]).
pub const WEIGHT_SMOOTHING_PASSES: usize = 10;

/// Frame time of the settling simulation, seconds.
const SETTLE_FRAME_S: f64 = 1.0 / 30.0;

/// Parameters of the cloth simulation (XPBD). Compliances are per constraint, so they scale
/// with resolution: the defaults suit edges of 2–5 cm.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ClothParams {
    /// Areal density, kg/m² (vertex mass = a third of the adjacent triangles' pattern area ×
    /// density). Default: 0.25 (a medium cotton or light wool).
    pub density_kg_per_m2: f64,
    /// Compliance of the stretch (edge length) constraints, m/N (inverse stiffness; 0 =
    /// inextensible). Default: 1e-6 — stiffer than the substeps can resolve, so the cloth
    /// barely stretches.
    pub stretch_compliance_m_per_n: f64,
    /// Compliance of the bending constraints (distance between the vertices opposite each
    /// interior edge), m/N. Default: 1.0 — soft enough to fold and drape, stiff enough to keep
    /// the coarse mesh from crumpling.
    pub bend_compliance_m_per_n: f64,
    /// Velocity damping rate, 1/s (`v ← v e^{−c h}` each substep). Default: 1.5 — the air
    /// drag on a light fabric (≈ ρ_air · C_d · |v| / areal density = 1.2 kg/m³ × 1 × 0.3 m/s /
    /// 0.25 kg/m²): the hem still lags and swings visibly, and a swing dies within about 2 s.
    pub damping_per_s: f64,
    /// Gravity, m/s², acting along −Y. Default: 9.81.
    pub gravity_m_per_s2: f64,
    /// Longest substep, seconds (a frame of `dt` runs `⌈dt / max_substep_s⌉` substeps).
    /// Default: 0.002 (17 substeps per 1/30 s frame).
    pub max_substep_s: f64,
    /// Constraint iterations per substep. Default: 1 (small steps: more substeps beat more
    /// iterations).
    pub iterations: usize,
    /// Clearance kept between cloth vertices and every collider, metres. Default: 0.008.
    pub collision_margin_m: f64,
    /// Coulomb friction coefficient against the body (dimensionless). Default: 0.3.
    pub friction: f64,
    /// Cap on a vertex's speed after each substep, m/s (`None`: no cap). Default: `None`
    /// (the skirt never needs it); the sheet's default ([`SheetParams::default`]) is 10 m/s —
    /// why in the cloth module's docs (a push-out at a non-rest first frame turned into a
    /// whip along the hanging sheet). Missing in serialised parameters = `None`.
    #[serde(default)]
    pub max_speed_m_per_s: Option<f64>,
}

impl Default for ClothParams {
    fn default() -> Self {
        ClothParams {
            density_kg_per_m2: 0.25,
            stretch_compliance_m_per_n: 1e-6,
            bend_compliance_m_per_n: 1.0,
            damping_per_s: 1.5,
            gravity_m_per_s2: 9.81,
            max_substep_s: 0.002,
            iterations: 1,
            collision_margin_m: 0.008,
            friction: 0.3,
            max_speed_m_per_s: None,
        }
    }
}

/// Parameters of the skirt (shape in module `skirt`'s docs: a flared tube from a waistband
/// around the body's waist to a hem below the knees).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SkirtParams {
    /// Joint the waistband sits above. Default: `"pelvis"`.
    pub waist_joint: String,
    /// Height of the waistband above that joint at rest, metres. Default: 0.12 (the natural
    /// waist of the MakeHuman figure, above where a thigh flexed 90° reaches).
    pub waist_above_joint_m: f64,
    /// Knee joints; the hem hangs below their mean height. Default: `l_knee`, `r_knee`.
    pub knee_joints: Vec<String>,
    /// Hip joints: the hem must lie below the lowest (a conservative crotch height).
    /// Default: `l_hip`, `r_hip`.
    pub hip_joints: Vec<String>,
    /// Depth of the hem below the knees at rest, metres (negative: above the knee, still
    /// below the hips). Default: 0.10.
    pub hem_below_knee_m: f64,
    /// Gap between the body and the waistband, metres. Default: 0.01.
    pub waist_ease_m: f64,
    /// Gap between the colliders and the skirt below the waistband, metres. Default: 0.02.
    pub ease_m: f64,
    /// Extra radius of the hem over the waistband, metres (the A-line's flare). Default: 0.10.
    pub flare_m: f64,
    /// A circular waistband of this radius about the skirt's axis instead of one fitted to the
    /// body, metres. Default: `None`.
    pub waist_radius_m: Option<f64>,
    /// A circular hem of this radius instead of the flare, metres. Default: `None`.
    pub hem_radius_m: Option<f64>,
    /// Joints whose colliders the skirt meets (and whose vertices and colliders its rest
    /// shape clears): trunk and legs. Arms are left out — a hand swinging through the skirt
    /// would tear a coarse cloth apart. A garment vertex inside a collider at rest (the
    /// waistband on the flat belly, inside the round spine capsule) ignores that collider.
    /// Default: pelvis, spine, chest, hips, knees, ankles.
    pub collider_joints: Vec<String>,
    /// Rings of vertices from waist to hem (≥ 3). Default: 32.
    pub rings: usize,
    /// Vertices around each ring (≥ 8). Default: 72. `rings × segments ≤`
    /// [`MAX_GARMENT_VERTICES`].
    pub segments: usize,
    /// Settling time at construction, seconds. Default: 4.0 (the drape then moves by about
    /// 3 mm/s at most when held at rest: a real equilibrium).
    pub settle_s: f64,
    /// The cloth. Default: [`ClothParams::default`].
    pub cloth: ClothParams,
}

impl Default for SkirtParams {
    fn default() -> Self {
        let names = |v: &[&str]| v.iter().map(|s| s.to_string()).collect();
        SkirtParams {
            waist_joint: "pelvis".into(),
            waist_above_joint_m: 0.12,
            knee_joints: names(&["l_knee", "r_knee"]),
            hip_joints: names(&["l_hip", "r_hip"]),
            hem_below_knee_m: 0.10,
            waist_ease_m: 0.01,
            ease_m: 0.02,
            flare_m: 0.10,
            waist_radius_m: None,
            hem_radius_m: None,
            collider_joints: names(&[
                "pelvis", "spine", "chest", "l_hip", "l_knee", "l_ankle", "r_hip", "r_knee",
                "r_ankle",
            ]),
            rings: 32,
            segments: 72,
            settle_s: 4.0,
            cloth: ClothParams::default(),
        }
    }
}

impl SkirtParams {
    /// These parameters with the hem `m` metres below the knees.
    pub fn with_hem_below_knee_m(mut self, m: f64) -> Self {
        self.hem_below_knee_m = m;
        self
    }

    /// These parameters with flare `m` metres.
    pub fn with_flare_m(mut self, m: f64) -> Self {
        self.flare_m = m;
        self
    }

    /// These parameters with a circular waistband of radius `m` metres.
    pub fn with_waist_radius_m(mut self, m: f64) -> Self {
        self.waist_radius_m = Some(m);
        self
    }

    /// These parameters with a circular hem of radius `m` metres.
    pub fn with_hem_radius_m(mut self, m: f64) -> Self {
        self.hem_radius_m = Some(m);
        self
    }

    /// These parameters with `rings × segments` vertices.
    pub fn with_resolution(mut self, rings: usize, segments: usize) -> Self {
        self.rings = rings;
        self.segments = segments;
        self
    }

    /// These parameters with cloth `cloth`.
    pub fn with_cloth(mut self, cloth: ClothParams) -> Self {
        self.cloth = cloth;
        self
    }
}

/// Parameters of the "Ghost" sheet (module `sheet`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SheetParams {
    /// Side of the square sheet, metres. Default: 2.4 (over a 1.67 m figure in A-pose it
    /// hangs to about the knees).
    pub size_m: f64,
    /// Vertices along each side (≥ 3; `resolution² ≤` [`MAX_GARMENT_VERTICES`]). Default: 48.
    pub resolution: usize,
    /// Height of the flat sheet above the top of the body when dropped, metres. Default: 0.02.
    pub drop_height_m: f64,
    /// Settling time at construction, seconds. Default: 2.5.
    pub settle_s: f64,
    /// Joints that carry the sheet: settled vertices resting on their colliders are pinned.
    /// Default: head, neck, chest, both clavicles and shoulders.
    pub pin_joints: Vec<String>,
    /// A settled vertex within this distance of the collision surface of a pin joint's
    /// collider is pinned, metres. Default: 0.01.
    pub pin_distance_m: f64,
    /// The cloth. Default: [`ClothParams::default`] with its speed capped at 10 m/s
    /// ([`ClothParams::max_speed_m_per_s`]).
    pub cloth: ClothParams,
}

/// The sheet's default speed cap, m/s: well above any garment speed a human motion drives
/// (a hand swings at ≈ 5–8 m/s), below the speeds of a whip crack.
const SHEET_MAX_SPEED_M_PER_S: f64 = 10.0;

impl Default for SheetParams {
    fn default() -> Self {
        SheetParams {
            size_m: 2.4,
            resolution: 48,
            drop_height_m: 0.02,
            settle_s: 2.5,
            pin_joints: [
                "head",
                "neck",
                "chest",
                "l_clavicle",
                "r_clavicle",
                "l_shoulder",
                "r_shoulder",
            ]
            .map(String::from)
            .to_vec(),
            pin_distance_m: 0.01,
            cloth: ClothParams {
                max_speed_m_per_s: Some(SHEET_MAX_SPEED_M_PER_S),
                ..ClothParams::default()
            },
        }
    }
}

impl SheetParams {
    /// These parameters with `n × n` vertices.
    pub fn with_resolution(mut self, n: usize) -> Self {
        self.resolution = n;
        self
    }

    /// These parameters with cloth `cloth`.
    pub fn with_cloth(mut self, cloth: ClothParams) -> Self {
        self.cloth = cloth;
        self
    }
}

/// Which garment to build.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum GarmentParams {
    /// A skirt from the waist to below the knee.
    Skirt(SkirtParams),
    /// A sheet draped over the standing figure ("Ghost").
    Sheet(SheetParams),
}

impl GarmentParams {
    fn cloth(&self) -> &ClothParams {
        match self {
            GarmentParams::Skirt(s) => &s.cloth,
            GarmentParams::Sheet(s) => &s.cloth,
        }
    }
}

/// A simulated garment on one body: its rest (scanned) mesh, skin weights for the skinned
/// reference, the cloth and the body's colliders. Immutable; the dynamics live in
/// [`GarmentState`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Garment {
    rest_mesh: TriMesh,
    weights: SkinWeights,
    cloth: Cloth,
    colliders: Colliders,
    body: BodySurface,
    joint_count: usize,
}

/// The garment's dynamic state from frame to frame. Start from `GarmentState::default()`: the
/// first [`Garment::step`] puts the cloth at rest on the skinned garment.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct GarmentState {
    /// Simulated vertex positions, metres (empty before the first step).
    pub positions: Vec<DVec3>,
    /// Vertex velocities, m/s.
    pub velocities: Vec<DVec3>,
    /// The skinned garment of the previous step (targets of the pinned vertices), metres.
    pub skinned: Vec<DVec3>,
    /// The body's joint frames at the previous step.
    pub world_from_joint: Vec<DAffine3>,
    /// The body's collision vertices at the previous step (module `body`), metres.
    pub body: Vec<DVec3>,
}

/// Index of the joint called `name`, else [`Error::InvalidParam`] naming `what`.
pub(super) fn joint_named(skeleton: &Skeleton, name: &str, what: &'static str) -> Result<usize> {
    skeleton
        .joint_index(name)
        .ok_or_else(|| Error::InvalidParam {
            name: what,
            reason: format!("the skeleton has no joint '{name}'"),
        })
}

impl Garment {
    /// Builds the garment for a body at rest (θ = 0): fits the colliders to `body`, builds the
    /// pattern (skirt or sheet) and lets it settle under gravity on the body; the settled drape
    /// is the rest mesh — what a scan at rest shows.
    ///
    /// # Errors
    /// [`Error::InvalidParam`] for a negative, zero or non-finite parameter where it must be
    /// positive, an unknown joint name, more than [`MAX_GARMENT_VERTICES`] vertices, a skirt
    /// whose hem lies above the crotch, whose explicit waist is smaller than the body's waist
    /// or whose explicit hem the leg colliders reach through; [`Error::SizeMismatch`] when the
    /// body's weights do not match body and skeleton; [`Error::Empty`] for a body without
    /// vertices (or none at the waist); [`Error::Degenerate`] for a sheet that slides off the
    /// body while settling; the body template's validation errors.
    pub fn new(
        params: &GarmentParams,
        skeleton: &Skeleton,
        body: &TriMesh,
        body_weights: &SkinWeights,
    ) -> Result<Garment> {
        body.validate()?;
        cloth::check_params(params.cloth())?;
        let rest = skeleton.forward_kinematics(&skeleton.rest_pose())?;
        let frames = rest.world_from_joint();
        let margin = params.cloth().collision_margin_m;
        let is_sheet = matches!(params, GarmentParams::Sheet(_));
        let mut colliders = colliders::fit(skeleton, frames, body, body_weights, margin, is_sheet)?;
        if let GarmentParams::Skirt(p) = params {
            let keep = p
                .collider_joints
                .iter()
                .map(|n| joint_named(skeleton, n, "skirt.collider_joints"))
                .collect::<Result<Vec<_>>>()?;
            colliders.retain(&keep);
        }
        let body_surface = match params {
            GarmentParams::Skirt(p) => {
                let joints = p
                    .collider_joints
                    .iter()
                    .map(|n| joint_named(skeleton, n, "skirt.collider_joints"))
                    .collect::<Result<Vec<_>>>()?;
                BodySurface::new(body, body_weights, &joints)?
            }
            GarmentParams::Sheet(_) => {
                let all: Vec<usize> = (0..skeleton.joint_count()).collect();
                BodySurface::new(body, body_weights, &all)?
            }
        };
        let posed = colliders.pose(frames);
        let owners: Vec<u32> = colliders.capsules.iter().map(|c| c.joint).collect();
        let (pattern, pinned, x) = match params {
            GarmentParams::Skirt(p) => {
                let clear = p
                    .collider_joints
                    .iter()
                    .map(|n| joint_named(skeleton, n, "skirt.collider_joints"))
                    .collect::<Result<Vec<_>>>()?;
                let profile = posed.subset(&owners, &clear);
                let pat = skirt::pattern(
                    p,
                    skeleton,
                    frames,
                    body,
                    body_weights,
                    &profile,
                    &clear,
                    margin,
                )?;
                let mut cloth = Cloth::new(&p.cloth, &pat.mesh, &pat.pinned)?;
                cloth.ignore = posed.inside_masks(&pat.mesh.vertices);
                let x = settle(&cloth, &colliders, frames, &pat.mesh.vertices, p.settle_s);
                (pat.mesh, pat.pinned, x)
            }
            GarmentParams::Sheet(p) => {
                let carriers = p
                    .pin_joints
                    .iter()
                    .map(|n| joint_named(skeleton, n, "sheet.pin_joints"))
                    .collect::<Result<Vec<_>>>()?;
                let top = body
                    .vertices
                    .iter()
                    .map(|v| v.y)
                    .fold(f64::NEG_INFINITY, f64::max);
                let centre = carriers
                    .iter()
                    .map(|&j| frames[j].translation)
                    .sum::<DVec3>()
                    / carriers.len() as f64;
                let pat = sheet::pattern(p, centre, top)?;
                let free = vec![false; pat.vertex_count()];
                let cloth = Cloth::new(&p.cloth, &pat, &free)?;
                let x = settle(&cloth, &colliders, frames, &pat.vertices, p.settle_s);
                let pinned = sheet::pins(p, &x, &posed.subset(&owners, &carriers), margin)?;
                (pat, pinned, x)
            }
        };
        let mut cloth = Cloth::new(params.cloth(), &pattern, &pinned)?;
        cloth.ignore = posed.inside_masks(&x);
        let rest_mesh = TriMesh::new(x, pattern.faces)?;
        // The skinned skirt a rigger would make: weights only on the waist joint, its
        // ancestors and children (pelvis, spine, thighs) — a knee's or shin's weight goes to
        // its nearest such ancestor — from the closest point on the trunk and legs.
        let remap: Vec<usize> = match params {
            GarmentParams::Skirt(p) => {
                let waist = joint_named(skeleton, &p.waist_joint, "skirt.waist_joint")?;
                let mut allowed: Vec<usize> = skeleton.children(waist).collect();
                let mut up = Some(waist);
                while let Some(j) = up {
                    allowed.push(j);
                    up = skeleton.joints()[j].parent;
                }
                (0..skeleton.joint_count())
                    .map(|j| {
                        let mut a = Some(j);
                        while let Some(k) = a {
                            if allowed.contains(&k) {
                                return k;
                            }
                            a = skeleton.joints()[k].parent;
                        }
                        waist
                    })
                    .collect()
            }
            GarmentParams::Sheet(_) => (0..skeleton.joint_count()).collect(),
        };
        let (surface, surface_vertex) = body_surface.submesh(body);
        let weights = garment_weights(
            &rest_mesh,
            &surface,
            surface_vertex,
            body_weights,
            &remap,
            &pinned,
        )?;
        Ok(Garment {
            rest_mesh,
            weights,
            cloth,
            colliders,
            body: body_surface,
            joint_count: skeleton.joint_count(),
        })
    }

    /// The rest mesh: the settled drape at θ = 0, world frame, metres.
    pub fn rest_mesh(&self) -> &TriMesh {
        &self.rest_mesh
    }

    /// Skin weights of the rest mesh over the skeleton's joints: the *skinned* reference
    /// garment. Each vertex takes the weights of the closest point of the body's collision
    /// surface (module `body`: for the skirt trunk and legs, for the sheet the whole body;
    /// blended barycentrically from that triangle's corners). A skirt is skinned as a rigger
    /// would skin it: only to the waist joint, its ancestors and its children (pelvis, spine,
    /// thighs) — the weight of any other joint (knee, shin, chest) goes to its nearest such
    /// ancestor, so the hem does not follow the shins. Then [`WEIGHT_SMOOTHING_PASSES`] Jacobi
    /// passes replace each free vertex's weights by the mean of its mesh neighbours' (pinned
    /// vertices keep the body's, so the waistband skins like the waist under it); at most 4
    /// influences ≥ 0.01 are kept, renormalised.
    pub fn weights(&self) -> &SkinWeights {
        &self.weights
    }

    /// Number of garment vertices.
    pub fn vertex_count(&self) -> usize {
        self.rest_mesh.vertex_count()
    }

    /// Whether vertex `i` is pinned to its skinned position (skirt: the waistband; sheet:
    /// where it rests on head and shoulders).
    ///
    /// # Panics
    /// If `i ≥ vertex_count()`.
    pub fn is_pinned(&self, i: usize) -> bool {
        self.cloth.is_pinned(i)
    }

    /// One frame: `skinned` = the garment's LBS positions this frame (the integrator computes
    /// them with [`skin_core::mesh::skin`] of [`Garment::rest_mesh`], [`Garment::weights`] and
    /// the body's `world_from_rest`), `world_from_joint` = the body's joint frames (they move
    /// the colliders), `body` = the posed body's vertices this frame (every vertex of the
    /// template the garment was built on, in its order: the skinned body, or the true one),
    /// `dt_s` = time since the previous call, seconds (ignored on the first call, which starts
    /// at rest on `skinned`). Over the interval pinned vertices and colliders move linearly
    /// from the previous call's to this call's; after the last substep every free vertex is
    /// put at least the collision margin outside the posed body (module `body`). Returns the
    /// simulated vertex positions, metres.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] for `skinned`, `world_from_joint` or `body` of the wrong length
    /// or a state of another garment; [`Error::NonFinite`] for non-finite inputs;
    /// [`Error::InvalidParam`] for a non-positive or non-finite `dt_s` after the first call.
    pub fn step(
        &self,
        state: &mut GarmentState,
        skinned: &[DVec3],
        world_from_joint: &[DAffine3],
        body: &[DVec3],
        dt_s: f64,
    ) -> Result<Vec<DVec3>> {
        let n = self.vertex_count();
        check::same_size("skinned garment vertices", n, skinned.len())?;
        check::same_size(
            "joint frames (world_from_joint)",
            self.joint_count,
            world_from_joint.len(),
        )?;
        check::same_size("posed body vertices", self.body.vertex_count, body.len())?;
        if !skinned.iter().all(|v| v.is_finite()) {
            return Err(Error::NonFinite {
                what: "skinned garment vertices",
            });
        }
        if !world_from_joint.iter().all(|t| t.is_finite()) {
            return Err(Error::NonFinite {
                what: "joint frames (world_from_joint)",
            });
        }
        if !body.iter().all(|v| v.is_finite()) {
            return Err(Error::NonFinite {
                what: "posed body vertices",
            });
        }
        let body_now = self.body.gather(body);
        if state.positions.is_empty() {
            *state = GarmentState {
                positions: skinned.to_vec(),
                velocities: vec![DVec3::ZERO; n],
                skinned: skinned.to_vec(),
                world_from_joint: world_from_joint.to_vec(),
                body: body_now,
            };
            return Ok(skinned.to_vec());
        }
        for (what, len) in [
            ("garment state positions", state.positions.len()),
            ("garment state velocities", state.velocities.len()),
            ("garment state skinned", state.skinned.len()),
        ] {
            check::same_size(what, n, len)?;
        }
        check::same_size(
            "garment state joint frames",
            self.joint_count,
            state.world_from_joint.len(),
        )?;
        check::same_size("garment state body", body_now.len(), state.body.len())?;
        check::positive("dt_s", dt_s)?;
        let from = self.colliders.pose(&state.world_from_joint);
        let to = self.colliders.pose(world_from_joint);
        self.cloth.advance(
            &mut state.positions,
            &mut state.velocities,
            &state.skinned,
            skinned,
            dt_s,
            |a| Colliders::between(&from, &to, a),
        );
        let posed_body = self.body.pose(body_now);
        body::project(
            &self.cloth,
            &posed_body,
            &state.body,
            dt_s,
            &mut state.positions,
            &mut state.velocities,
        );
        state.body = posed_body.vertices;
        state.skinned.clear();
        state.skinned.extend_from_slice(skinned);
        state.world_from_joint.clear();
        state.world_from_joint.extend_from_slice(world_from_joint);
        Ok(state.positions.clone())
    }
}

/// Lets the pattern `x0` settle on the body at rest for `seconds` (at least
/// [`SETTLE_DAMPING_PER_S`] damping); returns the settled positions.
fn settle(
    cloth: &Cloth,
    colliders: &Colliders,
    frames: &[DAffine3],
    x0: &[DVec3],
    seconds: f64,
) -> Vec<DVec3> {
    let mut settling = cloth.clone();
    settling.params.damping_per_s = settling.params.damping_per_s.max(SETTLE_DAMPING_PER_S);
    let posed = colliders.pose(frames);
    let mut x = x0.to_vec();
    let mut v = vec![DVec3::ZERO; x.len()];
    let frames_n = (seconds / SETTLE_FRAME_S).ceil() as usize;
    for _ in 0..frames_n {
        settling.advance(&mut x, &mut v, x0, x0, SETTLE_FRAME_S, |_| posed.clone());
    }
    x
}

/// The skinned reference's weights (see [`Garment::weights`]): from the closest point of
/// `surface` (its vertex `k` is body vertex `surface_vertex[k]`), joint `j`'s weight moved to
/// joint `remap[j]`.
fn garment_weights(
    rest: &TriMesh,
    surface: &TriMesh,
    surface_vertex: &[u32],
    body_weights: &SkinWeights,
    remap: &[usize],
    fixed: &[bool],
) -> Result<SkinWeights> {
    let query = MeshQuery::new(surface)?;
    let bones = body_weights.bone_count();
    let n = rest.vertex_count();
    let mut w = DMatrix::<f64>::zeros(n, bones);
    for (i, &p) in rest.vertices.iter().enumerate() {
        let cp = query.closest_point(p)?;
        let face = surface.faces[cp.point.face as usize];
        for (&corner, &b) in face.iter().zip(&cp.point.bary) {
            let v = surface_vertex[corner as usize] as usize;
            for (j, wj) in body_weights.influences(v) {
                w[(i, remap[j as usize])] += b * wj;
            }
        }
    }
    let nbrs = vertex_neighbors(rest)?;
    for _ in 0..WEIGHT_SMOOTHING_PASSES {
        let prev = w.clone();
        for i in 0..n {
            let row = nbrs.row(i);
            if fixed[i] || row.is_empty() {
                continue;
            }
            for j in 0..bones {
                w[(i, j)] =
                    row.iter().map(|&k| prev[(k as usize, j)]).sum::<f64>() / row.len() as f64;
            }
        }
    }
    SkinWeights::from_dense(&w, 0.01, 4)
}
