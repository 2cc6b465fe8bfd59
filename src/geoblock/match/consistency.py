"""The outlier test of ``geoblock match``: consistency with the sensor models, not a homography.

For a match ``a -> b`` (pixel ``a`` of image A, ``b`` of image B) the models predict ``p(a)``
(A's line of sight on the DEM, projected into B: :func:`geoblock.match.geometry.predict`).
The **offset** ``d = b - p(a)`` of a correct match is the sum of

1. the models' disagreement: on-board or vendor models are off by a few metres to tens of
   metres, which in image space is a smooth field over the images - a low-order polynomial
   of A's pixel (order 0: a shift as RPCV-0; order 1: affine as RPCV-1), the **bias**
   ``B(a)``;
2. a **height parallax** along the epipolar direction ``e(a)`` (pixels of B per metre of height
   along A's line of sight): where the DEM's height at the point is off by ``t`` metres (DEM
   error, or A's model error moving the line of sight over sloping ground), the true match
   lies at ``p + t e``;
3. the measurement noise, a fraction of a pixel.

So, with ``v = d - B(a)`` split into its component ``v_perp`` across the epipolar direction and
``v_par`` along it:

* ``v_perp`` is noise alone: the **epipolar test** rejects ``|v_perp| > k s_perp``;
* ``v_par / |e|`` is the height parallax, metres: the **height test** rejects
  ``|v_par| > k sqrt(s_perp^2 + s_h^2 |e|^2)``,

where ``s_perp`` (pixels) and ``s_h`` (metres) are robust scales (1.4826 x median absolute
value) of the inliers' residuals, floored at ``min_sigma_px`` and ``min_sigma_h_m``. A wrong
match that happens to lie near the epipolar line is caught only by the height test (and by
the descriptors and the correlation before): the models cannot tell heights apart better
than the DEM does. Where the two images see the ground from nearly the same direction
(``|e| ~ 0``: weak convergence, as Teo et al.'s strips) the test becomes isotropic.

:func:`fit_bias` fits ``B`` by weighted least squares with the anisotropic weights of this
model; :func:`consistent` iterates fit and rejection to a fixed point; :func:`consensus`
gives the starting set: the constant bias that most matches agree with (each match's own
offset tried as the hypothesis, RANSAC with every one-point sample).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from geoblock.errors import MatchError

__all__ = ["Bias", "Consistency", "consensus", "consistent", "fit_bias", "scale_of",
           "split_residuals"]

#: Robust scale of a normal distribution from the median absolute value.
MAD_SCALE = 1.4826
#: ``|e|`` (pixels per metre) below which the epipolar direction is not defined.
EPIPOLAR_EPS = 1e-9
#: Terms of the bias polynomial per order (in A's normalised row, col).
N_TERMS = {0: 1, 1: 3, 2: 6}
#: Matches per term of the bias polynomial below which :func:`fit_bias` lowers its order.
POINTS_PER_TERM = 10


@dataclass(frozen=True)
class Bias:
    """A low-order polynomial image-space bias of B relative to A.

    ``B(a) = C @ phi(a)`` with ``phi = [1]`` (order 0), ``[1, y, x]`` (order 1) or
    ``[1, y, x, y^2, x y, x^2]`` (order 2) of A's pixel normalised as
    ``y = (row - centre[0]) / scale``, ``x = (col - centre[1]) / scale``.

    Attributes
    ----------
    coefficients : ndarray, (2, terms)
        Rows: the bias in B's row and column, pixels.
    centre : (float, float)
    scale : float
    """

    coefficients: np.ndarray
    centre: tuple[float, float]
    scale: float

    @property
    def order(self) -> int:
        """Polynomial order (0, 1 or 2)."""
        return {v: k for k, v in N_TERMS.items()}[self.coefficients.shape[1]]

    def terms(self, row: np.ndarray, col: np.ndarray, order: int | None = None) -> np.ndarray:
        """``phi`` of A's pixels, ``(N, terms)``."""
        y = (np.asarray(row, float) - self.centre[0]) / self.scale
        x = (np.asarray(col, float) - self.centre[1]) / self.scale
        k = self.order if order is None else order
        cols = [np.ones_like(y)]
        if k >= 1:
            cols += [y, x]
        if k >= 2:
            cols += [y * y, x * y, x * x]
        return np.stack(cols, axis=-1)

    def __call__(self, row: np.ndarray, col: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The bias at A's pixels: ``(d_row, d_col)`` in B, pixels, each ``(N,)``."""
        value = self.terms(row, col) @ self.coefficients.T
        return value[:, 0], value[:, 1]

    def mean(self, row: np.ndarray, col: np.ndarray) -> tuple[float, float]:
        """The bias's mean over A's pixels ``(N,)``, ``(d_row, d_col)`` in B, pixels: the
        models' disagreement where those pixels are (NaN for no pixel).

        The constant term is the bias at ``centre`` (A's image or scene centre), an
        extrapolation when the pixels lie far from it (an overlap at A's edge, a crop).
        """
        if not np.size(row):
            return math.nan, math.nan
        d_row, d_col = self(row, col)
        return float(np.mean(d_row)), float(np.mean(d_col))

    @classmethod
    def zero(cls, centre: tuple[float, float], scale: float) -> Bias:
        """No bias."""
        return cls(np.zeros((2, 1)), centre, scale)


def split_residuals(v_row: np.ndarray, v_col: np.ndarray, epi_row: np.ndarray,
                    epi_col: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Residuals across and along the epipolar direction.

    Parameters
    ----------
    v_row, v_col : ndarray, (N,)
        Residual offsets in B, pixels.
    epi_row, epi_col : ndarray, (N,)
        Epipolar direction in B, pixels per metre.

    Returns
    -------
    perp, par, norm : ndarray, (N,)
        ``v`` across (pixels) and along (pixels) the epipolar direction, and ``|e|``
        (pixels per metre). Where ``|e|`` is 0 the along direction is B's row axis.
    """
    norm = np.hypot(epi_row, epi_col)
    safe = norm > EPIPOLAR_EPS
    ur = np.where(safe, epi_row / np.where(safe, norm, 1.0), 1.0)
    uc = np.where(safe, epi_col / np.where(safe, norm, 1.0), 0.0)
    par = v_row * ur + v_col * uc
    perp = -v_row * uc + v_col * ur
    return perp, par, np.where(safe, norm, 0.0)


def _weights(epi_row: np.ndarray, epi_col: np.ndarray, sigma_px: float, sigma_h_m: float
             ) -> np.ndarray:
    """Per point the (2, 2) weight matrix ``n n^T / s^2 + u u^T / (s^2 + s_h^2 |e|^2)``."""
    norm = np.hypot(epi_row, epi_col)
    safe = norm > EPIPOLAR_EPS
    ur = np.where(safe, epi_row / np.where(safe, norm, 1.0), 1.0)
    uc = np.where(safe, epi_col / np.where(safe, norm, 1.0), 0.0)
    w_perp = 1.0 / sigma_px**2
    w_par = 1.0 / (sigma_px**2 + (sigma_h_m * norm) ** 2)
    u = np.stack([ur, uc], axis=-1)
    n = np.stack([-uc, ur], axis=-1)
    return (w_perp * n[:, :, None] * n[:, None, :]
            + w_par[:, None, None] * u[:, :, None] * u[:, None, :])


def fit_bias(row_a: np.ndarray, col_a: np.ndarray, d_row: np.ndarray, d_col: np.ndarray,
             epi_row: np.ndarray, epi_col: np.ndarray, *, order: int, sigma_px: float,
             sigma_h_m: float, centre: tuple[float, float], scale: float) -> Bias:
    """Weighted least-squares fit of the bias polynomial to match offsets.

    Each offset weighs with the inverse of its expected covariance: ``sigma_px`` across the
    epipolar direction, ``sqrt(sigma_px^2 + sigma_h_m^2 |e|^2)`` along it (the height
    parallax).

    Parameters
    ----------
    row_a, col_a : ndarray, (N,)
        A's pixels.
    d_row, d_col : ndarray, (N,)
        Offsets ``b - p(a)`` in B, pixels.
    epi_row, epi_col : ndarray, (N,)
        Epipolar directions, pixels per metre.
    order : {0, 1, 2}
        Polynomial order; lowered while there are fewer than :data:`POINTS_PER_TERM`
        matches per term (an affine bias needs 30): with fewer, one wrong match at the edge
        of a small set bends the slopes towards itself and then passes the tests.
    sigma_px, sigma_h_m : float
        Scales across the epipolar direction (pixels) and of the height parallax (metres).
    centre, scale : (float, float), float
        Normalisation of A's pixels.

    Returns
    -------
    Bias

    Raises
    ------
    MatchError
        No point, or an unknown order.
    """
    if order not in N_TERMS:
        raise MatchError(f"the bias order must be 0, 1 or 2, got {order!r}")
    n = int(np.size(row_a))
    if n == 0:
        raise MatchError("fit_bias: no match to fit the bias to")
    while order > 0 and n < POINTS_PER_TERM * N_TERMS[order]:
        order -= 1
    template = Bias.zero(centre, scale)
    phi = template.terms(row_a, col_a, order)  # (N, m)
    m = phi.shape[1]
    w = _weights(epi_row, epi_col, sigma_px, sigma_h_m)  # (N, 2, 2)
    # unknowns p = [C_row, C_col] (2 m); design per point A_n = kron(I2, phi_n) (2, 2m)
    design = np.zeros((n, 2, 2 * m))
    design[:, 0, :m] = phi
    design[:, 1, m:] = phi
    d = np.stack([d_row, d_col], axis=-1)
    normal = np.einsum("nik,nij,njl->kl", design, w, design)
    rhs = np.einsum("nik,nij,nj->k", design, w, d)
    coef = np.linalg.lstsq(normal, rhs, rcond=None)[0]
    return Bias(coef.reshape(2, m), centre, scale)


@dataclass(frozen=True, eq=False)
class Consistency:
    """The outcome of :func:`consistent`.

    Attributes
    ----------
    bias : Bias
    inlier : ndarray of bool, (N,)
    epipolar : ndarray of bool, (N,)
        Rejected by the epipolar test.
    height : ndarray of bool, (N,)
        Rejected by the height test (and not by the epipolar one).
    perp : ndarray, (N,)
        Residual across the epipolar direction after the bias, pixels.
    height_m : ndarray, (N,)
        Residual along it as a height, metres (NaN where ``|e|`` is 0).
    sigma_px : float
        Robust scale of the inliers' ``perp``, pixels (floored).
    sigma_h_m : float
        Robust scale of the inliers' height parallax, metres (floored).
    iterations : int
    converged : bool
        The inlier set stopped changing within the iteration cap.
    """

    bias: Bias
    inlier: np.ndarray
    epipolar: np.ndarray
    height: np.ndarray
    perp: np.ndarray
    height_m: np.ndarray
    sigma_px: float
    sigma_h_m: float
    iterations: int
    converged: bool


def _robust_scale(values: np.ndarray, floor: float) -> float:
    values = values[np.isfinite(values)]
    if not values.size:
        return floor
    return max(MAD_SCALE * float(np.median(np.abs(values))), floor)


def consistent(row_a: np.ndarray, col_a: np.ndarray, d_row: np.ndarray, d_col: np.ndarray,
               epi_row: np.ndarray, epi_col: np.ndarray, start: np.ndarray, *,
               order: int = 1, k: float = 3.0, min_sigma_px: float = 0.1,
               min_sigma_h_m: float = 1.0, max_sigma_px: float = math.inf,
               max_sigma_h_m: float = math.inf, sigma_px: float = 1.0,
               sigma_h_m: float = 10.0, centre: tuple[float, float], scale: float,
               eligible: np.ndarray | None = None, max_iterations: int = 20) -> Consistency:
    """Fit the bias and reject the inconsistent matches, to a fixed point.

    Each iteration fits :func:`fit_bias` to the current inliers (with the current scales),
    computes every match's residuals, re-estimates the robust scales ``s_perp`` and ``s_h``
    from the inliers, and applies the epipolar and height tests (module docstring) to all
    matches; it stops when the inlier set no longer changes or after ``max_iterations``.

    Parameters
    ----------
    row_a, col_a, d_row, d_col, epi_row, epi_col : ndarray, (N,)
        As :func:`fit_bias`.
    start : ndarray of bool, (N,)
        The first inlier set (:func:`consensus`).
    order : {0, 1, 2}
        Bias polynomial order.
    k : float
        Rejection threshold, in robust standard deviations.
    min_sigma_px, min_sigma_h_m : float
        Floors of the robust scales (a handful of perfect matches must not make the test
        reject everything else).
    max_sigma_px, max_sigma_h_m : float
        Ceilings of the robust scales: where wrong matches are as many as right ones near
        the threshold, admitting them would widen the scale, which would admit more; the
        ceiling stops that.
    sigma_px, sigma_h_m : float
        Starting scales.
    centre, scale : (float, float), float
        Normalisation of A's pixels.
    eligible : ndarray of bool, (N,), optional
        The matches that may be inliers (default: all). Matches rejected by earlier tests
        (descriptor ratio, correlation) get residuals and test outcomes but never enter the
        bias fit, however close to it they fall.
    max_iterations : int
        Iteration cap.

    Returns
    -------
    Consistency

    Raises
    ------
    MatchError
        ``start`` selects no match.
    """
    eligible = (np.ones(np.size(row_a), bool) if eligible is None
                else np.asarray(eligible, bool))
    inlier = np.asarray(start, bool) & eligible
    if not inlier.any():
        raise MatchError("no match to start the consistency test from")
    s_p = min(max(float(sigma_px), min_sigma_px), max(max_sigma_px, min_sigma_px))
    s_h = min(max(float(sigma_h_m), min_sigma_h_m), max(max_sigma_h_m, min_sigma_h_m))
    converged = False
    it = 0
    bias = Bias.zero(centre, scale)
    perp = par = norm = np.zeros(np.size(row_a))
    eps_fail = h_fail = np.zeros(np.size(row_a), bool)
    for it in range(1, max_iterations + 1):  # noqa: B007 - the count is reported
        bias = fit_bias(row_a[inlier], col_a[inlier], d_row[inlier], d_col[inlier],
                        epi_row[inlier], epi_col[inlier], order=order, sigma_px=s_p,
                        sigma_h_m=s_h, centre=centre, scale=scale)
        br, bc = bias(row_a, col_a)
        perp, par, norm = split_residuals(d_row - br, d_col - bc, epi_row, epi_col)
        s_p = min(_robust_scale(perp[inlier], min_sigma_px), max(max_sigma_px, min_sigma_px))
        with np.errstate(invalid="ignore", divide="ignore"):
            height = np.where(norm > EPIPOLAR_EPS, par / norm, np.nan)
        # the height's scale from the points whose parallax is well above the noise
        informative = inlier & (norm * s_h > s_p)
        s_h = min(_robust_scale(height[informative], min_sigma_h_m),
                  max(max_sigma_h_m, min_sigma_h_m))
        eps_fail = np.abs(perp) > k * s_p
        h_fail = ~eps_fail & (np.abs(par) > k * np.sqrt(s_p**2 + (s_h * norm) ** 2))
        new = ~(eps_fail | h_fail) & eligible
        if not new.any():
            raise MatchError("the consistency test rejected every match")
        if np.array_equal(new, inlier):
            converged = True
            break
        inlier = new
    with np.errstate(invalid="ignore", divide="ignore"):
        height_m = np.where(norm > EPIPOLAR_EPS, par / norm, np.nan)
    return Consistency(bias, inlier, eps_fail, h_fail, perp, height_m, s_p, s_h, it,
                       converged)


def consensus(d_row: np.ndarray, d_col: np.ndarray, epi_row: np.ndarray, epi_col: np.ndarray,
              *, tolerance_px: float, height_tolerance_m: float,
              max_hypotheses: int = 400) -> np.ndarray:
    """The largest set of matches that agree on one constant bias (one-point RANSAC).

    Every match's own offset (at most ``max_hypotheses`` of them, evenly picked) is tried as
    the constant bias; a match agrees with it when its offset differs by at most
    ``tolerance_px`` across its epipolar direction and ``tolerance_px + height_tolerance_m
    |e|`` along it.

    Parameters
    ----------
    d_row, d_col : ndarray, (N,)
        Offsets ``b - p(a)``, pixels.
    epi_row, epi_col : ndarray, (N,)
        Epipolar directions, pixels per metre.
    tolerance_px : float
    height_tolerance_m : float
    max_hypotheses : int

    Returns
    -------
    ndarray of bool, (N,)
        The matches agreeing with the best hypothesis (all False when N is 0).
    """
    n = int(np.size(d_row))
    if n == 0:
        return np.zeros(0, bool)
    hyp = np.unique(np.linspace(0, n - 1, min(n, max_hypotheses)).round().astype(np.intp))
    # (H, N) residuals of every match against every hypothesis
    vr = d_row[None, :] - d_row[hyp, None]
    vc = d_col[None, :] - d_col[hyp, None]
    perp, par, norm = split_residuals(vr, vc, epi_row[None, :], epi_col[None, :])
    agree = (np.abs(perp) <= tolerance_px) & (
        np.abs(par) <= tolerance_px + height_tolerance_m * norm)
    best = int(np.argmax(agree.sum(axis=1)))
    return agree[best]


def scale_of(shape: tuple[int, int]) -> tuple[tuple[float, float], float]:
    """Normalisation (centre, scale) of an image's pixels for the bias polynomial."""
    rows, cols = shape
    return ((rows - 1) / 2.0, (cols - 1) / 2.0), max(max(rows, cols) / 2.0, 1.0)

