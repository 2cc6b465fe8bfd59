"""A CRS pyproj cannot read is a :class:`~geoblock.errors.GridError` (``parameter="crs"``)."""

from __future__ import annotations

import pytest
from affine import Affine

from geoblock.errors import GridError
from geoblock.ortho.grid import OutputGrid
from geoblock.testing.synthetic import AffineCamera


def test_output_grid_bad_crs():
    with pytest.raises(GridError, match="not a CRS") as info:
        OutputGrid("EPSG:999999", Affine(1, 0, 0, 0, -1, 0), (2, 2))
    assert info.value.parameter == "crs"
    with pytest.raises(GridError) as info:
        OutputGrid.from_bounds("not a crs", (0, 0, 10, 10), 1)
    assert info.value.parameter == "crs"


def test_for_model_bad_crs():
    with pytest.raises(GridError) as info:
        OutputGrid.for_model(AffineCamera.example((60, 80)), 150.0, crs="EPSG:999999")
    assert info.value.parameter == "crs"
