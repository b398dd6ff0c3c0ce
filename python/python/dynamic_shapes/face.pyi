"""multilinear-face (Vlasic 2010 Ch. 5): multilinear models, imputation, tracking."""

from os import PathLike
from typing import Any, Dict, List, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

F64 = npt.NDArray[np.float64]

class FaceModel:
    @staticmethod
    def fit(faces: F64, attribute_sizes: Sequence[int], ranks: Sequence[int]) -> Tuple[FaceModel, Dict[str, Any]]: ...
    @property
    def vertex_count(self) -> int: ...
    @property
    def ranks(self) -> List[int]: ...
    def factor(self, mode: int) -> F64: ...
    def training_weights(self, mode: int, index: int) -> F64: ...
    def mean_weights(self) -> List[F64]: ...
    def synthesize(self, weights: Sequence[F64]) -> F64: ...
    def track_points(self, tracked: Sequence[int], tracks: F64, constant: Sequence[bool]) -> Dict[str, Any]: ...
    def track_video(
        self,
        frames: npt.NDArray[np.uint8],
        triangles: npt.NDArray[np.uint32],
        tracked: Sequence[int],
        feature_vertices: Sequence[int],
        feature_pixels: F64,
        constant: Sequence[bool],
    ) -> Dict[str, Any]: ...

def impute(faces: F64, attribute_sizes: Sequence[int], known: npt.NDArray[np.uint8]) -> F64: ...
def ict_bilinear_set(ict_dir: Union[str, PathLike]) -> Tuple[F64, List[int], npt.NDArray[np.uint32]]: ...
def transfer(
    triangles: npt.NDArray[np.uint32],
    source_face: F64,
    source_scale: float,
    source_rows: F64,
    source_translation: Tuple[float, float],
    source_frame: npt.NDArray[np.uint8],
    target_face: F64,
    target_scale: float,
    target_rows: F64,
    target_translation: Tuple[float, float],
    target_frame: npt.NDArray[np.uint8],
) -> npt.NDArray[np.uint8]: ...
