"""The fused lattice pass (geoblock.ortho._fused) against the reference path: bit-identical."""

from __future__ import annotations

import numpy as np
import pytest
import rasterio
from affine import Affine

import geoblock
from geoblock.ortho import _fused
from geoblock.ortho.grid import OutputGrid
from geoblock.ortho.lattice import _Context, _lattice_fields

VENTOUX_RPC = "shareloc/rpc/phr_ventoux/RPC_PHR1B_P_201308051042194_SEN_690908101-001.XML"
SRTM = "shareloc/dtm/srtm_ventoux/srtm90_non_void_filled/N44E005.hgt"
GEOID = "shareloc/dtm/geoid/egm96_15.gtx"


def _rpc():
    from geoblock_rpc import RpcModel

    return RpcModel.example()


def _centre(model):
    rows, cols = model.shape
    g = model.backproject(np.array([(rows - 1) / 2]), np.array([(cols - 1) / 2]),
                          np.array([800.0]))
    return float(g.lon[0]), float(g.lat[0])


def _write_dem(path, lon0, lat0, *, n=300, post=0.0003, nodata_hole=False, crs="EPSG:4979"):
    """Rough terrain (200-1400 m, random) on ``n`` x ``n`` posts around (lon0, lat0)."""
    rng = np.random.default_rng(3)
    h = rng.uniform(200.0, 1400.0, (n, n)).astype(np.float32)
    if nodata_hole:
        h[::9, ::7] = -32768  # scattered missing posts
    transform = Affine(post, 0.0, lon0 - n * post / 2, 0.0, -post, lat0 + n * post / 2)
    with rasterio.open(path, "w", driver="GTiff", width=n, height=n, count=1,
                       dtype="float32", crs=crs, transform=transform,
                       nodata=-32768 if nodata_hole else None) as ds:
        ds.write(h[None])
    return path


def _both(model, dem, grid, window=None, tolerance=0.01):
    ctx = _Context(model, dem, grid.crs, grid.transform, tuple(grid.shape), None)
    fused = _lattice_fields(ctx, tolerance_px=tolerance, window=window, block_px=256)
    ref = _lattice_fields(ctx, tolerance_px=tolerance, window=window, block_px=256,
                          fused=False)
    return fused, ref


def _assert_identical(fused, ref):
    for a, b in zip(fused, ref, strict=True):
        np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("interpolation", ["bilinear", "bicubic", "nearest"])
@pytest.mark.parametrize("hole", [False, True])
def test_fused_is_the_reference_bit_for_bit(tmp_path, interpolation, hole):
    model = _rpc()
    path = _write_dem(tmp_path / "dem.tif", *_centre(model), nodata_hole=hole)
    dem = geoblock.open_dem(path, interpolation=interpolation, nodata="nan")
    assert _fused.plan(dem) is not None
    grid = OutputGrid.for_model(model, dem)
    window = (slice(1000, 1700), slice(2000, 2900))
    fused, ref = _both(model, dem, grid, window)
    _assert_identical(fused, ref)
    assert fused[2].mean() > 0.5
    if hole:  # the DEM's nodata: invalid pixels, in both
        assert not fused[2].all()
    else:
        assert fused[2].all()


def test_fused_with_the_geoid_on_real_srtm(data_dir):
    """SRTM + EGM96 (the geoid added in the pass, a global grid that wraps)."""
    paths = [data_dir / p for p in (SRTM, GEOID, VENTOUX_RPC)]
    if not all(p.exists() for p in paths):
        pytest.skip(f"{paths} not all found (shared data)")
    dem = geoblock.open_dem(paths[0], geoid=paths[1], nodata="fill")
    p = _fused.plan(dem)
    assert p is not None and p.geoid[5]  # the geoid in the pass
    model = geoblock.open_model(paths[2])
    grid = OutputGrid.from_bounds("EPSG:32631", (672000, 4894000, 680000, 4902000), 10.0)
    fused, ref = _both(model, dem, grid, (slice(100, 700), slice(50, 800)))
    _assert_identical(fused, ref)
    assert fused[2].all()


def test_fused_chunk_independent(tmp_path):
    model = _rpc()
    path = _write_dem(tmp_path / "dem.tif", *_centre(model))
    dem = geoblock.open_dem(path)
    grid = OutputGrid.for_model(model, dem)
    ctx = _Context(model, dem, grid.crs, grid.transform, tuple(grid.shape), None)
    rows, cols = slice(900, 1500), slice(1800, 2500)
    whole = _lattice_fields(ctx, tolerance_px=0.01, window=(rows, cols), block_px=256)
    part = _lattice_fields(ctx, tolerance_px=0.01, block_px=256,
                           window=(slice(1000, 1300), slice(2100, 2400)))
    np.testing.assert_array_equal(whole[0][100:400, 300:600], part[0])
    np.testing.assert_array_equal(whole[1][100:400, 300:600], part[1])


def test_plan_declines_what_it_cannot_do_exactly(tmp_path):
    model = _rpc()
    lon0, lat0 = _centre(model)
    assert _fused.plan(geoblock.open_dem("const:300")) is None  # not a raster
    # a projected DEM: pyproj per point, the reference path
    import pyproj

    from geoblock import coords
    crs = coords.utm_crs(lon0, lat0)
    x, y = pyproj.Transformer.from_crs("EPSG:4326", crs, always_xy=True).transform(lon0, lat0)
    utm = tmp_path / "utm.tif"
    with rasterio.open(utm, "w", driver="GTiff", width=50, height=50, count=1, dtype="float32",
                       crs=rasterio.crs.CRS.from_wkt(crs.to_wkt()),
                       transform=Affine(100.0, 0.0, x - 2500, 0.0, -100.0, y + 2500)) as ds:
        ds.write(np.full((1, 50, 50), 500.0, np.float32))
    assert _fused.plan(geoblock.open_dem(utm, vertical="ellipsoid")) is None


def test_strict_dem_outside_raises_as_the_reference_does(tmp_path):
    """A strict DEM smaller than the grid: the fused pass hands over, the reference raises."""
    from geoblock.errors import DemCoverageError

    model = _rpc()
    path = _write_dem(tmp_path / "dem.tif", *_centre(model), n=100)
    dem = geoblock.open_dem(path, strict=True)
    grid = OutputGrid.for_model(model, geoblock.open_dem("const:800"))
    ctx = _Context(model, dem, grid.crs, grid.transform, tuple(grid.shape), None)
    rows, cols = grid.shape  # a corner half outside the DEM
    window = (slice(rows // 2 - 3000, rows // 2 - 1500), slice(cols // 2 - 3000, cols // 2 - 1500))
    for fused in (False, True):
        with pytest.raises(DemCoverageError):
            _lattice_fields(ctx, tolerance_px=0.01, block_px=256, window=window, fused=fused)
    # not strict: the same pixels, NaN outside the DEM, in both
    lax = geoblock.open_dem(path)
    ctx = _Context(model, lax, grid.crs, grid.transform, tuple(grid.shape), None)
    fused = _lattice_fields(ctx, tolerance_px=0.01, block_px=256, window=window)
    ref = _lattice_fields(ctx, tolerance_px=0.01, block_px=256, window=window, fused=False)
    _assert_identical(fused, ref)
    assert 0 < fused[2].mean() < 1
