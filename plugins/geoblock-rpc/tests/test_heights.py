"""Heights outside an RPC's stated range (issue 26, item 7): a margin in metres.

shareloc's ``PHRDIMAP_P1BP--2018122638935449CP.XML`` states 490-660 m; shareloc
(``tests/geomodels/test_rpc.py`` l.251-267) and GDAL localise its pixel (row 200, col 600) at
125 m, which the normalised limit |H| <= 5 refused (H = -5.3). CNES's physical location grid of
the same scene (``GRID_P1BP--2018122638935449CP.tif``, altitudes -30..4900 m) measures how the
vendor's RPC extrapolates in height.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from geoblock_rpc.model import HEIGHT_MARGIN_M, RpcModel
from rasterio.rpc import RPC
from rasterio.transform import RPCTransformer

import geoblock
from geoblock.typing import Status

SCENE = "shareloc/rpc/PHRDIMAP_P1BP--2018122638935449CP.XML"
GRID = "shareloc/ellipsoide/P1BP--2018122638935449CP/GRID_P1BP--2018122638935449CP.tif"


def _open(data_dir, rel):
    path = data_dir / rel
    if not path.is_file():
        pytest.skip(f"{rel} not in {data_dir}")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return geoblock.open_model(path, model="rpc")


def test_the_pleiades_rpc_localises_at_125_m_as_gdal_does(data_dir):
    model = _open(data_dir, SCENE)
    assert model.height_range == (490.0, 660.0)
    assert model.valid_height_range == (490.0 - HEIGHT_MARGIN_M, 660.0 + HEIGHT_MARGIN_M)
    ground, status = model.backproject_with_status(200.0, 600.0, 125.0)
    assert status == Status.CONVERGED  # OUT_OF_DOMAIN before (|H| = 5.3 > 5)
    # shareloc's assertion: back to (200, 600) within 2e-2 px
    (row, col), status = model.project_with_status(ground.lon, ground.lat, 125.0)
    assert status == Status.CONVERGED
    assert abs(row - 200.0) < 1e-8 and abs(col - 600.0) < 1e-8
    # GDAL's RPC transformer (pixel/line = col + 0.5, row + 0.5), iterated to its own threshold
    with RPCTransformer(RPC.from_gdal(model.rpc.to_gdal())) as tr:
        lon, lat = tr.xy(200.5, 600.5, zs=125.0, offset="ul")
    assert abs(lon - ground.lon) < 1e-7 and abs(lat - ground.lat) < 1e-7


def test_the_height_margin_is_where_the_rpc_stays_on_the_physical_grid(data_dir):
    """Inside the vendor's range widened by the margin the RPC stays within 0.1 px of CNES's
    physical grid; beyond it, points are OUT_OF_DOMAIN."""
    rasterio = pytest.importorskip("rasterio")
    model = _open(data_dir, SCENE)
    if not (data_dir / GRID).is_file():
        pytest.skip(f"{GRID} not in {data_dir}")
    with rasterio.open(data_dir / GRID) as ds:
        bands, tags, gt = ds.read(), ds.tags(), ds.transform
    n_rows, n_cols = bands.shape[1:]
    i, j = np.mgrid[0:n_rows, 0:n_cols]
    # grid nodes in shareloc's convention (pixel centres at .5), geoblock's less 0.5
    row = gt.f + i * gt.e - 0.5
    col = gt.c + j * gt.a - 0.5
    low, high = model.valid_height_range
    seen = {"inside": 0, "outside": 0}
    for b in range(0, bands.shape[0], 2):
        alt = float(tags[f"ALTITUDE_B{b}"])
        (r, c), status = model.project_with_status(bands[b], bands[b + 1], np.full_like(row, alt))
        if low <= alt <= high:
            seen["inside"] += 1
            assert np.all(status == Status.CONVERGED)
            assert np.max(np.hypot(r - row, c - col)) < 0.1, alt
        else:
            seen["outside"] += 1
            assert np.all(status == Status.OUT_OF_DOMAIN), alt
    assert seen["inside"] >= 3 and seen["outside"] >= 3  # -30, 586, 1202 m; 2435 m and up


def test_a_narrow_vendor_range_gets_the_margin_and_gdal_s_failure_stays(data_dir):
    """GDAL's test_transformer_11 (range 1101-1127 m): 1150 m localises, 4000 m fails in GDAL
    and is OUT_OF_DOMAIN here (2 873 m above the range, beyond the 1 500 m margin)."""
    model = _open(data_dir, "gdal-autotest/extracted/transformer_11_rpc.vrt")
    _, status = model.backproject_with_status([0.0] * 3, [0.0] * 3, [1150.0, 2500.0, 4000.0])
    assert list(status) == [Status.CONVERGED, Status.CONVERGED, Status.OUT_OF_DOMAIN]


def test_height_margin_options(tmp_path):
    model = RpcModel.example()  # HEIGHT_OFF 500, HEIGHT_SCALE 1000: 5 scales are wider
    assert model.valid_height_range == (-4500.0, 5500.0)
    narrow = RpcModel(model.rpc, model.shape, height_limit=1.0, height_margin_m=100.0)
    assert narrow.valid_height_range == (-600.0, 1600.0)
    _, status = narrow.backproject_with_status([5000.0] * 2, [6000.0] * 2, [1590.0, 1610.0])
    assert list(status) == [Status.CONVERGED, Status.OUT_OF_DOMAIN]
    again = RpcModel.from_dict(narrow.to_dict())
    assert again.valid_height_range == narrow.valid_height_range
    assert narrow.with_shape((100, 100)).height_margin_m == 100.0
    for bad in (-1.0, float("inf"), float("nan"), "x"):
        with pytest.raises(geoblock.errors.ModelFormatError, match="height_margin_m"):
            RpcModel(model.rpc, model.shape, height_margin_m=bad)
