"""File DEMs through rasterio: GeoTIFF, SRTM ``.hgt``, VRT, any GDAL raster; tiles mosaicked.

:class:`RasterDem` samples one raster file (its compiled block kernels are in
:mod:`geoblock.dem.sampling`, its block cache in :mod:`geoblock.dem.cache`; the in-memory
:class:`~geoblock.dem.array.ArrayDem` is a subclass); :class:`~geoblock.dem.mosaic.MosaicDem`
a list of them (each point takes the first tile that has a height). Users normally call
:func:`geoblock.open_dem`.

Reading
    The raster is read in square blocks (512 x 512 pixels, or the whole raster when it is at
    most 2048 x 2048) with a 2-pixel halo, so that every nearest/bilinear/bicubic kernel of a
    point lies inside one block. Blocks go to one process-wide, thread-safe LRU cache
    (:data:`~geoblock.dem.cache.BLOCK_CACHE`, 256 MB by default, ``GEOBLOCK_DEM_CACHE_MB``)
    shared by every ``RasterDem`` of the same file and options, hence by every call and every
    dask task in a worker. Past the raster's outer edge the block repeats the edge pixels, and
    the points of the half pixel between the outermost pixel centres and the raster edge are
    sampled at the outermost centre (edge extension, which is what GDAL's warper gives for
    bilinear there).

Vertical datum
    Heights come out above the WGS84 ellipsoid. ``vertical=None`` takes the datum from the
    file: a compound CRS whose vertical part is EGM96 height -> geoid; a 3-D geographic CRS
    (EPSG:4979) -> ellipsoid; an SRTM ``.hgt`` tile (GDAL driver ``SRTMHGT``) -> geoid, because
    the SRTM specification defines its heights above EGM96 (GDAL itself reports only
    EPSG:4326 for them). Otherwise the file is refused with a :class:`~geoblock.errors.DemError`
    that says to pass ``vertical="geoid"`` or ``vertical="ellipsoid"``. An explicit
    ``vertical=`` always wins over the file.

Nodata
    ``nodata="nan"`` (default): nodata pixels and voids are NaN, and any kernel touching one
    gives NaN with status ``NO_DEM``. A number: nodata pixels take that value (in the file's
    own vertical datum and units, before the geoid is added). ``"fill"`` (alias
    ``"nearest"``): voids are filled from their neighbours by ``rasterio.fill.fillnodata``
    (GDAL's inverse-distance fill, search distance ``fill_distance`` pixels, no smoothing:
    shareloc's ``"rio_fillnodata"``), block by block with a margin of ``fill_distance`` pixels.
"""

from __future__ import annotations

import math
import os
import threading
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pyproj
from affine import Affine

from geoblock import coords
from geoblock._affine import apply as affine_apply
from geoblock._array import finite_bounds
from geoblock.dem._raycast import RayWindow
from geoblock.dem.base import DemBase
from geoblock.dem.cache import BLOCK_CACHE
from geoblock.dem.geoid import Geoid, find_geoid
from geoblock.dem.grid import _is_lonlat, box_window, lonlat_to_crs
from geoblock.dem.protocol import Bounds
from geoblock.dem.sampling import (
    INTERPOLATIONS,
    _nb_locate,
    _nb_pixel_coords,
    _nb_sample_index,
    _nb_sample_keyed,
    _nb_sample_window,
)
from geoblock.errors import DemCoverageError, DemDatumError, DemError
from geoblock.io.rasters import open_quietly, read_window
from geoblock.pixels import PIXEL_CENTRE, pixel_to_map

#: How to state a DEM's datum in the Python API (front ends give their own spelling:
#: :meth:`geoblock.errors.DemDatumError.with_hint`).
API_DATUM_HINT = (
    "pass vertical='geoid' (heights above EGM96, e.g. SRTM; the Copernicus DEM uses EGM2008: "
    "pass its grid with geoid=) or vertical='ellipsoid' (heights above WGS84), e.g. "
    "open_dem(path, vertical='geoid'); or give the file a compound CRS such as "
    "EPSG:4326+5773")

__all__ = ["API_DATUM_HINT", "VERTICALS", "RasterDem", "file_vertical"]

VERTICALS = ("ellipsoid", "geoid")
"""Accepted values of ``vertical=`` (besides ``None``: from the file)."""

_HALO = 2  # pixels around each block: enough for bicubic's 4 x 4 taps
#: :meth:`RasterDem._sample_window` assembles a window of several blocks only when it has
#: at most this many posts per point sampled (plus 65536): beyond, the per-block path wins
_WINDOW_POSTS_PER_POINT = 2.0
_BLOCK = 512
_WHOLE = 2048  # rasters up to this size (both sides) are one block
_STRIP_PIXELS = 1 << 22  # pixels per read when scanning a window for statistics
#: largest window (posts) :meth:`RasterDem._ray_window` assembles for the compiled scan
_RAY_WINDOW_POSTS = 1 << 22


_stats: dict[Any, tuple[float, float, int, int]] = {}  # full-raster statistics, per file+options
_stats_lock = threading.Lock()


# ---------------------------------------------------------------------------- vertical datum
def _to_pyproj(crs: Any) -> pyproj.CRS:
    return pyproj.CRS.from_wkt(crs.to_wkt())


def file_vertical(crs: pyproj.CRS, driver: str) -> tuple[str | None, str]:
    """The vertical datum a DEM file states, and how it states it.

    Parameters
    ----------
    crs : pyproj.CRS
        The raster's CRS as read.
    driver : str
        GDAL driver short name.

    Returns
    -------
    (str or None, str)
        ``"geoid"`` (EGM96), ``"ellipsoid"``, ``"other"`` (a vertical datum geoblock has no
        grid for) or ``None`` (not stated); and a description for messages and ``dem-info``.
    """
    if crs.is_compound and len(crs.sub_crs_list) > 1:
        vert = crs.sub_crs_list[1]
        datum = vert.datum.name if vert.datum is not None else vert.name
        if "EGM96" in datum.upper().replace(" ", "") or "EGM96" in vert.name.upper():
            return "geoid", f"compound CRS, vertical part {vert.name!r} (EGM96)"
        if vert.is_geographic or "ellipsoid" in vert.name.lower():
            return "ellipsoid", f"compound CRS, vertical part {vert.name!r}"
        return "other", f"compound CRS, vertical part {vert.name!r} (datum {datum!r})"
    if crs.is_geographic and len(crs.axis_info) == 3:
        return "ellipsoid", f"3-D geographic CRS {crs.name!r} (ellipsoidal heights)"
    if driver == "SRTMHGT":
        return "geoid", "SRTM .hgt tile: heights above EGM96 by the SRTM specification"
    return None, "not stated by the file"


# ---------------------------------------------------------------------------- RasterDem
class RasterDem(DemBase):
    """A DEM file read through rasterio, sampled at pixel centres, heights ellipsoidal.

    Parameters
    ----------
    path : str or os.PathLike
        Any raster rasterio opens (GeoTIFF, SRTM ``.hgt``, VRT, ...), in any CRS.
    vertical : {"ellipsoid", "geoid"} or None
        Datum of the file's heights; ``None``: as the file states (see the module notes).
    geoid : Geoid, str or os.PathLike, optional
        Geoid grid for ``vertical="geoid"`` (default: found by
        :func:`~geoblock.dem.geoid.find_geoid`).
    nodata : "nan", "fill", "nearest" or float
        Nodata policy (module notes).
    interpolation : {"nearest", "bilinear", "bicubic"}
    strict : bool
        Raise :class:`~geoblock.errors.DemCoverageError` when points fall outside the raster
        (default: NaN and status ``NO_DEM``).
    band : int
        1-based band holding the heights.
    fill_distance : int
        Search distance of ``nodata="fill"``, pixels.

    Raises
    ------
    DemError
        The file cannot be opened, has no CRS, an option is invalid, or its vertical datum is
        not stated by the file nor by ``vertical=``.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        *,
        vertical: str | None = None,
        geoid: Geoid | str | os.PathLike[str] | None = None,
        nodata: str | float = "nan",
        interpolation: str = "bilinear",
        strict: bool = False,
        band: int = 1,
        fill_distance: int = 100,
    ) -> None:
        from rasterio.errors import RasterioIOError

        self._path = str(path) if str(path).startswith(("/vsi", "http")) else str(
            Path(path).expanduser().resolve())
        self._set_options(vertical, nodata, interpolation, strict, band, fill_distance)
        try:
            ds = open_quietly(self._path)  # no georeferencing is refused below
            with ds:
                if not 1 <= self._band <= ds.count:
                    raise DemError(f"DEM {self._path}: band {band} does not exist "
                                   f"({ds.count} bands)")
                if ds.crs is None:
                    raise DemError(f"DEM {self._path} has no CRS (georeferencing); geoblock "
                                   "needs one to place its heights")
                k = self._band - 1
                self._set_raster(
                    driver=ds.driver, shape=(int(ds.height), int(ds.width)),
                    transform=Affine(*tuple(ds.transform)[:6]), crs=_to_pyproj(ds.crs),
                    file_nodata=ds.nodatavals[k], dtype=np.dtype(ds.dtypes[k]),
                    scale=ds.scales[k], offset=ds.offsets[k], tags=ds.tags(self._band))
        except RasterioIOError as exc:
            raise DemError(f"cannot open DEM {self._path}: {exc}") from exc
        self._finish(vertical, geoid, (self._path,))

    # ------------------------------------------------------------------ set-up steps
    def _set_options(self, vertical: str | None, nodata: str | float, interpolation: str,
                     strict: bool, band: int, fill_distance: int) -> None:
        """Check and keep the options (``self._path`` names the DEM in the messages)."""
        if interpolation not in INTERPOLATIONS:
            raise DemError(f"DEM {self._path}: interpolation must be one of {INTERPOLATIONS}, "
                           f"got {interpolation!r}")
        if vertical is not None and vertical not in VERTICALS:
            raise DemError(f"DEM {self._path}: vertical must be 'geoid', 'ellipsoid' or None, "
                           f"got {vertical!r}")
        if isinstance(nodata, str):
            if nodata not in ("nan", "fill", "nearest"):
                raise DemError(f"DEM {self._path}: nodata must be 'nan', 'fill', 'nearest' or a "
                               f"number, got {nodata!r}")
            nodata = "fill" if nodata == "nearest" else nodata
        else:
            nodata = float(nodata)
            if not math.isfinite(nodata):
                raise DemError(f"DEM {self._path}: a nodata fill value must be finite")
        self._nodata_policy: str | float = nodata
        self._interpolation = interpolation
        self._strict = bool(strict)
        self._band = int(band)
        self._fill_distance = int(fill_distance)

    def _set_raster(self, *, driver: str, shape: tuple[int, int], transform: Affine,
                    crs: pyproj.CRS, file_nodata: float | None, dtype: np.dtype,
                    scale: float | None, offset: float | None, tags: Mapping[str, str]) -> None:
        """Keep what the raster states about itself (as rasterio reports it for the band)."""
        self._driver = str(driver)
        self._shape = shape
        self._transform = transform
        self._crs = crs
        self._file_nodata = None if file_nodata is None else float(file_nodata)
        self._dtype = np.dtype(dtype)
        self._scale = float(scale or 1.0)
        self._offset = float(offset or 0.0)
        self._tag_stats = (tags.get("STATISTICS_MINIMUM"), tags.get("STATISTICS_MAXIMUM"))

    def _finish(self, vertical: str | None, geoid: Geoid | str | os.PathLike[str] | None,
                identity: tuple[Any, ...]) -> None:
        """The vertical datum, the geoid, the block layout and the cache key (``identity``:
        what identifies the pixels, e.g. the path)."""
        if self._transform.is_degenerate:
            raise DemError(f"DEM {self._path}: degenerate geotransform {tuple(self._transform)}")
        stated, how = file_vertical(self._crs, self._driver)
        if vertical is None:
            if stated is None:
                raise DemDatumError(
                    str(self._path),
                    f"its vertical datum is not stated (CRS {self._crs.name!r} has no "
                    "vertical part) and geoblock does not guess it",
                    API_DATUM_HINT)
            if stated == "other":
                raise DemDatumError(
                    str(self._path),
                    f"{how} is not supported (geoblock converts EGM96 heights, or another "
                    "geoid's with its grid)",
                    "pass vertical='geoid' with geoid= the grid of that datum, or "
                    "vertical='ellipsoid'")
            self._vertical = stated
            self._vertical_source = how
        else:
            self._vertical = vertical
            self._vertical_source = f"stated by the caller (file: {how})"
        self._geoid = find_geoid(geoid) if self._vertical == "geoid" else None

        self._horizontal = self._crs.sub_crs_list[0] if self._crs.is_compound else self._crs
        self._lonlat = _is_lonlat(self._horizontal)
        rows, cols = self._shape
        self._block = max(rows, cols) if max(rows, cols) <= _WHOLE else _BLOCK
        self._nbc = -(-cols // self._block)
        self._store_dtype = np.dtype(np.float64 if self._dtype == np.float64 else np.float32)
        self._cache_key = (*identity, self._band, str(self._nodata_policy), self._fill_distance)
        self._inverse = np.array(tuple(~self._transform)[:6], dtype=np.float64)
        self._ray_windows: dict[tuple[int, int, int, int], RayWindow] = {}
        self._window_stats: dict[tuple[int, int, int, int], tuple[float, float, int, int]] = {}

    # ------------------------------------------------------------------ properties
    @property
    def path(self) -> str:
        """Absolute path of the file."""
        return self._path

    @property
    def shape(self) -> tuple[int, int]:
        """``(rows, cols)`` of the raster."""
        return self._shape

    @property
    def transform(self) -> Affine:
        """GDAL geotransform (pixel corners) of the raster."""
        return self._transform

    @property
    def crs(self) -> pyproj.CRS:
        """The file's CRS (compound when the file states a vertical part)."""
        return self._crs

    @property
    def driver(self) -> str:
        return self._driver

    @property
    def vertical(self) -> str:
        """``"geoid"`` or ``"ellipsoid"``: datum of the file's heights."""
        return self._vertical

    @property
    def vertical_source(self) -> str:
        """How :attr:`vertical` was decided (file CRS, SRTM specification, caller)."""
        return self._vertical_source

    @property
    def geoid(self) -> Geoid | None:
        """The geoid added to the file's heights, if any."""
        return self._geoid

    @property
    def nodata(self) -> str | float:
        """The nodata policy: ``"nan"``, ``"fill"`` or a fill value."""
        return self._nodata_policy

    @property
    def file_nodata(self) -> float | None:
        """The file's nodata value."""
        return self._file_nodata

    @property
    def interpolation(self) -> str:
        return self._interpolation

    @property
    def strict(self) -> bool:
        return self._strict

    @property
    def native_bounds(self) -> tuple[float, float, float, float]:
        """``(left, bottom, right, top)`` in the file's CRS."""
        rows, cols = self._shape
        x, y = affine_apply(self._transform, np.array([0, cols, cols, 0]),
                            np.array([0, 0, rows, rows]))
        return (float(np.min(x)), float(np.min(y)), float(np.max(x)), float(np.max(y)))

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """``(west, south, east, north)`` of the raster, degrees (WGS84)."""
        rows, cols = self._shape
        t = np.linspace(0.0, 1.0, 21)
        c = np.concatenate([t * cols, np.full(21, cols), t[::-1] * cols, np.zeros(21)])
        r = np.concatenate([np.zeros(21), t * rows, np.full(21, rows), t[::-1] * rows])
        x, y = affine_apply(self._transform, *(c, r))
        if self._lonlat:
            lon, lat = np.asarray(x), np.asarray(y)
        else:
            lon, lat = coords.transformer(self._horizontal, "EPSG:4326").transform(x, y)
        return (float(np.min(lon)), float(np.min(lat)), float(np.max(lon)), float(np.max(lat)))

    @property
    def resolution_m(self) -> float:
        """Post spacing, metres (geometric mean of the two axes; degrees scaled at the
        equator for geographic rasters, i.e. an upper bound)."""
        a, b, _, d, e, _ = tuple(self._transform)[:6]
        size = float(np.sqrt(abs(a * e - b * d)))
        if self._horizontal.is_geographic:
            return size * np.radians(1.0) * coords.WGS84_A
        return size

    # ------------------------------------------------------------------ reading
    def _read_raw(self, r0: int, r1: int, c0: int, c1: int) -> np.ndarray:
        """Rows ``r0:r1``, cols ``c0:c1`` of the band as stored (through the per-thread handle
        cache of :mod:`geoblock.io.rasters`: one open per file and thread)."""
        return read_window(self._path, (r0, r1, c0, c1), band=self._band, what="the DEM ")

    def _read(self, r0: int, r1: int, c0: int, c1: int) -> np.ndarray:
        """Rows ``r0:r1``, cols ``c0:c1`` (inside the raster) as floats, NaN for nodata."""
        raw = self._read_raw(r0, r1, c0, c1)
        out = raw.astype(self._store_dtype)
        bad = ~np.isfinite(out)
        if self._file_nodata is not None and np.isfinite(self._file_nodata):
            bad |= raw == self._file_nodata
        if self._scale != 1.0 or self._offset != 0.0:
            out = out * self._scale + self._offset
        out[bad] = np.nan
        return out

    def _load_block(self, br: int, bc: int) -> np.ndarray:
        rows, cols = self._shape
        b, h = self._block, _HALO
        margin = h + (self._fill_distance if self._nodata_policy == "fill" else 0)
        r0, r1 = max(br * b - margin, 0), min((br + 1) * b + margin, rows)
        c0, c1 = max(bc * b - margin, 0), min((bc + 1) * b + margin, cols)
        data = self._read(r0, r1, c0, c1)
        if self._nodata_policy == "fill":
            data = self._fill(data)
        elif not isinstance(self._nodata_policy, str):
            data[np.isnan(data)] = self._nodata_policy
        # crop to block + halo, then repeat the edge pixels past the raster's edge
        want_r0, want_c0 = br * b - h, bc * b - h
        cr0, cc0 = max(want_r0, 0) - r0, max(want_c0, 0) - c0
        cr1 = min((br + 1) * b + h, rows) - r0
        cc1 = min((bc + 1) * b + h, cols) - c0
        core = data[cr0:cr1, cc0:cc1]
        pad_top = max(0, -want_r0)
        pad_left = max(0, -want_c0)
        pad_bottom = b + 2 * h - pad_top - core.shape[0]
        pad_right = b + 2 * h - pad_left - core.shape[1]
        return np.pad(core, ((pad_top, pad_bottom), (pad_left, pad_right)), mode="edge")

    def _fill(self, data: np.ndarray) -> np.ndarray:
        from rasterio.fill import fillnodata

        mask = np.isfinite(data)
        if mask.all() or not mask.any():
            return data
        sentinel = np.float32(-1e30)  # left where no valid pixel is within reach
        filled = fillnodata(np.where(mask, data, sentinel).astype(np.float32),
                            mask=mask.astype(np.uint8), max_search_distance=self._fill_distance,
                            smoothing_iterations=0)
        out = np.where(filled == sentinel, np.nan, filled).astype(self._store_dtype)
        out[mask] = data[mask]
        return out

    def pixel_coords(self, lon: np.ndarray, lat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pixel-centre ``(row, col)`` of WGS84 points in the raster (integers at centres)."""
        lon = np.asarray(lon, float)
        lat = np.asarray(lat, float)
        x, y = lonlat_to_crs(self._crs, lon, lat)
        x = np.ascontiguousarray(x, dtype=np.float64)
        y = np.ascontiguousarray(y, dtype=np.float64)
        row = np.empty(x.shape)
        col = np.empty(x.shape)
        _nb_pixel_coords(x.reshape(-1), y.reshape(-1), self._inverse, bool(self._lonlat),
                         float(self._transform.c), row.reshape(-1), col.reshape(-1))
        return row, col

    def _sample(self, lon: np.ndarray, lat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Ellipsoidal heights (NaN for none) and the mask of points outside the raster.

        Compiled (GIL released): pixel coordinates, coverage and block of every point in one
        pass, then each block's points sampled in place (bit-identical to
        :func:`geoblock.dem._reference.sample_reference`)."""
        rows, cols = self._shape
        b = self._block
        nearest = self._interpolation == "nearest"
        n = 0 if nearest else (2 if self._interpolation == "bilinear" else 4)
        fused = self._sample_window(lon, lat, n)
        if fused is not None:
            return fused
        row, col = self.pixel_coords(lon, lat)
        shape = row.shape
        row = row.reshape(-1)
        col = col.reshape(-1)
        keys = np.empty(row.size, dtype=np.int64)
        kmin, kmax = _nb_locate(row, col, rows, cols, b, self._nbc, nearest, keys)
        out = np.full(row.size, np.nan)
        if kmin < 0:  # no point inside
            return out.reshape(shape), np.ones(shape, bool)
        if kmin == kmax:
            kr, kc = divmod(int(kmin), self._nbc)
            block = self._get_block(kr, kc)
            _nb_sample_keyed(block, row, col, keys, kmin, float(kr * b - _HALO),
                             float(kc * b - _HALO), n, out)
        else:
            idx_in = np.flatnonzero(keys >= 0)
            k_in = keys[idx_in]
            order = idx_in[np.argsort(k_in, kind="stable")]
            sorted_keys = keys[order]
            starts = np.flatnonzero(np.r_[True, sorted_keys[1:] != sorted_keys[:-1]])
            ends = np.append(starts[1:], order.size)
            for s0, e0 in zip(starts, ends, strict=True):
                key = int(sorted_keys[s0])
                kr, kc = divmod(key, self._nbc)
                block = self._get_block(kr, kc)
                _nb_sample_index(block, row, col, order[s0:e0], float(kr * b - _HALO),
                                 float(kc * b - _HALO), n, out)
        outside = (keys < 0).reshape(shape)
        heights = out.reshape(shape)
        if self._geoid is not None and not outside.all():
            inside = ~outside
            heights[inside] = heights[inside] + self._geoid.undulation(lon[inside], lat[inside])
        return heights, outside

    def _sample_window(
        self, lon: np.ndarray, lat: np.ndarray, n: int
    ) -> tuple[np.ndarray, np.ndarray] | None:
        """:meth:`_sample` in one compiled pass over the points, for points that span a small
        part of the raster (an orthorectifier's chunk, a lattice): the blocks they touch are
        sampled as one window (one cached block as is, several assembled), the pixel
        coordinates, coverage and sample computed per point without intermediate arrays.

        ``None`` when it does not apply (no finite point, or points spread over more posts
        than ``_WINDOW_POSTS_PER_POINT`` each): :meth:`_sample`'s general path then runs.
        Bit-identical to it (subtracting a window's integer origin from a pixel coordinate is
        exact)."""
        lon = np.asarray(lon, float)
        lat = np.asarray(lat, float)
        shape = lon.shape
        if lon.size == 0:
            return None
        x, y = lonlat_to_crs(self._crs, lon, lat)
        x = np.ascontiguousarray(x, dtype=np.float64).reshape(-1)
        y = np.ascontiguousarray(y, dtype=np.float64).reshape(-1)
        x_lo, x_hi, y_lo, y_hi = finite_bounds(x, y)
        if not all(math.isfinite(v) for v in (x_lo, x_hi, y_lo, y_hi)):
            return None
        west = float(self._transform.c)
        if self._lonlat and not (x_lo >= west and x_hi < west + 360.0):
            # the box of the longitudes as the kernel wraps them (it wraps x itself)
            wrapped = west + (x - west) % 360.0
            x_lo, x_hi, _, _ = finite_bounds(wrapped, y)
        rows, cols = self._shape
        cc, rr = affine_apply(~self._transform, np.array([x_lo, x_lo, x_hi, x_hi]),
                              np.array([y_lo, y_hi, y_lo, y_hi]))
        r_lo = min(max(math.floor(float(np.min(rr))) - 2, 0), rows - 1)
        r_hi = min(max(math.floor(float(np.max(rr))) + 1, 0), rows - 1)
        c_lo = min(max(math.floor(float(np.min(cc))) - 2, 0), cols - 1)
        c_hi = min(max(math.floor(float(np.max(cc))) + 1, 0), cols - 1)
        found = self._posts_window(r_lo, r_hi, c_lo, c_hi,
                                   _WINDOW_POSTS_PER_POINT * x.size + 65536)
        if found is None:
            return None
        window, off_r, off_c = found
        out = np.empty(x.size)
        outside = np.empty(x.size, dtype=np.bool_)
        _nb_sample_window(x, y, self._inverse, bool(self._lonlat), west, rows, cols, n, window,
                          float(off_r), float(off_c), out, outside)
        heights = out.reshape(shape)
        missed = outside.reshape(shape)
        if self._geoid is not None and not missed.all():
            if missed.any():
                inside = ~missed
                heights[inside] = heights[inside] + self._geoid.undulation(lon[inside],
                                                                           lat[inside])
            else:
                heights += self._geoid.undulation(lon, lat)
        return heights, missed

    def _posts_window(self, r_lo: int, r_hi: int, c_lo: int, c_hi: int,
                      max_posts: float) -> tuple[np.ndarray, int, int] | None:
        """The cached posts of raster rows ``r_lo..r_hi``, columns ``c_lo..c_hi`` (inside the
        raster) and the halo around them, as one array, with the raster pixel of its first
        post: one cached block as is, several assembled (None beyond ``max_posts``)."""
        b, h = self._block, _HALO
        kr0, kr1 = r_lo // b, r_hi // b
        kc0, kc1 = c_lo // b, c_hi // b
        if kr0 == kr1 and kc0 == kc1:
            return self._get_block(kr0, kc0), kr0 * b - h, kc0 * b - h
        # rows/cols [r0, r1) x [c0, c1) of the raster edge-padded by the halo, copied from
        # the blocks (each is that padded raster around its core: overlaps agree)
        off_r, r1 = r_lo - h, r_hi + h + 1
        off_c, c1 = c_lo - h, c_hi + h + 1
        if (r1 - off_r) * (c1 - off_c) > max_posts:
            return None
        window = np.empty((r1 - off_r, c1 - off_c), dtype=self._store_dtype)
        for kr in range(kr0, kr1 + 1):
            for kc in range(kc0, kc1 + 1):
                block = self._get_block(kr, kc)
                br, bc = kr * b - h, kc * b - h  # the block's origin
                a0, a1 = max(off_r, br), min(r1, br + b + 2 * h)
                e0, e1 = max(off_c, bc), min(c1, bc + b + 2 * h)
                window[a0 - off_r:a1 - off_r, e0 - off_c:e1 - off_c] = \
                    block[a0 - br:a1 - br, e0 - bc:e1 - bc]
        return window, off_r, off_c

    def _ray_window(self, bounds: Bounds) -> RayWindow | None:
        """The posts over a lon/lat box for :func:`geoblock.dem.raycast.scan`, with the
        geoid grid and a bound on the surface's gradient; None when this DEM is not in a
        geographic CRS, samples ``nearest`` (its surface is not continuous), the box is
        larger than :data:`_RAY_WINDOW_POSTS` posts, or a regional geoid has holes."""
        if not self._lonlat or self._interpolation == "nearest" or self._strict:
            return None
        geoid = self._geoid
        if geoid is not None and not np.isfinite(geoid.nodes).all():
            return None
        window = self._window(bounds)
        if window is None:
            return None
        r0, r1, c0, c1 = window
        rows, cols = self._shape
        r_lo, r_hi = min(max(r0 - 1, 0), rows - 1), min(max(r1, 0), rows - 1)
        c_lo, c_hi = min(max(c0 - 1, 0), cols - 1), min(max(c1, 0), cols - 1)
        key = (r_lo, r_hi, c_lo, c_hi)
        cached = self._ray_windows.get(key)
        if cached is not None:
            return cached
        found = self._posts_window(r_lo, r_hi, c_lo, c_hi, _RAY_WINDOW_POSTS)
        if found is None:
            return None
        posts, off_r, off_c = found
        # only the part over the box (a whole-raster block can be much larger)
        a0, a1 = r_lo - _HALO - off_r, r_hi + _HALO + 1 - off_r
        e0, e1 = c_lo - _HALO - off_c, c_hi + _HALO + 1 - off_c
        posts = posts[max(a0, 0):a1, max(e0, 0):e1]
        off_r, off_c = off_r + max(a0, 0), off_c + max(e0, 0)
        # the gradient bound: neighbour differences over the post spacing (bilinear: the
        # surface's slope is at most the sum of the two; bicubic overshoots: 2.5 times that,
        # its weights' absolute sums being 1.25 per axis on top of the 1-D kernel's slope)
        t = self._transform
        lat_max = max(abs(float(t.f)), abs(float(t.f + rows * t.e)))
        m_lat = abs(float(t.e)) * np.radians(1.0) * coords.WGS84_A
        m_lon = abs(float(t.a)) * np.radians(1.0) * coords.WGS84_A * max(
            math.cos(math.radians(min(lat_max, 89.9))), 1e-6)
        g_r, g_c = _max_step(posts, 0), _max_step(posts, 1)
        over = 1.0 if self._interpolation == "bilinear" else 2.5  # Keys' kernel overshoots
        slope = (g_r / m_lat + g_c / m_lon) * over
        slope += 1e-3  # the geoid's own slope (EGM96: below 1e-4)
        has_voids = not bool(np.isfinite(posts).all())
        # geoid-corrected posts (N at each post centre) for the scan, and a bound on how far
        # their interpolation is from the heights with N at the point: none where N is
        # bilinear over a DEM cell, a quarter of the kink in N's slope across a geoid grid
        # line times the cell size where one crosses it
        corrected = np.asarray(posts, np.float64)
        geoid_err = 0.0
        if geoid is not None:
            pr = np.arange(posts.shape[0]) + off_r + PIXEL_CENTRE
            pc = np.arange(posts.shape[1]) + off_c + PIXEL_CENTRE
            p_lon = float(t.c) + pc * float(t.a)
            p_lat = float(t.f) + pr * float(t.e)
            und = geoid.undulation(*np.meshgrid(p_lon, p_lat))
            corrected = corrected + und
            # N's slope over the window (it is piecewise bilinear: its differences between
            # neighbouring posts bound it, with 10 % for a kink between two posts)
            g_lat = _max_step(und, 0) / m_lat
            g_lon = _max_step(und, 1) / m_lon
            geoid_err = 1.1 * over * (g_lat + g_lon) * max(m_lat, m_lon) + 1e-9
        out = RayWindow(
            posts=posts, off_r=float(off_r), off_c=float(off_c), inverse=self._inverse,
            west=float(t.c), rows=rows, cols=cols,
            taps=2 if self._interpolation == "bilinear" else 4,
            geoid=geoid.nodes if geoid is not None else np.empty((0, 0)),
            geoid_header=geoid.header if geoid is not None else np.zeros(5),
            slope=slope, post_m=min(m_lat, m_lon), has_voids=has_voids,
            corrected=np.ascontiguousarray(corrected), geoid_err=geoid_err)
        if len(self._ray_windows) >= 2:
            self._ray_windows.clear()
        self._ray_windows[key] = out
        return out

    def _get_block(self, kr: int, kc: int) -> np.ndarray:
        return BLOCK_CACHE.get((*self._cache_key, kr, kc), lambda: self._load_block(kr, kc))

    def _heights(self, lon: np.ndarray, lat: np.ndarray) -> np.ndarray:
        h, outside = self._sample(lon, lat)
        if self._strict and outside.any():
            raise DemCoverageError(
                f"{int(outside.sum())} of {outside.size} points fall outside the DEM "
                f"{self._path} (bounds {_fmt_bounds(self.bounds)}); strict=True"
            )
        return h

    def heights_on_grid(
        self, crs: Any, transform: Affine | Sequence[float], shape: tuple[int, int]
    ) -> np.ndarray:
        """The DEM resampled onto an output grid (e.g. an orthorectifier's chunk).

        Parameters
        ----------
        crs : pyproj.CRS, str or int
            CRS of the output grid.
        transform : affine.Affine or sequence of 6
            GDAL geotransform of the output grid (pixel corners).
        shape : (int, int)
            ``(rows, cols)`` of the output grid.

        Returns
        -------
        ndarray, (rows, cols)
            Ellipsoidal heights, metres, at the output pixel centres (NaN where none).
        """
        return _heights_on_grid(self, crs, transform, shape)

    # ------------------------------------------------------------------ statistics
    def _scan(self, r0: int, r1: int, c0: int, c1: int) -> tuple[float, float, int, int]:
        """Raw (file datum) min, max, nodata count and pixel count of a window, after the
        nodata policy."""
        lo, hi, nbad, n = np.inf, -np.inf, 0, 0
        step = max(1, _STRIP_PIXELS // max(c1 - c0, 1))
        for s in range(r0, r1, step):
            data = self._read(s, min(s + step, r1), c0, c1)
            good = np.isfinite(data)
            n += data.size
            nbad += int(data.size - good.sum())
            if good.any():
                lo = min(lo, float(data[good].min()))
                hi = max(hi, float(data[good].max()))
        if nbad and not isinstance(self._nodata_policy, str):
            lo, hi = min(lo, self._nodata_policy), max(hi, self._nodata_policy)
        return lo, hi, nbad, n

    def statistics(self) -> dict[str, Any]:
        """Whole-raster figures (cached per file and options): ``min``/``max`` of the file's
        heights (its own datum, metres), ``nodata_count``, ``pixel_count`` and
        ``nodata_share`` (0..1)."""
        key = self._cache_key
        with _stats_lock:
            found = _stats.get(key)
        if found is None:
            rows, cols = self._shape
            found = self._scan(0, rows, 0, cols)
            with _stats_lock:
                _stats[key] = found
        lo, hi, nbad, n = found
        return {"min": lo if np.isfinite(lo) else float("nan"),
                "max": hi if np.isfinite(hi) else float("nan"),
                "nodata_count": nbad, "pixel_count": n, "nodata_share": nbad / n if n else 0.0}

    def height_range(self, bounds: Bounds | None = None) -> tuple[float, float]:
        """``(min, max)`` ellipsoidal height of the posts over ``(west, south, east, north)``
        degrees (default the whole raster), metres; NaN when there is none.

        The posts of a window read covering the box (one pixel around it) are scanned; the
        geoid's range over the box is added for a geoid DEM, so the range is conservative by
        at most the geoid's variation over the box (metres).
        """
        if bounds is None:
            stats = self.statistics()
            lo, hi = stats["min"], stats["max"]
            box = self.bounds
        else:
            window = self._window(bounds)
            if window is None:
                return (float("nan"), float("nan"))
            found = self._window_stats.get(window)
            if found is None:  # a window read and scanned once per DEM (localize asks twice)
                found = self._scan(*window)
                if len(self._window_stats) >= 64:
                    self._window_stats.clear()
                self._window_stats[window] = found
            lo, hi, _, _ = found
            west, south, east, north = (float(v) for v in bounds)
            box = (west, south, east, north)
        if not (np.isfinite(lo) and np.isfinite(hi)):
            return (float("nan"), float("nan"))
        if self._geoid is not None:
            n_lo, n_hi = self._geoid.undulation_range(box)
            lo, hi = lo + n_lo, hi + n_hi
        return (float(lo), float(hi))

    def _window(self, bounds: Bounds) -> tuple[int, int, int, int] | None:
        """``(r0, r1, c0, c1)`` of the pixels whose kernels reach into a lon/lat box."""
        return box_window(self.pixel_coords, self._shape, self._lonlat, bounds)

    # ------------------------------------------------------------------ values
    def to_dict(self) -> dict[str, Any]:
        """JSON-safe: the path and the options (no pixels); :func:`geoblock.open_dem` takes it
        back."""
        return {
            "dem": "raster",
            "path": self._path,
            "vertical": self._vertical,
            "geoid": None if self._geoid is None else self._geoid.path,
            "nodata": self._nodata_policy,
            "interpolation": self._interpolation,
            "strict": self._strict,
            "band": self._band,
            "fill_distance": self._fill_distance,
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> RasterDem:
        """The DEM of :meth:`to_dict`."""
        opts = {k: v for k, v in data.items() if k not in ("dem", "path")}
        return cls(data["path"], **opts)

    def __reduce__(self) -> tuple[Any, ...]:
        return (RasterDem.from_dict, (self.to_dict(),))

    def __repr__(self) -> str:
        rows, cols = self._shape
        return (f"<RasterDem {self._path} {rows}x{cols} {self._crs.name!r} heights above the "
                f"{self._vertical}, {self._interpolation}>")


def _max_step(array: np.ndarray, axis: int) -> float:
    """Largest ``|difference|`` between neighbours along ``axis`` (NaN ignored; 0 if none)."""
    with np.errstate(invalid="ignore"):
        d = np.abs(np.diff(array, axis=axis))
    return float(np.nanmax(d)) if np.isfinite(d).any() else 0.0


def _crs_of(crs: Any, name: str) -> pyproj.CRS:
    """A pyproj CRS of ``crs`` (pyproj, rasterio, WKT, EPSG code...); DemError if none."""
    if crs is None:
        raise DemError(f"DEM {name} has no CRS (georeferencing); geoblock needs one to place "
                       "its heights (crs=)")
    try:
        if not isinstance(crs, pyproj.CRS) and hasattr(crs, "to_wkt"):
            return _to_pyproj(crs)
        return pyproj.CRS.from_user_input(crs)
    except pyproj.exceptions.CRSError as exc:
        raise DemError(f"DEM {name}: {crs!r} is not a CRS pyproj knows: {exc}") from None


# ---------------------------------------------------------------------------- helpers
def _fmt_bounds(b: Bounds) -> str:
    return "(" + ", ".join(f"{v:.6f}" for v in b) + ")"


def _heights_on_grid(dem: DemBase, crs: Any, transform: Affine | Sequence[float],
                     shape: tuple[int, int]) -> np.ndarray:
    rows, cols = (int(v) for v in shape)
    t = transform if isinstance(transform, Affine) else Affine(*tuple(transform)[:6])
    rr, cc = np.mgrid[0:rows, 0:cols]
    x, y = pixel_to_map(t, rr, cc)
    dst = pyproj.CRS.from_user_input(crs)
    horizontal = dst.sub_crs_list[0] if dst.is_compound else dst
    if _is_lonlat(horizontal):
        lon, lat = x, y
    else:
        lon, lat = coords.transformer(horizontal, "EPSG:4326").transform(x, y)
    return dem.height(np.asarray(lon, float), np.asarray(lat, float))
