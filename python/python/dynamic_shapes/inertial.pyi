"""inertial-acoustic (Vlasic 2010 Ch. 4): recordings, the pipeline, the one-board filter."""

from os import PathLike
from typing import Any, Dict, Optional, Tuple, Union

import numpy as np
import numpy.typing as npt

from . import Skeleton

F64 = npt.NDArray[np.float64]
Path = Union[str, PathLike]

class Recording:
    @staticmethod
    def read(path: Path, skeleton: Skeleton) -> Recording: ...
    def write(self, path: Path, skeleton: Skeleton) -> None: ...
    @property
    def rate_hz(self) -> float: ...
    @property
    def frame_count(self) -> int: ...
    @property
    def duration_s(self) -> float: ...
    @property
    def board_count(self) -> int: ...
    @property
    def rest_pose(self) -> F64: ...

def run_pipeline(skeleton: Skeleton, recording: Recording, heading_fit: bool = False) -> Dict[str, Any]: ...

class ImuLog:
    @staticmethod
    def read_broad(path: Path) -> ImuLog: ...
    @property
    def time_s(self) -> F64: ...
    @property
    def gyro_rad_s(self) -> F64: ...
    @property
    def accel_m_s2(self) -> F64: ...
    @property
    def reference(self) -> F64: ...
    @property
    def movement(self) -> npt.NDArray[np.uint8]: ...
    def __len__(self) -> int: ...

def run_orientation(
    log: ImuLog,
    rest_s: float,
    process_sigma: Optional[float] = None,
    accelerometer_sigma: Optional[float] = None,
    gyroscope_sigma: Optional[float] = None,
    gyro_only: bool = False,
) -> Tuple[F64, F64]: ...
def heading_inclination_rmse(
    estimate: F64,
    reference: F64,
    use_sample: npt.NDArray[np.uint8],
    up: Tuple[float, float, float] = (0.0, 0.0, 1.0),
) -> Dict[str, float]: ...
