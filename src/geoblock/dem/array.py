"""In-memory DEMs: a height grid sampled exactly as :class:`~geoblock.dem.raster.RasterDem`
samples a file holding the same pixels (same blocks, kernels, nodata policies, vertical datum).
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from affine import Affine

from geoblock.dem.geoid import Geoid
from geoblock.dem.raster import RasterDem, _crs_of
from geoblock.errors import DemError

__all__ = ["ArrayDem", "tile_from_dict"]

class ArrayDem(RasterDem):
    """A height grid in memory, sampled exactly as :class:`RasterDem` samples a file.

    The same blocks, kernels, edge extension, nodata policies and vertical datum rules as a
    ``RasterDem`` of a file holding the same pixels, so the heights are identical to that
    file's. Users normally call ``geoblock.open_dem(array, transform=..., crs=...)``, or
    ``open_dem`` with an ``xarray.DataArray`` or an in-memory rasterio dataset.

    Parameters
    ----------
    heights : array_like, (R, C) or (1, R, C)
        The posts as stored, any real numeric dtype (kept as a read-only view, not copied).
    transform : affine.Affine or sequence of 6
        GDAL geotransform of the array (pixel corners), rasterio order.
    crs : pyproj.CRS, rasterio CRS, str or int
        CRS of the grid; a compound CRS may state the vertical datum (as a file's does).
    nodata_value : float, optional
        The value marking posts without a height (NaN always does).
    scale, offset : float
        Heights are ``stored * scale + offset`` (a file's band scale and offset).
    driver : str
        The GDAL driver the pixels come from (``"SRTMHGT"`` states EGM96 heights); default
        ``"MEM"``.
    name : str, optional
        What to call the DEM in messages.
    vertical, geoid, nodata, interpolation, strict, fill_distance
        As :class:`RasterDem`.

    Raises
    ------
    DemError
        Not a 2-D numeric array, no or degenerate geotransform, no or unreadable CRS, an
        invalid option, or a vertical datum stated neither by the CRS nor by ``vertical=``.
    """

    def __init__(
        self,
        heights: Any,
        transform: Affine | Sequence[float],
        crs: Any,
        *,
        nodata_value: float | None = None,
        scale: float = 1.0,
        offset: float = 0.0,
        driver: str = "MEM",
        name: str | None = None,
        vertical: str | None = None,
        geoid: Geoid | str | os.PathLike[str] | None = None,
        nodata: str | float = "nan",
        interpolation: str = "bilinear",
        strict: bool = False,
        fill_distance: int = 100,
    ) -> None:
        arr = np.asarray(heights)
        if arr.ndim == 3 and arr.shape[0] == 1:
            arr = arr[0]
        if arr.ndim != 2 or min(arr.shape) < 1 or arr.dtype.kind not in "iuf":
            raise DemError(f"{name or 'in-memory DEM'}: heights must be a non-empty 2-D array "
                           f"of numbers, got shape {np.shape(heights)} and dtype {arr.dtype}")
        # an own read-only copy: a caller changing its array afterwards must not change
        # heights behind the block cache and the digest
        own = np.array(arr, copy=arr.flags.writeable)
        own.flags.writeable = False
        self._array = own
        rows, cols = arr.shape
        self._path = name or f"<in-memory {rows} x {cols} DEM>"
        self._set_options(vertical, nodata, interpolation, strict, 1, fill_distance)
        if transform is None:
            raise DemError(f"DEM {self._path}: a geotransform is needed (transform=)")
        t = transform if isinstance(transform, Affine) else Affine(*tuple(transform)[:6])
        if t.b != 0.0 or t.d != 0.0 or t.a == 0.0 or t.e == 0.0:
            raise DemError(
                f"DEM {self._path}: the geotransform {tuple(t)[:6]} is rotated or degenerate; "
                "an in-memory DEM needs a north-up transform in rasterio order (a, b, c, d, "
                "e, f) = (x step, 0, x of the corner, 0, y step, y of the corner); GDAL's "
                "GetGeoTransform() order is (c, a, b, f, d, e): use Affine.from_gdal(*gt)")
        self._set_raster(driver=driver, shape=(rows, cols), transform=t,
                         crs=_crs_of(crs, self._path), file_nodata=nodata_value,
                         dtype=arr.dtype, scale=scale, offset=offset, tags={})
        self._digest = _digest(arr)
        self._finish(vertical, geoid, ("array", self._digest, tuple(t)[:6],
                                       self._file_nodata, self._scale, self._offset))

    @property
    def path(self) -> str:
        """The DEM's name (an in-memory DEM has no file)."""
        return self._path

    @property
    def array(self) -> np.ndarray:
        """(R, C) the posts as given (read-only)."""
        return self._array

    def _read_raw(self, r0: int, r1: int, c0: int, c1: int) -> np.ndarray:
        return self._array[r0:r1, c0:c1]

    def _state(self) -> dict[str, Any]:
        """Everything but the posts (JSON-safe)."""
        return {
            "dem": "array",
            "name": self._path,
            "transform": [float(v) for v in tuple(self._transform)[:6]],
            "crs": self._crs.to_wkt(),
            "nodata_value": self._file_nodata,
            "scale": self._scale,
            "offset": self._offset,
            "driver": self._driver,
            "vertical": self._vertical,
            "geoid": None if self._geoid is None else self._geoid.path,
            "nodata": self._nodata_policy,
            "interpolation": self._interpolation,
            "strict": self._strict,
            "fill_distance": self._fill_distance,
        }

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe, with the posts (``heights``, rows of numbers, None for NaN, and their
        ``dtype``): large; pickling and dask tokens do not go through it."""
        out = self._state()
        out["dtype"] = self._array.dtype.str
        out["heights"] = [[None if v != v else v for v in row] for row in self._array.tolist()]
        return out

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> ArrayDem:
        """The DEM of :meth:`to_dict`."""
        heights = np.array([[np.nan if v is None else v for v in row] for row in data["heights"]],
                           dtype=np.dtype(data.get("dtype", "<f8")))
        opts = {k: v for k, v in data.items()
                if k not in ("dem", "heights", "dtype", "transform", "crs")}
        return cls(heights, data["transform"], data["crs"], **opts)

    def _identity(self) -> str:
        return json.dumps({**self._state(), "digest": self._digest}, sort_keys=True)

    def __eq__(self, other: object) -> bool:
        if type(other) is not type(self):
            return NotImplemented
        return self._identity() == other._identity()

    def __hash__(self) -> int:
        return hash(self._identity())

    def __dask_tokenize__(self) -> tuple[str, str]:
        return (type(self).__name__, self._identity())

    def __reduce__(self) -> tuple[Any, ...]:
        state = self._state()
        return (_rebuild_array_dem, (self._array, state))

    def __repr__(self) -> str:
        rows, cols = self._shape
        return (f"<ArrayDem {self._path} {rows}x{cols} {self._crs.name!r} heights above the "
                f"{self._vertical}, {self._interpolation}>")


def _rebuild_array_dem(heights: np.ndarray, state: dict[str, Any]) -> ArrayDem:
    opts = {k: v for k, v in state.items() if k not in ("dem", "transform", "crs")}
    return ArrayDem(heights, state["transform"], state["crs"], **opts)


def _digest(array: np.ndarray) -> str:
    """A hash of an array's values, dtype and shape (the block cache's key for its pixels)."""
    h = hashlib.blake2b(digest_size=16)
    h.update(f"{array.dtype.str}{array.shape}".encode())
    h.update(np.ascontiguousarray(array).data)
    return h.hexdigest()


def tile_from_dict(data: Mapping[str, Any]) -> RasterDem:
    """A :class:`RasterDem` or :class:`ArrayDem` from its ``to_dict()``."""
    if data.get("dem") == "array":
        return ArrayDem.from_dict(data)
    return RasterDem.from_dict(dict(data))

