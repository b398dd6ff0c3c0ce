"""dynamic-shapes from Python (type stubs). Shapes and units are in each docstring."""

from os import PathLike
from typing import List, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt
import scipy.sparse

from . import batch as batch
from . import face as face
from . import inertial as inertial
from . import needle as needle
from . import photometric as photometric
from . import studio as studio
from . import template as template
from ._errors import DynamicShapesError as DynamicShapesError
from ._errors import FileError as FileError
from ._errors import FormatError as FormatError
from ._errors import InvalidInputError as InvalidInputError
from ._errors import NumericalError as NumericalError

__version__: str
CMU_METRES_PER_UNIT: float
"""Metres per unit of the CMU motion-capture BVH files."""

F64 = npt.NDArray[np.float64]
U32 = npt.NDArray[np.uint32]
Path = Union[str, PathLike]
Vec3 = Tuple[float, float, float]

class Camera:
    """A pinhole camera with first-order radial distortion (x right, y down, z forward)."""

    def __init__(
        self,
        fx: float,
        fy: float,
        cx: float,
        cy: float,
        width: int,
        height: int,
        world_from_camera: F64,
        k1: float = 0.0,
        distortion_centre: Optional[Tuple[float, float]] = None,
    ) -> None: ...
    @staticmethod
    def look_at(
        eye: Vec3,
        target: Vec3,
        width: int,
        height: int,
        horizontal_fov_rad: float,
        up: Vec3 = (0.0, 1.0, 0.0),
    ) -> Camera: ...
    @staticmethod
    def read_opencv(path: Path) -> Camera: ...
    def write_opencv(self, path: Path) -> None: ...
    @property
    def width(self) -> int: ...
    @property
    def height(self) -> int: ...
    @property
    def intrinsic_matrix(self) -> F64: ...
    @property
    def world_from_camera(self) -> F64: ...
    @property
    def k1(self) -> float: ...
    def project(self, points: F64) -> F64:
        """(n, 3) world points (m) -> (n, 2) pixels."""
    def rays(self, pixels: F64) -> Tuple[F64, F64]:
        """(n, 2) pixels -> (origins, unit directions), each (n, 3)."""
    def to_json(self) -> str: ...
    @staticmethod
    def from_json(text: str) -> Camera: ...

class Skeleton:
    """A joint tree with per-joint degrees of freedom (rad, m)."""

    @staticmethod
    def human(height_m: float = 1.75) -> Skeleton: ...
    @property
    def joint_count(self) -> int: ...
    @property
    def dof_count(self) -> int: ...
    @property
    def joint_names(self) -> List[str]: ...
    @property
    def parents(self) -> List[int]: ...
    @property
    def dof_names(self) -> List[str]: ...
    def rest_pose(self) -> F64: ...
    def forward_kinematics(self, theta: F64) -> F64:
        """(dof_count,) -> (joint_count, 4, 4) world-from-joint transforms."""
    def joint_positions(self, theta: F64) -> F64:
        """(dof_count,) -> (joint_count, 3) positions (m)."""
    def to_json(self) -> str: ...
    @staticmethod
    def from_json(text: str) -> Skeleton: ...

def read_obj(path: Path) -> Tuple[F64, U32]: ...
def read_ply(path: Path) -> Tuple[F64, U32]: ...
def write_obj(path: Path, vertices: F64, faces: U32) -> None: ...
def write_ply(path: Path, vertices: F64, faces: U32, binary: bool = True) -> None: ...
def cotangent_laplacian(vertices: F64, faces: U32) -> scipy.sparse.csc_matrix: ...
def read_bvh(path: Path, metres_per_unit: float = 1.0) -> Tuple[Skeleton, F64, float]: ...
def write_bvh(
    path: Path,
    skeleton: Skeleton,
    motion: F64,
    frame_time_s: float,
    metres_per_unit: float = 1.0,
) -> None: ...
def linear_blend_skinning(
    vertices: F64, faces: U32, skeleton: Skeleton, weights: F64, theta: F64
) -> F64: ...
def bone_heat_weights(
    vertices: F64, faces: U32, skeleton: Skeleton, visibility: bool = True
) -> F64: ...
