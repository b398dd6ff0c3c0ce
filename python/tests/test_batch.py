"""The batch entry points from Python, and the two-pass photometric reconstruction of a studio
frame from NumPy arrays against the Rust entry point that reads the same frame from disk (the
same Rust calls, so the meshes must agree to the last bit)."""

import json

import numpy as np
import pytest

import dynamic_shapes as ds
from dynamic_shapes import batch, photometric

from conftest import REPO

DEPTH = 6


@pytest.fixture(scope="module")
def capture(tmp_path_factory):
    """One studio frame: MakeHuman under the dome, 8 ring cameras at 96 x 96."""
    folder = tmp_path_factory.mktemp("photometric")
    batch.write_photometric_capture(str(REPO / "data" / "makehuman"), str(folder), 60, 61, cameras=8, size=96)
    return folder


def test_reconstruct_from_arrays_equals_the_rust_entry_point(capture, tmp_path):
    (ply,) = batch.photometric_frames(str(capture), 0, 1, f"{tmp_path}/rust/", DEPTH)
    info = json.loads((capture / "capture.json").read_text())
    cams = [ds.Camera.from_json((capture / "cameras" / f"cam{c}.json").read_text())
            for c in range(info["cameras"])]
    wl = info["white_level"]
    centre = tuple(np.load(capture / "performance_centre.npy"))
    table = np.load(capture / "calibration" / "spheres.npy")
    spheres, radius = [tuple(s[:3]) for s in table], table[0, 3]
    frame = capture / "frames" / "000000"
    masks = np.stack([np.load(frame / f"cam{c}_mask.npy") for c in range(len(cams))])
    normals, valid = [], []
    for c, cam in enumerate(cams):
        sphere_images = np.stack(
            [np.load(capture / "calibration" / f"cam{c}_sphere{i}.npy") for i in range(len(spheres))]
        ).astype(np.float64)
        cal = photometric.calibrate_spheres(cam, spheres, radius, sphere_images, white_level=wl)
        images = np.load(frame / f"cam{c}_patterns.npy").astype(np.float64)
        n, v = photometric.estimate_normals(cam, cal, images, masks[c], white_level=wl, performance_centre=centre)
        normals.append(n)
        valid.append(v)
    pairs = [(c, (c + 1) % len(cams)) for c in range(len(cams))]
    vertices, faces = photometric.reconstruct(cams, masks, np.stack(normals), np.stack(valid), pairs,
                                              poisson_depth=DEPTH)
    rust_vertices, rust_faces = ds.read_ply(str(ply))
    assert len(faces) > 100
    assert np.array_equal(faces, rust_faces)
    assert np.array_equal(vertices.astype(rust_vertices.dtype), rust_vertices)


def test_batch_bad_input(capture, tmp_path):
    with pytest.raises(ds.InvalidInputError, match="empty range"):
        batch.photometric_frames(str(capture), 0, 0, f"{tmp_path}/", DEPTH)
    with pytest.raises(ds.InvalidInputError, match="has 1 frames"):
        batch.photometric_frames(str(capture), 0, 2, f"{tmp_path}/", DEPTH)
    with pytest.raises(ds.FileError):
        batch.photometric_frames(str(tmp_path / "none"), 0, 1, f"{tmp_path}/", DEPTH)
    with pytest.raises(ds.FormatError, match="a \"photometric\" capture"):
        batch.track_chunk(str(capture), 0, 1, [0.0], f"{tmp_path}/")
    with pytest.raises(ds.InvalidInputError, match="no stores"):
        batch.needle_merge([], str(tmp_path / "merged.json"))
