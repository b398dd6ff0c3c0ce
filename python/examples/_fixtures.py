"""The studio capture the Rust fixture test writes (target/tmp/python-fixtures): the examples
of the methods whose Rust examples run on the synthetic studio read their input from there.
Run `cargo test --release -p dynamic-shapes-py --test python_fixtures` first."""

from pathlib import Path

import numpy as np

import dynamic_shapes as ds

FOLDER = Path(__file__).resolve().parents[2] / "target" / "tmp" / "python-fixtures"


def load(name):
    path = FOLDER / f"{name}.npy"
    if not path.exists():
        raise SystemExit(f"{path} missing: run `cargo test --release -p dynamic-shapes-py --test python_fixtures`")
    return np.load(path)


def camera(name):
    return ds.Camera.from_json((FOLDER / name).read_text())


def studio():
    """The procedural performer in fast motion seen by 4 cameras at 160 x 120, 3 frames:
    (skeleton, cameras, true thetas, masks)."""
    skel = ds.Skeleton.from_json((FOLDER / "skeleton.json").read_text())
    cams = [camera(f"camera{i}.json") for i in range(4)]
    return skel, cams, load("studio_thetas"), load("studio_masks")
