"""needle-model (Sand 2003): needles on bones fitted to silhouettes, animated by NRBF."""

from typing import List, Optional, Sequence, Tuple

import numpy as np
import numpy.typing as npt

from . import Camera, Skeleton

F64 = npt.NDArray[np.float64]

class NeedleModel:
    @property
    def primitive_count(self) -> int: ...
    @property
    def primitive_names(self) -> List[str]: ...
    @property
    def observation_count(self) -> int: ...
    def needle_lengths(self, primitive: int, theta: F64) -> F64: ...
    def surface(self, theta: F64) -> Tuple[F64, npt.NDArray[np.uint32]]: ...

def reconstruct(
    skeleton: Skeleton,
    cameras: Sequence[Camera],
    thetas: F64,
    masks: npt.NDArray[np.uint8],
    density: float = 1.0,
    prototype_count: Optional[int] = None,
    seed: Optional[int] = None,
) -> NeedleModel: ...
