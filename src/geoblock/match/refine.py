"""Sub-pixel refinement of matches: correlation, then least-squares matching, in the models'
local geometry.

For a match ``a -> b`` the template is the ``(2 half + 1)^2`` patch of A centred on ``a``
(A's keypoint: the reference, never moved). B is not compared on its own pixel grid but on the
template's grid mapped into B by the models' local affinity ``J``
(:func:`geoblock.match.geometry.local_affine`: A's pixels -> B's pixels through the DEM), so
that a rotation, a scale difference or the foreshortening of a slope between the two views
does not blur the comparison. B is resampled with the bicubic kernel of the orthorectifier
(:func:`geoblock.ortho.kernels.resample`).

1. **Correlation.** The normalised cross-correlation (NCC) of the template with B at every
   integer shift of the grid within ``search_px``; while the peak lies on the border of the
   searched shifts, ``b`` moves there and the search is repeated with one pixel around it
   (at most ``search_px`` in all). A quadratic fitted to the 3 x 3 correlations around the
   peak gives its sub-pixel vertex; a peak that is not a maximum, or a ridge (the smaller
   curvature below ``min_curvature_ratio`` times the larger: a straight edge, whose position
   along itself is undetermined) is refused.
2. **Least-squares matching** (Gruen 1985; the solver of :mod:`geoblock.match.lsm`), from
   that vertex: Gauss-Newton on the shift ``d`` and a radiometric gain and offset (started
   from the patches' moments), minimising ``sum w(u) (T(u) - g0 - g1 B(b + J (u + d)))^2``
   over the patch with a Gaussian window ``w`` (:data:`WINDOW_SIGMA`), until the shift's
   update is at most ``tolerance_px`` (at most ``max_iterations``; the solution must stay
   within :data:`MAX_SHIFT_PX` of the correlation peak). Unlike a peak fitted to
   correlations, which a patch's asymmetry biases by a tenth of a pixel, the least-squares
   solution is unbiased where the two patches are the same signal (0.02 px on a smooth image
   shifted by a known amount); its covariance gives each match's precision.

Per match the outcome is a :class:`RefineStatus`. Vectorised over matches in chunks (no loop
over points or pixels).
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

import numpy as np

from geoblock.errors import MatchError
from geoblock.match.lsm import LsmStatus, least_squares_match

__all__ = ["RefineStatus", "Refined", "refine_matches"]


class RefineStatus(enum.IntEnum):
    """Outcome of the refinement of one match."""

    #: converged, correlation at least ``min_score``
    CONVERGED = 0
    #: converged but the correlation peak is below ``min_score``
    LOW_SCORE = 1
    #: the peak left the search area (moved more than ``search_px`` from the start)
    EDGE = 2
    #: a patch reaches out of the image window or into nodata, or has no contrast (the
    #: least-squares matching's normal equations are ill-conditioned: :data:`MAX_CONDITION`)
    NO_DATA = 3
    #: still moving after ``max_iterations``, or the least-squares matching left the
    #: correlation peak (beyond :data:`MAX_SHIFT_PX`)
    MAX_ITERATIONS = 4
    #: the correlation peak is a ridge (a straight edge: its position along the edge is
    #: undetermined) or not a maximum
    RIDGE = 5


@dataclass(frozen=True, eq=False)
class Refined:
    """Refined positions in B.

    Attributes
    ----------
    row, col : ndarray, (N,)
        Pixels of B's window (as given); the start where the refinement failed.
    score : ndarray, (N,)
        Normalised cross-correlation at the refined position, in [-1, 1] (NaN without
        data).
    sigma : ndarray, (N,)
        Standard deviation of the refined position from the least-squares matching (the
        larger axis), pixels of A's grid (NaN where not refined): the precision the patch's
        texture and the residual differences allow.
    status : ndarray of uint8, (N,)
        :class:`RefineStatus`.
    """

    row: np.ndarray
    col: np.ndarray
    score: np.ndarray
    sigma: np.ndarray
    status: np.ndarray


def _sample(pixels: np.ndarray, row: np.ndarray, col: np.ndarray) -> np.ndarray:
    """Bicubic samples of a 2-D float window (NaN: nodata) at fractional pixels; NaN where a
    tap is outside or without data."""
    from geoblock.ortho.kernels import resample

    values, valid = resample(pixels[None], row, col, "bicubic", nodata=math.nan)
    out = values[0]
    out[~valid] = np.nan
    return out


# least squares of c = a0 + a1 y + a2 x + a3 y^2 + a4 x y + a5 x^2 on the 3 x 3 samples
_Y, _X = (v.ravel() for v in np.meshgrid([-1.0, 0.0, 1.0], [-1.0, 0.0, 1.0], indexing="ij"))
_QUADRATIC = np.linalg.pinv(np.column_stack([np.ones(9), _Y, _X, _Y**2, _X * _Y, _X**2]))


def _peak(samples: np.ndarray, min_ratio: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sub-pixel peak of ``(n, 3, 3)`` correlations centred on their maximum.

    Returns the vertex ``(n, 2)`` (row, col offsets from the centre, clipped to [-1, 1]), the
    quadratic's value there, and whether the peak is well defined: the Hessian is negative
    definite and its smaller curvature is at least ``min_ratio`` times the larger (a ridge,
    the correlation of a straight edge, is not a point).
    """
    a = samples.reshape(-1, 9) @ _QUADRATIC.T  # (n, 6)
    h = np.empty((a.shape[0], 2, 2))
    h[:, 0, 0] = 2 * a[:, 3]
    h[:, 1, 1] = 2 * a[:, 5]
    h[:, 0, 1] = h[:, 1, 0] = a[:, 4]
    curv = np.linalg.eigvalsh(-h)  # ascending: the smaller curvature first
    sharp = (curv[:, 0] > 0) & (curv[:, 0] >= min_ratio * curv[:, 1])
    det = h[:, 0, 0] * h[:, 1, 1] - h[:, 0, 1] ** 2
    safe = np.where(sharp, det, 1.0)
    # vertex: H v = -g
    gy, gx = a[:, 1], a[:, 2]
    vy = np.where(sharp, (-gy * h[:, 1, 1] + gx * h[:, 0, 1]) / safe, 0.0)
    vx = np.where(sharp, (-gx * h[:, 0, 0] + gy * h[:, 1, 0]) / safe, 0.0)
    vertex = np.clip(np.stack([vy, vx], axis=-1), -1.0, 1.0)
    value = (a[:, 0] + a[:, 1] * vertex[:, 0] + a[:, 2] * vertex[:, 1]
             + a[:, 3] * vertex[:, 0] ** 2 + a[:, 4] * vertex[:, 0] * vertex[:, 1]
             + a[:, 5] * vertex[:, 1] ** 2)
    return vertex, value, sharp


def _correlate(template: np.ndarray, area: np.ndarray) -> np.ndarray:
    """NCC of ``(n, P, P)`` zero-mean unit-norm templates with every ``P x P`` window of
    ``(n, Q, Q)`` areas: ``(n, Q - P + 1, Q - P + 1)`` (NaN where a window has no contrast or
    no data)."""
    p = template.shape[-1]
    windows = np.lib.stride_tricks.sliding_window_view(area, (p, p), axis=(1, 2))
    num = np.einsum("nijpq,npq->nij", windows, template)
    s1 = windows.sum(axis=(-1, -2))
    s2 = np.einsum("nijpq,nijpq->nij", windows, windows)
    var = s2 - s1 * s1 / (p * p)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(var > 1e-12, num / np.sqrt(np.maximum(var, 1e-12)), np.nan)


_OFF = np.array([-1, 0, 1])


def _affine_grid(jac: np.ndarray, q: np.ndarray, shift: np.ndarray | None = None
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Offsets in B (rows, cols), ``(m, Q, Q)``, of the template grid ``q x q`` (shifted by
    ``shift`` (m, 2), template-grid pixels) mapped by ``jac`` (m, 2, 2)."""
    qr = q[None, :, None] + (0.0 if shift is None else shift[:, 0, None, None])
    qc = q[None, None, :] + (0.0 if shift is None else shift[:, 1, None, None])
    dr = jac[:, 0, 0, None, None] * qr + jac[:, 0, 1, None, None] * qc
    dc = jac[:, 1, 0, None, None] * qr + jac[:, 1, 1, None, None] * qc
    return dr, dc


def _ncc_walk(template: np.ndarray, pix_b: np.ndarray, row: np.ndarray, col: np.ndarray,
              jac: np.ndarray, half: int, search: int, max_iterations: int,
              min_ratio: float, status: np.ndarray) -> np.ndarray:
    """Stage 1: the integer NCC peak, walking to it while it is on the search border; its
    sub-pixel vertex (a quadratic through the 3 x 3 correlations) starts stage 2.

    Moves ``row, col`` (in place) to the integer peak; returns the vertex (n, 2), template-
    grid pixels. ``status`` (in place) gets NO_DATA, EDGE, RIDGE or MAX_ITERATIONS for the
    points that do not reach stage 2 (which keep ``_PENDING``).
    """
    n = row.size
    vertex = np.zeros((n, 2))
    moved = np.zeros((n, 2))
    active = status == _PENDING
    s = search
    for _ in range(max_iterations):
        idx = np.flatnonzero(active)
        if not idx.size:
            break
        q = np.arange(-(half + s), half + s + 1, dtype=float)
        dr, dc = _affine_grid(jac[idx], q)
        area = _sample(pix_b, row[idx, None, None] + dr, col[idx, None, None] + dc)
        ncc = _correlate(template[idx], area)  # (m, 2s+1, 2s+1)
        m = idx.size
        flat = np.where(np.isfinite(ncc), ncc, -np.inf).reshape(m, -1)
        peak = np.argmax(flat, axis=1)
        pi, pj = np.divmod(peak, 2 * s + 1)
        no_data = ~np.isfinite(flat[np.arange(m), peak])
        inner = (pi > 0) & (pi < 2 * s) & (pj > 0) & (pj < 2 * s) & ~no_data
        step = np.stack([pi - s, pj - s], axis=-1).astype(float)
        step[no_data] = 0.0
        moved[idx] += step
        shift = np.einsum("nij,nj->ni", jac[idx], step)
        row[idx] += shift[:, 0]
        col[idx] += shift[:, 1]
        drifted = ~no_data & (np.abs(moved[idx]).max(axis=1) > search)
        # the 3 x 3 correlations around an inner peak -> its sub-pixel vertex
        ci, cj = np.clip(pi, 1, 2 * s - 1), np.clip(pj, 1, 2 * s - 1)
        around = ncc[np.arange(m)[:, None, None], ci[:, None, None] + _OFF[:, None],
                     cj[:, None, None] + _OFF[None, :]]
        v, _, sharp = _peak(np.nan_to_num(around, nan=-1.0), min_ratio)
        vertex[idx] = v
        status[idx[no_data]] = RefineStatus.NO_DATA
        status[idx[drifted]] = RefineStatus.EDGE
        status[idx[inner & ~sharp & ~drifted]] = RefineStatus.RIDGE
        active[idx[no_data | drifted | inner]] = False
        s = 1
    status[active] = RefineStatus.MAX_ITERATIONS
    return vertex


def _lsm(template: np.ndarray, pix_b: np.ndarray, row: np.ndarray, col: np.ndarray,
         jac: np.ndarray, start: np.ndarray, half: int, max_iterations: int,
         tolerance: float) -> tuple[np.ndarray, ...]:
    """Stage 2: least-squares matching of the template with B
    (:func:`geoblock.match.lsm.least_squares_match`), for the shift ``d`` (template-grid
    pixels) and a radiometric gain and offset (from the moments), from ``start``: minimise
    ``sum w(u) (T(u) - g0 - g1 B(b + J (u + d)))^2`` over the patch, ``w`` a Gaussian window.

    Returns ``d`` (n, 2), its standard deviation (n,) (the larger of the two axes',
    template-grid pixels; NaN without data or texture), the NCC at ``d`` (n,), and the
    :class:`~geoblock.match.lsm.LsmStatus` of each point.
    """
    q = np.arange(-(half + 1), half + 2, dtype=float)  # one more pixel for the gradients

    def sample(idx: np.ndarray, shift: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """B on the template grid mapped by J and shifted, and its central differences along
        the template's rows and columns, ``(m, P)`` each."""
        dr, dc = _affine_grid(jac[idx], q, shift)
        big = _sample(pix_b, row[idx, None, None] + dr, col[idx, None, None] + dc)
        g = big[:, 1:-1, 1:-1]
        gr = 0.5 * (big[:, 2:, 1:-1] - big[:, :-2, 1:-1])  # d/d(template row)
        gc = 0.5 * (big[:, 1:-1, 2:] - big[:, 1:-1, :-2])  # d/d(template col)
        m = idx.size
        return g.reshape(m, -1), gr.reshape(m, -1), gc.reshape(m, -1)

    # a Gaussian window: the centre, where the match is wanted, counts most (over relief, the
    # patch's edges see other parallaxes)
    u = q[1:-1]
    weight = np.exp(-0.5 * (u[:, None] ** 2 + u[None, :] ** 2) / (WINDOW_SIGMA * half) ** 2
                    ).ravel()
    solution = least_squares_match(
        template.reshape(row.size, -1), sample, start, weight=weight, radiometry="moments",
        max_iterations=max_iterations, tolerance_px=tolerance, max_shift_px=MAX_SHIFT_PX,
        shift_norm="max", max_condition=MAX_CONDITION)
    d = solution.shift
    sigma = np.sqrt(np.maximum(solution.covariance[:, 0, 0], solution.covariance[:, 1, 1]))
    # the NCC at the final shift
    dr, dc = _affine_grid(jac, u, d)
    final = _sample(pix_b, row[:, None, None] + dr, col[:, None, None] + dc)
    centred = template - template.mean(axis=(1, 2), keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        unit = centred / np.sqrt((centred**2).sum(axis=(1, 2)))[:, None, None]
    score = _correlate(unit, final)[:, 0, 0]
    return d, sigma, score, solution.status


_PENDING = np.uint8(255)
#: Standard deviation of the least-squares matching's Gaussian window, in patch half-sizes.
WINDOW_SIGMA = 0.5
#: Largest row or column distance of the least-squares matching's solution from the
#: correlation peak, template-grid pixels: beyond it the iteration left the peak's 3 x 3 cells.
MAX_SHIFT_PX = 1.5
#: Largest condition number of the least-squares matching's column-equilibrated normal
#: matrix: above it the patch has no texture to match.
MAX_CONDITION = 1e8


def _refine_chunk(pix_a: np.ndarray, pix_b: np.ndarray, ra: np.ndarray, ca: np.ndarray,
                  rb: np.ndarray, cb: np.ndarray, jac: np.ndarray, half: int, search: int,
                  max_iterations: int, tolerance: float, min_score: float, min_ratio: float
                  ) -> tuple[np.ndarray, ...]:
    n = ra.size
    u = np.arange(-half, half + 1, dtype=float)
    raw = _sample(pix_a, ra[:, None, None] + u[None, :, None], ca[:, None, None] + u[None, None, :])
    centred = raw - raw.mean(axis=(1, 2), keepdims=True)
    norm = np.sqrt((centred**2).sum(axis=(1, 2)))
    with np.errstate(invalid="ignore", divide="ignore"):
        unit = centred / norm[:, None, None]
    status = np.full(n, _PENDING)
    status[~(norm > 1e-6)] = RefineStatus.NO_DATA  # NaN (nodata) or a flat patch
    row, col = rb.copy(), cb.copy()
    vertex = _ncc_walk(unit, pix_b, row, col, jac, half, search, max_iterations, min_ratio,
                       status)
    score = np.full(n, np.nan)
    sigma = np.full(n, np.nan)
    idx = np.flatnonzero(status == _PENDING)
    if idx.size:
        d, sig, sc, lsm = _lsm(raw[idx], pix_b, row[idx], col[idx], jac[idx], vertex[idx],
                               half, max_iterations, tolerance)
        shift = np.einsum("nij,nj->ni", jac[idx], d)
        row[idx] += shift[:, 0]
        col[idx] += shift[:, 1]
        score[idx] = sc
        sigma[idx] = sig
        no_data = np.isin(lsm, (LsmStatus.NO_DATA, LsmStatus.NO_TEXTURE)) | ~np.isfinite(sc)
        status[idx] = np.where(no_data, RefineStatus.NO_DATA, np.where(
            lsm != LsmStatus.CONVERGED, RefineStatus.MAX_ITERATIONS, np.where(
                sc >= min_score, RefineStatus.CONVERGED, RefineStatus.LOW_SCORE)))
    failed = status != RefineStatus.CONVERGED
    row[failed] = rb[failed]
    col[failed] = cb[failed]
    return row, col, score, sigma, status


def refine_matches(pixels_a: np.ndarray, pixels_b: np.ndarray, row_a: np.ndarray,
                   col_a: np.ndarray, row_b: np.ndarray, col_b: np.ndarray,
                   jacobian: np.ndarray, *, half_px: int = 7, search_px: int = 3,
                   max_iterations: int = 10, tolerance_px: float = 0.01,
                   min_score: float = 0.7, min_curvature_ratio: float = 0.1,
                   chunk: int = 256) -> Refined:
    """Refine the B side of matches to sub-pixel accuracy by normalised cross-correlation.

    Parameters
    ----------
    pixels_a, pixels_b : ndarray, (R, C)
        The two images' windows as floats, NaN where there is no data.
    row_a, col_a : ndarray, (N,)
        A's points (the templates' centres), pixels of ``pixels_a``.
    row_b, col_b : ndarray, (N,)
        Starting positions in B, pixels of ``pixels_b``.
    jacobian : ndarray, (N, 2, 2)
        Local affinity A -> B (:func:`geoblock.match.geometry.local_affine`).
    half_px : int
        Template half-size: ``(2 half_px + 1)^2`` pixels.
    search_px : int
        Largest shift searched from the start, template-grid pixels.
    max_iterations : int
        Iteration cap.
    tolerance_px : float
        Converged when the last shift is at most this, template-grid pixels.
    min_score : float
        Correlation below which a converged match is ``LOW_SCORE``.
    min_curvature_ratio : float
        The correlation peak's smaller curvature must be at least this times the larger one,
        or the match is a ``RIDGE`` (an edge, undetermined along itself).
    chunk : int
        Matches per vectorised chunk (memory: about ``chunk * (2 search + 1)^2 *
        (2 half + 1)^2 * 16`` bytes).

    Returns
    -------
    Refined

    Raises
    ------
    MatchError
        An option out of range.
    """
    if half_px < 2 or search_px < 1 or max_iterations < 1 or chunk < 1:
        raise MatchError(f"refine_matches: need half_px >= 2, search_px >= 1, max_iterations "
                         f">= 1 and chunk >= 1, got {half_px}, {search_px}, {max_iterations}, "
                         f"{chunk}")
    if not (math.isfinite(tolerance_px) and tolerance_px > 0):
        raise MatchError(f"refine_matches: tolerance_px must be > 0, got {tolerance_px!r}")
    row_a, col_a, row_b, col_b = (np.asarray(v, float).ravel()
                                  for v in (row_a, col_a, row_b, col_b))
    n = row_a.size
    out: list[np.ndarray] = [np.empty(n), np.empty(n), np.empty(n), np.empty(n),
                             np.empty(n, np.uint8)]
    pix_a = np.asarray(pixels_a, np.float64)
    pix_b = np.asarray(pixels_b, np.float64)
    for start in range(0, n, chunk):  # chunks of matches, each vectorised
        sl = slice(start, min(start + chunk, n))
        res = _refine_chunk(pix_a, pix_b, row_a[sl], col_a[sl], row_b[sl], col_b[sl],
                            np.asarray(jacobian, float)[sl], int(half_px), int(search_px),
                            int(max_iterations), float(tolerance_px), float(min_score),
                            float(min_curvature_ratio))
        for target, value in zip(out, res, strict=True):
            target[sl] = value
    return Refined(*out)
