"""Source images (read lazily, window by window) and orthoimage writing (tiled GeoTIFF / COG).

* :func:`open_image` returns an :class:`ImageSource` for a file: the path and what the
  orthorectifier needs to know before reading (shape, bands, dtype, nodata, georeferencing).
  It holds no open dataset, so it pickles by path to dask workers; :meth:`ImageSource.read`
  reads one window through a dataset kept open per thread
  (:func:`geoblock.io.rasters.cached_dataset`). For pixels already in memory (a numpy array,
  an ``xarray.DataArray``, an in-memory rasterio dataset) it returns an :class:`ArrayImage`,
  which reads its windows from the array and pickles with it.
* :func:`write_ortho` computes a lazy ``(band, y, x)`` :class:`xarray.DataArray` chunk by chunk
  and writes it as a tiled GeoTIFF or a COG, under a temporary name in the destination
  directory, renamed to ``path`` only when everything was written: a failed or interrupted run
  leaves nothing under ``path`` (and removes its temporary file). An output with no valid pixel
  (every pixel nodata) is refused by default (``empty="error"``).
"""

from __future__ import annotations

import math
import os
import re
import sys
import warnings
from collections import deque
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeAlias

import numpy as np

from geoblock.errors import (
    EmptyOutputError,
    EmptyOutputWarning,
    GeoblockIOError,
    InputTypeError,
    UnsupportedFormatError,
)
from geoblock.io._atomic import atomic_path
from geoblock.io._progress import Progress as _Progress
from geoblock.io.geotiff import DEFAULT_COMPRESS, compression_options
from geoblock.io.rasters import (
    dataarray_georeferencing,
    dataarray_grid,
    is_dataarray,
    is_dataset,
    open_quietly,
    read_window,
    type_name,
)

if TYPE_CHECKING:
    import xarray as xr
    from rasterio.io import DatasetReader

__all__ = ["ArrayImage", "ImageLike", "ImageSource", "OpenedImage", "open_image",
           "raster_source_ids", "read_band", "write_image", "write_ortho"]

PathLike = str | os.PathLike[str]


@dataclass(frozen=True)
class ImageSource:
    """A raster image file read lazily by window.

    Attributes
    ----------
    path : str
        Absolute path (or GDAL dataset name) of the image.
    shape : (int, int)
        ``(rows, cols)``, pixels.
    bands : int
        Number of bands.
    dtype : str
        NumPy dtype name of the pixels (the first band's).
    nodata : float or None
        The file's nodata value, if any.
    crop_offset : (float, float) or None
        ``(row0, col0)``: where the image's first pixel lies in a larger scene, when the file
        says so with a pixel-unit geotransform ``(col0, 1, 0, row0, 0, 1)`` and no CRS (as
        shareloc's Ventoux crops carry); None
        otherwise (no geotransform, GDAL's default identity one, or a map geotransform).
        :func:`geoblock.models.crop.model_for_image` shifts a full-scene model by it.
    crs : rasterio.crs.CRS or None
        The file's CRS, if any.
    transform : affine.Affine or None
        The file's geotransform (rasterio order; the identity when the file has none).
    source_ids : tuple of (str, str)
        ``(kind, id)`` pairs of the ids the raster carries (:func:`raster_source_ids`), which
        :func:`geoblock.models.crop.model_for_image` compares with the model's
        ``source_ids``; empty when it carries none.
    """

    path: str
    shape: tuple[int, int]
    bands: int
    dtype: str
    nodata: float | None = None
    crop_offset: tuple[float, float] | None = None
    crs: Any = None
    transform: Any = None
    source_ids: tuple[tuple[str, str], ...] = ()

    @property
    def name(self) -> str:
        """What to call the image in messages: its path."""
        return self.path

    def read(self, window: tuple[int, int, int, int] | None = None) -> np.ndarray:
        """Read a window of every band.

        Parameters
        ----------
        window : (row_start, row_stop, col_start, col_stop), optional
            Pixels, inside the image; default the whole image.

        Returns
        -------
        ndarray, (bands, R, C)
            Of :attr:`dtype`.

        Raises
        ------
        GeoblockIOError
            The file cannot be read (names it).
        """
        if window is None:
            window = (0, self.shape[0], 0, self.shape[1])
        # kept open per thread: one window per ortho/mosaic chunk, no open per read
        return read_window(self.path, window, what="the image ")

    def __dask_tokenize__(self) -> tuple[object, ...]:
        try:
            st = os.stat(self.path)
            stamp: tuple[int, int] | tuple[()] = (st.st_size, st.st_mtime_ns)
        except OSError:
            stamp = ()
        return ("ImageSource", self.path, self.shape, self.bands, self.dtype, self.nodata,
                self.crop_offset, None if self.crs is None else str(self.crs),
                None if self.transform is None else tuple(self.transform), stamp)


@dataclass(frozen=True, eq=False)
class ArrayImage:
    """An image held in memory, read by window like an :class:`ImageSource`.

    It pickles with its pixels (to dask workers: in-memory images suit images that fit in
    memory; a large image is better given as a file, read window by window).

    Parameters
    ----------
    array : ndarray, (R, C) or (bands, R, C)
        The pixels, any real numeric dtype; kept as a read-only view (not copied).
    nodata : float, optional
        The value of pixels without data.
    crop_offset : (float, float), optional
        ``(row0, col0)`` of the image's first pixel in a larger scene (as
        :attr:`ImageSource.crop_offset`).
    crs : rasterio.crs.CRS, optional
        The image's CRS (an ortho's); None for raw sensor geometry.
    transform : affine.Affine, optional
        The image's geotransform (rasterio order); None for raw sensor geometry.
    name : str
        What to call the image in messages.

    Raises
    ------
    InputTypeError
        ``array`` is not 2-D or 3-D with a real numeric dtype.
    """

    array: np.ndarray
    nodata: float | None = None
    crop_offset: tuple[float, float] | None = None
    crs: Any = None
    transform: Any = None
    name: str = "<in-memory image>"

    def __post_init__(self) -> None:
        data = np.asarray(self.array)
        if data.ndim == 2:
            data = data[None]
        if data.ndim != 3 or min(data.shape) < 1 or data.dtype.kind not in "biuf":
            raise InputTypeError(
                f"{self.name}: an image array must be (R, C) or (bands, R, C) of a real "
                f"numeric dtype, got shape {np.shape(self.array)} and dtype {data.dtype}")
        # an own read-only copy: a caller changing its array afterwards must not change
        # (part of) an image whose token and cached windows say otherwise
        own = np.array(data, copy=data.flags.writeable)
        own.flags.writeable = False
        object.__setattr__(self, "array", own)

    @property
    def path(self) -> str:
        """:attr:`name` (an in-memory image has no file; messages name it so)."""
        return self.name

    @property
    def shape(self) -> tuple[int, int]:
        """``(rows, cols)``, pixels."""
        return (int(self.array.shape[1]), int(self.array.shape[2]))

    @property
    def bands(self) -> int:
        """Number of bands."""
        return int(self.array.shape[0])

    @property
    def dtype(self) -> str:
        """NumPy dtype name of the pixels."""
        return str(self.array.dtype)

    def read(self, window: tuple[int, int, int, int] | None = None) -> np.ndarray:
        """A window of every band, ``(bands, R, C)``, a copy (as :meth:`ImageSource.read`)."""
        if window is None:
            return self.array.copy()
        r0, r1, c0, c1 = (int(v) for v in window)
        return self.array[:, r0:r1, c0:c1].copy()

    def __dask_tokenize__(self) -> tuple[object, ...]:
        from dask.base import tokenize

        return ("ArrayImage", tokenize(self.array), self.nodata, self.crop_offset,
                None if self.crs is None else str(self.crs),
                None if self.transform is None else tuple(self.transform), self.name)


OpenedImage: TypeAlias = ImageSource | ArrayImage
"""What :func:`open_image` returns: an image read window by window (``shape``, ``bands``,
``dtype``, ``nodata``, ``crop_offset``, ``crs``, ``transform``, ``read(window)``)."""

if TYPE_CHECKING:
    ImageLike: TypeAlias = (PathLike | ImageSource | ArrayImage | DatasetReader | xr.DataArray
                            | np.ndarray)
else:
    ImageLike = Any
"""What :func:`open_image` (hence :func:`geoblock.orthorectify`) accepts as an image."""

def read_band(image: OpenedImage, window: tuple[int, int, int, int] | None = None,
              band: int = 0) -> np.ndarray:
    """One band of a window as float64, NaN where the image has no data (its nodata value).

    Parameters
    ----------
    image : ImageSource or ArrayImage
    window : (row_start, row_stop, col_start, col_stop), optional
        Pixels; default the whole image.
    band : int
        0-based band index.

    Returns
    -------
    ndarray, (R, C)
        float64, a fresh array.
    """
    data = np.array(image.read(window)[band], dtype=np.float64)  # a copy, always
    nodata = image.nodata
    if nodata is not None and not math.isnan(nodata):
        data[data == nodata] = np.nan  # a NaN nodata is NaN already
    return data


_ACCEPTED = ("a path (str or os.PathLike), an ImageSource or ArrayImage, an open rasterio "
             "dataset, an xarray.DataArray (band, y, x) or (y, x), or a numpy array (R, C) or "
             "(bands, R, C)")


def open_image(
    source: ImageLike,
    *,
    nodata: float | None = None,
    transform: Any = None,
    crs: Any = None,
) -> OpenedImage:
    """Open an image for windowed reading: a file, or pixels already in memory.

    Parameters
    ----------
    source : str, os.PathLike, ImageSource, ArrayImage, rasterio dataset, DataArray or ndarray
        * a raster file rasterio opens (GeoTIFF, JP2, VRT, ...): an :class:`ImageSource`;
        * an :class:`ImageSource` or :class:`ArrayImage`: returned as it is;
        * an open rasterio dataset: re-opened by its name when it is a file (the same
          :class:`ImageSource` as its path gives); an in-memory one (``MemoryFile``, the
          ``MEM`` driver) is read into an :class:`ArrayImage`;
        * an ``xarray.DataArray`` ``(band, y, x)`` or ``(y, x)``: its values (a dask-backed
          array is computed once) in an :class:`ArrayImage`, with the nodata
          (``_FillValue``), CRS and geotransform it states as rioxarray writes them
          (:func:`~geoblock.io.rasters.dataarray_georeferencing`);
        * a numpy array ``(R, C)`` or ``(bands, R, C)``: an :class:`ArrayImage` (raw sensor
          geometry needs no geotransform).
    nodata, transform, crs : optional
        For arrays only (numpy arrays and DataArrays, overriding what a DataArray states): the
        pixels' nodata value, their geotransform (rasterio order; a pixel-unit one states a
        crop offset, as for files) and CRS.

    Returns
    -------
    ImageSource or ArrayImage
        With ``crop_offset`` when the geotransform is pixel-unit (a crop of a larger scene,
        see :func:`pixel_crop_offset`).

    Raises
    ------
    GeoblockIOError
        The file is missing or is not a raster.
    InputTypeError
        ``source`` is none of the above (the message says what it is), or ``nodata``,
        ``transform`` or ``crs`` were given for a file.
    """
    in_memory = isinstance(source, np.ndarray) or is_dataarray(source)
    if not in_memory and (nodata is not None or transform is not None or crs is not None):
        raise InputTypeError(
            f"open_image: nodata=, transform= and crs= describe an in-memory array; "
            f"{type_name(source)} states its own")
    if isinstance(source, ImageSource | ArrayImage):
        return source
    if isinstance(source, str | os.PathLike):
        return _open_file(os.fspath(source))
    if is_dataset(source):
        return _from_dataset(source)
    if is_dataarray(source):
        return _from_dataarray(source, nodata, transform, crs)
    if isinstance(source, np.ndarray):
        return _from_array(source, nodata, transform, crs, "<in-memory image>")
    raise InputTypeError(f"open_image: cannot use {type_name(source)} as an image; accepted: "
                         f"{_ACCEPTED}")


def _open_file(name: str) -> ImageSource:
    import rasterio

    if os.path.exists(name):
        name = str(Path(name).resolve())
    try:
        with open_quietly(name) as ds:
            return _image_source(name, ds)
    except rasterio.errors.RasterioIOError as exc:
        raise GeoblockIOError(f"cannot open the image {name}: {exc}") from exc


def _image_source(name: str, ds: Any) -> ImageSource:
    nodata = ds.nodata
    return ImageSource(
        path=name,
        shape=(int(ds.height), int(ds.width)),
        bands=int(ds.count),
        dtype=str(np.dtype(ds.dtypes[0])),
        nodata=None if nodata is None else float(nodata),
        crop_offset=pixel_crop_offset(ds.transform, ds.crs),
        crs=ds.crs,
        transform=ds.transform,
        source_ids=raster_source_ids(ds),
    )


_GML_NAME = re.compile(r"<gml:name>\s*([^<\s]+)\s*</gml:name>")


def raster_source_ids(ds: Any) -> tuple[tuple[str, str], ...]:
    """The ids an open rasterio dataset carries, as ``(kind, id)`` pairs.

    Only real ids are read, never file names:

    * ``catalog_id``: the DigitalGlobe/Maxar catalog id (``IMAGE.CATID`` or
      ``IMAGE_1.CATID`` of GDAL's ``IMD`` metadata domain, which GDAL fills from the
      product's ``.IMD`` or ISD ``.XML`` beside the image);
    * ``dataset_name``: DIMAP ``DATASET_NAME`` in the ``IMD`` domain (a DIMAP document
      beside the image);
    * ``datastrip_id``: the Pleiades / SPOT 6-7 datastrip (``DS_...``) named by the GML
      coverage embedded in the image (``gml.root-instance``), as the Ventoux crops carry;
    * ``nitf_iid2``: a NITF image's ``IID2`` (when not empty).

    Parameters
    ----------
    ds : rasterio dataset

    Returns
    -------
    tuple of (str, str)
        Sorted by kind; one id per kind.
    """
    ids: dict[str, str] = {}
    imd = {k.upper(): str(v).strip().strip('"') for k, v in (ds.tags(ns="IMD") or {}).items()}
    for key in ("IMAGE.CATID", "IMAGE_1.CATID"):
        if imd.get(key):
            ids["catalog_id"] = imd[key]
            break
    for key, value in imd.items():
        if key.endswith("DATASET_NAME") and value:
            ids["dataset_name"] = value
            break
    tags = ds.tags() or {}
    gml = _GML_NAME.search(str(tags.get("gml.root-instance", "")))
    if gml and gml.group(1).startswith("DS_"):
        ids["datastrip_id"] = gml.group(1)
    iid2 = str(tags.get("NITF_IID2", "")).strip()
    if iid2:
        ids["nitf_iid2"] = iid2
    return tuple(sorted(ids.items()))


def _from_dataset(ds: Any) -> ImageSource | ArrayImage:
    """A file dataset by its name (the path route); an in-memory one read into memory."""
    if ds.closed:
        raise InputTypeError(f"open_image: the rasterio dataset {ds.name!r} is closed")
    name = str(ds.name)
    if ds.driver != "MEM" and not name.startswith("/vsimem/") and name:
        return _open_file(name)
    nodata = ds.nodata
    return ArrayImage(ds.read(), nodata=None if nodata is None else float(nodata),
                      crop_offset=pixel_crop_offset(ds.transform, ds.crs), crs=ds.crs,
                      transform=ds.transform, name=name or "<in-memory rasterio dataset>")


def _from_dataarray(data: Any, nodata: float | None, transform: Any, crs: Any) -> ArrayImage:
    if data.ndim not in (2, 3):
        raise InputTypeError(f"open_image: a DataArray image must be (band, y, x) or (y, x), "
                             f"got dims {tuple(data.dims)}")
    wkt, stated_transform, stated_nodata = dataarray_georeferencing(data)
    if crs is None and wkt is not None:
        import rasterio.crs
        import rasterio.errors

        try:
            crs = rasterio.crs.CRS.from_user_input(wkt)
        except rasterio.errors.CRSError as exc:
            raise InputTypeError(f"open_image: the DataArray's CRS {wkt!r} cannot be read: "
                                 f"{exc}") from None
    return _from_array(dataarray_grid(data, "open_image", bands=True),
                       stated_nodata if nodata is None else nodata,
                       stated_transform if transform is None else transform, crs,
                       f"<DataArray {data.name}>" if data.name is not None else "<DataArray>")


def _from_array(array: np.ndarray, nodata: float | None, transform: Any, crs: Any,
                name: str) -> ArrayImage:
    from affine import Affine

    if transform is not None and not isinstance(transform, Affine):
        transform = Affine(*tuple(transform)[:6])
    offset = pixel_crop_offset(transform, crs) if transform is not None else None
    return ArrayImage(array, nodata=None if nodata is None else float(nodata),
                      crop_offset=offset, crs=crs, transform=transform, name=name)


def pixel_crop_offset(transform: Any, crs: Any = None) -> tuple[float, float] | None:
    """``(row0, col0)`` of a crop stated by a pixel-unit geotransform, else None.

    A raster without CRS whose geotransform is ``(col0, 1, 0, row0, 0, 1)`` (GDAL order;
    rasterio's ``Affine(1, 0, col0, 0, 1, row0)``) is a window of a larger image starting at
    pixel ``(row0, col0)`` (shareloc's crops carry one; GDAL
    writes none on a raw image): pixel ``(r, c)`` of the
    file is pixel ``(r + row0, c + col0)`` of the scene, pixel centres on both sides. The
    identity (GDAL's default for rasters without geotransform) says nothing and gives None,
    as does any map geotransform or a raster with a geographic or projected CRS.

    Parameters
    ----------
    transform : affine.Affine or sequence
        The raster's geotransform, rasterio order ``(a, b, c, d, e, f)``.
    crs : rasterio CRS, optional
    """
    if crs is not None and (getattr(crs, "is_geographic", False)
                            or getattr(crs, "is_projected", False)):
        return None
    try:
        a, b, c, d, e, f = (float(v) for v in tuple(transform)[:6])
    except (TypeError, ValueError):
        return None
    if (a, b, d, e) != (1.0, 0.0, 0.0, 1.0) or not (math.isfinite(c) and math.isfinite(f)):
        return None
    if (c == 0.0 and f == 0.0) or not (c.is_integer() and f.is_integer()):
        return None  # the identity, or not a window of whole pixels
    return f, c


# ---------------------------------------------------------------------- writing
def _distributed_client(scheduler: Any) -> Any:
    """The dask.distributed Client to use, or None for a local scheduler."""
    if (scheduler is None or isinstance(scheduler, str)) and "distributed" not in sys.modules:
        return None  # no Client can exist (and importing distributed costs 0.3 s)
    try:
        from distributed import Client, default_client
    except ImportError:  # pragma: no cover - distributed is a dependency
        return None
    if isinstance(scheduler, Client):
        return scheduler
    if scheduler is None:
        try:
            return default_client()
        except ValueError:
            return None
    return None


def _local_in_flight() -> int:
    """The default number of chunks computed ahead of the writer here: 2 per core."""
    return 2 * (os.cpu_count() or 1)


def _iter_blocks(array: Any, scheduler: Any, in_flight: int | None,
                 progress: bool) -> Iterator[tuple[int, int, np.ndarray]]:
    """Yield ``(row0, col0, block)`` of a (bands, y, x) dask array in row-major chunk order,
    computing up to ``in_flight`` chunks ahead of the one yielded (finished chunks wait for
    their turn: the order of the writes, hence the file's bytes, never depends on which chunk
    finished first)."""
    import dask

    starts = [np.concatenate([[0], np.cumsum(c)[:-1]]).astype(int) for c in array.chunks[1:]]
    delayed = array.to_delayed()  # (1, ny, nx)
    items = [(int(starts[0][i]), int(starts[1][j]), delayed[0, i, j])
             for i in range(delayed.shape[1]) for j in range(delayed.shape[2])]
    bar = _Progress(len(items), progress)
    client = _distributed_client(scheduler)
    if in_flight is None:
        in_flight = _local_in_flight()
        if client is not None:  # two chunks per worker thread of the cluster, not of here
            in_flight = max(in_flight, 2 * sum(client.nthreads().values()))
    try:
        if client is not None:
            def result(fut: Any) -> Any:
                block = fut.result()
                fut.release()
                return block

            for r0, c0, block in _in_order(items, in_flight, client.compute, result,
                                           lambda fut: fut.release()):
                bar.update()
                yield r0, c0, block
        elif _local_threads(scheduler):
            # dask's threaded scheduler, pipelined: a pool of one thread per core computes
            # chunks while this thread writes the finished ones (dask.compute on batches
            # would leave the cores idle during the writes and at each batch's tail)
            yield from _iter_threads(items, in_flight, bar)
        else:
            for k in range(0, len(items), in_flight):
                batch = items[k:k + in_flight]
                blocks = dask.compute(*[d for _, _, d in batch], scheduler=scheduler)
                for (r0, c0, _), block in zip(batch, blocks, strict=True):
                    bar.update()
                    yield r0, c0, block
    finally:
        bar.close()


def _local_threads(scheduler: Any) -> bool:
    """Whether ``scheduler`` means dask's local threaded scheduler (the default for arrays)."""
    if scheduler is None and "dask" in sys.modules:  # else nothing can have configured one
        import dask

        scheduler = dask.config.get("scheduler", None)
    return scheduler is None or (isinstance(scheduler, str)
                                 and scheduler in ("threads", "threading"))


def _compute_one(delayed: Any) -> Any:
    import dask

    return dask.compute(delayed, scheduler="synchronous")[0]


def _in_order(items: list[tuple[int, int, Any]], in_flight: int, submit: Any, result: Any,
              drop: Any) -> Iterator[tuple[int, int, Any]]:
    """Yield ``(row0, col0, block)`` of ``items`` (``(row0, col0, delayed)``) in their order,
    with up to ``in_flight`` of them submitted ahead of the one yielded: ``submit(delayed)``
    starts a computation and returns its handle, ``result(handle)`` waits for its block,
    ``drop(handle)`` abandons one still in flight (when the consumer stops early)."""
    pending = deque(items)
    window: deque[tuple[Any, int, int]] = deque()  # (handle, row0, col0), in ``items`` order
    try:
        while pending and len(window) < in_flight:
            r0, c0, d = pending.popleft()
            window.append((submit(d), r0, c0))
        while window:
            handle, r0, c0 = window.popleft()
            block = result(handle)
            if pending:
                nr0, nc0, d = pending.popleft()
                window.append((submit(d), nr0, nc0))
            yield r0, c0, block
    finally:
        for handle, _, _ in window:
            drop(handle)


def _iter_threads(items: list[tuple[int, int, Any]], in_flight: int,
                  bar: Any, compute: Any = _compute_one) -> Iterator[tuple[int, int, Any]]:
    """:func:`_iter_blocks` on a thread pool: up to ``in_flight`` chunks computed ahead of the
    one yielded, yielded in ``items`` order (``compute(item)`` makes a chunk's block)."""
    import concurrent.futures as cf

    with cf.ThreadPoolExecutor(os.cpu_count() or 1, thread_name_prefix="geoblock") as pool:
        for r0, c0, block in _in_order(items, in_flight, lambda d: pool.submit(compute, d),
                                       lambda fut: fut.result(), lambda fut: fut.cancel()):
            bar.update()
            yield r0, c0, block


def _iter_job(job: Any, in_flight: int, progress: bool) -> Iterator[tuple[int, int, Any]]:
    """:func:`_iter_blocks` for an :class:`~geoblock.ortho.graph.OrthoJob` on local threads:
    its chunks computed by :meth:`~geoblock.ortho.graph.OrthoJob.chunk` on a thread pool, no
    dask graph (the same function and arguments as the graph's tasks: the same values)."""
    items = [(w[0], w[2], w) for w in job.windows()]
    bar = _Progress(len(items), progress)
    try:
        yield from _iter_threads(items, in_flight, bar, job.chunk)
    finally:
        bar.close()


def _has_valid(block: np.ndarray, nodata: float | None) -> bool:
    """Whether some pixel of a (bands, R, C) block has a band that is neither nodata nor NaN."""
    bad = np.isnan(block) if block.dtype.kind == "f" else np.zeros(block.shape, bool)
    if nodata is not None and not math.isnan(nodata):
        bad |= block == nodata
    return not bool(bad.all(axis=0).all())


class _TileRows:
    """Writes chunks, received in row-major chunk order, as whole rows of tiles in file order.

    GDAL's tiled GeoTIFF appends each compressed tile to the file when it is complete (the
    offsets table records where it went), so the order of the writes decides the bytes. Here
    every write is one full-width row of tiles (``blocksize`` rows, fewer at the bottom edge),
    top to bottom: the same sequence of GDAL calls, hence the same bytes, whatever the chunk
    size and whichever chunk finished first. Memory: one row of chunks (the last chunk of a
    row completes its first tile row) and one tile-row strip; never the whole output.
    """

    def __init__(self, dst: Any, bands: int, rows: int, cols: int, blocksize: int,
                 dtype: np.dtype) -> None:
        self.dst, self.rows, self.cols, self.bs = dst, rows, cols, blocksize
        self.strip = np.empty((bands, min(blocksize, rows), cols), dtype)
        self.top = 0      # first row of the tile row being filled
        self.filled = 0   # rows of it already filled
        # the chunks of the current chunk row: (col0, block)
        self.band: list[tuple[int, np.ndarray]] = []
        self.band_r0 = 0

    def add(self, r0: int, c0: int, block: np.ndarray) -> None:
        if not self.band:
            if r0 != self.top + self.filled or c0 != 0:
                raise AssertionError(f"chunks out of row-major order at ({r0}, {c0})")
            self.band_r0 = r0
        self.band.append((c0, block))
        if c0 + block.shape[2] < self.cols:
            return
        height = block.shape[1]
        cursor, end = self.band_r0, self.band_r0 + height
        while cursor < end:
            stop = min(end, self.top + self.bs, self.rows)
            i0, i1 = cursor - self.band_r0, stop - self.band_r0
            s0 = cursor - self.top
            for bc0, b in self.band:
                self.strip[:, s0:s0 + i1 - i0, bc0:bc0 + b.shape[2]] = b[:, i0:i1]
            self.filled += stop - cursor
            cursor = stop
            if self.top + self.filled in (self.top + self.bs, self.rows):
                self._flush()
        self.band = []

    def _flush(self) -> None:
        from rasterio.windows import Window

        h = self.filled
        data = self.strip if h == self.strip.shape[1] else np.ascontiguousarray(self.strip[:, :h])
        self.dst.write(data, window=Window(0, self.top, self.cols, h))
        self.top += h
        self.filled = 0

    def close(self) -> None:
        if self.band or self.top != self.rows:
            raise AssertionError(f"write_ortho: {self.top} of {self.rows} rows written")


EMPTY = ("error", "warn", "ignore")

def write_ortho(
    data: Any,
    path: PathLike,
    *,
    driver: str = "GTiff",
    blocksize: int = 512,
    compress: str | None = DEFAULT_COMPRESS,
    level: int | None = None,
    nodata: float | None = None,
    scheduler: Any = None,
    in_flight: int | None = None,
    progress: bool = False,
    empty: str = "error",
    tags: Mapping[str, str] | None = None,
    band_descriptions: Sequence[str] | None = None,
    units: str | None = None,
    **creation_options: Any,
) -> Path:
    """Compute a ``(band, y, x)`` DataArray and write it as a tiled GeoTIFF or a COG, atomically.

    Parameters
    ----------
    data : xarray.DataArray, (band, y, x), or OrthoJob
        Lazy (dask) or in memory, georeferenced by a ``spatial_ref`` coordinate with
        ``crs_wkt`` and ``GeoTransform`` attributes (as :func:`geoblock.orthorectify` returns
        and rioxarray writes); or an :class:`~geoblock.ortho.OrthoJob`
        (:func:`geoblock.ortho.ortho_job`), whose chunks run on a local thread pool without
        dask when ``scheduler`` is local threads (the same bytes as its DataArray, without
        dask's and xarray's import and graph costs: what ``geoblock ortho`` does).
    path : str or os.PathLike
        Destination. Written under a temporary name (``.NAME.<random>.tmp`` in the same
        directory) and renamed to ``path`` (``os.replace``) only on success.
    driver : {"GTiff", "COG"}
        Tiled GeoTIFF, or Cloud-Optimized GeoTIFF (written as a tiled GeoTIFF, then copied by
        GDAL's COG driver, with overviews).
    blocksize : int
        Tile side, pixels (a multiple of 16).
    compress : str or None
        GDAL compression, one of :data:`COMPRESSIONS` (``"zstd"``, ``"deflate"``, ``"lzw"``,
        ...; None or ``"none"``: uncompressed, as gdalwarp writes by default). Default
        ZSTD, at level 1 (:data:`geoblock.io.geotiff.DEFAULT_COMPRESS` gives the
        measurement behind it).
    level : int, optional
        Compression level (ZSTD 1-22, DEFLATE 1-9); default the fastest,
        not GDAL's (ZSTD 9, DEFLATE 6): :data:`geoblock.io.geotiff.FAST_LEVEL`.
    nodata : float, optional
        Nodata value written in the file; default ``data.attrs["_FillValue"]`` if present.
    scheduler : str, dask.distributed.Client or None
        ``"threads"``, ``"processes"``, ``"synchronous"``, a Client, or None (the default
        client if one exists, else dask's default scheduler).
    in_flight : int, optional
        Chunks computed ahead of the writer (bounds memory); default 2 per core, or with a
        ``dask.distributed`` Client 2 per worker thread of its cluster (else most workers
        of a cluster of N machines would wait).
    progress : bool
        Show a progress bar on standard error (a tqdm bar on a terminal; elsewhere only a
        final summary line, no carriage-return frames).
    empty : {"error", "warn", "ignore"}
        What to do when no pixel is valid (every band of every pixel is ``nodata`` or NaN:
        e.g. an ortho whose DEM does not cover the scene or whose grid misses it):
        ``"error"`` raises :class:`~geoblock.errors.EmptyOutputError` and leaves nothing
        under ``path``; ``"warn"`` writes the file and warns
        (:class:`~geoblock.errors.EmptyOutputWarning`); ``"ignore"`` writes it silently.
        Without a nodata value every pixel of an integer array is valid.
    tags : mapping of str to str, optional
        Dataset metadata items (``gdalinfo``'s Metadata), e.g. an accuracy layer's
        :func:`~geoblock.ortho.accuracy.accuracy_tags`.
    band_descriptions : sequence of str, optional
        One description per band (``gdalinfo``'s ``Description``).
    units : str, optional
        The unit of every band's values (GDAL's unit type, e.g. ``"m"``).
    **creation_options
        More GDAL creation options (``gdal_translate -co`` / ``gdalwarp -co``), keys in any
        case: ``PREDICTOR=2``, ``NUM_THREADS=ALL_CPUS``, ``BIGTIFF=YES``, ``BLOCKXSIZE``...
        They win over ``compress``, ``level`` and ``blocksize``. With ``driver="COG"`` they
        go to GDAL's COG driver (``OVERVIEWS``, ``RESAMPLING``, ``LEVEL``...), and the
        intermediate tiled GeoTIFF is written uncompressed.

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    GeoblockIOError
        The destination directory does not exist, or GDAL cannot write: one line naming
        ``path``, never the temporary; a full disk, a quota, a read-only file system or a
        missing permission in plain words (:func:`geoblock.io._atomic.write_error`).
    EmptyOutputError
        No pixel is valid and ``empty="error"``.
    """
    path = Path(path)
    if driver.upper() not in ("GTIFF", "COG"):
        raise ValueError(f"write_ortho: driver must be 'GTiff' or 'COG', got {driver!r}")
    if empty not in EMPTY:
        raise ValueError(f"write_ortho: empty must be one of {EMPTY}, got {empty!r}")
    try:
        # the directory is checked and stale temporaries of ``path`` removed on entry; ``tmp``
        # is renamed to ``path`` on success, removed on any failure
        with atomic_path(path) as tmp:
            _write_ortho(data, path, tmp, driver=driver, blocksize=blocksize,
                         compress=compress, level=level, nodata=nodata, scheduler=scheduler,
                         in_flight=in_flight, progress=progress, empty=empty,
                         creation_options=creation_options,
                         describe=(tags, band_descriptions, units))
    except GeoblockIOError as exc:
        inner = exc.__cause__
        if isinstance(inner, GeoblockIOError):  # an input's error (a source image): as it is
            raise inner from inner.__cause__
        raise
    return path


def _describe(dst: Any, bands: int, tags: Mapping[str, str] | None,
              descriptions: Sequence[str] | None, units: str | None) -> None:
    """Metadata items, band descriptions and units of a dataset open for writing."""
    if tags:
        dst.update_tags(**{str(k): str(v) for k, v in tags.items()})
    if descriptions is not None:
        if len(descriptions) != bands:
            raise ValueError(f"write_ortho: {len(descriptions)} band descriptions for "
                             f"{bands} band(s)")
        for i, text in enumerate(descriptions, start=1):
            dst.set_band_description(i, str(text))
    if units is not None:
        dst.units = (str(units),) * bands


def _is_job(data: Any) -> bool:
    """Whether ``data`` is a planned job (:class:`geoblock.ortho.OrthoJob`: chunks it computes
    itself, ``windows()``/``chunk(window)``, and its dask form, ``to_dataarray()``) rather than
    a DataArray. Duck-typed: the openers' layer does not import the engines'."""
    return all(callable(getattr(data, name, None)) for name in
               ("windows", "chunk", "to_dataarray")) and hasattr(data, "grid")


def _int_option(value: Any, key: str) -> int:
    """A creation option that must be a positive integer (a tile side)."""
    try:
        number = int(value)
    except (TypeError, ValueError):
        number = 0
    if number <= 0 or number % 16:
        raise UnsupportedFormatError(f"write_ortho: {key.upper()} must be a positive multiple "
                                     f"of 16, got {value!r}")
    return number


def _dask_blocks(data: Any, nodata: float | None, scheduler: Any, in_flight: int | None,
                 progress: bool) -> tuple[Any, ...]:
    """Georeferencing, nodata, dtype, shape and the block iterator of a ``(band, y, x)``
    DataArray (computed through dask)."""
    import dask.array as da

    if tuple(data.dims) != ("band", "y", "x"):
        raise ValueError(f"write_ortho: dims must be ('band', 'y', 'x'), got {data.dims}")
    wkt, transform, _ = dataarray_georeferencing(data)
    if nodata is None:
        nodata = data.attrs.get("_FillValue", data.encoding.get("_FillValue"))
    array = data.data
    if not isinstance(array, da.Array):
        array = da.from_array(np.asarray(array), chunks=(-1, 1024, 1024))
    if len(array.chunks[0]) != 1:
        array = array.rechunk({0: -1})
    blocks = _iter_blocks(array, scheduler, in_flight, progress)
    return wkt, transform, nodata, np.dtype(array.dtype), array.shape, blocks


def _write_ortho(data: Any, path: Path, tmp: Path, *, driver: str, blocksize: int,
                 compress: str | None, level: int | None, nodata: float | None, scheduler: Any,
                 in_flight: int | None, progress: bool, empty: str,
                 creation_options: dict[str, Any],
                 describe: tuple[Mapping[str, str] | None, Sequence[str] | None,
                                 str | None] = (None, None, None)) -> None:
    """:func:`write_ortho`'s work: the file written to ``tmp`` (the COG through a second
    temporary GeoTIFF beside it)."""
    import rasterio
    import rasterio.shutil

    from geoblock.io._atomic import _temporary_for

    cog = driver.upper() == "COG"
    user = {str(k).lower(): v for k, v in creation_options.items()}
    compression = compression_options(compress, level, cog)
    job = _is_job(data)
    if job and _local_threads(scheduler) and _distributed_client(scheduler) is None:
        # local threads: the job's chunks on a thread pool, without dask
        wkt, transform = data.grid.crs.to_wkt(), data.grid.transform
        if nodata is None:
            nodata = data.fill
        bands, rows, cols = data.shape
        dtype = data.dtype
        blocks = _iter_job(data, _local_in_flight() if in_flight is None else in_flight,
                           progress)
    else:
        if job:
            data = data.to_dataarray()
        wkt, transform, nodata, dtype, (bands, rows, cols), blocks = _dask_blocks(
            data, nodata, scheduler, in_flight, progress)
    profile: dict[str, Any] = {
        "driver": "GTiff",
        "width": cols,
        "height": rows,
        "count": bands,
        "dtype": dtype.name if dtype != np.dtype(bool) else "uint8",
        "tiled": True,
        "blockxsize": int(blocksize),
        "blockysize": int(blocksize),
        "bigtiff": "IF_SAFER",
    }
    if not cog:  # a COG's intermediate GeoTIFF is written uncompressed (GDAL compresses once)
        profile.update(compression)
        profile.update(user)
        for key in ("blockxsize", "blockysize"):
            profile[key] = _int_option(profile[key], key)
    if wkt:
        profile["crs"] = rasterio.crs.CRS.from_wkt(wkt)
    if transform is not None:
        profile["transform"] = transform
    if nodata is not None and not (isinstance(nodata, float) and math.isnan(nodata)
                                   and dtype.kind in "iub"):
        profile["nodata"] = nodata
    valid_nodata = profile.get("nodata")
    valid_nodata = None if valid_nodata is None else float(valid_nodata)
    any_valid = empty == "ignore"
    gtiff = _temporary_for(path) if cog else tmp
    try:
        with rasterio.open(gtiff, "w", **profile) as dst:
            strips = _TileRows(dst, bands, rows, cols, int(profile["blockysize"]),
                               np.dtype(profile["dtype"]))
            for r0, c0, block in blocks:
                block = np.asarray(block)
                if block.dtype == np.dtype(bool):
                    block = block.astype(np.uint8)
                if not any_valid:
                    any_valid = _has_valid(block, valid_nodata)
                strips.add(r0, c0, block)
            strips.close()
            _describe(dst, bands, *describe)
        if not any_valid:
            message = (f"{path}: no valid pixel to write: all {rows} x {cols} pixels are nodata "
                       f"({valid_nodata if valid_nodata is not None else 'NaN'})")
            if empty == "error":
                raise EmptyOutputError(message + "; nothing was written")
            warnings.warn(message + "; written anyway", EmptyOutputWarning, stacklevel=3)
        if cog:
            options = {"blocksize": int(blocksize), **compression, **user}
            rasterio.shutil.copy(gtiff, tmp, driver="COG", **options)
    finally:
        if cog:
            gtiff.unlink(missing_ok=True)



def write_image(
    path: PathLike,
    array: np.ndarray,
    *,
    nodata: float | None = None,
    compress: str | None = "deflate",
    tags: Mapping[str, str] | None = None,
    crs: Any = None,
    transform: Any = None,
) -> Path:
    """Write an in-memory image as a GeoTIFF, atomically: raw, or georeferenced.

    Without ``crs`` and ``transform`` the file has no CRS and no geotransform: pixel
    ``(row, col)`` of ``array`` is pixel ``(row, col)`` of the file, and its geometry comes
    from a sensor model (for example a model JSON beside it, :func:`~geoblock.io.write_model`).
    With them it is a map (an orthoimage, a reference rendered by the simulator).

    Parameters
    ----------
    path : str or os.PathLike
        Destination; written under a temporary name in the same directory and renamed to
        ``path`` only when complete.
    array : ndarray, (R, C) or (bands, R, C)
        Pixels of any numeric dtype GeoTIFF holds (``uint8``, ``uint16``, ``float32``...).
    nodata : float, optional
        Nodata value declared in the file.
    compress : str or None
        GDAL compression.
    tags : mapping of str to str, optional
        Dataset metadata tags.
    crs : pyproj.CRS, rasterio CRS or str, optional
        The map's CRS (with ``transform``).
    transform : affine.Affine or sequence of 6, optional
        GDAL-style geotransform (pixel corners), as rasterio's (with ``crs``).

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    ValueError
        ``array`` is not 2-D or 3-D, or only one of ``crs`` and ``transform`` is given.
    GeoblockIOError
        The directory does not exist or GDAL cannot write.
    """

    path = Path(path)
    data = np.asarray(array)
    if data.ndim == 2:
        data = data[None]
    if data.ndim != 3 or min(data.shape) < 1:
        raise ValueError(f"write_image: array must be (R, C) or (bands, R, C), got shape "
                         f"{np.shape(array)}")
    if data.dtype == np.dtype(bool):
        data = data.astype(np.uint8)
    bands, rows, cols = data.shape
    profile: dict[str, Any] = {"driver": "GTiff", "width": cols, "height": rows, "count": bands,
                               "dtype": data.dtype.name}
    if max(rows, cols) > 512:
        profile.update(tiled=True, blockxsize=256, blockysize=256)
    if compress:
        profile["compress"] = compress
    if nodata is not None:
        profile["nodata"] = nodata
    if (crs is None) != (transform is None):
        raise ValueError("write_image: give both crs and transform, or neither")
    if crs is not None:
        import rasterio
        from affine import Affine

        wkt = crs.to_wkt() if hasattr(crs, "to_wkt") else str(crs)
        profile["crs"] = rasterio.crs.CRS.from_user_input(wkt)
        profile["transform"] = transform if isinstance(transform, Affine) else \
            Affine(*tuple(transform)[:6])
    with atomic_path(path) as tmp:
        with open_quietly(tmp, "w", **profile) as dst:
            dst.write(data)
            if tags:
                dst.update_tags(**{str(k): str(v) for k, v in tags.items()})
    return path
