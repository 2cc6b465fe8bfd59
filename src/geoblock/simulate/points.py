"""Simulated GCPs, ICPs, TPs and ICTPs over a set of images, with their true values kept.

:func:`simulate_points` places

* **GCPs** and **ICPs** (ground control and independent check points) per image, by a random
  or a stratified random design over an ``n x n`` grid of the image (Aguilar et al.: one GCP
  per cell of a 3 x 3 grid; their 45 GCPs: five per cell);
* **TPs** and **ICTPs** (tie points and independent check tie points) in the overlap of each
  pair of images (Teo et al.: strips overlapping by 10-15 %, 13-32 TPs per overlap).

Each point is found by drawing an image position, intersecting its line of sight with the
true terrain through the TRUE model (:func:`geoblock.localize`: heights above the ellipsoid,
whatever the DEM's own datum), and projecting the ground point into every image through the
true models; a measurement is kept where the point falls inside the image and is not hidden
by the terrain. Then the noise: image pointing noise (``sigma_px``, on row and col), ground
survey noise (``sigma_e, sigma_n, sigma_h`` metres, GCPs and ICPs only) and optional blunders.
Every noisy value keeps its true value beside it, so that accuracy statistics are exact.

Files (:meth:`PointSet.write`): the ground CSV and the image-measurement CSV of
ARCHITECTURE.md section 7 (read by :func:`geoblock.io.read_points`) and a truth CSV.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from geoblock import coords
from geoblock.adjust.observations import KINDS, GroundPoints, ImagePoints
from geoblock.dem.intersect import localize
from geoblock.errors import GeoblockError
from geoblock.typing import Status

__all__ = ["KINDS", "PointSet", "SimulatedGround", "SimulatedMeasurements", "simulate_points"]


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
def _project(model: Any, lon: np.ndarray, lat: np.ndarray, h: np.ndarray):
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


def _inside(model: Any, row: np.ndarray, col: np.ndarray, margin: float = 0.0) -> np.ndarray:
    rows, cols = model.shape
    return ((row >= -0.5 + margin) & (row < rows - 0.5 - margin)
            & (col >= -0.5 + margin) & (col < cols - 0.5 - margin))


def _localize(model: Any, row: np.ndarray, col: np.ndarray, dem: Any):
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


def _cell_candidates(rng: np.random.Generator, model: Any, count: int, design: str, cells: int,
                     margin: float, factor: int = 4):
    """Candidate image positions: ``row, col, cell`` (cell -1 for the random design), with
    the number wanted per cell."""
    rows, cols = model.shape
    r0, r1 = margin - 0.5, rows - 0.5 - margin
    c0, c1 = margin - 0.5, cols - 0.5 - margin
    if r1 <= r0 or c1 <= c0:
        raise GeoblockError(f"simulate_points: a margin of {margin} px leaves no room in an "
                            f"image of {rows} x {cols} px")
    if design == "random":
        n = factor * count + 8
        return rng.uniform(r0, r1, n), rng.uniform(c0, c1, n), np.full(n, -1), {-1: count}
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
    return row, col, cell, dict(enumerate(wanted.tolist()))


def _pick(ok: np.ndarray, cell: np.ndarray, wanted: Mapping[int, int], what: str) -> np.ndarray:
    """Indices of the first ``wanted[c]`` usable candidates of each cell (in drawing order)."""
    chosen = []
    for c, n in wanted.items():  # a loop over the (few) cells, not over points
        idx = np.flatnonzero(ok & (cell == c))
        if idx.size < n:
            where = "" if c < 0 else f" in cell {c} (row-major)"
            raise GeoblockError(f"simulate_points: found {idx.size} of the {n} {what}{where}: the "
                                "true DEM must cover the image (lines of sight meet no terrain)")
        chosen.append(idx[:n])
    return np.concatenate(chosen) if chosen else np.zeros(0, np.intp)


def _overlap_box(mi: Any, mj: Any, heights: tuple[float, float], margin: float):
    """Bounding box in image ``mi`` of image ``mj``'s footprint at two heights, or None."""
    rows, cols = mi.shape
    lon, lat, h = [], [], []
    for hh in heights:
        fp = mj.footprint(h=hh, n=16)
        lon.append(fp.lon)
        lat.append(fp.lat)
        h.append(np.full(fp.lon.shape, hh))
    r, c, ok = _project(mi, np.concatenate(lon), np.concatenate(lat), np.concatenate(h))
    if not ok.any():
        return None
    r0 = max(margin - 0.5, float(r[ok].min()))
    r1 = min(rows - 0.5 - margin, float(r[ok].max()))
    c0 = max(margin - 0.5, float(c[ok].min()))
    c1 = min(cols - 0.5 - margin, float(c[ok].max()))
    if r1 <= r0 or c1 <= c0:
        return None
    return r0, r1, c0, c1


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
        GCPs and ICPs drawn per image.
    design : {"stratified", "random"}
        GCP/ICP sampling: uniform over the image, or stratified random: the image is cut into
        ``cells x cells`` equal cells and each cell gets ``count // cells**2`` points (the
        remainder goes to randomly chosen cells), uniform inside its cell.
    cells : int
        Cells per side of the stratified design (Aguilar et al.: 3).
    tp, ictp : int or (int, int)
        TPs and ICTPs per overlapping pair of images; ``(low, high)`` draws the count per pair
        uniformly in that range (Teo et al.: 13-32). They are drawn uniformly in the overlap
        and measured in every image that sees them.
    min_overlap : float
        Pairs whose overlap box covers less than this fraction of the first image get no tie
        points.
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
    from geoblock.simulate.terrain import Terrain

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
    for name, value in (("sigma_px", sigma_px), ("sigma_e", sigma_e), ("sigma_n", sigma_n),
                        ("sigma_h", sigma_h), ("blunder_px", blunder_px),
                        ("ground_blunder_m", ground_blunder_m)):
        if not (math.isfinite(value) and value >= 0):
            raise GeoblockError(f"simulate_points: {name} must be a finite number >= 0, "
                                f"got {value}")
    for name, value in (("blunder_fraction", blunder_fraction),
                        ("ground_blunder_fraction", ground_blunder_fraction)):
        if not 0.0 <= value <= 1.0:
            raise GeoblockError(f"simulate_points: {name} must be in [0, 1], got {value}")
    if isinstance(dem, Terrain):
        dem = dem.to_dem()
    elif isinstance(dem, int | float):
        from geoblock.dem.constant import ConstantDem

        dem = ConstantDem(float(dem))
    rng = np.random.default_rng(seed)
    names = list(named)

    pts_lon: list[np.ndarray] = []
    pts_lat: list[np.ndarray] = []
    pts_h: list[np.ndarray] = []
    pts_kind: list[np.ndarray] = []
    pts_home: list[np.ndarray] = []  # the image each point was drawn in (visible there)

    def add(kind: str, lon, lat, h, home: int) -> None:
        pts_lon.append(lon)
        pts_lat.append(lat)
        pts_h.append(h)
        pts_kind.append(np.full(lon.size, kind))
        pts_home.append(np.full(lon.size, home))

    # --- GCPs and ICPs, per image
    for i, name in enumerate(names):
        model = named[name]
        for kind, count in (("gcp", gcp), ("icp", icp)):
            if count == 0:
                continue
            row, col, cell, wanted = _cell_candidates(rng, model, count, design, cells, margin_px)
            lon, lat, h, ok = _localize(model, row, col, dem)
            k = _pick(ok, cell, wanted, f"{kind.upper()}s of image {name!r}")
            add(kind, lon[k], lat[k], h[k], i)

    # --- TPs and ICTPs, per overlapping pair
    lo_h, hi_h = dem.height_range()
    for i in range(len(names)):
        for j in range(i + 1, len(names)):
            mi, mj = named[names[i]], named[names[j]]
            box = _overlap_box(mi, mj, (lo_h, hi_h), margin_px)
            if box is None:
                continue
            r0, r1, c0, c1 = box
            if (r1 - r0) * (c1 - c0) < min_overlap * mi.shape[0] * mi.shape[1]:
                continue
            n_tp = _count(rng, tp, "tp")
            n_ictp = _count(rng, ictp, "ictp")
            need = n_tp + n_ictp
            if need == 0:
                continue
            found = np.zeros(0, np.intp)
            for factor in (8, 64):
                n = factor * need + 16
                row, col = rng.uniform(r0, r1, n), rng.uniform(c0, c1, n)
                lon, lat, h, ok = _localize(mi, row, col, dem)
                rj, cj, okj = _project(mj, lon, lat, h)
                ok &= okj & _inside(mj, rj, cj, margin_px)
                idx = np.flatnonzero(ok)
                vis = _visible(mj, rj[idx], cj[idx], dem, lon[idx], lat[idx], h[idx])
                found = idx[vis]
                if found.size >= need:
                    break
            if found.size < need:
                raise GeoblockError(
                    f"simulate_points: only {found.size} of the {need} tie points wanted could be "
                    f"placed in the overlap of images {names[i]!r} and {names[j]!r}"
                )
            k = found[:need]
            add("tp", lon[k[:n_tp]], lat[k[:n_tp]], h[k[:n_tp]], i)
            add("ictp", lon[k[n_tp:]], lat[k[n_tp:]], h[k[n_tp:]], i)

    if not pts_lon:
        raise GeoblockError("simulate_points: no point requested (gcp, icp, tp and ictp are 0, "
                            "or the images do not overlap)")
    lon_t = np.concatenate(pts_lon)
    lat_t = np.concatenate(pts_lat)
    h_t = np.concatenate(pts_h)
    kind = np.concatenate(pts_kind)
    home = np.concatenate(pts_home)
    n_pts = lon_t.size
    ids = np.empty(n_pts, dtype=object)
    for kd in KINDS:
        sel = np.flatnonzero(kind == kd)
        ids[sel] = [f"{kd}{k + 1:04d}" for k in range(sel.size)]

    # --- measurements: every image that sees each point
    m_pt, m_img, m_row, m_col = [], [], [], []
    for i, name in enumerate(names):
        model = named[name]
        row, col, ok = _project(model, lon_t, lat_t, h_t)
        ok &= _inside(model, row, col)
        other = ok & (home != i)
        idx_other = np.flatnonzero(other)
        seen = ok & (home == i)
        seen[idx_other] = _visible(model, row[idx_other], col[idx_other], dem, lon_t[idx_other],
                                   lat_t[idx_other], h_t[idx_other])
        idx = np.flatnonzero(seen)
        m_pt.append(idx)
        m_img.append(np.full(idx.size, name))
        m_row.append(row[idx])
        m_col.append(col[idx])
    pt = np.concatenate(m_pt)
    order = np.lexsort((np.concatenate([np.full(a.size, i) for i, a in enumerate(m_pt)]), pt))
    pt = pt[order]
    img = np.concatenate(m_img)[order]
    row_true = np.concatenate(m_row)[order]
    col_true = np.concatenate(m_col)[order]
    n_meas = pt.size

    # --- image noise and blunders
    row_m = row_true + rng.normal(0.0, 1.0, n_meas) * sigma_px
    col_m = col_true + rng.normal(0.0, 1.0, n_meas) * sigma_px
    blunder = np.zeros(n_meas, bool)
    nb = int(round(blunder_fraction * n_meas))
    if nb:
        sel = rng.choice(n_meas, nb, replace=False)
        theta = rng.uniform(0.0, 2.0 * np.pi, nb)
        row_m[sel] += blunder_px * np.cos(theta)
        col_m[sel] += blunder_px * np.sin(theta)
        blunder[sel] = True

    # --- ground survey noise and blunders (GCPs and ICPs)
    surveyed = np.isin(kind, ("gcp", "icp"))
    enu = rng.normal(0.0, 1.0, (n_pts, 3)) * np.array([sigma_e, sigma_n, sigma_h])
    g_blunder = np.zeros(n_pts, bool)
    candidates = np.flatnonzero(surveyed)
    ngb = int(round(ground_blunder_fraction * candidates.size))
    if ngb:
        sel = rng.choice(candidates, ngb, replace=False)
        theta = rng.uniform(0.0, 2.0 * np.pi, ngb)
        enu[sel, 0] += ground_blunder_m * np.cos(theta)
        enu[sel, 1] += ground_blunder_m * np.sin(theta)
        g_blunder[sel] = True
    xyz = np.stack(coords.geodetic_to_ecef(lon_t, lat_t, h_t), axis=-1)
    rot = coords.enu_rotation(lon_t, lat_t)  # rows: east, north, up in ECEF
    xyz = xyz + np.einsum("nij,ni->nj", rot, enu)
    lon_s, lat_s, h_s = coords.ecef_to_geodetic(xyz[:, 0], xyz[:, 1], xyz[:, 2])
    nan = np.full(n_pts, np.nan)
    ground = SimulatedGround(
        id=ids.astype(str), kind=kind, lon_true=lon_t, lat_true=lat_t, h_true=h_t,
        lon=np.where(surveyed, lon_s, nan), lat=np.where(surveyed, lat_s, nan),
        h=np.where(surveyed, h_s, nan),
        sigma_e=np.where(surveyed, sigma_e, nan), sigma_n=np.where(surveyed, sigma_n, nan),
        sigma_h=np.where(surveyed, sigma_h, nan), blunder=g_blunder,
    )
    image = SimulatedMeasurements(
        id=ids.astype(str)[pt], image=img, kind=kind[pt], row_true=row_true, col_true=col_true,
        row=row_m, col=col_m, sigma=np.full(n_meas, float(sigma_px)), blunder=blunder,
    )
    return PointSet(ground, image, tuple(names))


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
