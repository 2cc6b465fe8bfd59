"""geoblock.localize on real data: GDAL's RPC DEM transformer cases, shareloc's Ventoux case,
and a comparison with GDAL's ``RPC_DEM`` inverse transform (rasterio ``RPCTransformer``).

Expected values: shared/data/MANIFEST.md (GDAL autotest ``transformer.py`` test_transformer_5
and _8; shareloc ``tests/geofunctions/test_localization.py`` l.324-366).
"""

from __future__ import annotations

import numpy as np
import pytest

import geoblock
from geoblock import Status
from geoblock.errors import NoIntersectionWarning

rasterio = pytest.importorskip("rasterio")
from affine import Affine  # noqa: E402  (rasterio's dependency)
from rasterio.transform import RPCTransformer  # noqa: E402

pytestmark = pytest.mark.skipif(
    not hasattr(geoblock, "open_dem"), reason="geoblock.open_dem not available yet"
)

# GDAL test_transformer_5: pixel/line (20.5, 10.5) = geoblock (row 10, col 20)
GDAL_H30 = (125.64828521533849, 39.869345204440144)
GDAL_MISSING = (125.64746155942839, 39.869506789921168)  # (-99.5, 0.5), missing value 0
SHARELOC = (5.17388499778903, 44.2257233720898, 376.86)  # (col 1999.5, row 999.5) top-left
M_PER_DEG = 111_320.0


def _write(path, values, transform, crs, dtype="float32", nodata=None):
    values = np.asarray(values)
    with rasterio.open(path, "w", driver="GTiff", width=values.shape[1], height=values.shape[0],
                       count=1, dtype=dtype, crs=crs, transform=transform, nodata=nodata) as dst:
        dst.write(values.astype(dtype), 1)
    return str(path)


@pytest.fixture(scope="module")
def quickbird(data_dir):
    return geoblock.open_model(data_dir / "gdal-autotest/gcore/data/rpc.vrt")


@pytest.mark.parametrize("interpolation", ["bilinear", "bicubic", "nearest"])
def test_gdal_transformer_5_constant_dem(tmp_path, quickbird, interpolation):
    """A 15 m DEM in EPSG:32652 with RPC_HEIGHT_SCALE=2 in GDAL: the same as a 30 m DEM."""
    path = _write(tmp_path / "dem.tif", np.full((100, 100), 30.0),
                  Affine(200, 0, 213300, 0, -200, 4418700), "EPSG:32652")
    dem = geoblock.open_dem(path, vertical="ellipsoid", interpolation=interpolation)
    g, status = geoblock.localize(quickbird, 10.0, 20.0, dem)
    assert status == Status.CONVERGED
    assert abs(g.lon - GDAL_H30[0]) < 1e-6 and abs(g.lat - GDAL_H30[1]) < 1e-6
    assert abs(g.h - 30.0) < 1e-3
    # the same through GDAL itself, on the 15 m DEM with RPC_HEIGHT_SCALE=2
    path15 = _write(tmp_path / "dem15.tif", np.full((100, 100), 15.0),
                    Affine(200, 0, 213300, 0, -200, 4418700), "EPSG:32652")
    gdal_interp = {"bicubic": "cubic", "nearest": "near"}.get(interpolation, interpolation)
    with RPCTransformer(quickbird_rpcs(quickbird), RPC_DEM=path15, RPC_HEIGHT_SCALE=2,
                        RPC_DEMINTERPOLATION=gdal_interp,
                        RPC_PIXEL_ERROR_THRESHOLD=1e-6) as tr:
        x, y = tr.xy(10.0, 20.0, zs=0.0, offset="center")
    assert abs(x - g.lon) < 1e-8 and abs(y - g.lat) < 1e-8


def quickbird_rpcs(model):
    from rasterio.rpc import RPC

    return RPC.from_gdal(model.rpc.to_gdal())


def test_gdal_transformer_5_outside_dem_and_missing_value(tmp_path, quickbird):
    path = _write(tmp_path / "dem.tif", np.full((100, 100), 30.0),
                  Affine(200, 0, 213300, 0, -200, 4418700), "EPSG:32652")
    dem = geoblock.open_dem(path, vertical="ellipsoid")
    # GDAL forward (40000, 0) fails outside the DEM; geoblock's RPC domain check fires first
    with pytest.warns(geoblock.GeoblockWarning):
        g, status = geoblock.localize(quickbird, 0.0, 40000.0, dem)
    assert status in (Status.OUT_OF_DOMAIN, Status.NO_DEM) and np.isnan(g.lon)
    # RPC_DEM_MISSING_VALUE=0 on a 1 m DEM: (-99.5, 0.5) is outside it and gets h = 0
    tiny = _write(tmp_path / "tiny.tif", np.full((100, 100), 30.0),
                  Affine(1, 0, 213300, 0, -1, 4418700), "EPSG:32652")
    dem = geoblock.open_dem(tiny, vertical="ellipsoid")
    with pytest.warns(NoIntersectionWarning, match="no DEM height"):
        g, status = geoblock.localize(quickbird, 0.0, -100.0, dem)  # outside: no fill
    assert status == Status.NO_DEM and np.isnan(g.lon)
    g, status = geoblock.localize(quickbird, 0.0, -100.0, dem, fill_height=0.0)
    assert status == Status.CONVERGED
    assert abs(g.lon - GDAL_MISSING[0]) < 1e-6 and abs(g.lat - GDAL_MISSING[1]) < 1e-6
    assert abs(g.h) < 1e-3


@pytest.mark.parametrize("interpolation", ["bilinear", "bicubic", "nearest"])
def test_gdal_transformer_8_all_nodata_dem(tmp_path, quickbird, interpolation):
    path = _write(tmp_path / "nodata.tif", np.full((100, 100), -32768),
                  Affine(200, 0, 213300, 0, -200, 4418700), "EPSG:32652",
                  dtype="int16", nodata=-32768)
    dem = geoblock.open_dem(path, vertical="ellipsoid", interpolation=interpolation)
    for method in ("robust", "ray-tracing"):
        with pytest.warns(NoIntersectionWarning, match="no DEM height"):
            g, status = geoblock.localize(quickbird, 10.0, 20.0, dem, method=method)
        assert status == Status.NO_DEM and np.isnan(g.h)


# ---------------------------------------------------------------- Ventoux
@pytest.fixture(scope="module")
def ventoux(data_dir):
    shareloc = data_dir / "shareloc"
    model = geoblock.open_model(shareloc / "rectification/left_image.geom")
    dem = geoblock.open_dem(
        shareloc / "dtm/srtm_ventoux/srtm90_non_void_filled/N44E005.hgt",
        geoid=shareloc / "dtm/geoid/egm96_15.gtx",
        nodata="fill",
    )
    return model, dem


@pytest.mark.parametrize("method", ["robust", "ray-tracing"])
def test_shareloc_ventoux_localisation_on_srtm(ventoux, method):
    """shareloc test_localization.py l.324-366: (col 1999.5, row 999.5) top-left convention."""
    model, dem = ventoux
    g, status = geoblock.localize(model, 999.0, 1999.0, dem, method=method)
    assert status == Status.CONVERGED
    assert abs(g.lon - SHARELOC[0]) < 3e-5
    assert abs(g.lat - SHARELOC[1]) < 2e-4
    assert abs(g.h - SHARELOC[2]) < 15.0
    assert abs(g.h - dem.height(g.lon, g.lat)) <= 1e-3


@pytest.fixture(scope="module")
def ventoux_ellipsoidal(ventoux, tmp_path_factory):
    """SRTM + EGM96 resampled by geoblock onto a GeoTIFF of ellipsoidal heights (the SRTM
    posts, south-west part of the tile that the image covers), read by both GDAL and geoblock."""
    _, dem = ventoux
    res = 1.0 / 1200.0
    west, north = 5.0 - res / 2 + 120 * res, 44.0 + res / 2 + 360 * res  # on SRTM posts
    cols, rows = 480, 340
    lon = west + (np.arange(cols) + 0.5) * res
    lat = north - (np.arange(rows) + 0.5) * res
    heights = dem.height(*np.meshgrid(lon, lat))
    assert np.all(np.isfinite(heights))
    path = _write(tmp_path_factory.mktemp("ventoux") / "ventoux_ellipsoidal.tif", heights,
                  Affine(res, 0, west, 0, -res, north), "EPSG:4326", dtype="float64")
    return path


def _residual_px(model, row, col, lon, lat, h):
    (r, c), _ = model.project_with_status(lon, lat, h)
    return np.hypot(r - row, c - col)


def test_ventoux_against_gdal_rpc_dem(ventoux, ventoux_ellipsoidal):
    """Same heights for both (an ellipsoidal GeoTIFF); GDAL iterates to 0.1 px by default."""
    model, _ = ventoux
    dem = geoblock.open_dem(ventoux_ellipsoidal, vertical="ellipsoid")
    row, col = (a.ravel() for a in np.meshgrid(np.linspace(0, model.shape[0] - 1, 12),
                                               np.linspace(0, model.shape[1] - 1, 12),
                                               indexing="ij"))
    g, status = geoblock.localize(model, row, col, dem)
    assert np.all(status == Status.CONVERGED)
    res_gb = _residual_px(model, row, col, g.lon, g.lat, g.h)
    assert res_gb.max() < 1e-6
    assert np.all(np.abs(g.h - dem.height(g.lon, g.lat)) <= 1e-3)
    scale = np.array([np.cos(np.radians(44.1)), 1.0]) * M_PER_DEG
    for threshold, max_m in ((None, 0.5), (1e-6, 1e-3)):
        options = {"RPC_DEM": ventoux_ellipsoidal}
        if threshold is not None:
            options["RPC_PIXEL_ERROR_THRESHOLD"] = threshold
        with RPCTransformer(quickbird_rpcs(model), **options) as tr:
            x, y = tr.xy(row, col, zs=np.zeros_like(row), offset="center")
        x, y = np.asarray(x, float), np.asarray(y, float)
        ok = np.isfinite(x) & np.isfinite(y)  # where GDAL converges
        assert ok.mean() > 0.9
        dist = np.hypot((x - g.lon) * scale[0], (y - g.lat) * scale[1])[ok]
        assert dist.max() < max_m, (threshold, dist.max())
        res_gdal = _residual_px(model, row[ok], col[ok], x[ok], y[ok], dem.height(x[ok], y[ok]))
        assert res_gb[ok].max() < res_gdal.max()
