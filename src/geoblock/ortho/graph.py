"""``orthorectify``: a lazy, dask-chunked orthoimage as an ``xarray.DataArray``; ``ortho_job``:
the same chunks without dask.

:func:`ortho_job` checks the inputs and cuts the output grid into chunks (an
:class:`OrthoJob`); :func:`orthorectify` turns the job into a dask graph wrapped in a
DataArray, and :func:`geoblock.io.write_ortho` on local threads runs the job's chunks on a
thread pool directly (no dask or xarray import: a command's start-up). Both run
:func:`ortho_chunk` on the same arguments.

The graph has one task per output chunk and no dependencies between tasks. A task receives
only picklable values - the image (an :class:`~geoblock.io.images.ImageSource`, by path, or
an :class:`~geoblock.io.images.ArrayImage` with its pixels), the model (pickled through
``to_dict``), the DEM (by path or value), the **full** output grid and the chunk's window -
and:

1. computes the source coordinates of its pixels (:func:`~geoblock.ortho.lattice.
   source_coordinates`, the lattice anchored to the full grid, so values do not depend on the
   chunking);
2. reads the source window they need: the bounding box of the finite coordinates padded by
   ``KERNEL_RADIUS[kernel] + 1`` pixels, clipped to the image (nothing if it is empty);
3. resamples and casts to the source dtype in one pass
   (:func:`~geoblock.ortho.kernels.resample_cast`), ``nodata`` where invalid.

Keys are ``ortho-<tokenize(inputs)>``: the same inputs give the same graph.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal, overload

import numpy as np

from geoblock._array import finite_bounds
from geoblock.dem.intersect import as_dem_source
from geoblock.ortho._dataarrays import _coords
from geoblock.ortho.kernels import KERNEL_RADIUS, cast, resample_cast
from geoblock.ortho.lattice import BLOCK_PX, source_coordinates

if TYPE_CHECKING:
    import xarray as xr

    from geoblock.dem.protocol import DemSource
    from geoblock.io.dem import EngineDem
    from geoblock.io.images import ImageLike, OpenedImage
    from geoblock.models.protocol import SensorModel
    from geoblock.models.uncertainty import ModelPosterior
    from geoblock.ortho.grid import OutputGrid

__all__ = ["OrthoJob", "ortho_chunk", "ortho_job", "orthorectify"]


def _default_fill(dtype: np.dtype, source_nodata: float | None) -> float:
    if source_nodata is not None:
        return source_nodata
    return float("nan") if dtype.kind == "f" else 0


def ortho_chunk(
    image: OpenedImage,
    model: SensorModel,
    dem: DemSource,
    grid: OutputGrid,
    window: tuple[int, int, int, int],
    kernel: str,
    tolerance_px: float,
    fill: float,
    block_px: int = BLOCK_PX,
) -> np.ndarray:
    """Orthorectify one chunk (the dask task).

    Parameters
    ----------
    image : ImageSource or ArrayImage
        The source image (read inside the task, only the window needed).
    model : SensorModel
    dem : DemSource
    grid : OutputGrid
        The full output grid.
    window : (row_start, row_stop, col_start, col_stop)
        The chunk, output pixels.
    kernel : {"nearest", "bilinear", "bicubic", "sinc"}
    tolerance_px : float
        Lattice tolerance, source pixels (0: exact per pixel).
    fill : scalar
        Output value of invalid pixels.
    block_px : int
        Lattice block side (see :func:`~geoblock.ortho.lattice.source_coordinates`).

    Returns
    -------
    ndarray, (bands, R, C)
        Of the image's dtype.
    """
    r0, r1, c0, c1 = window
    dtype = np.dtype(image.dtype)
    row, col, _valid = source_coordinates(
        model, dem, grid, tolerance_px=tolerance_px,
        window=(slice(r0, r1), slice(c0, c1)), block_px=block_px,
    )
    out_shape = (image.bands, r1 - r0, c1 - c0)
    rows, cols = image.shape
    pad = KERNEL_RADIUS[kernel] + 1
    # row/col are NaN exactly where not valid: skipped without a gather
    r_lo, r_hi, c_lo, c_hi = finite_bounds(row, col)
    if math.isfinite(r_lo) and math.isfinite(c_lo):
        wr0 = max(math.floor(r_lo) - pad, 0)
        wr1 = min(math.ceil(r_hi) + pad + 1, rows)
        wc0 = max(math.floor(c_lo) - pad, 0)
        wc1 = min(math.ceil(c_hi) + pad + 1, cols)
    else:
        wr0 = wr1 = wc0 = wc1 = 0
    if wr1 <= wr0 or wc1 <= wc0:
        return cast(np.full(out_shape, np.nan), np.zeros(out_shape[1:], bool), dtype, fill)
    src = image.read((wr0, wr1, wc0, wc1))
    # subtracting the window origin (an integer) is exact: values do not depend on it
    row -= wr0
    col -= wc0
    out, _ = resample_cast(src, row, col, kernel, dtype, fill, nodata=image.nodata)
    return out


@dataclass(frozen=True, eq=False)
class OrthoJob:
    """One orthorectification, planned: its inputs and its output chunks (see :func:`ortho_job`).

    Attributes
    ----------
    image : ImageSource or ArrayImage
    model : SensorModel
        Reconciled with the image (crop offset applied).
    dem : DemSource
    grid : OutputGrid
        The full output grid.
    kernel : str
    tolerance_px : float
        Lattice tolerance, source pixels.
    fill : float
        Output value of invalid pixels (the file's nodata).
    block_px : int
        Lattice block side, output pixels.
    row_chunks, col_chunks : tuple of (start, stop)
        The chunks' output rows and columns; the chunks are their product.
    """

    image: OpenedImage
    model: SensorModel
    dem: DemSource
    grid: OutputGrid
    kernel: str
    tolerance_px: float
    fill: float
    block_px: int
    row_chunks: tuple[tuple[int, int], ...]
    col_chunks: tuple[tuple[int, int], ...]

    @property
    def shape(self) -> tuple[int, int, int]:
        """``(bands, rows, cols)`` of the output."""
        return (self.image.bands, int(self.grid.shape[0]), int(self.grid.shape[1]))

    @property
    def dtype(self) -> np.dtype:
        """The output's dtype (the image's)."""
        return np.dtype(self.image.dtype)

    def windows(self) -> list[tuple[int, int, int, int]]:
        """Every chunk's ``(row_start, row_stop, col_start, col_stop)``, row-major order."""
        return [(ra, rb, ca, cb) for ra, rb in self.row_chunks for ca, cb in self.col_chunks]

    def chunk(self, window: tuple[int, int, int, int]) -> np.ndarray:
        """Compute one chunk: :func:`ortho_chunk` on this job's inputs, ``(bands, R, C)``."""
        return ortho_chunk(self.image, self.model, self.dem, self.grid, window, self.kernel,
                           self.tolerance_px, self.fill, self.block_px)

    def to_dataarray(self) -> xr.DataArray:
        """The lazy ``(band, y, x)`` DataArray of :func:`orthorectify`: one dask task per
        chunk, no dependencies, keys ``ortho-<tokenize(inputs)>``."""
        import dask.array as da
        import xarray as xr
        from dask.base import tokenize
        from dask.highlevelgraph import HighLevelGraph

        src, rc, cc = self.image, self.row_chunks, self.col_chunks
        args = (self.model, self.dem, self.grid)
        name = "ortho-" + tokenize(src, *args, self.kernel, self.tolerance_px, self.fill,
                                   self.block_px, rc, cc)
        dsk: dict[Any, Any] = {}
        for i, (ra, rb) in enumerate(rc):
            for j, (ca, cb) in enumerate(cc):
                dsk[(name, 0, i, j)] = (ortho_chunk, src, *args, (ra, rb, ca, cb), self.kernel,
                                        self.tolerance_px, self.fill, self.block_px)
        graph = HighLevelGraph.from_collections(name, dsk, dependencies=())
        array = da.Array(graph, name,
                         chunks=((src.bands,), tuple(b - a for a, b in rc),
                                 tuple(b - a for a, b in cc)),
                         dtype=self.dtype)
        return xr.DataArray(
            array, dims=("band", "y", "x"), coords=_coords(self.grid, src.bands, self.fill),
            attrs={"_FillValue": self.fill, "grid_mapping": "spatial_ref"}, name="ortho",
        )


@overload
def orthorectify(
    image: ImageLike, model: SensorModel, dem: EngineDem, grid: OutputGrid | None = None, *,
    kernel: str = ..., tolerance_px: float = ..., chunks: int | tuple[int, int] = ...,
    nodata: float | None = ..., block_px: int = ...,
    crop_offset: tuple[float, float] | None = ..., crop: bool = ...,
    accuracy: Literal[False] = ..., dem_sigma: float | None = ...,
    posterior: ModelPosterior | None = ...,
) -> xr.DataArray: ...


@overload
def orthorectify(
    image: ImageLike, model: SensorModel, dem: EngineDem, grid: OutputGrid | None = None, *,
    kernel: str = ..., tolerance_px: float = ..., chunks: int | tuple[int, int] = ...,
    nodata: float | None = ..., block_px: int = ...,
    crop_offset: tuple[float, float] | None = ..., crop: bool = ...,
    accuracy: Literal[True], dem_sigma: float | None = ...,
    posterior: ModelPosterior | None = ...,
) -> tuple[xr.DataArray, xr.DataArray]: ...


def orthorectify(
    image: ImageLike,
    model: SensorModel,
    dem: EngineDem,
    grid: OutputGrid | None = None,
    *,
    kernel: str = "bilinear",
    tolerance_px: float = 0.01,
    chunks: int | tuple[int, int] = 1024,
    nodata: float | None = None,
    block_px: int = BLOCK_PX,
    crop_offset: tuple[float, float] | None = None,
    crop: bool = True,
    accuracy: bool = False,
    dem_sigma: float | None = None,
    posterior: ModelPosterior | None = None,
) -> xr.DataArray | tuple[xr.DataArray, xr.DataArray]:
    """Orthorectify an image: a lazy ``(band, y, x)`` DataArray on an output grid.

    Building the result computes nothing (the default grid aside, which projects the scene
    outline): every chunk is one task run at ``.compute()``, ``write_ortho`` or
    ``.to_raster``.

    Parameters
    ----------
    image : str, os.PathLike, ImageSource, rasterio dataset, xarray.DataArray or ndarray
        The source image: any raster file rasterio reads, or pixels in memory (an open
        rasterio dataset, a ``(band, y, x)`` DataArray, a ``(bands, R, C)`` or ``(R, C)``
        numpy array in the sensor's geometry; :func:`geoblock.io.open_image` says how each
        is taken, and takes a nodata value for arrays). Bands, dtype and nodata are kept; the
        result is the same, value for value, whichever form the pixels come in.
    model : SensorModel
        The image's sensor model (ground -> image through ``project_with_status``).
    dem : DemSource, float, or anything geoblock.open_dem opens
        Terrain heights above the WGS84 ellipsoid (:func:`geoblock.open_dem`); a number is a
        constant height, a path or opened raster is opened with ``open_dem``'s defaults.
    grid : OutputGrid, optional
        Default :meth:`OutputGrid.for_model(model, dem) <geoblock.ortho.grid.OutputGrid.for_model>`
        (UTM zone, GSD rounded to a nice number, footprint, aligned, checked).
    kernel : {"nearest", "bilinear", "bicubic", "sinc"}
        Resampling kernel.
    tolerance_px : float
        Largest lattice interpolation error accepted at the check points, source pixels;
        ``0`` projects every output pixel exactly.
    chunks : int or (int, int)
        Output chunk ``(rows, cols)``, pixels. The values do not depend on it.
    nodata : float, optional
        Output value of pixels with no source (outside the image, no DEM height, source
        nodata); default the source nodata, else NaN for float images and 0 for integers.
    block_px : int
        Lattice block side, output pixels (a power of two).
    crop_offset : (float, float), optional
        ``(row0, col0)``: the image is the crop of ``model``'s scene whose first pixel is
        scene pixel ``(row0, col0)``; default: as the image's pixel-unit geotransform states
        it, if it does (:func:`~geoblock.models.crop.model_for_image`).
    crop : bool
        False: use ``model`` as it is, image pixel ``(r, c)`` being model pixel ``(r, c)``
        (no crop offset, no shape check; e.g. a model already reconciled with the image).
    accuracy : bool
        Also return the ortho's accuracy layer
        (:func:`~geoblock.ortho.accuracy.accuracy_layer`: the predicted horizontal error of
        every pixel, metres, NaN where the ortho has no data).
    dem_sigma : float, optional
        The DEM heights' standard deviation, metres; required with ``accuracy=True``.
    posterior : ModelPosterior, optional
        The model's posterior covariance (:func:`geoblock.io.read_model_posterior`) for the
        accuracy layer; default the model's a-priori statement.

    Returns
    -------
    xarray.DataArray, (band, y, x)
        Dask-backed, of the image's dtype. Coordinates ``band`` (1..n), ``y`` and ``x``
        (pixel centres, CRS units) and ``spatial_ref`` (attributes ``crs_wkt`` and
        ``GeoTransform``, as rioxarray reads them); ``attrs["_FillValue"]`` is ``nodata``.
        With ``accuracy=True``, the pair ``(ortho, accuracy_layer)``.

    Raises
    ------
    InputTypeError
        ``image`` or ``dem`` is of a kind geoblock cannot read (the message names it).
    GeoblockIOError, DemError
        The image or the DEM cannot be opened.
    CropError
        The image and the model do not fit (shapes, crop offset).
    NoAccuracyError
        ``accuracy=True`` and the model states no accuracy.
    ValueError
        ``accuracy=True`` without a ``dem_sigma``.
    """
    job = ortho_job(image, model, dem, grid, kernel=kernel, tolerance_px=tolerance_px,
                    chunks=chunks, nodata=nodata, block_px=block_px, crop_offset=crop_offset,
                    crop=crop)
    ortho = job.to_dataarray()
    if not accuracy:
        return ortho
    from geoblock.ortho.accuracy import accuracy_layer

    if dem_sigma is None:
        raise ValueError("orthorectify: accuracy=True needs dem_sigma= (the DEM heights' "
                         "standard deviation, metres)")
    layer = accuracy_layer(job.model, job.dem, job.grid, dem_sigma=dem_sigma,
                           posterior=posterior, ortho=ortho, chunks=chunks, block_px=block_px)
    return ortho, layer


def ortho_job(
    image: ImageLike,
    model: SensorModel,
    dem: EngineDem,
    grid: OutputGrid | None = None,
    *,
    kernel: str = "bilinear",
    tolerance_px: float = 0.01,
    chunks: int | tuple[int, int] = 1024,
    nodata: float | None = None,
    block_px: int = BLOCK_PX,
    crop_offset: tuple[float, float] | None = None,
    crop: bool = True,
) -> OrthoJob:
    """Plan an orthorectification: the inputs checked and the output cut into chunks.

    Takes :func:`orthorectify`'s arguments and computes nothing (the default grid aside,
    which projects the scene outline). The :class:`OrthoJob` runs its chunks itself
    (:meth:`OrthoJob.chunk`, what :func:`geoblock.io.write_ortho` does on local threads:
    no dask graph, no dask or xarray import) or becomes :func:`orthorectify`'s DataArray
    (:meth:`OrthoJob.to_dataarray`: dask processes, dask.distributed); both run the same
    chunk function on the same arguments, so they give the same values.

    Parameters
    ----------
    image, model, dem, grid, kernel, tolerance_px, chunks, nodata, block_px, crop_offset, crop
        As :func:`orthorectify`.

    Returns
    -------
    OrthoJob

    Raises
    ------
    InputTypeError
        ``image`` or ``dem`` is of a kind geoblock cannot read (the message names it).
    GeoblockIOError, DemError
        The image or the DEM cannot be opened.
    CropError
        The image and the model do not fit (shapes, crop offset).
    """
    from geoblock.io.images import open_image
    from geoblock.models.crop import model_for_image
    from geoblock.ortho.grid import OutputGrid
    from geoblock.ortho.kernels import KERNELS

    if kernel not in KERNELS:
        raise ValueError(f"orthorectify: kernel must be one of {KERNELS}, got {kernel!r}")
    if not tolerance_px >= 0:
        raise ValueError(f"orthorectify: tolerance_px must be >= 0, got {tolerance_px}")
    src = open_image(image)
    dem = as_dem_source(dem)
    # a crop of a scene (pixel-unit geotransform) addresses the scene model at its offset; an
    # image whose shape differs from the model's with no crop information is refused
    model = model_for_image(model, src, crop_offset=crop_offset, crop=crop)
    if grid is None:
        grid = OutputGrid.for_model(model, dem)
    dtype = np.dtype(src.dtype)
    fill = _default_fill(dtype, src.nodata) if nodata is None else nodata
    windows = grid.chunks(chunks)
    row_chunks = tuple(dict.fromkeys((w[0].start, w[0].stop) for w in windows))
    col_chunks = tuple(dict.fromkeys((w[1].start, w[1].stop) for w in windows))
    return OrthoJob(src, model, dem, grid, kernel, float(tolerance_px), fill, int(block_px),
                    row_chunks, col_chunks)
