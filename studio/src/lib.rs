#![doc = include_str!("../README.md")]
//!
//! ## Parts, in the order a capture uses them
//!
//! | Part | Source | Public items |
//! |---|---|---|
//! | performers: template mesh (metres), skeleton, skin weights, deformation | MakeHuman CC0 base mesh; Vlasic §2.5.1 (LBS) | [`makehuman_performer`], [`procedural_performer`], [`Performer`] ([`Performer::pose`] → [`PosedFrame`]) |
//! | pose-driven muscle and joint shapes, a pure C¹ function of θ | pose-space correctives (Lewis et al. 2000) | [`PoseDeformParams`], [`PoseEffect`] |
//! | dynamic deformation: hip flap, garments (XPBD cloth) | Macklin et al. 2016/2019 | [`DeformationParams`], [`FlapParams`], [`Garment`], [`GarmentParams`], [`SkirtParams`], [`SheetParams`], [`ClothParams`] |
//! | wrinkles on a refined surface | — | [`WrinkleModel`], [`WrinkleParams`] → [`FineSurface`] |
//! | albedo texture | — | [`AlbedoTexture`], [`TextureParams`] |
//! | motions | CMU motion capture (BVH) for real motion | [`range_of_motion`], [`fast_motion`], [`exercise_motion`], [`play_bvh`], [`retarget`], [`range_coverage`], [`max_pose_share`] |
//! | lights: point, area, the light-stage dome; Lambertian shading with shadows | Vlasic §3.2.1 | [`shading`] |
//! | the capture: rig × performer × motion → observations and truth, frame by frame | — | [`studio_ring`], [`CaptureSpec`], [`Capture`] → [`CaptureFrame`] ([`FrameTruth`]) |
//! | the rest pose as a 3D scanner sees it: one closed outer surface | Vlasic §2.5.1 (scanned templates) | [`scan_outer_surface`], [`ScanParams`] → [`Scan`] |
//! | skin markers with occlusion | Fua et al. §2 | [`MarkerSet`], [`draw_markers`] |
//! | preview pictures | — | [`preview`] |
//!
//! Rendering is [`skin_core::raster`]. Errors are [`skin_core::Error`]. The facade re-exports
//! the crate as `dynamic_shapes::studio` with its feature `studio`.
#![cfg_attr(docsrs, feature(doc_cfg))]

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
mod scan;
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
pub use scan::{scan_outer_surface, Scan, ScanParams};
pub use texture::{AlbedoTexture, Material, Print, TextureParams};
pub use wrinkles::{
    CreaseWrinkles, FineSurface, GarmentWrinkles, WrinkleModel, WrinkleParams, CREASE_LOBE_RAD,
};
