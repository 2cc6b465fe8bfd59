"""Mosaics of orthoimages: priority or distance-weighted feathering, with a contribution band.

:func:`mosaic` puts several orthos (lazy ``(band, y, x)`` DataArrays as
:func:`~geoblock.ortho.graph.orthorectify` returns them, or ``(image, model)`` pairs that it
orthorectifies itself) onto one grid and returns an :class:`xarray.Dataset` with

* ``mosaic`` - ``(band, y, x)``, the mosaicked values, and
* ``contribution`` - ``(y, x)``, ``uint8`` (``uint16`` beyond 255 sources): ``k`` where the
  pixel came from ``sources[k - 1]`` (for feathering: the source with the largest weight),
  ``0`` where no source has a valid pixel - the block mosaics of Teo et al. (Fig. 13).

Nothing is reprojected or resampled: every source must be on a grid of the same CRS, the same
resolution and the same pixel phase (its pixel edges on the output grid's), so a source is
placed by an integer pixel offset. A source pixel is *valid* when none of its bands is the
source's nodata (``attrs["_FillValue"]``) or NaN.

Methods
-------
``priority``
    The first source (in the order given) with a valid pixel wins.
``feather``
    Each valid source pixel gets the weight ``w = min(d, feather_px)``, ``d`` the Euclidean
    distance, in pixels, from its centre to the centre of the nearest invalid pixel of the same
    source (pixels outside a source's own grid are invalid; a valid pixel next to an invalid
    one has ``d = 1``). The output is ``sum(w_k v_k) / sum(w_k)`` (float64, then rounded half
    away from zero and clipped for integer outputs); where a single source is valid its value
    is copied unchanged. The distance is computed per chunk with a halo of
    ``ceil(feather_px)`` pixels (``dask.array.map_overlap``), which holds every invalid pixel
    closer than the cap: the result is exact and identical, byte for byte, whatever the
    chunking.

:func:`open_ortho` reads a georeferenced GeoTIFF as such a lazy DataArray (what ``geoblock
mosaic`` does with its inputs).
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from geoblock.errors import MosaicError  # defined there; importable from here as before
from geoblock.ortho._dataarrays import _coords, _fill_of, _grid_of, _valid

if TYPE_CHECKING:
    import dask.array as da
    import xarray as xr
    from numpy.typing import DTypeLike

    from geoblock.io.dem import EngineDem
    from geoblock.io.images import ImageLike, OpenedImage
    from geoblock.models.protocol import SensorModel
    from geoblock.ortho.grid import OutputGrid

__all__ = ["MosaicError", "mosaic", "open_ortho"]

METHODS = ("priority", "feather")

#: largest misalignment of a source's pixel edges on the output grid, pixels
_PHASE_TOL = 1e-6
#: largest relative difference of resolutions taken as equal
_RES_RTOL = 1e-9


# ---------------------------------------------------------------------- inputs
def _offset(grid: OutputGrid, ref: OutputGrid, index: int) -> tuple[int, int]:
    """Integer ``(row, col)`` of ``grid``'s first pixel on ``ref``; raises unless aligned."""
    if not grid.crs == ref.crs:
        raise MosaicError(
            f"mosaic: source {index + 1} is in another CRS ({grid.crs.name!r}, not "
            f"{ref.crs.name!r}); mosaic does not reproject: warp it onto the same CRS first")
    for mine, theirs in zip(grid.resolution, ref.resolution, strict=True):
        if abs(mine - theirs) > _RES_RTOL * max(abs(mine), abs(theirs)):
            raise MosaicError(
                f"mosaic: source {index + 1} has resolution {grid.resolution}, not "
                f"{ref.resolution}; mosaic does not resample: make the orthos at one resolution "
                "(geoblock ortho's default rounds the GSD, or pass the same --res to each) or "
                "warp them onto it")
    t, r = grid.transform, ref.transform
    col = (t.c - r.c) / r.a
    row = (t.f - r.f) / r.e
    icol, irow = round(col), round(row)
    if abs(col - icol) > _PHASE_TOL or abs(row - irow) > _PHASE_TOL:
        raise MosaicError(
            f"mosaic: source {index + 1} is not pixel-aligned with the others (offset "
            f"{row:.6f}, {col:.6f} px); mosaic does not resample: use grids whose origins "
            "differ by whole pixels (e.g. OutputGrid.from_bounds(..., align=True))")
    return irow, icol


def _union_grid(grids: Sequence[OutputGrid]) -> OutputGrid:
    from affine import Affine

    from geoblock.ortho.grid import OutputGrid

    ref = grids[0]
    offsets = [_offset(g, ref, i) for i, g in enumerate(grids)]
    r0 = min(o[0] for o in offsets)
    c0 = min(o[1] for o in offsets)
    r1 = max(o[0] + g.shape[0] for o, g in zip(offsets, grids, strict=True))
    c1 = max(o[1] + g.shape[1] for o, g in zip(offsets, grids, strict=True))
    t = ref.transform
    return OutputGrid(ref.crs, Affine(t.a, 0.0, t.c + t.a * c0, 0.0, t.e, t.f + t.e * r0),
                      (r1 - r0, c1 - c0))


def _chunk_pair(chunks: int | tuple[int, int]) -> tuple[int, int]:
    """``(rows, cols)`` of a chunk given as one side or a pair."""
    if isinstance(chunks, int | float | np.number):
        return int(chunks), int(chunks)
    rows, cols = chunks
    return int(rows), int(cols)


def _chunk_tuple(n: int, size: int) -> tuple[int, ...]:
    return tuple(min(size, n - s) for s in range(0, n, size))


# ---------------------------------------------------------------------- per-source arrays
def _place(array: da.Array, offset: tuple[int, int], shape: tuple[int, int], pad: int,
           value: float | bool) -> da.Array:
    """``array`` (..., h, w) placed at ``offset`` on a ``shape`` grid grown by ``pad`` pixels
    on every side; ``value`` elsewhere."""
    import dask.array as da

    lead = array.shape[:-2]
    h, w = array.shape[-2:]
    rows, cols = shape[0] + 2 * pad, shape[1] + 2 * pad
    orow, ocol = offset[0] + pad, offset[1] + pad
    ra, rb = max(orow, 0), min(orow + h, rows)
    ca, cb = max(ocol, 0), min(ocol + w, cols)
    if rb <= ra or cb <= ca:
        return da.full(lead + (rows, cols), value, dtype=array.dtype)
    sub = array[..., ra - orow:rb - orow, ca - ocol:cb - ocol]
    widths = [(0, 0)] * len(lead) + [(ra, rows - rb), (ca, cols - cb)]
    if any(p for pair in widths for p in pair):
        sub = da.pad(sub, widths, mode="constant", constant_values=value)
    return sub


def _capped_distance(mask: np.ndarray, cap: float) -> np.ndarray:
    """Euclidean distance (pixels) of every pixel to the nearest ``False`` one, capped."""
    from scipy import ndimage

    if mask.size == 0:
        return np.zeros(mask.shape)
    if mask.all():
        return np.full(mask.shape, float(cap))
    if not mask.any():
        return np.zeros(mask.shape)
    return np.minimum(ndimage.distance_transform_edt(mask), float(cap))


def _weights(mask_padded: da.Array, halo: int, cap: float, shape: tuple[int, int]) -> da.Array:
    """Feather weights on the output grid from a mask on the grid grown by ``halo``."""
    import dask.array as da

    dist = da.map_overlap(
        _capped_distance, mask_padded, depth=halo, boundary="none", trim=True,
        allow_rechunk=True, dtype=np.float64, meta=np.empty((0, 0), np.float64), cap=cap,
    )
    return dist[halo:halo + shape[0], halo:halo + shape[1]]


# ---------------------------------------------------------------------- block functions
def _cast_block(values: np.ndarray, valid: np.ndarray, dtype: DTypeLike,
                fill: float) -> np.ndarray:
    from geoblock.ortho.kernels import cast

    return cast(values, valid, dtype, fill)


def mosaic(
    sources: Sequence[xr.DataArray | tuple[ImageLike, SensorModel]],
    grid: OutputGrid | None = None,
    *,
    method: str = "priority",
    feather_px: float = 32.0,
    nodata: float | None = None,
    dem: EngineDem | None = None,
    chunks: int | tuple[int, int] | None = None,
    kernel: str = "bilinear",
    tolerance_px: float = 0.01,
    accuracy: Sequence[xr.DataArray] | None = None,
) -> xr.Dataset:
    """Mosaic orthoimages onto one grid: priority or feathering, and a contribution band.

    Lazy: building the result computes nothing.

    Parameters
    ----------
    sources : sequence of xarray.DataArray or (image, model)
        In priority order. A DataArray is a ``(band, y, x)`` ortho georeferenced by a
        ``spatial_ref`` coordinate (``crs_wkt``, ``GeoTransform``), e.g. from
        :func:`~geoblock.ortho.graph.orthorectify` or :func:`open_ortho`, with its nodata in
        ``attrs["_FillValue"]`` (NaN for floats without one; integers without one have no
        nodata). An ``(image, model)`` pair (``image`` a path, an open rasterio dataset, a
        DataArray or a numpy array in the sensor's geometry, as
        :func:`~geoblock.ortho.graph.orthorectify` takes it; ``model`` a
        :class:`~geoblock.models.SensorModel`) is orthorectified onto ``grid`` with ``dem``,
        ``kernel``, ``tolerance_px`` and ``chunks``. Every source has the same number of bands
        and is on a grid of the same CRS, resolution and pixel phase as the others (and as
        ``grid``): nothing is reprojected or resampled.
    grid : OutputGrid, optional
        The output grid; required with ``(image, model)`` pairs. Default: the union of the
        sources' grids (the first source's pixel edges). Sources are cut to it.
    method : {"priority", "feather"}
        ``priority``: the first source with a valid pixel wins. ``feather``: sources are
        blended with weights ``min(d, feather_px)``, ``d`` the distance (pixels) to the
        source's nearest invalid pixel (module docstring).
    feather_px : float
        Cap of the feathering weights, pixels (> 0): the width of the transition at a seam.
    nodata : float, optional
        Output value where no source is valid. Default: the first source's nodata; else NaN
        for float outputs and 0 for integers.
    dem : DemSource, float, or anything geoblock.open_dem opens, optional
        Terrain heights for the ``(image, model)`` pairs (opened once for all of them).
    chunks : int or (int, int), optional
        Output chunk ``(rows, cols)``; default the first DataArray's chunk size, else 1024.
        The values do not depend on it.
    kernel : {"nearest", "bilinear", "bicubic", "sinc"}
        Resampling kernel of the ``(image, model)`` pairs.
    tolerance_px : float
        Lattice tolerance of the ``(image, model)`` pairs, source pixels.
    accuracy : sequence of xarray.DataArray, optional
        One accuracy layer per source (:func:`~geoblock.ortho.accuracy.accuracy_layer`, or
        :func:`open_ortho` of the ``*_accuracy.tif`` beside an ortho): ``(band, y, x)`` with
        one band, metres, each on its source's grid. The mosaic then has an ``accuracy``
        variable made with the same selection: ``priority`` takes the winning source's
        value; ``feather`` blends the sources' errors with the image's weights,
        ``sigma = sum(w_k sigma_k) / sum(w_k)``: the error of the blended position
        ``sum(a_k e_k)`` (``a_k = w_k / sum(w)``) when the sources' errors are fully
        correlated, and an upper bound of its RMS whatever their correlation (Cauchy-Schwarz):
        the layer never understates the error.

    Returns
    -------
    xarray.Dataset
        Dask-backed, on the output grid, with the coordinates ``orthorectify`` gives
        (``band``, ``y``, ``x``, ``spatial_ref``) and the variables:

        ``mosaic`` : (band, y, x)
            Of the sources' common dtype (``numpy.result_type``); ``attrs["_FillValue"]`` is
            ``nodata``. :func:`geoblock.io.images.write_ortho` writes it.
        ``contribution`` : (y, x), uint8 (uint16 beyond 255 sources)
            ``k`` where the pixel comes from ``sources[k - 1]`` (the largest weight for
            ``feather``, the first source on ties), 0 where no source is valid;
            ``attrs["_FillValue"]`` is 0. Write it with
            ``write_ortho(ds.contribution.expand_dims(band=[1]), path)``.
        ``accuracy`` : (y, x), float32, only with ``accuracy=``
            The mosaic's predicted horizontal error, metres; NaN where no source is valid
            (or the selected source's layer has no value). Write it with
            ``write_ortho(ds.accuracy.expand_dims(band=[1]), path)``.

    Raises
    ------
    MosaicError
        No sources; sources of different CRS, resolution, pixel phase or band count; pairs
        without ``grid`` or ``dem``; an unknown ``method`` or a bad ``feather_px``; an
        ``accuracy`` list of another length than ``sources``, or a layer not on its source's
        grid or with more than one band.
    """
    import dask.array as da
    import xarray as xr

    from geoblock.ortho.graph import orthorectify

    if method not in METHODS:
        raise MosaicError(f"mosaic: method must be one of {METHODS}, got {method!r}")
    if method == "feather" and not (math.isfinite(feather_px) and feather_px > 0):
        raise MosaicError(f"mosaic: feather_px must be positive and finite, got {feather_px!r}")
    sources = list(sources)
    if not sources:
        raise MosaicError("mosaic: no sources")
    if dem is not None:
        from geoblock.dem.intersect import as_dem_source

        dem = as_dem_source(dem)

    orthos = []
    for i, src in enumerate(sources):
        if isinstance(src, xr.DataArray):
            orthos.append(src)
            continue
        if not (isinstance(src, (tuple, list)) and len(src) == 2):
            raise MosaicError(f"mosaic: source {i + 1} must be a DataArray or an (image, model) "
                              f"pair, got {type(src).__name__}")
        if grid is None or dem is None:
            raise MosaicError("mosaic: (image, model) sources need a common grid= and a dem=")
        image, model = src
        orthos.append(orthorectify(image, model, dem, grid, kernel=kernel,
                                   tolerance_px=tolerance_px,
                                   chunks=1024 if chunks is None else chunks))
    if chunks is None:
        first = next((s for s in sources if isinstance(s, xr.DataArray)), None)
        if first is not None and first.chunks is not None:
            chunks = (int(first.chunks[1][0]), int(first.chunks[2][0]))
        else:
            chunks = 1024
    rc, cc = _chunk_pair(chunks)
    if rc <= 0 or cc <= 0:
        raise MosaicError(f"mosaic: chunks must be positive, got {chunks!r}")

    grids = [_grid_of(o, i) for i, o in enumerate(orthos)]
    if grid is None:
        grid = _union_grid(grids)
    offsets = [_offset(g, grid, i) for i, g in enumerate(grids)]
    bands = {int(o.sizes["band"]) for o in orthos}
    if len(bands) != 1:
        raise MosaicError(f"mosaic: the sources have different numbers of bands: "
                          f"{[int(o.sizes['band']) for o in orthos]}")
    nb = bands.pop()
    dtype = np.result_type(*[np.dtype(o.dtype) for o in orthos])
    fills = [_fill_of(o) for o in orthos]
    if nodata is None:
        nodata = fills[0]
    if nodata is None or (math.isnan(nodata) and dtype.kind != "f"):
        nodata = float("nan") if dtype.kind == "f" else 0
    if dtype.kind in "iu":
        info = np.iinfo(dtype)
        if not (info.min <= nodata <= info.max):
            raise MosaicError(f"mosaic: nodata {nodata!r} is not representable in {dtype}")
    shape = grid.shape
    out_chunks = ((nb,), _chunk_tuple(shape[0], rc), _chunk_tuple(shape[1], cc))
    ctype = np.uint8 if len(orthos) <= 255 else np.uint16

    errors = _accuracy_sources(accuracy, grids, shape, offsets, (rc, cc))
    values, masks = [], []
    halo = int(math.ceil(feather_px)) if method == "feather" else 0
    for o, off, fill in zip(orthos, offsets, fills, strict=True):
        arr = o.data if isinstance(o.data, da.Array) else da.from_array(
            np.asarray(o.data), chunks=(-1, rc, cc))
        valid = _valid(arr, fill)
        values.append(_place(arr, off, shape, 0, 0).astype(dtype).rechunk(out_chunks))
        masks.append(_place(valid, off, shape, halo, False))
    acc_chunks = ((1,),) + out_chunks[1:]
    first_err = da.full((1,) + shape, np.nan, dtype=np.float64, chunks=acc_chunks)

    # priority (also feather's value where a single source is valid)
    first_valid = da.zeros(shape, dtype=ctype, chunks=out_chunks[1:])
    value = da.zeros((nb,) + shape, dtype=dtype, chunks=out_chunks)
    for k in range(len(orthos), 0, -1):
        m = masks[k - 1]
        if halo:
            m = m[halo:halo + shape[0], halo:halo + shape[1]]
        m = m.rechunk(out_chunks[1:])
        first_valid = da.where(m, ctype(k), first_valid)
        value = da.where(m[None], values[k - 1], value)
        if errors is not None:
            first_err = da.where(m[None], errors[k - 1], first_err)
    any_valid = first_valid > 0
    err = first_err

    if method == "priority":
        contribution = first_valid
        result = da.where(any_valid[None], value, np.asarray(nodata).astype(dtype))
    else:
        num = da.zeros((nb,) + shape, dtype=np.float64, chunks=out_chunks)
        den = da.zeros(shape, dtype=np.float64, chunks=out_chunks[1:])
        count = da.zeros(shape, dtype=np.int32, chunks=out_chunks[1:])
        best_w = da.zeros(shape, dtype=np.float64, chunks=out_chunks[1:])
        contribution = da.zeros(shape, dtype=ctype, chunks=out_chunks[1:])
        err_num = da.zeros((1,) + shape, dtype=np.float64, chunks=acc_chunks)
        for k, (v, m) in enumerate(zip(values, masks, strict=True), start=1):
            w = _weights(m, halo, float(feather_px), shape).rechunk(out_chunks[1:])
            num = num + da.where((w > 0)[None], w[None] * v.astype(np.float64), 0.0)
            if errors is not None:
                err_num = err_num + da.where((w > 0)[None], w[None] * errors[k - 1], 0.0)
            den = den + w
            count = count + (w > 0)
            better = w > best_w
            contribution = da.where(better, ctype(k), contribution)
            best_w = da.where(better, w, best_w)
        blended = da.map_blocks(_cast_block, num / da.where(den > 0, den, 1.0)[None],
                                den > 0, dtype, nodata, dtype=dtype)
        result = da.where((count == 1)[None], value, blended)
        result = da.where(any_valid[None], result, np.asarray(nodata).astype(dtype))
        err = da.where((count == 1)[None], first_err,
                       err_num / da.where(den > 0, den, 1.0)[None])

    result = result.astype(dtype).rechunk(out_chunks)
    contribution = contribution.astype(ctype).rechunk(out_chunks[1:])
    coords = _coords(grid, nb, nodata)
    out = xr.DataArray(result, dims=("band", "y", "x"), coords=coords, name="mosaic",
                       attrs={"_FillValue": nodata, "grid_mapping": "spatial_ref"})
    contrib = xr.DataArray(
        contribution, dims=("y", "x"),
        coords={k: v for k, v in coords.items() if k != "band"}, name="contribution",
        attrs={"_FillValue": 0, "grid_mapping": "spatial_ref",
               "long_name": "1-based index of the source of each pixel (0: none)"},
    )
    variables = {"mosaic": out, "contribution": contrib}
    if errors is not None:
        err = da.where(any_valid, err[0], np.nan).astype(np.float32).rechunk(out_chunks[1:])
        variables["accuracy"] = xr.DataArray(
            err, dims=("y", "x"), coords={k: v for k, v in coords.items() if k != "band"},
            name="accuracy", attrs={"_FillValue": float("nan"), "grid_mapping": "spatial_ref",
                                    "units": "m",
                                    "long_name": "predicted horizontal error (m, radial RMS)"})
    return xr.Dataset(variables, attrs={"method": method, "feather_px": float(feather_px),
                                        "sources": len(orthos)})


def _accuracy_sources(accuracy: Sequence[xr.DataArray] | None, grids: Sequence[OutputGrid],
                      shape: tuple[int, int], offsets: Sequence[tuple[int, int]],
                      chunks: tuple[int, int]) -> list[da.Array] | None:
    """Each source's accuracy layer placed on the output grid, ``(1, y, x)`` float64 (NaN
    outside it), or None without layers."""
    import dask.array as da

    if accuracy is None:
        return None
    layers = list(accuracy)
    if len(layers) != len(grids):
        raise MosaicError(f"mosaic: {len(layers)} accuracy layers for {len(grids)} sources "
                          "(one per source, in the same order)")
    out = []
    for i, (layer, g, off) in enumerate(zip(layers, grids, offsets, strict=True)):
        mine = _grid_of(layer, i)
        if int(layer.sizes["band"]) != 1:
            raise MosaicError(f"mosaic: accuracy layer {i + 1} has {int(layer.sizes['band'])} "
                              "bands, not 1")
        if not (mine.crs == g.crs and mine.shape == g.shape and all(
                abs(a - b) <= 1e-9 * max(1.0, abs(b))
                for a, b in zip(tuple(mine.transform)[:6], tuple(g.transform)[:6],
                                strict=True))):
            raise MosaicError(f"mosaic: accuracy layer {i + 1} is not on its source's grid "
                              f"({mine.shape} at {tuple(mine.transform)[:6]}, not {g.shape} "
                              f"at {tuple(g.transform)[:6]})")
        arr = layer.data if isinstance(layer.data, da.Array) else da.from_array(
            np.asarray(layer.data), chunks=(1,) + chunks)
        fill = _fill_of(layer)
        arr = arr.astype(np.float64)
        if fill is not None and not math.isnan(fill):
            arr = da.where(arr == fill, np.nan, arr)
        placed = _place(arr, off, shape, 0, np.nan)
        out.append(placed.rechunk(((1,), _chunk_tuple(shape[0], chunks[0]),
                                   _chunk_tuple(shape[1], chunks[1]))))
    return out


# ---------------------------------------------------------------------- reading orthos
def _read_block(image: OpenedImage, window: tuple[int, int, int, int]) -> np.ndarray:
    return image.read(window)


def open_ortho(path: ImageLike, chunks: int | tuple[int, int] = 1024) -> xr.DataArray:
    """A georeferenced raster (e.g. a GeoTIFF ortho) as a lazy ``(band, y, x)`` DataArray.

    Parameters
    ----------
    path : str, os.PathLike or an opened image
        Any north-up, georeferenced raster rasterio reads (or what
        :func:`geoblock.io.open_image` takes: an open rasterio dataset, a georeferenced
        numpy array or DataArray).
    chunks : int or (int, int)
        Chunk ``(rows, cols)``, pixels; each chunk is one windowed read.

    Returns
    -------
    xarray.DataArray, (band, y, x)
        With the coordinates of :func:`~geoblock.ortho.graph.orthorectify`'s result
        (``spatial_ref`` with ``crs_wkt`` and ``GeoTransform``); ``attrs["_FillValue"]`` is the
        file's nodata when it has one.

    Raises
    ------
    GeoblockIOError
        The file is missing or not a raster.
    MosaicError
        The raster has no CRS, or is not north-up.
    """
    import dask.array as da
    import pyproj
    import xarray as xr
    from dask.base import tokenize
    from dask.highlevelgraph import HighLevelGraph

    from geoblock.io.images import ImageSource, open_image
    from geoblock.ortho.grid import OutputGrid

    image = open_image(path)  # one open: shape, bands, dtype, nodata, CRS and geotransform
    if image.transform is None and isinstance(image, ImageSource):
        # an ImageSource made by hand: its file's georeferencing
        fresh = open_image(image.path)
        image = dataclasses.replace(image, crs=fresh.crs, transform=fresh.transform)
    crs, transform = image.crs, image.transform
    if crs is None:
        raise MosaicError(f"{image.path} has no CRS: it is not an ortho")
    try:
        grid = OutputGrid(pyproj.CRS.from_wkt(crs.to_wkt()), transform, image.shape)
    except ValueError as exc:
        raise MosaicError(f"{image.path} is not a north-up ortho: {exc}") from exc
    rc, cc = _chunk_pair(chunks)
    rows, cols = image.shape
    row_chunks, col_chunks = _chunk_tuple(rows, rc), _chunk_tuple(cols, cc)
    name = "read-ortho-" + tokenize(image, row_chunks, col_chunks)
    dsk: dict[Any, Any] = {}
    r0 = 0
    for i, h in enumerate(row_chunks):
        c0 = 0
        for j, w in enumerate(col_chunks):
            dsk[(name, 0, i, j)] = (_read_block, image, (r0, r0 + h, c0, c0 + w))
            c0 += w
        r0 += h
    graph = HighLevelGraph.from_collections(name, dsk, dependencies=())
    array = da.Array(graph, name, chunks=((image.bands,), row_chunks, col_chunks),
                     dtype=np.dtype(image.dtype))
    attrs: dict[str, Any] = {"grid_mapping": "spatial_ref"}
    if image.nodata is not None:
        attrs["_FillValue"] = image.nodata
    return xr.DataArray(array, dims=("band", "y", "x"),
                        coords=_coords(grid, image.bands, image.nodata), attrs=attrs,
                        name=os.path.basename(image.path))
