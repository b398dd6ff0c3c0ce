"""Core bindings against the Rust results; bad input; zero-copy outputs."""

import numpy as np
import pytest
import scipy.sparse

import dynamic_shapes as ds
from conftest import same


@pytest.fixture(scope="module")
def camera():
    return ds.Camera.look_at((0.3, 1.2, 3.0), (0.0, 1.0, 0.0), 640, 480, 1.0)


def test_version_is_the_crates():
    assert ds.__version__ == "0.2.0"


def test_projection_and_rays_match_rust(fx, camera):
    pixels = camera.project(fx["camera_points"])
    assert same(pixels, fx["camera_pixels"])
    origins, directions = camera.rays(pixels)
    assert same(origins, fx["camera_ray_origins"])
    assert same(directions, fx["camera_ray_directions"])


def test_camera_json_round_trips(fx, camera):
    again = ds.Camera.from_json(fx.text("camera.json"))
    np.testing.assert_allclose(again.project(fx["camera_points"]), fx["camera_pixels"], atol=1e-9)
    assert (again.width, again.height) == (640, 480)
    np.testing.assert_allclose(again.world_from_camera, camera.world_from_camera, atol=1e-15)
    with pytest.raises(ds.InvalidInputError, match="camera JSON"):
        ds.Camera.from_json("{}")


def test_camera_from_matrices_round_trips(fx, camera):
    k = camera.intrinsic_matrix
    same_cam = ds.Camera(k[0, 0], k[1, 1], k[0, 2], k[1, 2], 640, 480, camera.world_from_camera)
    np.testing.assert_allclose(same_cam.project(fx["camera_points"]), fx["camera_pixels"], atol=1e-9)


def test_opencv_file_round_trip(fx, camera, tmp_path):
    path = tmp_path / "cam.yml"
    camera.write_opencv(path)
    back = ds.Camera.read_opencv(path)
    np.testing.assert_allclose(back.project(fx["camera_points"]), fx["camera_pixels"], atol=1e-6)


def test_project_rejects_bad_input(camera):
    with pytest.raises(TypeError, match="float64"):
        camera.project(np.zeros((3, 3), dtype=np.float32))
    with pytest.raises(TypeError, match="NumPy array"):
        camera.project([[0.0, 1.0, 0.0]])
    with pytest.raises(ds.InvalidInputError, match=r"shape \(n, 3\)"):
        camera.project(np.zeros((3, 2)))
    with pytest.raises(ds.InvalidInputError, match="NaN"):
        camera.project(np.array([[0.0, np.nan, 0.0]]))
    with pytest.raises(ds.InvalidInputError, match="point 1: nothing visible"):
        camera.project(np.array([[0.0, 1.0, 0.0], [0.3, 1.2, 4.0]]))
    # InvalidInputError is a ValueError.
    with pytest.raises(ValueError):
        camera.project(np.zeros((3, 2)))


def test_meshes_read_as_rust_reads_them(fx):
    v, f = ds.read_obj(fx.path("sphere.obj"))
    assert v.dtype == np.float64 and f.dtype == np.uint32
    assert same(v, fx["sphere_obj_vertices"]) and same(f, fx["sphere_obj_faces"])
    v, f = ds.read_ply(fx.path("sphere.ply"))
    assert same(v, fx["sphere_ply_vertices"]) and same(f, fx["sphere_ply_faces"])


def test_mesh_write_read_round_trip(fx, tmp_path):
    v, f = fx["sphere_obj_vertices"], fx["sphere_obj_faces"]
    for binary in (True, False):
        ds.write_ply(tmp_path / "m.ply", v, f, binary=binary)
        v2, f2 = ds.read_ply(tmp_path / "m.ply")
        assert same(v2, v) and same(f2, f)
    ds.write_obj(tmp_path / "m.obj", v, f)
    v2, f2 = ds.read_obj(tmp_path / "m.obj")
    np.testing.assert_allclose(v2, v, rtol=1e-12)
    assert same(f2, f)


def test_mesh_errors(fx, tmp_path):
    with pytest.raises(ds.FileError, match="No such file"):
        ds.read_obj(tmp_path / "missing.obj")
    with pytest.raises(FileNotFoundError.__mro__[1]):  # an OSError
        ds.read_ply(tmp_path / "missing.ply")
    (tmp_path / "bad.obj").write_text("v 0 0 0\nf 1 2 3\n")
    with pytest.raises(ds.DynamicShapesError):
        ds.read_obj(tmp_path / "bad.obj")
    v = fx["sphere_obj_vertices"]
    with pytest.raises(TypeError, match="uint32"):
        ds.write_obj(tmp_path / "x.obj", v, fx["sphere_obj_faces"].astype(np.int64))
    bad = fx["sphere_obj_faces"].copy()
    bad[0, 0] = len(v)
    with pytest.raises(ds.InvalidInputError, match="face 0"):
        ds.write_obj(tmp_path / "x.obj", v, bad)


def test_cotangent_laplacian_is_rusts_csc(fx):
    lap = ds.cotangent_laplacian(fx["sphere_obj_vertices"], fx["sphere_obj_faces"])
    assert isinstance(lap, scipy.sparse.csc_matrix)
    assert same(lap.data, fx["laplacian_data"])
    assert same(lap.indices, fx["laplacian_indices"].astype(np.int64))
    assert same(lap.indptr, fx["laplacian_indptr"].astype(np.int64))
    n = len(fx["sphere_obj_vertices"])
    assert lap.shape == (n, n)
    np.testing.assert_allclose(lap @ np.ones(n), 0.0, atol=1e-12)


def test_bvh_forward_kinematics_matches_rust(fx, tmp_path):
    skel, motion, frame_time = ds.read_bvh(fx.json["bvh_path"], fx.json["bvh_metres_per_unit"])
    assert motion.shape == (fx.json["bvh_frames"], skel.dof_count)
    assert frame_time == fx.json["bvh_frame_time_s"]
    assert same(skel.forward_kinematics(motion[10]), fx["bvh_fk10"])
    assert same(skel.joint_positions(motion[10]), fx["bvh_joints10"])
    assert len(skel.joint_names) == skel.joint_count == len(skel.parents)
    assert skel.parents[0] == -1
    ds.write_bvh(tmp_path / "w.bvh", skel, motion[:20], frame_time, fx.json["bvh_metres_per_unit"])
    skel2, motion2, _ = ds.read_bvh(tmp_path / "w.bvh", fx.json["bvh_metres_per_unit"])
    assert skel2.dof_names == skel.dof_names
    np.testing.assert_allclose(motion2, motion[:20], atol=1e-6)


def test_skeleton_errors(fx):
    skel = ds.Skeleton.human()
    with pytest.raises(ds.InvalidInputError, match=r"shape \(42,\)"):
        skel.forward_kinematics(np.zeros(3))
    with pytest.raises(ds.InvalidInputError, match="NaN"):
        skel.forward_kinematics(np.full(skel.dof_count, np.nan))
    with pytest.raises(ds.FileError):
        ds.read_bvh("/nonexistent/walk.bvh")
    with pytest.raises(ds.InvalidInputError, match="metres_per_unit"):
        ds.read_bvh(fx.json["bvh_path"], -1.0)
    assert ds.Skeleton.from_json(skel.to_json()).dof_names == skel.dof_names


def test_skinning_and_heat_weights_match_rust(fx):
    skel = ds.Skeleton.from_json(fx.text("skeleton.json"))
    v, f = fx["performer_vertices"], fx["performer_faces"]
    theta = fx["studio_thetas"][1]
    out = ds.linear_blend_skinning(v, f, skel, fx["performer_weights"], theta)
    assert same(out, fx["lbs_frame1"])
    assert same(ds.bone_heat_weights(v, f, skel), fx["heat_weights"])


def test_skinning_errors(fx):
    skel = ds.Skeleton.from_json(fx.text("skeleton.json"))
    v, f = fx["performer_vertices"], fx["performer_faces"]
    w = fx["performer_weights"]
    with pytest.raises(ds.InvalidInputError, match="weights must have shape"):
        ds.linear_blend_skinning(v, f, skel, w[:, :3], fx["studio_thetas"][1])
    bad = w.copy()
    bad[5] = 0.0
    with pytest.raises(ds.InvalidInputError, match="degenerate"):
        ds.linear_blend_skinning(v, f, skel, bad, fx["studio_thetas"][1])


def test_outputs_are_handed_over_without_a_copy(fx, camera):
    """Results own the Rust buffer: NumPy did not copy them into a buffer of its own."""
    pixels = camera.project(fx["camera_points"])
    assert not pixels.flags.owndata and pixels.base is not None
    assert not isinstance(pixels.base, np.ndarray)
    assert pixels.flags.c_contiguous and pixels.flags.writeable
    v, f = ds.read_obj(fx.path("sphere.obj"))
    for a in (v, f):
        assert not a.flags.owndata and not isinstance(a.base, np.ndarray)


def test_strided_inputs_are_read_in_place(fx, camera):
    """A non-contiguous view gives the same result as its contiguous copy."""
    wide = np.zeros((1000, 6))
    wide[:, ::2] = fx["camera_points"]
    view = wide[:, ::2]
    assert not view.flags.c_contiguous
    assert same(camera.project(view), fx["camera_pixels"])
