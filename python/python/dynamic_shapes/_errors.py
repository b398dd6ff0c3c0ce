"""Exceptions raised by dynamic_shapes.

Every error of the Rust library arrives as one of these, with the Rust error's message
(including where it happened: "frame 3: camera 1: empty input: ...").
"""


class DynamicShapesError(Exception):
    """Base class of every error raised by the library."""


class InvalidInputError(DynamicShapesError, ValueError):
    """Bad input: wrong shape or size, NaN or infinity, empty, out of range, degenerate."""


class FormatError(DynamicShapesError, ValueError):
    """Malformed file contents (OBJ, PLY, BVH, OpenCV YAML, recordings, HDF5)."""


class FileError(DynamicShapesError, OSError):
    """A file or directory that cannot be read or written."""


class NumericalError(DynamicShapesError, ArithmeticError):
    """A singular problem or an iteration that did not converge."""


__all__ = [
    "DynamicShapesError",
    "InvalidInputError",
    "FormatError",
    "FileError",
    "NumericalError",
]
