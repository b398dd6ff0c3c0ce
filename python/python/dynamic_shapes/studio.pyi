"""The synthetic capture studio: the scenes the Rust examples' quick runs score, with their
ground truth (validation equipment, not a method)."""

from os import PathLike
from typing import Any, Dict, Optional, Union

STUDIO_FRAME: int

def photometric_frame(
    makehuman_dir: Union[str, PathLike],
    cameras: int = 2,
    size: int = 256,
    white_level: float = 0.4,
) -> Dict[str, Any]:
    """MakeHuman in the wrinkled skirt at the studio frame under the 1,200-light dome, the
    seven pattern images of `cameras` ring cameras at `size` x `size` through the sensor model.
    Keys: cameras, images (c, 7, h, w), masks (c, h, w), true_normals (c, h, w, 3), open
    (c, h, w), calibrations, performance_centre, white_level."""

def silhouette_capture(
    makehuman_dir: Union[str, PathLike],
    skirt: bool = False,
    motion: str = "exercise",
    frames: int = 12,
    first: int = 40,
    fps: Optional[float] = 30.0,
    step: int = 2,
    cameras: int = 8,
    width: int = 480,
    height: int = 360,
    radius_m: float = 3.5,
    camera_height_m: Optional[float] = 2.2,
    scan_template: bool = True,
    template_vertices: int = 10000,
) -> Dict[str, Any]:
    """MakeHuman's silhouettes in a studio motion seen by a camera ring. Keys: cameras, masks
    (frames, cameras, h, w), thetas (frames, dofs), skeleton, rest_vertices, rest_faces,
    template_vertices, template_faces."""

def needle_capture(
    seconds: float = 24.0, seed: int = 11, cameras: int = 3, width: int = 360, height: int = 240
) -> Dict[str, Any]:
    """The needle example's training capture (procedural performer, free exercise, studio
    ring). Keys: cameras, skeleton, thetas (frames, dofs), masks (frames, cameras, h, w)."""

def needle_test_errors(model: Any, seconds: float = 8.0, seed: int = 23, stride: int = 8) -> Dict[str, Any]:
    """A needle model's length errors (mm) on a test exercise against the true surface. Keys:
    all_mm, near_joints_mm, deforming_mm, pose_deforming_mm."""
