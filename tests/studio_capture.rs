//! Integration test of the studio's capture on the real data: the MakeHuman performer plays
//! the retargeted CMU walk (`mocap-cmu/131_01.bvh`) in front of a small ring, and the captured
//! ground truth is checked against independent computations: depth against ray casting through
//! the mesh BVH, silhouettes against a second (mask-only) render, joint positions against the
//! skeleton's forward kinematics, and the skinned surface against the performer.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)] // not library code

use dynamic_shapes::core::camera::{Intrinsics, Rig};
use dynamic_shapes::core::math::{DVec2, DVec3};
use dynamic_shapes::core::mesh::MeshQuery;
use dynamic_shapes::core::raster::{Buffers, RenderParams};
use dynamic_shapes::core::skeleton::{BvhParams, CMU_METRES_PER_UNIT};
use dynamic_shapes_studio::{
    makehuman_performer, play_bvh, Capture, CaptureSpec, DeformationParams, RetargetParams,
};
use example_kit::data_path;

#[test]
fn cmu_walk_capture_truth_is_consistent() {
    let dir = data_path("makehuman/base.obj").expect("data/makehuman");
    let performer = makehuman_performer(
        dir.parent().expect("file in a folder"),
        &DeformationParams::default(),
    )
    .expect("MakeHuman performer");
    let walk = play_bvh(
        data_path("mocap-cmu/131_01.bvh").expect("CMU walk"),
        &BvhParams {
            metres_per_unit: CMU_METRES_PER_UNIT,
        },
        &performer.skeleton,
        1.0 / 30.0,
        &RetargetParams::default(),
    )
    .expect("retargeted walk");
    let root = performer
        .skeleton
        .forward_kinematics(walk.motion.frame(0))
        .expect("pose")
        .joint_positions()[0];
    let k = Intrinsics::new(150.0, 150.0, 79.5, 59.5, 160, 120).expect("intrinsics");
    let look_at = DVec3::new(root.x, 0.9, root.z);
    let rig = Rig::ring(4, 3.0, 1.1, look_at, DVec3::Y, k).expect("ring");
    let spec = CaptureSpec::new(rig).with_render(RenderParams::default().with_buffers(Buffers {
        triangle: true,
        ..Buffers::default()
    }));
    let capture = Capture::new(&performer, &walk.motion, spec).expect("capture");
    let mask_only = RenderParams::default().with_buffers(Buffers::MASK_ONLY);
    for frame in capture.frames_in(0..3) {
        let frame = frame.expect("frame renders");
        let truth = &frame.truth;
        // Joint positions are the forward kinematics of θ.
        let fk = performer
            .skeleton
            .forward_kinematics(&truth.theta)
            .expect("pose");
        for (a, b) in fk
            .joint_positions()
            .iter()
            .zip(&truth.posed.joint_positions)
        {
            assert!(a.distance(*b) < 1e-12);
        }
        let mesh = truth.true_mesh(&performer);
        let query = MeshQuery::new(&mesh).expect("BVH");
        for (i, (obs, view)) in frame.observations.iter().zip(&truth.views).enumerate() {
            let cam = &capture.rasterizers()[i];
            // Silhouettes of two renderers (full and mask-only paths) agree exactly.
            let second = cam.render(&mesh, &mask_only).expect("mask render");
            assert_eq!(second.covered_pixels, obs.mask.count());
            for (k, &m) in second.mask.iter().enumerate() {
                let (x, y) = (k as u32 % second.width, k as u32 / second.width);
                assert_eq!(
                    obs.mask.get(x, y),
                    m != 0,
                    "frame {} camera {i}",
                    frame.index
                );
            }
            let depth = view.depth_m.as_ref().expect("depth truth");
            assert!(view.covered_pixels > 300, "camera {i} sees the walker");
            // Depth equals the ray-cast distance to the mesh, on a grid of pixels.
            let mut checked = 0;
            for y in (0..120u32).step_by(3) {
                for x in (0..160u32).step_by(3) {
                    let ray = cam
                        .camera()
                        .ray(DVec2::new(x as f64, y as f64))
                        .expect("pixel ray");
                    let hit = query.cast_ray(ray, f64::INFINITY).expect("ray cast");
                    let d = depth.get_pixel(x, y)[0];
                    match hit {
                        Some(h) if obs.mask.get(x, y) => {
                            let t = h.t;
                            assert!(
                                (f64::from(d) - t).abs() < 1e-4,
                                "camera {i} pixel ({x}, {y}): depth {d} vs ray cast {t}"
                            );
                            checked += 1;
                        }
                        None => assert!(d.is_infinite()),
                        // A ray grazing the silhouette edge may hit in f64 and miss in the
                        // rasteriser's f32 coverage test.
                        Some(_) => {}
                    }
                }
            }
            assert!(checked > 20, "camera {i}: {checked} pixels compared");
        }
    }
}
