"""Accuracy statements the NSSDA/ASPRS way: circular (CE) and linear (LE) errors.

Two routes to the same figures:

* **empirical**, from errors measured at check points: the ``p``-th percentile of the radial
  (``sqrt(de**2 + dn**2)``) or absolute vertical errors (:func:`empirical_ce`,
  :func:`empirical_le`), and the NSSDA's normal-theory figures from the RMSE
  (:func:`nssda_ce`, :func:`nssda_le`: ``CE90 = 2.1460 RMSE_1d``, ``CE95 = 2.4477 RMSE_1d``,
  ``LE90 = 1.6449 RMSE_z``, ``LE95 = 1.9600 RMSE_z``, with ``RMSE_1d = RMSE_r / sqrt(2)``;
  FGDC-STD-007.3-1998 and the ASPRS Positional Accuracy Standards 2014/2023);
* **predicted**, from a covariance: :func:`predicted_ce` takes each point's (2, 2) east/north
  covariance and returns the radius that holds a fraction ``p`` of the population of errors
  those Gaussians describe (exact, not the NSSDA's near-circular approximation; one point
  gives that point's circular error), :func:`predicted_le` the same for vertical sigmas.

All figures are in metres; east/north/up are local to each point.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from geoblock.errors import ShapeMismatchError
from geoblock.typing import ArrayLike, Float64Array

__all__ = ["CE90_FACTOR", "CE95_FACTOR", "LE90_FACTOR", "LE95_FACTOR", "AccuracyStatement",
           "accuracy_statement", "circular_error_cdf", "empirical_ce", "empirical_le",
           "nssda_ce", "nssda_le", "predicted_ce", "predicted_le"]

#: CE90 / sigma of a circular normal error with sigma per axis: ``sqrt(-2 ln 0.10)``.
CE90_FACTOR = math.sqrt(-2.0 * math.log(0.10))
#: CE95 / sigma per axis: ``sqrt(-2 ln 0.05)``.
CE95_FACTOR = math.sqrt(-2.0 * math.log(0.05))
#: LE90 / sigma of a normal vertical error (two-sided): 1.6449.
LE90_FACTOR = 1.6448536269514722
#: LE95 / sigma: 1.9600.
LE95_FACTOR = 1.959963984540054

_ANGLES = 128  # periodic trapezoid nodes: exponential convergence for the smooth integrand
_TOLERANCE = 1e-9  # relative, on the radius
_MAX_ITERATIONS = 200


def _probability(p: float) -> float:
    if not 0.0 < p < 1.0:
        raise ValueError(f"probability must be in (0, 1), got {p!r}")
    return float(p)


def circular_error_cdf(radius: ArrayLike, covariance: ArrayLike) -> Float64Array:
    """P(|e| <= radius) for a zero-mean Gaussian horizontal error of covariance ``covariance``.

    Parameters
    ----------
    radius : array_like, (...)
        Radii, metres.
    covariance : array_like, (..., 2, 2)
        East/north covariance, square metres (broadcast against ``radius``).

    Returns
    -------
    ndarray, (...)
        The probability, exact to ~1e-12 (the integral over the angle of the error
        ellipse's polar form by a 128-node periodic trapezoid rule); 1 for a positive radius
        and a zero covariance.
    """
    r = np.asarray(radius, dtype=np.float64)
    cov = np.asarray(covariance, dtype=np.float64)
    # principal sigmas: the probability depends only on the eigenvalues
    tr = cov[..., 0, 0] + cov[..., 1, 1]
    det = cov[..., 0, 0] * cov[..., 1, 1] - cov[..., 0, 1] * cov[..., 1, 0]
    disc = np.sqrt(np.maximum(tr * tr / 4.0 - det, 0.0))
    l1 = np.maximum(tr / 2.0 + disc, 0.0)
    l2 = np.maximum(tr / 2.0 - disc, 0.0)
    # with x = sqrt(l1) rho cos(phi), y = sqrt(l2) rho sin(phi) the density is
    # exp(-rho**2 / 2) rho / (2 pi), and |e| <= r is rho <= r / s(phi) with
    # s**2 = l1 cos**2 + l2 sin**2:
    # P = mean over phi of 1 - exp(-r**2 / (2 s**2)), a smooth periodic integrand even for a
    # line error (l2 = 0), so the trapezoid rule converges exponentially
    phi = (np.arange(_ANGLES) + 0.5) * (2.0 * np.pi / _ANGLES)
    c2, s2 = np.cos(phi) ** 2, np.sin(phi) ** 2
    r, l1, l2 = np.broadcast_arrays(r, l1, l2)
    out = np.empty(r.shape)
    tiny = l1 <= 0.0
    out[tiny] = (r[tiny] > 0).astype(np.float64)
    full = ~tiny
    if full.any():
        var = l1[full][:, None] * c2 + l2[full][:, None] * s2  # (M, A)
        rr = r[full][:, None]
        with np.errstate(divide="ignore"):
            out[full] = (-np.expm1(-0.5 * rr * rr / var)).mean(axis=1)
    return np.clip(out, 0.0, 1.0)


def _quantile(cdf: Callable[[float], float], p: float, hi: float) -> float:
    """The radius ``r`` in ``[0, hi]`` with ``cdf(r) = p`` (``cdf`` non-decreasing), by
    bisection to :data:`_TOLERANCE` relative, at most :data:`_MAX_ITERATIONS` halvings."""
    if hi == 0.0:
        return 0.0
    lo = 0.0
    for _ in range(_MAX_ITERATIONS):
        mid = 0.5 * (lo + hi)
        if cdf(mid) < p:
            lo = mid
        else:
            hi = mid
        if hi - lo <= _TOLERANCE * hi:
            break
    return 0.5 * (lo + hi)


def predicted_ce(covariance: ArrayLike, p: float = 0.90) -> float:
    """The circular error at probability ``p`` that horizontal covariances predict.

    Parameters
    ----------
    covariance : array_like, (2, 2) or (N, 2, 2)
        East/north covariance of each point's error, square metres. NaN rows are ignored.
    p : float
        Probability (0.90 for CE90, 0.95 for CE95).

    Returns
    -------
    float
        Radius ``R`` (metres) with ``mean_i P_i(|e_i| <= R) = p``: the CE of the population of
        errors (each point equally likely), solved by bisection to 1e-9 relative (at most 200
        halvings). NaN when no point is finite.
    """
    p = _probability(p)
    cov = np.asarray(covariance, dtype=np.float64).reshape(-1, 2, 2)
    cov = cov[np.isfinite(cov).all(axis=(1, 2))]
    if not len(cov):
        return float("nan")
    hi = CE95_FACTOR * math.sqrt(float(np.max(cov[:, 0, 0] + cov[:, 1, 1]))) * 4.0
    return _quantile(lambda r: float(np.mean(circular_error_cdf(r, cov))), p, hi)


def predicted_le(sigma_up: ArrayLike, p: float = 0.90) -> float:
    """The linear (vertical) error at probability ``p`` that vertical sigmas predict.

    Parameters
    ----------
    sigma_up : array_like, (N,)
        Standard deviation of each point's vertical error, metres; NaN ignored.
    p : float
        Probability (0.90 for LE90).

    Returns
    -------
    float
        ``R`` (metres) with ``mean_i P(|z_i| <= R) = p``; for one sigma ``LE90_FACTOR * sigma``.
    """
    from scipy.special import erf

    p = _probability(p)
    s = np.asarray(sigma_up, dtype=np.float64).ravel()
    s = s[np.isfinite(s)]
    if not s.size:
        return float("nan")
    safe = np.where(s > 0, s, 1.0)
    return _quantile(
        lambda r: float(np.where(s > 0, erf(r / (math.sqrt(2.0) * safe)), 1.0).mean()), p,
        4.0 * float(s.max()) * LE95_FACTOR)


def _finite(values: ArrayLike) -> Float64Array:
    v = np.asarray(values, dtype=np.float64).ravel()
    return v[np.isfinite(v)]


def empirical_ce(de: ArrayLike, dn: ArrayLike, p: float = 0.90) -> float:
    """The ``p``-th percentile of the radial errors ``sqrt(de**2 + dn**2)`` (metres).

    NaN pairs are ignored; NaN when none is finite. ``numpy.percentile``'s linear rule.
    """
    p = _probability(p)
    e = np.asarray(de, dtype=np.float64)
    n = np.asarray(dn, dtype=np.float64)
    if e.shape != n.shape:
        raise ShapeMismatchError(f"empirical_ce: de has shape {e.shape} but dn {n.shape}")
    r = _finite(np.hypot(e, n))
    return float(np.percentile(r, 100.0 * p)) if r.size else float("nan")


def empirical_le(dh: ArrayLike, p: float = 0.90) -> float:
    """The ``p``-th percentile of the absolute vertical errors ``|dh|`` (metres)."""
    p = _probability(p)
    z = np.abs(_finite(dh))
    return float(np.percentile(z, 100.0 * p)) if z.size else float("nan")


def nssda_ce(rmse_e: float, rmse_n: float, p: float = 0.90) -> float:
    """The NSSDA circular error from per-axis RMSEs (metres): ``factor * RMSE_r / sqrt(2)``.

    The standard's normal-theory formula, valid when ``min/max(rmse_e, rmse_n) >= 0.6``
    (beyond that use :func:`predicted_ce` with the covariance). ``factor`` is
    ``sqrt(-2 ln(1 - p))``: 2.1460 at 90 %, 2.4477 at 95 %.
    """
    p = _probability(p)
    return math.sqrt(-2.0 * math.log(1.0 - p)) * math.sqrt((rmse_e**2 + rmse_n**2) / 2.0)


def nssda_le(rmse_z: float, p: float = 0.90) -> float:
    """The NSSDA linear error from the vertical RMSE (metres): 1.6449 RMSE_z at 90 %."""
    from scipy.special import erfinv

    p = _probability(p)
    return math.sqrt(2.0) * float(erfinv(p)) * rmse_z


# --------------------------------------------------------------------------- statements
@dataclass(frozen=True)
class AccuracyStatement:
    """CE90/CE95/LE90 of one image or a block: predicted from the posterior covariance beside
    the empirical figures at independent check points, metres.

    Attributes
    ----------
    image : str or None
        The image, or None for the whole block.
    n_icp : int
        ICP measurements with a finite horizontal error (each measured image point located
        at the ICP's surveyed height through its adjusted model): the CE figures' sample.
    ce90_predicted, ce95_predicted : float
        :func:`predicted_ce` of the ICP measurements' predicted east/north covariances.
    ce90_empirical, ce95_empirical : float
        :func:`empirical_ce`: the percentile of the radial errors.
    ce90_nssda, ce95_nssda : float
        :func:`nssda_ce` from the RMSE per axis.
    n_le : int
        ICPs intersected from two images or more (the LE figures' sample).
    le90_predicted : float
        :func:`predicted_le` of their predicted vertical sigmas.
    le90_empirical, le90_nssda : float
        :func:`empirical_le` and :func:`nssda_le` of their vertical errors.
    reason : str
        Why some figures are NaN ("" when all are given): no ICP, or no ICP measured in two
        images (vertical figures need an intersection).
    ce90_grid, ce95_grid : float
        :func:`predicted_ce` over a grid of image points located on the DEM (the adjusted
        parameters' posterior and the DEM's sigma propagated to the ground, no image
        measurement error): a prediction that needs no check point; NaN without a DEM.
    """

    image: str | None
    n_icp: int
    ce90_predicted: float
    ce90_empirical: float
    ce90_nssda: float
    ce95_predicted: float
    ce95_empirical: float
    ce95_nssda: float
    n_le: int
    le90_predicted: float
    le90_empirical: float
    le90_nssda: float
    reason: str = ""
    ce90_grid: float = float("nan")
    ce95_grid: float = float("nan")

    def as_dict(self) -> dict[str, Any]:
        """The fields as a plain dictionary (NaN kept)."""
        return asdict(self)


def accuracy_statement(de: ArrayLike, dn: ArrayLike, covariance: ArrayLike,
                       du: ArrayLike = (), sigma_up: ArrayLike = (), *,
                       image: str | None = None, grid_covariance: ArrayLike = (),
                       ) -> AccuracyStatement:
    """The :class:`AccuracyStatement` of check-point errors and their predicted covariances.

    Parameters
    ----------
    de, dn : array_like, (N,)
        Horizontal errors at the check points, metres (NaN ignored).
    covariance : array_like, (N, 2, 2)
        Their predicted east/north covariances, square metres.
    du : array_like, (L,)
        Vertical errors of the check points intersected from two images or more, metres.
    sigma_up : array_like, (L,)
        Their predicted vertical sigmas, metres.
    image : str, optional
        The label (None: the block).
    grid_covariance : array_like, (G, 2, 2)
        Predicted east/north covariances over a grid of ground points (no check point
        needed), square metres; empty: ``ce90_grid`` is NaN.
    """
    e = np.asarray(de, dtype=np.float64).ravel()
    n = np.asarray(dn, dtype=np.float64).ravel()
    cov = np.asarray(covariance, dtype=np.float64).reshape(-1, 2, 2)
    ok = np.isfinite(e) & np.isfinite(n)
    e, n, cov = e[ok], n[ok], cov[ok] if cov.shape[0] == ok.size else cov
    z = np.asarray(du, dtype=np.float64).ravel()
    s = np.asarray(sigma_up, dtype=np.float64).ravel()
    zok = np.isfinite(z) & (np.isfinite(s) if s.size == z.size else True)
    z, s = z[zok], (s[zok] if s.size == zok.size else s)
    nan = float("nan")
    reasons = []
    if e.size == 0:
        reasons.append("no ICP")
        ce = (nan,) * 6
    else:
        rmse_e, rmse_n = math.sqrt(float(np.mean(e**2))), math.sqrt(float(np.mean(n**2)))
        ce = (predicted_ce(cov, 0.90), empirical_ce(e, n, 0.90), nssda_ce(rmse_e, rmse_n, 0.90),
              predicted_ce(cov, 0.95), empirical_ce(e, n, 0.95), nssda_ce(rmse_e, rmse_n, 0.95))
    if z.size == 0:
        if e.size:
            reasons.append("LE90 n/a: no ICP measured in two images or more (a vertical "
                           "error needs an intersection)")
        le = (nan, nan, nan)
    else:
        le = (predicted_le(s, 0.90), empirical_le(z, 0.90),
              nssda_le(math.sqrt(float(np.mean(z**2))), 0.90))
    grid = np.asarray(grid_covariance, dtype=np.float64).reshape(-1, 2, 2)
    nan_grid = not np.isfinite(grid).all(axis=(1, 2)).any()
    return AccuracyStatement(image, int(e.size), *ce, int(z.size), *le,
                             reason="; ".join(reasons),
                             ce90_grid=nan if nan_grid else predicted_ce(grid, 0.90),
                             ce95_grid=nan if nan_grid else predicted_ce(grid, 0.95))
