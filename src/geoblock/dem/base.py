"""DemBase: shared behaviour of the DEM sources (status handling, value semantics)."""

from __future__ import annotations

import abc
import json
from typing import Any

import numpy as np

from geoblock._array import all_finite, broadcast_float64
from geoblock.typing import ArrayLike, Float64Array, Status

__all__ = ["DemBase"]


class DemBase(abc.ABC):
    """Implementers provide ``_heights(lon, lat)`` on flat finite arrays (NaN = no height),
    ``bounds``, ``resolution_m``, ``height_range`` and ``to_dict``."""

    @abc.abstractmethod
    def _heights(self, lon: np.ndarray, lat: np.ndarray) -> np.ndarray:
        """Ellipsoidal heights (N,) at flat finite points; NaN where there is none."""

    @property
    @abc.abstractmethod
    def bounds(self) -> tuple[float, float, float, float]: ...

    @property
    @abc.abstractmethod
    def resolution_m(self) -> float: ...

    @abc.abstractmethod
    def height_range(
        self, bounds: tuple[float, float, float, float] | None = None
    ) -> tuple[float, float]: ...

    @abc.abstractmethod
    def to_dict(self) -> dict[str, Any]: ...

    def height_with_status(self, lon: ArrayLike, lat: ArrayLike) -> tuple[Float64Array, np.ndarray]:
        """(*S,) ellipsoidal heights (metres) and statuses: ``NO_DEM`` where NaN,
        ``INVALID_INPUT`` for non-finite coordinates."""
        lon, lat = broadcast_float64(lon=lon, lat=lat, _copy=False)  # only read here
        ok = np.isfinite(lon) & np.isfinite(lat)
        if ok.all():  # the common case, without the gather/scatter copies
            h = np.asarray(self._heights(lon.reshape(-1), lat.reshape(-1))).reshape(lon.shape)
            found = np.isfinite(h)
            status = np.where(found, np.uint8(Status.CONVERGED), np.uint8(Status.NO_DEM))
            return h, status.astype(np.uint8, copy=False)
        h = np.full(lon.shape, np.nan)
        status = np.full(lon.shape, np.uint8(Status.INVALID_INPUT), dtype=np.uint8)
        if ok.any():
            h[ok] = self._heights(lon[ok], lat[ok])
            status[ok] = np.where(np.isfinite(h[ok]), Status.CONVERGED, Status.NO_DEM)
        return h, status

    def height(self, lon: ArrayLike, lat: ArrayLike) -> Float64Array:
        """(*S,) ellipsoidal heights, metres; NaN where the DEM has none (see
        :meth:`height_with_status` for why).

        The engines' path (the orthorectifier samples every output pixel): with finite
        coordinates, no status array is made; the heights are those of
        :meth:`height_with_status`, bit for bit."""
        lon, lat = broadcast_float64(lon=lon, lat=lat, _copy=False)  # only read here
        if all_finite(lon, lat):
            return np.asarray(self._heights(lon.reshape(-1), lat.reshape(-1))).reshape(lon.shape)
        return self.height_with_status(lon, lat)[0]

    def __eq__(self, other: object) -> bool:
        if type(other) is not type(self):
            return NotImplemented
        mine = json.dumps(self.to_dict(), sort_keys=True)
        theirs = json.dumps(other.to_dict(), sort_keys=True)
        return mine == theirs

    def __hash__(self) -> int:
        return hash(json.dumps(self.to_dict(), sort_keys=True))

    def __dask_tokenize__(self) -> tuple[str, str]:
        return (type(self).__name__, json.dumps(self.to_dict(), sort_keys=True))
