"""Fixtures of the DEM tests: the real DEMs of the shared data and small synthetic GeoTIFFs."""

from __future__ import annotations

import numpy as np
import pytest
import rasterio
from affine import Affine


@pytest.fixture(scope="session")
def srtm(data_dir):
    return data_dir / "shareloc" / "dtm" / "srtm_ventoux" / "srtm90_non_void_filled" / "N44E005.hgt"


@pytest.fixture(scope="session")
def egm96_path(data_dir):
    return data_dir / "shareloc" / "dtm" / "geoid" / "egm96_15.gtx"


@pytest.fixture(scope="session")
def mnt_geoid(data_dir):
    return (
        data_dir / "shareloc" / "geoide" / "P1BP--2017030824934340CP"
        / "MNT_P1BP--2017030824934340CP.tif"
    )


def write_tif(path, array, transform, crs, nodata=None):
    """A one-band GeoTIFF (crs: anything pyproj reads, compound CRSs included)."""
    import pyproj

    crs = rasterio.crs.CRS.from_wkt(pyproj.CRS.from_user_input(crs).to_wkt())
    array = np.asarray(array)
    with rasterio.open(path, "w", driver="GTiff", width=array.shape[1], height=array.shape[0],
                       count=1, dtype=array.dtype, crs=crs, transform=transform,
                       nodata=nodata) as ds:
        ds.write(array, 1)
    return path


def smooth_terrain(rows, cols, seed=0):
    rng = np.random.default_rng(seed)
    r, c = np.mgrid[0:rows, 0:cols]
    return (500 + 200 * np.sin(r / 17.0) * np.cos(c / 23.0) + rng.normal(0, 3, (rows, cols)))


@pytest.fixture
def utm_tif(tmp_path):
    """60 x 80 float32 heights in EPSG:32631 (near 5E 44N), 30 m posts, ellipsoidal (3-D)."""
    arr = smooth_terrain(60, 80).astype(np.float32)
    t = Affine(30.0, 0.0, 660000.0, 0.0, -30.0, 4900000.0)
    return write_tif(tmp_path / "utm.tif", arr, t, "EPSG:32631"), arr, t
