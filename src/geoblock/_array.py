"""Private helpers shared by every vectorised function: argument broadcasting, status
warnings, the finite bounding box of coordinate arrays.

The two kernels are :func:`~geoblock._jit.lazy_njit`: importing this module (every model
does) imports neither numba nor its registries."""

from __future__ import annotations

import math
import warnings

import numpy as np
from numpy.typing import NDArray

from geoblock._jit import lazy_njit
from geoblock.errors import (
    ConvergenceWarning,
    NoIntersectionWarning,
    OutOfBoundsWarning,
    ShapeMismatchError,
)
from geoblock.typing import ArrayLike, Float64Array, Status

_WARNINGS = {
    Status.MAX_ITERATIONS: (ConvergenceWarning, "reached the iteration cap"),
    Status.DIVERGED: (ConvergenceWarning, "diverged"),
    Status.OUT_OF_DOMAIN: (OutOfBoundsWarning, "lie outside the model's validity domain"),
    Status.NO_DEM: (NoIntersectionWarning, "have no DEM height"),
    Status.NO_INTERSECTION: (NoIntersectionWarning, "have no line-of-sight/DEM intersection"),
}


def broadcast_float64(*, _copy: bool = True, **arrays: ArrayLike) -> tuple[Float64Array, ...]:
    """Broadcast named coordinate arguments together as float64 arrays.

    The results are writable copies, unless ``_copy=False``: then read-only views (no copy
    when the arguments are float64 arrays of one shape), for callers that only read them.

    Raises
    ------
    ShapeMismatchError
        Naming every argument and its shape when they do not broadcast.
    TypeError
        When an argument is not numeric.
    """
    try:
        converted = [np.asarray(v, dtype=np.float64) for v in arrays.values()]
    except (TypeError, ValueError) as exc:
        raise ShapeMismatchError(
            f"coordinates {', '.join(arrays)} must be numeric arrays: {exc}"
        ) from exc
    try:
        out = np.broadcast_arrays(*converted)
    except ValueError:
        shapes = ", ".join(f"{k} {np.shape(v)}" for k, v in zip(arrays, converted, strict=True))
        raise ShapeMismatchError(f"coordinate shapes do not broadcast together: {shapes}") from None
    if not _copy:
        return tuple(out)
    # broadcast_arrays returns read-only views; copy so callers may write into results.
    return tuple(np.array(a, dtype=np.float64) for a in out)


def warn_status(status: NDArray[np.uint8], operation: str, stacklevel: int = 3) -> None:
    """Emit one warning per failure category present in ``status``, with the count.

    Non-finite inputs (``INVALID_INPUT``) give NaN silently: NaN in, NaN out.
    """
    if status.size == 0:
        return
    counts = np.bincount(status.ravel(), minlength=len(Status))
    for code, (category, text) in _WARNINGS.items():
        n = int(counts[code])
        if n:
            warnings.warn(
                f"{operation}: {n} of {status.size} points {text} ({code.name}); they are NaN",
                category,
                stacklevel=stacklevel,
            )


@lazy_njit(nogil=True, cache=True)
def _nb_all_finite(x: Float64Array, y: Float64Array) -> bool:  # pragma: no cover - compiled
    for k in range(x.size):
        if not (math.isfinite(x[k]) and math.isfinite(y[k])):
            return False
    return True


def all_finite(x: Float64Array, y: Float64Array) -> bool:
    """Whether every value of two same-shape float64 arrays is finite (one compiled pass, no
    temporaries; stops at the first non-finite value).

    Examples
    --------
    >>> all_finite(np.array([1.0, 2.0]), np.array([3.0, np.inf]))
    False
    """
    return bool(_nb_all_finite(np.ascontiguousarray(x, dtype=np.float64).reshape(-1),
                               np.ascontiguousarray(y, dtype=np.float64).reshape(-1)))


@lazy_njit(nogil=True, cache=True)
def _nb_finite_bounds(  # pragma: no cover - compiled
    x: Float64Array, y: Float64Array
) -> tuple[float, float, float, float]:
    x_lo = math.inf
    x_hi = -math.inf
    y_lo = math.inf
    y_hi = -math.inf
    for k in range(x.size):
        a = x[k]
        b = y[k]
        if a < x_lo:
            x_lo = a
        if a > x_hi:
            x_hi = a
        if b < y_lo:
            y_lo = b
        if b > y_hi:
            y_hi = b
    return x_lo, x_hi, y_lo, y_hi


def finite_bounds(x: ArrayLike, y: ArrayLike) -> tuple[float, float, float, float]:
    """``(x_min, x_max, y_min, y_max)`` of two same-shape float arrays in one compiled pass,
    ignoring NaN (as ``np.fmin``/``np.fmax`` reductions do); NaN for an all-NaN array.

    Examples
    --------
    >>> finite_bounds(np.array([1.0, np.nan, -2.0]), np.array([np.nan, 5.0, 4.0]))
    (-2.0, 1.0, 4.0, 5.0)
    """
    xs = np.ascontiguousarray(x, dtype=np.float64).reshape(-1)
    ys = np.ascontiguousarray(y, dtype=np.float64).reshape(-1)
    x_lo, x_hi, y_lo, y_hi = _nb_finite_bounds(xs, ys)
    out = []
    for lo, hi in ((x_lo, x_hi), (y_lo, y_hi)):
        if lo > hi:  # no finite value (NaN never compares)
            lo = hi = math.nan
        out += [float(lo), float(hi)]
    return out[0], out[1], out[2], out[3]
