"""The Python side of the binding-overhead measurement (benches/overhead.rs is the Rust side,
on the same inputs): `python overhead.py project CALLS` or `python overhead.py normals CALLS [array]` (`array`:
pass the NumPy array each call instead of a `PatternImages` converted once).
Time whole runs with CALLS and with 0; the difference over CALLS is one call's time."""

import sys
from pathlib import Path

import numpy as np

import dynamic_shapes as ds
from dynamic_shapes import photometric

FIXTURES = Path(__file__).resolve().parents[2] / "target" / "tmp" / "python-fixtures"


def main():
    what = sys.argv[1] if len(sys.argv) > 1 else "project"
    calls = int(sys.argv[2]) if len(sys.argv) > 2 else 1000
    if what == "project":
        cam = ds.Camera.from_json((FIXTURES / "camera.json").read_text())
        pts = np.load(FIXTURES / "camera_points.npy")
        total = 0.0
        for _ in range(calls):
            total += cam.project(pts)[0, 0]
        print(total)
    elif what == "normals":
        cam = ds.Camera.from_json((FIXTURES / "overhead_camera.json").read_text())
        cal = photometric.calibrate_sphere(cam, (0.0, 1.0, 0.0), 0.2, np.load(FIXTURES / "overhead_sphere_images.npy"))
        probe = np.load(FIXTURES / "overhead_probe_images.npy")
        if len(sys.argv) < 4 or sys.argv[3] != "array":
            probe = photometric.PatternImages(probe)  # converted once, as the Rust side does
        valid = 0
        for _ in range(calls):
            _, v = photometric.estimate_normals(cam, cal, probe)
            valid += int(v.sum())
        print(valid)
    else:
        sys.exit(f"unknown bench {what}: project or normals")


if __name__ == "__main__":
    main()
