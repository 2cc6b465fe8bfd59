"""Localisation and DEM coverage of a scene across the antimeridian (issue 26, item 4).

GDAL autotest ``autotest/gcore/transformer.py`` test_transformer_15: the RPC of
``gdal-autotest/extracted/transformer_15_rpc.vrt`` (``LONG_OFF 179.9``) over a DEM of two
constant 50 m tiles either side of 180 degrees; GDAL pixel/line (0, 0), i.e. geoblock
``(row, col) = (-0.5, -0.5)``, localises at lon 180.02280735469199, lat 0.061069145746997976
(abs 1e-7 in GDAL's test; shared/data/MANIFEST.md). GDAL stops its image-to-ground
iteration at 0.1 px, geoblock solves to 1e-8 px: the two differ by 3.9e-7 degrees (0.01 px),
so GDAL's value is checked to 1e-6 degrees, as plugins/geoblock-rpc/tests/test_model.py does,
and the truth (the backprojection at the DEM's height) to 1e-9. Before the fix, the box of
the backprojected longitudes was the whole band from -180 to 180: a DEM holding heights
beyond 180 degrees gave the scan its far terrain (every ray ``OUT_OF_DOMAIN`` of the RPC's 0-100 m height domain), and
``coverage_gap`` called any DEM on the equator a cover of the scene.
"""

from __future__ import annotations

import numpy as np
import pytest
from affine import Affine

import geoblock
from geoblock import Status
from geoblock.dem import coverage_gap

from .conftest import write_tif

RPC = "gdal-autotest/extracted/transformer_15_rpc.vrt"
GDAL_00 = (180.02280735469199, 0.061069145746997976)  # GDAL pixel/line (0, 0) at 50 m


@pytest.fixture(scope="module")
def model(data_dir):
    return geoblock.open_model(data_dir / RPC)


@pytest.fixture(scope="module")
def grid(model):
    rows, cols = model.shape
    r, c = np.meshgrid(np.linspace(-0.5, rows - 0.5, 9), np.linspace(-0.5, cols - 0.5, 9),
                       indexing="ij")
    return r.ravel(), c.ravel()


def _dlon(a, b):
    return (np.asarray(a) - np.asarray(b) + 180.0) % 360.0 - 180.0


@pytest.fixture(scope="module")
def beyond_180(tmp_path_factory):
    """One GeoTIFF from 179 to 181 degrees: 50 m over the scene (179.7..180.1), a 2000 m
    plateau east of 180.6 (outside the scene, inside the whole-band box)."""
    lon = 179.0 + 0.005 * (np.arange(400) + 0.5)
    heights = np.where(lon > 180.6, 2000.0, 50.0)[None, :] * np.ones((200, 1))
    path = write_tif(tmp_path_factory.mktemp("am") / "dem.tif", heights.astype("float32"),
                     Affine(0.005, 0, 179.0, 0, -0.005, 0.5), "EPSG:4326")
    return geoblock.open_dem(path, vertical="ellipsoid")


def test_localize_on_a_dem_beyond_180_is_the_backprojection_at_its_height(model, grid,
                                                                           beyond_180):
    row, col = grid
    g, status = geoblock.localize(model, row, col, beyond_180)
    assert (status == Status.CONVERGED).all(), np.unique(status)
    truth = model.backproject(row, col, 50.0)  # the DEM's height over the whole scene
    assert np.max(np.abs(_dlon(g.lon, truth.lon))) < 1e-9
    assert np.max(np.abs(g.lat - truth.lat)) < 1e-9
    assert np.max(np.abs(g.h - 50.0)) < 1e-3
    # the scene does cross the line: both signs of longitude among the answers
    assert (g.lon > 179.0).any() and (g.lon < -179.0).any()
    # GDAL's value at its pixel/line (0, 0)
    g0, s0 = geoblock.localize(model, -0.5, -0.5, beyond_180)
    assert s0 == Status.CONVERGED
    assert abs(_dlon(g0.lon, GDAL_00[0])) < 1e-6 and abs(g0.lat - GDAL_00[1]) < 1e-6


@pytest.mark.parametrize("east_west", [179.0, -181.0], ids=["east-tile-179", "east-tile--181"])
@pytest.mark.parametrize("west_west", [-180.0, 180.0], ids=["west-tile--180", "west-tile-180"])
def test_localize_on_two_tiles_either_side_as_gdal(tmp_path, model, grid, east_west,
                                                    west_west):
    """GDAL's two constant 50 m tiles, each stored in either longitude convention; a 2000 m
    tile at lon 100 on the equator is in the mosaic too (inside the whole-band box)."""
    tiles = [write_tif(tmp_path / f"{name}.tif", np.full((100, 100), h, "float32"),
                       Affine(0.01, 0, west, 0, -0.01, 0.5), "EPSG:4326")
             for name, west, h in (("e", east_west, 50.0), ("w", west_west, 50.0),
                                   ("far", 100.0, 2000.0))]
    dem = geoblock.open_dem(tiles, vertical="ellipsoid")
    row, col = grid
    g, status = geoblock.localize(model, row, col, dem)
    assert (status == Status.CONVERGED).all(), np.unique(status)
    truth = model.backproject(row, col, 50.0)
    assert np.max(np.abs(_dlon(g.lon, truth.lon))) < 1e-9
    assert np.max(np.abs(g.lat - truth.lat)) < 1e-9
    g0, _ = geoblock.localize(model, -0.5, -0.5, dem)
    assert abs(_dlon(g0.lon, GDAL_00[0])) < 1e-6 and abs(g0.lat - GDAL_00[1]) < 1e-6
    assert coverage_gap(dem, model) is None


def test_coverage_gap_names_the_narrow_box_across_the_line(tmp_path, model, beyond_180):
    assert coverage_gap(beyond_180, model) is None
    for west in (-0.5, 100.0, 179.0 - 1.0):  # on the equator, but not under the scene
        far = geoblock.open_dem(
            write_tif(tmp_path / f"far{west}.tif", np.full((50, 50), 50.0, "float32"),
                      Affine(0.01, 0, west, 0, -0.01, 0.25), "EPSG:4326"), vertical="ellipsoid")
        gap = coverage_gap(far, model)
        assert gap is not None and "no valid height over the scene" in gap
        lon0 = float(gap.split("lon ")[1].split(" to ")[0])
        lon1 = float(gap.split(" to ")[1].split(",")[0])
        assert 0.0 < lon1 - lon0 < 0.5 and abs(_dlon(0.5 * (lon0 + lon1), 179.9)) < 0.1, gap
