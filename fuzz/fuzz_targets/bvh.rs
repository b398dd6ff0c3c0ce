//! Fuzz target: the BVH parser, forward kinematics of the parsed frames, export and re-import
//! must never panic; a re-import of an exported file must succeed whenever export does
//! (for values far from f64 overflow, where degree ↔ radian rounding cannot reach infinity).
#![no_main]

use libfuzzer_sys::fuzz_target;
use skin_core::skeleton::{parse_bvh, to_bvh_string, BvhParams};

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let params = BvhParams::default();
    let Ok(bvh) = parse_bvh(text, &params) else {
        return;
    };
    let s = &bvh.skeleton;
    for k in 0..bvh.motion.frame_count().min(4) {
        let _ = s.forward_kinematics(bvh.motion.frame(k));
    }
    let moderate = bvh.motion.frames.iter().all(|v| v.abs() < 1e300)
        && s.joints().iter().all(|j| {
            j.offset.abs().max_element() < 1e300
                && j.end_site.is_none_or(|e| e.abs().max_element() < 1e300)
        });
    if let Ok(out) = to_bvh_string(s, &bvh.motion, &params) {
        let again = parse_bvh(&out, &params);
        if moderate {
            let again = again.expect("re-import of an exported BVH");
            assert_eq!(again.skeleton.joint_count(), s.joint_count());
            assert_eq!(again.motion.frames.shape(), bvh.motion.frames.shape());
        }
    }
});
