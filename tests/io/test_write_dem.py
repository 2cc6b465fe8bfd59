"""geoblock.io.write_dem: GeoTIFFs whose CRS states the vertical datum, read back by open_dem."""

from __future__ import annotations

import numpy as np
import pytest
import rasterio
from affine import Affine

from geoblock.dem.raster import file_vertical
from geoblock.errors import DemError, GeoblockIOError
from geoblock.io import open_dem, write_dem
from geoblock.io.dem import vertical_crs

UTM_T = Affine(30.0, 0.0, 660000.0, 0.0, -30.0, 4900000.0)
GEO_T = Affine(0.001, 0.0, 5.0, 0.0, -0.001, 44.1)


def _heights(rows=40, cols=50):
    r, c = np.mgrid[0:rows, 0:cols]
    return 500.0 + 200.0 * np.sin(r / 7.0) * np.cos(c / 9.0)


@pytest.mark.parametrize(("crs", "transform"), [("EPSG:32631", UTM_T), ("EPSG:4326", GEO_T)])
def test_ellipsoidal_round_trip_without_being_told(tmp_path, crs, transform):
    h = _heights()
    h[3, 4] = np.nan
    path = write_dem(tmp_path / "e.tif", h, transform, crs, "ellipsoid", dtype="float64")
    dem = open_dem(path)
    assert dem.vertical == "ellipsoid"
    with rasterio.open(path) as ds:
        assert ds.nodata == -9999.0 and ds.dtypes[0] == "float64"
        assert ds.tags(1)["GEOBLOCK_VERTICAL"] == "ellipsoid"
        assert ds.tags(1)["VERTICAL_DATUM"] == "WGS84 ellipsoid"
        data = ds.read(1, masked=True)
        assert data.mask[3, 4] and data.mask.sum() == 1
        np.testing.assert_array_equal(data.filled(np.nan)[~np.isnan(h)], h[~np.isnan(h)])
    # sample at pixel centres through geoblock
    rows, cols = np.array([10.0, 20.0]), np.array([11.0, 30.0])
    x, y = transform.c + (cols + 0.5) * transform.a, transform.f + (rows + 0.5) * transform.e
    from geoblock.coords import transformer

    lon, lat = transformer(crs, "EPSG:4326").transform(x, y)
    np.testing.assert_allclose(dem.height(lon, lat), h[10:21:10, [11, 30]].diagonal(), atol=1e-6)
    assert list(tmp_path.iterdir()) == [path]  # no temporary file left


def test_geoid_round_trip(tmp_path, data_dir):
    egm96 = data_dir / "shareloc" / "dtm" / "geoid" / "egm96_15.gtx"
    path = write_dem(tmp_path / "g.tif", _heights(), UTM_T, "EPSG:32631", "geoid")
    dem = open_dem(path, geoid=egm96)
    assert dem.vertical == "geoid" and "EGM96" in dem.vertical_source
    with rasterio.open(path) as ds:
        assert ds.tags(1)["GEOBLOCK_VERTICAL"] == "geoid"


@pytest.mark.parametrize("crs", ["EPSG:32631", "EPSG:4326", "EPSG:4979", "EPSG:32631+5773"])
@pytest.mark.parametrize("vertical", ["ellipsoid", "geoid"])
def test_vertical_crs_states_the_datum(crs, vertical):
    assert file_vertical(vertical_crs(crs, vertical), "GTiff")[0] == vertical


def test_bad_arguments(tmp_path):
    with pytest.raises(DemError, match="vertical must be"):
        write_dem(tmp_path / "x.tif", _heights(), UTM_T, "EPSG:32631", None)
    with pytest.raises(DemError, match="2-D"):
        write_dem(tmp_path / "x.tif", np.zeros(4), UTM_T, "EPSG:32631", "geoid")
    with pytest.raises(DemError, match="infinite"):
        write_dem(tmp_path / "x.tif", np.full((2, 2), np.inf), UTM_T, "EPSG:32631", "geoid")
    with pytest.raises(GeoblockIOError, match="does not exist"):
        write_dem(tmp_path / "no" / "x.tif", _heights(), UTM_T, "EPSG:32631", "geoid")
    assert list(tmp_path.iterdir()) == []
