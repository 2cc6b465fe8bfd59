"""OutputGrid: gdalwarp's -te/-tr/-tap grid, slicing, chunks, the default grid of a model."""

from __future__ import annotations

import ctypes
import glob
import os
import pickle

import numpy as np
import pyproj
import pytest
import rasterio
from affine import Affine
from hypothesis import given, settings
from hypothesis import strategies as st

from geoblock import coords
from geoblock.dem import ConstantDem
from geoblock.errors import GridError
from geoblock.ortho.grid import OutputGrid
from geoblock.testing.synthetic import AffineCamera


# ---------------------------------------------------------------------- real gdalwarp
def _libgdal():
    """rasterio's own libgdal, through ctypes (GDALWarp is the library behind gdalwarp)."""
    site_packages = os.path.dirname(os.path.dirname(rasterio.__file__))
    libs = glob.glob(os.path.join(site_packages, "rasterio.libs", "libgdal*"))
    if not libs:
        pytest.skip("rasterio's bundled libgdal not found (GDALWarp needed)")
    lib = ctypes.CDLL(libs[0])
    lib.GDALAllRegister()
    vp, cp = ctypes.c_void_p, ctypes.c_char_p
    lib.GDALOpen.restype, lib.GDALOpen.argtypes = vp, [cp, ctypes.c_int]
    lib.GDALWarpAppOptionsNew.restype = vp
    lib.GDALWarpAppOptionsNew.argtypes = [ctypes.POINTER(cp), vp]
    lib.GDALWarpAppOptionsFree.argtypes = [vp]
    lib.GDALWarp.restype = vp
    lib.GDALWarp.argtypes = [
        cp, vp, ctypes.c_int, ctypes.POINTER(vp), vp, ctypes.POINTER(ctypes.c_int)
    ]
    lib.GDALGetRasterXSize.argtypes = lib.GDALGetRasterYSize.argtypes = [vp]
    lib.GDALGetGeoTransform.argtypes = [vp, ctypes.POINTER(ctypes.c_double)]
    lib.GDALClose.argtypes = [vp]
    return lib


def gdalwarp_grid(tmp_path, crs, bounds, res, tap):
    """(shape, transform) of ``gdalwarp -of MEM -t_srs crs -tr res -te bounds [-tap]``."""
    lib = _libgdal()
    xmin, ymin, xmax, ymax = bounds
    src_path = str(tmp_path / "src.tif")
    transform = Affine(abs(xmax - xmin) / 4, 0, xmin, 0, -abs(ymax - ymin) / 4, ymax)
    with rasterio.open(src_path, "w", driver="GTiff", width=4, height=4, count=1, dtype="uint8",
                       crs=crs, transform=transform) as ds:
        ds.write(np.ones((1, 4, 4), np.uint8))
    args = [b"-of", b"MEM", b"-t_srs", crs.encode(),
            b"-tr", repr(res[0]).encode(), repr(res[1]).encode(),
            b"-te", *(repr(float(v)).encode() for v in bounds)] + ([b"-tap"] if tap else [])
    argv = (ctypes.c_char_p * (len(args) + 1))(*args, None)
    opts = lib.GDALWarpAppOptionsNew(argv, None)
    src = lib.GDALOpen(src_path.encode(), 0)
    err = ctypes.c_int(0)
    dst = lib.GDALWarp(b"", None, 1, (ctypes.c_void_p * 1)(src), opts, ctypes.byref(err))
    assert dst, "GDALWarp failed"
    gt = (ctypes.c_double * 6)()
    lib.GDALGetGeoTransform(dst, gt)
    shape = (lib.GDALGetRasterYSize(dst), lib.GDALGetRasterXSize(dst))
    lib.GDALClose(dst)
    lib.GDALClose(src)
    lib.GDALWarpAppOptionsFree(opts)
    return shape, Affine.from_gdal(*gt)


CASES = [
    ("EPSG:32632", (341649.73, 4839370.11, 344097.2, 4841429.69), (2.0, 2.0)),
    ("EPSG:32632", (300000.1, 4799900.05, 300033.2, 4799999.97), (0.3, 0.3)),
    ("EPSG:32632", (500000.0, 4000000.0, 500010.5, 4000007.5), (1.0, 1.0)),  # exact halves
    ("EPSG:3857", (-12345.678, -9876.5, -1234.5, 1111.1), (7.3, 11.9)),  # negative, xres != yres
    ("EPSG:3857", (-1000.0, -1000.0, -999.9, -999.95), (1.0, 1.0)),  # smaller than a pixel
    ("EPSG:4326", (6.912, 43.6017, 7.1803, 43.7791), (0.00025, 0.0003)),
]


@pytest.mark.parametrize("align", [False, True])
@pytest.mark.parametrize(("crs", "bounds", "res"), CASES)
def test_from_bounds_is_gdalwarp_grid(tmp_path, crs, bounds, res, align):
    shape, transform = gdalwarp_grid(tmp_path, crs, bounds, res, align)
    grid = OutputGrid.from_bounds(crs, bounds, res, align=align)
    assert grid.shape == shape
    assert tuple(grid.transform) == tuple(transform)  # bit for bit
    assert grid.crs == pyproj.CRS.from_user_input(crs)


def test_from_bounds_rounding_rule():
    # cols = round half away from zero of (xmax - xmin) / xres, at least 1
    g = OutputGrid.from_bounds("EPSG:32632", (0.0, 0.0, 10.5, 7.49), 1.0)
    assert g.shape == (7, 11)
    assert g.transform == Affine(1.0, 0.0, 0.0, 0.0, -1.0, 7.49)
    assert OutputGrid.from_bounds("EPSG:32632", (0.0, 0.0, 0.2, 0.2), 1.0).shape == (1, 1)
    a = OutputGrid.from_bounds("EPSG:32632", (0.3, -2.2, 10.5, 7.49), 2.0, align=True)
    assert a.bounds == (0.0, -4.0, 12.0, 8.0)
    assert a.shape == (6, 6)
    with pytest.raises(ValueError):
        OutputGrid.from_bounds("EPSG:32632", (1.0, 0.0, 0.0, 1.0), 1.0)
    with pytest.raises(ValueError):
        OutputGrid.from_bounds("EPSG:32632", (0.0, 0.0, 1.0, 1.0), -1.0)


# ---------------------------------------------------------------------- geometry
GRID = OutputGrid("EPSG:32632", Affine(2.0, 0.0, 340000.0, 0.0, -2.5, 4840000.0), (40, 60))


def test_xy_rowcol_bounds_resolution():
    x, y = GRID.xy(0, 0)
    assert (float(x), float(y)) == (340001.0, 4839998.75)
    rr, cc = np.mgrid[0:40, 0:60]
    x, y = GRID.xy(rr, cc)
    assert x.shape == (40, 60)
    r, c = GRID.rowcol(x, y)
    np.testing.assert_allclose(r, rr, atol=1e-9)
    np.testing.assert_allclose(c, cc, atol=1e-9)
    r, c = GRID.rowcol(340000.0, 4840000.0)  # the outer corner is (-0.5, -0.5)
    assert (float(r), float(c)) == (-0.5, -0.5)
    assert GRID.bounds == (340000.0, 4839900.0, 340120.0, 4840000.0)
    assert GRID.resolution == (2.0, 2.5)
    x, y = GRID.xy(np.arange(3)[:, None], np.arange(4))  # broadcast
    assert x.shape == y.shape == (3, 4)


def test_lonlat_matches_pyproj():
    rr, cc = np.mgrid[0:40:7, 0:60:9]
    lon, lat = GRID.lonlat(rr, cc)
    x, y = GRID.xy(rr, cc)
    ref = pyproj.Transformer.from_crs("EPSG:32632", "EPSG:4326", always_xy=True).transform(x, y)
    np.testing.assert_allclose(lon, ref[0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(lat, ref[1], rtol=0, atol=1e-12)
    assert lon.shape == rr.shape


def test_rejects_bad_arguments():
    with pytest.raises(ValueError):
        OutputGrid("EPSG:32632", Affine(2.0, 0.1, 0.0, 0.0, -2.0, 0.0), (4, 4))  # rotated
    with pytest.raises(ValueError):
        OutputGrid("EPSG:32632", Affine(2.0, 0.0, 0.0, 0.0, 2.0, 0.0), (4, 4))  # south-up
    with pytest.raises(ValueError):
        OutputGrid("EPSG:32632", Affine(2.0, 0.0, 0.0, 0.0, -2.0, 0.0), (0, 4))
    with pytest.raises(TypeError):
        GRID[3]
    with pytest.raises(IndexError):
        GRID[::2, :]
    with pytest.raises(IndexError):
        GRID[5:5, :]


def test_value_semantics():
    import dask.base

    same = OutputGrid.from_dict(GRID.to_dict())
    assert same == GRID and hash(same) == hash(GRID)
    assert pickle.loads(pickle.dumps(GRID)) == GRID
    assert dask.base.tokenize(same) == dask.base.tokenize(GRID)
    assert GRID[1:, :] != GRID
    assert dask.base.tokenize(GRID[1:, :]) != dask.base.tokenize(GRID)
    d = GRID.to_dict()
    assert d["shape"] == [40, 60] and d["transform"] == [2.0, 0.0, 340000.0, 0.0, -2.5, 4840000.0]
    assert "UTM zone 32N" in d["crs"]
    with pytest.raises(AttributeError):
        GRID.shape = (1, 1)  # type: ignore[misc]


@settings(max_examples=60, deadline=None)
@given(
    rows=st.integers(1, 50), cols=st.integers(1, 50),
    size=st.one_of(st.integers(1, 60), st.tuples(st.integers(1, 60), st.integers(1, 60))),
)
def test_chunks_cover_grid_once_row_major(rows, cols, size):
    grid = OutputGrid("EPSG:32632", Affine(0.5, 0.0, -10.0, 0.0, -0.5, 20.0), (rows, cols))
    tiles = grid.chunks(size)
    count = np.zeros((rows, cols), int)
    for rs, cs in tiles:
        count[rs, cs] += 1
    assert (count == 1).all()
    starts = [(rs.start, cs.start) for rs, cs in tiles]
    assert starts == sorted(starts)
    for rs, cs in tiles:  # each tile is a sub-grid whose pixels are the parent's
        sub = grid[rs, cs]
        assert sub.shape == (rs.stop - rs.start, cs.stop - cs.start)
        np.testing.assert_allclose(sub.xy(0, 0), grid.xy(rs.start, cs.start), rtol=0, atol=1e-9)
        assert sub.resolution == grid.resolution and sub.crs == grid.crs


@settings(max_examples=60, deadline=None)
@given(r0=st.integers(-40, 39), r1=st.integers(-40, 40),
       c0=st.integers(-60, 59), c1=st.integers(-60, 60))
def test_slicing_like_numpy(r0, r1, c0, c1):
    ref = np.empty(GRID.shape)[r0:r1, c0:c1]
    if ref.size == 0:
        with pytest.raises(IndexError):
            GRID[r0:r1, c0:c1]
        return
    sub = GRID[r0:r1, c0:c1]
    assert sub.shape == ref.shape
    start_r = range(40)[r0:r1][0]
    start_c = range(60)[c0:c1][0]
    np.testing.assert_allclose(sub.xy(0, 0), GRID.xy(start_r, start_c), rtol=0, atol=1e-9)
    assert sub[0:1, 0:1] == GRID[start_r:start_r + 1, start_c:start_c + 1]


# ---------------------------------------------------------------------- default grid of a model
def test_for_model_affine_camera():
    model = AffineCamera.example()
    grid = OutputGrid.for_model(model, ConstantDem(100.0))
    assert grid.crs.to_epsg() == 32632
    xres, yres = grid.resolution
    assert xres == yres and abs(xres - 2.0) < 0.01  # 2 m GSD times the UTM scale factor
    assert abs(grid.transform.c / xres - round(grid.transform.c / xres)) < 1e-6  # aligned
    assert abs(grid.transform.f / yres - round(grid.transform.f / yres)) < 1e-6
    # the footprint on the DEM (pixel edges at h = 100) lies inside, and fills the box
    fp = model.footprint(100.0, n=64)
    x, y = coords.transformer("EPSG:4326", grid.crs).transform(fp.lon, fp.lat)
    xmin, ymin, xmax, ymax = grid.bounds
    assert x.min() >= xmin and x.max() <= xmax and y.min() >= ymin and y.max() <= ymax
    assert x.min() - xmin < xres and xmax - x.max() < xres
    assert y.min() - ymin < yres and ymax - y.max() < yres
    # the image centre projects to the grid's interior; the grid covers the image at 2 m
    rows, cols = grid.shape
    assert 1000 <= rows <= 1100 and 1200 <= cols <= 1300


def test_for_model_overrides():
    model = AffineCamera.example((200, 300))
    g = OutputGrid.for_model(model, 100.0, crs="EPSG:32631", resolution=5.0, align=False)
    assert g.crs.to_epsg() == 32631 and g.resolution == (5.0, 5.0)
    b = (g.bounds[0], g.bounds[1], g.bounds[0] + 100.0, g.bounds[1] + 50.0)
    g2 = OutputGrid.for_model(model, 100.0, crs="EPSG:32631", resolution=5.0, bounds=b)
    assert g2 == OutputGrid.from_bounds("EPSG:32631", b, 5.0, align=True)


def test_for_model_uses_dem_height_range():
    """The default bounds hold the outline at the DEM's lowest and highest heights."""

    class TiltedDem(ConstantDem):
        def height_range(self, bounds=None):
            return (0.0, 2000.0)

    model = AffineCamera.example((200, 300))
    flat = OutputGrid.for_model(model, ConstantDem(1000.0))
    tall = OutputGrid.for_model(model, TiltedDem(1000.0))
    for h in (0.0, 2000.0):
        fp = model.footprint(h)
        x, y = coords.transformer("EPSG:4326", tall.crs).transform(fp.lon, fp.lat)
        xmin, ymin, xmax, ymax = tall.bounds
        assert x.min() >= xmin and x.max() <= xmax and y.min() >= ymin and y.max() <= ymax
    assert tall.shape[0] > flat.shape[0] and tall.shape[1] > flat.shape[1]


# ---------------------------------------------------------------------- issue 12, items 2 and 10
def test_nice_resolution():
    from geoblock.ortho.grid import nice_resolution

    cases = {1.99987: 2.0, 2.0: 2.0, 2.03: 2.0, 2.5: 2.5, 2.49: 2.5, 0.31: 0.25, 0.5: 0.5,
             0.7: 0.5, 0.72: 1.0, 1.5: 2.0, 9.7: 10.0, 30.0: 25.0, 1.8e-5: 2e-5, 4e-6: 5e-6}
    for value, nice in cases.items():
        assert nice_resolution(value) == nice, value
    assert nice_resolution(0.2) == float("2e-1")
    for bad in (0.0, -1.0, float("nan"), float("inf")):
        with pytest.raises(GridError):
            nice_resolution(bad)


def test_for_model_rounds_and_aligns_the_default_resolution():
    """Two scenes of one sensor get one resolution and one pixel phase: they mosaic."""
    grids = []
    for lon in (7.05, 7.0513, 7.2):
        model = AffineCamera((60, 80), (lon, 43.70, 100.0),
                             [[29.5, 0.0, -0.5, 0.05], [39.5, 0.5, 0.0, -0.02]],
                             (-500.0, 3000.0))
        grids.append(OutputGrid.for_model(model, ConstantDem(150.0)))
    for g in grids:
        assert g.resolution == (2.0, 2.0)
        assert g.transform.c % 2.0 == 0.0 and g.transform.f % 2.0 == 0.0
    # an explicit resolution is kept as given
    g = OutputGrid.for_model(AffineCamera.example((60, 80)), 150.0, resolution=1.99987)
    assert g.resolution == (1.99987, 1.99987)


def test_check_refuses_impossible_grids():
    model = AffineCamera.example((60, 80))
    with pytest.raises(GridError, match=r"resolution 1e-06 .* pixels .*max_pixels") as info:
        OutputGrid.for_model(model, 150.0, resolution=1e-6)  # 10^16 pixels: refused at once
    assert info.value.parameter == "resolution" and isinstance(info.value, ValueError)
    with pytest.raises(GridError, match=r"geographic.*degree"):
        OutputGrid.for_model(model, 150.0, crs="EPSG:4326", resolution=1000.0)
    with pytest.raises(GridError, match=r"1 x 1 pixels: fewer than 2 x 2"):
        OutputGrid.for_model(model, 150.0, resolution=1000.0)
    with pytest.raises(GridError, match=r"more than max_pixels = 100"):
        OutputGrid.for_model(model, 150.0, max_pixels=100)
    huge = OutputGrid.from_bounds("EPSG:32632", (0.0, 0.0, 3e6, 10.0), 0.001)  # gdalwarp's
    assert huge.shape == (10000, 3_000_000_000)
    with pytest.raises(GridError, match=r"2\*\*31 - 1"):
        huge.check()
    with pytest.raises(GridError, match=r"--res 0\.001 over --bounds"):
        huge.check(names={"resolution": "--res", "bounds": "--bounds"})
    # unchecked on request; a reasonable geographic grid passes
    assert OutputGrid.for_model(model, 150.0, resolution=1000.0, max_pixels=None).shape == (1, 1)
    geo = OutputGrid.for_model(model, 150.0, crs="EPSG:4326")
    assert geo.check() is geo and geo.resolution[0] in (1e-5, 2e-5, 2.5e-5, 5e-5)
    # invalid arguments are GridErrors (still ValueErrors) naming the argument
    with pytest.raises(GridError) as info:
        OutputGrid.from_bounds("EPSG:32632", (1.0, 1.0, 0.0, 0.0), 1.0)
    assert info.value.parameter == "bounds"
    with pytest.raises(GridError) as info:
        OutputGrid.from_bounds("EPSG:32632", (0.0, 0.0, 1.0, 1.0), 0.0)
    assert info.value.parameter == "resolution"


def test_oversampling_gsd_height_needs_no_ray_intersection():
    """check_oversampling's height (a few fixed-point steps on the DEM, no localize kernels)
    gives the GSD at localize's height to 1e-6 over rough terrain."""
    from geoblock_rpc import RpcModel

    from geoblock.dem import GridDem
    from geoblock.dem.intersect import localize
    from geoblock.ortho.grid import _centre_height, _gsd

    model = RpcModel.example()
    rng = np.random.default_rng(7)
    dem = GridDem(rng.uniform(200.0, 1400.0, (40, 40)),
                  Affine(0.004, 0.0, 7.05 - 0.08, 0.0, -0.004, 43.70 + 0.08), "EPSG:4326")
    rows, cols = model.shape
    rc, cc = (rows - 1) / 2.0, (cols - 1) / 2.0
    h = _centre_height(model, rc, cc, dem)
    lo, hi = dem.height_range(dem.bounds)
    assert lo <= h <= hi
    exact, _ = localize(model, rc, cc, dem, warn=False)
    crs = "EPSG:32632"
    g_fast = _gsd(model, rc, cc, h, pyproj.CRS(crs))
    g_exact = _gsd(model, rc, cc, float(exact.h), pyproj.CRS(crs))
    assert abs(g_fast / g_exact - 1) < 1e-6
