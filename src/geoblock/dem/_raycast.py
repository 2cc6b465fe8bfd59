"""Compiled scan of lines of sight over a DEM window, for :func:`geoblock.localize`.

:func:`geoblock.dem.intersect.localize` (``method="robust"``) brackets the first crossing of
each line of sight with the terrain by sampling ``f(h) = h - dem(ray(h))`` at levels from the
top of the scanned height range down. Exactly, every sample costs one backprojection and one
DEM lookup (with the geoid). This module scans an *approximate* ray instead, in one compiled
pass per point, and says where the exact ray must be looked at:

* The ray is approximated by the quadratic (in ``h``) through its exact ground positions at
  three heights ``h0 < h1 < h2`` shared by all points (Lagrange form); a fourth exact position
  bounds the approximation's horizontal error ``delta`` (metres) per point.
* The DEM is sampled from a :class:`RayWindow`: the posts of a raster window covering every
  ray with the geoid's ``N`` added at each post (cached per DEM, so the geoid is not
  evaluated per sample), a bound ``geoid_err`` on how far their interpolation is from the
  DEM's heights (``N`` at the point), and a bound ``slope`` on the surface's horizontal
  gradient (metres per metre), so ``|f_exact(h) - f_approx(h)| <= tau``, with
  ``tau = slope * delta + geoid_err`` plus rounding.
* A level is *certain above* when ``f_approx > tau`` there and the sample is certainly known
  (the whole square of half-side ``delta`` around it is inside the coverage and, on a DEM
  with voids, every tap of it finite). The scan stops at the first level that is not: its
  index ``j`` is returned with whether it is *certain below* (``f_approx < -tau``, known for
  sure). Only then does :mod:`geoblock.dem.intersect` touch the exact ray.
* For a certain bracket, the root of ``f_approx`` between the levels ``j - 1`` and ``j`` is
  refined here (Illinois, tolerance and iteration cap given, outcome per point) with the
  approximate slope ``f'`` there: the caller evaluates the exact ray once at that height and
  accepts it when it meets the tolerance, else refines exactly inside the certain bracket.

Nothing here decides an answer: every returned point is checked on the exact ray by the
caller. :func:`scan_reference` is the numpy reference of :func:`scan` (tests only).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numba
import numpy as np

from geoblock.dem.sampling import _nb_geoid_point, _nb_map_to_pixel, _nb_point_s
from geoblock.pixels import PIXEL_CENTRE

__all__ = ["RayWindow", "box", "heights", "lagrange3", "levels", "scan", "scan_reference"]

#: outcome codes of :func:`scan`, per point
NONE = 0  #: every level certainly above the terrain (no crossing in the range)
BRACKET = 1  #: a certain bracket, refined on the approximate ray
UNSURE = 2  #: the level ``j`` (and below) must be scanned on the exact ray
INELIGIBLE = 3  #: the approximation is not good enough (or unknown): scan the exact ray
_NO_GEOID = np.empty((0, 0))
#: refinement outcome flags (``refined``)
REFINED = 1
REFINE_CAP = 2


@dataclass(frozen=True)
class RayWindow:
    """A DEM window in a geographic CRS, ready for the compiled scan.

    Attributes
    ----------
    posts : ndarray, (R, C) float32 or float64
        Heights in the file's vertical datum (NaN for none), the raster's rows
        ``off_r .. off_r + R`` and columns ``off_c .. off_c + C`` (edge-padded beyond it).
    off_r, off_c : float
        Raster pixel of ``posts[0, 0]``.
    inverse : ndarray, (6,)
        Inverse geotransform ``(a, b, c, d, e, f)``: lon/lat -> raster pixel corner coords.
    west : float
        Longitude of the raster's west edge (longitudes are wrapped from it).
    rows, cols : int
        Raster size (coverage: pixel-centre coordinates in ``[-0.5, rows - 0.5]``).
    taps : int
        0 nearest, 2 bilinear, 4 bicubic.
    geoid : ndarray, (GR, GC) or (0, 0)
        Geoid undulation nodes (metres), empty when the posts are ellipsoidal.
    geoid_header : ndarray, (5,)
        ``lat0, lon0, dlat, dlon, global`` of the geoid grid.
    slope : float
        Bound on ``|dem(p) - dem(q)| / |p - q|`` (metres per metre) for points of the window.
    post_m : float
        Smallest post spacing, metres (converts ``delta`` to pixels).
    has_voids : bool
        Whether ``posts`` has a NaN.
    corrected : ndarray, (R, C) float64
        ``posts`` plus the geoid's ``N`` at each post (the ellipsoidal posts): what the scan
        interpolates, so that the geoid is not evaluated per sample.
    geoid_err : float
        Bound on ``|interpolated corrected - (interpolated posts + N(point))|``, metres
        (0 without a geoid).
    """

    posts: np.ndarray
    off_r: float
    off_c: float
    inverse: np.ndarray
    west: float
    rows: int
    cols: int
    taps: int
    geoid: np.ndarray
    geoid_header: np.ndarray
    slope: float
    post_m: float
    has_voids: bool
    corrected: np.ndarray
    geoid_err: float


def lagrange3(h0: float, h1: float, h2: float,
              h: np.ndarray | float) -> tuple[Any, Any, Any]:
    """Lagrange weights of the nodes ``h0, h1, h2`` at ``h`` (numpy; as the kernel computes
    them)."""
    d01, d02, d12 = h0 - h1, h0 - h2, h1 - h2
    w0 = (h - h1) * (h - h2) * (1.0 / (d01 * d02))
    w1 = (h - h0) * (h - h2) * (1.0 / (-d01 * d12))
    w2 = (h - h0) * (h - h1) * (1.0 / (d02 * d12))
    return w0, w1, w2


# ------------------------------------------------------------------------------ compiled
@numba.njit(inline="always")
def _in_window(posts: np.ndarray, r: float, c: float, margin: float,
               n: int) -> bool:  # pragma: no cover - compiled
    """Whether every tap of the points within ``margin`` of window coords ``(r, c)`` lies in
    ``posts``."""
    R, C = posts.shape
    lo = -1.0 if n == 4 else 0.0
    hi = 2.0 if n == 4 else 1.0
    return (math.floor(r - margin) + lo >= 0 and math.floor(r + margin) + hi <= R - 1
            and math.floor(c - margin) + lo >= 0 and math.floor(c + margin) + hi <= C - 1)


@numba.njit(inline="always")
def _undulation(g: np.ndarray, hdr: np.ndarray, lon: float,
                lat: float) -> float:  # pragma: no cover - compiled
    """:meth:`geoblock.dem.Geoid.undulation` at one point (0 without a geoid); ``hdr`` is
    :attr:`geoblock.dem.Geoid.header`."""
    if g.shape[0] == 0:
        return 0.0
    return _nb_geoid_point(g, g.shape[0], g.shape[1], lon, lat, hdr[1], hdr[3], hdr[0],
                           hdr[2], hdr[4] != 0.0)


@numba.njit(inline="always")
def _height_px(posts: np.ndarray, off_r: float, off_c: float, rows: int, cols: int, n: int,
               rr: float, cc: float, margin: float,
               voids: bool) -> tuple[float, bool]:  # pragma: no cover - compiled
    """The interpolated posts at raster pixel-centre coords ``(rr, cc)`` (NaN outside the
    coverage or the window) and whether every point within ``margin`` pixels has a value
    too (``certain``)."""
    if not (rr >= -PIXEL_CENTRE and rr <= rows - PIXEL_CENTRE
            and cc >= -PIXEL_CENTRE and cc <= cols - PIXEL_CENTRE):
        return np.nan, False
    certain = (rr - margin >= -PIXEL_CENTRE and rr + margin <= rows - PIXEL_CENTRE
               and cc - margin >= -PIXEL_CENTRE and cc + margin <= cols - PIXEL_CENTRE)
    hi_r = rows - 1.0
    hi_c = cols - 1.0
    r = min(max(rr, 0.0), hi_r) - off_r
    c = min(max(cc, 0.0), hi_c) - off_c
    if not _in_window(posts, r, c, margin, n):
        return np.nan, False
    z = _nb_point_s(posts, r, c, n)
    if voids and certain:
        for sr in (-1.0, 1.0):
            for sc in (-1.0, 1.0):
                r2 = min(max(rr + sr * margin, 0.0), hi_r) - off_r
                c2 = min(max(cc + sc * margin, 0.0), hi_c) - off_c
                if not np.isfinite(_nb_point_s(posts, r2, c2, n)):
                    certain = False
    if not np.isfinite(z):
        certain = False
    return z, certain


@numba.njit(inline="always")
def _height(posts: np.ndarray, off_r: float, off_c: float, inv: np.ndarray, west: float,
            rows: int, cols: int, n: int, g: np.ndarray, hdr: np.ndarray, lon: float,
            lat: float) -> float:  # pragma: no cover - compiled
    """Ellipsoidal height at a point: the posts interpolated plus the geoid's ``N`` at the
    point (NaN when none), as :meth:`geoblock.dem.RasterDem.height` computes it."""
    rr, cc = _nb_map_to_pixel(lon, lat, west, True, inv[0], inv[1], inv[2], inv[3], inv[4],
                              inv[5])
    z = _height_px(posts, off_r, off_c, rows, cols, n, rr, cc, 0.0, False)[0]
    return z + _undulation(g, hdr, lon, lat)


@numba.njit(inline="always")
def _level(top: float, bottom: float, step: float, nlev: int, j: int) -> float:
    """Height of scan level ``j`` (as :func:`geoblock.dem.intersect._scan` places it)."""
    if j >= nlev:
        return bottom
    return top - j * step


@numba.njit(inline="always")
def _approx(w0: float, w1: float, w2: float, v0: float, v1: float,
            v2: float) -> float:  # pragma: no cover - compiled
    return w0 * v0 + w1 * v1 + w2 * v2


@numba.njit(nogil=True, cache=True, parallel=True, error_model="numpy")
def _nb_scan(nodes: np.ndarray, lon4: np.ndarray, lat4: np.ndarray, known: np.ndarray,
             top: np.ndarray, bottom: np.ndarray, step: np.ndarray, nlev: np.ndarray,
             posts: np.ndarray, off_r: float, off_c: float, inv: np.ndarray, west: float,
             rows: int, cols: int, n: int, g: np.ndarray, hdr: np.ndarray, slope: float,
             post_m: float, voids: bool, geoid_err: float, tol: float, max_iter: int,
             outcome: np.ndarray,
             level: np.ndarray, root: np.ndarray, droot: np.ndarray,
             refined: np.ndarray) -> None:  # pragma: no cover - compiled
    """See :func:`scan`."""
    h0, h1, h2, hq = nodes[0], nodes[1], nodes[2], nodes[3]
    d01, d02, d12 = h0 - h1, h0 - h2, h1 - h2
    i0, i1, i2 = 1.0 / (d01 * d02), 1.0 / (-d01 * d12), 1.0 / (d02 * d12)
    m_per_deg = math.radians(1.0) * 6378137.0
    width = abs(cols / inv[0])  # degrees of longitude the raster spans
    centre = west + 0.5 * cols / inv[0]  # (inv[0] = 1 / the column step, signed)
    wide = width > 180.0
    for i in numba.prange(top.size):
        outcome[i] = INELIGIBLE
        level[i] = nlev[i] + 1
        root[i] = np.nan
        droot[i] = np.nan
        refined[i] = 0
        if not known[i]:
            continue
        # the nodes, longitudes unwrapped around the middle one
        lo1 = lon4[1, i]
        lo0 = lo1 + ((lon4[0, i] - lo1 + 180.0) % 360.0 - 180.0)
        lo2 = lo1 + ((lon4[2, i] - lo1 + 180.0) % 360.0 - 180.0)
        loq = lo1 + ((lon4[3, i] - lo1 + 180.0) % 360.0 - 180.0)
        la0, la1, la2, laq = lat4[0, i], lat4[1, i], lat4[2, i], lat4[3, i]
        w0 = (hq - h1) * (hq - h2) * i0
        w1 = (hq - h0) * (hq - h2) * i1
        w2 = (hq - h0) * (hq - h1) * i2
        e_lon = (_approx(w0, w1, w2, lo0, lo1, lo2) - loq) * math.cos(math.radians(laq))
        e_lat = _approx(w0, w1, w2, la0, la1, la2) - laq
        # the quadratic's error at the quarter node, times 3 for the terms it does not show
        delta = 3.0 * m_per_deg * math.sqrt(e_lon * e_lon + e_lat * e_lat) + 1e-7
        if not (delta < 0.25 * post_m):
            continue
        tau = slope * delta + geoid_err + 1e-6
        margin = delta / post_m + 1e-9
        # the nodes in raster pixel coordinates (affine in lon/lat: the quadratic through
        # them is the quadratic through the ground positions), the ray's longitudes taken
        # as one piece within 180 degrees of the raster's centre (where every point of its
        # coverage is); on a raster wider than 180 degrees, a ray across its west edge
        # (where the sampling wraps) is left to the exact scan
        x1 = centre + ((lo1 - centre + 180.0) % 360.0 - 180.0)
        x0 = x1 + (lo0 - lo1)
        x2 = x1 + (lo2 - lo1)
        if wide and not (min(x0, x2) >= west and max(x0, x2) < west + 360.0):
            outcome[i] = INELIGIBLE
            continue
        c0 = (inv[0] * x0 + inv[1] * la0 + inv[2]) - PIXEL_CENTRE
        c1 = (inv[0] * x1 + inv[1] * la1 + inv[2]) - PIXEL_CENTRE
        c2 = (inv[0] * x2 + inv[1] * la2 + inv[2]) - PIXEL_CENTRE
        r0 = (inv[3] * x0 + inv[4] * la0 + inv[5]) - PIXEL_CENTRE
        r1 = (inv[3] * x1 + inv[4] * la1 + inv[5]) - PIXEL_CENTRE
        r2 = (inv[3] * x2 + inv[4] * la2 + inv[5]) - PIXEL_CENTRE
        outcome[i] = NONE
        f_up = np.nan
        h_up = np.nan
        for j in range(0, nlev[i] + 1):
            h = _level(top[i], bottom[i], step[i], nlev[i], j)
            w0 = (h - h1) * (h - h2) * i0
            w1 = (h - h0) * (h - h2) * i1
            w2 = (h - h0) * (h - h1) * i2
            z, certain = _height_px(posts, off_r, off_c, rows, cols, n,
                                    _approx(w0, w1, w2, r0, r1, r2),
                                    _approx(w0, w1, w2, c0, c1, c2), margin, voids)
            f = h - z
            if certain and f > tau:
                f_up = f
                h_up = h
                continue
            level[i] = j
            if not (certain and f < -tau and j > 0 and np.isfinite(f_up)):
                outcome[i] = UNSURE
                break
            outcome[i] = BRACKET
            # Illinois on the approximate ray between h_up (f > 0) and h (f < 0)
            a, fa, b, fb = h_up, f_up, h, f
            ga, gb = fa, fb
            side = 0
            x = b
            for _ in range(max_iter):
                x = a - ga * (b - a) / (gb - ga)
                if not (x < a and x > b):
                    x = 0.5 * (a + b)
                w0 = (x - h1) * (x - h2) * i0
                w1 = (x - h0) * (x - h2) * i1
                w2 = (x - h0) * (x - h1) * i2
                zx = _height_px(posts, off_r, off_c, rows, cols, n,
                                _approx(w0, w1, w2, r0, r1, r2),
                                _approx(w0, w1, w2, c0, c1, c2), 0.0, False)[0]
                fx = x - zx
                if not np.isfinite(fx):
                    x = np.nan
                    break
                if fx > 0:
                    if side == 1:
                        gb = 0.5 * gb
                    a, fa, ga = x, fx, fx
                    side = 1
                else:
                    if side == -1:
                        ga = 0.5 * ga
                    b, fb, gb = x, fx, fx
                    side = -1
                if abs(fx) <= tol or a - b <= tol:
                    refined[i] = REFINED
                    break
            if refined[i] != REFINED:
                refined[i] = REFINE_CAP
            root[i] = x
            # f' on the approximate ray at the root, from the final bracket's secant
            if a - b > 0 and np.isfinite(fa - fb):
                droot[i] = (fa - fb) / (a - b)
            break


@numba.njit(nogil=True, cache=True, parallel=True, error_model="numpy")
def _nb_heights(lon: np.ndarray, lat: np.ndarray, posts: np.ndarray, off_r: float,
                off_c: float, inv: np.ndarray, west: float, rows: int, cols: int, n: int,
                g: np.ndarray, hdr: np.ndarray, out: np.ndarray) -> None:  # pragma: no cover
    """Ellipsoidal heights at points from the window (NaN where it has none)."""
    for i in numba.prange(lon.size):
        out[i] = _height(posts, off_r, off_c, inv, west, rows, cols, n, g, hdr, lon[i],
                         lat[i])


def heights(window: RayWindow, lon: np.ndarray, lat: np.ndarray) -> np.ndarray:
    """(N,) ellipsoidal heights at ``lon, lat`` (degrees) from ``window`` (compiled): the DEM's
    :meth:`~geoblock.dem.RasterDem.height` to rounding; NaN where the DEM has no height or
    the window does not reach."""
    lon = np.ascontiguousarray(lon, np.float64)
    lat = np.ascontiguousarray(lat, np.float64)
    out = np.empty(lon.size)
    if lon.size:
        _nb_heights(lon, lat, window.posts, window.off_r, window.off_c, window.inverse,
                    window.west, window.rows, window.cols, window.taps, window.geoid,
                    window.geoid_header, out)
    return out


@numba.njit(nogil=True, cache=True, error_model="numpy")
def _nb_levels(lo_lon: np.ndarray, lo_lat: np.ndarray, hi_lon: np.ndarray, hi_lat: np.ndarray,
               dh: float, res: float, span: float, max_levels: int, step: np.ndarray,
               nlev: np.ndarray, along: np.ndarray) -> None:  # pragma: no cover - compiled
    """See :func:`levels`."""
    m_per_deg = math.radians(1.0) * 6378137.0
    n = lo_lon.size
    kmax = -1.0
    for i in range(n):
        dy = (hi_lat[i] - lo_lat[i]) * m_per_deg
        dx = (((hi_lon[i] - lo_lon[i] + 180.0) % 360.0 - 180.0) * m_per_deg
              * math.cos(math.radians(lo_lat[i])))
        k = math.sqrt(dx * dx + dy * dy) / dh
        along[i] = k  # k for now
        if np.isfinite(k) and k > kmax:
            kmax = k
    if kmax < 0.0:
        kmax = 1.0  # no ray known at both ends: half a post per metre of height
    lo_step = span / max_levels
    for i in range(n):
        k = along[i]
        if not np.isfinite(k):
            k = kmax
        st = np.inf
        if res > 0 and k > 0:
            st = 0.5 * res / k
        st = min(max(st, lo_step), span)
        step[i] = st
        nlev[i] = int(math.ceil(span / st - 1e-9))
        along[i] = math.sqrt(1.0 + k * k)


def levels(lo_lon: np.ndarray, lo_lat: np.ndarray, hi_lon: np.ndarray, hi_lat: np.ndarray,
           dh: float, res: float, span: float,
           max_levels: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The scan's height step, level count and obliquity per ray (compiled, one pass).

    Parameters
    ----------
    lo_lon, lo_lat, hi_lon, hi_lat : ndarray, (N,)
        Each ray's ground position at two heights ``dh`` metres apart, degrees.
    dh : float
        Height between the two positions, metres.
    res : float
        DEM post spacing, metres (0: unknown).
    span : float
        Height interval scanned, metres.
    max_levels : int
        Cap on the levels per ray.

    Returns
    -------
    step : ndarray, (N,)
        ``0.5 * res / k`` (``k``: horizontal metres per metre of height; unknown rays take
        the largest known ``k``, or 1), clipped to ``[span / max_levels, span]``: successive
        samples at most half a post apart on the ground.
    nlev : ndarray of int64, (N,)
        ``ceil(span / step)`` intervals (levels ``0 .. nlev``).
    along : ndarray, (N,)
        ``sqrt(1 + k**2)``: metres along the ray per metre of height.
    """
    n = lo_lon.size
    step = np.empty(n)
    nlev = np.empty(n, np.int64)
    along = np.empty(n)
    if n:
        _nb_levels(np.ascontiguousarray(lo_lon, np.float64),
                   np.ascontiguousarray(lo_lat, np.float64),
                   np.ascontiguousarray(hi_lon, np.float64),
                   np.ascontiguousarray(hi_lat, np.float64), float(dh), float(res),
                   float(span), int(max_levels), step, nlev, along)
    return step, nlev, along


@numba.njit(nogil=True, cache=True)
def _nb_box(lon: np.ndarray, lat: np.ndarray, out: np.ndarray) -> int:  # pragma: no cover
    """Min/max of ``lon`` and ``lat`` over the points where both are finite, into ``out``
    (``lon_min, lon_max, lat_min, lat_max``); returns how many such points there are."""
    count = 0
    for i in range(lon.size):
        x = lon[i]
        y = lat[i]
        if not (np.isfinite(x) and np.isfinite(y)):
            continue
        if count == 0:
            out[0] = x
            out[1] = x
            out[2] = y
            out[3] = y
        else:
            out[0] = min(out[0], x)
            out[1] = max(out[1], x)
            out[2] = min(out[2], y)
            out[3] = max(out[3], y)
        count += 1
    return count


def box(pairs: list[tuple[np.ndarray, np.ndarray]]) -> tuple[float, float, float, float] | None:
    """``(lon_min, lon_max, lat_min, lat_max)`` of the points of ``pairs`` (lon, lat arrays)
    where both coordinates are finite (compiled, one pass); None when there is none."""
    acc: list[float] | None = None
    for lon, lat in pairs:
        out = np.empty(4)
        if _nb_box(np.ascontiguousarray(lon, np.float64).reshape(-1),
                   np.ascontiguousarray(lat, np.float64).reshape(-1), out):
            vals = [float(v) for v in out]
            acc = vals if acc is None else [min(acc[0], vals[0]), max(acc[1], vals[1]),
                                            min(acc[2], vals[2]), max(acc[3], vals[3])]
    return None if acc is None else (acc[0], acc[1], acc[2], acc[3])


def scan(window: RayWindow, nodes: np.ndarray, lon4: np.ndarray, lat4: np.ndarray,
         known: np.ndarray, top: np.ndarray, bottom: np.ndarray, step: np.ndarray,
         nlev: np.ndarray, tol: float,
         max_iter: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Scan approximate rays over ``window`` (compiled, threads over points).

    Parameters
    ----------
    window : RayWindow
    nodes : ndarray, (4,)
        Heights ``h0 < h1 < h2`` (metres) of the exact ray positions the quadratic goes
        through, and ``hq`` where it is checked.
    lon4, lat4 : ndarray, (4, N)
        Each ray's exact ground position at the four heights, degrees.
    known : ndarray of bool, (N,)
        Whether the four positions are known (the model backprojected them).
    top, bottom, step : ndarray, (N,)
        Scan levels ``top - j * step`` for ``j < nlev``, ``bottom`` at ``j = nlev`` (metres).
    nlev : ndarray of int64, (N,)
        Last level index.
    tol : float
        Tolerance of the refinement on the approximate ray, metres of ``|f|`` or bracket.
    max_iter : int
        Iteration cap of that refinement.

    Returns
    -------
    outcome : ndarray of uint8, (N,)
        :data:`NONE`, :data:`BRACKET`, :data:`UNSURE` or :data:`INELIGIBLE` (a node is
        unknown or the quadratic's error bound exceeds a quarter of a post).
    level : ndarray of int64, (N,)
        The first level not certainly above the terrain (``nlev + 1`` for ``NONE``).
    root, droot : ndarray, (N,)
        ``BRACKET``: the root of ``f`` on the approximate ray (metres) and ``f'`` there.
    refined : ndarray of uint8, (N,)
        ``BRACKET``: :data:`REFINED` or :data:`REFINE_CAP` (the cap was reached or the
        window had no height).
    """
    m = top.size
    outcome = np.empty(m, np.uint8)
    level = np.empty(m, np.int64)
    root = np.empty(m)
    droot = np.empty(m)
    refined = np.empty(m, np.uint8)
    if m:
        _nb_scan(np.ascontiguousarray(nodes, np.float64), np.ascontiguousarray(lon4),
                 np.ascontiguousarray(lat4), np.ascontiguousarray(known, np.bool_), top,
                 bottom, step, nlev.astype(np.int64), window.corrected, window.off_r,
                 window.off_c, window.inverse, window.west, window.rows, window.cols,
                 window.taps, _NO_GEOID, window.geoid_header, window.slope,
                 window.post_m, window.has_voids, window.geoid_err, float(tol),
                 int(max_iter), outcome, level,
                 root, droot, refined)
    return outcome, level, root, droot, refined


def scan_reference(window: RayWindow, nodes: np.ndarray, lon4: np.ndarray, lat4: np.ndarray,
                   known: np.ndarray, top: np.ndarray, bottom: np.ndarray, step: np.ndarray,
                   nlev: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """numpy reference of :func:`scan`'s ``outcome`` and ``level`` (tests only): the
    approximate rays sampled at every level with :func:`geoblock.dem.sampling.sample`, then
    the first level that is not certainly above the terrain."""
    from geoblock.dem.sampling import sample

    interp = {0: "nearest", 2: "bilinear", 4: "bicubic"}[window.taps]
    h0, h1, h2, hq = (float(v) for v in nodes)
    m = top.size
    outcome = np.full(m, INELIGIBLE, np.uint8)
    level = nlev + 1
    lon4 = lon4[1] + ((lon4 - lon4[1] + 180.0) % 360.0 - 180.0)
    wq = lagrange3(h0, h1, h2, hq)
    e_lon = (sum(w * v for w, v in zip(wq, lon4[:3], strict=True)) - lon4[3]) * np.cos(
        np.radians(lat4[3]))
    e_lat = sum(w * v for w, v in zip(wq, lat4[:3], strict=True)) - lat4[3]
    delta = 3.0 * math.radians(1.0) * 6378137.0 * np.hypot(e_lon, e_lat) + 1e-7
    posts = np.asarray(window.corrected, np.float64)
    lim_r, lim_c = window.rows - PIXEL_CENTRE, window.cols - PIXEL_CENTRE
    inv = window.inverse
    for i in range(m):
        if not (known[i] and delta[i] < 0.25 * window.post_m):
            continue
        outcome[i] = NONE
        js = np.arange(nlev[i] + 1)
        hs = np.where(js >= nlev[i], bottom[i], top[i] - js * step[i])
        w = lagrange3(h0, h1, h2, hs)
        lon = w[0] * lon4[0, i] + w[1] * lon4[1, i] + w[2] * lon4[2, i]
        lat = w[0] * lat4[0, i] + w[1] * lat4[1, i] + w[2] * lat4[2, i]
        x = window.west + (lon - window.west) % 360.0
        cc = inv[0] * x + inv[1] * lat + inv[2] - PIXEL_CENTRE
        rr = inv[3] * x + inv[4] * lat + inv[5] - PIXEL_CENTRE
        margin = delta[i] / window.post_m + 1e-9
        inside = (rr >= -0.5) & (rr <= lim_r) & (cc >= -0.5) & (cc <= lim_c)
        sure = ((rr - margin >= -0.5) & (rr + margin <= lim_r) & (cc - margin >= -0.5)
                & (cc + margin <= lim_c))

        def at(r: np.ndarray, c: np.ndarray) -> np.ndarray:
            return sample(posts, np.clip(r, 0, window.rows - 1) - window.off_r,
                          np.clip(c, 0, window.cols - 1) - window.off_c, interp)

        z = np.where(inside, at(rr, cc), np.nan)
        if window.has_voids:
            for sr in (-1, 1):
                for sc in (-1, 1):
                    sure &= np.isfinite(at(rr + sr * margin, cc + sc * margin))
        f = hs - z
        tau = window.slope * delta[i] + window.geoid_err + 1e-6
        above = sure & np.isfinite(f) & (f > tau)
        if above.all():
            continue
        k = int(np.argmin(above))
        level[i] = js[k]
        below = bool(sure[k]) and bool(np.isfinite(f[k])) and f[k] < -tau
        outcome[i] = BRACKET if (below and k > 0) else UNSURE
    return outcome, level
