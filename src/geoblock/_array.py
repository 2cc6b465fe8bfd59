"""Private helpers shared by every vectorised function: argument broadcasting and status warnings."""

from __future__ import annotations

import warnings

import numpy as np

from geoblock.errors import (
    ConvergenceWarning,
    NoIntersectionWarning,
    OutOfBoundsWarning,
    ShapeMismatchError,
)
from geoblock.typing import Status

_WARNINGS = {
    Status.MAX_ITERATIONS: (ConvergenceWarning, "reached the iteration cap"),
    Status.DIVERGED: (ConvergenceWarning, "diverged"),
    Status.OUT_OF_DOMAIN: (OutOfBoundsWarning, "lie outside the model's validity domain"),
    Status.NO_DEM: (NoIntersectionWarning, "have no DEM height"),
    Status.NO_INTERSECTION: (NoIntersectionWarning, "have no line-of-sight/DEM intersection"),
}


def broadcast_float64(**arrays) -> tuple[np.ndarray, ...]:
    """Broadcast named coordinate arguments together as float64 arrays.

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
    # broadcast_arrays returns read-only views; copy so callers may write into results.
    return tuple(np.array(a, dtype=np.float64) for a in out)


def warn_status(status: np.ndarray, operation: str, stacklevel: int = 3) -> None:
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
