"""open_dem: every kind of source, options and errors."""

from __future__ import annotations

import pickle

import numpy as np
import pytest
from affine import Affine

import geoblock
from geoblock.dem import ConstantDem, ConstantGeoidDem, DemSource, MosaicDem, RasterDem
from geoblock.errors import DemError, GeoblockError, InputTypeError

from .conftest import write_tif


def test_exported():
    assert geoblock.open_dem is geoblock.io.open_dem
    assert "open_dem" in geoblock.__all__ and "open_dem" in geoblock.io.__all__


def test_const(egm96_path):
    dem = geoblock.open_dem("const:250.5")
    assert isinstance(dem, ConstantDem) and float(dem.height(1.0, 2.0)) == 250.5
    g = geoblock.open_dem("const:100", vertical="geoid", geoid=egm96_path)
    assert isinstance(g, ConstantGeoidDem) and isinstance(g, DemSource)
    assert float(g.height(0.0, 0.0)) == pytest.approx(100 + 17.16157913, abs=1e-6)
    lo, hi = g.height_range((5.0, 44.0, 6.0, 45.0))
    assert lo < float(g.height(5.5, 44.5)) < hi
    assert pickle.loads(pickle.dumps(g)) == g
    assert geoblock.open_dem(g.to_dict()) == g
    with pytest.raises(DemError, match="const:abc"):
        geoblock.open_dem("const:abc")


def test_files_lists_and_dicts(srtm, utm_tif, egm96_path):
    path, _, _ = utm_tif
    one = geoblock.open_dem(str(path), vertical="ellipsoid")
    assert isinstance(one, RasterDem) and isinstance(one, DemSource)
    assert isinstance(geoblock.open_dem([path], vertical="ellipsoid"), RasterDem)
    both = geoblock.open_dem([srtm, path], geoid=egm96_path, vertical="ellipsoid")
    assert isinstance(both, MosaicDem) and len(both.tiles) == 2
    assert geoblock.open_dem(both.to_dict()) == both
    assert geoblock.open_dem(one) is one


def test_vrt(tmp_path, srtm, egm96_path):
    """A VRT over the SRTM tile gives the tile's heights (stated datum: the caller's)."""
    import rasterio
    from rasterio.vrt import WarpedVRT

    vrt = tmp_path / "srtm.vrt"
    with rasterio.open(srtm) as ds, WarpedVRT(ds) as w:
        from rasterio.shutil import copy

        copy(w, vrt, driver="VRT")
    dem = geoblock.open_dem(vrt, vertical="geoid", geoid=egm96_path)
    ref = geoblock.open_dem(srtm, geoid=egm96_path, interpolation="nearest")
    lon, lat = np.array([5.3, 5.7]), np.array([44.2, 44.8])
    np.testing.assert_allclose(
        geoblock.open_dem(vrt, vertical="geoid", geoid=egm96_path,
                          interpolation="nearest").height(lon, lat), ref.height(lon, lat))
    assert np.isfinite(dem.height(lon, lat)).all()


def test_errors(tmp_path):
    with pytest.raises(DemError, match="not found: .*missing.tif"):
        geoblock.open_dem(tmp_path / "missing.tif")
    with pytest.raises(GeoblockError, match="vertical"):
        geoblock.open_dem("const:0", vertical="orthometric")
    with pytest.raises(DemError, match="empty"):
        geoblock.open_dem([])
    with pytest.raises(DemError, match="kind"):
        geoblock.open_dem({"dem": "weird"})
    with pytest.raises(InputTypeError, match="cannot use an object of type int as a DEM"):
        geoblock.open_dem(42)
    p = write_tif(tmp_path / "x.tif", np.zeros((3, 3), np.float32),
                  Affine(1, 0, 0, 0, -1, 3), "EPSG:32631")
    with pytest.raises(DemError, match="x.tif.*vertical="):
        geoblock.open_dem(p)


def test_missing_heights_policy_covers_voids_and_outside(tmp_path):
    """open_dem(missing=H): GDAL's RPC_DEM_MISSING_VALUE, as a DEM of its own."""
    import pickle

    import rasterio
    from affine import Affine

    import geoblock
    from geoblock.dem import FilledDem

    path = tmp_path / "dem.tif"
    data = np.full((4, 4), 100.0)
    data[1, 1] = -9999.0
    with rasterio.open(path, "w", driver="GTiff", width=4, height=4, count=1, dtype="float64",
                       crs="EPSG:4979", transform=Affine(0.1, 0.0, 5.0, 0.0, -0.1, 45.0),
                       nodata=-9999.0) as ds:
        ds.write(data, 1)
    dem = geoblock.open_dem(path, missing=7.0, interpolation="nearest")
    assert isinstance(dem, FilledDem)
    h, status = dem.height_with_status([5.05, 5.15, 20.0], [44.95, 44.85, 0.0])
    assert h.tolist() == [100.0, 7.0, 7.0] and status.tolist() == [0, 0, 0]
    assert dem.height_range() == (7.0, 100.0)
    again = geoblock.open_dem(dem.to_dict())
    assert again == dem and pickle.loads(pickle.dumps(dem)) == dem
