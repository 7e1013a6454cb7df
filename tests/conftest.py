"""Shared fixtures: libraries and rendered photos (tests render, they do not paste)."""

from __future__ import annotations

import os

import numpy as np
import pytest
from hypothesis import HealthCheck, settings

from rockscan.core.information import FaceConfig
from rockscan.core.library import Library, ShapeSpec
from rockscan.core.superformula import SuperformulaParams
from rockscan.io import default_library, default_spec_path, read_spec

# The suite is deterministic (the same examples every run, so a failure can be
# replayed anywhere); "explore" draws new examples each run, "thorough" many more.
settings.register_profile(
    "default",
    deadline=None,
    max_examples=25,
    derandomize=True,
    suppress_health_check=[HealthCheck.too_slow],
)
settings.register_profile(
    "explore", deadline=None, max_examples=25, suppress_health_check=[HealthCheck.too_slow]
)
settings.register_profile("thorough", deadline=None, max_examples=200)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "default"))

#: The paper's three library shapes (Section IV, Fig. 7).
PAPER_SHAPES = {
    "rounded-triangle": SuperformulaParams(3, 3, 1500, 1500, 1500),
    "three-faced-blunt": SuperformulaParams(6, 6, 60, 55, 10),
    "six-pointed-star": SuperformulaParams(6, 6, 0.2, 1.7, 1.7),
}
#: The paper's near shapes (Tables II-IV), by base shape.
PAPER_NEAR = {
    "rounded-triangle": SuperformulaParams(3, 3, 1650, 1650, 1650),
    "three-faced-blunt": SuperformulaParams(6, 6, 66, 60.5, 11),
    "six-pointed-star": SuperformulaParams(6, 6, 0.205, 1.71, 1.71),
}


@pytest.fixture(scope="session")
def default_lib() -> Library:
    """The built-in default library (information faces, polar grid)."""
    return default_library()


@pytest.fixture(scope="session")
def default_specs() -> list[ShapeSpec]:
    return read_spec(default_spec_path())


@pytest.fixture(scope="session")
def paper_lib() -> Library:
    """A library of the paper's three shapes, as in its experiments."""
    return Library.from_shapes([ShapeSpec(name, p) for name, p in PAPER_SHAPES.items()])


@pytest.fixture(scope="session")
def radii_lib() -> Library:
    """The default shapes with plain radii faces (the matched-filter baseline)."""
    return default_library(FaceConfig(kind="radii"))


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(12345)
