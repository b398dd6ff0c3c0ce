"""needle-model from Python: the Rust example `needle_capture --quick`'s main model. The
procedural performer (pose-driven shapes, no hip flap) turning through 24 s of the studio's
free exercise (seed 11), seen by the 3-camera studio ring at 360 x 240; every needle of
Table 3.1 walked through every silhouette at the mocap poses, the NRBF model reconstructed
with the paper's parameters; then scored against the true surface on an exercise of another
seed (23, 8 s, every 8th frame). The headline printed is `deforming_mean_mm`: the mean error
of the needle lengths the pose deforms.

    python python/examples/needle_capture.py
"""

import json
import time

import numpy as np

from dynamic_shapes import needle, studio


def main():
    start = time.perf_counter()
    cap = studio.needle_capture(seconds=24.0, seed=11, cameras=3, width=360, height=240)
    capture_s = time.perf_counter() - start
    t = time.perf_counter()
    model = needle.reconstruct(cap["skeleton"], cap["cameras"], cap["thetas"], cap["masks"])
    reconstruct_s = time.perf_counter() - t
    errors = studio.needle_test_errors(model, seconds=8.0, seed=23, stride=8)
    deforming = float(np.mean(errors["pose_deforming_mm"]))
    print(f"{len(cap['thetas'])} training frames, {model.primitive_count} primitives, "
          f"{model.observation_count} needle observations; test exercise: "
          f"{errors['pose_deforming_mm'].size} pose-deforming needle-frames, mean error {deforming:.4f} mm "
          f"(all needles: median {np.median(errors['all_mm']):.2f} mm)")
    print(json.dumps({"deforming_mean_mm": deforming, "test_median_mm": float(np.median(errors["all_mm"])),
                      "capture_s": capture_s, "reconstruct_s": reconstruct_s,
                      "seconds": time.perf_counter() - start}))


if __name__ == "__main__":
    main()
