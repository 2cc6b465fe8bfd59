"""GridDem: a DEM held in memory as an array with an affine geotransform in any CRS.

Used for synthetic terrain (tests, the simulator, benchmarks) and as the sampling engine that
file DEMs delegate to block by block.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol

import numpy as np
import pyproj
from affine import Affine

from geoblock import coords
from geoblock._affine import apply as affine_apply
from geoblock.dem.base import DemBase
from geoblock.dem.sampling import INTERPOLATIONS, sample
from geoblock.pixels import map_to_pixel, pixel_to_map

__all__ = ["GridDem", "Undulation", "lonlat_to_crs"]


class Undulation(Protocol):
    """A geoid model: ``N(lon, lat)``, metres of geoid above the ellipsoid."""

    def undulation(self, lon: np.ndarray, lat: np.ndarray) -> np.ndarray: ...


def _is_lonlat(crs: pyproj.CRS) -> bool:
    """Whether ``crs`` is geographic on WGS84 with lon/lat axes in degrees (as EPSG:4326)."""
    if not crs.is_geographic:
        return False
    geod = crs.geodetic_crs
    return geod is not None and geod.ellipsoid is not None and geod.ellipsoid.name == "WGS 84"


def lonlat_to_crs(
    crs: pyproj.CRS, lon: np.ndarray, lat: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """``(x, y)`` in ``crs`` (its horizontal part) of WGS84 ``lon, lat`` (always_xy order)."""
    horizontal = crs.sub_crs_list[0] if crs.is_compound else crs
    if _is_lonlat(horizontal):
        return lon, lat
    x, y = coords.transformer("EPSG:4326", horizontal).transform(lon, lat)
    return np.asarray(x, float), np.asarray(y, float)


def box_window(
    pixel_coords: Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]],
    shape: tuple[int, int],
    lonlat: bool,
    bounds: tuple[float, float, float, float],
) -> tuple[int, int, int, int] | None:
    """``(r0, r1, c0, c1)`` of a grid's posts whose interpolation kernels reach into a
    lon/lat box ``(west, south, east, north)``, or None when the box misses the grid.

    The box outline (21 points per edge) is mapped into the grid through ``pixel_coords``
    (``(lon, lat) -> (row, col)``), with a margin for the bicubic kernel's reach.
    """
    w, s, e, n = (float(v) for v in bounds)
    t = np.linspace(0.0, 1.0, 21)
    lon = np.concatenate([w + t * (e - w), np.full(21, e), e - t * (e - w), np.full(21, w)])
    lat = np.concatenate([np.full(21, s), s + t * (n - s), np.full(21, n), n - t * (n - s)])
    row, col = pixel_coords(lon, lat)
    rows, cols = shape
    if lonlat and e - w >= 360.0:
        col = np.array([-1.0, cols + 1.0])
    if not (np.isfinite(row).any() and np.isfinite(col).any()):
        return None
    r0 = max(int(np.floor(np.nanmin(row))) - 1, 0)
    r1 = min(int(np.floor(np.nanmax(row))) + 3, rows)
    c0 = max(int(np.floor(np.nanmin(col))) - 1, 0)
    c1 = min(int(np.floor(np.nanmax(col))) + 3, cols)
    if r0 >= r1 or c0 >= c1:
        return None
    return (r0, r1, c0, c1)


class GridDem(DemBase):
    """Heights on a regular grid in memory.

    Parameters
    ----------
    heights : array_like, (R, C)
        Heights in metres, NaN for nodata, above the ellipsoid or (with ``geoid``) above the
        geoid.
    transform : affine.Affine or sequence of 6
        GDAL-style geotransform of the array (pixel corner based, as rasterio's).
    crs : pyproj.CRS or str
        CRS of the grid (geographic or projected; a compound CRS's horizontal part is used).
    geoid : Undulation, optional
        When the heights are above a geoid: the geoid model whose undulation is added.
    interpolation : {"nearest", "bilinear", "bicubic"}
    """

    def __init__(
        self,
        heights: np.ndarray,
        transform: Affine | tuple[float, ...],
        crs: pyproj.CRS | str = "EPSG:4326",
        *,
        geoid: Undulation | None = None,
        interpolation: str = "bilinear",
    ) -> None:
        arr = np.array(heights, dtype=np.float64)
        if arr.ndim != 2 or min(arr.shape) < 1:
            raise ValueError(f"GridDem: heights must be a non-empty 2-D array, got {arr.shape}")
        arr.flags.writeable = False
        self._heights_array = arr
        self._transform = transform if isinstance(transform, Affine) else Affine(*transform[:6])
        if self._transform.is_degenerate:
            raise ValueError("GridDem: the geotransform is degenerate")
        self._crs = pyproj.CRS.from_user_input(crs)
        if interpolation not in INTERPOLATIONS:
            raise ValueError(f"GridDem: interpolation must be one of {INTERPOLATIONS}")
        self._interpolation = interpolation
        self._geoid = geoid

    # ------------------------------------------------------------------ properties
    @property
    def array(self) -> np.ndarray:
        """(R, C) the heights as given (read-only)."""
        return self._heights_array

    @property
    def transform(self) -> Affine:
        return self._transform

    @property
    def crs(self) -> pyproj.CRS:
        return self._crs

    @property
    def interpolation(self) -> str:
        return self._interpolation

    @property
    def geoid(self) -> Undulation | None:
        return self._geoid

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        rows, cols = self._heights_array.shape
        c = np.array([0, cols, cols, 0, cols / 2, 0, cols / 2, cols], float)
        r = np.array([0, 0, rows, rows, 0, rows / 2, rows, rows / 2], float)
        x, y = affine_apply(self._transform, *(c, r))
        horizontal = self._crs.sub_crs_list[0] if self._crs.is_compound else self._crs
        if _is_lonlat(horizontal):
            lon, lat = np.asarray(x), np.asarray(y)
        else:
            lon, lat = coords.transformer(horizontal, "EPSG:4326").transform(x, y)
        return (float(np.min(lon)), float(np.min(lat)), float(np.max(lon)), float(np.max(lat)))

    @property
    def resolution_m(self) -> float:
        a, b, _, d, e, _ = tuple(self._transform)[:6]
        size = float(np.sqrt(abs(a * e - b * d)))
        horizontal = self._crs.sub_crs_list[0] if self._crs.is_compound else self._crs
        if horizontal.is_geographic:
            return size * np.radians(1.0) * coords.WGS84_A
        return size

    # ------------------------------------------------------------------ sampling
    def pixel_coords(self, lon: np.ndarray, lat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pixel-centre ``(row, col)`` of WGS84 points in this grid."""
        x, y = lonlat_to_crs(self._crs, lon, lat)
        horizontal = self._crs.sub_crs_list[0] if self._crs.is_compound else self._crs
        if _is_lonlat(horizontal):
            # bring longitudes next to the grid (a grid on 0..360 or across the antimeridian)
            west = self._transform.c  # x of the grid's left edge (north-up grids)
            x = west + (np.asarray(x, float) - west) % 360.0
        return map_to_pixel(self._transform, x, y)

    def _heights(self, lon: np.ndarray, lat: np.ndarray) -> np.ndarray:
        row, col = self.pixel_coords(lon, lat)
        h = sample(self._heights_array, row, col, self._interpolation)
        if self._geoid is not None:
            h = h + self._geoid.undulation(lon, lat)
        return h

    def height_range(
        self, bounds: tuple[float, float, float, float] | None = None
    ) -> tuple[float, float]:
        """Min and max ellipsoidal height of the posts whose interpolation kernels reach into
        ``bounds`` (``(west, south, east, north)`` degrees; default all posts).

        Only the window of posts around the box is read (its outline is mapped into the
        grid), so a small box on a large grid costs little."""
        rows, cols = self._heights_array.shape
        horizontal = self._crs.sub_crs_list[0] if self._crs.is_compound else self._crs
        window = (0, rows, 0, cols) if bounds is None else box_window(
            self.pixel_coords, (rows, cols), _is_lonlat(horizontal), bounds)
        if window is None:
            return (float("nan"), float("nan"))
        r0, r1, c0, c1 = window
        h = self._heights_array[r0:r1, c0:c1]
        if self._geoid is not None:
            rr, cc = np.mgrid[r0:r1, c0:c1]
            x, y = pixel_to_map(self._transform, rr, cc)
            if _is_lonlat(horizontal):
                lon, lat = x, y
            else:
                lon, lat = coords.transformer(horizontal, "EPSG:4326").transform(x, y)
            h = h + self._geoid.undulation(np.asarray(lon), np.asarray(lat))
        if not np.isfinite(h).any():
            return (float("nan"), float("nan"))
        return (float(np.nanmin(h)), float(np.nanmax(h)))

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "dem": "grid",
            "heights": [[None if not np.isfinite(v) else float(v) for v in row]
                        for row in self._heights_array],
            "transform": list(tuple(self._transform)[:6]),
            "crs": self._crs.to_wkt(),
            "interpolation": self._interpolation,
        }
        if self._geoid is not None:
            out["geoid"] = getattr(self._geoid, "to_dict", lambda: repr(self._geoid))()
        return out

    def __reduce__(self) -> tuple[Any, ...]:
        return (_rebuild, (self._heights_array, tuple(self._transform)[:6], self._crs.to_wkt(),
                           self._geoid, self._interpolation))

    def __repr__(self) -> str:
        rows, cols = self._heights_array.shape
        datum = "geoid" if self._geoid is not None else "ellipsoid"
        return f"<GridDem {rows}x{cols} {self._crs.to_string()} heights above the {datum}>"


def _rebuild(heights: np.ndarray, transform: tuple[float, ...], crs: str,
             geoid: Undulation | None, interpolation: str) -> GridDem:
    return GridDem(heights, transform, crs, geoid=geoid, interpolation=interpolation)
