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
* the check point's own survey error (and its source's common error), added on the diagonal.
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
    cov = cov + survey[:, :, None] * np.eye(3)
    return VerticalCheck(id=t.id.astype(str), rays=t.rays, e=de, n=dn, u=du,
                         covariance=np.where(ok[:, None, None], cov, np.nan),
                         status=t.status)


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
