"""dynamic-shapes from Python: capture and re-animation of moving human bodies and faces.

The Rust library underneath, NumPy arrays at the surface. Arrays are float64 (masks and
flags uint8, triangle indices uint32) with the shapes and units each function documents;
lengths are in metres, angles in radians unless a name says otherwise. A wrong dtype raises
TypeError, anything else wrong with an input an InvalidInputError (a ValueError). Long calls
release the GIL. Arrays returned are built in Rust and handed to NumPy without a copy.

Modules: the core (meshes, cameras, skeletons, skinning, Laplacian) at the top level, and one
submodule per method: needle, template, photometric, inertial, face; studio holds the
synthetic capture studio's scenes with their ground truth (validation equipment); batch
the frame-range entry points of batch runs (paths and plain values).
"""

import sys as _sys

from . import _native
from ._errors import (
    DynamicShapesError,
    FileError,
    FormatError,
    InvalidInputError,
    NumericalError,
)
from ._native import (
    CMU_METRES_PER_UNIT,
    Camera,
    Skeleton,
    bone_heat_weights,
    cotangent_laplacian,
    linear_blend_skinning,
    read_bvh,
    read_obj,
    read_ply,
    write_bvh,
    write_obj,
    write_ply,
)

__version__ = _native.__version__

needle = _native.needle
template = _native.template
photometric = _native.photometric
inertial = _native.inertial
face = _native.face
studio = _native.studio
batch = _native.batch
for _name in ("needle", "template", "photometric", "inertial", "face", "studio", "batch"):
    _sys.modules[f"{__name__}.{_name}"] = getattr(_native, _name)

__all__ = [
    "CMU_METRES_PER_UNIT",
    "Camera",
    "Skeleton",
    "bone_heat_weights",
    "cotangent_laplacian",
    "linear_blend_skinning",
    "read_bvh",
    "read_obj",
    "read_ply",
    "write_bvh",
    "write_obj",
    "write_ply",
    "needle",
    "template",
    "photometric",
    "inertial",
    "face",
    "studio",
    "batch",
    "DynamicShapesError",
    "InvalidInputError",
    "FormatError",
    "FileError",
    "NumericalError",
]
