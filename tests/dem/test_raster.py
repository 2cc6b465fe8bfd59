"""RasterDem and MosaicDem on real and synthetic DEMs: shareloc's values, GDAL identity,
nodata, coverage, vertical datum, blocks, pickling."""

from __future__ import annotations

import pickle
import threading

import numpy as np
import pytest
import rasterio
from affine import Affine
from rasterio.warp import Resampling, reproject

import geoblock
from geoblock._affine import apply as affine_apply
from geoblock.dem import BLOCK_CACHE, GridDem, MosaicDem, RasterDem
from geoblock.errors import DemCoverageError, DemError
from geoblock.typing import Status

from .conftest import smooth_terrain, write_tif


# ---------------------------------------------------------------- shareloc's expected values
@pytest.mark.parametrize(("col", "row", "expected"), [(10.0, 20.0, 196.0), (20.5, 25.5, 189.5)])
def test_shareloc_mnt_index_values(mnt_geoid, col, row, expected):
    """shareloc test_dtm_intersection.py l.71-107: origin and step at pixel centres."""
    dem = RasterDem(mnt_geoid, vertical="ellipsoid")  # raw heights: no geoid added
    lon = 57.2083333333 + col * 0.00833333333333
    lat = 22.2166666667 - row * 0.00833333333333
    r, c = dem.pixel_coords(np.array([lon]), np.array([lat]))
    assert r[0] == pytest.approx(row, abs=1e-6) and c[0] == pytest.approx(col, abs=1e-6)
    assert float(dem.height(lon, lat)) == pytest.approx(expected, abs=1e-6)


def test_shareloc_srtm_geoid_value(srtm, egm96_path):
    """shareloc l.110-137: SRTM N44E005 + EGM96 -> 221.73 m ellipsoidal (rel 1e-2)."""
    dem = geoblock.open_dem(srtm, geoid=egm96_path)
    assert dem.vertical == "geoid" and "SRTM" in dem.vertical_source
    lon, lat = 5.002777777777778, 44.99444444444445
    assert float(dem.geoid.undulation(lon, lat)) == pytest.approx(50.73, abs=5e-3)
    assert float(dem.height(lon, lat)) == pytest.approx(221.73, rel=1e-2)


def _first_void(srtm):
    with rasterio.open(srtm) as ds:
        r, c = np.argwhere(ds.read(1) == -32768)[0]
        return ds.xy(r, c)


def test_nodata_policies_shareloc(srtm, egm96_path):
    """shareloc test_dtm_image.py l.45-72: a void is -32768; rio_fillnodata gives 783 there."""
    lon, lat = _first_void(srtm)
    h, status = RasterDem(srtm, vertical="ellipsoid").height_with_status(lon, lat)
    assert np.isnan(h) and status == Status.NO_DEM
    filled = RasterDem(srtm, vertical="ellipsoid", nodata="fill", interpolation="nearest")
    assert int(float(filled.height(lon, lat))) == 783  # shareloc's int16 result (truncated)
    assert geoblock.open_dem(srtm, vertical="ellipsoid", nodata="nearest").nodata == "fill"
    const = RasterDem(srtm, vertical="ellipsoid", nodata=100.0, interpolation="nearest")
    assert float(const.height(lon, lat)) == 100.0
    # the fill value is in the file's datum: the geoid is added to it
    g = RasterDem(srtm, geoid=egm96_path, nodata=100.0, interpolation="nearest")
    assert float(g.height(lon, lat)) == pytest.approx(100.0 + float(g.geoid.undulation(lon, lat)))
    stats = RasterDem(srtm, vertical="ellipsoid").statistics()
    assert (stats["min"], stats["max"]) == (32.0, 2757.0)  # N44E005.omd min/max
    assert 0 < stats["nodata_share"] < 0.01


# ---------------------------------------------------------------- GDAL identity
def test_nearest_identical_to_rasterio_sample(srtm, mnt_geoid):
    rng = np.random.default_rng(1)
    for path in (srtm, mnt_geoid):
        dem = RasterDem(path, vertical="ellipsoid", interpolation="nearest")
        w, s, e, n = dem.native_bounds
        lon, lat = rng.uniform(w, e, 5000), rng.uniform(s, n, 5000)
        with rasterio.open(path) as ds:
            ref = np.array([v[0] for v in ds.sample(zip(lon, lat, strict=True))], float)
            if ds.nodata is not None:
                ref[ref == ds.nodata] = np.nan
        np.testing.assert_array_equal(dem.height(lon, lat), ref)


def _gdal_bilinear(path, fx, fy, crs=None):
    """GDAL's warper (the engine of gdal.Warp) resampling the DEM bilinearly onto the same
    grid shifted by (fx, fy) pixels: destination centre (r, c) is source pixel-centre
    coordinate (r + fy, c + fx). Returns the destination transform and heights."""
    with rasterio.open(path) as ds:
        src, t, nodata = ds.read(1), ds.transform, ds.nodata
        crs = crs or ds.crs
    dst = np.full((src.shape[0] - 1, src.shape[1] - 1), np.nan)
    dt = t @ Affine.translation(fx, fy)
    reproject(src, dst, src_transform=t, src_crs=crs, dst_transform=dt, dst_crs=crs,
              resampling=Resampling.bilinear, src_nodata=nodata, dst_nodata=np.nan,
              num_threads=1)
    return dt, dst


@pytest.mark.parametrize(("fx", "fy"), [(0.25, 0.6), (0.71, 0.13), (0.5, 0.5)])
def test_bilinear_identical_to_gdal_warp_srtm(srtm, fx, fy):
    dem = RasterDem(srtm, vertical="ellipsoid")
    dt, ref = _gdal_bilinear(srtm, fx, fy)
    rr, cc = np.mgrid[0:ref.shape[0], 0:ref.shape[1]]
    lon, lat = affine_apply(dt, *(cc + 0.5, rr + 0.5))
    h = dem.height(lon, lat)
    ok = np.isfinite(h)
    # geoblock is NaN where a tap is a void; GDAL's warper re-weights the valid taps there
    assert ok.mean() > 0.99
    np.testing.assert_allclose(h[ok], ref[ok], rtol=0, atol=1e-6)


def test_bilinear_identical_to_gdal_warp_projected(utm_tif):
    path, arr, t = utm_tif
    dem = RasterDem(path, vertical="ellipsoid")
    dt, ref = _gdal_bilinear(path, 0.37, 0.81)
    rr, cc = np.mgrid[0:ref.shape[0], 0:ref.shape[1]]
    x, y = affine_apply(dt, *(cc + 0.5, rr + 0.5))
    from geoblock import coords

    lon, lat = coords.transformer("EPSG:32631", "EPSG:4326").transform(x, y)
    np.testing.assert_allclose(dem.height(lon, lat), ref, rtol=0, atol=1e-5)


def test_bicubic_matches_in_memory_grid(utm_tif):
    path, arr, t = utm_tif
    dem = RasterDem(path, vertical="ellipsoid", interpolation="bicubic")
    grid = GridDem(arr, t, "EPSG:32631", interpolation="bicubic")
    rng = np.random.default_rng(3)
    x, y = affine_apply(t, *(rng.uniform(2, 77, 2000), rng.uniform(2, 57, 2000)))
    from geoblock import coords

    lon, lat = coords.transformer("EPSG:32631", "EPSG:4326").transform(x, y)
    np.testing.assert_allclose(dem.height(lon, lat), grid.height(lon, lat), atol=1e-9)


def test_blocks_of_a_large_raster_match_whole_array(tmp_path):
    """A raster larger than one block: every kernel, across block seams, as on the whole array."""
    arr = smooth_terrain(2100, 2100, seed=5).astype(np.float32)
    t = Affine(0.001, 0.0, 5.0, 0.0, -0.001, 45.0)
    path = write_tif(tmp_path / "big.tif", arr, t, "EPSG:4979")
    rng = np.random.default_rng(4)
    r = np.concatenate([rng.uniform(0, 2099, 3000), np.full(200, 511.5), np.full(200, 1023.9)])
    c = np.concatenate([rng.uniform(0, 2099, 3000), rng.uniform(0, 2099, 400)])
    lon, lat = affine_apply(t, *(c + 0.5, r + 0.5))
    for interp in ("nearest", "bilinear", "bicubic"):
        dem = RasterDem(path, interpolation=interp)
        assert dem.vertical == "ellipsoid"
        grid = GridDem(arr, t, "EPSG:4326", interpolation=interp)
        got, ref = dem.height(lon, lat), grid.height(lon, lat)
        ok = np.isfinite(ref)
        np.testing.assert_allclose(got[ok], ref[ok], atol=1e-9)
    assert len(BLOCK_CACHE) >= 4


# ---------------------------------------------------------------- coverage
def test_outside_is_nan_with_status_or_error_in_strict_mode(utm_tif):
    path, arr, t = utm_tif
    dem = RasterDem(path, vertical="ellipsoid")
    w, s, e, n = dem.bounds
    lon = np.array([(w + e) / 2, w - 1.0, np.nan, e + 1.0])
    h, status = dem.height_with_status(lon, (s + n) / 2)
    assert np.isfinite(h[0]) and np.isnan(h[1:]).all()
    assert status.tolist() == [Status.CONVERGED, Status.NO_DEM, Status.INVALID_INPUT,
                               Status.NO_DEM]
    strict = RasterDem(path, vertical="ellipsoid", strict=True)
    with pytest.raises(DemCoverageError, match="2 of 3 points"):
        strict.height(lon, (s + n) / 2)


def test_edge_half_pixel_is_edge_extended(utm_tif):
    path, arr, t = utm_tif
    dem = RasterDem(path, vertical="ellipsoid")
    from geoblock import coords

    # a quarter pixel inside the top-left corner: the corner post's value
    lon, lat = coords.transformer("EPSG:32631", "EPSG:4326").transform(
        *(affine_apply(t, *(0.25, 0.25)))
    )
    assert float(dem.height(lon, lat)) == pytest.approx(float(arr[0, 0]), abs=1e-9)


# ---------------------------------------------------------------- vertical datum
def test_vertical_from_compound_crs(tmp_path, egm96_path):
    arr = np.full((10, 10), 100.0, np.float32)
    t = Affine(0.01, 0.0, 5.0, 0.0, -0.01, 44.1)
    geoidal = write_tif(tmp_path / "g.tif", arr, t, "EPSG:4326+5773")
    dem = RasterDem(geoidal, geoid=egm96_path)
    assert dem.vertical == "geoid" and "EGM96" in dem.vertical_source
    assert float(dem.height(5.05, 44.05)) == pytest.approx(
        100.0 + float(dem.geoid.undulation(5.05, 44.05)), abs=1e-9)
    utm = write_tif(tmp_path / "u.tif", arr, Affine(30, 0, 660000, 0, -30, 4900000),
                    "EPSG:32631+5773")
    assert RasterDem(utm, geoid=egm96_path).vertical == "geoid"
    ell = write_tif(tmp_path / "e.tif", arr, t, "EPSG:4979")
    assert RasterDem(ell).vertical == "ellipsoid"
    assert float(RasterDem(ell).height(5.05, 44.05)) == 100.0
    # the caller wins over the file
    assert RasterDem(geoidal, vertical="ellipsoid").geoid is None
    other = write_tif(tmp_path / "o.tif", arr, t, "EPSG:4326+3855")  # EGM2008 height
    with pytest.raises(DemError, match="EGM2008"):
        RasterDem(other)


def test_unstated_vertical_is_refused_with_how_to(mnt_geoid):
    with pytest.raises(DemError) as info:
        geoblock.open_dem(mnt_geoid)
    text = str(info.value)
    assert mnt_geoid.name in text
    assert "vertical='geoid'" in text and "vertical='ellipsoid'" in text


# ---------------------------------------------------------------- mosaic, grid, range
def test_mosaic_first_tile_with_height_wins(tmp_path):
    t1 = Affine(0.01, 0.0, 5.0, 0.0, -0.01, 44.1)
    a1 = np.full((10, 10), 10.0, np.float32)
    a1[:5, :5] = -9999
    p1 = write_tif(tmp_path / "a.tif", a1, t1, "EPSG:4979", nodata=-9999)
    from geoblock import coords

    x0, y0 = coords.transformer("EPSG:4326", "EPSG:32631").transform(4.95, 44.15)
    t2 = Affine(100.0, 0.0, x0, 0.0, -100.0, y0)
    p2 = write_tif(tmp_path / "b.tif", np.full((200, 200), 20.0, np.float32), t2,
                   "EPSG:32631")
    dem = geoblock.open_dem([p1, p2], vertical="ellipsoid")
    assert isinstance(dem, MosaicDem)
    h = dem.height([5.07, 5.02, 5.15, 20.0], [44.02, 44.08, 44.0, 0.0])
    assert h[:2].tolist() == [10.0, 20.0]  # valid in tile 1; void in tile 1 -> tile 2
    assert h[2] == pytest.approx(20.0) and np.isnan(h[3])
    assert dem.height_range() == (10.0, 20.0)
    assert dem.height_range((5.06, 44.01, 5.08, 44.03)) == (10.0, 20.0)
    strict = geoblock.open_dem([p1, p2], vertical="ellipsoid", strict=True)
    with pytest.raises(DemCoverageError, match="1 of 2"):
        strict.height([5.07, 20.0], [44.02, 0.0])
    assert pickle.loads(pickle.dumps(dem)) == dem


def test_heights_on_grid(utm_tif):
    path, arr, t = utm_tif
    dem = RasterDem(path, vertical="ellipsoid")
    out_t = Affine(45.0, 0.0, 660100.0, 0.0, -45.0, 4899900.0)
    grid = dem.heights_on_grid("EPSG:32631", out_t, (20, 30))
    assert grid.shape == (20, 30)
    x, y = affine_apply(out_t, *(np.arange(30)[None, :] + 0.5, np.arange(20)[:, None] + 0.5))
    from geoblock import coords

    lon, lat = coords.transformer("EPSG:32631", "EPSG:4326").transform(x, y)
    np.testing.assert_array_equal(grid, dem.height(lon, lat))


def test_height_range(srtm, egm96_path):
    dem = RasterDem(srtm, geoid=egm96_path)
    box = (5.2, 44.1, 5.3, 44.2)
    lo, hi = dem.height_range(box)
    rng = np.random.default_rng(0)
    h = dem.height(rng.uniform(5.2, 5.3, 20000), rng.uniform(44.1, 44.2, 20000))
    assert lo <= np.nanmin(h) and np.nanmax(h) <= hi
    assert hi - np.nanmax(h) < 60 and np.nanmin(h) - lo < 60
    full = dem.height_range()
    assert full[0] <= lo and hi <= full[1]
    assert np.isnan(dem.height_range((20.0, 0.0, 21.0, 1.0))).all()


# ---------------------------------------------------------------- values, pickling, threads
def test_pickle_by_path_and_to_dict(srtm, egm96_path):
    dem = RasterDem(srtm, geoid=egm96_path, interpolation="bicubic", nodata="fill")
    data = pickle.dumps(dem)
    assert len(data) < 1000  # no pixels
    again = pickle.loads(data)
    assert again == dem and again.to_dict() == dem.to_dict()
    assert geoblock.open_dem(dem.to_dict()) == dem
    import dask.base

    assert dask.base.tokenize(dem) == dask.base.tokenize(again)


def test_thread_safe_shared_cache(srtm, egm96_path):
    BLOCK_CACHE.clear()
    dem = RasterDem(srtm, geoid=egm96_path)
    rng = np.random.default_rng(2)
    lon, lat = rng.uniform(5, 6, 20000), rng.uniform(44, 45, 20000)
    expected = dem.height(lon, lat)
    results = [None] * 8

    def work(i):
        results[i] = RasterDem(srtm, geoid=egm96_path).height(lon, lat)

    threads = [threading.Thread(target=work, args=(i,)) for i in range(8)]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    for r in results:
        np.testing.assert_array_equal(r, expected)
    assert BLOCK_CACHE.hits >= 8 and len(BLOCK_CACHE) == 1  # one block, shared


def test_bad_inputs(tmp_path, srtm):
    with pytest.raises(DemError, match="interpolation"):
        RasterDem(srtm, interpolation="cubic")
    with pytest.raises(DemError, match="nodata"):
        RasterDem(srtm, nodata="zero")
    with pytest.raises(DemError, match="band"):
        RasterDem(srtm, band=2)
    junk = tmp_path / "junk.tif"
    junk.write_text("nope")
    with pytest.raises(DemError, match="junk.tif"):
        RasterDem(junk, vertical="ellipsoid")
    nocrs = tmp_path / "nocrs.tif"
    with rasterio.open(nocrs, "w", driver="GTiff", width=2, height=2, count=1,
                       dtype="float32", transform=Affine(1, 0, 0, 0, -1, 2)) as ds:
        ds.write(np.zeros((1, 2, 2), np.float32))
    with pytest.raises(DemError, match="no CRS"):
        RasterDem(nocrs, vertical="ellipsoid")
