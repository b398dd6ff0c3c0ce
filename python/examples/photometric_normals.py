"""photometric-normals from Python: the Rust example `photometric_normals --quick`'s static
frame. MakeHuman in the wrinkled skirt under the 1,200-light dome, 2 cameras at 256 x 256,
the seven half-on pattern images through the sensor model; each camera calibrated with grey
spheres, its normals estimated (Eq. 3.2, performance centre at the root) and scored against
the true normals. The headline printed is `normal_median_deg`: the median angular error on
the body outside shadowed concavities (pixels receiving at least 90 % of the dome's power).

    python python/examples/photometric_normals.py 
"""

import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import dynamic_shapes as ds
from dynamic_shapes import batch, photometric, studio

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


def compare_reconstruct(depth=8):
    capture = Path(tempfile.mkdtemp(prefix="photometric-frame-"))
    batch.write_photometric_capture(str(DATA / "makehuman"), str(capture), 60, 61, cameras=8, size=256)
    t = time.perf_counter()
    (ply,) = batch.photometric_frames(str(capture), 0, 1, f"{capture}/rust/", depth)
    rust_s = time.perf_counter() - t
    info = json.loads((capture / "capture.json").read_text())
    cams = [ds.Camera.from_json((capture / "cameras" / f"cam{c}.json").read_text()) for c in range(info["cameras"])]
    wl, centre = info["white_level"], tuple(np.load(capture / "performance_centre.npy"))
    table = np.load(capture / "calibration" / "spheres.npy")
    spheres, radius = [tuple(s[:3]) for s in table], table[0, 3]
    frame = capture / "frames" / "000000"
    t = time.perf_counter()
    masks = np.stack([np.load(frame / f"cam{c}_mask.npy") for c in range(len(cams))])
    normals, valid = [], []
    for c, cam in enumerate(cams):
        sphere_images = np.stack([np.load(capture / "calibration" / f"cam{c}_sphere{i}.npy")
                                  for i in range(len(spheres))]).astype(np.float64)
        cal = photometric.calibrate_spheres(cam, spheres, radius, sphere_images, white_level=wl)
        images = np.load(frame / f"cam{c}_patterns.npy").astype(np.float64)
        n, v = photometric.estimate_normals(cam, cal, images, masks[c], white_level=wl, performance_centre=centre)
        normals.append(n)
        valid.append(v)
    pairs = [(c, (c + 1) % len(cams)) for c in range(len(cams))]
    vertices, faces = photometric.reconstruct(cams, masks, np.stack(normals), np.stack(valid), pairs,
                                              poisson_depth=depth)
    python_s = time.perf_counter() - t
    rust_vertices, rust_faces = ds.read_ply(str(ply))
    equal = np.array_equal(faces, rust_faces) and np.array_equal(vertices, rust_vertices)
    print(json.dumps({"reconstruct_faces": int(len(faces)), "bit_for_bit_equal": bool(equal),
                      "rust_entry_point_s": rust_s, "python_s": python_s}))
    if not equal:
        sys.exit("the Python and Rust reconstructions differ")


if __name__ == "__main__":
    main()
    if "--compare-reconstruct" in sys.argv[1:]:
        compare_reconstruct()
