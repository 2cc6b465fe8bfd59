"""Single-image adjustment (resection) of a sensor model's parameters from GCPs.

Weighted Gauss-Newton on the model's adjustable parameters. Observations:

* image measurements of the GCPs, with ``sigma_row, sigma_col`` (pixels);
* the GCPs' ground coordinates, with ``sigma_e, sigma_n, sigma_h`` (metres). A GCP appears in
  one image only, so its ground unknowns are eliminated exactly: its image observation gets
  the covariance ``diag(sigma_row^2, sigma_col^2) + J S J^T`` (``J`` the ground partials,
  ``S`` the ground covariance in ECEF);
* a-priori parameter values as pseudo-observations, weighted by the a-priori covariance of
  the parameters whose sigma is finite (Teo et al.'s MBA pseudo-observations).

Every feature that fits a model to points (RPCV-0/RPCV-1 refinement, SPOT resection) calls
:func:`resect`; the block adjustment generalises it to many images and tie points.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from geoblock import coords
from geoblock.adjust.observations import ControlPoints
from geoblock.adjust.statistics import AccuracyStats
from geoblock.adjust.weights import (
    check_measured_geometry,
    check_not_degenerate,
    ground_covariance,
    prior_weight,
    undetermined,
)
from geoblock.errors import AdjustmentError, SingularSystemError, TooFewPointsError
from geoblock.models.protocol import SensorModel
from geoblock.typing import Float64Array, Status, StatusArray, StrArray

__all__ = ["PointResiduals", "ResectionResult", "resect"]

#: singular values below this fraction of the largest (of the column-scaled, whitened design)
#: mark a rank deficiency
RANK_TOLERANCE = 1e-10


@dataclass(frozen=True)
class PointResiduals:
    """Per-point residuals of one point set.

    ``row, col``: image residuals, observed minus computed, pixels. ``e, n``: planimetric
    errors, metres: the measured image point located on the surface at the point's height
    through the model, minus the reference ground point, along local east and north.
    """

    id: StrArray
    row: Float64Array
    col: Float64Array
    e: Float64Array
    n: Float64Array
    stats: AccuracyStats

    @property
    def rmse_px(self) -> tuple[float, float]:
        """RMSE of the row and column residuals, pixels."""
        return (float(np.sqrt(np.nanmean(self.row**2))), float(np.sqrt(np.nanmean(self.col**2))))

    @property
    def rms_px(self) -> float:
        """RMS of the 2D image residual ``hypot(row, col)``, pixels."""
        return float(np.sqrt(np.nanmean(self.row**2 + self.col**2)))

    @property
    def max_px(self) -> float:
        """Largest 2D image residual, pixels."""
        return float(np.nanmax(np.hypot(self.row, self.col)))

    @classmethod
    def of(cls, model: SensorModel, points: ControlPoints,
           v: Float64Array | None = None) -> PointResiduals:
        """Residuals of ``points`` through ``model``: image residuals (observed - computed,
        or the given ``v`` (N, 2)) and ground errors (located at each point's height -
        reference)."""
        if v is None:
            (r, c), _ = model.project_with_status(points.lon, points.lat, points.h)
            v = np.stack([points.row - r, points.col - c], axis=-1)
        (lon, lat, h), _ = model.backproject_with_status(points.row, points.col, points.h)
        de, dn, _ = coords.enu_offsets(points.lon, points.lat, points.h, lon, lat, h)
        return cls(id=points.id, row=v[:, 0], col=v[:, 1], e=de, n=dn,
                   stats=AccuracyStats.from_errors(de, dn))


@dataclass(frozen=True)
class ResectionResult:
    """Outcome of :func:`resect`.

    Attributes
    ----------
    model : SensorModel
        The model with the adjusted parameter values.
    names : tuple of str, (K,)
        The adjusted parameters.
    values, sigmas : ndarray, (K,)
        Adjusted values and their posterior standard deviations (units of each parameter).
    covariance : ndarray, (K, K)
        Posterior covariance, ``sigma0**2 * N^-1`` (``N^-1`` alone when there is no
        redundancy).
    cofactor : ndarray, (K, K)
        ``N^-1``: the covariance the a-priori sigmas predict (for sigma0 = 1).
    sigma0 : float
        Posterior standard deviation of unit weight (NaN when ``dof == 0``); close to 1 when
        the a-priori sigmas are right.
    dof : int
        Degrees of freedom: observations + pseudo-observations - unknowns.
    converged : bool
    iterations : int
    history : list of dict
        Per iteration: ``rms_px`` (weighted image residual RMS before the step) and
        ``max_step_sigma`` (largest step in posterior sigmas).
    gcp, icp : PointResiduals or None
        Residuals and accuracy statistics at the GCPs and at the independent check points.
    """

    model: SensorModel
    names: tuple[str, ...]
    values: Float64Array
    sigmas: Float64Array
    covariance: Float64Array
    cofactor: Float64Array
    sigma0: float
    dof: int
    converged: bool
    iterations: int
    history: list[dict[str, Any]] = field(repr=False)
    gcp: PointResiduals = field(repr=False)
    icp: PointResiduals | None = field(default=None, repr=False)

    def report(self) -> str:
        """A plain-text report: parameters, sigma0, GCP residuals and GCP/ICP statistics."""
        lines = [
            f"resection of {self.model.name}: {'converged' if self.converged else 'NOT converged'}"
            f" in {self.iterations} iterations, sigma0 {self.sigma0:.4g}, dof {self.dof}",
            "parameter        value          sigma",
        ]
        for name, v, s in zip(self.names, self.values, self.sigmas, strict=True):
            lines.append(f"{name:12s} {v:14.6g} {s:14.4g}")
        lines.append("GCP residuals (observed - computed, px; ground error, m):")
        g = self.gcp
        for i in range(len(g.id)):
            lines.append(
                f"  {g.id[i]:>10s}  row {g.row[i]:8.3f} col {g.col[i]:8.3f}"
                f"  E {g.e[i]:8.3f} N {g.n[i]:8.3f}"
            )
        lines.append(f"GCP  {g.stats.as_row()}")
        if self.icp is not None:
            lines.append(f"ICP  {self.icp.stats.as_row()}")
        return "\n".join(lines)


def resect(
    model: SensorModel,
    gcps: ControlPoints,
    icps: ControlPoints | None = None,
    *,
    max_iterations: int = 20,
    tolerance: float = 1e-8,
) -> ResectionResult:
    """Adjust a model's adjustable parameters to ground control points.

    Parameters
    ----------
    model : SensorModel
        Any model; its ``parameters.adjustable`` mask selects the unknowns and its finite
        a-priori sigmas (or covariance) become pseudo-observations.
    gcps : ControlPoints
        Ground control points measured in the image.
    icps : ControlPoints, optional
        Independent check points: not used in the fit, only in the accuracy statistics.
    max_iterations : int
        Iteration cap of Gauss-Newton.
    tolerance : float
        Converged when every parameter step is below ``tolerance`` times its posterior
        standard deviation (dimensionless).

    Returns
    -------
    ResectionResult

    Raises
    ------
    TooFewPointsError
        Fewer GCPs than the free adjustable parameters need (two observations per GCP); the
        message states the minimum.
    SingularSystemError
        The GCPs cannot determine some parameters (for example collinear GCPs for an affine
        correction, or GCPs all measured at one pixel); ``.undetermined`` names them.
    AdjustmentError
        No adjustable parameter, a GCP that the model cannot project, or a degenerate
        solution (an adjusted model that collapses the image geometry).
    """
    params = model.parameters
    adjustable = np.flatnonzero(params.adjustable)
    names = tuple(params.names[i] for i in adjustable)
    if adjustable.size == 0:
        raise AdjustmentError(f"resect: model {model.name!r} has no adjustable parameter")
    prior_cov = params.prior_covariance[np.ix_(adjustable, adjustable)]
    constrained = np.isfinite(np.diag(prior_cov))
    n_free = int((~constrained).sum())
    minimum = max(1, -(-n_free // 2))
    if len(gcps) < minimum:
        free = [n for n, c in zip(names, constrained, strict=True) if not c]
        raise TooFewPointsError(
            f"resect: {len(gcps)} GCP(s) given, but the {n_free} adjustable parameters without "
            f"a-priori sigma ({', '.join(free)}) need at least {minimum} GCPs (two observations "
            "each); add GCPs or give parameters a-priori sigmas"
        )
    # prior weight on the constrained subset
    check_measured_geometry(gcps.id, gcps.row, gcps.col,
                            [n for n, c in zip(names, constrained, strict=True) if not c],
                            "resect")
    prior_sqrt = _sqrt_weight(prior_weight(prior_cov))  # (K, K) with L^T L = prior_weight
    x_prior = params.values[adjustable].copy()
    x = params.values.copy()

    observed = np.stack([gcps.row, gcps.col], axis=-1)  # (N, 2)
    ground_cov_ecef = _ground_covariance_ecef(gcps)  # (N, 3, 3)
    history: list[dict[str, Any]] = []
    converged = False
    current = model
    for iteration in range(1, max_iterations + 1):
        current = model.with_parameters(x)
        computed, status = current.project_with_status(gcps.lon, gcps.lat, gcps.h)
        _check_projected(status, gcps, model)
        v = observed - np.stack(computed, axis=-1)  # (N, 2) observed - computed
        a = current.partials_parameters(gcps.lon, gcps.lat, gcps.h)[..., adjustable]  # (N,2,K)
        whiten = _whitening(current, gcps, ground_cov_ecef)  # (N, 2, 2), W = whiten^T whiten
        design = np.concatenate(
            [np.einsum("nij,njk->nik", whiten, a).reshape(-1, adjustable.size), prior_sqrt]
        )
        rhs = np.concatenate(
            [np.einsum("nij,nj->ni", whiten, v).ravel(), prior_sqrt @ (x_prior - x[adjustable])]
        )
        step, n_inv = _solve(design, rhs, names)
        sig = np.sqrt(np.diag(n_inv))
        history.append(
            {
                "iteration": iteration,
                "rms_px": float(np.sqrt(np.mean(v**2))),
                "max_step_sigma": float(np.max(np.abs(step) / sig)),
            }
        )
        x[adjustable] += step
        if np.all(np.abs(step) <= tolerance * sig):
            converged = True
            break
    current = model.with_parameters(x)
    check_not_degenerate(model, current, gcps.lon, gcps.lat, gcps.h, "resect")
    computed, status = current.project_with_status(gcps.lon, gcps.lat, gcps.h)
    _check_projected(status, gcps, model)
    v = observed - np.stack(computed, axis=-1)
    whiten = _whitening(current, gcps, ground_cov_ecef)
    wv = np.einsum("nij,nj->ni", whiten, v).ravel()
    wp = prior_sqrt @ (x[adjustable] - x_prior)
    n_obs = 2 * len(gcps) + int(constrained.sum())
    dof = n_obs - adjustable.size
    sigma0 = float(np.sqrt((wv @ wv + wp @ wp) / dof)) if dof > 0 else float("nan")
    covariance = n_inv * (sigma0**2 if dof > 0 else 1.0)
    return ResectionResult(
        model=current,
        names=names,
        values=x[adjustable].copy(),
        sigmas=np.sqrt(np.diag(covariance)),
        covariance=covariance,
        cofactor=n_inv,
        sigma0=sigma0,
        dof=dof,
        converged=converged,
        iterations=len(history),
        history=history,
        gcp=PointResiduals.of(current, gcps, v),
        icp=None if icps is None else PointResiduals.of(current, icps, None),
    )


def _check_projected(status: StatusArray, gcps: ControlPoints, model: SensorModel) -> None:
    bad = status != Status.CONVERGED
    if bad.any():
        listed = ", ".join(
            f"{i} ({Status(s).name.lower()})"
            for i, s in zip(gcps.id[bad][:5], status[bad][:5], strict=True)
        )
        raise AdjustmentError(
            f"resect: model {model.name!r} cannot project GCP(s) {listed}; check their "
            "coordinates and heights against the model's validity domain"
        )


def _ground_covariance_ecef(points: ControlPoints) -> Float64Array:
    """(N, 3, 3) covariance of the ground coordinates in ECEF, metres squared."""
    sig = np.stack([points.sigma_e, points.sigma_n, points.sigma_h], axis=-1)
    return ground_covariance(points.lon, points.lat, sig)


def _whitening(model: SensorModel, points: ControlPoints, ground_cov: Float64Array
               ) -> Float64Array:
    """(N, 2, 2) ``L^T`` with ``L L^T = inv(image covariance)`` per point."""
    cov = np.zeros((len(points), 2, 2))
    cov[:, 0, 0] = points.sigma_row**2
    cov[:, 1, 1] = points.sigma_col**2
    if np.any(ground_cov):
        jac = model.partials_ground(points.lon, points.lat, points.h)  # (N, 2, 3)
        cov = cov + jac @ ground_cov @ np.swapaxes(jac, -1, -2)
    weight = np.linalg.inv(cov)
    return np.swapaxes(np.linalg.cholesky(weight), -1, -2)


def _sqrt_weight(weight: Float64Array) -> Float64Array:
    """A square root ``R`` with ``R^T R = weight`` for a PSD weight matrix (zero rows allowed)."""
    values, vectors = np.linalg.eigh(weight)
    values = np.clip(values, 0.0, None)
    return (vectors * np.sqrt(values)).T


def _solve(
    design: Float64Array, rhs: Float64Array, names: tuple[str, ...]
) -> tuple[Float64Array, Float64Array]:
    """Least-squares step and ``N^-1`` by SVD of the column-scaled design; rank check."""
    norms = np.linalg.norm(design, axis=0)
    zero = norms == 0
    if zero.any():
        unused = tuple(n for n, z in zip(names, zero, strict=True) if z)
        raise SingularSystemError(
            f"resect: the observations do not depend on parameter(s) {', '.join(unused)}: "
            "they cannot be determined; fix them (adjustable=False) or give them a-priori sigmas",
            unused,
        )
    scaled = design / norms
    u, s, vt = np.linalg.svd(scaled, full_matrices=False)
    small = s < RANK_TOLERANCE * s[0]
    if small.any():
        names_out, directions = undetermined(scaled, names, RANK_TOLERANCE, design=True)
        raise SingularSystemError(
            f"resect: the GCPs cannot determine parameters {', '.join(names_out)} (the normal "
            f"equations have {directions} singular direction(s)). Spread the GCPs over "
            "the image (an affine correction needs three GCPs that are not collinear) or give "
            "these parameters a-priori sigmas",
            names_out,
        )
    step_scaled = vt.T @ ((u.T @ rhs) / s)
    n_inv_scaled = (vt.T / s**2) @ vt
    return step_scaled / norms, n_inv_scaled / np.outer(norms, norms)


