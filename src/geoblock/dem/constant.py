"""ConstantDem: one height everywhere (``const:H``)."""

from __future__ import annotations

from typing import Any

import numpy as np

from geoblock.dem.base import DemBase
from geoblock.dem.protocol import Bounds

__all__ = ["ConstantDem"]


class ConstantDem(DemBase):
    """The same ellipsoidal height everywhere.

    Parameters
    ----------
    h : float
        Metres above the WGS84 ellipsoid. (A constant height above the geoid is not constant
        above the ellipsoid: give ``geoid=`` and ``vertical="geoid"`` to
        :func:`geoblock.open_dem` for that.)
    """

    def __init__(self, h: float) -> None:
        self._h = float(h)
        if not np.isfinite(self._h):
            raise ValueError(f"ConstantDem: height must be finite, got {h!r}")

    @property
    def h(self) -> float:
        """The height, metres above the ellipsoid."""
        return self._h

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        return (-180.0, -90.0, 180.0, 90.0)

    @property
    def resolution_m(self) -> float:
        return 0.0

    def _heights(self, lon: np.ndarray, lat: np.ndarray) -> np.ndarray:
        return np.full(lon.shape, self._h)

    def height_range(self, bounds: Bounds | None = None) -> tuple[float, float]:
        return (self._h, self._h)

    def to_dict(self) -> dict[str, Any]:
        return {"dem": "constant", "h": self._h}

    def __reduce__(self) -> tuple[Any, ...]:
        return (ConstantDem, (self._h,))

    def __repr__(self) -> str:
        return f"ConstantDem({self._h:g} m above the ellipsoid)"
