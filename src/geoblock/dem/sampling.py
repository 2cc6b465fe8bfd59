"""Interpolation of a 2-D array at fractional pixel coordinates (pixel-centre convention).

``(row, col)`` are pixel coordinates with integers at pixel centres, as everywhere in
geoblock: GDAL's pixel/line minus 0.5. The kernels reproduce GDAL's:

* ``nearest``: the pixel containing the point (``floor(col + PIXEL_CENTRE)``);
* ``bilinear``: the four surrounding centres; any nodata (NaN) tap gives NaN, as GDAL's RPC
  DEM sampling does per point;
* ``bicubic``: Keys' cubic convolution (a = -0.5, GDAL's warp ``cubic``) on the 4 x 4
  surrounding centres; any NaN tap gives NaN.

Points whose taps leave the array are NaN (outside coverage). The numpy reference of the
compiled path is :func:`geoblock.dem._reference.sample_array_reference` (tests only).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from geoblock.pixels import PIXEL_CENTRE

__all__ = ["INTERPOLATIONS", "halo", "sample"]

INTERPOLATIONS = ("nearest", "bilinear", "bicubic")


def halo(interpolation: str) -> int:
    """Pixels needed on each side of a point's cell by ``interpolation``."""
    return {"nearest": 0, "bilinear": 1, "bicubic": 2}[interpolation]


def _keys(t: np.ndarray) -> np.ndarray:
    """(..., 4) Keys cubic-convolution weights (a = -0.5) for taps at -1, 0, 1, 2."""
    a = -0.5
    t2, t3 = t * t, t * t * t
    return np.stack(
        [
            a * t3 - 2 * a * t2 + a * t,
            (a + 2) * t3 - (a + 3) * t2 + 1,
            -(a + 2) * t3 + (2 * a + 3) * t2 - a * t,
            -a * t3 + a * t2,
        ],
        axis=-1,
    )


def sample(array: np.ndarray, row: np.ndarray, col: np.ndarray, interpolation: str) -> np.ndarray:
    """Values of ``array`` (float, NaN = nodata) at pixel coordinates, NaN outside.

    Parameters
    ----------
    array : ndarray, (R, C)
    row, col : ndarray, (N,)
        Pixel-centre coordinates.
    interpolation : {"nearest", "bilinear", "bicubic"}

    Returns
    -------
    ndarray, (N,) float64
    """
    if interpolation not in INTERPOLATIONS:
        raise ValueError(f"interpolation must be one of {INTERPOLATIONS}, got {interpolation!r}")
    rows, cols = array.shape
    out = np.full(row.shape, np.nan)
    finite = np.isfinite(row) & np.isfinite(col)
    if interpolation == "nearest":
        with np.errstate(invalid="ignore"):
            r = np.floor(row + PIXEL_CENTRE)  # the pixel holding the point
            c = np.floor(col + PIXEL_CENTRE)
        ok = finite & (r >= 0) & (r < rows) & (c >= 0) & (c < cols)
        out[ok] = array[r[ok].astype(np.intp), c[ok].astype(np.intp)]
        return out
    # bilinear / bicubic: one compiled pass (no (M, n, n) gathers; releases the GIL)
    arr = np.ascontiguousarray(array, dtype=np.float64)
    flat_r = np.ascontiguousarray(row, dtype=np.float64).reshape(-1)
    flat_c = np.ascontiguousarray(col, dtype=np.float64).reshape(-1)
    flat = out.reshape(-1)
    _nb_sample(arr, flat_r, flat_c, 2 if interpolation == "bilinear" else 4, flat)
    return flat.reshape(out.shape)


@numba.njit(inline="always")
def _keys4(t: float) -> tuple[float, float, float, float]:  # pragma: no cover - compiled
    """Keys weights (a = -0.5) for taps at -1, 0, 1, 2, as :func:`_keys`, as a tuple (no
    scratch array: hot loops stay free of array reference counting)."""
    a = -0.5
    t2 = t * t
    t3 = t * t * t
    return (a * t3 - 2 * a * t2 + a * t,
            (a + 2) * t3 - (a + 3) * t2 + 1,
            -(a + 2) * t3 + (2 * a + 3) * t2 - a * t,
            -a * t3 + a * t2)


@numba.njit(inline="always")
def _nb_map_to_pixel(x: float, y: float, west: float, lonlat: bool, a: float, b: float,
                     c: float, d: float, e: float,
                     f: float) -> tuple[float, float]:  # pragma: no cover - compiled
    """Raster (row, col), pixel centres at integers, of map coordinates ``(x, y)`` by the
    inverse geotransform ``a..f``; a longitude (``lonlat``) is first wrapped into
    ``[west, west + 360)``. The one place the DEM kernels (sampling, the fused ortho lattice,
    the ray scan) turn a point into a DEM pixel."""
    if lonlat:
        dx = x - west
        if not (dx >= 0.0 and dx < 360.0):  # else dx % 360.0 == dx exactly
            dx = dx % 360.0
        x = west + dx
    cc = (a * x + b * y + c) - PIXEL_CENTRE
    rr = (d * x + e * y + f) - PIXEL_CENTRE
    return rr, cc


@numba.njit(inline="always")
def _nb_geoid_point(g: np.ndarray, rows: int, cols: int, lon: float, lat: float, lon0: float,
                    dlon: float, lat0: float, dlat: float,
                    glob: bool) -> float:  # pragma: no cover - compiled
    """:meth:`geoblock.dem.geoid.Geoid.undulation` at one point, in its order of operations
    (NaN outside a regional grid): ``g`` (rows, cols) its nodes (m), ``lon0, dlon, lat0,
    dlat`` its grid (degrees), ``glob`` whether it wraps around the Earth. The fused ortho
    lattice (:mod:`geoblock.ortho._fused`) and the ray scan (:mod:`geoblock.dem._raycast`)
    share it."""
    x = (lon - lon0) / dlon
    y = (lat - lat0) / dlat
    if glob:
        x = np.mod(x, cols)
    if not (y >= 0 and y <= rows - 1):
        return np.nan
    if not glob and not (x >= 0 and x <= cols - 1):
        return np.nan
    i0 = min(int(math.floor(y)), rows - 2)
    ty = y - i0
    if glob:
        fx = math.floor(x)
        j0 = int(fx) % cols
        j1 = (j0 + 1) % cols
        tx = x - fx
    else:
        j0 = min(int(math.floor(x)), cols - 2)
        j1 = j0 + 1
        tx = x - j0
    return ((1 - ty) * ((1 - tx) * g[i0, j0] + tx * g[i0, j1])
            + ty * ((1 - tx) * g[i0 + 1, j0] + tx * g[i0 + 1, j1]))


@numba.njit(inline="always")
def _nb_point_s(array: np.ndarray, r: float, c: float,
                n: int) -> float:  # pragma: no cover - compiled
    """One point of :func:`sample` (n = 0 nearest, 2 bilinear, 4 bicubic): NaN outside the
    array or for a non-finite coordinate; NaN taps propagate. Scalars only."""
    rows, cols = array.shape
    if not (np.isfinite(r) and np.isfinite(c)):
        return np.nan
    if n == 0:
        ri = math.floor(r + PIXEL_CENTRE)  # the pixel holding the point
        ci = math.floor(c + PIXEL_CENTRE)
        if ri < 0 or ri >= rows or ci < 0 or ci >= cols:
            return np.nan
        return np.float64(array[int(ri), int(ci)])
    first = 0 if n == 2 else -1
    r0 = math.floor(r)
    c0 = math.floor(c)
    if r0 + first < 0 or r0 + first + n - 1 >= rows or c0 + first < 0 or c0 + first + n - 1 >= cols:
        return np.nan
    tr = r - r0
    tc = c - c0
    if n == 2:
        ri = int(r0)
        ci = int(c0)
        wc0 = 1.0 - tc
        s0 = 0.0 + array[ri, ci] * wc0
        s0 = s0 + array[ri, ci + 1] * tc
        s1 = 0.0 + array[ri + 1, ci] * wc0
        s1 = s1 + array[ri + 1, ci + 1] * tc
        acc = 0.0 + (1.0 - tr) * s0
        return acc + tr * s1
    wr = _keys4(tr)
    wc = _keys4(tc)
    ri = int(r0) - 1
    ci = int(c0) - 1
    acc = 0.0
    for i in range(4):
        s = 0.0
        s += array[ri + i, ci] * wc[0]
        s += array[ri + i, ci + 1] * wc[1]
        s += array[ri + i, ci + 2] * wc[2]
        s += array[ri + i, ci + 3] * wc[3]
        acc += wr[i] * s
    return acc


@numba.njit(nogil=True, cache=True, inline="always")
def _nb_point(array: np.ndarray, r: float, c: float, n: int, wr: np.ndarray,
              wc: np.ndarray) -> float:  # pragma: no cover - compiled
    """:func:`_nb_point_s` (``wr, wc``: unused scratch, kept for the callers' signature)."""
    return _nb_point_s(array, r, c, n)


@numba.njit(nogil=True, cache=True)
def _nb_sample(array: np.ndarray, row: np.ndarray, col: np.ndarray, n: int,
               out: np.ndarray) -> None:  # pragma: no cover - compiled
    """Bilinear (n = 2) or bicubic (n = 4) values at (row, col) into ``out``."""
    wr = np.empty(4)
    wc = np.empty(4)
    for k in range(row.size):
        out[k] = _nb_point(array, row[k], col[k], n, wr, wc)


# ---------------------------------------------------------------------------- raster DEM blocks
# locating and sampling points in the cached blocks of a RasterDem (geoblock.dem.raster)
@numba.njit(nogil=True, cache=True)
def _nb_pixel_coords(x: np.ndarray, y: np.ndarray, inv: np.ndarray, lonlat: bool, west: float,
                     row: np.ndarray, col: np.ndarray) -> None:  # pragma: no cover - compiled
    """Pixel-centre row/col of CRS points ``x, y`` (longitudes wrapped from ``west`` when
    ``lonlat``), with the inverse geotransform ``inv`` (a, b, c, d, e, f)."""
    a, b, c, d, e, f = inv[0], inv[1], inv[2], inv[3], inv[4], inv[5]
    for k in range(x.size):
        row[k], col[k] = _nb_map_to_pixel(x[k], y[k], west, lonlat, a, b, c, d, e, f)


@numba.njit(nogil=True, cache=True)
def _nb_locate(row: np.ndarray, col: np.ndarray, rows: int, cols: int, b: int, nbc: int,
               nearest: bool, keys: np.ndarray) -> tuple[int, int]:  # pragma: no cover
    """Coverage and block of every point: ``keys`` = block index (``-1`` outside); row/col
    clipped in place to the outermost centres. Returns (min, max) key of the inside points
    (``(-1, -1)`` when none)."""
    kmin = -1
    kmax = -1
    hi_r = rows - 1.0
    hi_c = cols - 1.0
    for k in range(row.size):
        r = row[k]
        c = col[k]
        if not (r >= -PIXEL_CENTRE and r <= rows - PIXEL_CENTRE
                and c >= -PIXEL_CENTRE and c <= cols - PIXEL_CENTRE):
            keys[k] = -1
            continue
        r = min(max(r, 0.0), hi_r)
        c = min(max(c, 0.0), hi_c)
        row[k] = r
        col[k] = c
        if nearest:
            br = int(math.floor(r + PIXEL_CENTRE)) // b  # the pixel holding the point
            bc = int(math.floor(c + PIXEL_CENTRE)) // b
        else:
            br = min(int(math.floor(r)), rows - 1) // b
            bc = min(int(math.floor(c)), cols - 1) // b
        key = br * nbc + bc
        keys[k] = key
        if kmin < 0 or key < kmin:
            kmin = key
        if key > kmax:
            kmax = key
    return kmin, kmax


@numba.njit(nogil=True, cache=True)
def _nb_sample_keyed(block: np.ndarray, row: np.ndarray, col: np.ndarray, keys: np.ndarray,
                     key: int, off_r: float, off_c: float, n: int,
                     out: np.ndarray) -> None:  # pragma: no cover - compiled
    """Sample ``block`` (origin at raster pixel ``off_r, off_c``) at the points of ``key``."""
    wr = np.empty(4)
    wc = np.empty(4)
    for k in range(row.size):
        if keys[k] == key:
            out[k] = _nb_point(block, row[k] - off_r, col[k] - off_c, n, wr, wc)


@numba.njit(nogil=True, cache=True)
def _nb_sample_index(block: np.ndarray, row: np.ndarray, col: np.ndarray, idx: np.ndarray,
                     off_r: float, off_c: float, n: int,
                     out: np.ndarray) -> None:  # pragma: no cover - compiled
    """Sample ``block`` (origin at raster pixel ``off_r, off_c``) at points ``idx``."""
    wr = np.empty(4)
    wc = np.empty(4)
    for m in range(idx.size):
        k = idx[m]
        out[k] = _nb_point(block, row[k] - off_r, col[k] - off_c, n, wr, wc)



@numba.njit(nogil=True, cache=True, error_model="numpy")
def _nb_sample_window(x: np.ndarray, y: np.ndarray, inv: np.ndarray, lonlat: bool, west: float,
                      rows: int, cols: int, n: int, window: np.ndarray, off_r: float,
                      off_c: float, out: np.ndarray,
                      outside: np.ndarray) -> None:  # pragma: no cover - compiled
    """:func:`_nb_pixel_coords`, :func:`_nb_locate` and the sampling of ``window`` (origin at
    raster pixel ``off_r, off_c``) in one pass: heights into ``out`` (NaN outside), the
    coverage into ``outside``."""
    a, b, c, d, e, f = inv[0], inv[1], inv[2], inv[3], inv[4], inv[5]
    hi_r = rows - 1.0
    hi_c = cols - 1.0
    for k in range(x.size):
        rr, cc = _nb_map_to_pixel(x[k], y[k], west, lonlat, a, b, c, d, e, f)
        if not (rr >= -PIXEL_CENTRE and rr <= rows - PIXEL_CENTRE
                and cc >= -PIXEL_CENTRE and cc <= cols - PIXEL_CENTRE):
            out[k] = np.nan
            outside[k] = True
            continue
        rr = min(max(rr, 0.0), hi_r)
        cc = min(max(cc, 0.0), hi_c)
        outside[k] = False
        out[k] = _nb_point_s(window, rr - off_r, cc - off_c, n)
