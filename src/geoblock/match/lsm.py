"""Least-squares matching (Gruen 1985): the Gauss-Newton solver shared by the matcher's sub-pixel
refinement (:func:`geoblock.match.refine.refine_matches`) and the seam measurement between
orthos (:func:`geoblock.match.seams.seam_shift`).

A patch is a set of ``P`` pixels ``u`` of a reference image ``T`` (the target) and the search
image ``B`` seen through a shift ``d``; the solver finds, per patch, the shift and a linear
radiometric correction that make them agree:

    minimise  sum_u  w(u) (T(u) - offset - gain B(u + d))^2

by Gauss-Newton on ``(d_row, d_col, gain, offset)``. The caller supplies ``B`` and its
derivatives through a sampler (the frame of ``d``, the interpolation and the geometry of the
patch are the caller's: the matcher maps its template grid into B by the models' local
affinity, the seam measurement shifts orthos on one map grid). The weights are the product of
a fixed window ``w0(u)`` (e.g. a Gaussian: the patch's centre counts most) and, optionally,
Cauchy weights of the residuals ``1 / (1 + (r / (k s))^2)`` with ``s`` the residuals' robust
standard deviation (1.4826 times their median absolute deviation), recomputed at every
iteration from the second on, so that pixels that differ for other reasons than the shift
(occlusions, clouds, aliased texture) do not pull it.

Every patch stops with a :class:`LsmStatus`: converged when the shift's update is at most
``tolerance_px`` (with robust weights, not before the second iteration: the first step is
taken with other weights), diverged when the shift's norm (its length, or its largest
component) exceeds ``max_shift_px``, no texture when
the normal equations are ill-conditioned, no data when a sample is NaN, or still moving after
``max_iterations``. Vectorised over patches of one size and over their pixels.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

import numpy as np

from geoblock.errors import MatchError, ShapeMismatchError

if TYPE_CHECKING:
    from geoblock.typing import Float64Array, IndexArray, StatusArray

__all__ = ["LsmSolution", "LsmStatus", "Sampler", "least_squares_match"]

#: ``sample(index, shift) -> (values, d_row, d_col)``: the search image at the pixels of the
#: patches ``index`` (``(m,)`` indices into the ``N`` patches) shifted by ``shift``
#: (``(m, 2)``, row and column, pixels of the frame the caller chose), and its derivatives
#: with respect to the shift's row and column: three ``(m, P)`` arrays, NaN where there is
#: no data.
Sampler = Callable[["IndexArray", "Float64Array"],
                   tuple["Float64Array", "Float64Array", "Float64Array"]]

#: Smallest robust standard deviation of the residuals the Cauchy weights divide by.
_MIN_SPREAD = 1e-12


class LsmStatus(enum.IntEnum):
    """Outcome of the least-squares matching of one patch."""

    #: the shift's last update is at most ``tolerance_px``
    CONVERGED = 0
    #: still moving after ``max_iterations``
    MAX_ITERATIONS = 1
    #: the shift left ``max_shift_px`` (its length, or its largest component)
    DIVERGED = 2
    #: the normal equations are ill-conditioned (condition number of their column-equilibrated
    #: matrix above ``max_condition``, or a column of zeros): a patch without texture, or
    #: whose texture is a straight edge
    NO_TEXTURE = 3
    #: a sample of the search image (or of the target) is NaN: the patch reaches out of the
    #: image or into nodata
    NO_DATA = 4


@dataclass(frozen=True, eq=False)
class LsmSolution:
    """The solution of :func:`least_squares_match`, per patch.

    Attributes
    ----------
    shift : ndarray, (N, 2)
        ``(d_row, d_col)``, pixels of the sampler's frame: where the search image shows what
        the target shows at ``u`` is ``u + d``. The last iterate whatever the status (the
        start for a patch that stopped at the first iteration without data or texture).
    gain, offset : ndarray, (N,)
        The radiometric correction, ``T ~ offset + gain B`` (last iterate).
    covariance : ndarray, (N, 2, 2)
        A posteriori covariance of the shift, pixels squared: ``s0^2`` times the shift's block
        of the inverse normal matrix at the last linearisation, ``s0^2`` the weighted residuals'
        sum of squares over ``sum(w) - 4``. NaN for ``NO_DATA`` and ``NO_TEXTURE``.
    iterations : ndarray of int, (N,)
        Iterations run (the one at which the patch stopped).
    status : ndarray of uint8, (N,)
        :class:`LsmStatus`.
    """

    shift: Float64Array
    gain: Float64Array
    offset: Float64Array
    covariance: Float64Array
    iterations: IndexArray
    status: StatusArray


def _moments(target: Float64Array, values: Float64Array) -> tuple[Float64Array, Float64Array]:
    """Gain and offset matching the mean and standard deviation of ``values`` (m, P) to those
    of ``target`` (m, P); gain 1 where either has no spread."""
    with np.errstate(invalid="ignore", divide="ignore"):
        gain = target.std(axis=1) / values.std(axis=1)
    gain = np.where(np.isfinite(gain) & (gain > 0), gain, 1.0)
    return gain, target.mean(axis=1) - gain * values.mean(axis=1)


def _cauchy(residual: Float64Array, k: float) -> Float64Array:
    """Cauchy weights of ``(m, P)`` residuals, in units of ``k`` robust standard deviations
    (1.4826 x the median absolute deviation) of each patch's residuals."""
    centre = np.median(residual, axis=1, keepdims=True)
    spread = 1.4826 * np.median(np.abs(residual - centre), axis=1, keepdims=True)
    u = residual / (k * np.maximum(spread, _MIN_SPREAD))
    return 1.0 / (1.0 + u**2)


def least_squares_match(
    target: np.ndarray,
    sample: Sampler,
    start: np.ndarray,
    *,
    weight: np.ndarray | None = None,
    robust_k: float | None = None,
    radiometry: Literal["moments", "identity"] = "moments",
    max_iterations: int = 10,
    tolerance_px: float = 0.01,
    max_shift_px: float = 1.5,
    shift_norm: Literal["euclidean", "max"] = "euclidean",
    max_condition: float = 1e8,
) -> LsmSolution:
    """Least-squares matching of ``N`` patches: shift plus radiometric gain and offset (module
    docstring).

    Parameters
    ----------
    target : ndarray, (N, P)
        The reference patches' values (a patch with a NaN is ``NO_DATA``).
    sample : Sampler
        The search image and its derivatives with respect to the shift at a shift, per patch
        (:data:`Sampler`); it defines the frame of the shift.
    start : ndarray, (N, 2)
        Initial shift ``(d_row, d_col)``, pixels of the sampler's frame.
    weight : ndarray, (P,), optional
        Fixed weights of the patch's pixels (a window; non-negative). Default: all 1.
    robust_k : float, optional
        Constant of the Cauchy weights, in robust standard deviations of the residuals,
        applied from the second iteration on. Default: none (the fixed weights only).
    radiometry : {"moments", "identity"}
        Initial gain and offset: matching the first samples' mean and standard deviation to
        the target's, or 1 and 0.
    max_iterations : int
        Iteration cap.
    tolerance_px : float
        Converged when the largest component of the shift's update is at most this, pixels.
    max_shift_px : float
        Diverged when the shift's norm exceeds this, pixels.
    shift_norm : {"euclidean", "max"}
        The norm ``max_shift_px`` bounds: the shift's length (a disc), or its largest
        component (a square: e.g. the 3 x 3 cells around a correlation peak).
    max_condition : float
        Largest condition number of the column-equilibrated normal matrix (the square of the
        weighted Jacobian's): above it the patch has ``NO_TEXTURE``.

    Returns
    -------
    LsmSolution

    Raises
    ------
    ShapeMismatchError
        ``target``, ``start`` or ``weight`` of inconsistent shapes.
    MatchError
        An option out of range.
    """
    t = np.asarray(target, np.float64)
    d = np.array(start, np.float64)  # a copy: the iterate
    if t.ndim != 2 or d.shape != (t.shape[0], 2):
        raise ShapeMismatchError(f"least_squares_match: target must be (N, P) and start (N, 2), "
                                 f"got {t.shape} and {d.shape}")
    n, p = t.shape
    w0 = np.ones(p) if weight is None else np.asarray(weight, np.float64)
    if w0.shape != (p,):
        raise ShapeMismatchError(f"least_squares_match: weight must be ({p},) like the "
                                 f"patches, got {w0.shape}")
    if max_iterations < 1 or radiometry not in ("moments", "identity") \
            or shift_norm not in ("euclidean", "max"):
        raise MatchError(f"least_squares_match: need max_iterations >= 1, radiometry "
                         f"'moments' or 'identity' and shift_norm 'euclidean' or 'max', got "
                         f"{max_iterations}, {radiometry!r}, {shift_norm!r}")
    for name, value in (("tolerance_px", tolerance_px), ("max_shift_px", max_shift_px),
                        ("max_condition", max_condition),
                        ("robust_k", 1.0 if robust_k is None else robust_k)):
        if not (math.isfinite(value) and value > 0):
            raise MatchError(f"least_squares_match: {name} must be > 0, got {value!r}")
    if not (np.isfinite(w0).all() and (w0 >= 0).all()):
        raise MatchError("least_squares_match: weight must be finite and >= 0")

    gain, offset = np.ones(n), np.zeros(n)
    covariance = np.full((n, 2, 2), np.nan)
    iterations = np.zeros(n, np.intp)
    status = np.full(n, LsmStatus.MAX_ITERATIONS, np.uint8)
    active = np.ones(n, bool)
    for iteration in range(1, max_iterations + 1):
        idx = np.flatnonzero(active)
        if not idx.size:
            break
        iterations[idx] = iteration
        values, d_row, d_col = sample(idx, d[idx])
        ti = t[idx]
        finite = (np.isfinite(ti).all(axis=1) & np.isfinite(values).all(axis=1)
                  & np.isfinite(d_row).all(axis=1) & np.isfinite(d_col).all(axis=1))
        if iteration == 1 and radiometry == "moments":
            gain[idx[finite]], offset[idx[finite]] = _moments(ti[finite], values[finite])
        g1, g0 = gain[idx, None], offset[idx, None]
        design = np.stack([g1 * d_row, g1 * d_col, values, np.ones_like(values)], axis=-1)
        residual = ti - g0 - g1 * values
        design[~finite] = 0.0
        residual[~finite] = 0.0
        w = np.broadcast_to(w0, residual.shape)
        if robust_k is not None and iteration > 1:
            w = w0 * _cauchy(residual, robust_k)
        normal = np.einsum("mpi,mp,mpj->mij", design, w, design)
        rhs = np.einsum("mpi,mp,mp->mi", design, w, residual)
        # conditioning of the column-equilibrated normal matrix (Jacobian columns of unit
        # norm): independent of the units of the shift, the gain and the offset
        scale = np.sqrt(np.einsum("mii->mi", normal))
        textured = finite & (scale > 0).all(axis=1)
        normal[~textured] = np.eye(4)
        scale[~textured] = 1.0
        with np.errstate(all="ignore"):
            textured &= np.linalg.cond(normal / scale[:, :, None] / scale[:, None, :]) \
                <= max_condition
        normal[~textured] = np.eye(4)
        rhs[~textured] = 0.0
        step = np.linalg.solve(normal, rhs[:, :, None])[:, :, 0]
        d[idx] += step[:, :2]
        gain[idx] += step[:, 2]
        offset[idx] += step[:, 3]
        dof = np.maximum(w.sum(axis=1) - 4.0, 1.0)
        s0 = (w * residual**2).sum(axis=1) / dof
        covariance[idx] = s0[:, None, None] * np.linalg.inv(normal)[:, :2, :2]
        covariance[idx[~textured]] = np.nan
        size = np.hypot(d[idx, 0], d[idx, 1]) if shift_norm == "euclidean" \
            else np.abs(d[idx]).max(axis=1)
        diverged = textured & (size > max_shift_px)
        converged = textured & ~diverged & (np.abs(step[:, :2]).max(axis=1) <= tolerance_px) \
            & (robust_k is None or iteration > 1)
        status[idx[~finite]] = LsmStatus.NO_DATA
        status[idx[finite & ~textured]] = LsmStatus.NO_TEXTURE
        status[idx[diverged]] = LsmStatus.DIVERGED
        status[idx[converged]] = LsmStatus.CONVERGED
        active[idx[~textured | diverged | converged]] = False
    return LsmSolution(d, gain, offset, covariance, iterations, status)
