"""A control source's common error *considered*: propagated into the posterior, not estimated.

A reference orthoimage's misregistration is one error shared by all the control points matched
on it (the ground CSV's ``sigma_shift_e/n/h`` per ``source``). It can be estimated, as three
unknowns per source with that prior (``control_shifts="estimate"``), but where nothing else in
the block sees absolute position (no surveyed GCP, no other source) it is unobservable next to
the images' own biases: the estimate is then made of the weak couplings the terrain and the
DEM rows give, which carry the DEM's and the models' systematic errors, and drifts by
metres. Considered (``control_shifts="consider"``, the default; Schmidt's *consider
covariance*), the block is adjusted with the sources held where they say they are, each
point weighted by its own sigma only, and the common error's covariance is added to every
posterior figure through the solution's sensitivity to it::

    C = C_adjusted + sum over sources and axes of sigma_shift**2 * d d^T

``d`` the change of the solution (parameters, points, the errors at check points, the ground
of each image's accuracy grid) when the source's control points are moved by 1 m along that
axis (local east, north or up at each point), measured by adjusting the block again with them
moved: exact for the linearised problem, and the same engine, options and robust weights
path as the solution itself (one more adjustment per source and axis). The adjusted block
is then registered to the sources exactly, and its stated accuracy is never better than
theirs (``sigma_shift`` is a stated prior: it is not scaled by sigma0).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING

import numpy as np

from geoblock import coords
from geoblock.adjust.observations import GroundPoints
from geoblock.adjust.problem import Block
from geoblock.adjust.results import BlockResult, SourceShift
from geoblock.typing import Float64Array

if TYPE_CHECKING:
    from geoblock.models.protocol import SensorModel

__all__ = ["CONSIDER_STEP_M", "consider_sources", "has_source_shifts"]

#: The control points' displacement of the sensitivity runs, metres: large against the
#: solution's numerical noise, small against the problem's nonlinearity (a few pixels).
CONSIDER_STEP_M = 1.0


def _shift_sigmas(ground: GroundPoints) -> Float64Array:
    return np.stack([ground.sigma_shift_e, ground.sigma_shift_n, ground.sigma_shift_h], -1)


def has_source_shifts(block: Block) -> bool:
    """The block's ground points state a common error for some source."""
    return block.ground is not None and bool(np.any(_shift_sigmas(block.ground) > 0))


def _ground(g: GroundPoints, lon: Float64Array, lat: Float64Array, h: Float64Array,
            shifts: bool) -> GroundPoints:
    zero = np.zeros(len(g))
    return GroundPoints(g.id, g.kind, lon, lat, h, g.sigma_e, g.sigma_n, g.sigma_h, g.source,
                        g.sigma_shift_e if shifts else zero, g.sigma_shift_n if shifts else zero,
                        g.sigma_shift_h if shifts else zero)


def _moved(g: GroundPoints, sel: np.ndarray, axis: int, metres: float) -> GroundPoints:
    """``g`` without shift sigmas, the points ``sel`` moved by ``metres`` along local axis
    ``axis`` (0 east, 1 north, 2 up)."""
    lon, lat, h = (np.array(a, dtype=np.float64) for a in (g.lon, g.lat, g.h))
    if axis == 2:
        h[sel] += metres
    else:
        ok = sel & np.isfinite(lon) & np.isfinite(lat)
        x, y, z = coords.geodetic_to_ecef(lon[ok], lat[ok], h[ok])
        unit = coords.enu_rotation(lon[ok], lat[ok])[:, axis, :]  # (P, 3) in ECEF
        moved = coords.ecef_to_geodetic(x + metres * unit[:, 0], y + metres * unit[:, 1],
                                        z + metres * unit[:, 2])
        lon[ok], lat[ok], h[ok] = moved.lon, moved.lat, moved.h
    return _ground(g, lon, lat, h, shifts=False)


def _enu(lon0: Float64Array, lat0: Float64Array, h0: Float64Array, lon1: Float64Array,
         lat1: Float64Array, h1: Float64Array) -> Float64Array:
    e, n, u = coords.enu_offsets(lon0, lat0, h0, lon1, lat1, h1)
    return np.nan_to_num(np.stack([e, n, u], -1))


def _grid_ground(block: Block, models: Mapping[str, SensorModel]) -> dict[str, Float64Array]:
    """The ground (lon, lat, h) (G, 3) of each image's accuracy grid nodes (NaN where the
    model does not reach the DEM), the nodes of :func:`geoblock.adjust._vertical.grid_covariances`."""
    from geoblock.adjust._vertical import GRID_NODES
    from geoblock.dem.intersect import localize

    out: dict[str, Float64Array] = {}
    if block.dem is None:
        return out
    for image, model in models.items():
        rows, cols = model.shape
        r, c = np.meshgrid(np.linspace(0, rows - 1, GRID_NODES),
                           np.linspace(0, cols - 1, GRID_NODES), indexing="ij")
        g, _ = localize(model, r.ravel(), c.ravel(), block.dem, warn=False)
        out[image] = np.stack([np.asarray(g.lon, float), np.asarray(g.lat, float),
                               np.asarray(g.h, float)], -1)
    return out


def consider_sources(block: Block, run: Callable[[Block], BlockResult]) -> BlockResult:
    """Adjust ``block`` with its sources' common errors considered (module docstring).

    Parameters
    ----------
    block : Block
        With ground points whose ``sigma_shift_*`` are nonzero for some source.
    run : callable
        Adjusts a block (:func:`geoblock.adjust.adjust` with the caller's options and
        ``control_shifts="estimate"``).

    Returns
    -------
    BlockResult
        The adjustment with the sources held fixed, its covariances (parameters, points,
        check points' predicted errors, accuracy grids) grown by the sources' common errors,
        and :attr:`~BlockResult.shifts` stating each source's considered error (value 0,
        sigma the prior, solution ``"considered"``).
    """
    g = block.ground
    assert g is not None
    sig = _shift_sigmas(g)
    fixed = dataclasses.replace(block, ground=_ground(g, g.lon, g.lat, g.h, shifts=False))
    base = run(fixed)
    n_par = base.covariance.shape[0]
    index = {key: k for k, key in enumerate(base.parameter_index)}
    values0 = np.zeros(n_par)
    for image, est in base.parameters.items():
        for name, value in zip(est.names, est.values, strict=True):
            values0[index[(image, name)]] = value
    grid0 = _grid_ground(block, dict(base.models))
    cov = np.array(base.covariance, dtype=np.float64)
    pts_cov = np.array(base.points.covariance, dtype=np.float64)
    check_cov = (np.array(base.predicted_covariance, dtype=np.float64)
                 if base.predicted_covariance is not None else None)
    grid_cov = {i: np.array(c, dtype=np.float64) for i, c in base.grid_covariance.items()}
    shifts: dict[str, SourceShift] = {}
    notes = list(base.notes)
    affected = (sig > 0).any(axis=1)
    for source in dict.fromkeys(g.source[affected].tolist()):
        sel = g.source == source
        prior = sig[sel].max(axis=0)
        for axis in range(3):
            if prior[axis] <= 0:
                continue
            moved = run(dataclasses.replace(fixed, ground=_moved(g, sel, axis, CONSIDER_STEP_M)))
            s2 = prior[axis] ** 2 / CONSIDER_STEP_M ** 2
            d_par = np.zeros(n_par)
            for image, est in moved.parameters.items():
                for name, value in zip(est.names, est.values, strict=True):
                    k = index.get((image, name))
                    if k is not None:
                        d_par[k] = value - values0[k]
            cov += s2 * np.outer(d_par, d_par)
            p0, p1 = base.points, moved.points
            d_pts = _enu(p0.lon, p0.lat, p0.h, p1.lon, p1.lat, p1.h)
            pts_cov += s2 * np.einsum("ji,jk->jik", d_pts, d_pts)
            if check_cov is not None and len(base.check.id):
                d_chk = np.nan_to_num(np.stack([moved.check.e - base.check.e,
                                                moved.check.n - base.check.n], -1))
                check_cov += s2 * np.einsum("ji,jk->jik", d_chk, d_chk)
            grid1 = _grid_ground(block, dict(moved.models))
            for image, c in grid_cov.items():
                a, b = grid0.get(image), grid1.get(image)
                if a is None or b is None:
                    continue
                ok = np.all(np.isfinite(a), axis=1)
                if ok.sum() != c.shape[0]:
                    continue
                d = _enu(a[ok, 0], a[ok, 1], a[ok, 2], b[ok, 0], b[ok, 1], b[ok, 2])[:, :2]
                c += s2 * np.einsum("ji,jk->jik", d, d)
        lon = float(np.nanmean(g.lon[sel])) if np.isfinite(g.lon[sel]).any() else float("nan")
        lat = float(np.nanmean(g.lat[sel])) if np.isfinite(g.lat[sel]).any() else float("nan")
        shifts[source] = SourceShift(
            source=source, solution="considered", values=np.zeros(3), sigmas=prior.copy(),
            prior_sigmas=prior.copy(), covariance=np.diag(prior ** 2), lon=lon, lat=lat,
            h=float(np.nanmean(g.h[sel])), n_points=int(sel.sum()))
        notes.append(f"control source {source}: its common error (sigma_shift "
                     f"{'/'.join(f'{v:g}' for v in prior)} m east/north/up) is considered, not "
                     "estimated: the block is registered to it and every posterior figure "
                     "includes it")
    parameters = {}
    for image, est in base.parameters.items():
        rows = np.array([index[(image, n)] for n in est.names], dtype=np.intp)
        parameters[image] = dataclasses.replace(
            est, sigmas=np.sqrt(np.diag(cov)[rows]) if rows.size else est.sigmas)
    predicted_sigma = base.predicted_sigma
    if check_cov is not None:
        predicted_sigma = np.sqrt(np.einsum("jii->ji", check_cov))
    return dataclasses.replace(
        base, covariance=cov, parameters=parameters,
        points=dataclasses.replace(base.points, covariance=pts_cov),
        predicted_covariance=check_cov, predicted_sigma=predicted_sigma,
        grid_covariance=grid_cov, shifts=shifts, notes=notes)

