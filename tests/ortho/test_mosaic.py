"""mosaic: union grid, priority and feather values, contribution band, chunk independence,
alignment errors, (image, model) pairs, reading GeoTIFF orthos."""

from __future__ import annotations

import hashlib
import math
import warnings

import dask
import dask.array as da
import numpy as np
import pytest
import rasterio
import xarray as xr
from affine import Affine

from geoblock.dem import ConstantDem
from geoblock.errors import GeoblockError
from geoblock.io import write_ortho
from geoblock.ortho import OutputGrid, mosaic, orthorectify
from geoblock.ortho.graph import _coords
from geoblock.ortho.mosaic import MosaicError, open_ortho
from geoblock.testing.synthetic import AffineCamera

RES = 10.0
X0, Y0 = 500000.0, 4800000.0


def _grid(row0: int, col0: int, shape, crs="EPSG:32631", res=RES, shift=0.0) -> OutputGrid:
    return OutputGrid(crs, Affine(res, 0.0, X0 + res * col0 + shift, 0.0, -res, Y0 - res * row0),
                      shape)


def _ortho(values: np.ndarray, grid: OutputGrid, fill=0, chunks=8) -> xr.DataArray:
    attrs = {} if fill is None else {"_FillValue": fill}
    return xr.DataArray(da.from_array(values, chunks=(-1, chunks, chunks)), dims=("band", "y", "x"),
                        coords=_coords(grid, values.shape[0], fill), attrs=attrs)


@pytest.fixture(scope="module")
def pair():
    """Two overlapping uint16 orthos (2 bands) on a 10 m UTM grid; A has a nodata hole."""
    rng = np.random.default_rng(1)
    a = rng.integers(1, 60000, (2, 20, 30)).astype(np.uint16)
    b = rng.integers(1, 60000, (2, 24, 26)).astype(np.uint16)
    a[:, 12:15, 20:23] = 0  # a hole in A, inside the overlap
    return (a, _grid(0, 0, (20, 30))), (b, _grid(8, 12, (24, 26)))


def _placed(values, grid, union, fill=0):
    """Values and validity of one source on the union grid (NumPy reference)."""
    r0 = round((grid.transform.f - union.transform.f) / union.transform.e)
    c0 = round((grid.transform.c - union.transform.c) / union.transform.a)
    out = np.full((values.shape[0],) + union.shape, fill, values.dtype)
    out[:, r0:r0 + grid.shape[0], c0:c0 + grid.shape[1]] = values
    valid = np.zeros(union.shape, bool)
    valid[r0:r0 + grid.shape[0], c0:c0 + grid.shape[1]] = (values != fill).all(axis=0)
    return out, valid


def _brute_distance(valid: np.ndarray, cap: float) -> np.ndarray:
    """min(distance to the nearest invalid pixel, cap); outside the array is invalid."""
    pad = int(math.ceil(cap)) + 1
    m = np.pad(valid, pad, constant_values=False)
    bad = np.argwhere(~m)
    rows, cols = np.nonzero(valid)
    d = np.sqrt(((rows[:, None] + pad - bad[None, :, 0]) ** 2
                 + (cols[:, None] + pad - bad[None, :, 1]) ** 2).min(axis=1))
    out = np.zeros(valid.shape)
    out[rows, cols] = np.minimum(d, cap)
    return out


def _digest(ds: xr.Dataset) -> str:
    ds = ds.compute()
    h = hashlib.sha256(np.ascontiguousarray(ds.mosaic.values).tobytes())
    h.update(np.ascontiguousarray(ds.contribution.values).tobytes())
    return h.hexdigest()


def test_union_grid_and_layout(pair):
    (a, ga), (b, gb) = pair
    ds = mosaic([_ortho(a, ga), _ortho(b, gb)])
    assert isinstance(ds, xr.Dataset)
    assert ds.mosaic.dims == ("band", "y", "x") and ds.contribution.dims == ("y", "x")
    assert ds.mosaic.shape == (2, 32, 38) and ds.mosaic.dtype == np.uint16
    assert ds.contribution.dtype == np.uint8
    assert isinstance(ds.mosaic.data, da.Array) and ds.mosaic.chunks[1][0] == 8
    ref = ds.coords["spatial_ref"].attrs
    c, a_, b_, f, d, e = (float(v) for v in ref["GeoTransform"].split())
    assert Affine(a_, b_, c, d, e, f) == Affine(RES, 0, X0, 0, -RES, Y0)
    assert ds.mosaic.attrs["_FillValue"] == 0
    np.testing.assert_array_equal(ds.x.values, X0 + RES * (np.arange(38) + 0.5))


def test_building_computes_nothing(pair):
    (a, ga), (b, gb) = pair

    def refuse(*args, **kwargs):
        raise AssertionError("the graph was computed")

    with dask.config.set(scheduler=refuse):
        for method in ("priority", "feather"):
            mosaic([_ortho(a, ga), _ortho(b, gb)], method=method, feather_px=3)


def test_priority_values_and_contribution(pair):
    (a, ga), (b, gb) = pair
    ds = mosaic([_ortho(a, ga), _ortho(b, gb)]).compute()
    union = _grid(0, 0, (32, 38))
    va, ma = _placed(a, ga, union)
    vb, mb = _placed(b, gb, union)
    expected = np.where(ma[None], va, np.where(mb[None], vb, 0))
    np.testing.assert_array_equal(ds.mosaic.values, expected)
    contrib = np.where(ma, 1, np.where(mb, 2, 0))
    np.testing.assert_array_equal(ds.contribution.values, contrib)
    # the hole of A is filled from B, the overlap elsewhere comes from A
    assert (ds.contribution.values[12:15, 20:23] == 2).all()
    assert (ds.contribution.values[8:12, 12:30] == 1).all()
    # reversed priority
    ds2 = mosaic([_ortho(b, gb), _ortho(a, ga)]).compute()
    np.testing.assert_array_equal(ds2.mosaic.values,
                                  np.where(mb[None], vb, np.where(ma[None], va, 0)))


def test_feather_values_exact(pair):
    (a, ga), (b, gb) = pair
    cap = 4.5
    ds = mosaic([_ortho(a, ga), _ortho(b, gb)], method="feather", feather_px=cap).compute()
    union = _grid(0, 0, (32, 38))
    va, ma = _placed(a, ga, union)
    vb, mb = _placed(b, gb, union)
    wa, wb = _brute_distance(ma, cap), _brute_distance(mb, cap)
    with np.errstate(invalid="ignore", divide="ignore"):
        blend = (wa * va + wb * vb) / (wa + wb)
    rounded = np.floor(blend + 0.5)  # values are positive: half away from zero
    both = ma & mb
    expected = np.where(ma[None] & ~mb[None], va, np.where(mb[None] & ~ma[None], vb, 0))
    expected = np.where(both[None], rounded, expected).astype(np.uint16)
    np.testing.assert_array_equal(ds.mosaic.values, expected)
    contrib = np.where(wb > wa, 2, np.where(ma, 1, np.where(mb, 2, 0)))
    np.testing.assert_array_equal(ds.contribution.values, contrib)
    # a real transition: at least one blended value differs from both sources
    assert ((ds.mosaic.values != va) & (ds.mosaic.values != vb))[:, both].any()


def test_feather_float_nan_nodata():
    g1, g2 = _grid(0, 0, (10, 12)), _grid(3, 4, (10, 12))
    v1 = np.full((1, 10, 12), 10.0, np.float32)
    v2 = np.full((1, 10, 12), 20.0, np.float32)
    v1[0, 0, 0] = np.nan
    ds = mosaic([_ortho(v1, g1, fill=None), _ortho(v2, g2, fill=None)], method="feather",
                feather_px=2).compute()
    assert ds.mosaic.dtype == np.float32 and math.isnan(ds.mosaic.attrs["_FillValue"])
    out = ds.mosaic.values[0]
    assert math.isnan(out[0, 0]) and math.isnan(out[12, 0])
    assert out[1, 1] == 10.0 and out[12, 15] == 20.0  # single sources copied exactly
    # pixel (5, 6): distance to A's edge 4 (->2), to B's 3 (->2): the mean
    assert out[5, 6] == 15.0
    # pixel (3, 5): A's weight 2, B's weight 1 (first row of B)
    assert out[3, 5] == np.float32((2 * 10.0 + 1 * 20.0) / 3)


@pytest.mark.parametrize("method", ["priority", "feather"])
def test_identical_bytes_whatever_the_chunking(pair, method):
    (a, ga), (b, gb) = pair
    digests = {
        (src_chunks, out_chunks): _digest(mosaic(
            [_ortho(a, ga, chunks=src_chunks), _ortho(b, gb, chunks=src_chunks)],
            method=method, feather_px=6.0, chunks=out_chunks))
        for src_chunks, out_chunks in ((4, 5), (7, (3, 11)), (100, 1000))
    }
    assert len(set(digests.values())) == 1, digests


def test_given_grid_cuts_and_extends(pair):
    (a, ga), (b, gb) = pair
    full = mosaic([_ortho(a, ga), _ortho(b, gb)], method="feather", feather_px=3).compute()
    grid = _grid(-2, 5, (20, 40))  # two rows above the union, cut on the left
    part = mosaic([_ortho(a, ga), _ortho(b, gb)], grid, method="feather", feather_px=3).compute()
    assert part.mosaic.shape == (2, 20, 40)
    np.testing.assert_array_equal(part.mosaic.values[:, 2:, :33], full.mosaic.values[:, :18, 5:])
    np.testing.assert_array_equal(part.contribution.values[2:, :33],
                                  full.contribution.values[:18, 5:])
    assert (part.contribution.values[:2] == 0).all() and (part.mosaic.values[:, :2] == 0).all()


def test_nodata_argument(pair):
    (a, ga), (b, gb) = pair
    ds = mosaic([_ortho(a, ga), _ortho(b, gb)], nodata=65535).compute()
    assert ds.mosaic.attrs["_FillValue"] == 65535
    assert (ds.mosaic.values[:, ds.contribution.values == 0] == 65535).all()
    with pytest.raises(MosaicError, match="representable"):
        mosaic([_ortho(a, ga)], nodata=-1)


def test_crs_mismatch(pair):
    (a, ga), (b, _) = pair
    other = _grid(8, 12, (24, 26), crs="EPSG:32632")
    with pytest.raises(MosaicError, match="CRS") as info:
        mosaic([_ortho(a, ga), _ortho(b, other)])
    assert isinstance(info.value, GeoblockError)
    assert "source 2" in str(info.value) and "reproject" in str(info.value)


def test_resolution_phase_bands_mismatch(pair):
    (a, ga), (b, _) = pair
    with pytest.raises(MosaicError, match="resolution"):
        mosaic([_ortho(a, ga), _ortho(b, _grid(8, 12, (24, 26), res=5.0))])
    with pytest.raises(MosaicError, match="pixel-aligned"):
        mosaic([_ortho(a, ga), _ortho(b, _grid(8, 12, (24, 26), shift=2.5))])
    with pytest.raises(MosaicError, match="bands"):
        mosaic([_ortho(a, ga), _ortho(b[:1], _grid(8, 12, (24, 26)))])
    with pytest.raises(MosaicError, match="method"):
        mosaic([_ortho(a, ga)], method="average")
    with pytest.raises(MosaicError, match="feather_px"):
        mosaic([_ortho(a, ga)], method="feather", feather_px=0)
    with pytest.raises(MosaicError, match="no sources"):
        mosaic([])


def _raw_image(path, shape, value):
    data = ((np.arange(shape[0] * shape[1]) % 200) + value).astype(np.uint8).reshape((1,) + shape)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
        with rasterio.open(path, "w", driver="GTiff", width=shape[1], height=shape[0], count=1,
                           dtype="uint8") as ds:
            ds.write(data)
    return str(path)


def test_image_model_pairs(tmp_path):
    model = AffineCamera.example((40, 50))
    dem = ConstantDem(150.0)
    p1 = _raw_image(tmp_path / "a.tif", (40, 50), 1)
    p2 = _raw_image(tmp_path / "b.tif", (40, 50), 40)
    grid = OutputGrid.for_model(model, dem)
    ds = mosaic([(p1, model), (p2, model)], grid, dem=dem, method="feather", feather_px=3,
                chunks=32)
    o1 = orthorectify(p1, model, dem, grid, chunks=32)
    o2 = orthorectify(p2, model, dem, grid, chunks=16)
    ref = mosaic([o1, o2], method="feather", feather_px=3, chunks=32)
    assert _digest(ds) == _digest(ref)
    assert ds.mosaic.shape[1:] == grid.shape
    with pytest.raises(MosaicError, match="grid"):
        mosaic([(p1, model)], dem=dem)


def test_open_ortho_round_trip(pair, tmp_path):
    (a, ga), _ = pair
    path = write_ortho(_ortho(a, ga), tmp_path / "a.tif")
    back = open_ortho(path, chunks=7)
    assert back.chunks[1][0] == 7 and back.attrs["_FillValue"] == 0
    np.testing.assert_array_equal(back.values, a)
    assert back.coords["spatial_ref"].attrs["GeoTransform"] == \
        _ortho(a, ga).coords["spatial_ref"].attrs["GeoTransform"]
