"""Georeferenced lazy rasters: the coordinates of a ``(band, y, x)`` DataArray on an output
grid, its grid, nodata and valid pixels (shared by the orthorectifier, the mosaic and the
accuracy layer)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from geoblock.errors import MosaicError
from geoblock.pixels import pixel_centres

if TYPE_CHECKING:
    import dask.array as da
    import xarray as xr

    from geoblock.ortho.grid import OutputGrid


def _coords(grid: OutputGrid, bands: int, fill: Any) -> dict[str, Any]:
    import xarray as xr

    t = grid.transform
    x, y = pixel_centres(t, grid.shape)
    wkt = grid.crs.to_wkt() if hasattr(grid.crs, "to_wkt") else str(grid.crs)
    gt = " ".join(repr(float(v)) for v in (t.c, t.a, t.b, t.f, t.d, t.e))
    spatial_ref = xr.DataArray(0, attrs={"crs_wkt": wkt, "spatial_ref": wkt, "GeoTransform": gt})
    return {"band": np.arange(1, bands + 1), "y": y, "x": x, "spatial_ref": spatial_ref}


def _grid_of(data: xr.DataArray, index: int) -> OutputGrid:
    """The :class:`OutputGrid` of a ``(band, y, x)`` DataArray, from its ``spatial_ref``."""
    import pyproj
    from affine import Affine

    from geoblock.ortho.grid import OutputGrid

    if tuple(data.dims) != ("band", "y", "x"):
        raise MosaicError(f"mosaic: source {index + 1} must have dims ('band', 'y', 'x'), "
                          f"got {tuple(data.dims)}")
    ref = data.coords.get("spatial_ref")
    wkt = gt = None
    if ref is not None:
        wkt = ref.attrs.get("crs_wkt") or ref.attrs.get("spatial_ref")
        gt = ref.attrs.get("GeoTransform")
    if not wkt or gt is None:
        raise MosaicError(f"mosaic: source {index + 1} is not georeferenced (no spatial_ref "
                          "coordinate with crs_wkt and GeoTransform)")
    c, a, b, f, d, e = (float(v) for v in str(gt).split())
    try:
        return OutputGrid(pyproj.CRS.from_wkt(wkt), Affine(a, b, c, d, e, f),
                          (int(data.sizes["y"]), int(data.sizes["x"])))
    except ValueError as exc:
        raise MosaicError(f"mosaic: source {index + 1}: {exc}") from exc


def _fill_of(data: xr.DataArray) -> float | None:
    fill = data.attrs.get("_FillValue", data.encoding.get("_FillValue"))
    if fill is None and np.dtype(data.dtype).kind == "f":
        return float("nan")
    return None if fill is None else float(fill)


def _valid(array: da.Array, fill: float | None) -> da.Array:
    """``(y, x)`` bool dask array: no band is ``fill`` or NaN."""
    import dask.array as da

    bad = da.zeros(array.shape[1:], dtype=bool, chunks=array.chunks[1:])
    if np.dtype(array.dtype).kind == "f":
        bad = bad | da.isnan(array).any(axis=0)
    if fill is not None and not math.isnan(fill):
        bad = bad | (array == fill).any(axis=0)
    return ~bad
