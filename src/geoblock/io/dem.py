"""``open_dem``: every DEM source geoblock reads, as a :class:`~geoblock.dem.DemSource`;
``write_dem``: a height grid written as a GeoTIFF that states its vertical datum.

This module sits above :mod:`geoblock.dem` (it builds its DEM classes) and imports it inside
the functions: :mod:`geoblock.dem` reads its files through :mod:`geoblock.io.rasters`, and
``import geoblock.io`` must not need a half-imported ``geoblock.dem``.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeAlias

import numpy as np

from geoblock.errors import DemError, InputTypeError
from geoblock.io._atomic import atomic_path
from geoblock.io.rasters import (
    dataarray_georeferencing,
    dataarray_grid,
    dataarray_scale_offset,
    is_dataarray,
    is_dataset,
    type_name,
)

if TYPE_CHECKING:
    import xarray as xr
    from rasterio.io import DatasetReader

    from geoblock.dem.geoid import Geoid
    from geoblock.dem.protocol import DemSource
    from geoblock.dem.raster import RasterDem

__all__ = ["DemLike", "EngineDem", "as_dem", "open_dem", "vertical_crs", "write_dem"]

PathLike = str | os.PathLike[str]

if TYPE_CHECKING:
    DemLike: TypeAlias = (PathLike | Sequence[PathLike] | Mapping[str, Any] | DemSource
                          | DatasetReader | xr.DataArray | np.ndarray)
    EngineDem: TypeAlias = DemLike | float
else:
    DemLike = EngineDem = Any
"""``DemLike``: what :func:`open_dem` accepts as a DEM; ``EngineDem``: what the engines
(:func:`geoblock.localize`, :func:`geoblock.orthorectify`, :func:`geoblock.ortho.mosaic`,
``OutputGrid.for_model``) accept: the same, or a number (a constant height above the
ellipsoid), through :func:`as_dem`."""

_ACCEPTED = ("a path (str or os.PathLike) or a list of them, 'const:H', a DemSource or its "
             "to_dict(), an open rasterio dataset, a georeferenced xarray.DataArray, or a numpy "
             "array with transform= and crs=")


def open_dem(
    source: DemLike,
    *,
    vertical: str | None = None,
    geoid: Geoid | PathLike | None = None,
    nodata: str | float = "nan",
    interpolation: str = "bilinear",
    strict: bool = False,
    missing: float | None = None,
    transform: Any = None,
    crs: Any = None,
    nodata_value: float | None = None,
) -> DemSource:
    """Open a DEM; its heights come out above the WGS84 ellipsoid.

    Parameters
    ----------
    source : DemLike
        * a raster file rasterio opens: GeoTIFF, SRTM ``.hgt``, VRT, ... in any CRS;
        * a list of such files (tiles, each in any CRS; open rasterio datasets and
          DataArrays too): a mosaic where each point takes the first tile, in the order
          given, that has a height;
        * ``"const:H"``: ``H`` metres everywhere, above the ellipsoid (or above the geoid
          with ``vertical="geoid"``);
        * the ``to_dict()`` of a DEM opened before (how dask workers re-open it);
        * a DEM object (any :class:`~geoblock.dem.DemSource`), returned as it is;
        * an open rasterio dataset: a file dataset is re-opened by its name (the DEM its path
          gives, read window by window); an in-memory one (``MemoryFile``, ``MEM`` driver) is
          read into an :class:`~geoblock.dem.array.ArrayDem` (band 1);
        * an ``xarray.DataArray`` ``(y, x)`` or ``(1, y, x)``: its values (a dask-backed
          array is computed once) with the CRS, geotransform and nodata it states the way
          rioxarray writes them (a ``spatial_ref`` coordinate with ``crs_wkt`` and
          ``GeoTransform``, ``_FillValue``; see
          :func:`~geoblock.io.rasters.dataarray_georeferencing`), as an
          :class:`~geoblock.dem.array.ArrayDem`;
        * a numpy array ``(R, C)`` with ``transform=`` and ``crs=``: an
          :class:`~geoblock.dem.array.ArrayDem`.

        An in-memory DEM gives exactly the heights a file of the same pixels gives.
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
    transform : affine.Affine or sequence of 6, optional
        Arrays only: the geotransform (pixel corners, rasterio order) of a numpy array, or
        one overriding a DataArray's.
    crs : pyproj.CRS, str or int, optional
        Arrays only: the CRS of a numpy array (a compound CRS may state the vertical
        datum), or one overriding a DataArray's.
    nodata_value : float, optional
        Arrays only: the value marking posts without a height (NaN always does), or one
        overriding a DataArray's ``_FillValue``.

    Returns
    -------
    DemSource
        :class:`~geoblock.dem.RasterDem`, :class:`~geoblock.dem.array.ArrayDem`,
        :class:`~geoblock.dem.MosaicDem`, :class:`~geoblock.dem.ConstantDem`,
        :class:`~geoblock.dem.ConstantGeoidDem`, :class:`~geoblock.dem.FilledDem` or the
        DEM object given.

    Raises
    ------
    DemError
        Unreadable file, unknown option, unstated vertical datum, geoid grid not found, an
        array without its geotransform or CRS.
    InputTypeError
        ``source`` is none of the above (the message says what it is and what is accepted),
        or ``transform``, ``crs`` or ``nodata_value`` were given for a file.

    Examples
    --------
    >>> dem = open_dem("const:100")
    >>> float(dem.height(5.0, 44.0))
    100.0
    """
    from geoblock.dem.base import DemBase
    from geoblock.dem.filled import FilledDem
    from geoblock.dem.mosaic import MosaicDem
    from geoblock.dem.protocol import DemSource
    from geoblock.dem.raster import VERTICALS

    if missing is not None:
        inner = open_dem(source, vertical=vertical, geoid=geoid, nodata=nodata,
                         interpolation=interpolation, strict=strict, transform=transform,
                         crs=crs, nodata_value=nodata_value)
        try:
            return FilledDem(inner, missing)
        except ValueError as exc:
            raise DemError(f"open_dem: missing={missing!r}: {exc}") from None
    if vertical is not None and vertical not in VERTICALS:
        raise DemError(f"open_dem: vertical must be 'geoid', 'ellipsoid' or None, got {vertical!r}")
    in_memory = isinstance(source, np.ndarray) or is_dataarray(source)
    if not in_memory and (transform is not None or crs is not None or nodata_value is not None):
        raise InputTypeError(
            f"open_dem: transform=, crs= and nodata_value= describe an in-memory array; "
            f"{type_name(source)} states its own georeferencing")
    if isinstance(source, DemBase):
        return source
    if isinstance(source, Mapping):
        return _from_dict(source)
    options = _Options(vertical, geoid, nodata, interpolation, strict)
    if isinstance(source, str | os.PathLike):
        text = os.fspath(source)
        if text.startswith("const:"):
            return _constant(text, vertical, geoid)
        return options.tile(text)
    if is_dataset(source) or in_memory:
        return options.tile(source, transform=transform, crs=crs, nodata_value=nodata_value)
    if isinstance(source, DemSource):  # a DEM of another kind (a plugin's, a user's)
        return source
    if isinstance(source, Sequence) and not isinstance(source, bytes):
        tiles = list(source)
        if not tiles:
            raise DemError("open_dem: the list of DEM tiles is empty")
        if len(tiles) == 1:
            return open_dem(tiles[0], vertical=vertical, geoid=geoid, nodata=nodata,
                            interpolation=interpolation, strict=strict)
        return MosaicDem([options.tile(t, strict=False) for t in tiles], strict=strict)
    raise InputTypeError(f"open_dem: cannot use {type_name(source)} as a DEM; accepted: "
                         f"{_ACCEPTED}")


def as_dem(dem: EngineDem) -> DemSource:
    """The DEM an engine works on: a :class:`~geoblock.dem.DemSource` as it is, a number as a
    :class:`~geoblock.dem.ConstantDem` (metres above the ellipsoid), anything else through
    :func:`open_dem` (a path, an open rasterio dataset, a georeferenced DataArray, ...).

    Raises
    ------
    DemError, InputTypeError
        As :func:`open_dem`.
    """
    from geoblock.dem.base import DemBase
    from geoblock.dem.constant import ConstantDem

    if isinstance(dem, DemBase):
        return dem
    if isinstance(dem, int | float | np.integer | np.floating) and not isinstance(dem, bool):
        return ConstantDem(float(dem))
    return open_dem(dem)


class _Options:
    """The options of one :func:`open_dem` call, applied to each raster (tile) it opens."""

    def __init__(self, vertical: str | None, geoid: Any, nodata: str | float,
                 interpolation: str, strict: bool) -> None:
        self.common: dict[str, Any] = dict(vertical=vertical, geoid=geoid, nodata=nodata,
                                           interpolation=interpolation)
        self.strict = strict

    def tile(self, source: Any, *, strict: bool | None = None, transform: Any = None,
             crs: Any = None, nodata_value: float | None = None) -> RasterDem:
        """A :class:`RasterDem` (file) or :class:`ArrayDem` (pixels in memory) of ``source``."""
        from geoblock.dem.array import ArrayDem
        from geoblock.dem.raster import RasterDem

        options = dict(self.common, strict=self.strict if strict is None else strict)
        if isinstance(source, str | os.PathLike):
            return RasterDem(_existing(os.fspath(source)), **options)
        if is_dataset(source):
            if source.closed:
                raise InputTypeError(f"open_dem: the rasterio dataset {source.name!r} is closed")
            name = str(source.name)
            if source.driver != "MEM" and name and not name.startswith("/vsimem/"):
                return RasterDem(name, **options)  # a file: read window by window
            return ArrayDem(source.read(1), source.transform, source.crs,
                            nodata_value=source.nodatavals[0], scale=source.scales[0] or 1.0,
                            offset=source.offsets[0] or 0.0, driver=source.driver,
                            name=name or "<in-memory rasterio dataset>", **options)
        if is_dataarray(source):
            grid = dataarray_grid(source, "open_dem", bands=False)
            if grid.ndim == 3 and grid.shape[0] == 1:
                grid = grid[0]
            if grid.ndim != 2:
                raise DemError(f"open_dem: a DataArray DEM must be (y, x) or (1, y, x), got "
                               f"dims {tuple(source.dims)}")
            wkt, stated_transform, stated_nodata = dataarray_georeferencing(source)
            scale, offset = dataarray_scale_offset(source)
            transform = stated_transform if transform is None else transform
            crs = wkt if crs is None else crs
            name = f"<DataArray {source.name}>" if source.name is not None else "<DataArray>"
            if transform is None or crs is None:
                raise DemError(
                    f"open_dem: the DataArray {name} is not georeferenced: it needs a "
                    "spatial_ref coordinate with crs_wkt and GeoTransform attributes (as "
                    "rioxarray writes them), or pass transform= and crs=")
            return ArrayDem(grid, transform, crs,
                            nodata_value=stated_nodata if nodata_value is None else nodata_value,
                            scale=scale, offset=offset, name=name, **options)
        if isinstance(source, np.ndarray):
            if transform is None or crs is None:
                raise DemError("open_dem: a numpy array needs its georeferencing: "
                               "open_dem(array, transform=..., crs=...) (transform: pixel "
                               "corners, rasterio order)")
            return ArrayDem(source, transform, crs, nodata_value=nodata_value, **options)
        raise InputTypeError(f"open_dem: cannot use {type_name(source)} as a DEM tile; "
                             "accepted: a path, an open rasterio dataset or a georeferenced "
                             "xarray.DataArray")


def _existing(path: str) -> str:
    if path.startswith(("/vsi", "http://", "https://")) or Path(path).exists():
        return path
    raise DemError(f"DEM file not found: {path}")


def _constant(text: str, vertical: str | None, geoid: Any) -> DemSource:
    from geoblock.dem.constant import ConstantDem
    from geoblock.dem.geoid import ConstantGeoidDem, find_geoid

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


def _from_dict(data: Mapping[str, Any]) -> DemSource:
    from geoblock.dem.array import ArrayDem
    from geoblock.dem.constant import ConstantDem
    from geoblock.dem.filled import FilledDem
    from geoblock.dem.geoid import ConstantGeoidDem, find_geoid
    from geoblock.dem.mosaic import MosaicDem
    from geoblock.dem.raster import RasterDem

    kind = data.get("dem")
    try:
        if kind == "raster":
            return RasterDem.from_dict(dict(data))
        if kind == "array":
            return ArrayDem.from_dict(data)
        if kind == "mosaic":
            return MosaicDem.from_dict(dict(data))
        if kind == "filled":
            return FilledDem(_from_dict(data["source"]), float(data["fill"]))
        if kind == "constant":
            if data.get("vertical") == "geoid":
                return ConstantGeoidDem(float(data["h"]), find_geoid(data.get("geoid")))
            return ConstantDem(float(data["h"]))
        if kind == "grid":
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


# ---------------------------------------------------------------------------- writing
#: WKT of a vertical CRS "WGS 84 ellipsoidal height", the vertical part of the compound CRS
#: that :func:`write_dem` gives projected grids of ellipsoidal heights (GeoTIFF stores it as a
#: user-defined vertical CRS; :func:`open_dem` recognises the name).
_ELLIPSOIDAL_VERTCRS = (
    'VERTCRS["WGS 84 ellipsoidal height",VDATUM["WGS 84 ellipsoid"],CS[vertical,1],'
    'AXIS["gravity-related height (H)",up,LENGTHUNIT["metre",1]]]'
)


def vertical_crs(crs: Any, vertical: str) -> Any:
    """The CRS that states ``vertical`` in a GeoTIFF, built on ``crs``'s horizontal part.

    Parameters
    ----------
    crs : pyproj.CRS or str
        Horizontal CRS of the grid (a compound CRS's vertical part is replaced).
    vertical : {"ellipsoid", "geoid"}
        ``"geoid"``: compound with EGM96 height (EPSG:5773); ``"ellipsoid"``: EPSG:4979 for
        WGS84 longitude/latitude grids, otherwise compound with a "WGS 84 ellipsoidal
        height" vertical CRS.

    Returns
    -------
    pyproj.CRS
        A CRS from which :func:`open_dem` reads ``vertical`` back without being told.
    """
    import pyproj
    from pyproj.crs import CompoundCRS

    from geoblock.dem.grid import _is_lonlat
    from geoblock.dem.raster import VERTICALS

    if vertical not in VERTICALS:
        raise DemError(f"write_dem: vertical must be 'ellipsoid' or 'geoid', got {vertical!r}")
    try:
        crs = pyproj.CRS.from_user_input(crs)
    except pyproj.exceptions.CRSError as exc:
        raise DemError(f"write_dem: invalid crs {crs!r}: {exc}") from None
    horizontal = crs.sub_crs_list[0] if crs.is_compound else crs
    if len(horizontal.axis_info) == 3:
        horizontal = horizontal.to_2d()
    if vertical == "ellipsoid" and _is_lonlat(horizontal):
        return pyproj.CRS.from_epsg(4979)
    vert = (pyproj.CRS.from_epsg(5773) if vertical == "geoid"
            else pyproj.CRS.from_wkt(_ELLIPSOIDAL_VERTCRS))
    return CompoundCRS(name=f"{horizontal.name} + {vert.name}", components=[horizontal, vert])


def write_dem(
    path: PathLike,
    heights: np.ndarray,
    transform: Any,
    crs: Any,
    vertical: str,
    *,
    nodata: float = -9999.0,
    dtype: str = "float32",
    compress: str | None = "deflate",
) -> Path:
    """Write a height grid as a GeoTIFF whose CRS states its vertical datum, atomically.

    :func:`open_dem` reads the file back with the same datum and no ``vertical=`` argument:
    the CRS is compound (horizontal + EGM96 height, or + "WGS 84 ellipsoidal height") or, for
    ellipsoidal heights on WGS84 longitude/latitude, the 3-D EPSG:4979 (see
    :func:`vertical_crs`). The band also carries the tags ``GEOBLOCK_VERTICAL``
    (``ellipsoid``/``geoid``) and ``VERTICAL_DATUM`` for people and other tools.

    Parameters
    ----------
    path : str or os.PathLike
        Destination; written under a temporary name in the same directory (``.NAME.<random>.tmp``)
        and renamed to ``path`` only when complete.
    heights : array_like, (R, C)
        Metres above ``vertical``; NaN marks nodata.
    transform : affine.Affine or sequence of 6
        GDAL-style geotransform (pixel corners), as rasterio's.
    crs : pyproj.CRS or str
        CRS of the grid (its horizontal part is used).
    vertical : {"ellipsoid", "geoid"}
        Datum of ``heights``: the WGS84 ellipsoid or the EGM96 geoid.
    nodata : float
        Value written for NaN heights, and declared as the file's nodata.
    dtype : {"float32", "float64"}
        Sample type in the file.
    compress : str or None
        GDAL compression.

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    DemError
        Invalid heights, transform, CRS, ``vertical`` or ``dtype``.
    GeoblockIOError
        The directory does not exist or GDAL cannot write: one line naming ``path``, never
        the temporary (a full disk says so, :func:`geoblock.io._atomic.write_error`).
    """
    import rasterio
    from affine import Affine

    path = Path(path)
    arr = np.asarray(heights, dtype=np.float64)
    if arr.ndim != 2 or min(arr.shape) < 1:
        raise DemError(f"write_dem {path}: heights must be a non-empty 2-D array, got shape "
                       f"{arr.shape}")
    if dtype not in ("float32", "float64"):
        raise DemError(f"write_dem {path}: dtype must be 'float32' or 'float64', got {dtype!r}")
    if not math.isfinite(float(nodata)):
        raise DemError(f"write_dem {path}: nodata must be a finite number, got {nodata!r}")
    strips = [(r0, min(arr.shape[0], r0 + 1024)) for r0 in range(0, arr.shape[0], 1024)]
    if any(np.isinf(arr[r0:r1]).any() for r0, r1 in strips):
        raise DemError(f"write_dem {path}: heights contain infinite values")
    transform = transform if isinstance(transform, Affine) else Affine(*tuple(transform)[:6])
    if transform.is_degenerate:
        raise DemError(f"write_dem {path}: degenerate transform {tuple(transform)[:6]}")
    full_crs = vertical_crs(crs, vertical)
    profile: dict[str, Any] = {
        "driver": "GTiff", "width": arr.shape[1], "height": arr.shape[0], "count": 1,
        "dtype": dtype, "crs": rasterio.crs.CRS.from_wkt(full_crs.to_wkt()),
        "transform": transform, "nodata": float(nodata),
    }
    if max(arr.shape) > 512:
        profile.update(tiled=True, blockxsize=256, blockysize=256)
    if compress:
        profile["compress"] = compress
    datum = "EGM96 geoid" if vertical == "geoid" else "WGS84 ellipsoid"
    with atomic_path(path, "DEM ") as tmp, rasterio.open(tmp, "w", **profile) as dst:
        for r0, r1 in strips:  # 1024 rows at a time: no full-size copy of a large grid
            block = arr[r0:r1]
            dst.write(np.where(np.isnan(block), float(nodata), block).astype(dtype), 1,
                      window=rasterio.windows.Window(0, r0, arr.shape[1], r1 - r0))
        dst.update_tags(1, GEOBLOCK_VERTICAL=vertical, VERTICAL_DATUM=datum)
        dst.set_band_unit(1, "metre")
    return path
