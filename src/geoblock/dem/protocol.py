"""The DemSource protocol: what the engines (localisation, ortho, adjustment) ask of a DEM."""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from geoblock.typing import ArrayLike, Float64Array

__all__ = ["Bounds", "DemSource"]

Bounds = tuple[float, float, float, float]
"""``(west, south, east, north)``, degrees (WGS84). A box across the antimeridian keeps
``west < east`` with one end beyond +-180 (e.g. ``(179.8, -0.1, 180.02, 0.1)``); a DEM source
takes the longitudes of a box modulo 360."""


@runtime_checkable
class DemSource(Protocol):
    """Terrain heights above the WGS84 ellipsoid, whatever the file's vertical datum.

    Coordinates are ``lon, lat`` degrees (WGS84); heights metres above the ellipsoid. Points
    without a height (outside the DEM, nodata, voids) are NaN with status ``NO_DEM``.
    """

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """``(west, south, east, north)`` of the coverage, degrees."""
        ...

    @property
    def resolution_m(self) -> float:
        """Approximate ground spacing of the DEM posts, metres (0 for a constant DEM)."""
        ...

    def height(self, lon: ArrayLike, lat: ArrayLike) -> Float64Array:
        """(*S,) ellipsoidal heights, metres; NaN where there is none."""
        ...

    def height_with_status(
        self, lon: ArrayLike, lat: ArrayLike
    ) -> tuple[Float64Array, NDArray[np.uint8]]:
        """:meth:`height` and the (*S,) :class:`~geoblock.typing.Status` (``NO_DEM``)."""
        ...

    def height_range(
        self, bounds: tuple[float, float, float, float] | None = None
    ) -> tuple[float, float]:
        """``(min, max)`` ellipsoidal height over ``(west, south, east, north)`` (default all)."""
        ...

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe state (a file DEM is stored by path, so it pickles cheaply to workers)."""
        ...
