"""Least-squares fitting of rational functions ``y = N(T) / D(T)`` in the RPC00B terms.

One solver for both uses of rational functions in geoblock-rpc: the sensor-oriented RPC
fitted to a dense grid of a model's virtual points (:mod:`geoblock_rpc.fit`) and the
terrain-dependent RFM fitted to a handful of GCPs (:mod:`geoblock_rpc.rfm`).

The ratio is linearised as in Tao & Hu (2001): with the denominator's constant term fixed to 1,

    Y = N(T) / D(T),  D(T) = 1 + d . T[1:]   ->   N(T) - Y (d . T[1:]) = Y,

which is linear in the unknowns. The system is solved by Tikhonov-regularised least squares on
unit-norm columns, reweighted by ``1 / D(T)`` of the previous iteration so that the minimised
quantity tends to the true residual ``Y - N / D``. With a *common* denominator the row and
column equations share ``d`` and are solved together.

The Tikhonov weight ``lambda`` is chosen per iteration from one SVD of the weighted design,
by generalised cross-validation (``"gcv"``, Golub, Heath & Wahba 1979). (rpcfit uses the
L-curve corner instead; on noise-free grids from a sensor model the L-curve has no corner and
its choice was found to damp a synthetic pushbroom's fit to 100 px, where GCV reaches 1e-5
px.) A weight that leaves a denominator
below :data:`MIN_DENOMINATOR` at a guard point (the fit points and any others the caller
names, such as a check grid) is rejected in favour of the next larger one: a ratio with a pole
inside its domain is never returned.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from geoblock.errors import SingularSystemError

__all__ = [
    "MIN_DENOMINATOR",
    "RatioFit",
    "TERM_COUNTS",
    "lambda_grid",
    "solve_ratios",
]

#: order of the polynomials -> number of RPC00B terms (1, L, P, H, then the quadratic, then
#: the cubic ones, in :data:`geoblock_rpc.rpc00b.TERMS` order)
TERM_COUNTS = {1: 4, 2: 10, 3: 20}

#: a fitted denominator (constant term 1) must stay above this at every guard point; vendor
#: RPCs keep their denominators within a few per cent of 1
MIN_DENOMINATOR = 0.1

#: candidate Tikhonov weights, relative to the largest squared singular value of the design
_RELATIVE_LAMBDAS = np.logspace(-16, 0, 65)


@dataclass(frozen=True)
class RatioFit:
    """The fitted ratios and how they were found.

    Attributes
    ----------
    numerators : ndarray, (k, 20)
        One numerator per fitted coordinate (``k`` = 1 or 2), zero beyond the order's terms.
    denominators : ndarray, (k, 20)
        The denominators, constant term 1 (identical rows with a common denominator).
    regularization : float
        The Tikhonov weight of the last iteration, on the unit-norm columns (0: none).
    condition : float
        Condition number of the last iteration's column-scaled weighted design (without the
        Tikhonov term): ``> 1e12`` means the points do not determine the coefficients.
    iterations : int
        ``1 / D`` reweighting iterations run.
    """

    numerators: np.ndarray
    denominators: np.ndarray
    regularization: float
    condition: float
    iterations: int

    def evaluate(self, terms: np.ndarray) -> np.ndarray:
        """The fitted coordinates at ``terms`` (n, 20): (n, k)."""
        return (terms @ self.numerators.T) / (terms @ self.denominators.T)


def lambda_grid(s: np.ndarray) -> np.ndarray:
    """Candidate Tikhonov weights for singular values ``s``: 0, then 1e-16..1 x ``s_max^2``."""
    return np.concatenate([[0.0], _RELATIVE_LAMBDAS * float(s[0]) ** 2])


def _choose(s: np.ndarray, beta: np.ndarray, outside: float, m: int, how: str) -> np.ndarray:
    """Candidate weights ordered by preference (best first) for the criterion ``how``."""
    lams = lambda_grid(s)
    with np.errstate(divide="ignore", invalid="ignore"):
        f = s[None, :] ** 2 / (s[None, :] ** 2 + lams[:, None])
        f[0] = (s > s[0] * 1e-15).astype(float)  # lambda = 0: the pseudo-inverse
        residual2 = np.sum(((1.0 - f) * beta[None, :]) ** 2, axis=1) + outside
        if how == "gcv":
            dof = m - f.sum(axis=1)
            score = np.where(dof > 0.5, m * residual2 / dof**2, np.inf)
        else:
            raise ValueError(f"regularization must be a number or 'gcv', got {how!r}")
    score = np.where(np.isfinite(score), score, np.inf)
    best = int(np.argmin(score))
    # preference: the best weight, then ever larger ones (more damping, no pole)
    larger = [i for i in range(best + 1, lams.size)]
    return lams[[best, *larger]]


def _design(terms: np.ndarray, y: np.ndarray, n_terms: int, common: bool
            ) -> tuple[np.ndarray, np.ndarray]:
    """Linearised design (m, p) and right-hand side (m,) for ``y`` (n, k)."""
    n, k = y.shape
    t = terms[:, :n_terms]
    if not common:
        assert k == 1
        return np.concatenate([t, -y[:, :1] * t[:, 1:]], axis=1), y[:, 0]
    blocks = []
    for j in range(k):
        num = np.zeros((n, k * n_terms))
        num[:, j * n_terms:(j + 1) * n_terms] = t
        blocks.append(np.concatenate([num, -y[:, j:j + 1] * t[:, 1:]], axis=1))
    return np.concatenate(blocks, axis=0), y.T.ravel()


def _unpack(x: np.ndarray, n_terms: int, k: int) -> tuple[np.ndarray, np.ndarray]:
    num = np.zeros((k, 20))
    den = np.zeros((k, 20))
    for j in range(k):
        num[j, :n_terms] = x[j * n_terms:(j + 1) * n_terms]
        den[j, 0] = 1.0
        den[j, 1:n_terms] = x[k * n_terms:]
    return num, den


def solve_ratios(
    terms: np.ndarray,
    y: np.ndarray,
    *,
    order: int = 3,
    common: bool = False,
    weights: np.ndarray | None = None,
    regularization: float | str = "gcv",
    guard: np.ndarray | None = None,
    max_iterations: int = 10,
    tolerance: float = 1e-6,
) -> RatioFit:
    """Fit ``y[:, j] ~ N_j(T) / D_j(T)`` by reweighted, regularised linear least squares.

    Parameters
    ----------
    terms : ndarray, (n, 20)
        RPC00B terms of the normalised ground coordinates
        (:func:`~geoblock_rpc.rpc00b.evaluate_terms`).
    y : ndarray, (n,) or (n, k)
        Normalised image coordinates (one ratio per column; several columns with
        ``common=True`` share one denominator, else each column is fitted separately).
    order : {1, 2, 3}
        Polynomial order: 4, 10 or 20 terms per polynomial.
    common : bool
        One denominator for all columns (``2 t + t - 1`` unknowns for two columns) instead of
        one per column (``2 t - 1`` each).
    weights : ndarray, (n,) or (n, k), optional
        Observation weights (``1 / sigma``, any unit), default 1.
    regularization : float or ``"gcv"``
        A fixed Tikhonov weight on the unit-norm columns, or generalised cross-validation
        choosing it at each iteration.
    guard : ndarray, (g, 20), optional
        Terms of further points where the denominators must stay above
        :data:`MIN_DENOMINATOR` (the fit points always are).
    max_iterations : int
        Cap on the ``1 / D`` reweighting iterations.
    tolerance : float
        Stop when the weighted RMS residual changes by less than this fraction.

    Returns
    -------
    RatioFit

    Raises
    ------
    SingularSystemError
        No candidate weight keeps every denominator above :data:`MIN_DENOMINATOR` (or a fixed
        weight does not).
    """
    y2 = np.asarray(y, dtype=float).reshape(len(terms), -1)
    k = y2.shape[1]
    n_terms = TERM_COUNTS[order]
    w_all = np.ones_like(y2) if weights is None else np.broadcast_to(
        np.asarray(weights, dtype=float).reshape(len(terms), -1), y2.shape)
    if not common and k > 1:
        fits = [solve_ratios(terms, y2[:, j], order=order, weights=w_all[:, j],
                             regularization=regularization, guard=guard,
                             max_iterations=max_iterations, tolerance=tolerance)
                for j in range(k)]
        return RatioFit(
            numerators=np.concatenate([f.numerators for f in fits]),
            denominators=np.concatenate([f.denominators for f in fits]),
            regularization=max(f.regularization for f in fits),
            condition=max(f.condition for f in fits),
            iterations=max(f.iterations for f in fits),
        )
    design, rhs = _design(terms, y2, n_terms, common)
    w_obs = w_all.T.ravel() if common else w_all[:, 0]
    norms = np.linalg.norm(design, axis=0)
    norms[norms == 0] = 1.0
    scaled = design / norms
    checks = terms[:, :n_terms] if guard is None else np.concatenate(
        [terms[:, :n_terms], guard[:, :n_terms]])
    den_fit = np.ones(len(terms))
    previous = math.inf
    result: RatioFit | None = None
    for iteration in range(1, max_iterations + 1):
        w = w_obs / np.tile(den_fit, k if common else 1)
        a = scaled * w[:, None]
        b = rhs * w
        u, s, vt = np.linalg.svd(a, full_matrices=False)
        if s[0] == 0 or not np.all(np.isfinite(s)):
            raise SingularSystemError("the rational-function design is zero or not finite")
        beta = u.T @ b
        outside = max(float(b @ b - beta @ beta), 0.0)
        if isinstance(regularization, str):
            candidates = _choose(s, beta, outside, a.shape[0], regularization)
        else:
            candidates = np.array([float(regularization)])
        for lam in candidates:
            if lam == 0:
                keep = s > s[0] * 1e-15
                f = np.where(keep, 1.0 / np.where(keep, s, 1.0), 0.0)
            else:
                f = s / (s**2 + lam)
            x = vt.T @ (f * beta) / norms
            num, den = _unpack(x, n_terms, k if common else 1)
            d_checks = checks @ den[0, :n_terms]
            if np.all(np.isfinite(d_checks)) and d_checks.min() > MIN_DENOMINATOR:
                break
        else:
            raise SingularSystemError(
                "the fitted denominator comes within "
                f"{MIN_DENOMINATOR:g} of zero inside the fit domain for every regularisation "
                "weight tried"
                + ("" if isinstance(regularization, str) else f" ({float(regularization):g})")
                + ": the points do not determine a rational function of this order"
            )
        den_fit = terms[:, :n_terms] @ den[0, :n_terms]
        residual = (terms[:, :n_terms] @ num[:, :n_terms].T) / den_fit[:, None] - y2
        rms = float(np.sqrt(np.mean((residual * w_all) ** 2)))
        result = RatioFit(numerators=num, denominators=den, regularization=float(lam),
                          condition=float(s[0] / s[-1]) if s[-1] > 0 else math.inf,
                          iterations=iteration)
        if abs(previous - rms) <= tolerance * max(rms, 1e-300) + 1e-16:
            break
        previous = rms
    assert result is not None
    return result
