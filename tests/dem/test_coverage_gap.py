"""geoblock.dem.coverage_gap: whether a DEM can place any ray of an image, for error messages
(an empty ortho, images that seem not to overlap)."""

from __future__ import annotations

import numpy as np
import pytest

from geoblock.dem import ArrayDem, ConstantDem, coverage_gap
from geoblock.models.linescan import LinescanModel


@pytest.fixture(scope="module")
def model():
    return LinescanModel.example()  # over Nice, about 7.2 E, 43.7 N


def _dem(west, south, values):
    from affine import Affine

    return ArrayDem(values, Affine(0.01, 0, west, 0, -0.01, south + 0.01 * values.shape[0]),
                    crs="EPSG:4326", vertical="ellipsoid")


def test_a_dem_over_the_scene_has_no_gap(model):
    assert coverage_gap(ConstantDem(100.0), model) is None
    fp = model.footprint()
    dem = _dem(float(np.min(fp.lon)) - 0.2, float(np.min(fp.lat)) - 0.2,
               np.full((100, 100), 50.0))
    assert coverage_gap(dem, model) is None


def test_a_dem_elsewhere_or_all_nodata_is_named_with_the_scene_box(model):
    elsewhere = _dem(100.0, 10.0, np.full((50, 50), 50.0))
    gap = coverage_gap(elsewhere, model)
    assert gap is not None and "no valid height over the scene" in gap
    fp = model.footprint()
    assert f"lon {float(np.min(fp.lon)):.6f}" in gap
    fp_west, fp_south = float(np.min(fp.lon)) - 0.2, float(np.min(fp.lat)) - 0.2
    voids = _dem(fp_west, fp_south, np.full((100, 100), np.nan))
    assert "all nodata" in coverage_gap(voids, model)
