"""Raster files: quiet opens, the per-thread handle cache, window reads and geoid grids.

This is geoblock's one door to raster files for the objects that read lazily (a file DEM, the
geoid grid, a source image): they hold a path, not an open dataset (so they pickle by path to
dask workers), and read their windows through this module.

Quiet opens
    ``warnings.catch_warnings`` changes process-wide state and is not thread-safe: two threads
    that enter and leave it in an interleaved order can leave a thread without its filter, so
    a warning that was meant to be silenced reaches (and, under ``-W error``, breaks) a dask
    worker. Every quiet open in geoblock goes through :func:`open_quietly`, which serialises
    them on one lock (opens are short; the reads after them are not serialised).

Handle cache
    Repeated window reads of one file (DEM blocks, source-image windows of every ortho or
    mosaic chunk) go through :func:`cached_dataset` (or :func:`read_window`): one open dataset
    per file and thread, so that they pay neither for ``rasterio.open`` nor for the lock.

In-memory rasters
    :func:`dataarray_georeferencing` reads the georeferencing of an ``xarray.DataArray`` the
    way rioxarray writes it (a ``spatial_ref`` coordinate with ``crs_wkt`` and
    ``GeoTransform``), for the engines that accept arrays as well as files.

This module imports nothing from ``geoblock.dem``, ``geoblock.ortho`` or ``geoblock.models``:
they import it.
"""

from __future__ import annotations

import os
import struct
import threading
import warnings
from collections import OrderedDict
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from geoblock.errors import DemError, GeoblockIOError, InputTypeError

if TYPE_CHECKING:
    from affine import Affine
    from rasterio.io import DatasetReader

__all__ = [
    "MAX_HANDLES_PER_THREAD",
    "cached_dataset",
    "dataarray_georeferencing",
    "dataarray_grid",
    "dataarray_scale_offset",
    "is_dataarray",
    "is_dataset",
    "open_quietly",
    "read_gtx",
    "read_window",
]

_LOCK = threading.RLock()


def open_quietly(name: Any, mode: str = "r", **kwargs: Any) -> Any:
    """``rasterio.open(name, mode, **kwargs)`` with ``NotGeoreferencedWarning`` silenced.

    Raw images and outputs being created have no geotransform: that is expected, not worth a
    warning. Opens are serialised on one lock (see the module notes); the returned dataset
    is the caller's to close.
    """
    import rasterio

    with _LOCK, warnings.catch_warnings():
        warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
        return rasterio.open(name, mode, **kwargs)


# ---------------------------------------------------------------------------- dataset handles
_handles = threading.local()  # per thread: path -> (signature, open rasterio dataset)
#: open datasets kept per thread, least recently used closed beyond (a mosaic of hundreds of
#: orthos on every core must not run out of file descriptors)
MAX_HANDLES_PER_THREAD = 16


def _signature(path: str) -> tuple[int, int, int] | None:
    """What identifies the file's current contents (None for non-local paths)."""
    try:
        st = os.stat(path)
    except OSError:
        return None
    return (st.st_ino, st.st_size, st.st_mtime_ns)


def cached_dataset(path: str) -> DatasetReader:
    """An open (read-only) rasterio dataset of ``path``, kept per thread and reopened when the
    file changes, so that repeated window reads do not pay for ``rasterio.open``.

    Opened with :func:`open_quietly`. The handle belongs to the calling thread (GDAL datasets
    are not thread-safe) and to the calling process (a forked child opens its own: shared file
    offsets); the caller must not close it nor keep it beyond its reads (at most
    :data:`MAX_HANDLES_PER_THREAD` are kept: the least recently used is closed).

    Raises
    ------
    rasterio.errors.RasterioIOError
        The file cannot be opened (callers name it in their own error).
    """
    cache = getattr(_handles, "datasets", None)
    if cache is None or getattr(_handles, "pid", None) != os.getpid():
        # (a forked child never reads through its parent's handles: shared file offsets)
        cache = _handles.datasets = OrderedDict()
        _handles.pid = os.getpid()
    sig = _signature(path)
    found = cache.get(path)
    if found is not None:
        if found[0] == sig and not found[1].closed:
            cache.move_to_end(path)
            return found[1]
        found[1].close()
        del cache[path]
    ds = open_quietly(path)
    cache[path] = (sig, ds)
    while len(cache) > MAX_HANDLES_PER_THREAD:
        _, (_, old) = cache.popitem(last=False)
        old.close()
    return ds


def read_window(
    path: str,
    window: tuple[int, int, int, int],
    band: int | None = None,
    what: str = "",
) -> np.ndarray:
    """Pixels of a window of a raster file, read through the per-thread handle cache.

    Parameters
    ----------
    path : str
        The raster (a path or GDAL dataset name).
    window : (row_start, row_stop, col_start, col_stop)
        Pixels, inside the raster.
    band : int, optional
        1-based band; default every band.
    what : str
        What the file is, for the message (``"the image "``).

    Returns
    -------
    ndarray
        ``(R, C)`` for one band, ``(bands, R, C)`` for all, of the file's dtype.

    Raises
    ------
    GeoblockIOError
        The file cannot be opened or read (the message names it).
    """
    import rasterio
    from rasterio.windows import Window

    r0, r1, c0, c1 = (int(v) for v in window)
    try:
        ds = cached_dataset(path)
        return ds.read(band, window=Window(c0, r0, c1 - c0, r1 - r0))
    except rasterio.errors.RasterioIOError as exc:
        raise GeoblockIOError(f"cannot read {what}{path}: {exc}") from exc


def is_dataset(obj: object) -> bool:
    """Whether ``obj`` is an open rasterio dataset (without importing rasterio for others)."""
    module = type(obj).__module__ or ""
    if not module.startswith("rasterio"):
        return False
    from rasterio.io import DatasetReaderBase

    return isinstance(obj, DatasetReaderBase)


def is_dataarray(obj: object) -> bool:
    """Whether ``obj`` is an ``xarray.DataArray`` (without importing xarray for others)."""
    if not (type(obj).__module__ or "").startswith("xarray"):
        return False
    import xarray as xr

    return isinstance(obj, xr.DataArray)


def type_name(obj: object) -> str:
    """``"an object of type numpy.ndarray"``: how messages name what they were given."""
    kind = type(obj)
    module = kind.__module__
    name = kind.__qualname__ if module == "builtins" else f"{module}.{kind.__qualname__}"
    return f"an object of type {name}"


# ---------------------------------------------------------------------------- geoid grids
_GTX_HEADER = struct.Struct(">4d2i")


def read_gtx(path: str | os.PathLike[str]) -> tuple[tuple[float, float, float, float],
                                                    np.ndarray]:
    """A NOAA ``.gtx`` grid: header ``(lat0, lon0, dlat, dlon)`` and its nodes.

    Parameters
    ----------
    path : str or os.PathLike
        The ``.gtx`` file (big-endian header of four doubles and two ints, then
        ``rows * cols`` big-endian float32 nodes, south row first).

    Returns
    -------
    header : (float, float, float, float)
        Latitude and longitude of the south-west node and the steps, degrees.
    nodes : ndarray, (rows, cols) float64
        As stored (NOAA's no-value marker is left to the caller).

    Raises
    ------
    DemError
        The file cannot be read or is not a ``.gtx`` grid (the message names it).
    """
    try:
        raw = Path(path).read_bytes()
    except OSError as exc:
        raise DemError(f"cannot read the geoid grid {path}: {exc.strerror or exc}") from exc
    if len(raw) < _GTX_HEADER.size:
        raise DemError(f"geoid grid {path}: not a .gtx file (only {len(raw)} bytes)")
    lat0, lon0, dlat, dlon, rows, cols = _GTX_HEADER.unpack(raw[:_GTX_HEADER.size])
    if (rows < 2 or cols < 2 or dlat <= 0 or dlon <= 0
            or len(raw) != _GTX_HEADER.size + 4 * rows * cols):
        raise DemError(
            f"geoid grid {path}: invalid .gtx header (rows={rows}, cols={cols}, "
            f"lat_step={dlat}, lon_step={dlon}, {len(raw)} bytes)"
        )
    nodes = np.frombuffer(raw, dtype=">f4", offset=_GTX_HEADER.size)
    return (lat0, lon0, dlat, dlon), nodes.astype(np.float64).reshape(rows, cols)


# ---------------------------------------------------------------------------- DataArrays
def _transform_from_coords(data: Any) -> Affine | None:
    """The north-up geotransform of regular 1-D ``x``/``y`` pixel-centre coordinates."""
    from affine import Affine

    from geoblock.pixels import PIXEL_CENTRE

    if "x" not in data.coords or "y" not in data.coords:
        return None
    x = np.asarray(data.coords["x"].values, dtype=np.float64)
    y = np.asarray(data.coords["y"].values, dtype=np.float64)
    if x.ndim != 1 or y.ndim != 1 or x.size < 2 or y.size < 2:
        return None
    dx, dy = np.diff(x), np.diff(y)
    # regular within the precision the coordinates were stored with (float32 coordinates of
    # UTM eastings carry ~0.03 m of rounding)
    eps = float(np.finfo(data.coords["x"].dtype).eps
                if np.issubdtype(data.coords["x"].dtype, np.floating) else np.finfo(float).eps)
    tol_x = 8 * eps * max(float(np.abs(x).max()), abs(float(dx[0])))
    tol_y = 8 * eps * max(float(np.abs(y).max()), abs(float(dy[0])))
    if not (np.allclose(dx, dx[0], rtol=0, atol=tol_x) and np.allclose(dy, dy[0], rtol=0,
                                                                        atol=tol_y)):
        return None
    a, e = float(dx[0]), float(dy[0])
    return Affine(a, 0.0, float(x[0]) - PIXEL_CENTRE * a, 0.0, e, float(y[0]) - PIXEL_CENTRE * e)


def _same_grid(a: Affine, b: Affine) -> bool:
    """Whether two geotransforms place pixels within 1e-6 px of each other."""
    step = max(abs(a.a), abs(a.e), abs(a.b), abs(a.d))
    return all(abs(u - v) <= 1e-6 * step for u, v in zip(tuple(a)[:6], tuple(b)[:6],
                                                         strict=True))


def _parse_geotransform(value: Any) -> Affine | None:
    """An ``Affine`` of a GDAL-order ``GeoTransform`` string (``"c a b f d e"``) or sequence."""
    from affine import Affine

    parts: Sequence[Any] = str(value).split() if isinstance(value, str) else value
    try:
        c, a, b, f, d, e = (float(v) for v in parts)
    except (TypeError, ValueError):
        return None
    return Affine(a, b, c, d, e, f)


def dataarray_georeferencing(data: Any) -> tuple[str | None, Affine | None, float | None]:
    """``(crs_wkt, transform, nodata)`` of an ``xarray.DataArray``, as rioxarray writes them.

    Looked up, first found wins:

    * CRS: the ``spatial_ref`` coordinate's ``crs_wkt`` or ``spatial_ref`` attribute, then
      ``attrs["crs"]``;
    * geotransform: regular 1-D ``x``/``y`` coordinates (pixel centres) when there are some:
      they follow ``isel``/``sel`` slicing, which leaves a stored GeoTransform stale (as
      rioxarray does); otherwise the ``spatial_ref`` coordinate's ``GeoTransform`` (GDAL
      order, as rioxarray and :func:`geoblock.orthorectify` write it), then
      ``attrs["transform"]`` (rasterio order ``a, b, c, d, e, f``);
    * nodata: ``attrs["_FillValue"]``, ``encoding["_FillValue"]``, ``attrs["nodata"]``,
      ``attrs["nodatavals"][0]`` (the old ``xarray.open_rasterio``).

    Missing items are ``None``.
    """
    from affine import Affine

    ref = data.coords.get("spatial_ref")
    ref_attrs = ref.attrs if ref is not None else {}
    wkt = ref_attrs.get("crs_wkt") or ref_attrs.get("spatial_ref") or data.attrs.get("crs")
    stored = None
    if ref_attrs.get("GeoTransform") is not None:
        stored = _parse_geotransform(ref_attrs["GeoTransform"])
    if stored is None and data.attrs.get("transform") is not None:
        try:
            stored = Affine(*(float(v) for v in tuple(data.attrs["transform"])[:6]))
        except (TypeError, ValueError):
            stored = None
    from_coords = _transform_from_coords(data)
    transform = stored
    if from_coords is not None and (stored is None or not _same_grid(stored, from_coords)):
        transform = from_coords  # a slice: the stored transform is stale
    nodata = None
    legacy = data.attrs.get("nodatavals")
    for value in (data.attrs.get("_FillValue"), data.encoding.get("_FillValue"),
                  data.attrs.get("nodata"), legacy[0] if legacy else None):
        if value is not None:
            nodata = float(value)
            break
    return (None if wkt is None else str(wkt)), transform, nodata


def dataarray_scale_offset(data: Any) -> tuple[float, float]:
    """``(scale, offset)`` of a DataArray's stored values (``value * scale + offset``), from
    ``scale_factor``/``add_offset`` in its attributes or encoding, as rioxarray leaves them
    with ``mask_and_scale=False``; ``(1, 0)`` when absent."""
    def first(key: str, default: float) -> float:
        for where in (data.attrs, data.encoding):
            if where.get(key) is not None:
                return float(where[key])
        return default

    return first("scale_factor", 1.0), first("add_offset", 0.0)


def dataarray_grid(data: Any, what: str, *, bands: bool) -> np.ndarray:
    """The values of a DataArray ordered ``(y, x)`` (or ``(band, y, x)`` with ``bands``).

    Dimensions named ``y``/``x`` (and ``band``) are put in that order whatever their order in
    the DataArray; unnamed layouts are taken as they are. Other named layouts are refused.
    """
    dims = tuple(str(d) for d in data.dims)
    if "x" in dims and "y" in dims:
        wanted: tuple[str, ...] = ("y", "x")
        if bands and data.ndim == 3:
            extra = [d for d in dims if d not in wanted]
            wanted = (extra[0], "y", "x")
        elif data.ndim == 3 and data.shape[dims.index(
                next(d for d in dims if d not in ("x", "y")))] == 1:
            data = data.squeeze([d for d in dims if d not in ("x", "y")])
        if data.ndim != len(wanted):
            raise InputTypeError(f"{what}: a DataArray with dims {dims} cannot be read as "
                                 f"{' x '.join(wanted)}")
        data = data.transpose(*wanted)
    return np.asarray(data.values)
