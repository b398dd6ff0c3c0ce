"""photometric-normals from Python: a camera calibrated with a grey sphere under the dome's
half-on patterns, then the normals of a second, smaller sphere estimated from its seven
pattern images (the crate's quick start, 256 x 256); the headline figure of the Rust example
`photometric_normals`, the median angular error of the normals, here against the probe's
exact sphere normals (the Rust quick run scores MakeHuman in the skirt, 2 cameras).

    python python/examples/photometric_normals.py
"""

import json
import time

import numpy as np

from dynamic_shapes import photometric
from _fixtures import camera, load

CENTRE, PROBE_RADIUS_M = np.array([0.0, 1.0, 0.0]), 0.15


def main():
    start = time.perf_counter()
    cam = camera("overhead_camera.json")
    cal = photometric.calibrate_sphere(cam, tuple(CENTRE), 0.2, load("overhead_sphere_images"))
    normals, valid = photometric.estimate_normals(cam, cal, load("overhead_probe_images"))
    # The true normal where each valid pixel's ray meets the probe sphere.
    h, w = valid.shape
    ys, xs = np.nonzero(valid)
    origins, dirs = cam.rays(np.stack([xs, ys], axis=1).astype(np.float64))
    oc = origins - CENTRE
    b = (oc * dirs).sum(axis=1)
    disc = b * b - (oc * oc).sum(axis=1) + PROBE_RADIUS_M ** 2
    hit = disc >= 0
    t = -b[hit] - np.sqrt(disc[hit])
    world = (origins[hit] + t[:, None] * dirs[hit] - CENTRE) / PROBE_RADIUS_M
    # Normal maps are in the camera frame: rotate the world normals by camera_from_world.
    truth = world @ cam.world_from_camera[:3, :3]
    est = normals[ys[hit], xs[hit]]
    angle = np.degrees(np.arccos(np.clip((est * truth).sum(axis=1), -1.0, 1.0)))
    print(f"{hit.sum()} probe pixels with a normal of {h * w}; median error {np.median(angle):.2f} deg, "
          f"mean {angle.mean():.2f} deg")
    print(json.dumps({"normal_median_deg": float(np.median(angle)), "normal_mean_deg": float(angle.mean()),
                      "seconds": time.perf_counter() - start}))


if __name__ == "__main__":
    main()
