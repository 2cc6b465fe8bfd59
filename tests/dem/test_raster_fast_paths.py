"""The compiled fast paths of RasterDem and the lattice against their numpy/loop references."""

from __future__ import annotations

import numpy as np
import pytest
import rasterio
from affine import Affine

from geoblock.dem import raster as raster_mod
from geoblock.dem._reference import pixel_coords_reference, sample_reference
from geoblock.dem.cache import BLOCK_CACHE
from geoblock.dem.raster import RasterDem
from geoblock.ortho import lattice
from geoblock.pixels import pixel_to_map


def _write(path, data, transform, crs="EPSG:4979", nodata=None):
    with rasterio.open(path, "w", driver="GTiff", width=data.shape[1], height=data.shape[0],
                       count=1, dtype=data.dtype, crs=crs, transform=transform,
                       nodata=nodata, tiled=True, blockxsize=256, blockysize=256) as ds:
        ds.write(data, 1)


@pytest.fixture(scope="module")
def dem_files(tmp_path_factory):
    d = tmp_path_factory.mktemp("fastdem")
    rng = np.random.default_rng(7)
    # small (one block) and large (several 512-pixel blocks), with nodata holes
    small = (rng.normal(100.0, 30.0, (300, 400))).astype(np.float32)
    small[50:55, 60:70] = -9999.0
    big = (rng.normal(500.0, 80.0, (2300, 2100))).astype(np.float32)
    big[1000:1010, 700:720] = -9999.0
    t_small = Affine(0.001, 0.0, 10.0, 0.0, -0.001, 45.0)
    t_big = Affine(0.0002, 0.0, 179.9, 0.0, -0.0002, 45.0)  # crosses the antimeridian
    paths = {"small": d / "small.tif", "big": d / "big.tif"}
    _write(paths["small"], small, t_small, nodata=-9999.0)
    _write(paths["big"], big, t_big, nodata=-9999.0)
    _write(d / "utm.tif", small, Affine(30.0, 0.0, 500000.0, 0.0, -30.0, 5000000.0),
           crs="EPSG:32632+5773", nodata=-9999.0)
    paths["utm"] = d / "utm.tif"
    return paths


def _points(dem, n, seed):
    rng = np.random.default_rng(seed)
    w, s, e, nn = dem.bounds
    dw, dn = 0.05 * (e - w), 0.05 * (nn - s)
    lon = rng.uniform(w - dw, e + dw, n)
    lat = rng.uniform(s - dn, nn + dn, n)
    lon[:5] = np.nan
    # points exactly on pixel centres / edges
    row = rng.integers(0, dem.shape[0], 50) + 0.0
    col = rng.integers(0, dem.shape[1], 50) + 0.0
    x, y = pixel_to_map(dem.transform, row, col)
    if dem._lonlat:
        lon[5:55], lat[5:55] = x, y
    return lon, lat


@pytest.mark.parametrize("name", ["small", "big", "utm"])
@pytest.mark.parametrize("interpolation", ["nearest", "bilinear", "bicubic"])
@pytest.mark.parametrize("nodata", ["nan", "fill", 5.0])
def test_sample_matches_reference(dem_files, name, interpolation, nodata):
    if name == "utm":
        pytest.importorskip("pyproj")
    dem = RasterDem(dem_files[name], interpolation=interpolation, nodata=nodata,
                    fill_distance=20, vertical="ellipsoid")
    lon, lat = _points(dem, 20000, 3)
    fast, out_fast = dem._sample(lon, lat)
    ref, out_ref = sample_reference(dem, lon, lat)
    np.testing.assert_array_equal(out_fast, out_ref)
    assert np.array_equal(fast, ref, equal_nan=True)
    r1, c1 = dem.pixel_coords(lon, lat)
    r2, c2 = pixel_coords_reference(dem, lon, lat)
    assert np.array_equal(r1, r2, equal_nan=True) and np.array_equal(c1, c2, equal_nan=True)


def _cluster(dem, n, seed, centre, spread_px):
    """Points within ``spread_px`` DEM pixels of the fractional pixel ``centre`` (some past
    the raster's edges when ``centre`` is near one), as an ortho chunk's are."""
    rng = np.random.default_rng(seed)
    r = centre[0] * dem.shape[0] + rng.uniform(-spread_px, spread_px, n)
    c = centre[1] * dem.shape[1] + rng.uniform(-spread_px, spread_px, n)
    x, y = pixel_to_map(dem.transform, r, c)
    if not dem._lonlat:
        from geoblock import coords

        x, y = coords.transformer(dem.crs.sub_crs_list[0], "EPSG:4326").transform(x, y)
    return np.asarray(x, float), np.asarray(y, float)


@pytest.mark.parametrize("name", ["small", "big", "utm"])
@pytest.mark.parametrize("interpolation", ["nearest", "bilinear", "bicubic"])
@pytest.mark.parametrize("centre", [(0.5, 0.5), (0.22, 0.49), (0.0, 0.0), (1.0, 0.7)])
def test_window_path_matches_reference(dem_files, name, interpolation, centre, monkeypatch):
    """Compact point sets take the one-pass window path (one block, or several assembled:
    "big" straddles two or four 512-post blocks), bit-identical to the reference,
    edges and nodata holes included."""
    dem = RasterDem(dem_files[name], interpolation=interpolation, vertical="ellipsoid")
    lon, lat = _cluster(dem, 30000, 5, centre, 40.0)
    taken = []
    real = raster_mod._nb_sample_window
    monkeypatch.setattr(raster_mod, "_nb_sample_window",
                        lambda *a: taken.append(a[8].shape) or real(*a))
    fast, out_fast = dem._sample(lon, lat)
    assert taken, "the window path was not taken"
    ref, out_ref = sample_reference(dem, lon, lat)
    np.testing.assert_array_equal(out_fast, out_ref)
    assert np.array_equal(fast, ref, equal_nan=True)
    if name == "big" and centre == (0.22, 0.49):  # assembled from four 512-post blocks
        assert taken[0][0] < 100 and taken[0][1] < 100


def test_window_path_declines_spread_points(dem_files, monkeypatch):
    """Few points over many blocks: the per-block path, not a huge window."""
    dem = RasterDem(dem_files["big"], vertical="ellipsoid")
    w, s, e, n = dem.bounds
    lon = np.array([w + 0.01, e - 0.01, w + 0.01])
    lat = np.array([s + 0.01, n - 0.01, n - 0.01])
    called = []
    monkeypatch.setattr(raster_mod, "_nb_sample_window", lambda *a: called.append(1))
    h, outside = dem._sample(lon, lat)
    assert not called and np.isfinite(h).all() and not outside.any()


def test_sample_all_outside_and_empty(dem_files):
    dem = RasterDem(dem_files["small"])
    h, out = dem._sample(np.array([0.0, 1.0]), np.array([0.0, 1.0]))
    assert np.isnan(h).all() and out.all()
    h, out = dem._sample(np.array([]), np.array([]))
    assert h.shape == (0,) and out.shape == (0,)


def test_height_range_reuses_handle(dem_files, monkeypatch):
    dem = RasterDem(dem_files["big"])
    w, s, e, n = dem.bounds
    box = (w + 0.01, s + 0.01, w + 0.05, s + 0.05)
    first = dem.height_range(box)
    import rasterio as rio

    calls = []
    real_open = rio.open
    monkeypatch.setattr(rio, "open", lambda *a, **k: calls.append(a) or real_open(*a, **k))
    for _ in range(5):
        assert dem.height_range(box) == first
    assert calls == []
    BLOCK_CACHE.clear()
    dem.height(np.array([w + 0.02]), np.array([s + 0.02]))
    assert calls == []


def test_handle_reopened_when_file_changes(tmp_path):
    path = tmp_path / "d.tif"
    t = Affine(0.001, 0.0, 10.0, 0.0, -0.001, 45.0)
    _write(path, np.full((50, 50), 10.0, np.float32), t)
    assert RasterDem(path).height_range((10.01, 44.96, 10.02, 44.97)) == (10.0, 10.0)
    _write(path, np.full((60, 50), 20.0, np.float32), t)
    assert RasterDem(path).height_range((10.01, 44.96, 10.02, 44.97)) == (20.0, 20.0)


def test_lattice_point_kernels_match_loops():
    rng = np.random.default_rng(1)
    for s in (1, 2, 8, 64):
        n = 256 // s + 1
        nodes = rng.normal(size=(n, n))
        pr = rng.integers(0, 256, 300)
        pc = rng.integers(0, 256, 300)
        fast = lattice._bilinear_points(nodes, pr, pc, s)
        ref = np.array([lattice._bilinear(nodes, int(a), int(b), 1, 1, s)[0, 0]
                        for a, b in zip(pr, pc, strict=True)])
        assert fast.tobytes() == ref.tobytes()
        for pairs in (1, 2, 4):
            rn = rng.normal(size=(2 * pairs + 1, n, n)) * 1000
            cn = rng.normal(size=(2 * pairs + 1, n, n)) * 1000
            h = rng.uniform(-50.0, 900.0, 300)
            h[:7] = np.nan
            h0, dh = 0.0, 800.0 / (2 * pairs)
            fr, fc = lattice._interp_image_points(rn, cn, h, pr, pc, s, h0, dh, pairs)
            rr = np.empty(300)
            rc = np.empty(300)
            for k in range(300):
                a, b = lattice._interp_image(rn, cn, h[k:k + 1].reshape(1, 1), int(pr[k]),
                                             int(pc[k]), s, h0, dh, pairs)
                rr[k], rc[k] = a[0, 0], b[0, 0]
            assert fr.tobytes() == rr.tobytes() and fc.tobytes() == rc.tobytes()
