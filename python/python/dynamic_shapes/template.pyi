"""template-silhouette (Vlasic 2010 Ch. 2): template tracking and deformation transfer."""

from typing import Literal, Sequence, Tuple

import numpy as np
import numpy.typing as npt

from . import Camera, Skeleton

F64 = npt.NDArray[np.float64]

class Template:
    def __init__(
        self, vertices: F64, faces: npt.NDArray[np.uint32], skeleton: Skeleton, weights: F64
    ) -> None: ...
    @staticmethod
    def rigged(
        vertices: F64, faces: npt.NDArray[np.uint32], skeleton: Skeleton, visibility: bool = True
    ) -> "Template":
        """A template rigged by bone-heat weights computed and kept in Rust."""
    @property
    def vertex_count(self) -> int: ...
    def skin(self, theta: F64) -> F64: ...

def track(
    template: Template,
    cameras: Sequence[Camera],
    masks: npt.NDArray[np.uint8],
    first_pose: F64,
    *,
    shape_start: Literal["skinning", "previous"] = "skinning",
    w_anchor: float = 0.0,
    w_c: float = 1000.0,
    w_l_step: float = 0.2,
    filter_sigma_m: float = 0.07,
    filter_passes: int = 2,
    w_d: float = 5.0,
    w_t: float = 1.0,
    w_r: float = 500.0,
    w_u: float = 5000.0,
    samples_per_bone: int = 4,
    refinement_rounds: int = 2,
) -> Tuple[F64, F64]:
    """Poses `(frames, dofs)` and molded vertices `(frames, n, 3)` of a silhouette sequence
    (section 2.2); the keywords are ShapeParams' and PoseParams' fields with the Rust
    defaults."""

class DeformationTransfer:
    def __init__(self, vertices: F64, faces: npt.NDArray[np.uint32], edited: F64) -> None: ...
    def transfer(self, frame: F64) -> F64: ...
