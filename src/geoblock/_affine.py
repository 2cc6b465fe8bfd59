"""Applying affine geotransforms to coordinate arrays (no reliance on ``Affine.__mul__``,
which affine 3 deprecates for points)."""

from __future__ import annotations

import numpy as np
from affine import Affine

from geoblock.typing import ArrayLike

__all__ = ["apply"]


def apply(transform: Affine, x: ArrayLike, y: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """``transform`` applied to points: ``(a x + b y + c, d x + e y + f)``, float64 arrays."""
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    a, b, c, d, e, f = tuple(transform)[:6]
    return a * x + b * y + c, d * x + e * y + f
