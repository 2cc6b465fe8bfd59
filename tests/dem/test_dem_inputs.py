"""open_dem (hence localize) takes opened objects as well as paths: an open rasterio dataset,
a georeferenced xarray.DataArray, a numpy array with its transform and CRS; the heights are
identical, bit for bit, to the file's. Anything else is an InputTypeError naming it."""

from __future__ import annotations

import pickle

import numpy as np
import pytest
import rasterio
import xarray as xr
from affine import Affine
from dask.base import tokenize
from rasterio.io import MemoryFile

import geoblock
import geoblock.pixels
from geoblock.dem import ArrayDem, MosaicDem, RasterDem
from geoblock.errors import DemError, GeoblockError, InputTypeError
from geoblock.testing.synthetic import AffineCamera

from .conftest import smooth_terrain, write_tif


def _points(dem, n=4000, seed=1):
    """Random points over the DEM and a little beyond (edges, outside)."""
    rng = np.random.default_rng(seed)
    w, s, e, nn = dem.bounds
    dw, dn = 0.03 * (e - w), 0.03 * (nn - s)
    return rng.uniform(w - dw, e + dw, n), rng.uniform(s - dn, nn + dn, n)


def _same(a, b):
    return np.array_equal(a, b, equal_nan=True)


def _dataarray(array, transform, crs_wkt, nodata=None):
    """A DataArray georeferenced as rioxarray writes it (spatial_ref: crs_wkt, GeoTransform)."""
    t = transform
    gt = " ".join(repr(float(v)) for v in (t.c, t.a, t.b, t.f, t.d, t.e))
    ref = xr.DataArray(0, attrs={"crs_wkt": crs_wkt, "spatial_ref": crs_wkt, "GeoTransform": gt})
    attrs = {} if nodata is None else {"_FillValue": nodata}
    return xr.DataArray(array, dims=("y", "x"), coords={"spatial_ref": ref}, attrs=attrs,
                        name="heights")


@pytest.fixture(scope="module")
def srtm_pixels(srtm):
    with rasterio.open(srtm) as ds:
        return ds.read(1), ds.transform, ds.crs.to_wkt(), ds.nodata


@pytest.mark.parametrize("interpolation", ["nearest", "bilinear", "bicubic"])
def test_array_dem_heights_are_the_files(srtm, srtm_pixels, egm96_path, interpolation):
    """The real SRTM tile (geoid heights, int16, nodata -32768) from memory: the same heights
    as from the file, bit for bit, statistics and height range included."""
    heights, transform, wkt, nodata = srtm_pixels
    options = dict(vertical="geoid", geoid=egm96_path, interpolation=interpolation)
    from_file = geoblock.open_dem(srtm, **options)
    from_array = geoblock.open_dem(heights, transform=transform, crs=wkt, nodata_value=nodata,
                                   **options)
    assert isinstance(from_array, ArrayDem) and from_array.shape == from_file.shape
    lon, lat = _points(from_file)
    assert _same(from_array.height(lon, lat), from_file.height(lon, lat))
    box = (5.2, 44.1, 5.4, 44.3)
    assert from_array.height_range(box) == from_file.height_range(box)
    assert from_array.statistics() == from_file.statistics()


def test_every_opened_form_gives_the_files_heights(tmp_path, egm96_path):
    """A file dataset (re-opened by its name), an in-memory dataset, a DataArray and a numpy
    array: the same heights as the path, voids filled by the same policy."""
    arr = smooth_terrain(70, 90).astype(np.float32)
    arr[30:34, 40:45] = -9999.0  # a void
    t = Affine(0.001, 0.0, 5.1, 0.0, -0.001, 44.3)
    path = write_tif(tmp_path / "dem.tif", arr, t, "EPSG:4326+5773", nodata=-9999.0)
    options = dict(geoid=egm96_path, nodata="fill")
    reference = geoblock.open_dem(path, **options)
    lon, lat = _points(reference, seed=3)
    expected = reference.height(lon, lat)
    assert np.isnan(expected).any() and np.isfinite(expected).sum() > 3000

    with rasterio.open(path) as ds:
        reopened = geoblock.open_dem(ds, **options)
        assert type(reopened) is RasterDem and reopened.path == reference.path
    with open(path, "rb") as f, MemoryFile(f.read()) as mem, mem.open() as ds:
        in_memory = geoblock.open_dem(ds, **options)
        assert isinstance(in_memory, ArrayDem) and in_memory.vertical == "geoid"
        assert _same(in_memory.height(lon, lat), expected)
    with rasterio.open(path) as ds:
        wkt = ds.crs.to_wkt()
    data = _dataarray(arr, t, wkt, nodata=-9999.0)
    assert _same(geoblock.open_dem(data, **options).height(lon, lat), expected)
    banded = data.expand_dims(band=[1])  # (1, y, x), as rioxarray opens a one-band file
    assert _same(geoblock.open_dem(banded, **options).height(lon, lat), expected)
    assert _same(geoblock.open_dem(arr, transform=t, crs="EPSG:4326+5773",
                                   nodata_value=-9999.0, **options).height(lon, lat), expected)
    # a dask-backed DataArray is computed once
    assert _same(geoblock.open_dem(data.chunk(32), **options).height(lon, lat), expected)


def test_dataarray_georeferenced_by_coordinates(utm_tif):
    """Without a spatial_ref GeoTransform, regular x/y pixel-centre coordinates place it."""
    path, arr, t = utm_tif
    reference = geoblock.open_dem(path, vertical="ellipsoid")
    rows, cols = arr.shape
    x = t.c + t.a * (np.arange(cols) + 0.5)
    y = t.f + t.e * (np.arange(rows) + 0.5)
    data = xr.DataArray(arr, dims=("y", "x"), coords={"y": y, "x": x},
                        attrs={"crs": reference.crs.to_wkt()})
    lon, lat = _points(reference, seed=5)
    assert _same(geoblock.open_dem(data, vertical="ellipsoid").height(lon, lat),
                 reference.height(lon, lat))


def test_array_dem_is_a_value(utm_tif):
    """Pickles with its posts, equal by value, a dask token that follows the posts, a
    to_dict() that open_dem takes back; a mosaic of an array and a file pickles."""
    path, arr, t = utm_tif
    dem = geoblock.open_dem(arr, transform=t, crs="EPSG:32631", vertical="ellipsoid")
    lon, lat = _points(dem, seed=7)
    h = dem.height(lon, lat)
    again = pickle.loads(pickle.dumps(dem))
    assert again == dem and hash(again) == hash(dem) and _same(again.height(lon, lat), h)
    assert tokenize(again) == tokenize(dem)
    other = geoblock.open_dem(arr + 1.0, transform=t, crs="EPSG:32631", vertical="ellipsoid")
    assert other != dem and tokenize(other) != tokenize(dem)
    np.testing.assert_allclose(other.height(lon, lat), h + 1.0, rtol=0, atol=1e-4)
    back = geoblock.open_dem(dem.to_dict())
    assert back == dem and _same(back.height(lon, lat), h)
    assert not dem.array.flags.writeable
    mosaic = geoblock.open_dem([_dataarray(arr, t, dem.crs.to_wkt()), path],
                               vertical="ellipsoid")
    assert isinstance(mosaic, MosaicDem)
    assert _same(pickle.loads(pickle.dumps(mosaic)).height(lon, lat), h)
    assert _same(geoblock.open_dem(mosaic.to_dict()).height(lon, lat), h)


def test_localize_takes_paths_and_opened_dems(tmp_path):
    """localize opens what open_dem opens (with its defaults): the same ground points."""
    model = AffineCamera.example()  # around 7.05E 43.70N
    arr = smooth_terrain(60, 80).astype(np.float32)
    t = Affine(0.001, 0.0, 7.01, 0.0, -0.001, 43.73)
    path = write_tif(tmp_path / "dem.tif", arr, t, "EPSG:4979")  # ellipsoidal: stated
    dem = geoblock.open_dem(path)
    rows, cols = model.shape
    row, col = np.meshgrid(np.linspace(0, rows - 1, 7), np.linspace(0, cols - 1, 9))
    expected, status = geoblock.localize(model, row, col, dem, warn=False)
    assert (status == 0).all()
    with rasterio.open(path) as ds:
        forms = [path, str(path), ds, dem.to_dict(), _dataarray(arr, t, ds.crs.to_wkt())]
        for form in forms:
            got, got_status = geoblock.localize(model, row, col, form, warn=False)
            assert np.array_equal(got_status, status)
            for a, b in zip(got, expected, strict=True):
                assert _same(a, b)


def test_what_cannot_be_a_dem_is_named(tmp_path, utm_tif):
    path, arr, t = utm_tif
    with pytest.raises(InputTypeError, match=r"cannot use an object of type object as a DEM; "
                                             r"accepted: a path") as info:
        geoblock.open_dem(object())
    assert isinstance(info.value, TypeError) and isinstance(info.value, GeoblockError)
    with pytest.raises(InputTypeError, match="type complex as a DEM"):
        geoblock.localize(AffineCamera.example(), 1.0, 2.0, 1j)
    with pytest.raises(DemError, match=r"open_dem\(array, transform=..., crs=...\)"):
        geoblock.open_dem(arr)
    with pytest.raises(InputTypeError, match="describe an in-memory array"):
        geoblock.open_dem(path, transform=t)
    with pytest.raises(DemError, match="not georeferenced.*spatial_ref"):
        geoblock.open_dem(xr.DataArray(arr, dims=("y", "x")))
    with pytest.raises(DemError, match="no CRS"):
        ArrayDem(arr, t, None, vertical="ellipsoid")
    with pytest.raises(DemError, match="2-D"):
        geoblock.open_dem(np.zeros((2, 3, 4)), transform=t, crs="EPSG:32631")
    with pytest.raises(DemError, match="vertical datum is not stated"):
        geoblock.open_dem(arr, transform=t, crs="EPSG:32631")  # as a file refuses it
    with rasterio.open(path) as ds:
        pass
    with pytest.raises(InputTypeError, match="closed"):
        geoblock.open_dem(ds)
    with pytest.raises(InputTypeError, match="DEM tile"):
        geoblock.open_dem([path, object()], vertical="ellipsoid")


def _with_coords(da, transform):
    """``da`` with x/y pixel-centre coordinates (what rioxarray gives)."""
    rows, cols = da.shape[-2:]
    x, y = geoblock.pixels.pixel_centres(transform, (rows, cols))
    return da.assign_coords(x=("x", x), y=("y", y))


def test_dataarray_slices_transposes_scales_and_legacy_nodata_give_the_files_heights(
        srtm, srtm_pixels, egm96_path):
    """Silent wrong answers a DataArray could give: a slice placed by its stale GeoTransform,
    (x, y) dims read as (y, x), scale_factor/add_offset or ``nodatavals`` ignored."""
    heights, transform, wkt, nodata = srtm_pixels
    options = dict(vertical="geoid", geoid=egm96_path)
    full = _with_coords(_dataarray(heights, transform, wkt, nodata), transform)
    from_file = geoblock.open_dem(srtm, **options)
    lon, lat = _points(from_file)
    want = from_file.height(lon, lat)
    sliced = full.isel(x=slice(100, None), y=slice(200, None))  # GeoTransform now stale
    inside = (lon > sliced.x.values[2]) & (lat < sliced.y.values[2])  # bicubic support inside
    got = geoblock.open_dem(sliced, **options).height(lon[inside], lat[inside])
    np.testing.assert_allclose(got, want[inside], rtol=0, atol=1e-6)  # transform from coords
    close = dict(rtol=0, atol=1e-6, equal_nan=True)  # the transform from rounded coordinates
    np.testing.assert_allclose(
        geoblock.open_dem(full.transpose("x", "y"), **options).height(lon, lat), want, **close)
    scaled = full.copy(data=heights.astype(np.float64) * 10.0)
    scaled.attrs.update(scale_factor=0.1, _FillValue=nodata * 10.0)
    np.testing.assert_allclose(geoblock.open_dem(scaled, **options).height(lon, lat), want,
                               **close)
    legacy = full.copy()
    legacy.attrs = {"nodatavals": (nodata,)}
    np.testing.assert_allclose(geoblock.open_dem(legacy, **options).height(lon, lat), want,
                               **close)


def test_a_gdal_order_geotransform_is_refused_and_arrays_are_copied(srtm_pixels):
    heights, transform, wkt, nodata = srtm_pixels
    with pytest.raises(DemError, match=r"from_gdal"):
        geoblock.open_dem(heights, transform=transform.to_gdal(), crs=wkt)
    mine = heights.astype(np.float64)
    dem = geoblock.open_dem(mine, transform=transform, crs=wkt, vertical="ellipsoid",
                            nodata_value=nodata)
    lon, lat = geoblock.pixels.pixel_to_map(transform, 600.0, 600.0)
    before = dem.height(lon, lat)
    mine[:] = 0.0  # the caller's array changes; the DEM must not
    assert dem.height(lon, lat) == before != 0.0
