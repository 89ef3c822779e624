"""Shared small grids: the model compiles once per process, so keep every sweep tiny."""

from __future__ import annotations

import pytest

from slopelander.envelope.axes import MapAxes
from slopelander.model import Model


@pytest.fixture(scope="session")
def model() -> Model:
    return Model.default()


@pytest.fixture(scope="session")
def tiny_axes() -> MapAxes:
    """5 slopes x 4 speeds over the paper's range."""
    return MapAxes.build(15.0, 0.8, slope_max=60.0, speed_min=0.6, speed_max=3.0)
