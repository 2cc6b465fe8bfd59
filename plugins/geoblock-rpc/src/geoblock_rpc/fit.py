"""Sensor-oriented RPCs: fit an RPC00B to any sensor model (terrain-independent fit).

The image is covered by a regular grid of ``(row, col)`` nodes, each backprojected through the
model onto several constant-height surfaces spanning the height range. That 3D grid of
``(lon, lat, h) <-> (row, col)`` correspondences is fitted by the 78 free coefficients of an
RPC00B (each denominator's constant term fixed at 1), as in Tao & Hu (2001): for the row,

    Y = N(T) / D(T),   D(T) = 1 + d . T[1:]    ->    N(T) - Y (d . T[1:]) = Y

is linear in the unknowns. It is solved by least squares, reweighted by ``1 / D(T)`` of the
previous iteration (so the minimised quantity tends to the true image residual ``Y - N / D``),
with an optional Tikhonov term ``lambda * |x|^2`` (on the column-scaled unknowns) for the
ill-conditioning of models whose true form has fewer terms than a full cubic ratio. The
normalisation offsets and scales come from the grid. The accuracy is measured on an
independent, denser check grid (nodes between the fit nodes, at heights between the fit
heights), in pixels.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np

from geoblock.errors import AdjustmentError, GeoblockWarning
from geoblock.models.protocol import SensorModel
from geoblock.typing import Status
from geoblock_rpc.rational import solve_ratios
from geoblock_rpc.rpc00b import Rpc00b, evaluate_terms, wrap_longitude

__all__ = ["FitStats", "check_grid", "fit_rpc", "image_grid"]


@dataclass(frozen=True)
class FitStats:
    """Accuracy of a fitted RPC, pixels.

    Attributes
    ----------
    rms_px, max_px : float
        RMS and maximum of the 2D image error ``hypot(drow, dcol)`` on the independent check
        grid (the figures to quote).
    rms_row_px, rms_col_px : float
        RMS of the row and column errors on the check grid.
    fit_rms_px, fit_max_px : float
        The same on the fit grid itself.
    n_fit, n_check : int
        Grid points used (points the model could not backproject are dropped).
    iterations : int
        Reweighting iterations run.
    regularization : float
        Tikhonov weight of the last iteration (on the unit-norm columns; 0: none).
    condition : float
        Condition number of the column-scaled design (without the Tikhonov term).
    grid, check : tuple of int
        ``(rows, cols, heights)`` nodes of the fit and check grids.
    """

    rms_px: float
    max_px: float
    rms_row_px: float
    rms_col_px: float
    fit_rms_px: float
    fit_max_px: float
    n_fit: int
    n_check: int
    iterations: int
    regularization: float
    condition: float
    grid: tuple[int, int, int]
    check: tuple[int, int, int]

    def __str__(self) -> str:
        return (
            f"RPC fit: check-grid error RMS {self.rms_px:.3g} px, max {self.max_px:.3g} px "
            f"({self.n_check} points); fit grid RMS {self.fit_rms_px:.3g} px "
            f"({self.n_fit} points, {self.iterations} iterations, regularization "
            f"{self.regularization:.3g})"
        )


def image_grid(
    shape: tuple[int, int], height_range: tuple[float, float], grid: tuple[int, int, int]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Fit-grid nodes covering the image extent and the height range.

    Parameters
    ----------
    shape : (int, int)
        ``(rows, cols)``; the nodes span ``[-0.5, rows - 0.5] x [-0.5, cols - 0.5]`` pixels.
    height_range : (float, float)
        Metres above the ellipsoid.
    grid : (int, int, int)
        Nodes along rows, columns and heights (each >= 2).

    Returns
    -------
    row, col, h : ndarray, (grid[0] * grid[1] * grid[2],)
    """
    nr, nc, nh = (int(n) for n in grid)
    if min(nr, nc, nh) < 2:
        raise ValueError(f"grid needs at least 2 nodes per axis, got {grid}")
    r = np.linspace(-0.5, shape[0] - 0.5, nr)
    c = np.linspace(-0.5, shape[1] - 0.5, nc)
    h = np.linspace(height_range[0], height_range[1], nh)
    rr, cc, hh = np.meshgrid(r, c, h, indexing="ij")
    return rr.ravel(), cc.ravel(), hh.ravel()


def check_grid(
    shape: tuple[int, int], height_range: tuple[float, float], grid: tuple[int, int, int]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """An independent check grid, denser than the fit ``grid`` and disjoint from its nodes.

    ``2 (n - 1)`` nodes per axis, at the centres of ``2 (n - 1)`` equal cells: every check
    node lies strictly between fit nodes (rows, columns and heights alike).

    Returns
    -------
    row, col, h : ndarray, (8 (nr - 1)(nc - 1)(nh - 1),)
    """
    axes = []
    for n, (lo, hi) in zip(grid, ((-0.5, shape[0] - 0.5), (-0.5, shape[1] - 0.5), height_range),
                           strict=True):
        m = 2 * (int(n) - 1)
        axes.append(lo + (hi - lo) * (np.arange(m) + 0.5) / m)
    rr, cc, hh = np.meshgrid(*axes, indexing="ij")
    return rr.ravel(), cc.ravel(), hh.ravel()


def _ground(model: SensorModel, row, col, h, what: str):
    (lon, lat, hh), status = model.backproject_with_status(row, col, h)
    ok = (status == Status.CONVERGED) & np.isfinite(lon) & np.isfinite(lat)
    if ok.sum() < 0.5 * ok.size:
        raise AdjustmentError(
            f"fit_rpc: the model could backproject only {int(ok.sum())} of the {ok.size} "
            f"{what} points; check the image shape and the height range"
        )
    if not ok.all():
        warnings.warn(
            f"fit_rpc: {int((~ok).sum())} of the {ok.size} {what} points could not be "
            "backprojected and were left out",
            GeoblockWarning,
            stacklevel=3,
        )
    return lon[ok], lat[ok], np.asarray(h, float)[ok], np.asarray(row)[ok], np.asarray(col)[ok]


def fit_rpc(
    model: SensorModel,
    shape: tuple[int, int] | None = None,
    height_range: tuple[float, float] | None = None,
    grid: tuple[int, int, int] = (21, 21, 9),
    *,
    regularization: float | str = "gcv",
    max_iterations: int = 10,
    tolerance: float = 1e-6,
    template: Rpc00b | None = None,
    source: str | None = None,
) -> tuple[Rpc00b, FitStats]:
    """Fit an RPC00B to any sensor model on a 3D grid (a sensor-oriented RPC).

    Parameters
    ----------
    model : SensorModel
        Any model; only its ``backproject_with_status`` is used.
    shape : (int, int), optional
        ``(rows, cols)`` covered by the grid; default ``model.shape``.
    height_range : (float, float), optional
        Heights of the grid, metres above the ellipsoid; default ``model.height_range``.
    grid : (int, int, int)
        Fit-grid nodes along rows, columns and heights (each >= 2; 21 x 21 x 9 = 3969 points
        for 78 unknowns by default). The check grid has ``2 (n - 1)`` nodes per axis.
    regularization : float or ``"gcv"``
        Tikhonov weight on the column-scaled unknowns (dimensionless; 0 disables it), or
        ``"gcv"`` (default) to choose it at each reweighting iteration by generalised
        cross-validation (:mod:`geoblock_rpc.rational`). Either way a weight that
        lets a denominator approach zero on the fit or check grid is replaced by the next
        larger one, so the full cubic ratio, over-parameterised for most sensors, never gets a
        pole inside the image.
    max_iterations : int
        Cap on the ``1 / D`` reweighting iterations.
    tolerance : float
        Stop when the fit-grid RMS changes by less than this fraction.
    template : Rpc00b, optional
        Copy ``err_bias``, ``err_rand`` and the validity box from it (e.g. the vendor RPC a
        corrected model wraps).
    source : str, optional
        ``source`` of the result (default names the model).

    Returns
    -------
    rpc : Rpc00b
        The fitted coefficients (pixel-centre convention).
    stats : FitStats
        Errors in pixels on the check grid and the fit grid.

    Raises
    ------
    AdjustmentError
        The model cannot backproject most of the grid.
    SingularSystemError
        (an ``AdjustmentError``) No regularisation keeps the fitted denominators away from
        zero.

    Examples
    --------
    >>> from geoblock.testing.synthetic import ConstantVelocityPushbroom
    >>> rpc, stats = fit_rpc(ConstantVelocityPushbroom.example())
    >>> stats.max_px < 1e-3
    True
    """
    shape = tuple(int(n) for n in (model.shape if shape is None else shape))
    hr = tuple(float(v) for v in (model.height_range if height_range is None else height_range))
    grid = tuple(int(n) for n in grid)
    lon, lat, h, row, col = _ground(model, *image_grid(shape, hr, grid), what="fit-grid")
    check_points = _ground(model, *check_grid(shape, hr, grid), what="check-grid")

    lon0 = float(np.median(lon))
    dlon = wrap_longitude(lon - lon0)
    long_off = lon0 + 0.5 * (dlon.max() + dlon.min())
    long_scale = max(0.5 * (dlon.max() - dlon.min()), 1e-12)
    lat_off = 0.5 * (lat.max() + lat.min())
    lat_scale = max(0.5 * (lat.max() - lat.min()), 1e-12)
    height_off = 0.5 * (hr[0] + hr[1])
    height_scale = max(0.5 * (hr[1] - hr[0]), 1.0)
    line_off, samp_off = (shape[0] - 1) / 2.0, (shape[1] - 1) / 2.0
    line_scale, samp_scale = shape[0] / 2.0, shape[1] / 2.0

    def normalised(lon, lat, h):
        return evaluate_terms(
            wrap_longitude(lon - long_off) / long_scale, (lat - lat_off) / lat_scale,
            (h - height_off) / height_scale,
        )

    terms = normalised(lon, lat, h)
    y = np.stack([(row - line_off) / line_scale, (col - samp_off) / samp_scale], axis=1)
    ratio = solve_ratios(terms, y, order=3, regularization=regularization,
                         guard=normalised(*check_points[:3]), max_iterations=max_iterations,
                         tolerance=tolerance)
    line_num, samp_num = ratio.numerators
    line_den, samp_den = ratio.denominators

    extra: dict[str, Any] = {}
    if template is not None:
        extra = {k: getattr(template, k) for k in
                 ("min_long", "min_lat", "max_long", "max_lat", "err_bias", "err_rand")}
    rpc = Rpc00b(
        line_off=line_off, samp_off=samp_off, lat_off=lat_off, long_off=long_off,
        height_off=height_off, line_scale=line_scale, samp_scale=samp_scale,
        lat_scale=lat_scale, long_scale=long_scale, height_scale=height_scale,
        line_num=line_num, line_den=line_den, samp_num=samp_num, samp_den=samp_den,
        source=source or f"fit_rpc({type(model).__name__})", **extra,
    )

    def errors(lon, lat, h, row, col):
        t = normalised(lon, lat, h)
        r = (t @ rpc.line_num) / (t @ rpc.line_den) * line_scale + line_off
        c = (t @ rpc.samp_num) / (t @ rpc.samp_den) * samp_scale + samp_off
        return r - row, c - col

    fr, fc = errors(lon, lat, h, row, col)
    fit_err = np.hypot(fr, fc)
    check = tuple(2 * (n - 1) for n in grid)
    cr, cc = errors(*check_points)
    err = np.hypot(cr, cc)
    stats = FitStats(
        rms_px=float(np.sqrt(np.mean(err**2))),
        max_px=float(err.max()),
        rms_row_px=float(np.sqrt(np.mean(cr**2))),
        rms_col_px=float(np.sqrt(np.mean(cc**2))),
        fit_rms_px=float(np.sqrt(np.mean(fit_err**2))),
        fit_max_px=float(fit_err.max()),
        n_fit=int(lon.size),
        n_check=int(cr.size),
        iterations=ratio.iterations,
        regularization=ratio.regularization,
        condition=ratio.condition,
        grid=grid,  # type: ignore[arg-type]
        check=check,  # type: ignore[arg-type]
    )
    return rpc, stats
