"""Resampling kernels: GDAL's warper, nodata, edges, dtypes, the windowed sinc."""

from __future__ import annotations

import numpy as np
import pytest
from affine import Affine
from rasterio.warp import Resampling, reproject

from geoblock.ortho import kernels
from geoblock.ortho._reference import resample_reference
from geoblock.ortho.kernels import KERNEL_RADIUS, KERNELS, cast, resample

CRS = "EPSG:32631"
T = Affine(1.0, 0.0, 0.0, 0.0, -1.0, 64.0)  # small coordinates: no rounding in the transformer


def _gdal_warp(src, fx, fy, resampling):
    """GDAL's warper resampling ``src`` (R, C) onto the grid shifted by (fx, fy) pixels: the
    destination centre (r, c) is the source pixel-centre coordinate (r + fy, c + fx)."""
    dst = np.full((src.shape[0] - 1, src.shape[1] - 1), np.nan)
    dt = T @ Affine.translation(fx, fy)
    reproject(src, dst, src_transform=T, src_crs=CRS, dst_transform=dt, dst_crs=CRS,
              resampling=resampling, dst_nodata=np.nan, num_threads=1)
    return dst


@pytest.mark.parametrize(("kernel", "resampling"), [
    ("nearest", Resampling.nearest),
    ("bilinear", Resampling.bilinear),
    ("bicubic", Resampling.cubic),
])
@pytest.mark.parametrize(("fx", "fy"), [(0.25, 0.6), (0.71, 0.13), (0.5, 0.5), (0.0, 0.37)])
def test_identical_to_gdal_warper(kernel, resampling, fx, fy):
    rng = np.random.default_rng(7)
    src = rng.uniform(-100, 1000, (41, 53))
    ref = _gdal_warp(src, fx, fy, resampling)
    rr, cc = np.mgrid[0:ref.shape[0], 0:ref.shape[1]].astype(float)
    values, valid = resample(src[None], rr + fy, cc + fx, kernel)
    assert values.shape == (1,) + ref.shape and valid.shape == ref.shape
    # valid wherever the whole kernel is inside: every point at least KERNEL_RADIUS from the edge
    assert valid[2:-2, 2:-2].all()
    np.testing.assert_allclose(values[0, 2:-2, 2:-2], ref[2:-2, 2:-2], rtol=0, atol=1e-9)
    # GDAL's cubic falls back to bilinear when its 4 x 4 box leaves the raster
    if kernel != "bicubic":
        np.testing.assert_allclose(values[0][valid], ref[valid], rtol=0, atol=1e-9)


def test_nearest_is_the_containing_pixel():
    src = np.arange(20.0).reshape(1, 4, 5)
    v, ok = resample(
        src, [0.49, 0.5, -0.5, 3.49, 3.5, -0.51], [1.0, 1.0, 0.0, 4.49, 0.0, 0.0], "nearest"
    )
    assert ok.tolist() == [True, True, True, True, False, False]
    assert v[0, :4].tolist() == [1.0, 6.0, 0.0, 19.0]


@pytest.mark.parametrize("kernel", KERNELS)
def test_integer_coordinates_reproduce_pixels_up_to_the_edges(kernel):
    rng = np.random.default_rng(1)
    src = rng.normal(size=(2, 9, 11))
    rr, cc = np.mgrid[0:9, 0:11].astype(float)
    v, ok = resample(src, rr, cc, kernel)
    assert ok.all()  # zero-weight taps are not needed, so the border pixels are valid too
    np.testing.assert_allclose(v, src, rtol=0, atol=1e-12)


def _taps_hit(x, k, kernel):
    """Whether pixel ``k`` of an axis gets a non-zero weight at coordinate ``x``."""
    if kernel == "nearest":
        return np.floor(x + 0.5) == k
    rad = KERNEL_RADIUS[kernel]
    f = np.floor(x)
    return np.where(x == f, x == k, (f - (rad - 1) <= k) & (k <= f + rad))


@pytest.mark.parametrize("kernel", KERNELS)
def test_points_whose_kernel_leaves_the_window_are_invalid(kernel):
    src = np.ones((1, 30, 30))
    rad = KERNEL_RADIUS[kernel]
    if kernel == "nearest":
        x = [-0.5, -0.51, 29.49, 29.5]
    else:  # taps floor(x) - (rad - 1) ... floor(x) + rad must lie in 0 ... 29
        x = [rad - 1 + 0.3, rad - 1 - 0.01, 29 - rad + 0.99, 29 - rad + 1.01]
    x = np.array(x + [np.nan, np.inf, 15.5])
    for row, col in ((x, np.full_like(x, 15.5)), (np.full_like(x, 15.5), x)):
        v, ok = resample(src, row, col, kernel)
        assert ok.tolist() == [True, False, True, False, False, False, True]
        assert np.isnan(v[0][~ok]).all()
        np.testing.assert_allclose(v[0][ok], 1.0, rtol=0, atol=1e-12)


@pytest.mark.parametrize("kernel", KERNELS)
def test_nodata_taps_invalidate(kernel):
    rng = np.random.default_rng(2)
    src = rng.integers(1, 200, (3, 40, 40)).astype(np.uint8)
    src[:, 20, 20] = 0  # a nodata pixel (all bands)
    src[0, 5:35, 5] = 0  # one band only: still data
    rows, cols = np.mgrid[10:30:0.37, 10:30:0.5]
    v, ok = resample(src, rows, cols, kernel, nodata=0)
    v_all, ok_all = resample(src, rows, cols, kernel)
    assert ok_all.all()
    np.testing.assert_array_equal(ok, ~(_taps_hit(rows, 20, kernel) & _taps_hit(cols, 20, kernel)))
    assert (~ok).sum() >= 1
    np.testing.assert_array_equal(v[:, ok], v_all[:, ok])
    assert np.isnan(v[:, ~ok]).all()
    v5, ok5 = resample(src, [15.0], [5.0], kernel, nodata=0)
    assert ok5[0] and v5[0, 0] == 0.0


def test_nan_in_float_source_is_invalid():
    src = np.ones((2, 10, 10), np.float32)
    src[1, 4, 4] = np.nan
    _, ok = resample(src, [4.5, 2.5, 4.0], [4.5, 2.5, 4.0], "bilinear")
    assert ok.tolist() == [False, True, False]


@pytest.mark.parametrize("dtype", [np.uint8, np.int16, np.uint16, np.float32, bool])
def test_any_dtype_same_as_float64(dtype):
    rng = np.random.default_rng(3)
    src = rng.integers(0, 2 if dtype is bool else 120, (2, 20, 20)).astype(dtype)
    r, c = rng.uniform(2, 17, (2, 500))
    for kernel in ("nearest", "bilinear", "bicubic"):
        v, ok = resample(src, r, c, kernel)
        ref, ok_ref = resample(src.astype(np.float64), r, c, kernel)
        assert v.dtype == np.float64
        np.testing.assert_array_equal(ok, ok_ref)
        np.testing.assert_allclose(v, ref, rtol=1e-12)


@pytest.mark.parametrize("kernel", KERNELS)
def test_numba_agrees_with_numpy_reference(kernel):
    rng = np.random.default_rng(4)
    src = rng.normal(size=(3, 50, 60))
    src[:, 10:12, 30] = -1.0
    n = 3000
    r = rng.uniform(-3, 53, n)
    c = rng.uniform(-3, 63, n)
    r[:300] = np.round(r[:300])  # exact integers: zero-weight taps
    c[150:450] = np.round(c[150:450])
    r[7] = np.nan
    v, ok = resample(src, r, c, kernel, nodata=-1.0)
    src_, r_, c_, _, mask = kernels._prepare(src, r, c, kernel, -1.0)
    v_ref, ok_ref = resample_reference(src_, r_, c_, kernel, mask)
    np.testing.assert_array_equal(ok, ok_ref)
    np.testing.assert_allclose(v[:, ok], v_ref[:, ok], rtol=0, atol=1e-12)
    assert np.isnan(v[:, ~ok]).all()


def test_output_shapes_broadcast():
    src = np.zeros((4, 10, 10))
    v, ok = resample(src, np.full((3, 1), 5.0), np.linspace(1, 8, 5), "bicubic")
    assert v.shape == (4, 3, 5) and ok.shape == (3, 5)
    v, ok = resample(src, 5.0, 5.0, "sinc")
    assert v.shape == (4,) and ok.shape == ()
    with pytest.raises(ValueError):
        resample(src[0], 1.0, 1.0, "bilinear")
    with pytest.raises(ValueError):
        resample(src, 1.0, 1.0, "lanczos")


def test_sinc_reproduces_band_limited_signal():
    """A sum of sinusoids below Nyquist: sinc 16 x 16 is far closer than bicubic."""
    n = 96
    yy, xx = np.mgrid[0:n, 0:n].astype(float)

    def f(y, x):
        return (np.sin(2 * np.pi * 0.21 * x + 0.3) * np.cos(2 * np.pi * 0.17 * y)
                + 0.5 * np.cos(2 * np.pi * (0.11 * x + 0.23 * y) + 1.0)
                + 0.2 * np.sin(2 * np.pi * 0.04 * y))

    src = f(yy, xx)[None]
    rng = np.random.default_rng(5)
    r, c = rng.uniform(30, 66, (2, 4000))
    truth = f(r, c)
    errs = {}
    for kernel in ("bicubic", "sinc"):
        v, ok = resample(src, r, c, kernel)
        assert ok.all()
        errs[kernel] = np.abs(v[0] - truth).max()
    assert errs["sinc"] < 0.02
    assert errs["sinc"] < errs["bicubic"] / 5
    # normalised weights: a constant stays constant
    v, ok = resample(np.full((1, 40, 40), 7.25), r[:100] / 3 + 8, c[:100] / 3 + 8, "sinc")
    np.testing.assert_allclose(v[0], 7.25, rtol=0, atol=1e-12)


def test_cast():
    values = np.array([[0.5, -0.5, 1.49999, 2.5, -2.5, 300.2, -7.0, np.nan]])
    valid = np.array([True] * 7 + [False])
    assert cast(values, valid, np.uint8, 255).tolist() == [[1, 0, 1, 3, 0, 255, 0, 255]]
    assert cast(values, valid, np.int16, -9999).tolist() == [[1, -1, 1, 3, -3, 300, -7, -9999]]
    assert cast(values, valid, np.int8, 0).tolist() == [[1, -1, 1, 3, -3, 127, -7, 0]]
    f = cast(values, valid, np.float32, np.nan)
    assert f.dtype == np.float32 and np.isnan(f[0, 7]) and f[0, 5] == np.float32(300.2)
    b = cast(values, valid, bool, False)
    assert b.tolist() == [[True, True, True, True, True, True, True, False]]
    assert cast(values[:, :2], valid[:2], np.uint16).dtype == np.uint16  # fill default 0


def test_cast_rejects_unrepresentable_fill():
    with pytest.raises(ValueError):
        cast(np.zeros((1, 2)), np.array([True, False]), np.uint8, np.nan)
    with pytest.raises(ValueError):
        cast(np.zeros((1, 2)), np.array([True, False]), np.uint8, -1)


@pytest.mark.parametrize("kernel", KERNELS)
@pytest.mark.parametrize("dtype", [np.uint8, np.int16, np.uint16, np.int32, np.float32,
                                   np.float64, bool, np.int64])
def test_resample_cast_equals_the_two_steps(kernel, dtype):
    """The orthorectifier's one-pass path gives the bytes of cast(resample(...)): rounding
    half away from zero, clipping to the dtype, fill where invalid (edges, nodata, NaN)."""
    rng = np.random.default_rng(11)
    if dtype is bool:
        src = rng.integers(0, 2, (2, 40, 50)).astype(bool)
    else:
        lo, hi = (-300.0, 300.0) if np.dtype(dtype).kind != "u" else (0.0, 300.0)
        src = rng.uniform(lo, hi, (2, 40, 50)).astype(dtype)
        src[:, 5:8, 10:14] = 7  # a nodata patch (every band)
        src[0, 20, 20] = 7
    if np.dtype(dtype).kind == "f":
        src[1, 30, 30] = np.nan
    row = rng.uniform(-3, 43, 5000)
    col = rng.uniform(-3, 53, 5000)
    row[:50] = np.round(row[:50])  # integer coordinates need their own pixel only
    col[:10] = np.nan
    nodata = None if dtype is bool else 7
    fill = 0 if dtype is bool else 5
    values, valid = resample(src, row, col, kernel, nodata=nodata)
    expected = cast(values, valid, dtype, fill)
    out, ok = kernels.resample_cast(src, row, col, kernel, dtype, fill, nodata=nodata)
    assert out.dtype == expected.dtype
    np.testing.assert_array_equal(ok, valid)
    assert np.array_equal(out, expected, equal_nan=True)
    assert 0 < valid.sum() < valid.size


def test_resample_cast_refuses_unrepresentable_fill():
    with pytest.raises(ValueError, match="not representable"):
        kernels.resample_cast(np.zeros((1, 4, 4), np.uint8), [1.0], [1.0], "bilinear",
                              np.uint8, fill=-1)
