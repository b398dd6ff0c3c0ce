"""template-silhouette (Vlasic 2010 Ch. 2): template tracking and deformation transfer."""

from typing import Sequence, Tuple

import numpy as np
import numpy.typing as npt

from . import Camera, Skeleton

F64 = npt.NDArray[np.float64]

class Template:
    def __init__(
        self, vertices: F64, faces: npt.NDArray[np.uint32], skeleton: Skeleton, weights: F64
    ) -> None: ...
    @property
    def vertex_count(self) -> int: ...
    def skin(self, theta: F64) -> F64: ...

def track(
    template: Template,
    cameras: Sequence[Camera],
    masks: npt.NDArray[np.uint8],
    first_pose: F64,
) -> Tuple[F64, F64]: ...

class DeformationTransfer:
    def __init__(self, vertices: F64, faces: npt.NDArray[np.uint32], edited: F64) -> None: ...
    def transfer(self, frame: F64) -> F64: ...
