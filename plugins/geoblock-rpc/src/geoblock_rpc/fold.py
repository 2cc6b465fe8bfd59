"""Fold an image-space correction of an RPC into new RPC00B coefficients (RPC export).

A refined vendor RPC is ``ImageCorrection(RpcModel(rpc), order, values)``: the RPC's image
coordinates ``r = LS * Nl / Dl + LO``, ``c = SS * Ns / Ds + SO`` corrected by

    row = r + a0 + a1 u + a2 v (+ a3 u^2 + a4 u v + a5 v^2),   u = (r - r0) / s
    col = c + b0 + b1 u + b2 v (+ b3 u^2 + b4 u v + b5 v^2),   v = (c - c0) / s

(``r0, c0`` the image centre, ``s`` half the larger image dimension). When it can be written
as an RPC00B exactly:

* **offset** (order 0, or higher orders whose other coefficients are all zero, RPCV-0):
  ``LINE_OFF += a0``, ``SAMP_OFF += b0``.
* **scale-offset** (no cross terms: ``a2 == 0`` and ``b1 == 0``, quadratic terms zero):
  ``row = (1 + a1/s) r + a0 - a1 r0 / s`` is an affine function of ``r`` alone, so
  ``LINE_SCALE' = LS (1 + a1/s)`` and ``LINE_OFF' = LO + a0 + a1 (LO - r0) / s`` (likewise the
  column with ``b2, b0``); the polynomials are unchanged.
* **affine-same-denominator** (order 1 with ``Dl = k Ds`` for a constant ``k``, e.g. the
  common-denominator RPCs many vendors deliver): with ``D = Dl``,
  ``row - LO = [(1 + a1/s) LS Nl + (a2/s) SS k Ns] / D + a0 + (a1 (LO - r0) + a2 (SO - c0)) / s``
  has the denominator ``D``, so keeping ``LINE_OFF, LINE_SCALE, LINE_DEN``:
  ``LINE_NUM' = (1 + a1/s) Nl + (a2/s)(SS/LS) k Ns
  + [a0 + (a1 (LO - r0) + a2 (SO - c0))/s] / LS * Dl``
  and ``SAMP_NUM' = (1 + b2/s) Ns + (b1/s)(LS/SS) Nl / k
  + [b0 + (b1 (LO - r0) + b2 (SO - c0))/s] / SS * Ds``.
* Otherwise (an affinity with cross terms over different denominators — the result would be
  a ratio with the product denominator ``Dl Ds``, of degree 6 — or any non-zero quadratic term,
  which squares the ratios) there is no exact RPC00B: the corrected model is **refit** as a
  sensor-oriented RPC (:func:`geoblock_rpc.fit.fit_rpc`) and the report gives its error.

Every fold's error is measured on an independent check grid (the corrected model's own
ground points of a grid denser than the refit grid, over the image and the height range).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from geoblock.models.corrections import ImageCorrection
from geoblock.models.protocol import SensorModel
from geoblock.typing import Status
from geoblock_rpc.fit import FitStats, check_grid, fit_rpc
from geoblock_rpc.model import RpcModel
from geoblock_rpc.rpc00b import Rpc00b

__all__ = ["FoldReport", "fold_correction", "is_rpc_based", "rpc_for"]

#: denominators are "proportional" when ``max |Dl - k Ds| <= this * max |Dl|``
PROPORTIONAL_RTOL = 1e-12


@dataclass(frozen=True)
class FoldReport:
    """How a model was turned into RPC00B coefficients, and how well they reproduce it.

    Attributes
    ----------
    exact : bool
        The RPC00B equals the model algebraically (errors are float64 rounding only).
    method : str
        ``"identity"`` (a plain RPC), ``"offset"``, ``"scale-offset"``,
        ``"affine-same-denominator"`` or ``"refit"`` (nested corrections join theirs with
        ``"+"``).
    max_error_px, rms_error_px : float
        2D image error ``hypot(drow, dcol)`` of the RPC00B against the model on the check
        grid, pixels.
    n_check : int
        Check points used.
    fit : FitStats or None
        The refit's own statistics (``method`` contains ``"refit"``).
    """

    exact: bool
    method: str
    max_error_px: float
    rms_error_px: float
    n_check: int = 0
    fit: FitStats | None = None

    def __str__(self) -> str:
        kind = "exact" if self.exact else "approximate"
        return (
            f"RPC00B {kind} ({self.method}): max error {self.max_error_px:.3g} px, "
            f"RMS {self.rms_error_px:.3g} px on {self.n_check} check points"
        )


def _proportional(dl: np.ndarray, ds: np.ndarray) -> float | None:
    """``k`` with ``dl = k ds`` (to :data:`PROPORTIONAL_RTOL`), else None."""
    k = dl[0] / ds[0]
    if np.max(np.abs(dl - k * ds)) <= PROPORTIONAL_RTOL * np.max(np.abs(dl)):
        return float(k)
    return None


def _fold_exact(
    rpc: Rpc00b, values: np.ndarray, order: int, origin: tuple[float, float], s: float
) -> tuple[Rpc00b, str] | None:
    """The exact RPC00B of a correction, or None when there is none (see the module notes)."""
    n = {0: 1, 1: 3, 2: 6}[order]
    a = np.zeros(6)
    b = np.zeros(6)
    a[:n], b[:n] = values[:n], values[n:]
    if np.any(a[3:]) or np.any(b[3:]):
        return None  # quadratic terms square the ratios
    r0, c0 = origin
    lo, so, ls, ss = rpc.line_off, rpc.samp_off, rpc.line_scale, rpc.samp_scale
    if not (a[1] or a[2] or b[1] or b[2]):
        return rpc.replace(line_off=lo + a[0], samp_off=so + b[0]), "offset"
    if a[2] == 0.0 and b[1] == 0.0:
        fr, fc = 1.0 + a[1] / s, 1.0 + b[2] / s
        if fr == 0.0 or fc == 0.0:
            return None
        return rpc.replace(
            line_scale=ls * fr, line_off=lo + a[0] + a[1] * (lo - r0) / s,
            samp_scale=ss * fc, samp_off=so + b[0] + b[2] * (so - c0) / s,
        ), "scale-offset"
    k = _proportional(rpc.line_den, rpc.samp_den)
    if k is None:
        return None
    shift_r = (a[0] + (a[1] * (lo - r0) + a[2] * (so - c0)) / s) / ls
    shift_c = (b[0] + (b[1] * (lo - r0) + b[2] * (so - c0)) / s) / ss
    line_num = ((1.0 + a[1] / s) * rpc.line_num + (a[2] / s) * (ss / ls) * k * rpc.samp_num
                + shift_r * rpc.line_den)
    samp_num = ((1.0 + b[2] / s) * rpc.samp_num + (b[1] / s) * (ls / ss) / k * rpc.line_num
                + shift_c * rpc.samp_den)
    return rpc.replace(line_num=line_num, samp_num=samp_num), "affine-same-denominator"


def _check_error(
    model: SensorModel, rpc: Rpc00b, domain_limit: float, grid: tuple[int, int, int]
) -> tuple[float, float, int]:
    """(max, rms, n) of the 2D error of ``rpc`` against ``model`` on the check grid, px."""
    row, col, h = check_grid(model.shape, model.height_range, grid)
    (lon, lat, _), status = model.backproject_with_status(row, col, h)
    ok = status == Status.CONVERGED
    lon, lat, h = lon[ok], lat[ok], h[ok]
    (r1, c1), s1 = model.project_with_status(lon, lat, h)
    folded = RpcModel(rpc, model.shape, domain_limit=max(domain_limit, 1e6))
    (r2, c2), s2 = folded.project_with_status(lon, lat, h)
    good = (s1 == Status.CONVERGED) & (s2 == Status.CONVERGED)
    err = np.hypot(r2 - r1, c2 - c1)[good]
    if err.size == 0:
        return float("nan"), float("nan"), 0
    return float(err.max()), float(np.sqrt(np.mean(err**2))), int(err.size)


def fold_correction(
    corrected: ImageCorrection,
    *,
    grid: tuple[int, int, int] = (21, 21, 9),
    regularization: float | str = "gcv",
) -> tuple[Rpc00b, FoldReport]:
    """RPC00B coefficients of an image-corrected RPC: exact when possible, else a refit.

    Parameters
    ----------
    corrected : ImageCorrection
        Wrapping an :class:`~geoblock_rpc.RpcModel` (or another ``ImageCorrection`` of one:
        nested corrections are folded innermost first).
    grid : (int, int, int)
        Refit grid (rows, columns, heights); the check grid has ``2 (n - 1)`` nodes per axis.
    regularization : float
        Passed to :func:`~geoblock_rpc.fit.fit_rpc` for a refit.

    Returns
    -------
    rpc : Rpc00b
        In geoblock's pixel-centre convention, valid for the image ``corrected.shape``.
    report : FoldReport
        Exact or refit, with the measured error in pixels.

    Raises
    ------
    TypeError
        ``corrected`` does not wrap an RPC model.
    """
    if not isinstance(corrected, ImageCorrection):
        raise TypeError(f"fold_correction needs an ImageCorrection, got {type(corrected).__name__}")
    base = corrected.model
    inner_methods: list[str] = []
    inner_exact = True
    if isinstance(base, ImageCorrection):
        inner_rpc, inner = fold_correction(base, grid=grid, regularization=regularization)
        inner_methods.append(inner.method)
        inner_exact = inner.exact
        base = RpcModel(inner_rpc, base.shape, domain_limit=_domain_limit(base))
    if not isinstance(base, RpcModel):
        raise TypeError(
            f"fold_correction: the corrected model wraps {type(base).__name__}, not an RpcModel"
        )
    values = np.asarray(corrected.parameters.values, float)
    scale = max(corrected.shape) / 2.0
    origin = ((corrected.shape[0] - 1) / 2.0, (corrected.shape[1] - 1) / 2.0)
    folded = _fold_exact(base.rpc, values, corrected.order, origin, scale)
    fit = None
    if folded is not None:
        rpc, method = folded
        exact = inner_exact
    else:
        rpc, fit = fit_rpc(
            corrected, grid=grid, regularization=regularization, template=base.rpc,
            source=f"{base.rpc.source} (refit with an order-{corrected.order} correction)",
        )
        method, exact = "refit", False
    max_err, rms_err, n = _check_error(corrected, rpc, base.domain_limit, grid)
    report = FoldReport(exact, "+".join([*inner_methods, method]), max_err, rms_err, n, fit)
    return rpc, report


def _domain_limit(model: SensorModel) -> float:
    while isinstance(model, ImageCorrection):
        model = model.model
    return model.domain_limit if isinstance(model, RpcModel) else 1.5


def rpc_for(model: SensorModel, **options) -> tuple[Rpc00b, FoldReport]:
    """The RPC00B to write for ``model``: its own, or its correction folded in.

    For the ``geoblock_write_sensor_model`` hook: the writer calls this for an
    :class:`~geoblock_rpc.RpcModel` or an ``ImageCorrection`` wrapping one, writes the
    coefficients and reports ``str(report)`` (exact or not, with the measured error).

    Parameters
    ----------
    model : RpcModel or ImageCorrection
    **options
        ``grid``, ``regularization`` for :func:`fold_correction`.

    Returns
    -------
    rpc : Rpc00b
    report : FoldReport

    Raises
    ------
    TypeError
        ``model`` is neither (the hook should return None for such models: see
        :func:`is_rpc_based`).
    """
    if isinstance(model, RpcModel):
        return model.rpc, FoldReport(True, "identity", 0.0, 0.0, 0)
    return fold_correction(model, **options)


def is_rpc_based(model: SensorModel) -> bool:
    """Whether :func:`rpc_for` accepts ``model`` (an RpcModel, possibly image-corrected)."""
    while isinstance(model, ImageCorrection):
        model = model.model
    return isinstance(model, RpcModel)
