"""template-silhouette from Python: the template (the studio performer's rest mesh with
bone-heat weights, as a user would rig it) tracked through the silhouettes of a small studio
capture, then molded; the headline figure of the Rust example `template_capture`, the mean
joint error against the true poses, on this smaller capture (procedural performer, 4 cameras
at 160 x 120, 2 frames; the Rust quick run uses MakeHuman, 8 cameras at 480 x 360).

    python python/examples/template_capture.py
"""

import json
import time

import numpy as np

import dynamic_shapes as ds
from dynamic_shapes import template
from _fixtures import load, studio


def main():
    start = time.perf_counter()
    skel, cams, thetas, masks = studio()
    v, f = load("performer_vertices"), load("performer_faces")
    weights = ds.bone_heat_weights(v, f, skel)
    t = template.Template(v, f, skel, weights)
    # The first frame's true pose stands in for the user's fit of frame 0 (section 2.3.3).
    poses, shapes = template.track(t, cams, masks[:2], thetas[0])
    err = [np.linalg.norm(skel.joint_positions(p) - skel.joint_positions(q), axis=1).mean()
           for p, q in zip(poses, thetas[:2])]
    print(f"{len(poses)} frames tracked, {shapes.shape[1]} vertices molded; "
          f"joint error {1e3 * np.mean(err):.1f} mm (frame 1: {1e3 * err[1]:.1f} mm)")
    print(json.dumps({"joint_error_mm": 1e3 * float(np.mean(err)), "seconds": time.perf_counter() - start}))


if __name__ == "__main__":
    main()
