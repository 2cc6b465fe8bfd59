"""Simulated GCPs, ICPs, TPs and ICTPs over a set of images, with their true values kept.

:func:`simulate_points` places

* **GCPs** and **ICPs** (ground control and independent check points) per image, by a random
  or a stratified random design over an ``n x n`` grid of the image (Aguilar et al.: one GCP
  per cell of a 3 x 3 grid; their 45 GCPs: five per cell);
* **TPs** and **ICTPs** (tie points and independent check tie points) in the overlap of each
  pair of images (Teo et al.: strips overlapping by 10-15 %, 13-32 TPs per overlap).

It is a composition of smaller steps, each public so that other designs can be built from
them (all draws come from one :class:`numpy.random.Generator`, in this order):

1. :func:`candidate_positions`: image positions drawn by a design (random, or stratified
   over ``cells x cells`` cells), several per point wanted;
2. :func:`ground_candidates`: their lines of sight intersected with the true terrain through
   the TRUE model (:func:`geoblock.localize`: heights above the ellipsoid, whatever the
   DEM's own datum), the first usable ones of each cell kept;
   for tie points, :func:`overlap_window` and :func:`overlap_points` do the same in the
   overlap of two images, keeping the points the second image sees;
3. :func:`point_ids`: ``gcp0001``, ``tp0001``... per kind;
4. :func:`measure_points`: each ground point projected into every image through the true
   models, a measurement kept where it falls inside the image and is not hidden by the
   terrain;
5. :func:`pointing_noise` on the measurements (``sigma_px`` on row and col, optional
   blunders) and :func:`survey_noise` on the ground coordinates of GCPs and ICPs
   (``sigma_e, sigma_n, sigma_h`` metres, optional horizontal blunders).

Every noisy value keeps its true value beside it, so that accuracy statistics are exact.

Files (:meth:`PointSet.write`, through :func:`geoblock.io.write_points`): the ground CSV and
the image-measurement CSV of ARCHITECTURE.md section 7 (read by
:func:`geoblock.io.read_points`) and a truth CSV.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from geoblock import coords
from geoblock.adjust.observations import KINDS, GroundPoints, ImagePoints
from geoblock.dem.intersect import localize
from geoblock.errors import GeoblockError
from geoblock.pixels import image_domain
from geoblock.typing import GroundCoords, Status

__all__ = [
    "KINDS",
    "CandidatePositions",
    "Measurements",
    "PointSet",
    "SimulatedGround",
    "SimulatedMeasurements",
    "candidate_positions",
    "ground_candidates",
    "measure_points",
    "overlap_points",
    "overlap_window",
    "point_ids",
    "pointing_noise",
    "simulate_points",
    "survey_noise",
]

Rng = int | np.random.Generator | None
"""A seed or a generator: ``numpy.random.default_rng(rng)`` (a generator is used as is, so
that steps sharing one draw from it in turn)."""

#: pointing sigma (pixels) given to the measurements of a noise-free simulation by
#: :meth:`PointSet.observations`
NOISE_FREE_SIGMA_PX = 1e-3

_VISIBLE_M = 1.0  # a ray that meets the terrain farther than this from the point: hidden


def _frozen(a: Any, dtype: Any) -> np.ndarray:
    out = np.array(a, dtype=dtype)
    out.flags.writeable = False
    return out


@dataclass(frozen=True, eq=False)
class SimulatedGround:
    """One row per point (every kind), with its true and its surveyed ground coordinates.

    Attributes
    ----------
    id, kind : ndarray of str, (N,)
        Point identifier and kind (``gcp``, ``icp``, ``tp``, ``ictp``).
    lon_true, lat_true, h_true : ndarray, (N,)
        True position on the true terrain: degrees and metres above the WGS84 ellipsoid.
    lon, lat, h : ndarray, (N,)
        Surveyed position (truth + survey noise + blunder); NaN for TPs and ICTPs, which have
        no ground coordinates.
    sigma_e, sigma_n, sigma_h : ndarray, (N,)
        Survey noise standard deviations, metres; NaN for TPs and ICTPs.
    blunder : ndarray of bool, (N,)
        Whether a ground blunder was added.
    """

    id: np.ndarray
    kind: np.ndarray
    lon_true: np.ndarray
    lat_true: np.ndarray
    h_true: np.ndarray
    lon: np.ndarray
    lat: np.ndarray
    h: np.ndarray
    sigma_e: np.ndarray
    sigma_n: np.ndarray
    sigma_h: np.ndarray
    blunder: np.ndarray

    def __post_init__(self) -> None:
        for name in ("id", "kind"):
            object.__setattr__(self, name, _frozen(getattr(self, name), str))
        for name in ("lon_true", "lat_true", "h_true", "lon", "lat", "h", "sigma_e", "sigma_n",
                     "sigma_h"):
            object.__setattr__(self, name, _frozen(getattr(self, name), np.float64))
        object.__setattr__(self, "blunder", _frozen(self.blunder, bool))

    def __len__(self) -> int:
        return int(self.id.size)


@dataclass(frozen=True, eq=False)
class SimulatedMeasurements:
    """One row per measurement of a point in an image.

    Attributes
    ----------
    id, image, kind : ndarray of str, (M,)
        Point identifier, image name, point kind.
    row_true, col_true : ndarray, (M,)
        The true model's projection of the true ground point, pixels.
    row, col : ndarray, (M,)
        Measured (truth + pointing noise + blunder), pixels.
    sigma : ndarray, (M,)
        Pointing noise standard deviation, pixels (on row and on col).
    blunder : ndarray of bool, (M,)
    """

    id: np.ndarray
    image: np.ndarray
    kind: np.ndarray
    row_true: np.ndarray
    col_true: np.ndarray
    row: np.ndarray
    col: np.ndarray
    sigma: np.ndarray
    blunder: np.ndarray

    def __post_init__(self) -> None:
        for name in ("id", "image", "kind"):
            object.__setattr__(self, name, _frozen(getattr(self, name), str))
        for name in ("row_true", "col_true", "row", "col", "sigma"):
            object.__setattr__(self, name, _frozen(getattr(self, name), np.float64))
        object.__setattr__(self, "blunder", _frozen(self.blunder, bool))

    def __len__(self) -> int:
        return int(self.id.size)


@dataclass(frozen=True, eq=False)
class PointSet:
    """Simulated points: :class:`SimulatedGround`, :class:`SimulatedMeasurements` and the image
    names.

    Attributes
    ----------
    ground : SimulatedGround
    image : SimulatedMeasurements
    images : tuple of str
        Image names, in the order the models were given.
    """

    ground: SimulatedGround
    image: SimulatedMeasurements
    images: tuple[str, ...]

    def count(self, kind: str) -> int:
        """Number of points of a kind (``gcp``, ``icp``, ``tp``, ``ictp``)."""
        return int(np.count_nonzero(self.ground.kind == kind))

    def observations(self) -> tuple[GroundPoints, ImagePoints]:
        """What a user would be given, as the block engine's tables: the surveyed GCPs and
        ICPs (:class:`geoblock.adjust.GroundPoints`) and the noisy measurements of every kind
        (:class:`geoblock.adjust.ImagePoints`); no truth. A noise-free simulation's pointing
        sigma of 0 becomes :data:`NOISE_FREE_SIGMA_PX` (measurement sigmas must be > 0)."""
        g, m = self.ground, self.image
        keep = np.isin(g.kind, ("gcp", "icp"))
        ground = GroundPoints(g.id[keep], g.kind[keep], g.lon[keep], g.lat[keep], g.h[keep],
                              g.sigma_e[keep], g.sigma_n[keep], g.sigma_h[keep])
        sigma = np.where(m.sigma > 0, m.sigma, NOISE_FREE_SIGMA_PX)
        return ground, ImagePoints(m.id, m.image, m.row, m.col, sigma, sigma, m.kind)

    def ground_columns(self) -> dict[str, np.ndarray]:
        """Columns of the ground-point file: GCPs and ICPs, ``id, lon, lat, h, sigma_e,
        sigma_n, sigma_h, kind`` (ARCHITECTURE.md section 7)."""
        g = self.ground
        keep = np.isin(g.kind, ("gcp", "icp"))
        return {"id": g.id[keep], "lon": g.lon[keep], "lat": g.lat[keep], "h": g.h[keep],
                "sigma_e": g.sigma_e[keep], "sigma_n": g.sigma_n[keep],
                "sigma_h": g.sigma_h[keep], "kind": g.kind[keep]}

    def image_columns(self) -> dict[str, np.ndarray]:
        """Columns of the image-measurement file: ``id, image, row, col, sigma, kind`` (every
        kind; ``kind`` tells TPs from ICTPs, which have no ground coordinates)."""
        m = self.image
        return {"id": m.id, "image": m.image, "row": m.row, "col": m.col, "sigma": m.sigma,
                "kind": m.kind}

    def truth_columns(self) -> dict[str, np.ndarray]:
        """Columns of the truth file: one row per measurement, with the true and the measured
        image coordinates and the true and the surveyed ground coordinates of its point."""
        g, m = self.ground, self.image
        index = {pid: i for i, pid in enumerate(g.id.tolist())}
        k = np.array([index[p] for p in m.id.tolist()], dtype=np.intp)
        return {
            "id": m.id, "kind": m.kind, "image": m.image,
            "row_true": m.row_true, "col_true": m.col_true, "row": m.row, "col": m.col,
            "sigma": m.sigma, "blunder": m.blunder.astype(np.int64),
            "lon_true": g.lon_true[k], "lat_true": g.lat_true[k], "h_true": g.h_true[k],
            "lon": g.lon[k], "lat": g.lat[k], "h": g.h[k],
            "sigma_e": g.sigma_e[k], "sigma_n": g.sigma_n[k], "sigma_h": g.sigma_h[k],
            "ground_blunder": g.blunder[k].astype(np.int64),
        }

    def write(self, directory: str | os.PathLike[str], prefix: str = "") -> dict[str, Path]:
        """Write ``{prefix}ground.csv``, ``{prefix}image.csv`` and ``{prefix}truth.csv``.

        Returns
        -------
        dict
            ``{"ground": path, "image": path, "truth": path}``.
        """
        from geoblock.io.points import write_points

        directory = Path(directory)
        paths = {name: directory / f"{prefix}{name}.csv" for name in ("ground", "image", "truth")}
        write_points(paths["ground"], self.ground_columns())
        write_points(paths["image"], self.image_columns())
        write_points(paths["truth"], self.truth_columns())
        return paths


# ---------------------------------------------------------------------------- helpers
def _as_dem(dem: Any) -> Any:
    """A DEM source from a DemSource, a :class:`~geoblock.simulate.terrain.Terrain` or a
    constant height above the ellipsoid."""
    from geoblock.simulate.terrain import Terrain

    if isinstance(dem, Terrain):
        return dem.to_dem()
    if isinstance(dem, int | float):
        from geoblock.dem.constant import ConstantDem

        return ConstantDem(float(dem))
    return dem


def _project(model: Any, lon: np.ndarray, lat: np.ndarray,
             h: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``row, col, ok`` through any model (``project_with_status`` when it has one)."""
    if hasattr(model, "project_with_status"):
        (row, col), status = model.project_with_status(lon, lat, h)
        ok = status == Status.CONVERGED
    else:  # pragma: no cover - every geoblock model has project_with_status
        import warnings

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            row, col = model.project(lon, lat, h)
        ok = np.isfinite(row) & np.isfinite(col)
    return np.asarray(row, float), np.asarray(col, float), ok & np.isfinite(row) & np.isfinite(col)


def _inner_domain(shape: tuple[int, int], margin: float) -> tuple[float, float, float, float]:
    """``(r0, r1, c0, c1)``: the image domain (:func:`geoblock.pixels.image_domain`) shrunk by
    ``margin`` pixels on every side."""
    r0, c0, r1, c1 = image_domain(shape)
    return r0 + margin, r1 - margin, c0 + margin, c1 - margin


def _inside(model: Any, row: np.ndarray, col: np.ndarray, margin: float = 0.0) -> np.ndarray:
    r0, r1, c0, c1 = _inner_domain(model.shape, margin)
    return (row >= r0) & (row < r1) & (col >= c0) & (col < c1)


def _localize(model: Any, row: np.ndarray, col: np.ndarray,
              dem: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    ground, status = localize(model, row, col, dem, warn=False)
    return ground.lon, ground.lat, ground.h, status == Status.CONVERGED


def _visible(model: Any, row: np.ndarray, col: np.ndarray, dem: Any, lon: np.ndarray,
             lat: np.ndarray, h: np.ndarray) -> np.ndarray:
    """Whether the line of sight of ``(row, col)`` meets the terrain at the point (not before)."""
    if row.size == 0:
        return np.zeros(0, bool)
    glon, glat, gh, ok = _localize(model, row, col, dem)
    a = np.stack(coords.geodetic_to_ecef(glon, glat, gh), axis=-1)
    b = np.stack(coords.geodetic_to_ecef(lon, lat, h), axis=-1)
    with np.errstate(invalid="ignore"):
        return ok & (np.linalg.norm(a - b, axis=-1) <= _VISIBLE_M)


def _count(rng: np.random.Generator, spec: int | tuple[int, int], name: str) -> int:
    if isinstance(spec, tuple | list):
        lo, hi = (int(v) for v in spec)
        if not 0 <= lo <= hi:
            raise GeoblockError(f"simulate_points: {name} range must be 0 <= low <= high, "
                                f"got {spec}")
        return int(rng.integers(lo, hi + 1))
    if int(spec) < 0:
        raise GeoblockError(f"simulate_points: {name} must be >= 0, got {spec}")
    return int(spec)


def _check_sigma(where: str, **values: float) -> None:
    for name, value in values.items():
        if not (math.isfinite(value) and value >= 0):
            raise GeoblockError(f"{where}: {name} must be a finite number >= 0, got {value}")


def _check_fraction(where: str, **values: float) -> None:
    for name, value in values.items():
        if not 0.0 <= value <= 1.0:
            raise GeoblockError(f"{where}: {name} must be in [0, 1], got {value}")


# ---------------------------------------------------------------------------- steps
class CandidatePositions(NamedTuple):
    """Candidate image positions of a design (:func:`candidate_positions`).

    Attributes
    ----------
    row, col : ndarray, (K,)
        Image positions, pixels (pixel-centre convention), in drawing order.
    cell : ndarray of int, (K,)
        The cell of each (row-major in the ``cells x cells`` grid); -1 for the random design.
    wanted : dict of int to int
        Points wanted per cell (``{-1: count}`` for the random design).
    """

    row: np.ndarray
    col: np.ndarray
    cell: np.ndarray
    wanted: dict[int, int]


def candidate_positions(
    shape: tuple[int, int],
    count: int,
    *,
    design: str = "stratified",
    cells: int = 3,
    margin_px: float = 10.0,
    rng: Rng = None,
    factor: int = 4,
) -> CandidatePositions:
    """Candidate image positions for ``count`` points of an image of ``shape`` by a design.

    ``"random"``: ``factor * count + 8`` positions uniform over the image. ``"stratified"``:
    the image is cut into ``cells x cells`` equal cells, each wanting ``count // cells**2``
    points (the remainder goes to randomly chosen cells), with ``factor`` times the largest
    number wanted (plus 4) positions uniform in every cell. The spare candidates stand in for
    those whose line of sight misses the terrain (:func:`ground_candidates`).

    Parameters
    ----------
    shape : (int, int)
        ``(rows, cols)`` of the image, pixels.
    count : int
        Points wanted.
    design : {"stratified", "random"}
    cells : int
        Cells per side of the stratified design.
    margin_px : float
        Positions are drawn at least this far inside the image edges, pixels.
    rng : int, numpy.random.Generator or None
        The draws' source (a generator is advanced).
    factor : int
        Candidates per point wanted.

    Returns
    -------
    CandidatePositions

    Raises
    ------
    GeoblockError
        The margin leaves no room in the image, or an unknown design.
    """
    if design not in ("stratified", "random"):
        raise GeoblockError(f"candidate_positions: design must be 'stratified' or 'random', "
                            f"got {design!r}")
    rng = np.random.default_rng(rng)
    rows, cols = shape
    r0, r1, c0, c1 = _inner_domain(shape, margin_px)
    if r1 <= r0 or c1 <= c0:
        raise GeoblockError(f"simulate_points: a margin of {margin_px} px leaves no room in an "
                            f"image of {rows} x {cols} px")
    if design == "random":
        n = factor * count + 8
        return CandidatePositions(rng.uniform(r0, r1, n), rng.uniform(c0, c1, n),
                                  np.full(n, -1), {-1: count})
    ncell = cells * cells
    wanted = np.full(ncell, count // ncell)
    extra = rng.permutation(ncell)[: count % ncell]
    wanted[extra] += 1
    per = factor * int(wanted.max()) + 4
    cell = np.repeat(np.arange(ncell), per)
    ci, cj = cell // cells, cell % cells
    u, v = rng.uniform(size=cell.size), rng.uniform(size=cell.size)
    row = r0 + (ci + u) * (r1 - r0) / cells
    col = c0 + (cj + v) * (c1 - c0) / cells
    return CandidatePositions(row, col, cell, dict(enumerate(wanted.tolist())))


def ground_candidates(model: Any, dem: Any, candidates: CandidatePositions, *,
                      what: str = "points") -> GroundCoords:
    """The ground points of the first usable candidates of each cell, in drawing order.

    Each candidate's line of sight through ``model`` is intersected with ``dem``
    (:func:`geoblock.localize`); a candidate is usable where it converges.

    Parameters
    ----------
    model : SensorModel
        The image's TRUE model.
    dem : DemSource, Terrain or float
        The TRUE terrain (a number: a constant height above the ellipsoid).
    candidates : CandidatePositions
    what : str
        The points' description in the error message (``"GCPs of image 'strip1'"``).

    Returns
    -------
    GroundCoords
        ``lon, lat`` degrees and ``h`` metres above the ellipsoid, ``(sum(wanted),)``, cell
        by cell.

    Raises
    ------
    GeoblockError
        A cell has fewer usable candidates than wanted (the DEM does not cover the image).
    """
    lon, lat, h, ok = _localize(model, candidates.row, candidates.col, _as_dem(dem))
    chosen = []
    for c, n in candidates.wanted.items():  # a loop over the (few) cells, not over points
        idx = np.flatnonzero(ok & (candidates.cell == c))
        if idx.size < n:
            where = "" if c < 0 else f" in cell {c} (row-major)"
            raise GeoblockError(f"simulate_points: found {idx.size} of the {n} {what}{where}: "
                                "the true DEM must cover the image (lines of sight meet no "
                                "terrain)")
        chosen.append(idx[:n])
    k = np.concatenate(chosen) if chosen else np.zeros(0, np.intp)
    return GroundCoords(lon[k], lat[k], h[k])


def overlap_window(
    model: Any,
    other: Any,
    heights: tuple[float, float],
    *,
    margin_px: float = 10.0,
    min_overlap: float = 0.0,
) -> tuple[float, float, float, float] | None:
    """The box of image ``model`` that ``other`` overlaps: ``(r0, r1, c0, c1)``, pixels.

    The bounding box in ``model`` of ``other``'s footprint at the two heights, inside
    ``model``'s image by ``margin_px``; None when they do not overlap, or when the box
    covers less than ``min_overlap`` of ``model``'s image.

    Parameters
    ----------
    model, other : SensorModel
        The two images' TRUE models (``footprint``, ``project`` and ``shape`` are used).
    heights : (float, float)
        Lowest and highest terrain heights above the ellipsoid, metres.
    margin_px : float
    min_overlap : float
        Fraction of ``model``'s image area.
    """
    rows, cols = model.shape
    lon, lat, h = [], [], []
    for hh in heights:
        fp = other.footprint(h=hh, n=16)
        lon.append(fp.lon)
        lat.append(fp.lat)
        h.append(np.full(fp.lon.shape, hh))
    r, c, ok = _project(model, np.concatenate(lon), np.concatenate(lat), np.concatenate(h))
    if not ok.any():
        return None
    lo_r, hi_r, lo_c, hi_c = _inner_domain(model.shape, margin_px)
    r0 = max(lo_r, float(r[ok].min()))
    r1 = min(hi_r, float(r[ok].max()))
    c0 = max(lo_c, float(c[ok].min()))
    c1 = min(hi_c, float(c[ok].max()))
    if r1 <= r0 or c1 <= c0:
        return None
    if (r1 - r0) * (c1 - c0) < min_overlap * rows * cols:
        return None
    return r0, r1, c0, c1


def overlap_points(
    model: Any,
    other: Any,
    dem: Any,
    count: int,
    window: tuple[float, float, float, float],
    *,
    margin_px: float = 10.0,
    rng: Rng = None,
    what: str = "the two images",
) -> GroundCoords:
    """``count`` ground points in the overlap of two images, seen by both.

    Image positions are drawn uniformly in ``window`` of ``model`` (:func:`overlap_window`),
    grounded through ``model`` on ``dem``, and kept where they project inside ``other`` (by
    ``margin_px``) and are not hidden from it by the terrain; ``8 * count + 16`` positions
    are drawn, then ``64 * count + 16`` if too few are kept.

    Parameters
    ----------
    model, other : SensorModel
        The TRUE models of the image the points are drawn in and of the other image.
    dem : DemSource, Terrain or float
        The TRUE terrain.
    count : int
    window : (float, float, float, float)
        ``(r0, r1, c0, c1)`` in ``model``'s image, pixels.
    margin_px : float
    rng : int, numpy.random.Generator or None
    what : str
        The pair's description in the error message.

    Returns
    -------
    GroundCoords
        ``(count,)`` each.

    Raises
    ------
    GeoblockError
        Fewer than ``count`` points could be placed.
    """
    if count <= 0:
        empty = np.zeros(0)
        return GroundCoords(empty, empty.copy(), empty.copy())
    rng = np.random.default_rng(rng)
    dem = _as_dem(dem)
    r0, r1, c0, c1 = window
    found = np.zeros(0, np.intp)
    lon = lat = h = np.zeros(0)
    for factor in (8, 64):
        n = factor * count + 16
        row, col = rng.uniform(r0, r1, n), rng.uniform(c0, c1, n)
        lon, lat, h, ok = _localize(model, row, col, dem)
        rj, cj, okj = _project(other, lon, lat, h)
        ok &= okj & _inside(other, rj, cj, margin_px)
        idx = np.flatnonzero(ok)
        vis = _visible(other, rj[idx], cj[idx], dem, lon[idx], lat[idx], h[idx])
        found = idx[vis]
        if found.size >= count:
            break
    if found.size < count:
        raise GeoblockError(f"simulate_points: only {found.size} of the {count} tie points "
                            f"wanted could be placed in the overlap of {what}")
    k = found[:count]
    return GroundCoords(lon[k], lat[k], h[k])


def point_ids(kind: np.ndarray) -> np.ndarray:
    """Point identifiers ``<kind><number>``, numbered from 1 within each kind in order
    (``gcp0001``, ``gcp0002``, ..., ``tp0001``...), ``(N,)`` str."""
    kind = np.asarray(kind, dtype=str)
    ids = np.empty(kind.size, dtype=object)
    for kd in np.unique(kind).tolist():
        sel = np.flatnonzero(kind == kd)
        ids[sel] = [f"{kd}{k + 1:04d}" for k in range(sel.size)]
    return ids.astype(str)


class Measurements(NamedTuple):
    """Where each image sees the points (:func:`measure_points`), one row per measurement.

    Attributes
    ----------
    point : ndarray of int, (M,)
        Index of the measured point.
    image : ndarray of str, (M,)
        Image name.
    row, col : ndarray, (M,)
        The true model's projection of the point, pixels.
    """

    point: np.ndarray
    image: np.ndarray
    row: np.ndarray
    col: np.ndarray


def measure_points(
    models: Mapping[str, Any],
    ground: GroundCoords,
    dem: Any,
    home: np.ndarray | None = None,
) -> Measurements:
    """The measurements of ground points in every image that sees them.

    A point is measured in an image where its projection through the image's TRUE model
    falls inside the image and the line of sight there meets the terrain at the point (not
    hidden by a ridge; checked by ray tracing on ``dem``). In a point's ``home`` image (where
    it was drawn and grounded) it is visible by construction and not traced again.

    Parameters
    ----------
    models : mapping of str to SensorModel
        The TRUE models by image name.
    ground : GroundCoords
        ``(N,)`` true ground points.
    dem : DemSource, Terrain or float
        The TRUE terrain.
    home : ndarray of int, (N,), optional
        Index (in ``models``' order) of each point's home image; -1 (or None: for every
        point) for none.

    Returns
    -------
    Measurements
        Sorted by point, then by image in ``models``' order.
    """
    dem = _as_dem(dem)
    lon, lat, h = (np.asarray(v, dtype=np.float64) for v in ground)
    home_a = np.full(lon.size, -1) if home is None else np.asarray(home)
    m_pt, m_img, m_row, m_col = [], [], [], []
    for i, (name, model) in enumerate(models.items()):
        row, col, ok = _project(model, lon, lat, h)
        ok &= _inside(model, row, col)
        other = ok & (home_a != i)
        idx_other = np.flatnonzero(other)
        seen = ok & (home_a == i)
        seen[idx_other] = _visible(model, row[idx_other], col[idx_other], dem, lon[idx_other],
                                   lat[idx_other], h[idx_other])
        idx = np.flatnonzero(seen)
        m_pt.append(idx)
        m_img.append(np.full(idx.size, name))
        m_row.append(row[idx])
        m_col.append(col[idx])
    pt = np.concatenate(m_pt)
    order = np.lexsort((np.concatenate([np.full(a.size, i) for i, a in enumerate(m_pt)]), pt))
    return Measurements(pt[order], np.concatenate(m_img)[order], np.concatenate(m_row)[order],
                        np.concatenate(m_col)[order])


def pointing_noise(
    row: np.ndarray,
    col: np.ndarray,
    *,
    sigma_px: float,
    blunder_fraction: float = 0.0,
    blunder_px: float = 10.0,
    rng: Rng = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Measured image positions: the true ones plus pointing noise and blunders.

    Parameters
    ----------
    row, col : ndarray, (M,)
        True image positions, pixels.
    sigma_px : float
        Standard deviation of the Gaussian noise on row and on col, pixels.
    blunder_fraction : float
        Fraction of the measurements (rounded) given a blunder of ``blunder_px`` pixels in a
        uniformly random direction.
    blunder_px : float
    rng : int, numpy.random.Generator or None

    Returns
    -------
    row, col : ndarray, (M,)
        Measured positions, pixels.
    blunder : ndarray of bool, (M,)
        Whether each got a blunder.
    """
    _check_sigma("pointing_noise", sigma_px=sigma_px, blunder_px=blunder_px)
    _check_fraction("pointing_noise", blunder_fraction=blunder_fraction)
    rng = np.random.default_rng(rng)
    row = np.asarray(row, dtype=np.float64)
    col = np.asarray(col, dtype=np.float64)
    n = row.size
    row_m = row + rng.normal(0.0, 1.0, n) * sigma_px
    col_m = col + rng.normal(0.0, 1.0, n) * sigma_px
    blunder = np.zeros(n, bool)
    nb = int(round(blunder_fraction * n))
    if nb:
        sel = rng.choice(n, nb, replace=False)
        theta = rng.uniform(0.0, 2.0 * np.pi, nb)
        row_m[sel] += blunder_px * np.cos(theta)
        col_m[sel] += blunder_px * np.sin(theta)
        blunder[sel] = True
    return row_m, col_m, blunder


def survey_noise(
    ground: GroundCoords,
    *,
    sigma_e: float,
    sigma_n: float,
    sigma_h: float,
    surveyed: np.ndarray | None = None,
    blunder_fraction: float = 0.0,
    blunder_m: float = 20.0,
    rng: Rng = None,
) -> tuple[GroundCoords, np.ndarray]:
    """Surveyed ground positions: the true ones plus survey noise and blunders.

    The noise is Gaussian in the local east/north/up frame of each point; a blunder is a
    horizontal offset of ``blunder_m`` metres in a uniformly random direction.

    Parameters
    ----------
    ground : GroundCoords
        ``(N,)`` true positions.
    sigma_e, sigma_n, sigma_h : float
        Standard deviations east, north and up, metres.
    surveyed : ndarray of bool, (N,), optional
        The points that are surveyed (GCPs and ICPs; default all); the others come out NaN.
        A noise draw is made for every point, so that the draws do not depend on which are
        surveyed.
    blunder_fraction : float
        Fraction of the surveyed points (rounded) given a blunder.
    blunder_m : float
    rng : int, numpy.random.Generator or None

    Returns
    -------
    GroundCoords
        Surveyed ``lon, lat`` (degrees) and ``h`` (metres above the ellipsoid); NaN where not
        surveyed.
    blunder : ndarray of bool, (N,)
    """
    _check_sigma("survey_noise", sigma_e=sigma_e, sigma_n=sigma_n, sigma_h=sigma_h,
                 blunder_m=blunder_m)
    _check_fraction("survey_noise", blunder_fraction=blunder_fraction)
    rng = np.random.default_rng(rng)
    lon, lat, h = (np.asarray(v, dtype=np.float64) for v in ground)
    n = lon.size
    keep = np.ones(n, bool) if surveyed is None else np.asarray(surveyed, dtype=bool)
    enu = rng.normal(0.0, 1.0, (n, 3)) * np.array([sigma_e, sigma_n, sigma_h])
    blunder = np.zeros(n, bool)
    candidates = np.flatnonzero(keep)
    nb = int(round(blunder_fraction * candidates.size))
    if nb:
        sel = rng.choice(candidates, nb, replace=False)
        theta = rng.uniform(0.0, 2.0 * np.pi, nb)
        enu[sel, 0] += blunder_m * np.cos(theta)
        enu[sel, 1] += blunder_m * np.sin(theta)
        blunder[sel] = True
    xyz = np.stack(coords.geodetic_to_ecef(lon, lat, h), axis=-1)
    rot = coords.enu_rotation(lon, lat)  # rows: east, north, up in ECEF
    xyz = xyz + np.einsum("nij,ni->nj", rot, enu)
    lon_s, lat_s, h_s = coords.ecef_to_geodetic(xyz[:, 0], xyz[:, 1], xyz[:, 2])
    nan = np.full(n, np.nan)
    return GroundCoords(np.where(keep, lon_s, nan), np.where(keep, lat_s, nan),
                        np.where(keep, h_s, nan)), blunder


# ---------------------------------------------------------------------------- simulation
def simulate_points(
    models: Mapping[str, Any] | Sequence[Any],
    dem: Any,
    *,
    gcp: int = 9,
    icp: int = 0,
    design: str = "stratified",
    cells: int = 3,
    tp: int | tuple[int, int] = 20,
    ictp: int | tuple[int, int] = 0,
    min_overlap: float = 0.01,
    sigma_px: float = 0.5,
    sigma_e: float = 1.0,
    sigma_n: float = 1.0,
    sigma_h: float = 1.0,
    blunder_fraction: float = 0.0,
    blunder_px: float = 10.0,
    ground_blunder_fraction: float = 0.0,
    ground_blunder_m: float = 20.0,
    margin_px: float = 10.0,
    seed: int = 0,
) -> PointSet:
    """Simulate GCPs, ICPs, TPs and ICTPs over images with known true models and terrain.

    A convenience composing the steps of this module (the module docstring) with one
    generator seeded by ``seed``.

    Parameters
    ----------
    models : mapping of str to SensorModel, or sequence of SensorModel
        The TRUE model of each image, by image name (a sequence is named ``image1``,
        ``image2``...). Only ``project``, ``backproject``, ``shape``, ``height_range`` and
        ``footprint`` are used, so any model works.
    dem : DemSource, Terrain or float
        The TRUE terrain: a number is a constant height above the ellipsoid, a
        :class:`~geoblock.simulate.terrain.Terrain` is turned into a DEM with
        :meth:`~geoblock.simulate.terrain.Terrain.to_dem`; heights come out above the
        ellipsoid whatever the DEM's datum.
    gcp, icp : int
        GCPs and ICPs drawn per image (:func:`candidate_positions`,
        :func:`ground_candidates`).
    design : {"stratified", "random"}
        GCP/ICP sampling: uniform over the image, or stratified random: the image is cut into
        ``cells x cells`` equal cells and each cell gets ``count // cells**2`` points (the
        remainder goes to randomly chosen cells), uniform inside its cell.
    cells : int
        Cells per side of the stratified design (Aguilar et al.: 3).
    tp, ictp : int or (int, int)
        TPs and ICTPs per overlapping pair of images; ``(low, high)`` draws the count per pair
        uniformly in that range (Teo et al.: 13-32). They are drawn uniformly in the overlap
        and measured in every image that sees them (:func:`overlap_points`).
    min_overlap : float
        Pairs whose overlap box covers less than this fraction of the first image get no tie
        points (:func:`overlap_window`).
    sigma_px : float
        Image pointing noise, pixels (standard deviation on row and on col).
    sigma_e, sigma_n, sigma_h : float
        Ground survey noise of GCPs and ICPs, metres east, north and up.
    blunder_fraction, blunder_px : float
        Fraction of the image measurements given a blunder, and its size in pixels (random
        direction).
    ground_blunder_fraction, ground_blunder_m : float
        Fraction of the GCPs and ICPs given a horizontal ground blunder, and its size, metres.
    margin_px : float
        Points are drawn at least this far inside the image edges.
    seed : int
        Same seed, same points.

    Returns
    -------
    PointSet

    Raises
    ------
    GeoblockError
        Invalid arguments, or the DEM does not let the points requested be placed (it does not
        cover an image, an overlap has too few visible points).
    """
    if isinstance(models, Mapping):
        named = {str(k): v for k, v in models.items()}
    else:
        named = {f"image{i + 1}": m for i, m in enumerate(models)}
    if not named:
        raise GeoblockError("simulate_points: no image models given")
    if design not in ("stratified", "random"):
        raise GeoblockError(f"simulate_points: design must be 'stratified' or 'random', got "
                            f"{design!r}")
    if cells < 1 or gcp < 0 or icp < 0:
        raise GeoblockError("simulate_points: cells must be >= 1 and gcp, icp >= 0")
    _check_sigma("simulate_points", sigma_px=sigma_px, sigma_e=sigma_e, sigma_n=sigma_n,
                 sigma_h=sigma_h, blunder_px=blunder_px, ground_blunder_m=ground_blunder_m)
    _check_fraction("simulate_points", blunder_fraction=blunder_fraction,
                    ground_blunder_fraction=ground_blunder_fraction)
    dem = _as_dem(dem)
    rng = np.random.default_rng(seed)
    names = list(named)
    parts: list[tuple[str, GroundCoords, int]] = []  # kind, points, home image

    # --- GCPs and ICPs, per image
    for i, name in enumerate(names):
        model = named[name]
        for kind, count in (("gcp", gcp), ("icp", icp)):
            if count == 0:
                continue
            candidates = candidate_positions(model.shape, count, design=design, cells=cells,
                                             margin_px=margin_px, rng=rng)
            parts.append((kind, ground_candidates(model, dem, candidates,
                                                  what=f"{kind.upper()}s of image {name!r}"), i))

    # --- TPs and ICTPs, per overlapping pair
    heights = dem.height_range()
    for i in range(len(names)):
        for j in range(i + 1, len(names)):
            mi, mj = named[names[i]], named[names[j]]
            window = overlap_window(mi, mj, heights, margin_px=margin_px,
                                    min_overlap=min_overlap)
            if window is None:
                continue
            n_tp = _count(rng, tp, "tp")
            n_ictp = _count(rng, ictp, "ictp")
            if n_tp + n_ictp == 0:
                continue
            ties = overlap_points(mi, mj, dem, n_tp + n_ictp, window, margin_px=margin_px,
                                  rng=rng, what=f"images {names[i]!r} and {names[j]!r}")
            parts.append(("tp", GroundCoords(*(v[:n_tp] for v in ties)), i))
            parts.append(("ictp", GroundCoords(*(v[n_tp:] for v in ties)), i))

    if not parts:
        raise GeoblockError("simulate_points: no point requested (gcp, icp, tp and ictp are 0, "
                            "or the images do not overlap)")
    truth = GroundCoords(*(np.concatenate([p[1][k] for p in parts]) for k in range(3)))
    kinds = np.concatenate([np.full(p[1].lon.size, p[0]) for p in parts])
    home = np.concatenate([np.full(p[1].lon.size, p[2]) for p in parts])
    ids = point_ids(kinds)

    # --- measurements: every image that sees each point, then the noise
    seen = measure_points(named, truth, dem, home)
    row_m, col_m, blunder = pointing_noise(seen.row, seen.col, sigma_px=sigma_px,
                                           blunder_fraction=blunder_fraction,
                                           blunder_px=blunder_px, rng=rng)
    surveyed = np.isin(kinds, ("gcp", "icp"))
    survey, g_blunder = survey_noise(truth, sigma_e=sigma_e, sigma_n=sigma_n, sigma_h=sigma_h,
                                     surveyed=surveyed, blunder_fraction=ground_blunder_fraction,
                                     blunder_m=ground_blunder_m, rng=rng)
    nan = np.full(kinds.size, np.nan)
    ground = SimulatedGround(
        id=ids, kind=kinds, lon_true=truth.lon, lat_true=truth.lat, h_true=truth.h,
        lon=survey.lon, lat=survey.lat, h=survey.h,
        sigma_e=np.where(surveyed, sigma_e, nan), sigma_n=np.where(surveyed, sigma_n, nan),
        sigma_h=np.where(surveyed, sigma_h, nan), blunder=g_blunder,
    )
    image = SimulatedMeasurements(
        id=ids[seen.point], image=seen.image, kind=kinds[seen.point], row_true=seen.row,
        col_true=seen.col, row=row_m, col=col_m,
        sigma=np.full(seen.point.size, float(sigma_px)), blunder=blunder,
    )
    return PointSet(ground, image, tuple(names))
