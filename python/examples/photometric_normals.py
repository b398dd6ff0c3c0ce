"""photometric-normals from Python: the Rust example `photometric_normals --quick`'s static
frame. MakeHuman in the wrinkled skirt under the 1,200-light dome, 2 cameras at 256 x 256,
the seven half-on pattern images through the sensor model; each camera calibrated with grey
spheres, its normals estimated (Eq. 3.2, performance centre at the root) and scored against
the true normals. The headline printed is `normal_median_deg`: the median angular error on
the body outside shadowed concavities (pixels receiving at least 90 % of the dome's power).

    python python/examples/photometric_normals.py 
"""

import json
import time
from pathlib import Path

import numpy as np

from dynamic_shapes import photometric, studio

DATA = Path(__file__).resolve().parents[2] / "data"


def angular_errors_deg(est, truth, valid):
    """Per-pixel angle between the estimate and the normalised truth (NaN where the estimate
    is invalid or there is no true normal)."""
    length = np.linalg.norm(truth, axis=-1, keepdims=True)
    has_truth = length[..., 0] > 0
    t = truth / np.where(length > 0, length, 1.0)
    dot = np.clip((est * t).sum(axis=-1), -1.0, 1.0)
    return np.where((valid != 0) & has_truth, np.degrees(np.arccos(dot)), np.nan)


def main():
    start = time.perf_counter()
    scene = studio.photometric_frame(str(DATA / "makehuman"), cameras=2, size=256)
    capture_s = time.perf_counter() - start
    errors, opens = [], []
    for c, cam in enumerate(scene["cameras"]):
        normals, valid = photometric.estimate_normals(
            cam,
            scene["calibrations"][c],
            scene["images"][c],
            scene["masks"][c],
            white_level=scene["white_level"],
            performance_centre=tuple(scene["performance_centre"]),
        )
        errors.append(angular_errors_deg(normals, scene["true_normals"][c], valid))
        opens.append(scene["open"][c] != 0)
    err, open_ = np.concatenate([e.ravel() for e in errors]), np.concatenate([o.ravel() for o in opens])
    scored = err[open_ & ~np.isnan(err)]
    median = float(np.median(scored))
    print(f"{len(scene['cameras'])} cameras at 256 x 256: {scored.size} body pixels outside shadowed "
          f"concavities with a normal; median error {median:.4f} deg")
    print(json.dumps({"normal_median_deg": median, "scored_pixels": int(scored.size),
                      "capture_s": capture_s, "seconds": time.perf_counter() - start}))


if __name__ == "__main__":
    main()
