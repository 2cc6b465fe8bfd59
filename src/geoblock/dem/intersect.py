"""Line-of-sight / DEM intersection for any sensor model: :func:`localize`.

Two methods, both generic (they only call ``model.backproject_with_status`` and
``dem.height_with_status``, vectorised over points):

``"robust"`` (default): bracket then refine.
    1. *Scan range.* The rays' footprint between the model's height range ends gives a
       ``(west, south, east, north)`` box; the DEM's ``height_range`` over that box (padded by
       two DEM posts), widened by a margin of ``1 m + 10 %`` of the relief, is the scanned
       height interval ``[bottom, top]``; repeated (up to 4 times) until the footprint of the
       interval is covered by the box it was computed from.
    2. *Step.* Each ray's horizontal displacement per metre of height ``k`` (metres per metre)
       comes from its two backprojections at ``top`` and ``bottom``; its height step is
       ``0.5 * dem.resolution_m / k`` (at most the whole interval, at most
       ``max_levels`` levels), so successive samples are at most half a DEM post apart on the
       ground.
    3. *Scan.* ``f(h) = h - dem(lon(h), lat(h))`` is evaluated from the top down, in slabs of
       levels for all unresolved points at once (at most ``max_evaluations`` backprojections
       per call, which bounds memory). The **first** level where ``f <= 0`` whose upper
       neighbour has ``f > 0`` brackets the first intersection seen from the sensor (the
       visible surface on cliffs, ridges and grazing rays).
    4. *Refine.* Illinois (modified regula falsi) inside the bracket, with a bisection step
       whenever an interpolated point leaves the bracket or the bracket has not halved in
       three iterations. Converged when the estimated distance *along the ray* to the root,
       ``|f| / f'(h) * sqrt(1 + k**2)``, and ``|f|`` are both at most ``tolerance_m``, or when
       the bracket itself is shorter than ``tolerance_m`` along the ray (a vertical step of a
       nearest-neighbour DEM).

    *Fast path.* When the DEM offers a window for the compiled scan (a
    :class:`~geoblock.dem.RasterDem` in a geographic CRS, not ``nearest``), steps 3 and 4 run
    first on approximate rays (:mod:`geoblock.dem._raycast`: the quadratic through three
    exact positions, its error bounded by a fourth, the DEM's geoid-corrected posts with a
    bound on the slope), at the same levels; only the levels it cannot decide for sure are
    scanned on the exact ray, and its roots are checked (and, if need be, refined) on the
    exact ray. Same statuses, same first crossing, same tolerance (``_FAST_SCAN = False``
    runs the exact scan alone: the reference path).

``"ray-tracing"``: the papers' iteration (Chen & Lee 1993; Teo et al. 2010, Fig. 2a):
    ``Z0 -> (lon, lat) = backproject(Z) -> Z' = dem(lon, lat) -> ...`` until
    ``|Z' - Z| <= tolerance_m``. It converges only where the terrain slope along the ray times
    the ray's obliquity is below 1 (``|slope * k| < 1``), and then to the intersection nearest
    its start, not necessarily the visible one. Kept as the reference method.

Missing heights (outside the DEM, voids, model failures) are "unknown" samples; see
:func:`localize` for what they mean for each point.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from geoblock._array import broadcast_float64, warn_status
from geoblock.dem import _raycast as raycast
from geoblock.dem._raycast import RayWindow
from geoblock.dem.base import DemBase
from geoblock.dem.filled import FilledDem
from geoblock.dem.protocol import Bounds, DemSource
from geoblock.errors import GeoblockError
from geoblock.typing import ArrayLike, GroundCoords, Status

if TYPE_CHECKING:
    from geoblock.io.dem import EngineDem
    from geoblock.models.protocol import SensorModel

__all__ = ["METHODS", "as_dem_source", "coverage_gap", "localize"]

METHODS = ("robust", "ray-tracing")

_OK = np.uint8(Status.CONVERGED)
_NO_DEM = np.uint8(Status.NO_DEM)
_NO_INTERSECTION = np.uint8(Status.NO_INTERSECTION)
_MAX_ITERATIONS = np.uint8(Status.MAX_ITERATIONS)
_DIVERGED = np.uint8(Status.DIVERGED)
_INVALID = np.uint8(Status.INVALID_INPUT)

# sample classes of the scan
_POS, _NEG, _UNK, _START, _PAD = 1, -1, 0, 2, 3

#: per point: lon, lat, h and the status (what the solvers return)
_Result = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]
#: per point: class, reason, a, f(a), b, f(b), lon and lat at b (what the scan returns)
_Scan = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray,
              np.ndarray, np.ndarray]

#: scan approximate rays first when the DEM offers a window (:mod:`geoblock.dem._raycast`);
#: False: the exact numpy scan alone (the reference path; tests and benchmarks)
_FAST_SCAN = True

#: points of the first guess of the scanned height range (then confirmed on all the points)
_RANGE_GUESS_POINTS = 2048

#: metres per degree of latitude (spherical approximation, for step sizes only)
_M_PER_DEG = math.radians(1.0) * 6378137.0


def localize(
    model: SensorModel,
    row: ArrayLike,
    col: ArrayLike,
    dem: EngineDem,
    *,
    method: str = "robust",
    tolerance_m: float = 1e-3,
    max_iterations: int | None = None,
    fill_height: float | None = None,
    h0: ArrayLike | None = None,
    max_levels: int = 20000,
    max_evaluations: int = 1 << 20,
    warn: bool = True,
) -> tuple[GroundCoords, np.ndarray]:
    """Intersect the lines of sight of image points with the terrain.

    Parameters
    ----------
    model : SensorModel
        Any sensor model; only ``backproject_with_status`` and ``height_range`` are used.
    row, col : array_like, (*S,)
        Image coordinates, pixels (pixel-centre convention: ``(0, 0)`` is the centre of the
        first pixel); broadcast together.
    dem : DemSource, float, or anything geoblock.open_dem opens
        Terrain heights above the WGS84 ellipsoid (:func:`geoblock.open_dem`,
        :class:`~geoblock.dem.GridDem`, ...); a number means a
        :class:`~geoblock.dem.ConstantDem`; a path, an open rasterio dataset or a
        georeferenced ``xarray.DataArray`` is opened by :func:`geoblock.open_dem` with its
        defaults (:func:`geoblock.io.dem.as_dem`).
    method : {"robust", "ray-tracing"}
        ``"robust"``: bracket the first intersection from the sensor by a scan of the line of
        sight, then refine (module docstring). ``"ray-tracing"``: the papers' fixed-point
        iteration ``Z -> XY -> Z'``.
    tolerance_m : float
        Metres. ``"robust"``: the returned point lies on the line of sight, at most
        ``tolerance_m`` vertically from the DEM surface and (estimated) at most
        ``tolerance_m`` along the ray from the intersection. ``"ray-tracing"``: stop when the
        height update ``|Z' - Z|`` is at most ``tolerance_m``.
    max_iterations : int, optional
        Iteration cap: of the refinement (default 60; bisection alone needs about 20 from a
        100 m bracket to 1 mm), or of the ray-tracing iteration (default 100).
    fill_height : float, optional
        Ellipsoidal height (metres) used wherever the DEM has none (outside its coverage,
        voids), as GDAL's ``RPC_DEM_MISSING_VALUE``. Default: such samples are unknown.
    h0 : array_like, optional
        ``"ray-tracing"`` only: starting height(s), metres; default the middle of the DEM's
        height range over the footprint.
    max_levels : int
        ``"robust"``: cap on the scan levels per ray (very oblique rays get a coarser step).
    max_evaluations : int
        ``"robust"``: at most this many backprojections per vectorised call during the scan
        (bounds memory: about 200 bytes each).
    warn : bool
        Emit one warning per failure status with its count (default), as
        :meth:`~geoblock.models.SensorModelBase.backproject` does.

    Returns
    -------
    GroundCoords
        ``lon, lat`` degrees and ``h`` metres above the ellipsoid, (*S,): the point of the
        line of sight at height ``h``. NaN where the status is not ``CONVERGED``.
    status : ndarray of uint8, (*S,)
        Per point :class:`~geoblock.typing.Status`:

        * ``CONVERGED``: found within the tolerance;
        * ``NO_INTERSECTION``: the line of sight stays above the terrain over the whole
          scanned height range (where the DEM has heights), or starts below it;
        * ``NO_DEM``: the DEM has no height where the answer is: the ray has no DEM height
          anywhere, crosses the terrain height inside a void or outside the coverage, or
          leaves the coverage before meeting the terrain. Samples without a height *above*
          the terrain are skipped: terrain outside the DEM is assumed not to hide the point;
        * ``MAX_ITERATIONS``: the iteration cap was reached (``"ray-tracing"`` oscillating
          or converging too slowly on steep slopes);
        * ``DIVERGED``: ``"ray-tracing"`` height updates grew three iterations in a row;
        * the model's own failure status (``OUT_OF_DOMAIN``, ...) when the model cannot
          backproject the point where it is needed;
        * ``INVALID_INPUT``: non-finite ``row`` or ``col`` (silently NaN).

    Raises
    ------
    GeoblockError
        Unknown ``method`` or invalid numeric options.

    Examples
    --------
    >>> import geoblock
    >>> from geoblock.testing.synthetic import AffineCamera
    >>> ground, status = geoblock.localize(AffineCamera.example(), 500, 600, 250.0)
    >>> round(float(ground.h), 6), int(status)
    (250.0, 0)
    """
    if method not in METHODS:
        raise GeoblockError(f"localize: method must be one of {METHODS}, got {method!r}")
    if not (tolerance_m > 0 and math.isfinite(tolerance_m)):
        raise GeoblockError(f"localize: tolerance_m must be positive, got {tolerance_m!r}")
    if max_iterations is not None and max_iterations < 1:
        raise GeoblockError(f"localize: max_iterations must be >= 1, got {max_iterations!r}")
    if fill_height is not None and not math.isfinite(float(fill_height)):
        raise GeoblockError(f"localize: fill_height must be finite, got {fill_height!r}")
    source = as_dem_source(dem)

    row, col = broadcast_float64(row=row, col=col)
    shape = row.shape
    r, c = row.ravel(), col.ravel()
    n = r.size
    lon = np.full(n, np.nan)
    lat = np.full(n, np.nan)
    h = np.full(n, np.nan)
    status = np.full(n, _INVALID, dtype=np.uint8)
    ok = np.flatnonzero(np.isfinite(r) & np.isfinite(c))
    if ok.size:
        if fill_height is not None:
            source = FilledDem(source, fill_height)
        ev = _Evaluator(model, source)
        if method == "robust":
            res = _robust(ev, r[ok], c[ok], tolerance_m, max_iterations or 60, max_levels,
                          max_evaluations)
        else:
            h_start = None
            if h0 is not None:
                h_start = np.broadcast_to(np.asarray(h0, np.float64), shape).ravel()[ok]
            res = _ray_tracing(ev, r[ok], c[ok], tolerance_m, max_iterations or 100, h_start)
        lon[ok], lat[ok], h[ok], status[ok] = res
    bad = status != _OK
    lon[bad] = lat[bad] = h[bad] = np.nan
    statuses = status.reshape(shape)
    if warn:
        warn_status(statuses, f"localize ({method})")
    return GroundCoords(lon.reshape(shape), lat.reshape(shape), h.reshape(shape)), statuses


def as_dem_source(dem: EngineDem) -> DemSource:
    """``dem`` as a :class:`DemSource`: itself when it is one, else
    :func:`geoblock.io.dem.as_dem` (a number, a path, an opened raster...).

    ``geoblock.io`` sits above the DEM service (it builds its classes): imported only when a
    DEM must be opened.
    """
    if isinstance(dem, DemBase):  # the common case, without the protocol's isinstance
        return dem
    from geoblock.io.dem import as_dem

    return as_dem(dem)


def coverage_gap(dem: DemSource, model: SensorModel) -> str | None:
    """Why ``dem`` cannot localise any of ``model``'s image, or None when it can.

    The model's footprint at the middle of its height range gives a ``(west, south, east,
    north)`` box; a DEM without a finite height over that box (outside it, or all nodata
    there) cannot place a ray of this image. For error messages: an empty ortho, images
    that seem not to overlap.

    Parameters
    ----------
    dem : DemSource
    model : SensorModel

    Returns
    -------
    str or None
        ``"the DEM has no valid height over the scene (lon ... to ..., lat ... to ...): it
        does not cover it or is all nodata there"``, ``"the model's footprint cannot be
        computed"``, or None.
    """
    from geoblock.models.base import image_outline

    lo, hi = (float(v) for v in model.height_range)
    mid = 0.5 * (lo + hi) if math.isfinite(lo) and math.isfinite(hi) else 0.0
    fp = image_outline(model, mid)
    box = _bbox([(np.asarray(fp.lon), np.asarray(fp.lat))], 0.0)
    if box is None:
        return "the model's footprint cannot be computed"
    dlo, dhi = (float(v) for v in dem.height_range(box))
    if math.isfinite(dlo) and math.isfinite(dhi):
        return None
    return (f"the DEM has no valid height over the scene (lon {box[0]:.6f} to {box[2]:.6f}, "
            f"lat {box[1]:.6f} to {box[3]:.6f}): it does not cover it or is all nodata there")


class _Evaluator:
    """``f(h) = h - dem(ray(h))`` for flat arrays of points, with the reason a sample fails."""

    def __init__(self, model: SensorModel, dem: DemSource) -> None:
        self.model = model
        self.dem = dem
        self.calls = 0

    def ground(self, row: np.ndarray, col: np.ndarray,
               h: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        (lon, lat, _), mstat = self.model.backproject_with_status(row, col, h)
        return lon, lat, np.asarray(mstat, np.uint8)

    def __call__(self, row: np.ndarray, col: np.ndarray, h: np.ndarray) -> _Result:
        """``(lon, lat, f, reason)``; ``reason`` is CONVERGED, NO_DEM or the model's status."""
        self.calls += 1
        lon, lat, mstat = self.ground(row, col, h)
        z, _ = self.dem.height_with_status(lon, lat)
        z = np.asarray(z, np.float64)
        f = h - z
        reason = np.where(mstat != _OK, mstat, np.where(np.isfinite(f), _OK, _NO_DEM))
        return lon, lat, f, reason.astype(np.uint8)

    def height_range(self, bounds: Bounds | None) -> tuple[float, float]:
        lo, hi = self.dem.height_range(bounds)
        if not (math.isfinite(lo) and math.isfinite(hi)):
            lo, hi = self.dem.height_range()
        return float(lo), float(hi)


def _resolution(dem: DemSource) -> float:
    res = float(getattr(dem, "resolution_m", 0.0) or 0.0)
    return res if math.isfinite(res) and res > 0 else 0.0


def _bbox(lon_lat: list[tuple[np.ndarray, np.ndarray]], pad_m: float) -> Bounds | None:
    """``(west, south, east, north)`` of the finite points, padded by ``pad_m`` metres.

    Longitudes are unwrapped around their circular mean first, so the box of a scene across
    the antimeridian is the narrow one (e.g. ``179.8`` to ``180.02``, ``east`` beyond 180),
    not the whole band from -180 to 180; DEM sources wrap the longitudes of a box into their
    own range (:data:`geoblock.dem.Bounds`).
    """
    pad_lat = pad_m / _M_PER_DEG
    found = raycast.box(lon_lat)  # one compiled pass: the common case, no unwrapping needed
    if found is None:
        return None
    w, e, s, n = found
    if w >= -180.0 and e <= 180.0 and e - w < 90.0:
        pad_lon = pad_lat / max(math.cos(math.radians(max(abs(s), abs(n)))), 1e-6)
        return (w - pad_lon, s - pad_lat, e + pad_lon, n + pad_lat)
    lon = np.concatenate([p[0] for p in lon_lat])
    lat = np.concatenate([p[1] for p in lon_lat])
    good = np.isfinite(lon) & np.isfinite(lat)
    lon, lat = lon[good], lat[good]
    rad = np.radians(lon)
    ref = math.degrees(math.atan2(float(np.mean(np.sin(rad))), float(np.mean(np.cos(rad)))))
    lon = ref + (lon - ref + 180.0) % 360.0 - 180.0
    pad_lon = pad_lat / max(math.cos(math.radians(float(np.max(np.abs(lat))))), 1e-6)
    return (float(lon.min() - pad_lon), float(lat.min() - pad_lat),
            float(lon.max() + pad_lon), float(lat.max() + pad_lat))


def _scan_range(ev: _Evaluator, row: np.ndarray, col: np.ndarray) -> tuple[float, float] | None:
    """``(bottom, top)`` heights that contain the terrain under all the rays, or None."""
    return _scan_range_nodes(ev, row, col)[0]


#: the rays' ground positions at two heights: ``(h_lo, h_hi, lon_lo, lat_lo, status_lo,
#: lon_hi, lat_hi, status_hi)``
_Nodes = tuple[float, float, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray,
               np.ndarray]


def _scan_range_nodes(ev: _Evaluator, row: np.ndarray,
                      col: np.ndarray) -> tuple[tuple[float, float] | None, _Nodes | None]:
    """:func:`_scan_range`, and the last backprojections it made (at two heights)."""
    pad = 2.0 * _resolution(ev.dem) + 1.0
    lo, hi = (float(v) for v in ev.model.height_range)
    result = None
    nodes = None
    n = row.size
    # the first pass on a subset of the points when there are many (the range is only a
    # guess until a pass over all the points confirms it: the loop ends only on those)
    sub = np.arange(0, n, max(1, n // _RANGE_GUESS_POINTS)) if n > 4 * _RANGE_GUESS_POINTS \
        else None
    for it in range(5):
        pick = sub if (it == 0 and sub is not None) else None
        r_, c_ = (row, col) if pick is None else (row[pick], col[pick])
        lon_lo, lat_lo, st_lo = ev.ground(r_, c_, np.full(r_.size, lo))
        lon_hi, lat_hi, st_hi = ev.ground(r_, c_, np.full(r_.size, hi))
        if pick is None:
            nodes = (lo, hi, lon_lo, lat_lo, st_lo, lon_hi, lat_hi, st_hi)
        box = _bbox([(lon_lo, lat_lo), (lon_hi, lat_hi)], pad)
        zmin, zmax = ev.height_range(box)
        if not (math.isfinite(zmin) and math.isfinite(zmax)):
            if pick is not None:
                continue  # the subset saw no DEM: ask all the points
            return result, nodes
        # (a guess from the subset gets twice the margin: the full box is a little larger)
        margin = (1.0 + 0.1 * (zmax - zmin)) * (1.0 if pick is None else 2.0)
        result = (zmin - margin, zmax + margin)
        if pick is None and box is not None and result[0] >= lo and result[1] <= hi:
            break
        lo, hi = result
    return result, nodes


def _robust(ev: _Evaluator, row: np.ndarray, col: np.ndarray, tol: float, max_iter: int,
            max_levels: int, max_evaluations: int, fast: bool | None = None) -> _Result:
    n = row.size
    lon = np.full(n, np.nan)
    lat = np.full(n, np.nan)
    h = np.full(n, np.nan)
    rng, nodes = _scan_range_nodes(ev, row, col)
    if rng is None:
        return lon, lat, h, np.full(n, _NO_DEM, np.uint8)
    bottom, top = rng
    status = np.full(n, _NO_INTERSECTION, np.uint8)

    # the rays at the ends of the range (the scan range's own nodes when they contain it)
    if nodes is not None and nodes[0] <= bottom and nodes[1] >= top:
        h_lo, h_hi, lo_lon, lo_lat, lo_st, hi_lon, hi_lat, hi_st = nodes
    else:
        h_lo, h_hi = bottom, top
        lo_lon, lo_lat, lo_st = ev.ground(row, col, np.full(n, bottom))
        hi_lon, hi_lat, hi_st = ev.ground(row, col, np.full(n, top))
    # per ray: the height step (half a DEM post on the ground), the intervals (levels
    # 0..nlev) and the metres along the ray per metre of height
    res = _resolution(ev.dem)
    span = top - bottom
    step, nlev, along = raycast.levels(lo_lon, lo_lat, hi_lon, hi_lat, h_hi - h_lo, res, span,
                                       max_levels)

    tops = np.full(n, top)
    bottoms = np.full(n, bottom)
    # per point: the level the exact scan starts at (negative: not scanned exactly)
    start: np.ndarray | None = None
    # brackets to refine on the exact ray: (points, a, f(a), b, f(b), lon and lat at b)
    brackets: list[tuple[np.ndarray, ...]] = []
    if _FAST_SCAN if fast is None else fast:
        window = _ray_window(ev, (lo_lon, lo_lat, hi_lon, hi_lat), res)
        if window is not None:
            ends = (h_lo, h_hi, lo_lon, lo_lat, lo_st, hi_lon, hi_lat, hi_st)
            start, acc, acc_lon, acc_lat, acc_h, certain = _fast_scan(
                ev, row, col, window, ends, tops, bottoms, step, nlev, along, tol, max_iter)
            lon[acc], lat[acc], h[acc] = acc_lon, acc_lat, acc_h
            status[acc] = _OK
            brackets.append(certain)
            # points found certainly above the terrain keep NO_INTERSECTION
    scan = np.arange(n) if start is None else np.flatnonzero(start >= 0)
    if scan.size:
        j0 = np.zeros(scan.size, np.int64) if start is None else start[scan]
        s_top = np.where(j0 > 0, tops[scan] - j0 * step[scan], tops[scan])
        outcome = _scan(ev, row[scan], col[scan], s_top, bottoms[scan], step[scan],
                        nlev[scan] - j0, max_evaluations)
        # rays whose top sample is already below the terrain: scan once more above the range
        redo = np.flatnonzero((outcome[0] == _START) & (j0 == 0))
        if redo.size:
            pts = scan[redo]
            extra = _scan(ev, row[pts], col[pts], np.full(redo.size, top + span),
                          np.full(redo.size, top), step[pts],
                          np.ceil(span / step[pts] - 1e-9).astype(np.int64), max_evaluations)
            for arr, new in zip(outcome, extra, strict=True):
                arr[redo] = new
        sc = outcome[0]
        status[scan] = np.where(sc == _NEG, _OK,
                                np.where((sc == _START) | (sc == _POS), _NO_INTERSECTION,
                                         outcome[1]))
        neg = sc == _NEG
        brackets.append((scan[neg], *(arr[neg] for arr in outcome[2:])))
    if brackets:
        pts, a, fa, b, fb, b_lon, b_lat = (np.concatenate(parts) for parts in zip(*brackets,
                                                                              strict=True))
        exact = fb == 0.0  # a level on the terrain
        pe = pts[exact]
        lon[pe], lat[pe], h[pe] = b_lon[exact], b_lat[exact], b[exact]
        status[pe] = _OK
        t = ~exact
        todo = pts[t]
        if todo.size:
            res_ = _illinois(ev, row[todo], col[todo], a[t], fa[t], b[t], fb[t], b_lon[t],
                             b_lat[t], along[todo], tol, max_iter)
            lon[todo], lat[todo], h[todo], status[todo] = res_
    return lon, lat, h, status


#: :func:`_fast_scan`'s ``start`` for points it resolved (or found above the terrain)
_RESOLVED, _NONE_LEFT = -1, -2


def _ray_window(ev: _Evaluator, ends: tuple[np.ndarray, ...], res: float) -> RayWindow | None:
    """The DEM's window for the compiled scan over the rays' footprint, when it offers one."""
    get = getattr(ev.dem, "_ray_window", None)
    if get is None or res <= 0:
        return None
    lo_lon, lo_lat, hi_lon, hi_lat = ends
    box = _bbox([(lo_lon, lo_lat), (hi_lon, hi_lat)], 2.0 * res + 1.0)
    if box is None:
        return None
    window = get(box)
    return window if isinstance(window, RayWindow) else None


def _fast_scan(ev: _Evaluator, row: np.ndarray, col: np.ndarray, window: RayWindow,
               ends: _Nodes, tops: np.ndarray, bottoms: np.ndarray, step: np.ndarray,
               nlev: np.ndarray, along: np.ndarray, tol: float,
               max_iter: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                       np.ndarray, tuple[np.ndarray, ...]]:
    """The scan on approximate rays (:mod:`geoblock.dem._raycast`), checked on the exact ray.

    Returns ``start`` (per point: the level the exact scan must start at, ``_RESOLVED`` when
    done here, ``_NONE_LEFT`` when the ray is certainly above the terrain over the range),
    the points converged here and their ``lon, lat, h``, and the certain brackets still to
    refine on the exact ray: ``(points, a, f(a), b, f(b), lon at b, lat at b)``.
    """
    n = row.size
    h_lo, h_hi, lo_lon, lo_lat, lo_st, hi_lon, hi_lat, hi_st = ends
    h_mid = 0.5 * (h_lo + h_hi)
    h_q = h_lo + 0.25 * (h_hi - h_lo)
    lon4 = np.empty((4, n))
    lat4 = np.empty((4, n))
    lon4[0], lat4[0], lon4[2], lat4[2] = lo_lon, lo_lat, hi_lon, hi_lat
    lon4[1], lat4[1], mid_st = ev.ground(row, col, np.full(n, h_mid))
    lon4[3], lat4[3], q_st = ev.ground(row, col, np.full(n, h_q))
    known = (lo_st == _OK) & (hi_st == _OK) & (mid_st == _OK) & (q_st == _OK)
    outcome, level, root, droot, refined = raycast.scan(
        window, np.array([h_lo, h_mid, h_hi, h_q]), lon4, lat4, known, tops, bottoms, step,
        nlev, 0.25 * tol, max_iter)
    # the exact scan starts at level 0 for the rays the approximation does not serve, and
    # from the level before the first doubtful one for the others; points certainly above
    # the terrain everywhere get no exact scan (NO_INTERSECTION, as the exact scan's _POS)
    start = np.zeros(n, np.int64)
    start[outcome == raycast.NONE] = _NONE_LEFT
    unsure = np.flatnonzero(outcome == raycast.UNSURE)
    start[unsure] = np.maximum(level[unsure] - 1, 0)
    # certain brackets: the exact ray at the approximate root, accepted when within tolerance
    pts = np.flatnonzero(outcome == raycast.BRACKET)
    start[pts] = _RESOLVED
    x = root[pts]
    good_root = np.isfinite(x) & (refined[pts] == raycast.REFINED)
    x_eval = np.where(good_root, x, 0.5 * (tops[pts] + bottoms[pts]))
    x_lon, x_lat, reason = ev.ground(row[pts], col[pts], x_eval)
    fx = x_eval - raycast.heights(window, x_lon, x_lat)
    with np.errstate(invalid="ignore", divide="ignore"):
        dist = np.abs(fx) / droot[pts] * along[pts]
        accept = (good_root & (reason == _OK) & (droot[pts] > 0) & np.isfinite(fx)
                  & (((np.abs(fx) <= tol) & (dist <= tol)) | (fx == 0)))
    acc = pts[accept]
    # the others: the exact Illinois in the certain bracket (levels j - 1 and j)
    rest = ~accept
    rp = pts[rest]
    j = level[rp]
    ha = tops[rp] - (j - 1) * step[rp]
    hb = np.where(j >= nlev[rp], bottoms[rp], tops[rp] - j * step[rp])
    m = rp.size
    e_lon, e_lat, e_f, e_reason = ev(np.tile(row[rp], 2), np.tile(col[rp], 2),
                                     np.concatenate([ha, hb]))
    sure = (e_reason[:m] == _OK) & (e_reason[m:] == _OK) & (e_f[:m] > 0) & (e_f[m:] <= 0)
    # a bracket the exact ray does not confirm (cannot happen within the bounds): rescan
    start[rp[~sure]] = np.maximum(j[~sure] - 1, 0)
    certain = (rp[sure], ha[sure], e_f[:m][sure], hb[sure], e_f[m:][sure], e_lon[m:][sure],
               e_lat[m:][sure])
    return start, acc, x_lon[accept], x_lat[accept], x_eval[accept], certain


def _scan(ev: _Evaluator, row: np.ndarray, col: np.ndarray, top: np.ndarray,
          bottom: np.ndarray, step: np.ndarray, nlev: np.ndarray, max_evaluations: int) -> _Scan:
    """Scan each ray from ``top`` down to ``bottom`` by ``step``; return per point:

    ``cls``: ``_NEG`` bracketed (between ``a`` above, ``f(a) = fa > 0``, and ``b`` below,
    ``fb <= 0``), ``_START`` the top sample is below the terrain, ``_POS`` the ray stays above
    the terrain to the bottom, ``_UNK`` failed with ``reason``.
    """
    n = row.size
    cls_out = np.full(n, _UNK, np.int8)
    reason_out = np.full(n, _NO_DEM, np.uint8)
    a = np.full(n, np.nan)
    fa = np.full(n, np.nan)
    b = np.full(n, np.nan)
    fb = np.full(n, np.nan)
    b_lon = np.full(n, np.nan)
    b_lat = np.full(n, np.nan)
    prev_cls = np.full(n, _START, np.int8)
    prev_reason = np.full(n, _NO_DEM, np.uint8)
    prev_h = np.full(n, np.nan)
    prev_f = np.full(n, np.nan)
    next_j = np.zeros(n, np.int64)
    active = np.arange(n)
    while active.size:
        remaining = nlev[active] + 1 - next_j[active]
        width = int(min(max(2, max_evaluations // active.size), remaining.max()))
        js = next_j[active][:, None] + np.arange(width)[None, :]  # (A, W)
        real = js <= nlev[active][:, None]
        hs = np.where(js >= nlev[active][:, None], bottom[active][:, None],
                      top[active][:, None] - js * step[active][:, None])
        rows = np.broadcast_to(row[active][:, None], js.shape)[real]
        cols = np.broadcast_to(col[active][:, None], js.shape)[real]
        s_lon = np.full(js.shape, np.nan)
        s_lat = np.full(js.shape, np.nan)
        s_f = np.full(js.shape, np.nan)
        s_reason = np.full(js.shape, _NO_DEM, np.uint8)
        s_lon[real], s_lat[real], s_f[real], s_reason[real] = ev(rows, cols, hs[real])
        cls = np.where(s_reason == _OK, np.where(s_f > 0, _POS, _NEG), _UNK).astype(np.int8)
        cls[~real] = _PAD
        # the class/reason/height/f of each sample's upper neighbour
        up_cls = np.concatenate([prev_cls[active][:, None], cls[:, :-1]], axis=1)
        up_reason = np.concatenate([prev_reason[active][:, None], s_reason[:, :-1]], axis=1)
        up_h = np.concatenate([prev_h[active][:, None], hs[:, :-1]], axis=1)
        up_f = np.concatenate([prev_f[active][:, None], s_f[:, :-1]], axis=1)
        isneg = cls == _NEG
        found = isneg.any(axis=1)
        j = np.argmax(isneg, axis=1)
        idx = np.arange(active.size)
        pts = active[found]
        jf, fi = j[found], idx[found]
        pc = up_cls[fi, jf]
        cls_out[pts] = np.where(pc == _POS, _NEG, np.where(pc == _START, _START, _UNK))
        reason_out[pts] = np.where(pc == _UNK, up_reason[fi, jf], _NO_DEM)
        a[pts], fa[pts] = up_h[fi, jf], up_f[fi, jf]
        b[pts], fb[pts] = hs[fi, jf], s_f[fi, jf]
        b_lon[pts], b_lat[pts] = s_lon[fi, jf], s_lat[fi, jf]
        # points that did not find the terrain: finished at the bottom, or continue
        nf = ~found
        last = np.where(real, np.arange(width)[None, :], -1).max(axis=1)  # last real column
        ended = nf & (js[idx, last] >= nlev[active])
        pts = active[ended]
        lc = cls[idx[ended], last[ended]]
        cls_out[pts] = np.where(lc == _POS, _POS, _UNK)
        reason_out[pts] = s_reason[idx[ended], last[ended]]
        cont = nf & ~ended
        pts = active[cont]
        ci, lcol = idx[cont], last[cont]
        prev_cls[pts] = cls[ci, lcol]
        prev_reason[pts] = s_reason[ci, lcol]
        prev_h[pts] = hs[ci, lcol]
        prev_f[pts] = s_f[ci, lcol]
        next_j[pts] += width
        active = pts
    return cls_out, reason_out, a, fa, b, fb, b_lon, b_lat


def _illinois(ev: _Evaluator, row: np.ndarray, col: np.ndarray, a: np.ndarray, fa: np.ndarray,
              b: np.ndarray, fb: np.ndarray, b_lon: np.ndarray, b_lat: np.ndarray,
              along: np.ndarray, tol: float, max_iter: int) -> _Result:
    """Refine brackets ``a > b`` (``f(a) > 0 >= f(b)``) to the root of ``f``."""
    n = row.size
    lon = b_lon.copy()
    lat = b_lat.copy()
    h = b.copy()
    status = np.full(n, _MAX_ITERATIONS, np.uint8)
    ga, gb = fa.copy(), fb.copy()  # Illinois-weighted values
    side = np.zeros(n, np.int8)  # +1: a moved last, -1: b moved last
    width_ref = a - b
    since = np.zeros(n, np.int64)
    active = np.arange(n)
    for _ in range(max_iter):
        if active.size == 0:
            break
        A, B, GA, GB = a[active], b[active], ga[active], gb[active]
        with np.errstate(invalid="ignore", divide="ignore"):
            x = A - GA * (B - A) / (GB - GA)
        bisect = ~((x < A) & (x > B)) | (since[active] >= 3)
        x = np.where(bisect, 0.5 * (A + B), x)
        x_lon, x_lat, fx, reason = ev(row[active], col[active], x)
        failed = reason != _OK
        status[active[failed]] = reason[failed]
        keep = ~failed
        act, x, fx, x_lon, x_lat = active[keep], x[keep], fx[keep], x_lon[keep], x_lat[keep]
        bis = bisect[keep]
        # convergence: distance along the ray to the root, from the bracket's secant slope
        with np.errstate(invalid="ignore", divide="ignore"):
            slope = (fa[act] - fb[act]) / (a[act] - b[act])
            dist = np.abs(fx) / slope * along[act]
        upper = fx > 0
        # update the bracket (Illinois: halve the value of an end kept twice in a row)
        ia, ib = act[upper], act[~upper]
        gb[ia] = np.where(side[ia] == 1, 0.5 * gb[ia], gb[ia])
        a[ia], fa[ia], ga[ia] = x[upper], fx[upper], fx[upper]
        side[ia] = 1
        ga[ib] = np.where(side[ib] == -1, 0.5 * ga[ib], ga[ib])
        b[ib], fb[ib], gb[ib] = x[~upper], fx[~upper], fx[~upper]
        side[ib] = -1
        w = a[act] - b[act]
        halved = (w <= 0.5 * width_ref[act]) | bis
        width_ref[act] = np.where(halved, w, width_ref[act])
        since[act] = np.where(halved, 0, since[act] + 1)
        done = ((np.abs(fx) <= tol) & (dist <= tol)) | (fx == 0) | (w * along[act] <= tol)
        pts = act[done]
        lon[pts], lat[pts], h[pts] = x_lon[done], x_lat[done], x[done]
        status[pts] = _OK
        active = act[~done]
    return lon, lat, h, status


def _ray_tracing(ev: _Evaluator, row: np.ndarray, col: np.ndarray, tol: float, max_iter: int,
                 h_start: np.ndarray | None) -> _Result:
    """Chen & Lee / Teo et al.: ``Z -> (lon, lat) = backproject(Z) -> Z' = dem(lon, lat)``."""
    n = row.size
    lon = np.full(n, np.nan)
    lat = np.full(n, np.nan)
    h = np.full(n, np.nan)
    status = np.full(n, _MAX_ITERATIONS, np.uint8)
    if h_start is None:
        rng = _scan_range(ev, row, col)
        if rng is None:
            return lon, lat, h, np.full(n, _NO_DEM, np.uint8)
        z = np.full(n, 0.5 * (rng[0] + rng[1]))
    else:
        z = np.array(h_start, np.float64)
    prev = np.full(n, np.inf)
    growth = np.zeros(n, np.int64)
    active = np.flatnonzero(np.isfinite(z))
    status[~np.isfinite(z)] = _INVALID
    for _ in range(max_iter):
        if active.size == 0:
            break
        za = z[active]
        x_lon, x_lat, f, reason = ev(row[active], col[active], za)
        failed = reason != _OK
        status[active[failed]] = reason[failed]
        keep = ~failed
        act, za, f = active[keep], za[keep], f[keep]
        x_lon, x_lat = x_lon[keep], x_lat[keep]
        dz = np.abs(f)  # |Z' - Z| with Z' = dem(XY(Z)) = Z - f
        done = dz <= tol
        pts = act[done]
        lon[pts], lat[pts], h[pts] = x_lon[done], x_lat[done], za[done]
        status[pts] = _OK
        grew = dz > prev[act]
        growth[act] = np.where(grew, growth[act] + 1, 0)
        prev[act] = dz
        div = ~done & (growth[act] >= 3)
        status[act[div]] = _DIVERGED
        cont = ~done & ~div
        z[act[cont]] = za[cont] - f[cont]
        active = act[cont]
    return lon, lat, h, status
