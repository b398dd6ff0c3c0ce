"""Shared fixtures: the inputs and Rust results written by the Rust test
`cargo test --release -p dynamic-shapes-py --test python_fixtures`
(into target/tmp/python-fixtures, or the folder in $DYNAMIC_SHAPES_FIXTURES)."""

import json
import os
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]
FIXTURES = Path(
    os.environ.get("DYNAMIC_SHAPES_FIXTURES", REPO / "target" / "tmp" / "python-fixtures")
)


class Fixtures:
    """The fixture folder: `fx["name"]` loads name.npy, `fx.json` the scalars."""

    def __init__(self, folder: Path):
        self.folder = folder
        self.json = json.loads((folder / "fixtures.json").read_text())

    def __getitem__(self, name: str) -> np.ndarray:
        return np.load(self.folder / f"{name}.npy")

    def path(self, name: str) -> Path:
        return self.folder / name

    def text(self, name: str) -> str:
        return (self.folder / name).read_text()


@pytest.fixture(scope="session")
def fx() -> Fixtures:
    if not (FIXTURES / "fixtures.json").exists():
        pytest.fail(
            f"no fixtures in {FIXTURES}: run "
            "`cargo test --release -p dynamic-shapes-py --test python_fixtures` first"
        )
    return Fixtures(FIXTURES)


def same(a, b) -> bool:
    """Equal to the last bit (NaN where the other is NaN), same shape."""
    a, b = np.asarray(a), np.asarray(b)
    return a.shape == b.shape and np.array_equal(a, b, equal_nan=True)
