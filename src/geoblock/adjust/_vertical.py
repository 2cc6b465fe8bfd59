"""Vertical check of a block adjustment: ICPs measured in two images or more intersected
through the adjusted models (:func:`geoblock.triangulation.triangulate`), their 3D error
against the surveyed point, and its covariance predicted to first order.

The predicted covariance of an intersected point (local east, north, up at the point) is the
linearised propagation of

* the image measurement noise: ``N^-1`` with ``N = sum_m B_m^T W_m B_m`` (``B_m`` the
  partials of measurement ``m`` in the point's ENU, ``W_m`` its weight);
* the adjusted parameters' posterior covariance ``Q`` (cross-image terms included, so a
  common error of the images is not averaged out): ``T Q T^T`` with
  ``T = sum_m N^-1 B_m^T W_m A_m`` and ``A_m`` the measurement's parameter partials;
* the check point's own survey error (and its source's common error), added on the diagonal;
* where the block's heights rest on the DEM alone (:func:`dem_common_sigma`), the DEM's error
  as an error common to the whole block, ``sigma_DEM**2`` on the vertical.

Why the last term: the engine weighs every height it takes from the DEM (each tie point's DEM
row, and the reference control's heights, which are the DEM's) as an independent observation,
so its posterior averages the DEM's error over hundreds of points. A DEM's error is spatially
correlated (a global DEM's over kilometres), and its part common to the block moves every
adjusted height metre for metre (measured: 1.000 m per metre of DEM on the study's 4-image
RPC block and on affine blocks): no number of points reduces it. On that RPC block
(``geoblock experiment reference``, a 30 m DEM of RMSEz 4 m correlated over 300 m) the
intersected ICPs' mean height error was +1.0 to +3.5 m in each of 20 repetitions (-0.1 to
-0.5 m on the true DEM, -0.4 to +0.3 m on a white-noise DEM of the same RMSEz, 4 seeds) while
the posterior said 0.6 m RMS.
The DEM's stated RMSEz is taken whole as the common part: the honest figure when nothing but
the DEM fixes the block's heights, pessimistic for a DEM whose error decorrelates within the
block. Where better height control exists the term is not added, though the DEM rows may
still pull the heights in part (0.37 m per metre of DEM on an affine block with 32 surveyed
GCPs of sigma_h 0.5 m and DEM control ``observation``, 0 with ``none``): measuring that needs
one more adjustment with the DEM raised, which this function cannot run.

What no term here can hold: image errors the adjusted model cannot represent (a linescan's
look-angle table and attitude wander under an RPC with an affine correction: 0.03/0.10 px
RMS along rows/columns in the simulated SPOT-5 views) reach the heights amplified by the
height-to-base ratio, and the posterior, conditional on the model, does not see them.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from geoblock import coords
from geoblock.adjust.observations import lookup
from geoblock.adjust.problem import Block
from geoblock.adjust.results import VerticalCheck
from geoblock.models.protocol import SensorModel
from geoblock.typing import Float64Array, Status

__all__: list[str] = []


def vertical_check(block: Block, models: Mapping[str, SensorModel],
                   adjusted: Mapping[str, SensorModel], covariance: Float64Array,
                   parameter_index: Sequence[tuple[str, str]]) -> VerticalCheck | None:
    """The :class:`VerticalCheck` of the block's ICPs measured in two images or more of
    ``models`` (None when there is none)."""
    from geoblock.triangulation import triangulate

    meas = block.measurements
    ground = block.ground
    if ground is None:
        return None
    sel = (meas.kind == "icp") & np.isin(meas.image, list(models))
    ids, counts = np.unique(meas.id[sel], return_counts=True)
    multi = ids[counts >= 2]
    if multi.size == 0:
        return None
    rows = np.flatnonzero(sel & np.isin(meas.id, multi))
    image = meas.image[rows]
    sigma = np.stack([meas.sigma_row[rows], meas.sigma_col[rows]], -1)
    t = triangulate(dict(models), meas.id[rows], image, meas.row[rows], meas.col[rows],
                    sigma_px=np.sqrt(0.5 * np.sum(sigma**2, axis=1)), warn=False)
    g = lookup(ground.id, t.id)
    good = t.status == Status.CONVERGED
    de, dn, du = (np.where(good, v, np.nan) for v in coords.enu_offsets(
        ground.lon[g], ground.lat[g], ground.h[g], t.lon, t.lat, t.h))
    # first-order propagation at the intersected point
    p = t.point
    k_all = covariance.shape[0]
    position = {(str(i), str(n)): k for k, (i, n) in enumerate(parameter_index)}
    b = np.full((rows.size, 2, 3), np.nan)
    a = np.zeros((rows.size, 2, k_all))
    for name, model in adjusted.items():
        m = np.flatnonzero(image == name)
        if m.size == 0:
            continue
        lon, lat, h = t.lon[p[m]], t.lat[p[m]], t.h[p[m]]
        b[m] = model.partials_ground(lon, lat, h) @ np.swapaxes(
            coords.enu_rotation(lon, lat), 1, 2)
        cols = np.array([position.get((str(name), n), -1) for n in model.parameters.names],
                        dtype=np.intp)
        have = np.flatnonzero(cols >= 0)
        if have.size:
            part = model.partials_parameters(lon, lat, h)[..., have]
            a[np.ix_(m, np.arange(2), cols[have])] = part
    w = 1.0 / sigma**2  # (K, 2)
    bw_t = np.swapaxes(b * w[:, :, None], 1, 2)  # (K, 3, 2): B^T W
    normal = np.zeros((t.id.size, 3, 3))
    np.add.at(normal, p, bw_t @ b)
    ok = good & np.isfinite(normal).all(axis=(1, 2))
    n_inv = np.full(normal.shape, np.nan)
    if ok.any():
        n_inv[ok] = np.linalg.inv(normal[ok])
    gain = n_inv[p] @ bw_t  # (K, 3, 2)
    t_mat = np.zeros((t.id.size, 3, k_all))
    np.add.at(t_mat, p, gain @ a)
    cov = n_inv + t_mat @ covariance @ np.swapaxes(t_mat, 1, 2)
    survey = np.stack([ground.sigma_e[g], ground.sigma_n[g], ground.sigma_h[g]], -1) ** 2
    survey = survey + ground.shift_sigmas[g] ** 2
    survey[:, 2] += dem_common_sigma(block) ** 2
    cov = cov + survey[:, :, None] * np.eye(3)
    return VerticalCheck(id=t.id.astype(str), rays=t.rays, e=de, n=dn, u=du,
                         covariance=np.where(ok[:, None, None], cov, np.nan),
                         status=t.status)


def dem_common_sigma(block: Block) -> float:
    """The sigma (metres) of the DEM's error common to the block that its intersected heights
    inherit (module docstring): the block's ``dem_sigma_m`` where its heights rest on the DEM
    alone, 0 where they do not.

    They rest on the DEM when the block has one and no control point (kind ``gcp`` or
    ``hcp``) states a height sigma below the DEM's: the tie points' DEM rows, and control
    whose heights are no better than the DEM (a reference's control, located on it), are then
    all the height information the block has, and a common error of the DEM moves the whole
    solution with it. Where better heights exist (surveyed GCPs, ICESat-2 or lidar HCPs), the
    block's heights follow them at least in part: how much depends on the geometry, and the
    term is not added (the posterior states what those points give).
    """
    if block.dem is None:
        return 0.0
    sigma = float(block.dem_sigma_m)
    g = block.ground
    if g is not None:
        kind = np.char.lower(np.asarray(g.kind).astype(str))
        sh = np.asarray(g.sigma_h, dtype=np.float64)[(kind == "gcp") | (kind == "hcp")]
        if np.any(np.isfinite(sh) & (sh < sigma)):
            return 0.0
    return sigma


#: nodes per image axis of the grid the ICP-free CE90 is predicted over
GRID_NODES = 9


def grid_covariances(block: Block, adjusted: Mapping[str, SensorModel],
                     q_by_image: Mapping[str, tuple[Sequence[str], Float64Array]],
                     ) -> dict[str, Float64Array]:
    """Per image, the predicted east/north covariance (G, 2, 2) of the ground point of a
    ``GRID_NODES`` x ``GRID_NODES`` grid of image points located on the DEM through the
    adjusted model: its parameters' posterior covariance and the DEM's sigma propagated to
    the ground (:func:`geoblock.models.uncertainty.ground_error`), no image-measurement
    term (what an ortho pixel carries). Empty without a DEM."""
    from geoblock.dem.intersect import localize
    from geoblock.models.uncertainty import ground_error

    out: dict[str, Float64Array] = {}
    if block.dem is None:
        return out
    for image, model in adjusted.items():
        names, cov = q_by_image.get(image, ((), np.zeros((0, 0))))
        rows, cols = model.shape
        r, c = np.meshgrid(np.linspace(0, rows - 1, GRID_NODES),
                           np.linspace(0, cols - 1, GRID_NODES), indexing="ij")
        g, status = localize(model, r.ravel(), c.ravel(), block.dem, warn=False)
        ok = status == Status.CONVERGED
        if not ok.any():
            continue
        err = ground_error(model, names, cov, ground=(g.lon[ok], g.lat[ok], g.h[ok]),
                           dem_sigma=block.dem_sigma_m)
        out[image] = err.covariance
    return out
