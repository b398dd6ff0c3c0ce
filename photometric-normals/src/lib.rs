//! # photometric-normals
//!
//! Multi-view photometric normal maps from binary half-on spherical lighting (§3.2) and the
//! surface built from them by integration, matching, merging and hole filling (§3.3), after
//! D. Vlasic, *Reconstruction and Analysis of Dynamic Shapes* (MIT PhD thesis, 2010), Chapter 3 (and Vlasic,
//! Peers, Baran, Debevec, Popović, Rusinkiewicz, Matusik, *Dynamic Shape Capture using
//! Multi-View Photometric Stereo*, SIGGRAPH Asia 2009).
//!
//! A light stage of 1,200 lights switches between the half-on patterns X, Y, Z, their
//! complements and a full-on tracking frame (§3.2.2, Eq. 3.1). Each camera photographs a grey
//! diffuse sphere under the patterns once; a pixel's key `k/‖k‖`,
//! `k = [I_X − I_X̄, I_Y − I_Ȳ, I_Z − I_Z̄]`, is then looked up among the sphere's keys and
//! the normals of the N best matches are blended (Eq. 3.2). Spheres at several heights
//! compensate for the lights' finite distance (§3.2.3).
//!
//! Use it to turn multi-view images under a light stage's gradient patterns into per-camera
//! normal maps, and those normal maps (with silhouettes) into one closed mesh per frame
//! (§3.3). It needs calibrated cameras, the seven lighting conditions per frame and a
//! grey-sphere calibration per camera; it is not a single-camera or distant-light photometric
//! stereo, and it does not track a mesh over time.
//!
//! ## Stages
//!
//! | stage | thesis | main items |
//! | --- | --- | --- |
//! | lighting conditions and the 8-frame cycle | §3.2.2 Eq. 3.1 | [`Pattern`], [`PATTERNS`], [`CYCLE`], [`patterns_weights`] |
//! | one view under the seven conditions, exposure limits | §3.2.2, §3.2.3 | [`PatternImages`], [`Exposure`] |
//! | grey-sphere lookup tables, N-best blending, heights | §3.2.2 Eq. 3.2, §3.2.3 | [`LookupTable`], [`HeightCalibration`] |
//! | normal maps | §3.2.2 | [`estimate_normals`], [`NormalMap`] |
//! | optical flow, motion compensation | §3.2.3 | [`dense_flow`], [`compensate_motion`] |
//! | silhouettes, colour transfer | §3.2.1 | [`extract_silhouette`], [`ColourTransfer`] |
//! | visual-hull proxy depths | §3.3 | [`PolygonalHull`], [`mesh_proxy_depth`] |
//! | single-view integration (Eq. 3.3) | §3.3.1 | [`integrate_normals`] |
//! | pairwise matching | §3.3.2 | [`match_pair`] |
//! | depth offsets (Eq. 3.4), the per-view stage | §3.3.2 | [`depth_offsets`], [`per_view_surfaces`] |
//! | VRIP merging | §3.3.3 | [`merge_views`] |
//! | screened Poisson hole filling | §3.3.3 | [`screened_poisson`] |
//! | the two passes | §3.3 | [`reconstruct`] |
//! | positions-and-normals refinement (beyond the thesis) | §3.1 ref. \[104\] | [`refine_mesh`] |
//! | Table 3.1 metrics | §3.4 | [`table_metrics`], [`surface_distance`] |
//!
//! Errors are one [`Error`]; an error inside a loop over cameras or frames says where
//! ([`Error::At`] with a [`Context`]). Parameters, formats, validation and limitations:
//! `docs/photometric-normals.md` in the repository.
//!
//! ## Quick start
//!
//! A 64 × 64 camera calibrated with a grey sphere under a small dome, then a second, smaller
//! sphere seen under the same patterns: its normals come back within a few degrees.
//!
//! ```
//! use photometric_normals::{
//!     estimate_normals, grey, patterns_weights, CalibrationParams, CalibrationSphere,
//!     HeightCalibration, LookupTable, NormalParams, PatternImages, PATTERNS,
//! };
//! use skin_core::camera::{Camera, Intrinsics};
//! use skin_core::math::DVec3;
//! use skin_core::mesh::shapes::uv_sphere;
//! use skin_core::raster::{Buffers, Rasterizer, RenderParams};
//! use dynamic_shapes_studio::shading::{dome_lights, shade_patterns, Albedo, DomeParams, Light, Shadows};
//!
//! let dome = DomeParams { sphere_lights: 300, floor_lights: 100, ..Default::default() };
//! let lights = dome_lights(&dome)?;
//! let centre = DVec3::new(0.0, 4.0 / 3.0, 0.0); // the dome sphere's centre
//! let positions: Vec<DVec3> = lights.iter().map(Light::position).collect();
//! let weights = patterns_weights(&positions, centre, &PATTERNS)?;
//! let k = Intrinsics::from_horizontal_fov(0.2, 64, 64)?;
//! let cam = Camera::look_at(k, DVec3::new(0.0, 1.0, 3.0), DVec3::new(0.0, 1.0, 0.0), DVec3::Y)?;
//! // The studio renders a grey sphere under the seven conditions.
//! let photograph = |s: &CalibrationSphere| -> Result<PatternImages, photometric_normals::Error> {
//!     let mesh = uv_sphere(s.centre, s.radius_m, 48, 96)?;
//!     let params = RenderParams::default().with_buffers(Buffers { triangle: true, ..Buffers::MASK_ONLY });
//!     let view = Rasterizer::new(&cam).render(&mesh, &params)?;
//!     let shaded = shade_patterns(&view, &mesh, &lights, &weights, &Albedo::Uniform([0.5; 3]), &Shadows::None)?;
//!     let images = PATTERNS.iter().zip(&shaded).map(|(&p, s)| Ok((p, grey(&s.to_image()?))));
//!     PatternImages::new(images.collect::<Result<_, photometric_normals::Error>>()?)
//! };
//! let sphere = CalibrationSphere { centre: DVec3::new(0.0, 1.0, 0.0), radius_m: 0.2 };
//! let table = LookupTable::from_sphere(&cam, &sphere, &photograph(&sphere)?, DVec3::Y, &CalibrationParams::default())?;
//! let calibration = HeightCalibration::new(vec![table])?;
//!
//! let probe = CalibrationSphere { radius_m: 0.15, ..sphere };
//! let map = estimate_normals(&cam, &calibration, &photograph(&probe)?, None, &NormalParams::default())?;
//! // The probe covers a disc of about 16 px radius; its centre faces the camera (−z).
//! assert!(map.valid.iter().filter(|&&v| v).count() > 500);
//! let centre_normal = map.normals[32 * 64 + 32];
//! assert!(centre_normal.z < -0.99, "{centre_normal}");
//! # Ok::<(), photometric_normals::Error>(())
//! ```
//!
//! ## Validation equipment
//!
//! With the cargo feature `validation`, the public module `truth` holds the studio scene of
//! the validation (`StudioScene`: a subject, its light stage and camera ring), the studio's
//! light patterns and calibration spheres, ground-truth scoring (angular error, shadowed
//! concavities, wrinkled regions) and the distant-light baseline; `peer_workloads` regenerates
//! the peer benchmarks' merging, Poisson and flow inputs (workloads 6a, 6b and the flow
//! pair) with their truth.
#![cfg_attr(docsrs, feature(doc_cfg))]
#![warn(missing_docs)]
#![warn(unnameable_types, unreachable_pub)]

mod calibration;
mod colour;
mod cycle;
mod depth_map;
mod error;
mod flow;
mod integrate;
mod marching_cubes;
mod matching;
mod merge;
mod metrics;
mod motion;
mod multigrid;
mod normals;
mod offsets;
mod patterns;
#[cfg(feature = "validation")]
#[cfg_attr(docsrs, doc(cfg(feature = "validation")))]
pub mod peer_workloads;
mod poisson;
mod proxy;
mod reconstruct;
mod refine;
mod silhouette;
#[cfg(feature = "validation")]
#[cfg_attr(docsrs, doc(cfg(feature = "validation")))]
pub mod truth;

pub use calibration::{CalibrationParams, CalibrationSphere, HeightCalibration, LookupTable};
pub use colour::{macbeth_reference, ColourParams, ColourTransfer};
pub use cycle::{Pattern, CYCLE, CYCLE_FRAME_RATE_HZ, PATTERNS};
pub use depth_map::DepthMap;
pub use error::{Context, Error, Result, ResultExt};
pub use flow::{dense_flow, warp, Flow, FlowParams};
pub use integrate::{
    depth_errors, depth_jumps, integrate_normals, integrate_normals_with_evidence,
    rendered_normals, DepthErrors, Integrated, IntegrationParams, IntegrationReport,
    IntegrationSolver,
};
pub use matching::{
    depth_map_mesh, match_pair, matching_images, MatchMetric, MatchStats, MatchView,
    MatchingParams, PairMatches, SubPixel, ViewMatches,
};
pub use merge::{merge_views, MergeParams, MergeStats, MergeTimes, MergeView, MergedSurface};
#[cfg(feature = "validation")]
#[cfg_attr(docsrs, doc(cfg(feature = "validation")))]
pub use metrics::{
    coverage_budget, displacement_survival, BudgetInputs, CoverageBudget, DisplacementSurvival,
};
pub use metrics::{
    covered_pixels, surface_distance, table_metrics, vertex_normal_samples, MetricParams,
    SurfaceDistance, TableMetrics, VertexNormalSample,
};
pub use motion::{compensate_motion, CompensatedFrame, MotionParams};
pub use multigrid::MultigridParams;
pub use normals::{estimate_normals, estimate_normals_on_proxy, NormalMap, NormalParams};
pub use offsets::{
    depth_offsets, depth_offsets_guided, per_view_surfaces, OffsetOutliers, OffsetParams,
    OffsetReport, OffsetSurface, RobustWeights, SurfaceErrors, SurfaceParams, SurfaceTimes,
    ViewSurfaces,
};
pub use patterns::{grey, pattern_weights, patterns_weights, Exposure, PatternImages};
pub use poisson::{
    screened_poisson, FluxSplat, OrientedSample, PoissonLevel, PoissonParams, PoissonSurface,
    PoissonTimes, ScreeningForm,
};
pub use proxy::{mesh_proxy_depth, PolygonalHull, PolygonalHullParams};
pub use reconstruct::{
    hull_samples, reconstruct, reconstruct_from_hull_depths, Pass, PassTimes, ReconstructParams,
    Reconstruction,
};
pub use refine::{
    refine_mesh, refine_with_normals, target_normals, RefineParams, RefineReport, RefinedMesh,
    TargetNormals,
};
pub use silhouette::{extract_silhouette, Backdrop, Silhouette, SilhouetteParams};
