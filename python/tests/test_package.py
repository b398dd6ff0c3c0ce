"""The package itself: stubs and docstrings for every public name, py.typed, exceptions."""

import ast
import inspect
from pathlib import Path

import pytest

import dynamic_shapes as ds

PACKAGE = Path(ds.__file__).parent
MODULES = {"__init__": ds, "needle": ds.needle, "template": ds.template,
           "photometric": ds.photometric, "inertial": ds.inertial, "face": ds.face,
           "studio": ds.studio, "batch": ds.batch}


def public(module):
    return {n for n in dir(module) if not n.startswith("_") and not inspect.ismodule(getattr(module, n))}


def stubbed(name):
    tree = ast.parse((PACKAGE / f"{name}.pyi").read_text())
    names = set()
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            names.add(node.target.id)
        elif isinstance(node, ast.ImportFrom) and node.module == "_errors":
            names.update(a.asname or a.name for a in node.names)
    return names


@pytest.mark.parametrize("name", sorted(MODULES))
def test_every_public_name_has_a_stub_and_a_docstring(name):
    module = MODULES[name]
    missing = public(module) - stubbed(name) - {"annotations"}
    assert not missing, f"{name}.pyi lacks {sorted(missing)}"
    for n in public(module):
        obj = getattr(module, n)
        if callable(obj):
            assert obj.__doc__ and len(obj.__doc__.strip()) > 20, f"{name}.{n} has no docstring"


def test_typed_package_and_version():
    assert (PACKAGE / "py.typed").exists()
    assert ds.__version__ == "0.2.0"


def test_exception_hierarchy():
    assert issubclass(ds.InvalidInputError, ValueError)
    assert issubclass(ds.FileError, OSError)
    assert issubclass(ds.FormatError, ValueError)
    assert issubclass(ds.NumericalError, ArithmeticError)
    for e in (ds.InvalidInputError, ds.FileError, ds.FormatError, ds.NumericalError):
        assert issubclass(e, ds.DynamicShapesError)


def test_ict_bilinear_set_reads_the_shipped_basis():
    from conftest import REPO
    faces, sizes, tris = ds.face.ict_bilinear_set(REPO / "data" / "ict-face")
    assert faces.shape == (sizes[0] * sizes[1], faces.shape[1], 3)
    assert tris.max() < faces.shape[1]
    with pytest.raises(ds.FileError):
        ds.face.ict_bilinear_set(REPO / "data" / "no-such-folder")
