"""Which images to match: :func:`select_pairs` and the :class:`PairGraph` it reports.

Matching every pair of a block is O(n^2) and mostly wasted: in a block of strips, an image
overlaps its few neighbours. The pairs are chosen from the images' **footprints** on the DEM,
before any pixel is read:

1. **footprint** - a ``grid x grid`` lattice of each image's pixels (its border included) is
   intersected with the DEM through the image's model (:func:`geoblock.localize`), once per
   image; the border, in order, is the footprint's ring; each lattice point also keeps its
   line of sight (the unit vector from the ground point towards the sensor, ECEF);
2. **candidates** - the footprints' longitude/latitude boxes are swept in order of their
   western edge (sort and sweep: O(n log n) plus the number of overlapping boxes), longitudes
   unwrapped around the block's mean (a block crossing the antimeridian works; one
   spanning more than 180 degrees of longitude does not);
3. **overlap** - of each candidate pair (A, B), the share of A's lattice points inside B's
   ring (a crossing-number test in the local east/north plane of A's centre) times A's area,
   over the smaller footprint's area: ``overlap = area(A & B) / min(area(A), area(B))``;
4. **convergence** - the angle between A's and B's lines of sight at the overlap's centre
   (each image's lattice point nearest it), degrees;
5. **selection** - pairs whose overlap is at least ``min_overlap`` and whose convergence is
   within ``[min_convergence_deg, max_convergence_deg]`` are eligible; a maximum spanning
   forest of the eligible graph (weighted by overlap) is kept first, so that the cap never
   splits a connected block; then the other eligible pairs, largest overlap first, while both
   images have fewer than ``max_pairs_per_image`` pairs.

Near-parallel lines of sight are fine for tie points (the adjustment needs the images' rays
to meet, not to intersect at an angle: the DEM fixes the height): the convergence bound from
below is for stereo (height from the images alone), and is off by default. The bound from above
is off by default too: guided by the models and refined in their local affine geometry, the
matching does not rely on SIFT's invariance alone; set it where very different views fail.

:meth:`PairGraph.report` says, before any matching, how many images, candidate and selected
pairs there are, the connected components (named by their images) and the images with no pair.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from geoblock import coords
from geoblock.errors import MatchError
from geoblock.typing import Status

if TYPE_CHECKING:
    from geoblock.dem.protocol import DemSource
    from geoblock.models.protocol import SensorModel

__all__ = ["FOOTPRINT_GRID", "Footprint", "PairGraph", "footprint", "select_pairs"]

#: Lattice points per side of an image's footprint.
FOOTPRINT_GRID = 16
#: Height step of the lines of sight, metres.
_RAY_STEP_M = 1000.0
#: Why a candidate pair is not selected, in the order the tests are applied.
PAIR_STATUSES = ("selected", "overlap", "convergence", "cap")


# ============================================================================== footprints
@dataclass(frozen=True, eq=False)
class Footprint:
    """An image's ground on the DEM: a lattice of its pixels, localised.

    Attributes
    ----------
    lon, lat, h : ndarray, (G, G)
        The lattice's ground points: degrees, metres above the ellipsoid (NaN where the line
        of sight misses the DEM).
    ray : ndarray, (G, G, 3)
        Unit line of sight at each point, from the ground towards the sensor, ECEF.
    ok : ndarray of bool, (G, G)
        The point was localised.
    """

    lon: np.ndarray
    lat: np.ndarray
    h: np.ndarray
    ray: np.ndarray
    ok: np.ndarray

    @property
    def valid(self) -> bool:
        """At least three points of the border and the centre region were localised."""
        return int(self.ok[self._ring_index()].sum()) >= 3

    def _ring_index(self) -> tuple[np.ndarray, np.ndarray]:
        g = self.ok.shape[0]
        r = np.r_[np.zeros(g - 1, int), np.arange(g - 1), np.full(g - 1, g - 1),
                  np.arange(g - 1, 0, -1)]
        c = np.r_[np.arange(g - 1), np.full(g - 1, g - 1), np.arange(g - 1, 0, -1),
                  np.zeros(g - 1, int)]
        return r, c

    def ring(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The border's localised points in order around the image: ``lon, lat, h``, (R,)."""
        r, c = self._ring_index()
        ok = self.ok[r, c]
        return self.lon[r, c][ok], self.lat[r, c][ok], self.h[r, c][ok]


def footprint(model: SensorModel, dem: DemSource, *, grid: int = FOOTPRINT_GRID) -> Footprint:
    """The footprint of ``model``'s image on ``dem``: a ``grid x grid`` lattice of its pixels
    (corners and border included) intersected with the DEM, with each point's line of sight.

    Parameters
    ----------
    model : SensorModel
    dem : DemSource
        Heights above the ellipsoid.
    grid : int
        Lattice points per side (>= 2).

    Returns
    -------
    Footprint
    """
    from geoblock.dem.intersect import localize

    rows, cols = (int(v) for v in model.shape)
    r = np.linspace(0, rows - 1, grid)
    c = np.linspace(0, cols - 1, grid)
    rr, cc = np.meshgrid(r, c, indexing="ij")
    # a footprint needs metres, not millimetres
    ground, status = localize(model, rr.ravel(), cc.ravel(), dem, tolerance_m=0.5, warn=False)
    ok = status == Status.CONVERGED
    up, st = model.backproject_with_status(rr.ravel(), cc.ravel(), ground.h + _RAY_STEP_M)
    ok &= st == Status.CONVERGED
    p0 = np.stack(coords.geodetic_to_ecef(ground.lon, ground.lat, ground.h), axis=-1)
    p1 = np.stack(coords.geodetic_to_ecef(up.lon, up.lat, up.h), axis=-1)
    ray = p1 - p0
    with np.errstate(invalid="ignore", divide="ignore"):
        ray /= np.linalg.norm(ray, axis=-1, keepdims=True)
    ok &= np.isfinite(ray).all(axis=-1)
    nan = np.where(ok, 1.0, np.nan)
    shape = (grid, grid)
    return Footprint((ground.lon * nan).reshape(shape), (ground.lat * nan).reshape(shape),
                     (ground.h * nan).reshape(shape), (ray * nan[:, None]).reshape(*shape, 3),
                     ok.reshape(shape))


# ============================================================================== the graph
@dataclass(frozen=True, eq=False)
class PairGraph:
    """The images of a block, their candidate pairs and the pairs selected for matching.

    Attributes
    ----------
    image_ids : tuple of str, (n,)
    pairs : ndarray of int, (K, 2)
        Candidate pairs ``(i, j)``, ``i < j`` (indices into ``image_ids``): footprints whose
        boxes overlap; sorted.
    overlap : ndarray, (K,)
        Overlap of each candidate, fraction of the smaller footprint's area, [0, 1].
    convergence_deg : ndarray, (K,)
        Angle between the two lines of sight at the overlap's centre, degrees (NaN without
        overlap).
    status : ndarray of str, (K,)
        ``selected``, or why not: ``overlap`` (below ``min_overlap``), ``convergence``
        (outside the bounds), ``cap`` (both images had their ``max_pairs_per_image``).
    footprint_ok : ndarray of bool, (n,)
        The image's footprint was placed on the DEM.
    options : dict
        The thresholds applied.
    """

    image_ids: tuple[str, ...]
    pairs: np.ndarray
    overlap: np.ndarray
    convergence_deg: np.ndarray
    status: np.ndarray
    footprint_ok: np.ndarray
    options: Mapping[str, Any]

    @property
    def selected(self) -> np.ndarray:
        """The selected pairs, ``(S, 2)`` image indices, ``i < j``, sorted."""
        return self.pairs[self.status == "selected"]

    def degree(self) -> np.ndarray:
        """Selected pairs per image, (n,)."""
        sel = self.selected
        return np.bincount(sel.ravel(), minlength=len(self.image_ids))

    def labels(self) -> np.ndarray:
        """Connected component of each image in the selected graph, (n,): components with
        two or more images numbered from 0, largest first (ties: by first image), -1 for the
        images with no pair."""
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import connected_components

        n = len(self.image_ids)
        sel = self.selected
        graph = coo_matrix((np.ones(len(sel)), (sel[:, 0], sel[:, 1])), shape=(n, n))
        _, label = connected_components(graph, directed=False)
        paired = self.degree() > 0
        out = np.full(n, -1, np.intp)
        if paired.any():
            comp, first, size = np.unique(label[paired], return_index=True, return_counts=True)
            first_image = np.flatnonzero(paired)[first]
            rank = np.lexsort((first_image, -size))
            number = np.empty(comp.size, np.intp)
            number[rank] = np.arange(comp.size)
            out[paired] = number[np.searchsorted(comp, label[paired])]
        return out

    def components(self) -> list[tuple[str, ...]]:
        """The connected components of the selected graph (two or more images each), largest
        first, each its image ids in the block's order."""
        label = self.labels()
        ids = np.array(self.image_ids, dtype=object)
        return [tuple(ids[label == k]) for k in range(int(label.max()) + 1)]

    def unpaired(self) -> tuple[str, ...]:
        """The images with no selected pair (no footprint on the DEM, no overlap, or all their
        pairs below the thresholds)."""
        return tuple(np.array(self.image_ids, dtype=object)[self.degree() == 0])

    def counts(self) -> dict[str, int]:
        """Candidates per status."""
        return {s: int((self.status == s).sum()) for s in PAIR_STATUSES}

    def summary(self) -> str:
        """One line: images, candidate and selected pairs, components, images with no pair."""
        c = self.counts()
        comps = self.components()
        why = ", ".join(f"{c[s]} {s}" for s in PAIR_STATUSES[1:] if c[s])
        return (f"pair graph: {len(self.image_ids)} images, {len(self.pairs)} candidate pairs, "
                f"{c['selected']} selected" + (f" (not: {why})" if why else "")
                + f", {len(comps)} component{'s' if len(comps) != 1 else ''}, "
                f"{len(self.unpaired())} image(s) with no pair")

    def report(self, *, pairs: bool = False, max_names: int = 10) -> str:
        """The graph as lines of text: the summary, the thresholds, the components (the first
        ``max_names``, each with its size and first ``max_names`` images), the images with no
        pair and why, and with ``pairs`` every candidate (overlap, convergence, status)."""
        def names(items: Sequence[str]) -> str:
            shown = ", ".join(items[:max_names])
            return shown + (f", ... ({len(items) - max_names} more)"
                            if len(items) > max_names else "")

        opts = self.options
        cap = opts.get("max_pairs_per_image")
        lines = [self.summary(),
                 f"  thresholds: overlap >= {100 * opts.get('min_overlap', 0):g} % of the "
                 f"smaller footprint, convergence {opts.get('min_convergence_deg', 0):g}-"
                 f"{opts.get('max_convergence_deg') or 180:g} deg, "
                 f"{'no cap' if cap is None else f'at most {cap} pairs per image'} "
                 "(a spanning forest first)"]
        degree = self.degree()
        comps = self.components()
        for k, comp in enumerate(comps[:max_names]):
            lines.append(f"  component {k + 1}: {len(comp)} images: {names(list(comp))}")
        if len(comps) > max_names:
            sizes = [len(c) for c in comps[max_names:]]
            lines.append(f"  ... {len(sizes)} more components of {min(sizes)}-{max(sizes)} "
                         "images")
        unpaired = np.flatnonzero(degree == 0)
        if unpaired.size:
            involved = np.zeros(len(self.image_ids), bool)
            involved[self.pairs[self.overlap > 0].ravel()] = True
            reasons = []
            for i in unpaired:
                why = ("no footprint on the DEM" if not self.footprint_ok[i]
                       else "overlaps no other image" if not involved[i]
                       else "no pair within the thresholds")
                reasons.append(f"{self.image_ids[i]} ({why})")
            lines.append(f"  no pair: {names(reasons)}")
        if pairs:
            for (i, j), f, a, s in zip(self.pairs, self.overlap, self.convergence_deg,
                                       self.status, strict=True):
                lines.append(f"  {self.image_ids[i]} & {self.image_ids[j]}: overlap "
                             f"{100 * f:.1f} %, convergence {a:.1f} deg, {s}")
        return "\n".join(lines)


def _sweep(lo_x: np.ndarray, hi_x: np.ndarray, lo_y: np.ndarray, hi_y: np.ndarray
           ) -> np.ndarray:
    """Pairs ``(i, j)``, ``i < j``, of boxes that overlap: sort and sweep along x."""
    order = np.argsort(lo_x, kind="stable")
    sx = lo_x[order]
    stop = np.searchsorted(sx, hi_x[order], side="right")
    out = []
    for k in range(order.size):  # per box: the boxes starting inside its x-range, vectorised
        others = order[k + 1:stop[k]]
        i = order[k]
        hit = others[(lo_y[others] <= hi_y[i]) & (hi_y[others] >= lo_y[i])]
        if hit.size:
            out.append(np.column_stack([np.minimum(i, hit), np.maximum(i, hit)]))
    if not out:
        return np.zeros((0, 2), np.intp)
    pairs = np.concatenate(out)
    return pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]


def _inside_ring(e: np.ndarray, n: np.ndarray, ring_e: np.ndarray, ring_n: np.ndarray
                 ) -> np.ndarray:
    """Crossing-number test of points ``(P,)`` against a closed ring ``(R,)``, (P,) bool."""
    e0, n0 = ring_e[None, :], ring_n[None, :]
    e1, n1 = np.roll(ring_e, -1)[None, :], np.roll(ring_n, -1)[None, :]
    y = n[:, None]
    straddle = (n0 > y) != (n1 > y)
    with np.errstate(invalid="ignore", divide="ignore"):
        x_cross = e0 + (y - n0) * (e1 - e0) / (n1 - n0)
    crossings = (straddle & (e[:, None] < x_cross)).sum(axis=1)
    return crossings % 2 == 1


def _area(e: np.ndarray, n: np.ndarray) -> float:
    """Shoelace area of a ring, square metres."""
    return 0.5 * abs(float(np.dot(e, np.roll(n, -1)) - np.dot(n, np.roll(e, -1))))


@dataclass(frozen=True, eq=False)
class _Plane:
    """A footprint in ECEF and in the east/north plane of its centre, computed once."""

    xyz: np.ndarray  # (P, 3) the localised lattice points, ECEF
    ray: np.ndarray  # (P, 3)
    origin: np.ndarray  # (3,) the centre, ECEF
    rot: np.ndarray  # (3, 3) ECEF -> east, north, up at the centre
    en: np.ndarray  # (P, 2) the points in that plane
    ring: np.ndarray  # (R, 3) the border, ECEF
    area: float  # square metres

    @classmethod
    def of(cls, fp: Footprint) -> _Plane:
        ok = fp.ok.ravel()
        lon, lat, h = (v.ravel()[ok] for v in (fp.lon, fp.lat, fp.h))
        xyz = np.stack(coords.geodetic_to_ecef(lon, lat, h), axis=-1)
        c_lon, c_lat = lon[lon.size // 2], lat[lat.size // 2]
        rot = coords.enu_rotation(c_lon, c_lat)
        origin = xyz.mean(axis=0)
        ring = np.stack(coords.geodetic_to_ecef(*fp.ring()), axis=-1)
        en = (xyz - origin) @ rot[:2].T
        ring_en = (ring - origin) @ rot[:2].T
        return cls(xyz, fp.ray.reshape(-1, 3)[ok], origin, rot, en, ring,
                   _area(ring_en[:, 0], ring_en[:, 1]))


def _pair_geometry(a: _Plane, b: _Plane) -> tuple[float, float]:
    """``(area of A inside B in square metres, convergence in degrees)`` of a pair."""
    ring = (b.ring - a.origin) @ a.rot[:2].T
    inside = _inside_ring(a.en[:, 0], a.en[:, 1], ring[:, 0], ring[:, 1])
    if not inside.any():
        return 0.0, math.nan
    # the overlap's centre and each image's line of sight nearest it
    pts = a.xyz[inside]
    mid = pts.mean(axis=0)
    ray_a = a.ray[inside][np.argmin(((pts - mid) ** 2).sum(axis=1))]
    ray_b = b.ray[np.argmin(((b.xyz - mid) ** 2).sum(axis=1))]
    angle = math.degrees(math.acos(min(1.0, max(-1.0, float(ray_a @ ray_b)))))
    return float(inside.mean()) * a.area, angle


def _as_models(images: Any, ids: Sequence[str] | None
               ) -> tuple[list[str], list[SensorModel]]:
    if isinstance(images, Mapping):
        return [str(k) for k in images], list(images.values())
    items = list(images)
    models = [getattr(im, "model", im) for im in items]
    if ids is None:
        ids = [str(getattr(im, "id", k)) for k, im in enumerate(items)]
    if len(ids) != len(models):
        raise MatchError(f"select_pairs: {len(ids)} ids for {len(models)} images")
    return [str(i) for i in ids], models


def select_pairs(images: Any, dem: DemSource, *, min_overlap: float = 0.1,
                 max_pairs_per_image: int | None = 10, min_convergence_deg: float = 0.0,
                 max_convergence_deg: float | None = None, grid: int = FOOTPRINT_GRID,
                 ids: Sequence[str] | None = None,
                 footprints: Sequence[Footprint] | None = None,
                 scheduler: Any = "synchronous") -> PairGraph:
    """Choose the pairs of images to match from their footprints on the DEM (module
    docstring): candidates by sort and sweep, overlap and convergence thresholds, a cap of
    pairs per image that never disconnects the graph.

    Parameters
    ----------
    images : sequence of MatchImage or SensorModel, or mapping of id to SensorModel
        The block's images, in order (their order numbers the pairs and ties).
    dem : DemSource
        Heights above the ellipsoid.
    min_overlap : float
        Smallest overlap kept, fraction of the smaller footprint, in [0, 1] (0: any overlap).
    max_pairs_per_image : int or None
        Cap of selected pairs per image (the largest overlaps kept); a pair of the maximum
        spanning forest is kept even beyond it. None: no cap.
    min_convergence_deg, max_convergence_deg : float
        Bounds of the angle between the two lines of sight at the overlap's centre, degrees
        (module docstring: a lower bound is for stereo only). None: no upper bound.
    grid : int
        Footprint lattice points per side.
    ids : sequence of str, optional
        The images' ids (default their ``id`` attribute, else their position).
    footprints : sequence of Footprint, optional
        Precomputed footprints (:func:`footprint`), one per image.
    scheduler : {"synchronous", "threads", "processes"} or distributed.Client
        Where the footprints are computed, one task per image
        (:func:`geoblock.match.tasks.run_tasks`); the graph is the same on every one.

    Returns
    -------
    PairGraph

    Raises
    ------
    MatchError
        A threshold out of range (names it), or ids and images of different lengths.
    """
    if not (isinstance(min_overlap, int | float) and 0 <= min_overlap <= 1):
        raise MatchError(f"min_overlap must be in [0, 1], got {min_overlap!r}")
    if max_pairs_per_image is not None and not (
            isinstance(max_pairs_per_image, int | np.integer) and max_pairs_per_image >= 1):
        raise MatchError(f"max_pairs_per_image must be an integer >= 1 (or None), got "
                         f"{max_pairs_per_image!r}")
    hi = 180.0 if max_convergence_deg is None else max_convergence_deg
    if not (0 <= min_convergence_deg <= hi <= 180):
        raise MatchError(f"convergence bounds must satisfy 0 <= min ({min_convergence_deg!r}) "
                         f"<= max ({max_convergence_deg!r}) <= 180 degrees")
    if int(grid) < 2:
        raise MatchError(f"grid must be >= 2, got {grid!r}")
    names, models = _as_models(images, ids)
    n = len(models)
    if footprints is not None:
        fps = list(footprints)
    elif scheduler == "synchronous":
        fps = [footprint(m, dem, grid=int(grid)) for m in models]
    else:
        import uuid

        import dask

        from geoblock.match.tasks import run_tasks

        run = uuid.uuid4().hex[:12]  # keys unique to this run (a cluster may run others)
        fps = list(run_tasks({f"fp-{k}": dask.delayed(footprint, pure=False)(
            m, dem, grid=int(grid), dask_key_name=f"footprint-{run}-{k}")
            for k, m in enumerate(models)}, scheduler).values())
    if len(fps) != n:
        raise MatchError(f"select_pairs: {len(fps)} footprints for {n} images")
    valid = np.array([f.valid for f in fps], bool)
    # boxes, longitudes unwrapped around the block's circular mean
    lon_all = np.concatenate([f.lon[f.ok] for f, v in zip(fps, valid, strict=True) if v]
                             or [np.zeros(1)])
    ref = math.degrees(math.atan2(np.mean(np.sin(np.radians(lon_all))),
                                  np.mean(np.cos(np.radians(lon_all)))))
    box = np.full((n, 4), np.nan)
    for k in np.flatnonzero(valid):
        lon = (fps[k].lon[fps[k].ok] - ref + 180.0) % 360.0 - 180.0
        lat = fps[k].lat[fps[k].ok]
        box[k] = lon.min(), lon.max(), lat.min(), lat.max()
    idx = np.flatnonzero(valid)
    cand = _sweep(box[idx, 0], box[idx, 1], box[idx, 2], box[idx, 3])
    pairs = idx[cand] if cand.size else np.zeros((0, 2), np.intp)
    overlap = np.zeros(len(pairs))
    angle = np.full(len(pairs), np.nan)
    planes = {int(k): _Plane.of(fps[k]) for k in np.unique(pairs)}
    for m, (i, j) in enumerate(pairs.tolist()):  # per candidate pair: vectorised over its points
        inter, angle[m] = _pair_geometry(planes[i], planes[j])
        smaller = min(planes[i].area, planes[j].area)
        overlap[m] = min(1.0, inter / smaller) if smaller > 0 else 0.0
    status = np.full(len(pairs), "selected", dtype="<U11")
    status[~(overlap >= min_overlap) | (overlap <= 0)] = "overlap"
    with np.errstate(invalid="ignore"):
        bad_angle = ~((angle >= min_convergence_deg) & (angle <= hi))
    status[(status == "selected") & bad_angle] = "convergence"
    eligible = np.flatnonzero(status == "selected")
    if max_pairs_per_image is not None and eligible.size:
        keep = _capped(pairs[eligible], overlap[eligible], n, int(max_pairs_per_image))
        status[eligible[~keep]] = "cap"
    return PairGraph(tuple(names), pairs.astype(np.intp), overlap, angle, status, valid,
                     {"min_overlap": float(min_overlap),
                      "max_pairs_per_image": max_pairs_per_image,
                      "min_convergence_deg": float(min_convergence_deg),
                      "max_convergence_deg": max_convergence_deg, "grid": int(grid)})


def _capped(pairs: np.ndarray, weight: np.ndarray, n: int, cap: int) -> np.ndarray:
    """Which eligible pairs to keep: a maximum spanning forest (by ``weight``), then the
    others by decreasing weight (ties: by image indices) while both images are under ``cap``."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import minimum_spanning_tree

    # positive weights, smaller for larger overlaps (zero would mean "no edge" to scipy)
    w = 2.0 - weight
    tree = minimum_spanning_tree(coo_matrix((w, (pairs[:, 0], pairs[:, 1])), shape=(n, n)))
    t = tree.tocoo()
    t_key = np.minimum(t.row, t.col).astype(np.int64) * n + np.maximum(t.row, t.col)
    key = pairs[:, 0].astype(np.int64) * n + pairs[:, 1]
    keep = np.isin(key, t_key)
    degree = np.bincount(pairs[keep].ravel(), minlength=n)
    order = np.lexsort((pairs[:, 1], pairs[:, 0], -weight))
    for k in order[~keep[order]]:  # greedy over the remaining pairs (not points): sequential
        i, j = pairs[k]
        if degree[i] < cap and degree[j] < cap:
            keep[k] = True
            degree[i] += 1
            degree[j] += 1
    return keep
