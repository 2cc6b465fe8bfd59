"""MosaicDem: several raster DEMs (tiles, in any CRSs) as one DEM.

Each point takes the first tile, in the order given, that has a height there; a tile meets a
box with longitudes compared modulo 360, so tiles stored either side of the antimeridian, in
either convention, serve a scene that crosses it.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from affine import Affine

from geoblock.dem.array import tile_from_dict
from geoblock.dem.base import DemBase
from geoblock.dem.protocol import Bounds
from geoblock.dem.raster import RasterDem, _fmt_bounds, _heights_on_grid
from geoblock.errors import DemCoverageError, DemError

__all__ = ["MosaicDem"]


class MosaicDem(DemBase):
    """Several raster DEMs (tiles, in any CRSs) as one: each point takes the first tile, in
    the order given, that has a height there.

    Parameters
    ----------
    tiles : sequence of RasterDem
    strict : bool
        Raise :class:`~geoblock.errors.DemCoverageError` for points outside every tile.
    """

    def __init__(self, tiles: Sequence[RasterDem], *, strict: bool = False) -> None:
        if not tiles:
            raise DemError("a DEM mosaic needs at least one tile")
        self._tiles = tuple(tiles)
        self._strict = bool(strict)

    @property
    def tiles(self) -> tuple[RasterDem, ...]:
        return self._tiles

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        b = np.array([t.bounds for t in self._tiles])
        return (float(b[:, 0].min()), float(b[:, 1].min()), float(b[:, 2].max()),
                float(b[:, 3].max()))

    @property
    def resolution_m(self) -> float:
        return min(t.resolution_m for t in self._tiles)

    def _heights(self, lon: np.ndarray, lat: np.ndarray) -> np.ndarray:
        out = np.full(lon.shape, np.nan)
        outside = np.ones(lon.shape, bool)
        todo = np.arange(lon.size)
        for tile in self._tiles:
            if todo.size == 0:
                break
            h, out_tile = tile._sample(lon[todo], lat[todo])
            outside[todo[~out_tile]] = False
            out[todo] = h
            todo = todo[~np.isfinite(h)]
        if self._strict and outside.any():
            raise DemCoverageError(
                f"{int(outside.sum())} of {outside.size} points fall outside every tile of the "
                f"DEM mosaic ({len(self._tiles)} tiles, bounds {_fmt_bounds(self.bounds)}); "
                "strict=True"
            )
        return out

    def height_range(self, bounds: Bounds | None = None) -> tuple[float, float]:
        """``(min, max)`` ellipsoidal height over the tiles meeting ``bounds``, metres."""
        ranges = []
        for t in self._tiles:
            if bounds is not None and not _overlap(t.bounds, bounds):
                continue
            lo, hi = t.height_range(bounds)
            if np.isfinite(lo):
                ranges.append((lo, hi))
        if not ranges:
            return (float("nan"), float("nan"))
        return (min(r[0] for r in ranges), max(r[1] for r in ranges))

    def heights_on_grid(self, crs: Any, transform: Affine | Sequence[float],
                        shape: tuple[int, int]) -> np.ndarray:
        """As :meth:`RasterDem.heights_on_grid`."""
        return _heights_on_grid(self, crs, transform, shape)

    def to_dict(self) -> dict[str, Any]:
        return {"dem": "mosaic", "tiles": [t.to_dict() for t in self._tiles],
                "strict": self._strict}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> MosaicDem:
        return cls([tile_from_dict(t) for t in data["tiles"]],
                   strict=data.get("strict", False))

    def __reduce__(self) -> tuple[Any, ...]:
        return (_rebuild_mosaic, (self._tiles, self._strict))  # each tile pickles itself

    def __repr__(self) -> str:
        return f"<MosaicDem of {len(self._tiles)} tiles>"


def _rebuild_mosaic(tiles: Sequence[RasterDem], strict: bool) -> MosaicDem:
    return MosaicDem(tiles, strict=strict)


def _overlap(a: Bounds, b: Bounds) -> bool:
    """Whether two ``(west, south, east, north)`` degree boxes meet, longitudes modulo 360
    (a tile stored as 180..181 meets a box from -179.9 to -179.5, a box 179.8..180.02 meets
    a tile from -180 to -179)."""
    if a[3] < b[1] or b[3] < a[1]:
        return False
    return any(not (a[2] < b[0] + k or b[2] + k < a[0]) for k in (-720.0, -360.0, 0.0,
                                                                   360.0, 720.0))
