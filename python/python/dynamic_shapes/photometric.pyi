"""photometric-normals (Vlasic 2010 §3.2-3.3): normals, integration, reconstruction."""

from typing import Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

from . import Camera

F64 = npt.NDArray[np.float64]
U8 = npt.NDArray[np.uint8]

class Calibration: ...

class PatternImages:
    """The seven pattern images of one view, converted once."""

    def __init__(self, images: F64) -> None: ...
    @property
    def shape(self) -> Tuple[int, int]: ...

Images = Union[F64, PatternImages]

def calibrate_sphere(
    camera: Camera,
    centre: Tuple[float, float, float],
    radius_m: float,
    images: Images,
    up: Tuple[float, float, float] = (0.0, 1.0, 0.0),
) -> Calibration: ...
def calibrate_spheres(
    camera: Camera,
    centres: Sequence[Tuple[float, float, float]],
    radius_m: float,
    images: F64,
    up: Tuple[float, float, float] = (0.0, 1.0, 0.0),
    *,
    white_level: float = 1.0,
    min_normalised: float = 0.03,
    max_normalised: float = 0.97,
    rim_fraction: float = 0.97,
    min_samples: int = 50,
) -> Calibration:
    """Calibration from grey spheres at several heights, images (spheres, 7, h, w)."""
def estimate_normals(
    camera: Camera,
    calibration: Calibration,
    images: Images,
    mask: Optional[U8] = None,
    *,
    n_best: int = 8,
    white_level: float = 1.0,
    min_normalised: float = 0.03,
    max_normalised: float = 0.97,
    performance_centre: Tuple[float, float, float] = (0.0, 1.0, 0.0),
    up: Tuple[float, float, float] = (0.0, 1.0, 0.0),
) -> Tuple[F64, U8]:
    """Per-pixel camera-frame normals `(h, w, 3)` and validity `(h, w)` (section 3.2); the
    keywords are NormalParams' fields with the Rust defaults."""
def integrate_normals(camera: Camera, normals: F64, valid: U8, proxy_depth_m: F64) -> F64: ...
def hull_depths(cameras: Sequence[Camera], masks: U8) -> F64: ...
def reconstruct(
    cameras: Sequence[Camera],
    masks: U8,
    normals: F64,
    valid: U8,
    pairs: Sequence[Tuple[int, int]],
    *,
    poisson_depth: int = 9,
) -> Tuple[F64, npt.NDArray[np.uint32]]: ...
