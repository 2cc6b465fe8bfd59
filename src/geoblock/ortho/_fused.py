"""The fused lattice pass: output pixel -> lon/lat -> DEM height (+ geoid) -> image (row, col).

:mod:`geoblock.ortho.lattice`'s production path interpolates every pixel's lon/lat into strip
arrays, samples the DEM on them (through :meth:`DemSource.height`: pixel coordinates,
coverage, sample, then the geoid as separate passes) and interpolates the image coordinates
from the heights. For the DEM most users pass (a :class:`~geoblock.dem.raster.RasterDem` in a
geographic CRS, heights above the ellipsoid or EGM96) this module does all of it in one
compiled pass per output row of a lattice block, with no intermediate full arrays: the lon/lat
of a pixel (bilinear in the lattice nodes), its DEM pixel, the DEM sample, the geoid
undulation and the image coordinates (bilinear in the nodes, quadratic in the height) stay in
registers.

The arithmetic is the reference path's, operation for operation (same lattice interpolation,
the DEM's own kernel :func:`geoblock.dem.sampling._nb_point_s`, the geoid's bilinear formula
in the same order), so the output is bit-identical to it (``tests/ortho/test_fused.py``).
Whatever the pass cannot do exactly as the reference path (a DEM in a projected CRS, a DEM
source of another kind, a strict DEM with a point outside it, a point whose DEM taps leave the
window read for the block) goes through the reference path instead: :func:`plan` returns
None, or :func:`fill_block_rows` returns False.

The DEM is read through the raster's block cache (:meth:`RasterDem._posts_window`): a private
contract with :mod:`geoblock.dem.raster`, checked by :func:`plan` (anything unexpected: None).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numba
import numpy as np

from geoblock.dem.sampling import _nb_geoid_point, _nb_map_to_pixel, _nb_point_s
from geoblock.pixels import PIXEL_CENTRE

#: DEM posts read for a block's window, at most, per output pixel of the block (beyond, the
#: reference path samples point by point through the DEM's blocks).
MAX_POSTS_PER_PIXEL = 2.0


@dataclass(frozen=True)
class DemPlan:
    """What the fused pass needs of a geographic :class:`RasterDem` (see :func:`plan`)."""

    dem: Any
    inverse: np.ndarray  # (6,) inverse geotransform a, b, c, d, e, f
    west: float  # longitude the kernel wraps from
    rows: int
    cols: int
    n: int  # 0 nearest, 2 bilinear, 4 bicubic
    strict: bool
    geoid_nodes: np.ndarray  # (R, C) float64, or (1, 1) unused
    geoid: tuple[float, float, float, float, bool, bool]  # lon0, dlon, lat0, dlat, global, on


def plan(dem: Any) -> DemPlan | None:
    """A :class:`DemPlan` for ``dem``, or None when the fused pass does not apply (the
    reference path then runs)."""
    from geoblock.dem.raster import RasterDem

    if type(dem) is not RasterDem:
        return None
    try:
        if not dem._lonlat:  # a projected DEM: pyproj per point, the reference path
            return None
        interp = dem._interpolation
        n = {"nearest": 0, "bilinear": 2, "bicubic": 4}[interp]
        inverse = np.ascontiguousarray(dem._inverse, dtype=np.float64)
        rows, cols = (int(v) for v in dem._shape)
        west = float(dem._transform.c)
        geoid = dem._geoid
        if geoid is None:
            g_nodes = np.zeros((1, 1))
            g = (0.0, 1.0, 0.0, 1.0, False, False)
        else:
            g_nodes = np.ascontiguousarray(geoid._nodes, dtype=np.float64)
            if g_nodes.ndim != 2 or min(g_nodes.shape) < 2:
                return None
            g = (float(geoid._lon0), float(geoid._dlon), float(geoid._lat0),
                 float(geoid._dlat), bool(geoid._global), True)
        if inverse.shape != (6,) or not hasattr(dem, "_posts_window"):
            return None
    except (AttributeError, KeyError, TypeError, ValueError):
        return None
    return DemPlan(dem, inverse, west, rows, cols, n, bool(dem._strict), g_nodes, g)


def dem_window(p: DemPlan, lon: np.ndarray, lat: np.ndarray,
               pixels: int) -> tuple[np.ndarray, float, float] | None:
    """The DEM posts (and their halo) under lattice nodes ``lon, lat``, with the raster pixel
    of the window's first post; None when the nodes are not all finite, wrap around the
    DEM's west edge, or need more than ``MAX_POSTS_PER_PIXEL * pixels`` posts.

    Bilinear interpolation in a lattice cell stays within its nodes' range, so the window of
    the nodes' box holds every pixel's taps (:func:`fill_block_rows` checks it per point)."""
    if lon.size == 0 or not (np.isfinite(lon).all() and np.isfinite(lat).all()):
        return None
    x_lo, x_hi = float(lon.min()), float(lon.max())
    if not (x_lo >= p.west and x_hi < p.west + 360.0):
        return None
    y_lo, y_hi = float(lat.min()), float(lat.max())
    a, b, c, d, e, f = (float(v) for v in p.inverse)
    xs = (x_lo, x_lo, x_hi, x_hi)
    ys = (y_lo, y_hi, y_lo, y_hi)
    cc = [a * x + b * y + c - PIXEL_CENTRE for x, y in zip(xs, ys, strict=True)]
    rr = [d * x + e * y + f - PIXEL_CENTRE for x, y in zip(xs, ys, strict=True)]
    rows, cols = p.rows, p.cols
    r_lo = min(max(math.floor(min(rr)) - 2, 0), rows - 1)
    r_hi = min(max(math.floor(max(rr)) + 2, 0), rows - 1)
    c_lo = min(max(math.floor(min(cc)) - 2, 0), cols - 1)
    c_hi = min(max(math.floor(max(cc)) + 2, 0), cols - 1)
    found = p.dem._posts_window(r_lo, r_hi, c_lo, c_hi, MAX_POSTS_PER_PIXEL * pixels + 65536)
    if found is None:
        return None
    window, off_r, off_c = found
    return window, float(off_r), float(off_c)


def fill_block_rows(p: DemPlan, window: tuple[np.ndarray, float, float], lon_n: np.ndarray,
                    lat_n: np.ndarray, rn: np.ndarray, cn: np.ndarray, r_lo: int, c_lo: int,
                    s: int, h0: float, dh: float, pairs: int, out_r: np.ndarray,
                    out_c: np.ndarray) -> tuple[bool, int]:
    """Image coordinates of block pixels ``r_lo + i, c_lo + j`` into ``out_r, out_c``
    (nrows, ncols, views of the output), in one pass.

    Returns
    -------
    done : bool
        False when a point's DEM taps leave ``window``, or a strict DEM has a point outside
        it: nothing reliable was written, run the reference path.
    miss : int
        Pixels with a DEM height whose interpolated coordinates are not finite (a node outside
        the model's domain): the caller's exact fallback, as the reference path's.
    """
    arr, off_r, off_c = window
    lon0, dlon, lat0, dlat, glob, on = p.geoid
    status = _nb_fused_rows(lon_n, lat_n, rn, cn, r_lo, c_lo, s, h0, dh, pairs, p.inverse,
                            p.west, p.rows, p.cols, p.n, arr, off_r, off_c, p.strict,
                            p.geoid_nodes, lon0, dlon, lat0, dlat, glob, on, out_r, out_c)
    if status < 0:
        return False, 0
    return True, int(status)


# ---------------------------------------------------------------------- kernels
# the lattice's interpolation steps, shared with geoblock.ortho.lattice (which imports them)
@numba.njit(inline="always")
def _cell(p: int, s: int, inv: float, n: int) -> tuple[int, float]:  # pragma: no cover
    """Node cell ``k`` and fraction ``t`` of block pixel ``p`` (nodes at multiples of ``s``)."""
    k = p // s
    if k > n - 2:
        k = n - 2
    return k, (p - k * s) * inv


@numba.njit(inline="always")
def _quadratic_weights(hh: float, h0: float, dh: float,
                       pairs: int) -> tuple[int, float, float, float]:  # pragma: no cover
    """First level ``2 k`` and Lagrange weights of height ``hh`` on levels ``h0 + k dh``."""
    u = (hh - h0) / dh
    k = int(math.floor(u * 0.5))
    if k < 0:
        k = 0
    elif k > pairs - 1:
        k = pairs - 1
    t = u - 2.0 * k
    return 2 * k, 0.5 * (t - 1.0) * (t - 2.0), -t * (t - 2.0), 0.5 * t * (t - 1.0)


@numba.njit(inline="always")
def _row_lerp(nodes: np.ndarray, kr: int, tr: float,
              out: np.ndarray) -> None:  # pragma: no cover - compiled
    """``out[..., kc]``: the nodes of rows ``kr, kr + 1`` interpolated at ``tr`` (the first
    step of :func:`_lerp2`, shared by a whole output row)."""
    for kc in range(nodes.shape[-1]):
        out[kc] = nodes[kr, kc] + tr * (nodes[kr + 1, kc] - nodes[kr, kc])


@numba.njit(nogil=True, cache=True)
def _column_cells(c_off: int, ncols: int, s: int,
                  n: int) -> tuple[np.ndarray, np.ndarray]:  # pragma: no cover - compiled
    """:func:`_cell` of block columns ``c_off .. c_off + ncols - 1``: shared by every row."""
    kcs = np.empty(ncols, dtype=np.int64)
    tcs = np.empty(ncols)
    inv = 1.0 / s
    for j in range(ncols):
        kcs[j], tcs[j] = _cell(c_off + j, s, inv, n)
    return kcs, tcs


@numba.njit(nogil=True, cache=True, error_model="numpy")
def _nb_fused_rows(lon_n: np.ndarray, lat_n: np.ndarray, rn: np.ndarray, cn: np.ndarray,
                   r_off: int, c_off: int, s: int, h0: float, dh: float, pairs: int,
                   inv: np.ndarray, west: float, rows: int, cols: int, n: int,
                   window: np.ndarray, off_r: float, off_c: float, strict: bool,
                   g: np.ndarray, g_lon0: float, g_dlon: float, g_lat0: float, g_dlat: float,
                   g_global: bool, g_on: bool, row_out: np.ndarray,
                   col_out: np.ndarray) -> int:  # pragma: no cover - compiled
    """:func:`fill_block_rows`: -1 when the pass cannot be exact (see there), else the
    number of pixels with a height but non-finite coordinates."""
    nrows, ncols = row_out.shape
    nlev, nr, nc = rn.shape
    inv_s = 1.0 / s
    a_, b_, c_, d_, e_, f_ = inv[0], inv[1], inv[2], inv[3], inv[4], inv[5]
    hi_r = rows - 1.0
    hi_c = cols - 1.0
    wr_n, wc_n = window.shape
    first = 0 if n == 2 else -1
    taps = 1 if n == 0 else n
    g_rows, g_cols = g.shape
    line_lon = np.empty(nc)
    line_lat = np.empty(nc)
    lr = np.empty((nlev, nc))
    lc = np.empty((nlev, nc))
    kcs, tcs = _column_cells(c_off, ncols, s, nc)
    hrow = np.empty(ncols)  # one output row's heights (the row's steps share these)
    lon_row = np.empty(ncols)
    lat_row = np.empty(ncols)
    miss = 0
    for i in range(nrows):
        kr, tr = _cell(r_off + i, s, inv_s, nr)
        _row_lerp(lon_n, kr, tr, line_lon)
        _row_lerp(lat_n, kr, tr, line_lat)
        for m in range(nlev):
            _row_lerp(rn[m], kr, tr, lr[m])
            _row_lerp(cn[m], kr, tr, lc[m])
        for j in range(ncols):  # lon, lat -> DEM pixel (branch-free: vectorised)
            kc = kcs[j]
            tc = tcs[j]
            a = line_lon[kc]
            lon = a + tc * (line_lon[kc + 1] - a)
            a = line_lat[kc]
            lat = a + tc * (line_lat[kc + 1] - a)
            lon_row[j] = lon
            lat_row[j] = lat
        for j in range(ncols):  # the DEM (RasterDem._sample_window's arithmetic)
            lon = lon_row[j]
            lat = lat_row[j]
            hh = np.nan
            if np.isfinite(lon) and np.isfinite(lat):
                rr, cc = _nb_map_to_pixel(lon, lat, west, True, a_, b_, c_, d_, e_, f_)
                if (rr >= -PIXEL_CENTRE and rr <= rows - PIXEL_CENTRE
                        and cc >= -PIXEL_CENTRE and cc <= cols - PIXEL_CENTRE):
                    rr = min(max(rr, 0.0), hi_r) - off_r
                    cc = min(max(cc, 0.0), hi_c) - off_c
                    # every tap inside the window, else the reference path (no silent NaN)
                    if n == 0:
                        t_r = math.floor(rr + PIXEL_CENTRE)
                        t_c = math.floor(cc + PIXEL_CENTRE)
                    else:
                        t_r = math.floor(rr) + first
                        t_c = math.floor(cc) + first
                    if t_r < 0 or t_c < 0 or t_r + taps > wr_n or t_c + taps > wc_n:
                        return -1
                    hh = _nb_point_s(window, rr, cc, n)
                    if g_on:
                        hh = hh + _nb_geoid_point(g, g_rows, g_cols, lon, lat, g_lon0, g_dlon,
                                                  g_lat0, g_dlat, g_global)
                elif strict:
                    return -1
            hrow[j] = hh
        for j in range(ncols):
            kc = kcs[j]
            tc = tcs[j]
            hh = hrow[j]
            if not np.isfinite(hh):
                row_out[i, j] = np.nan
                col_out[i, j] = np.nan
                continue
            lev, w0, w1, w2 = _quadratic_weights(hh, h0, dh, pairs)
            a = lr[lev, kc]
            vr = w0 * (a + tc * (lr[lev, kc + 1] - a))
            a = lc[lev, kc]
            vc = w0 * (a + tc * (lc[lev, kc + 1] - a))
            a = lr[lev + 1, kc]
            vr += w1 * (a + tc * (lr[lev + 1, kc + 1] - a))
            a = lc[lev + 1, kc]
            vc += w1 * (a + tc * (lc[lev + 1, kc + 1] - a))
            a = lr[lev + 2, kc]
            vr += w2 * (a + tc * (lr[lev + 2, kc + 1] - a))
            a = lc[lev + 2, kc]
            vc += w2 * (a + tc * (lc[lev + 2, kc + 1] - a))
            row_out[i, j] = vr
            col_out[i, j] = vc
            if not (np.isfinite(vr) and np.isfinite(vc)):
                miss += 1
    return miss
