"""Refinement studies on simulated points: Aguilar et al.'s RMSE-versus-GCP-count curves and
their residual-versus-distance figure, for any model and image-space correction.

An image-space correction of order 0 or 1 (:class:`~geoblock.models.ImageCorrection`: the
RPCV-0 shift and RPCV-1 affine refinements of Grodecki & Dial, applied here to whatever model
the image has, e.g. a simulated on-board physical model) is fitted to GCPs by
:func:`geoblock.adjust.resect`; its accuracy is the ground error at the ICPs: the ICP's true
image position backprojected through the refined model at the true height, minus the true
ground position (local east/north metres, :func:`geoblock.adjust.ground_errors`), the same
measure as the on-board model's error in a simulated block's report
(:func:`onboard_errors`). :func:`refinement_points` takes one image's GCPs and ICPs out of a
:class:`~geoblock.simulate.points.PointSet`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from geoblock.adjust import ControlPoints, PointErrors, ground_errors, resect
from geoblock.errors import GeoblockError
from geoblock.models import ImageCorrection, SensorModel
from geoblock.simulate.points import PointSet
from geoblock.typing import ArrayLike

__all__ = ["CheckPoints", "GcpCountStudy", "gcp_count_study", "onboard_errors",
           "refined_errors", "refinement_points"]

#: Correction orders and the papers' names for them on an RPC.
ORDER_NAMES = {0: "RPCV-0 (shift)", 1: "RPCV-1 (affine)", 2: "order 2"}


@dataclass(frozen=True)
class CheckPoints:
    """ICPs of one image with their truth.

    Attributes
    ----------
    lon, lat, h : ndarray, (M,)
        True ground position, degrees and metres above the ellipsoid.
    row, col : ndarray, (M,)
        True image position, pixels.
    """

    lon: np.ndarray
    lat: np.ndarray
    h: np.ndarray
    row: np.ndarray
    col: np.ndarray


def refined_errors(model: SensorModel, gcps: ControlPoints, icps: CheckPoints,
                   order: int) -> np.ndarray:
    """2D ground error (m) at the ICPs of ``model`` refined by an order-``order`` image-space
    correction fitted to ``gcps``.

    Returns
    -------
    ndarray, (M,)
        ``hypot(dE, dN)`` per ICP, metres; NaN where the refined model does not backproject.
    """
    refined = resect(ImageCorrection(model, order), gcps).model
    est = refined.backproject(icps.row, icps.col, icps.h)
    de, dn, _ = ground_errors(est.lon, est.lat, icps.lon, icps.lat, h=icps.h, h_ref=icps.h)
    return np.hypot(de, dn)


@dataclass(frozen=True)
class GcpCountStudy:
    """Result of :func:`gcp_count_study`.

    Attributes
    ----------
    counts : ndarray, (K,)
        Numbers of GCPs.
    rmse_m : dict of int to ndarray (R, K)
        Per correction order: RMSE 2D at the ICPs, metres, for each of ``R`` random GCP
        subsets of each size (NaN where the fit failed).
    """

    counts: np.ndarray
    rmse_m: dict[int, np.ndarray]

    def series(self) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """The input of :func:`geoblock.report.rmse_vs_gcp_count`, one line per order."""
        return {ORDER_NAMES.get(o, f"order {o}"): (self.counts, r) for o, r in self.rmse_m.items()}

    def table(self) -> str:
        """Markdown: mean (and spread) of the RMSE per order and GCP count."""
        head = "| GCPs | " + " | ".join(ORDER_NAMES.get(o, f"order {o}") for o in self.rmse_m)
        lines = [head + " |", "|---:|" + "---:|" * len(self.rmse_m)]
        for k, n in enumerate(self.counts):
            cells = []
            for r in self.rmse_m.values():
                col = r[:, k][np.isfinite(r[:, k])]
                cells.append(f"{col.mean():.2f} ({col.min():.2f}-{col.max():.2f})" if col.size
                             else "-")
            lines.append(f"| {int(n)} | " + " | ".join(cells) + " |")
        return "\n".join(lines) + "\n"


def gcp_count_study(
    model: SensorModel,
    gcps: ControlPoints,
    icps: CheckPoints,
    *,
    orders: tuple[int, ...] = (0, 1),
    counts: ArrayLike = (3, 6, 9, 18, 27, 45),
    repeats: int = 10,
    seed: int = 0,
) -> GcpCountStudy:
    """RMSE 2D at the ICPs after refining ``model`` with random subsets of the GCPs (Aguilar
    et al. Figs. 3, 6 and 7: how many GCPs a refinement needs).

    Parameters
    ----------
    model : SensorModel
        The image's model before refinement (e.g. a simulated on-board model).
    gcps : ControlPoints
        All GCPs available (measured ground and image coordinates, with their sigmas).
    icps : CheckPoints
        Check points with their truth.
    orders : tuple of int
        Image-space correction orders (0: RPCV-0, 1: RPCV-1).
    counts : array_like of int
        Subset sizes; sizes above ``len(gcps)`` are dropped, sizes below an order's minimum
        give NaN for that order.
    repeats : int
        Random subsets per size (all GCPs once when the size is ``len(gcps)``).
    seed : int
        Seed of the subsets.

    Returns
    -------
    GcpCountStudy

    Raises
    ------
    GeoblockError
        No usable count, or ``repeats < 1``.
    """
    counts = np.array([int(c) for c in np.atleast_1d(counts) if 1 <= int(c) <= len(gcps)])
    if counts.size == 0 or repeats < 1:
        raise GeoblockError(f"gcp_count_study: no GCP count in 1..{len(gcps)} or repeats < 1 "
                            f"(counts {counts.tolist()}, repeats {repeats})")
    rng = np.random.default_rng(seed)
    subsets = [[np.sort(rng.choice(len(gcps), n, replace=False)) for n in counts]
               for _ in range(repeats)]
    out = {}
    for order in orders:
        rmse = np.full((repeats, counts.size), np.nan)
        for r in range(repeats):
            for k, idx in enumerate(subsets[r]):
                if r > 0 and counts[k] == len(gcps):
                    rmse[r, k] = rmse[0, k]  # the full set is one subset
                    continue
                try:
                    err = refined_errors(model, gcps.subset(idx), icps, order)
                except GeoblockError:  # too few GCPs for the order, or a singular geometry
                    continue
                rmse[r, k] = float(np.sqrt(np.nanmean(err**2)))
        out[int(order)] = rmse
    return GcpCountStudy(counts, out)


def _point_index(points: PointSet, ids: np.ndarray) -> np.ndarray:
    """Row of each of ``ids`` in ``points.ground``."""
    index = {pid: i for i, pid in enumerate(points.ground.id.tolist())}
    return np.array([index[i] for i in ids.tolist()], dtype=np.intp)


def onboard_errors(sensors: Mapping[str, Any], points: PointSet) -> PointErrors:
    """Ground errors of the on-board models at the GCP and ICP measurements.

    The true image position of each measurement is backprojected through its image's
    on-board model at the point's true height and compared with the true ground position:
    the error of the model alone (no pointing, survey or DEM error), in local east/north
    metres.

    Parameters
    ----------
    sensors : mapping of str to SimulatedSensor
        By image name (anything with an ``onboard_model``).
    points : PointSet

    Returns
    -------
    PointErrors
        One row per GCP/ICP measurement, kinds ``GCP`` and ``ICP``, with its image.
    """
    m, g = points.image, points.ground
    keep = np.flatnonzero(np.isin(m.kind, ("gcp", "icp")))
    k = _point_index(points, m.id[keep])
    lon = np.full(keep.size, np.nan)
    lat = np.full(keep.size, np.nan)
    h_true = g.h_true[k]
    for image_id, sim in sensors.items():  # a loop over images, not points
        sel = np.flatnonzero(m.image[keep] == image_id)
        if sel.size:
            est = sim.onboard_model.backproject(m.row_true[keep][sel], m.col_true[keep][sel],
                                                h_true[sel])
            lon[sel], lat[sel] = est.lon, est.lat
    return PointErrors.from_ground(m.id[keep], np.char.upper(m.kind[keep].astype(str)), lon,
                                   lat, g.lon_true[k], g.lat_true[k], h=h_true, h_ref=h_true,
                                   image=m.image[keep])


def refinement_points(points: PointSet,
                      image_id: str) -> tuple[ControlPoints | None, CheckPoints | None]:
    """One image's points for a refinement study: its GCPs as measured and surveyed
    (:class:`~geoblock.adjust.ControlPoints`, with their sigmas) and its ICPs with their
    truth (:class:`CheckPoints`); None for a kind the image does not have."""
    m, g = points.image, points.ground
    gcps: ControlPoints | None = None
    icps: CheckPoints | None = None
    sel = np.flatnonzero((m.image == image_id) & (m.kind == "gcp"))
    if sel.size:
        k = _point_index(points, m.id[sel])
        gcps = ControlPoints(id=m.id[sel], lon=g.lon[k], lat=g.lat[k], h=g.h[k],
                             row=m.row[sel], col=m.col[sel], sigma_row=m.sigma[sel],
                             sigma_col=m.sigma[sel], sigma_e=g.sigma_e[k],
                             sigma_n=g.sigma_n[k], sigma_h=g.sigma_h[k])
    sel = np.flatnonzero((m.image == image_id) & (m.kind == "icp"))
    if sel.size:
        k = _point_index(points, m.id[sel])
        icps = CheckPoints(g.lon_true[k], g.lat_true[k], g.h_true[k], m.row_true[sel],
                           m.col_true[sel])
    return gcps, icps
