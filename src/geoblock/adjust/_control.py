"""Ground control beyond independent surveyed points, for the block engine
(:mod:`geoblock.adjust._engine`): the error common to the points of one source (a reference
orthoimage's misregistration) as extra unknowns, and height control points (HCPs).

**Common shift of a source.** The points of a ``source`` whose ``sigma_shift_e/n/h`` are not
zero share an error: ``observed = true + shift + independent noise``. Weighted as independent,
``N`` such points would average the shift down to ``sigma / sqrt(N)``; it does not average out.
Each such source gets up to three unknowns, the shift along local east, north and up at the
source's centroid (one per axis whose sigma is > 0), with the prior ``N(0, sigma_shift**2)``
as a pseudo-observation. The ground observation of its GCP ``j`` becomes
``g_j = x_j + R_s t_s`` (local frame; ``R_s`` the source's ENU axes in the frame) and that of
its HCP ``h_j = h(x_j) + u_j . R_s t_s`` (``u_j`` the up direction at the point).

Those rows couple the point with the shift, as an image measurement couples a point with
its image's parameters: they enter the normal equations as *pseudo-measurements* (two rows
each, whitened), the shift unknowns appended to the parameter vector. The point reduction
(Schur complement), the dense and sparse solutions and the cofactors then carry them with
no special case, and the parameters' posterior covariance includes the shift's uncertainty.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from geoblock import coords
from geoblock.adjust.observations import GroundPoints
from geoblock.typing import BoolArray, Float64Array, IndexArray, StrArray

__all__: list[str] = []

AXES = ("e", "n", "h")


@dataclass
class SourceShifts:
    """The shift unknowns of one solution.

    Attributes
    ----------
    sources : tuple of str, (S,)
        The sources with a common error among the solution's GCPs and HCPs.
    first : int
        Global index of the first shift unknown (the models' parameters come before).
    index : ndarray of intp, (S, 3)
        Global index of each source's unknown per axis e, n, h (-1: that axis has none).
    prior_sigma : ndarray, (S, 3)
        The sources' ``sigma_shift_e, _n, _h``, metres.
    centroid : ndarray, (S, 3)
        lon, lat, h of each source's centroid (its points in the solution).
    rotation : ndarray, (S, 3, 3)
        Columns: the source's east, north, up axes in the solution's local frame.
    point_source : ndarray of intp, (J,)
        Source of each point of the solution (-1: none, or not shifted).
    cols : ndarray of intp, (J, 3)
        The shift unknowns of each point's source (-1 padding).
    axes : ndarray, (J, 3, 3)
        ``R_s`` restricted to those unknowns' axes (zero columns in the padding): the
        offset of point ``j`` in the frame is ``axes[j] @ x[cols[j]]``.
    n_points : ndarray of intp, (S,)
        Points of each source in the solution.
    """

    sources: tuple[str, ...]
    first: int
    index: IndexArray
    prior_sigma: Float64Array
    centroid: Float64Array
    rotation: Float64Array
    point_source: IndexArray
    cols: IndexArray
    axes: Float64Array
    n_points: IndexArray

    @property
    def count(self) -> int:
        """Number of shift unknowns."""
        return int(np.sum(self.index >= 0))

    @property
    def shifted(self) -> BoolArray:
        """(J,) points whose observation carries a source's shift."""
        return self.point_source >= 0

    def labels(self) -> list[str]:
        """``shift:<source>:<axis>`` of each unknown, in order."""
        out = [""] * self.count
        for s, source in enumerate(self.sources):
            for a, axis in enumerate(AXES):
                if self.index[s, a] >= 0:
                    out[self.index[s, a] - self.first] = f"shift:{source}:{axis}"
        return out

    def offsets(self, x: Float64Array) -> Float64Array:
        """(J, 3) each point's shift in the local frame at parameters ``x``."""
        t = np.where(self.cols >= 0, x[np.maximum(self.cols, 0)], 0.0)
        return np.einsum("jik,jk->ji", self.axes, t)


def source_shifts(ground: GroundPoints | None, p_id: StrArray, p_kind: StrArray,
                  lon: Float64Array, lat: Float64Array, h: Float64Array,
                  frame: coords.LocalFrame, first: int) -> SourceShifts | None:
    """The shift unknowns of the solution's points ``p_id`` (kinds ``p_kind``, initial
    positions ``lon, lat, h`` (J,)), numbered from ``first``; None when no GCP or HCP source
    has a shift sigma (the engine then runs exactly as without the feature)."""
    if ground is None or not np.any(ground.shift_sigmas > 0):
        return None
    from geoblock.adjust.observations import lookup

    g = lookup(ground.id, p_id)
    control = np.isin(p_kind, ("gcp", "hcp")) & (g >= 0)
    sig = np.where(control[:, None], ground.shift_sigmas[np.maximum(g, 0)], 0.0)
    shifted = control & np.any(sig > 0, axis=1)
    if not shifted.any():
        return None
    src = np.where(shifted, ground.source[np.maximum(g, 0)], "")
    sources, inverse = np.unique(src[shifted], return_inverse=True)
    n_src = sources.size
    point_source = np.full(p_id.size, -1, np.intp)
    point_source[shifted] = inverse
    prior = np.zeros((n_src, 3))
    prior[inverse] = sig[shifted]  # equal within a source (GroundPoints checks)
    has = prior > 0
    index = np.full((n_src, 3), -1, np.intp)
    index[has] = first + np.arange(int(has.sum()))
    # centroid of each source's points (ECEF mean), for its ENU axes
    xyz = np.stack(coords.geodetic_to_ecef(lon[shifted], lat[shifted], h[shifted]), -1)
    sums = np.zeros((n_src, 3))
    np.add.at(sums, inverse, xyz)
    n_points = np.bincount(inverse, minlength=n_src)
    mean = sums / n_points[:, None]
    c_lon, c_lat, c_h = (np.asarray(v) for v in coords.ecef_to_geodetic(
        mean[:, 0], mean[:, 1], mean[:, 2]))
    # columns: east, north, up of the source's centroid, expressed in the local frame
    rotation = frame.rotation @ np.swapaxes(coords.enu_rotation(c_lon, c_lat), 1, 2)
    ps = np.maximum(point_source, 0)
    cols = np.where(shifted[:, None], index[ps], -1)
    axes = np.where((cols >= 0)[:, None, :], rotation[ps], 0.0)
    return SourceShifts(
        sources=tuple(str(s) for s in sources), first=first, index=index, prior_sigma=prior,
        centroid=np.stack([c_lon, c_lat, c_h], -1), rotation=rotation,
        point_source=point_source, cols=cols, axes=axes, n_points=n_points)


def pseudo_measurements(shifts: SourceShifts, is_gcp: BoolArray, g_chol_t: Float64Array,
                        g_residual: Float64Array, hcp_grad: Float64Array,
                        hcp_misclosure: Float64Array, hcp_sigma: Float64Array,
                        ) -> tuple[IndexArray, Float64Array, Float64Array, IndexArray,
                                   Float64Array]:
    """The whitened rows of the shifted points' ground observations, two pseudo-measurements
    of two rows per point.

    Parameters
    ----------
    shifts : SourceShifts
    is_gcp : ndarray of bool, (J,)
        GCPs (three rows: ``g_j - x_j - R t``); the other shifted points are HCPs (one row:
        ``h_j - h(x_j) - u_j . R t``, and two zero rows).
    g_chol_t : ndarray, (J, 3, 3)
        ``L^T`` with ``L L^T`` the ground weight of each point.
    g_residual : ndarray, (J, 3)
        ``g - x - offset`` of each point (local frame).
    hcp_grad, hcp_misclosure, hcp_sigma : ndarray, (J, 3), (J,), (J,)
        The HCP height rows: ``d h / d x``, ``h_obs - h(x) - offset_up``, sigma.

    Returns
    -------
    point : ndarray of intp, (2P,)
        The point of each pseudo-measurement.
    a : ndarray, (2P, 2, 3)
        Whitened partials in the shift columns ``cols`` (2P, 3).
    b : ndarray, (2P, 2, 3)
        Whitened point partials.
    cols : ndarray of intp, (2P, 3)
    v : ndarray, (2P, 2)
        Whitened misclosures.
    """
    j = np.flatnonzero(shifts.shifted)
    gcp = is_gcp[j]
    rows_b = np.zeros((j.size, 4, 3))  # 3 rows and a zero row, split into two pairs
    rows_v = np.zeros((j.size, 4))
    rows_b[gcp, :3] = g_chol_t[j[gcp]]
    rows_v[gcp, :3] = np.einsum("jik,jk->ji", g_chol_t[j[gcp]], g_residual[j[gcp]])
    h = ~gcp
    with np.errstate(invalid="ignore", divide="ignore"):
        w = np.where(np.isfinite(hcp_misclosure[j[h]]), 1.0 / hcp_sigma[j[h]], 0.0)
    rows_b[h, 0] = hcp_grad[j[h]] * w[:, None]
    rows_v[h, 0] = np.nan_to_num(hcp_misclosure[j[h]]) * w
    # computed = x + axes @ t: the shift partials are the point partials times the axes
    rows_a = rows_b @ shifts.axes[j]
    point = np.repeat(j, 2)
    return (point, rows_a.reshape(-1, 2, 3), rows_b.reshape(-1, 2, 3),
            np.repeat(shifts.cols[j], 2, axis=0), rows_v.reshape(-1, 2))


def padded_columns(a: Float64Array, cols: IndexArray, pa: Float64Array, pcols: IndexArray,
                   ) -> tuple[Float64Array, IndexArray]:
    """Rows ``a`` (M, 2, Kc) with their columns ``cols`` (M, Kc) and the pseudo-measurements'
    ``pa`` (P, 2, Kp), ``pcols`` (P, Kp) stacked, both padded to ``max(Kc, Kp)`` columns
    (zero partials, column -1)."""
    kc = max(cols.shape[1], pcols.shape[1])

    def pad(arr: NDArray[Any], fill: float) -> NDArray[Any]:
        extra = kc - arr.shape[-1]
        if extra == 0:
            return arr
        return np.concatenate([arr, np.full((*arr.shape[:-1], extra), fill, arr.dtype)], -1)

    return (np.concatenate([pad(a, 0.0), pad(pa, 0.0)]),
            np.concatenate([pad(cols, -1), pad(pcols, -1)]))
