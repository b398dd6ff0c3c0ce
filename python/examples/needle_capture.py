"""needle-model from Python: needles walked through the silhouettes of a small studio capture
(procedural performer, 4 cameras at 160 x 120, 3 frames, a quarter of Table 3.1's needles),
the NRBF model reconstructed, the body animated; the figure printed is the silhouette
agreement of the animated surface (the share of the capture's silhouette pixels the
projected surface vertices land in), the Rust example's `test_silhouette_error` counterpart on
this smaller capture (its quick run trains on 24 s of exercise at 360 x 240).

    python python/examples/needle_capture.py
"""

import json
import time

import numpy as np

from dynamic_shapes import needle
from _fixtures import studio


def main():
    start = time.perf_counter()
    skel, cams, thetas, masks = studio()
    model = needle.reconstruct(skel, cams, thetas, masks, density=0.25, prototype_count=2)
    inside = []
    for k, theta in enumerate(thetas):
        v, _ = model.surface(theta)
        for c, cam in enumerate(cams):
            px = np.rint(cam.project(v)).astype(int)
            ok = (px[:, 0] >= 0) & (px[:, 0] < cam.width) & (px[:, 1] >= 0) & (px[:, 1] < cam.height)
            inside.append(masks[k, c][px[ok, 1], px[ok, 0]].mean())
    outside = 1.0 - float(np.mean(inside))
    print(f"{model.primitive_count} primitives, {model.observation_count} needle observations; "
          f"surface vertices outside the silhouettes: {100 * outside:.1f} %")
    print(json.dumps({"surface_outside_silhouette_fraction": outside, "seconds": time.perf_counter() - start}))


if __name__ == "__main__":
    main()
