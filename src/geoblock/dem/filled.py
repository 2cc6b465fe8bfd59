"""FilledDem: a DEM whose missing heights (voids, nodata, outside coverage) take one value.

The policy of GDAL's ``RPC_DEM_MISSING_VALUE``, as a DEM of its own so that every engine
(localisation, orthorectification, adjustment) gets the same heights.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from geoblock.dem.base import DemBase
from geoblock.dem.protocol import Bounds, DemSource

__all__ = ["FilledDem"]


class FilledDem(DemBase):
    """``dem`` where it has a height, ``h`` (metres above the ellipsoid) everywhere else.

    Parameters
    ----------
    dem : DemSource
    h : float
        Height used where ``dem`` has none, metres above the WGS84 ellipsoid.
    """

    def __init__(self, dem: DemSource, h: float) -> None:
        self._dem = dem
        self._h = float(h)
        if not math.isfinite(self._h):
            raise ValueError(f"FilledDem: the fill height must be finite, got {h!r}")

    @property
    def dem(self) -> DemSource:
        return self._dem

    @property
    def fill(self) -> float:
        return self._h

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        return (-180.0, -90.0, 180.0, 90.0)

    @property
    def resolution_m(self) -> float:
        return self._dem.resolution_m

    def _heights(self, lon: np.ndarray, lat: np.ndarray) -> np.ndarray:
        h = np.asarray(self._dem.height(lon, lat), dtype=np.float64)
        return np.where(np.isnan(h), self._h, h)

    def height_range(self, bounds: Bounds | None = None) -> tuple[float, float]:
        lo, hi = self._dem.height_range(bounds)
        lo = self._h if not math.isfinite(lo) else min(lo, self._h)
        hi = self._h if not math.isfinite(hi) else max(hi, self._h)
        return (lo, hi)

    def to_dict(self) -> dict[str, Any]:
        return {"dem": "filled", "fill": self._h, "source": self._dem.to_dict()}

    def __reduce__(self) -> tuple[Any, ...]:
        return (FilledDem, (self._dem, self._h))

    def __repr__(self) -> str:
        return f"FilledDem({self._dem!r}, {self._h:g} m where it has no height)"
