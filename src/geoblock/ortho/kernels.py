"""Resampling kernels of the orthorectifier: a source window sampled at fractional pixels.

Coordinates follow geoblock's convention: ``(row, col)`` with integers at pixel centres,
``(0, 0)`` the centre of ``src[:, 0, 0]`` (GDAL's pixel/line minus 0.5). Kernels:

``nearest``
    The pixel containing the point: ``src[:, floor(row + PIXEL_CENTRE), floor(col +
    PIXEL_CENTRE)]`` (:data:`geoblock.pixels.PIXEL_CENTRE` = 0.5).
``bilinear``
    The 2 x 2 surrounding centres, weights ``(1 - t, t)`` per axis (GDAL's warper
    ``bilinear``).
``bicubic``
    Keys' cubic convolution with ``a = -0.5`` on the 4 x 4 surrounding centres (GDAL's warper
    ``cubic``; the weights are :func:`geoblock.dem.sampling._keys`, shared with the DEM
    sampler).
``sinc``
    Windowed sinc on 16 x 16 taps (taps ``floor(x) - 7 ... floor(x) + 8`` per axis), the
    Lanczos window with ``a = 8``: ``w(d) = sinc(d) sinc(d / 8)`` for ``|d| < 8``, weights
    normalised to sum 1 per axis so that a constant image stays constant. Aguilar et al.
    used a 16 x 16 sinc for QuickBird; GDAL's ``lanczos`` is the same window with ``a = 3``
    (6 x 6 taps), so this kernel has no GDAL counterpart.

Bilinear and bicubic reproduce GDAL's warper up to floating-point rounding (~1e-12
relative) at interior points (tested against ``rasterio.warp.reproject``); nearest is the
pixel GDAL picks. Within two pixels of the raster edge GDAL's ``cubic`` falls back to
bilinear, while this kernel stays cubic as long as its non-zero taps are inside.

Validity. A *tap* is a source pixel that gets a non-zero weight (so an integer coordinate
needs only its own pixel, whatever the kernel). A point is invalid (``valid`` False, values
NaN) when its coordinates are not finite, when one of its taps lies outside the window, when
one of its taps is nodata -- every band equal to ``nodata``, GDAL's rule for a nodata value
shared by all bands -- or when the result is not finite (a NaN in a float source). GDAL's
warper instead drops the invalid taps and renormalises the remaining weights (and treats
points near the raster edge the same way); geoblock prefers no value to a value made of part
of a kernel. The orthorectifier reads source windows padded by :data:`KERNEL_RADIUS`, so
inside an image only nodata makes a point invalid.

The work is done by numba kernels (one pass per point, no temporaries). The vectorised numpy
reference :func:`geoblock.ortho._reference.resample_reference` defines the same values (the
tests hold the kernels to it, to floating-point rounding).
"""

from __future__ import annotations

import math
from typing import Any

import numba
import numpy as np

from geoblock.pixels import PIXEL_CENTRE
from geoblock.typing import ArrayLike

__all__ = ["KERNELS", "KERNEL_RADIUS", "SINC_HALF_WIDTH", "cast", "resample", "resample_cast"]

KERNELS = ("nearest", "bilinear", "bicubic", "sinc")
"""The kernel names accepted by :func:`resample`."""

SINC_HALF_WIDTH = 8
"""Half-width ``a`` of the Lanczos-windowed sinc, pixels (16 x 16 taps)."""

KERNEL_RADIUS = {"nearest": 0, "bilinear": 1, "bicubic": 2, "sinc": SINC_HALF_WIDTH}
"""Pixels a kernel may need beyond the cell ``[floor(row), floor(row) + 1]`` (and likewise
for col) holding a point: the padding of the source window around the projected points."""

# per kernel: number of taps per axis, offset of the first tap from floor(x)
_TAPS = {"nearest": (1, 0), "bilinear": (2, 0), "bicubic": (4, -1), "sinc": (16, -7)}
_KIND = {name: i for i, name in enumerate(KERNELS)}


# ---------------------------------------------------------------------- public API
def resample(
    src: np.ndarray,
    row: Any,
    col: Any,
    kernel: str,
    *,
    nodata: float | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Sample a multi-band source window at fractional pixel coordinates.

    Parameters
    ----------
    src : ndarray, (bands, R, C)
        The source window, any real numeric dtype (or bool).
    row, col : array_like, (*S,)
        Source pixel-centre coordinates relative to the window (``(0, 0)`` is the centre of
        ``src[:, 0, 0]``), broadcast together; NaN means no source.
    kernel : {"nearest", "bilinear", "bicubic", "sinc"}
    nodata : float, optional
        Source nodata value: a pixel whose bands all equal it is not used (module docstring).

    Returns
    -------
    values : ndarray, (bands, *S) float64
        Interpolated values; NaN where invalid.
    valid : ndarray, (*S,) bool
        Whether every tap of the point was inside the window and valid.

    Examples
    --------
    >>> src = np.arange(12.0).reshape(1, 3, 4)
    >>> values, valid = resample(src, [0.5, 2.0], [1.5, 3.0], "bilinear")
    >>> values.tolist(), valid.tolist()
    ([[3.5, 11.0]], [True, True])
    """
    src, row, col, shape, mask = _prepare(src, row, col, kernel, nodata)
    bands = src.shape[0]
    values = np.empty((bands, row.size), dtype=np.float64)
    valid = np.empty(row.size, dtype=np.bool_)
    use_mask = mask is not None
    if mask is None:
        mask = np.zeros((0, 0), dtype=np.bool_)
    _nb_resample(src, mask, use_mask, row, col, _KIND[kernel], values, valid)
    return values.reshape((bands,) + shape), valid.reshape(shape)


def cast(values: np.ndarray, valid: np.ndarray, dtype: Any, fill: float = 0) -> np.ndarray:
    """Convert resampled float64 values to an output dtype, ``fill`` where invalid.

    Parameters
    ----------
    values : ndarray, (bands, *S) float64
        From :func:`resample`.
    valid : ndarray, (*S,) bool
    dtype : dtype
        Usually the source dtype. Integers: round half away from zero (as GDAL's warper does)
        and clip to the dtype's range; floats: plain conversion; bool: non-zero after rounding.
    fill : scalar
        Value of invalid points (e.g. the output nodata), converted to ``dtype``.

    Returns
    -------
    ndarray, (bands, *S) of ``dtype``
    """
    dtype = np.dtype(dtype)
    values = np.asarray(values, dtype=np.float64)
    valid = np.broadcast_to(np.asarray(valid, dtype=bool), values.shape[1:])
    if dtype.kind in "iu":
        info = np.iinfo(dtype)
        with np.errstate(invalid="ignore"):
            rounded = np.where(values < 0, np.ceil(values - 0.5), np.floor(values + 0.5))
            rounded = np.clip(rounded, info.min, info.max)
        rounded = np.where(valid, rounded, 0.0)  # NaN never reaches the integer conversion
        out = rounded.astype(dtype)
    elif dtype.kind == "b":
        with np.errstate(invalid="ignore"):
            out = np.where(valid, np.abs(values) >= 0.5, False)
    else:
        with np.errstate(over="ignore", invalid="ignore"):
            out = values.astype(dtype)
    fill_value = np.asarray(fill, dtype=np.float64) if dtype.kind in "iub" else np.asarray(fill)
    if dtype.kind in "iu" and not (np.isfinite(fill_value) and info.min <= fill_value <= info.max):
        raise ValueError(f"cast: fill {fill!r} is not representable in {dtype}")
    out[:, ~valid] = fill_value.astype(dtype)
    return out


#: output dtypes :func:`resample_cast` converts inside the compiled kernels (others: two steps)
_FUSED_DTYPES = frozenset(np.dtype(t) for t in ("uint8", "int8", "uint16", "int16", "uint32",
                                                 "int32", "float32", "float64"))


def resample_cast(
    src: np.ndarray,
    row: Any,
    col: Any,
    kernel: str,
    dtype: Any,
    fill: float = 0,
    *,
    nodata: float | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """``cast(*resample(src, row, col, kernel, nodata=nodata), dtype, fill)`` in one pass.

    The orthorectifier's path: the compiled kernels write the output dtype directly (no
    float64 values array), with the same values as the two steps (tested).

    Returns
    -------
    out : ndarray, (bands, *S) of ``dtype``
    valid : ndarray, (*S,) bool
    """
    dtype = np.dtype(dtype)
    if dtype not in _FUSED_DTYPES:
        values, valid = resample(src, row, col, kernel, nodata=nodata)
        return cast(values, valid, dtype, fill), valid
    src, row, col, shape, mask = _prepare(src, row, col, kernel, nodata)
    is_int = dtype.kind in "iu"
    if is_int:
        info = np.iinfo(dtype)
        lo, hi = float(info.min), float(info.max)
        fill_value = float(fill)
        if not (math.isfinite(fill_value) and lo <= fill_value <= hi):
            raise ValueError(f"cast: fill {fill!r} is not representable in {dtype}")
    else:
        lo = hi = 0.0
        fill_value = float(fill)
    bands = src.shape[0]
    out = np.empty((bands, row.size), dtype=dtype)
    valid = np.empty(row.size, dtype=np.bool_)
    use_mask = mask is not None
    if mask is None:
        mask = np.zeros((0, 0), dtype=np.bool_)
    _nb_resample(src, mask, use_mask, row, col, _KIND[kernel], out, valid, is_int, lo, hi,
                 fill_value)
    return out.reshape((bands,) + shape), valid.reshape(shape)


# ---------------------------------------------------------------------- helpers
def _prepare(
    src: ArrayLike, row: ArrayLike, col: ArrayLike, kernel: str, nodata: float | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, tuple[int, ...], np.ndarray | None]:
    if kernel not in KERNELS:
        raise ValueError(f"kernel must be one of {KERNELS}, got {kernel!r}")
    src = np.asarray(src)
    if src.ndim != 3:
        raise ValueError(f"src must be (bands, rows, cols), got shape {src.shape}")
    if src.dtype.kind not in "biuf":
        raise TypeError(f"src must have a real numeric dtype, got {src.dtype}")
    if src.dtype == np.bool_:
        src = src.view(np.uint8)
    elif src.dtype == np.float16:
        src = src.astype(np.float32)
    src = np.ascontiguousarray(src)
    row, col = np.broadcast_arrays(np.asarray(row, dtype=np.float64),
                                   np.asarray(col, dtype=np.float64))
    shape = row.shape
    row = np.ascontiguousarray(row).ravel()
    col = np.ascontiguousarray(col).ravel()
    mask = None
    if nodata is not None and not (isinstance(nodata, float) and math.isnan(nodata)):
        # a pixel is nodata when all its bands equal nodata (NaN is always invalid anyway)
        mask = np.all(src == np.asarray(nodata, dtype=np.float64), axis=0)
        if not mask.any():
            mask = None
    return src, row, col, shape, mask


# ---------------------------------------------------------------------- numba kernel
_M = np.arange(-7, 9)
_COS_M8 = np.cos(np.pi * _M / SINC_HALF_WIDTH)
_SIN_M8 = np.sin(np.pi * _M / SINC_HALF_WIDTH)

@numba.njit(nogil=True, cache=True)
def _nb_weights(x: float, kind: int, w: np.ndarray) -> int:  # pragma: no cover - compiled
    """Fill ``w`` with the axis weights of coordinate ``x``; return the first tap index."""
    if kind == 0:
        w[0] = 1.0
        return int(math.floor(x + PIXEL_CENTRE))  # the pixel holding the point
    base = math.floor(x)
    t = x - base
    i0 = int(base)
    if kind == 1:
        w[0] = 1.0 - t
        w[1] = t
        return i0
    if kind == 2:
        a = -0.5
        t2 = t * t
        t3 = t2 * t
        w[0] = a * t3 - 2 * a * t2 + a * t
        w[1] = (a + 2) * t3 - (a + 3) * t2 + 1
        w[2] = -(a + 2) * t3 + (2 * a + 3) * t2 - a * t
        w[3] = -a * t3 + a * t2
        return i0 - 1
    # sin(pi d) = (-1)^m sin(pi t) and sin(pi d / 8) by the angle-difference formula,
    # d = t - m for taps m = -7..8: three trig calls per axis instead of 32
    if t == 0.0:
        for k in range(16):
            w[k] = 0.0
        w[7] = 1.0
        return i0 - 7
    s1 = math.sin(math.pi * t)
    s8 = math.sin(math.pi * t / 8.0)
    c8 = math.cos(math.pi * t / 8.0)
    total = 0.0
    for k in range(16):
        m = k - 7
        d = t - m
        if abs(d) < 8.0:
            sign = 1.0 if m % 2 == 0 else -1.0
            num = sign * s1 * (s8 * _COS_M8[k] - c8 * _SIN_M8[k])
            wk = num * 8.0 / (math.pi * math.pi * d * d)
        else:
            wk = 0.0
        w[k] = wk
        total += wk
    for k in range(16):
        w[k] = w[k] / total
    return i0 - 7

@numba.njit(nogil=True, cache=True)
def _nb_nearest(src: np.ndarray, mask: np.ndarray, use_mask: bool, row: np.ndarray,
                col: np.ndarray, out: np.ndarray, valid: np.ndarray, is_int: bool, lo: float,
                hi: float, fill: float) -> None:  # pragma: no cover
    bands, rows, cols = src.shape
    for p in range(row.shape[0]):
        r = row[p]
        c = col[p]
        ok = np.isfinite(r) and np.isfinite(c)
        if ok:
            ri = int(math.floor(r + PIXEL_CENTRE))  # the pixel holding the point
            ci = int(math.floor(c + PIXEL_CENTRE))
            ok = 0 <= ri < rows and 0 <= ci < cols and not (use_mask and mask[ri, ci])
        if ok:
            for b in range(bands):
                if not np.isfinite(float(src[b, ri, ci])):
                    ok = False
            if ok:
                for b in range(bands):
                    out[b, p] = _store(float(src[b, ri, ci]), is_int, lo, hi)
        if not ok:
            for b in range(bands):
                out[b, p] = fill
        valid[p] = ok

@numba.njit(nogil=True, cache=True)
def _nb_bilinear(src: np.ndarray, mask: np.ndarray, use_mask: bool, row: np.ndarray,
                 col: np.ndarray, out: np.ndarray, valid: np.ndarray, is_int: bool, lo: float,
                 hi: float, fill: float) -> None:  # pragma: no cover
    bands, rows, cols = src.shape
    for p in range(row.shape[0]):
        r = row[p]
        c = col[p]
        ok = np.isfinite(r) and np.isfinite(c)
        if ok:
            fr = math.floor(r)
            fc = math.floor(c)
            tr = r - fr
            tc = c - fc
            r0 = int(fr)
            c0 = int(fc)
            r1 = r0 + 1 if tr != 0.0 else r0  # a zero-weight tap is not needed
            c1 = c0 + 1 if tc != 0.0 else c0
            ok = r0 >= 0 and r1 < rows and c0 >= 0 and c1 < cols
            if ok and use_mask:
                ok = not (mask[r0, c0] or mask[r0, c1] or mask[r1, c0] or mask[r1, c1])
        if ok:
            for b in range(bands):
                top = (1.0 - tc) * src[b, r0, c0] + tc * src[b, r0, c1]
                bot = (1.0 - tc) * src[b, r1, c0] + tc * src[b, r1, c1]
                v = (1.0 - tr) * top + tr * bot
                if not np.isfinite(v):
                    ok = False
                    break
                out[b, p] = _store(v, is_int, lo, hi)
        if not ok:
            for b in range(bands):
                out[b, p] = fill
        valid[p] = ok

@numba.njit(inline="always")
def _store(v: float, is_int: bool, lo: float, hi: float) -> float:  # pragma: no cover
    """A finite value as :func:`cast` converts it: integers rounded half away from zero
    and clipped to ``[lo, hi]``; floats as they are (the assignment converts)."""
    if is_int:
        r = math.ceil(v - 0.5) if v < 0 else math.floor(v + 0.5)
        return min(max(r, lo), hi)
    return v

def _nb_resample(src: np.ndarray, mask: np.ndarray, use_mask: bool, row: np.ndarray,
                 col: np.ndarray, kind: int, out: np.ndarray, valid: np.ndarray,
                 is_int: bool = False, lo: float = 0.0, hi: float = 0.0,
                 fill: float = np.nan) -> None:  # pragma: no cover
    """Dispatch in Python, so that numba compiles only the kernels used (per dtypes).

    ``out`` (bands, N) of float64 (values, NaN where invalid) or of the output dtype
    (values as :func:`cast` converts them, ``fill`` where invalid)."""
    args = (out, valid, is_int, float(lo), float(hi), fill)
    if kind == 0:
        _nb_nearest(src, mask, use_mask, row, col, *args)
    elif kind == 1:
        _nb_bilinear(src, mask, use_mask, row, col, *args)
    else:
        _nb_separable(src, mask, use_mask, row, col, kind, 4 if kind == 2 else 16, *args)

@numba.njit(nogil=True, cache=True)
def _nb_separable(src: np.ndarray, mask: np.ndarray, use_mask: bool, row: np.ndarray,
                  col: np.ndarray, kind: int, n: int, out: np.ndarray, valid: np.ndarray,
                  is_int: bool, lo: float, hi: float, fill: float) -> None:  # pragma: no cover
    """Bicubic and sinc: separable weights; only taps from the first to the last non-zero
    weight of each axis are read."""
    bands, rows, cols = src.shape
    wr = np.empty(16)
    wc = np.empty(16)
    for p in range(row.shape[0]):
        r = row[p]
        c = col[p]
        ok = np.isfinite(r) and np.isfinite(c)
        if ok:
            r0 = _nb_weights(r, kind, wr)
            c0 = _nb_weights(c, kind, wc)
            ilo, ihi = _nb_support(wr, n)
            jlo, jhi = _nb_support(wc, n)
            ok = r0 + ilo >= 0 and r0 + ihi < rows and c0 + jlo >= 0 and c0 + jhi < cols
            if ok and use_mask:
                for i in range(ilo, ihi + 1):
                    for j in range(jlo, jhi + 1):
                        if mask[r0 + i, c0 + j]:
                            ok = False
        if ok:
            for b in range(bands):
                acc = 0.0
                for i in range(ilo, ihi + 1):
                    line = 0.0
                    for j in range(jlo, jhi + 1):
                        line += wc[j] * src[b, r0 + i, c0 + j]
                    acc += wr[i] * line
                if not np.isfinite(acc):
                    ok = False
                    break
                out[b, p] = _store(acc, is_int, lo, hi)
        if not ok:
            for b in range(bands):
                out[b, p] = fill
        valid[p] = ok

@numba.njit(nogil=True, cache=True)
def _nb_support(w: np.ndarray, n: int) -> tuple[int, int]:  # pragma: no cover
    """First and last index of a non-zero weight in ``w[:n]``."""
    lo = 0
    while lo < n - 1 and w[lo] == 0.0:
        lo += 1
    hi = n - 1
    while hi > lo and w[hi] == 0.0:
        hi -= 1
    return lo, hi

