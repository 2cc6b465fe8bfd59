"""The per-pixel accuracy layer: the predicted horizontal error of every ortho pixel, metres.

For every output pixel centre ``(E, N)`` with its DEM height ``h``, the layer holds the radial
RMS ``sqrt(trace(C))`` of the horizontal error of the ground position the ortho shows there,
with ``C`` the east/north covariance of :func:`geoblock.models.uncertainty.ground_error`:

* the sensor model's parameter covariance (a block adjustment's posterior, carried in the
  adjusted model's JSON, or the model's a-priori statement) propagated to the ground through
  the model's partials, plus
* the DEM's height error through the viewing geometry (``sigma_DEM tan(incidence)``,
  Aguilar et al. 2007's ``sigma_ortho^2 = sigma_o^2 + (sigma_DEM tan(theta))^2``).

The field varies smoothly over the grid: it is evaluated exactly on the orthorectifier's
lattice (:mod:`geoblock.ortho.lattice`: blocks anchored to the grid, nodes at several heights
over each block's DEM range, random check points, refinement, exact fallback) and interpolated
to the pixels: bilinear in the nodes, quadratic in the height. The lattice interpolates the
logarithm of the error, so ``tolerance`` is a relative error (``0.001``: 0.1 %). Values do not
depend on the chunking, and :class:`AccuracyJob` runs the same chunk function on local threads
as through dask, so every scheduler writes the same bytes.

Pixels where the ortho has no data (no DEM height, outside the image, source nodata) are
nodata (NaN) when the ortho is given (``ortho=``): the layer then has exactly the ortho's
footprint.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from geoblock.models.uncertainty import ModelAccuracy, ModelPosterior, ground_error, model_accuracy
from geoblock.ortho._dataarrays import _coords, _fill_of, _grid_of, _valid
from geoblock.ortho.lattice import BLOCK_PX, _Context, _grid_parts, _lattice_fields

if TYPE_CHECKING:
    import xarray as xr

    from geoblock.dem.protocol import DemSource
    from geoblock.io.dem import EngineDem
    from geoblock.io.images import ImageLike, OpenedImage
    from geoblock.models.protocol import SensorModel
    from geoblock.ortho.grid import OutputGrid
    from geoblock.ortho.lattice import LatticeInfo

__all__ = ["ACCURACY_DESCRIPTION", "ACCURACY_TAG", "DEFAULT_TOLERANCE", "AccuracyJob",
           "accuracy_job", "accuracy_layer", "accuracy_path", "accuracy_tags"]

#: The tag (GeoTIFF metadata item) that names the layer's meaning; :func:`accuracy_tags`.
ACCURACY_TAG = "GEOBLOCK_ACCURACY"
#: The band description of an accuracy layer.
ACCURACY_DESCRIPTION = "predicted horizontal error (m, radial RMS)"
#: Default largest relative interpolation error of the lattice (0.1 %).
DEFAULT_TOLERANCE = 1e-3
#: The error's floor, metres (its logarithm is interpolated).
_FLOOR_M = 1e-9


def accuracy_path(output: str) -> str:
    """The default accuracy layer beside an ortho: ``<stem>_accuracy.tif``.

    Examples
    --------
    >>> accuracy_path("out/ortho.tif")
    'out/ortho_accuracy.tif'
    """
    import os

    stem, _ = os.path.splitext(output)
    return f"{stem}_accuracy.tif"


def accuracy_tags(accuracy: ModelAccuracy, dem_sigma: float, model: str = "") -> dict[str, str]:
    """The GeoTIFF metadata of an accuracy layer.

    Returns
    -------
    dict of str to str
        ``GEOBLOCK_ACCURACY`` (the meaning and unit), ``GEOBLOCK_ACCURACY_UNIT`` (``m``),
        ``GEOBLOCK_ACCURACY_COVARIANCE`` (``posterior`` or ``a-priori``),
        ``GEOBLOCK_ACCURACY_SOURCE`` (which statement), ``GEOBLOCK_ACCURACY_DEM_SIGMA``
        (metres) and, when given, ``GEOBLOCK_ACCURACY_MODEL``.
    """
    tags = {
        ACCURACY_TAG: ("predicted horizontal error (m), radial RMS sqrt(sigma_E^2 + sigma_N^2) "
                       "of each pixel's ground position: the sensor model's covariance "
                       "propagated to the ground plus the DEM error through the viewing "
                       "geometry; CE90 is 1.52 to 1.64 times it"),
        f"{ACCURACY_TAG}_UNIT": "m",
        f"{ACCURACY_TAG}_COVARIANCE": accuracy.kind,
        f"{ACCURACY_TAG}_SOURCE": accuracy.source,
        f"{ACCURACY_TAG}_DEM_SIGMA": f"{float(dem_sigma):g}",
    }
    if accuracy.left_out:
        tags[f"{ACCURACY_TAG}_LEFT_OUT"] = ", ".join(accuracy.left_out)
    if model:
        tags[f"{ACCURACY_TAG}_MODEL"] = model
    return tags


def _model_chain(model: Any) -> str:
    """``"crop of image-correction of rpc"``: the model and the models it wraps."""
    names: list[str] = []
    while model is not None and len(names) < 8:
        names.append(str(getattr(model, "name", type(model).__name__)))
        inner = getattr(model, "model", None)
        model = inner if inner is not model else None
    return " of ".join(names)


class _AccuracyContext(_Context):
    """The lattice's context with the log of the predicted error as its first field."""

    def __init__(self, model: SensorModel, dem: DemSource, grid: OutputGrid,
                 accuracy: ModelAccuracy, dem_sigma: float,
                 info: LatticeInfo | None = None) -> None:
        crs, transform, shape = _grid_parts(grid)
        super().__init__(model, dem, crs, transform, shape, info)
        self.accuracy = accuracy
        self.dem_sigma = float(dem_sigma)

    def project(self, lon: Any, lat: Any, h: Any) -> tuple[np.ndarray, np.ndarray]:
        lon, lat, h = np.broadcast_arrays(np.asarray(lon, np.float64),
                                          np.asarray(lat, np.float64),
                                          np.asarray(h, np.float64))
        acc = self.accuracy
        sigma = np.full(lon.shape, np.nan)
        ok = np.isfinite(lon) & np.isfinite(lat) & np.isfinite(h)
        if ok.any():
            err = ground_error(self.model, acc.names, acc.covariance,
                               ground=(lon[ok], lat[ok], h[ok]), dem_sigma=self.dem_sigma,
                               location_sigma_m=acc.location_sigma_m)
            sigma[ok] = err.sigma
        if self.info is not None:
            self.info.exact_points += int(lon.size)
        with np.errstate(invalid="ignore", divide="ignore"):
            field = np.log(np.maximum(sigma, _FLOOR_M))  # NaN stays NaN
        return field, np.where(np.isfinite(field), 0.0, np.nan)


def _ortho_valid(mask: OpenedImage, window: tuple[int, int, int, int]) -> np.ndarray:
    """``(R, C)`` bool: no band of the ortho is its nodata or NaN (as a reader sees it)."""
    block = np.asarray(mask.read(window))
    bad = np.zeros(block.shape[1:], bool)
    if block.dtype.kind == "f":
        bad |= np.isnan(block).any(axis=0)
    nodata = mask.nodata
    if nodata is not None and not (isinstance(nodata, float) and math.isnan(nodata)):
        bad |= (block == nodata).any(axis=0)
    return ~bad


def accuracy_chunk(
    model: SensorModel,
    accuracy: ModelAccuracy,
    dem: DemSource,
    dem_sigma: float,
    grid: OutputGrid,
    window: tuple[int, int, int, int],
    tolerance: float,
    block_px: int = BLOCK_PX,
    mask: OpenedImage | None = None,
    info: LatticeInfo | None = None,
) -> np.ndarray:
    """One chunk of the accuracy layer (the dask task): ``(1, R, C)`` float32 metres, NaN
    where invalid (no DEM height, the model does not project, ``mask`` has nodata)."""
    r0, r1, c0, c1 = window
    ctx = _AccuracyContext(model, dem, grid, accuracy, dem_sigma, info)
    field, _, valid = _lattice_fields(ctx, tolerance_px=tolerance,
                                      window=(slice(r0, r1), slice(c0, c1)), block_px=block_px)
    with np.errstate(invalid="ignore", over="ignore"):
        out = np.exp(field).astype(np.float32)
    if mask is not None:
        valid &= _ortho_valid(mask, window)
    out[~valid] = np.nan
    return out[None]


@dataclass(frozen=True, eq=False)
class AccuracyJob:
    """One accuracy layer, planned (see :func:`accuracy_job`): what
    :func:`geoblock.io.write_ortho` writes like an :class:`~geoblock.ortho.OrthoJob`.

    Attributes
    ----------
    model : SensorModel
    accuracy : ModelAccuracy
        The covariance propagated (:func:`~geoblock.models.uncertainty.model_accuracy`).
    dem : DemSource
    dem_sigma : float
        Standard deviation of the DEM heights, metres.
    grid : OutputGrid
        The full output grid.
    tolerance : float
        Largest relative interpolation error of the lattice.
    block_px : int
    mask : ImageSource or None
        An ortho on ``grid`` whose nodata pixels are nodata in the layer.
    row_chunks, col_chunks : tuple of (start, stop)
    fill : float
        NaN, the layer's nodata.
    """

    model: SensorModel
    accuracy: ModelAccuracy
    dem: DemSource
    dem_sigma: float
    grid: OutputGrid
    tolerance: float
    block_px: int
    mask: OpenedImage | None
    row_chunks: tuple[tuple[int, int], ...]
    col_chunks: tuple[tuple[int, int], ...]
    fill: float = float("nan")

    @property
    def shape(self) -> tuple[int, int, int]:
        """``(1, rows, cols)``."""
        return (1, int(self.grid.shape[0]), int(self.grid.shape[1]))

    @property
    def dtype(self) -> np.dtype:
        """float32."""
        return np.dtype(np.float32)

    @property
    def tags(self) -> dict[str, str]:
        """The GeoTIFF metadata (:func:`accuracy_tags`)."""
        return accuracy_tags(self.accuracy, self.dem_sigma, _model_chain(self.model))

    def windows(self) -> list[tuple[int, int, int, int]]:
        """Every chunk's ``(row_start, row_stop, col_start, col_stop)``, row-major order."""
        return [(ra, rb, ca, cb) for ra, rb in self.row_chunks for ca, cb in self.col_chunks]

    def chunk(self, window: tuple[int, int, int, int]) -> np.ndarray:
        """Compute one chunk, ``(1, R, C)`` float32."""
        return accuracy_chunk(self.model, self.accuracy, self.dem, self.dem_sigma, self.grid,
                              window, self.tolerance, self.block_px, self.mask)

    def to_dataarray(self) -> xr.DataArray:
        """The lazy ``(band, y, x)`` DataArray: one dask task per chunk, keys
        ``accuracy-<tokenize(inputs)>``; ``attrs`` holds the tags."""
        import dask.array as da
        import xarray as xr
        from dask.base import tokenize
        from dask.highlevelgraph import HighLevelGraph

        rc, cc = self.row_chunks, self.col_chunks
        args = (self.model, self.accuracy, self.dem, self.dem_sigma, self.grid)
        name = "accuracy-" + tokenize(*args, self.tolerance, self.block_px, self.mask, rc, cc)
        dsk: dict[Any, Any] = {}
        for i, (ra, rb) in enumerate(rc):
            for j, (ca, cb) in enumerate(cc):
                dsk[(name, 0, i, j)] = (accuracy_chunk, *args, (ra, rb, ca, cb),
                                        self.tolerance, self.block_px, self.mask)
        graph = HighLevelGraph.from_collections(name, dsk, dependencies=())
        array = da.Array(graph, name, chunks=((1,), tuple(b - a for a, b in rc),
                                              tuple(b - a for a, b in cc)),
                         dtype=np.float32)
        return xr.DataArray(
            array, dims=("band", "y", "x"), coords=_coords(self.grid, 1, self.fill),
            attrs={"_FillValue": self.fill, "grid_mapping": "spatial_ref", "units": "m",
                   "long_name": ACCURACY_DESCRIPTION, "tags": self.tags},
            name="accuracy")


def _dem_sigma(value: Any) -> float:
    try:
        sigma = float(value)
    except (TypeError, ValueError):
        sigma = float("nan")
    if isinstance(value, bool) or not (math.isfinite(sigma) and sigma >= 0):
        raise ValueError(f"accuracy layer: dem_sigma must be a finite number of metres >= 0 "
                         f"(the DEM heights' standard deviation), got {value!r}")
    return sigma


def accuracy_job(
    model: SensorModel,
    dem: EngineDem,
    grid: OutputGrid | None = None,
    *,
    dem_sigma: float,
    posterior: ModelPosterior | None = None,
    ortho: ImageLike | None = None,
    tolerance: float = DEFAULT_TOLERANCE,
    chunks: int | tuple[int, int] = 1024,
    block_px: int = BLOCK_PX,
) -> AccuracyJob:
    """Plan an accuracy layer: :func:`accuracy_layer`'s arguments checked, the grid cut into
    chunks, nothing computed (the default grid aside).

    Parameters
    ----------
    model, dem, grid, dem_sigma, posterior, tolerance, chunks, block_px
        As :func:`accuracy_layer`.
    ortho : str, os.PathLike or an opened image, optional
        A raster ortho on ``grid`` (e.g. the file ``geoblock ortho`` wrote) whose nodata
        pixels are nodata in the layer (read chunk by chunk).

    Returns
    -------
    AccuracyJob

    Raises
    ------
    NoAccuracyError
        The model states no accuracy (:func:`~geoblock.models.uncertainty.model_accuracy`).
    ValueError
        A ``dem_sigma`` that is not a finite number >= 0, a negative ``tolerance``.
    GridError
        ``ortho`` is not on ``grid``.
    """
    from geoblock.dem.intersect import as_dem_source
    from geoblock.ortho.grid import OutputGrid

    sigma = _dem_sigma(dem_sigma)
    if not tolerance >= 0:
        raise ValueError(f"accuracy layer: tolerance must be >= 0, got {tolerance!r}")
    accuracy = model_accuracy(model, posterior)
    dem = as_dem_source(dem)
    if grid is None:
        grid = OutputGrid.for_model(model, dem)
    mask = None
    if ortho is not None:
        from geoblock.io.images import open_image

        mask = open_image(ortho)
        _check_same_grid(grid, mask.crs, mask.transform, mask.shape, str(mask.path))
    windows = grid.chunks(chunks)
    row_chunks = tuple(dict.fromkeys((w[0].start, w[0].stop) for w in windows))
    col_chunks = tuple(dict.fromkeys((w[1].start, w[1].stop) for w in windows))
    return AccuracyJob(model, accuracy, dem, sigma, grid, float(tolerance), int(block_px), mask,
                       row_chunks, col_chunks)


def _check_same_grid(grid: OutputGrid, crs: Any, transform: Any, shape: Any,
                     what: str) -> None:
    import pyproj

    from geoblock.errors import GridError

    same = (crs is not None and transform is not None
            and tuple(int(v) for v in shape) == tuple(int(v) for v in grid.shape)
            and pyproj.CRS.from_user_input(crs.to_wkt() if hasattr(crs, "to_wkt") else crs)
            == grid.crs
            and all(abs(a - b) <= 1e-9 * max(1.0, abs(b))
                    for a, b in zip(tuple(transform)[:6], tuple(grid.transform)[:6],
                                    strict=True)))
    if not same:
        raise GridError(f"accuracy layer: the ortho {what} is not on the layer's grid "
                        f"({grid.shape[0]} x {grid.shape[1]} px, {grid.transform!r})")


def accuracy_layer(
    model: SensorModel,
    dem: EngineDem,
    grid: OutputGrid | None = None,
    *,
    dem_sigma: float,
    posterior: ModelPosterior | None = None,
    ortho: xr.DataArray | ImageLike | None = None,
    tolerance: float = DEFAULT_TOLERANCE,
    chunks: int | tuple[int, int] = 1024,
    block_px: int = BLOCK_PX,
) -> xr.DataArray:
    """The predicted horizontal error of every pixel of an output grid: a lazy layer.

    Parameters
    ----------
    model : SensorModel
        The image's sensor model (after an adjustment: the adjusted model).
    dem : DemSource, float, or anything geoblock.open_dem opens
        The ortho's terrain heights above the WGS84 ellipsoid.
    grid : OutputGrid, optional
        The ortho's grid; default :meth:`OutputGrid.for_model(model, dem)
        <geoblock.ortho.grid.OutputGrid.for_model>`, as :func:`~geoblock.ortho.orthorectify`.
    dem_sigma : float
        Standard deviation of the DEM's heights, metres (>= 0). Required: the DEM's error is
        most of an ortho's error in steep terrain and off-nadir views, and no default is
        right for every DEM.
    posterior : ModelPosterior, optional
        The model's posterior covariance (:func:`geoblock.io.read_model_posterior` of an
        adjusted model's JSON); default the model's a-priori statement
        (:func:`~geoblock.models.uncertainty.model_accuracy`).
    ortho : xarray.DataArray, path or opened image, optional
        The ortho on ``grid`` (:func:`~geoblock.ortho.orthorectify`'s lazy result, or a
        file): its nodata pixels are nodata in the layer. A DataArray is combined lazily (the
        graph shares its tasks: computing both together computes each ortho chunk once).
    tolerance : float
        Largest relative interpolation error of the lattice at its check points (``0``:
        every pixel evaluated exactly).
    chunks : int or (int, int)
        Output chunk, pixels; the values do not depend on it.
    block_px : int
        Lattice block side, output pixels (a power of two).

    Returns
    -------
    xarray.DataArray, (band, y, x) with one band, float32
        Metres; NaN where the ortho has no data (or, without ``ortho``, where there is no DEM
        height or the model does not project). Coordinates as
        :func:`~geoblock.ortho.orthorectify`'s; ``attrs["tags"]`` holds the GeoTIFF metadata
        (:func:`accuracy_tags`): ``write_ortho(layer, path, tags=layer.attrs["tags"],
        band_descriptions=[ACCURACY_DESCRIPTION])`` writes it.

    Raises
    ------
    NoAccuracyError
        The model states no accuracy: no posterior, no finite a-priori sigma, no stated
        location accuracy (adjust it first).
    ValueError
        ``dem_sigma`` missing or not a finite number >= 0.
    GridError
        ``ortho`` is not on ``grid``.

    Examples
    --------
    >>> ortho, accuracy = orthorectify(image, model, dem, accuracy=True,
    ...                                dem_sigma=4.0)  # doctest: +SKIP
    >>> layer = accuracy_layer(model, dem, ortho.grid, dem_sigma=4.0)  # doctest: +SKIP
    """
    import xarray as xr

    if isinstance(ortho, xr.DataArray):
        job = accuracy_job(model, dem, grid, dem_sigma=dem_sigma, posterior=posterior,
                           tolerance=tolerance, chunks=chunks, block_px=block_px)
        g = _grid_of(ortho, 0)
        _check_same_grid(job.grid, g.crs, g.transform, g.shape, "DataArray")
        layer = job.to_dataarray()
        import dask.array as da

        data = ortho.data if isinstance(ortho.data, da.Array) else da.from_array(
            np.asarray(ortho.data), chunks=(-1,) + layer.data.chunks[1:])
        valid = _valid(data, _fill_of(ortho)).rechunk(layer.data.chunks[1:])
        masked = da.where(valid[None], layer.data, np.float32(np.nan))
        return layer.copy(data=masked)
    return accuracy_job(model, dem, grid, dem_sigma=dem_sigma, posterior=posterior,
                        ortho=ortho, tolerance=tolerance, chunks=chunks,
                        block_px=block_px).to_dataarray()
