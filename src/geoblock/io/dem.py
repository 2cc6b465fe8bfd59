"""``open_dem``: every DEM source geoblock reads, as a :class:`~geoblock.dem.DemSource`."""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from geoblock.dem.filled import FilledDem
from geoblock.dem.base import DemBase
from geoblock.dem.constant import ConstantDem
from geoblock.dem.geoid import ConstantGeoidDem, Geoid, find_geoid
from geoblock.dem.raster import VERTICALS, MosaicDem, RasterDem
from geoblock.errors import DemError

__all__ = ["open_dem"]

PathLike = str | os.PathLike[str]


def open_dem(
    source: PathLike | Sequence[PathLike] | Mapping[str, Any] | DemBase,
    *,
    vertical: str | None = None,
    geoid: Geoid | PathLike | None = None,
    nodata: str | float = "nan",
    interpolation: str = "bilinear",
    strict: bool = False,
    missing: float | None = None,
) -> DemBase:
    """Open a DEM; its heights come out above the WGS84 ellipsoid.

    Parameters
    ----------
    source : str, os.PathLike, sequence of them, dict or DemSource
        * a raster file rasterio opens: GeoTIFF, SRTM ``.hgt``, VRT, ... in any CRS;
        * a list of such files (tiles, each in any CRS): a mosaic where each point takes the
          first tile, in the order given, that has a height;
        * ``"const:H"``: ``H`` metres everywhere, above the ellipsoid (or above the geoid
          with ``vertical="geoid"``);
        * the ``to_dict()`` of a DEM opened before (how dask workers re-open it);
        * a DEM object, returned as it is.
    vertical : {"geoid", "ellipsoid"} or None
        Vertical datum of the file's heights. ``None`` (default): as the file states it - a
        compound CRS with an EGM96 vertical part, a 3-D geographic CRS (ellipsoidal), or an
        SRTM ``.hgt`` tile (EGM96 by the SRTM specification). A file that states nothing is
        refused with a :class:`~geoblock.errors.DemError` saying to pass ``vertical=``. An
        explicit value overrides the file.
    geoid : Geoid, str or os.PathLike, optional
        The geoid grid (``.gtx``) for geoid heights; default ``GEOBLOCK_GEOID``, then
        ``egm96_15.gtx`` from pyproj's and the standard PROJ data directories
        (``apt-get install proj-data`` puts it in ``/usr/share/proj``).
    nodata : "nan", "fill", "nearest" or float
        Nodata pixels and voids: ``"nan"`` (NaN and status ``NO_DEM``), ``"fill"`` /
        ``"nearest"`` (filled from neighbours by ``rasterio.fill.fillnodata``) or a fill
        value in the file's own datum, metres.
    interpolation : {"bilinear", "nearest", "bicubic"}
        Sampling at pixel centres (GDAL-identical nearest and bilinear).
    strict : bool
        Raise :class:`~geoblock.errors.DemCoverageError` when points fall outside the DEM
        instead of returning NaN with status ``NO_DEM``.
    missing : float, optional
        A height, metres above the ellipsoid, for every point where the DEM has none (voids
        left by ``nodata``, and outside its coverage): GDAL's ``RPC_DEM_MISSING_VALUE``. The
        result is a :class:`~geoblock.dem.FilledDem`.

    Returns
    -------
    DemSource
        :class:`~geoblock.dem.RasterDem`, :class:`~geoblock.dem.MosaicDem`,
        :class:`~geoblock.dem.ConstantDem` or :class:`~geoblock.dem.ConstantGeoidDem`.

    Raises
    ------
    DemError
        Unreadable file, unknown option, unstated vertical datum, geoid grid not found.

    Examples
    --------
    >>> dem = open_dem("const:100")
    >>> float(dem.height(5.0, 44.0))
    100.0
    """
    if missing is not None:
        inner = open_dem(source, vertical=vertical, geoid=geoid, nodata=nodata,
                         interpolation=interpolation, strict=strict)
        try:
            return FilledDem(inner, missing)
        except ValueError as exc:
            raise DemError(f"open_dem: missing={missing!r}: {exc}") from None
    if vertical is not None and vertical not in VERTICALS:
        raise DemError(f"open_dem: vertical must be 'geoid', 'ellipsoid' or None, got {vertical!r}")
    if isinstance(source, DemBase):
        return source
    if isinstance(source, Mapping):
        return _from_dict(source)
    options = dict(vertical=vertical, geoid=geoid, nodata=nodata, interpolation=interpolation,
                   strict=strict)
    if isinstance(source, str | os.PathLike):
        text = os.fspath(source)
        if text.startswith("const:"):
            return _constant(text, vertical, geoid)
        return RasterDem(_existing(text), **options)
    if isinstance(source, Sequence) and not isinstance(source, bytes):
        paths = list(source)
        if not paths:
            raise DemError("open_dem: the list of DEM tiles is empty")
        if len(paths) == 1:
            return open_dem(paths[0], **options)
        options.pop("strict")
        tiles = [RasterDem(_existing(os.fspath(p)), **options) for p in paths]
        return MosaicDem(tiles, strict=strict)
    raise DemError(f"open_dem: cannot open a DEM from {type(source).__name__} {source!r}")


def _existing(path: str) -> str:
    if path.startswith(("/vsi", "http://", "https://")) or Path(path).exists():
        return path
    raise DemError(f"DEM file not found: {path}")


def _constant(text: str, vertical: str | None, geoid: Any) -> DemBase:
    try:
        h = float(text[len("const:"):])
    except ValueError:
        raise DemError(f"open_dem: {text!r} is not 'const:H' with H a height in metres") from None
    if vertical == "geoid":
        return ConstantGeoidDem(h, find_geoid(geoid))
    try:
        return ConstantDem(h)
    except ValueError as exc:
        raise DemError(f"open_dem: {text!r}: {exc}") from None


def _from_dict(data: Mapping[str, Any]) -> DemBase:
    kind = data.get("dem")
    try:
        if kind == "raster":
            return RasterDem.from_dict(dict(data))
        if kind == "mosaic":
            return MosaicDem.from_dict(dict(data))
        if kind == "filled":
            return FilledDem(_from_dict(data["source"]), float(data["fill"]))
        if kind == "constant":
            if data.get("vertical") == "geoid":
                return ConstantGeoidDem(float(data["h"]), find_geoid(data.get("geoid")))
            return ConstantDem(float(data["h"]))
        if kind == "grid":
            import numpy as np

            from geoblock.dem.grid import GridDem

            heights = np.array([[np.nan if v is None else v for v in row]
                                for row in data["heights"]], float)
            geoid = data.get("geoid")
            return GridDem(heights, data["transform"], data["crs"],
                           geoid=find_geoid(geoid["path"]) if isinstance(geoid, Mapping) else None,
                           interpolation=data.get("interpolation", "bilinear"))
    except KeyError as exc:
        raise DemError(f"open_dem: DEM dictionary of kind {kind!r} lacks the field {exc}") from None
    raise DemError(f"open_dem: unknown DEM dictionary kind {kind!r} (field 'dem')")
