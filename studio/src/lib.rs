//! # dynamic-shapes-studio
//!
//! The synthetic capture studio: a rigged performer with known non-skinning deformation,
//! motions, garments and lighting that render ground truth for every method of
//! `dynamic-shapes`. It is validation equipment: the methods never need it at run time, and
//! reach it only through their `validation` features and their tests (the facade re-exports it
//! as `dynamic_shapes::studio` with the feature `studio`). Errors are
//! [`skin_core::Error`], the foundations' error type it builds on.
//!
//! * [`Performer`]: template mesh (metres), skeleton, skin weights and a [`DeformationModel`]
//!   (pose-driven muscle and joint shapes, [`PoseDeformParams`], a pure smooth function of θ;
//!   a lagging hip flap) that linear blend skinning cannot produce; [`Performer::pose`] →
//!   [`PosedFrame`] with LBS and true vertices and each effect's displacement separately.
//! * [`makehuman_performer`]: the MakeHuman CC0 base mesh on a 19-joint, 42-DOF subset of its
//!   rig; [`procedural_performer`]: a smooth union of capsules, meshed by marching tetrahedra.
//! * Motions ([`skin_core::skeleton::Motion`]): [`range_of_motion`], [`fast_motion`],
//!   [`exercise_motion`] (every limited DOF at once through 90 % of its range, turning on the
//!   spot), and BVH playback through [`retarget`] with a [`JointMap`] ([`play_bvh`] reads,
//!   maps, retargets and resamples in one call). [`range_coverage`] and [`max_pose_share`]
//!   (per bone [`pose_shares`]) measure how much of each range a motion visits and how long
//!   it holds any one pose.
//! * Rendering is [`skin_core::raster`] (in skin-core: methods use it at run time).
//! * [`shading`]: lights (point, area, the light-stage dome of Vlasic thesis §3.2.1),
//!   Lambertian shading with albedo, cast shadows by ray casts.
//! * [`preview`]: front-view preview pictures of meshes side by side (flat or per-vertex
//!   colours), for looking at results by eye.
//! * Garments ([`Garment`], [`DeformationParams::garment`]): a skirt and a draped sheet
//!   ("Ghost") as their own cloth surfaces with second-order dynamics (XPBD), driven by the
//!   body and colliding with it, appended to the performer's template as their rest drape.
//! * Fine detail: [`WrinkleModel`] refines the wrinkle regions at render time
//!   ([`skin_core::mesh::Refinement`], edges ≤ 3 mm) and adds pose-dependent wrinkles as real
//!   geometry (elbow and knee creases driven by flexion, garment folds driven by its
//!   compression; 1–3 mm, 1–3 cm) → [`FineSurface`], with the wrinkle displacement kept
//!   separately; [`AlbedoTexture`] is a non-uniform albedo (skin variation, a printed garment
//!   pattern) evaluated at rest positions, shaded through
//!   [`shading::Albedo::Textured`].
//! * [`Capture`]: the capture builder — rig × performer × motion × frame rate → per-frame
//!   observations (silhouettes, shaded images) and ground truth, streamed frame by frame.
//! * Markers ([`MarkerSet`]): retro-reflective skin markers (Fua et al. §2) that follow the
//!   true surface, drawn into grey frames with occlusion by the body ([`draw_markers`]).

pub mod shading;

mod capture;
mod deformation;
mod garment;
mod makehuman;
mod markers;
mod motion;
mod muscles;
mod performer;
mod preview;
mod procedural_body;
mod retarget;
#[cfg(test)]
mod tests;
mod texture;
mod wrinkles;

pub use capture::{
    studio_ring, BarycentricImage, CameraObservation, Capture, CaptureFrame, CaptureFrames,
    CaptureLighting, CaptureSpec, FrameTruth, LightPatterns, PatternSchedule, PixelNoise,
    TriangleIdImage, ViewTruth, STUDIO_RING_HEIGHT_M, STUDIO_RING_HFOV_DEG, STUDIO_RING_RADIUS_M,
    STUDIO_RING_TARGET_M,
};
pub use deformation::{DeformationModel, DeformationParams, DeformationState, FlapParams};
pub use garment::{
    ClothParams, Garment, GarmentParams, GarmentState, SheetParams, SkirtParams,
    MAX_GARMENT_VERTICES, SETTLE_DAMPING_PER_S, WEIGHT_SMOOTHING_PASSES,
};
pub use makehuman::{
    makehuman_performer, makehuman_performer_from_parts, parse_mhskel, parse_mhw, read_mhskel,
    read_mhw, MhBone, MhSkeleton, MhVertexWeight, MhWeights, MAKEHUMAN_END_SITES,
    MAKEHUMAN_METRES_PER_UNIT, MAKEHUMAN_SUBSET,
};
pub use markers::{
    draw_markers, marker_base_image, MarkerImageStyle, MarkerObservation, MarkerScenario, MarkerSet,
};
pub use motion::{
    exercise_motion, fast_motion, max_pose_share, pose_shares, range_coverage, range_of_motion,
    DofCoverage, ExerciseParams, FastMotionParams, PoseShare, RangeOfMotionParams,
};
pub use muscles::{
    activation_ramp, Bump, EffectAxis, EffectSide, PoseDeformParams, PoseEffect, Push,
};
pub use performer::{Performer, PosedFrame};
pub use preview::{preview, Paint, PreviewPanel};
pub use procedural_body::{procedural_performer, ProceduralBodyParams};
pub use retarget::{play_bvh, retarget, JointMap, JointPair, RetargetParams, Retargeted};
pub use texture::{AlbedoTexture, Material, Print, TextureParams};
pub use wrinkles::{
    CreaseWrinkles, FineSurface, GarmentWrinkles, WrinkleModel, WrinkleParams, CREASE_LOBE_RAD,
};
