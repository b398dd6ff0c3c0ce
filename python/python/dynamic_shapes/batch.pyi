"""Frame-range entry points for batch runs: paths and plain values in, files under an output
prefix out (what a task scheduler such as Ray can ship to its workers)."""

from os import PathLike
from typing import List, Sequence, Union

Path = Union[str, PathLike]

def write_photometric_capture(
    makehuman_dir: Path,
    out_dir: Path,
    start: int,
    stop: int,
    cameras: int = 2,
    size: int = 128,
    skirt: bool = False,
    white_level: float = 0.4,
) -> None:
    """A photometric studio capture of the exercise's frames start..stop written to out_dir."""

def write_silhouette_capture(
    makehuman_dir: Path,
    out_dir: Path,
    first: int = 40,
    frames: int = 8,
    cameras: int = 4,
    width: int = 240,
    height: int = 180,
    template_vertices: int = 3000,
) -> None:
    """A silhouette studio capture (masks, mocap poses, scanned template) written to out_dir."""

def photometric_frames(capture_dir: Path, start: int, stop: int, out_prefix: str, poisson_depth: int = 8) -> List[str]:
    """Two-pass reconstruction of frames start..stop: one PLY per frame; returns the paths."""

def track_chunk(capture_dir: Path, start: int, stop: int, first_pose: Sequence[float], out_prefix: str) -> List[float]:
    """Tracks frames start..stop from first_pose; writes poses and vertices; returns the last pose."""

def needle_accumulate(capture_dir: Path, start: int, stop: int, out_prefix: str) -> str:
    """The needle observations of frames start..stop as a store file; returns its path."""

def needle_merge(stores: Sequence[Path], out: Path) -> int:
    """Merges stores (in frame order) into out; returns the number of observations."""

def inertial_recording(recording_dir: Path, skeleton_json: Path, start: int, stop: int, out_prefix: str) -> str:
    """The inertial pipeline of a recording; writes frames start..stop's joint angles."""
