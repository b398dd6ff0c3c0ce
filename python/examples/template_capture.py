"""template-silhouette from Python: the Rust example `template_capture --quick`'s body run
(`body_exercise`, the thesis' protocol with each frame's molding started from the previous
frame's). MakeHuman without the skirt in the studio's exercise, 12 frames at 30 fps from
frame 40, seen by 8 ring cameras at 480 x 360, 2.2 m above the floor; the template a user
would have (the outer surface a scanner sees, decimated to 10,000 vertices, rigged by
bone-heat weights) tracked through the silhouettes from the first frame's true pose (the
user's fit of frame 0, section 2.3.3), then molded. The Rust run also has an emulated user
who fixes frames whose joints leave their limbs; in this run it fixes none. The mean is taken
by NumPy (the last bit may differ from the Rust run's sum). The headline printed is `body_exercise_joint_error_mm`: the mean distance of the
tracked joints to the true ones over joints and frames.

    python python/examples/template_capture.py
"""

import json
import time
from pathlib import Path

import numpy as np

from dynamic_shapes import studio, template

DATA = Path(__file__).resolve().parents[2] / "data"


def main():
    start = time.perf_counter()
    cap = studio.silhouette_capture(str(DATA / "makehuman"), skirt=False, motion="exercise", frames=12)
    capture_s = time.perf_counter() - start
    skel, thetas = cap["skeleton"], cap["thetas"]
    v, f = cap["template_vertices"], cap["template_faces"]
    t = template.Template.rigged(v, f, skel)  # bone-heat weights kept in Rust
    poses, shapes = template.track(t, cap["cameras"], cap["masks"], thetas[0], shape_start="previous")
    err = [1e3 * np.linalg.norm(skel.joint_positions(p) - skel.joint_positions(q), axis=1).mean()
           for p, q in zip(poses, thetas)]
    joint = float(np.mean(err))
    print(f"{len(poses)} frames tracked, {shapes.shape[1]} template vertices molded; "
          f"joint error {joint:.4f} mm")
    print(json.dumps({"body_exercise_joint_error_mm": joint, "capture_s": capture_s,
                      "seconds": time.perf_counter() - start}))


if __name__ == "__main__":
    main()
