"""The output grid of an orthorectification: a CRS, a north-up geotransform and a shape.

:class:`OutputGrid` is a frozen, hashable, picklable value. Its geotransform is GDAL's
(corner-based: ``transform.c, transform.f`` is the outer corner of the top-left pixel), while
its pixel coordinates follow geoblock's convention (integers at pixel centres), so that::

    x, y = grid.xy(row, col)     # centre of output pixel (row, col)
    row, col = grid.rowcol(x, y) # inverse, float

:meth:`OutputGrid.from_bounds` reproduces gdalwarp's ``-t_srs CRS -tr XRES YRES -te XMIN YMIN
XMAX YMAX [-tap]`` grid exactly, so that a geoblock ortho and a gdalwarp one can be compared
pixel for pixel. The sizing rule is GDAL's ``GDALWarpCreateOutput`` (apps/gdalwarp_lib.cpp,
GDAL >= 3.8, ``ComputePixelsFromResAndExtent``)::

    cols = max(1, std::round((xmax - xmin) / xres))        # round half away from zero
    rows = max(1, std::round(|ymax - ymin| / yres))
    transform = (xmin, xres, 0, ymax, 0, -yres)             # origin at (xmin, ymax)

and with ``-tap`` (``bTargetAlignedPixels``) the bounds are first snapped outward::

    xmin = floor(xmin / xres + 1e-8) * xres;   xmax = ceil(xmax / xres - 1e-8) * xres
    ymin = floor(ymin / yres + 1e-8) * yres;   ymax = ceil(ymax / yres - 1e-8) * yres

(older GDAL computed ``(int)((xmax - xmin + xres / 2) / xres)``, the same rounding up to the
last bit). The right and bottom edges of the grid are therefore ``xmin + cols * xres`` and
``ymax - rows * yres``, which may differ from the requested bounds by up to half a pixel.

:meth:`OutputGrid.check` refuses grids that cannot be meant (:class:`~geoblock.errors.GridError`,
naming the argument and the size the grid would have had): more than ``2**31 - 1`` pixels per
side or more than ``max_pixels`` (default :data:`MAX_PIXELS`) in all, fewer than 2 x 2 pixels,
or pixels larger than 1 degree in a geographic CRS. :meth:`OutputGrid.for_model` applies it;
:meth:`OutputGrid.from_bounds` does not (it is gdalwarp's grid, whatever it is).

The default resolution of :meth:`OutputGrid.for_model` is the image's ground sample distance
rounded to the nearest (in ratio) "nice" number ``{1, 2, 2.5, 5} x 10**k``
(:func:`nice_resolution`), on a grid aligned to multiples of it, so that orthos of the same
sensor made with default options share one grid and can be mosaicked.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import pyproj
from affine import Affine

from geoblock import coords
from geoblock.errors import GridError
from geoblock.models.base import image_outline
from geoblock.ortho.limits import MAX_DEGREES, MAX_PIXELS, MAX_SIDE, MIN_SIDE
from geoblock.pixels import corner_to_centre, pixel_to_map
from geoblock.typing import ArrayLike

if TYPE_CHECKING:
    from geoblock.dem.protocol import DemSource
    from geoblock.io.dem import EngineDem
    from geoblock.models.protocol import SensorModel

__all__ = ["MAX_PIXELS", "OVERSAMPLING_LIMIT", "OutputGrid", "check_oversampling",
           "nice_resolution"]

#: An output pixel more than this many times finer than the image's ground sample distance
#: adds no detail and costs its square in time and space: :func:`check_oversampling` warns.
OVERSAMPLING_LIMIT = 10.0

_TAP_EPS = 1e-8  # gdalwarp's tolerance when snapping -tap bounds

#: mantissas of the "nice" resolutions
NICE_MANTISSAS = (1.0, 2.0, 2.5, 5.0)


def nice_resolution(value: float) -> float:
    """The "nice" number ``{1, 2, 2.5, 5} x 10**k`` nearest to ``value`` in ratio.

    Nearest in ratio: ``|log(value / nice)|`` is smallest (ties go to the finer one), so the
    boundaries sit at the geometric means of neighbours (1.41, 2.24, 3.54, 7.07 x 10**k), away
    from the usual nominal GSDs (0.3, 0.5, 1.5, 2.5, 5, 10, 20 m). The result is the double
    nearest to the decimal number (``0.2`` is ``float("2e-1")``).

    Parameters
    ----------
    value : float
        Positive and finite.

    Returns
    -------
    float

    Raises
    ------
    GridError
        ``value`` is not positive and finite.
    """
    v = float(value)
    if not (math.isfinite(v) and v > 0):
        raise GridError(f"nice_resolution: need a positive finite value, got {value!r}",
                        parameter="resolution")
    e = math.floor(math.log10(v))
    candidates = [float(f"{m:g}e{k}") for k in (e - 1, e, e + 1) for m in NICE_MANTISSAS]
    return min(candidates, key=lambda c: (abs(math.log(v / c)), c))


def _name(names: Mapping[str, str] | None, key: str) -> str:
    return (names or {}).get(key, key)


def _fmt_res(res: tuple[float, float]) -> str:
    return f"{res[0]:g}" if res[0] == res[1] else f"{res[0]:g} {res[1]:g}"


def _round_half_away(v: float) -> int:
    """C's ``std::round`` (half away from zero) for a finite double."""
    f = math.floor(v)
    return int(f + 1) if v - f >= 0.5 else int(f)


def _resolution_pair(resolution: float | tuple[float, float]) -> tuple[float, float]:
    if np.ndim(resolution) == 0:
        xres = yres = float(resolution)  # type: ignore[arg-type]
    else:
        xres, yres = (float(v) for v in resolution)  # type: ignore[union-attr]
    if not (math.isfinite(xres) and math.isfinite(yres) and xres > 0 and yres > 0):
        raise GridError(f"resolution must be positive and finite, got {resolution!r}",
                        parameter="resolution")
    return xres, yres


def _crs(value: Any, where: str) -> pyproj.CRS:
    """``pyproj.CRS.from_user_input(value)``; a CRS pyproj cannot read is a :class:`GridError`
    (``parameter="crs"``)."""
    try:
        return pyproj.CRS.from_user_input(value)
    except pyproj.exceptions.CRSError as exc:
        detail = " ".join(str(exc).split())
        raise GridError(f"{where}: {value!r} is not a CRS pyproj knows ({detail})",
                        parameter="crs") from exc


@dataclass(frozen=True, eq=False)
class OutputGrid:
    """A north-up raster grid in a map CRS.

    Parameters
    ----------
    crs : pyproj.CRS
        The grid's CRS (anything ``pyproj.CRS.from_user_input`` takes is converted).
    transform : affine.Affine
        GDAL geotransform, corner-based: ``x = c + a * (col + 0.5)``, ``y = f + e * (row + 0.5)``
        at the centre of pixel ``(row, col)``. North-up: ``b = d = 0``, ``a > 0``, ``e < 0``.
    shape : (int, int)
        ``(rows, cols)``, both positive.

    Raises
    ------
    GridError
        ``crs`` is not a CRS pyproj reads (``parameter="crs"``).
    ValueError
        The transform is not north-up or not finite, or the shape is not positive.

    Notes
    -----
    Equality, hashing, pickling and the dask token all go through :meth:`to_dict` (CRS as
    WKT), so two grids are equal exactly when their CRS WKT, transform and shape are.
    """

    crs: pyproj.CRS
    transform: Affine
    shape: tuple[int, int]

    def __post_init__(self) -> None:
        crs = _crs(self.crs, "OutputGrid")
        t = self.transform
        if not isinstance(t, Affine):
            t = Affine(*tuple(t)[:6])
        if t.b != 0.0 or t.d != 0.0 or not t.a > 0.0 or not t.e < 0.0:
            raise ValueError(
                f"OutputGrid: the transform must be north-up (b = d = 0, a > 0, e < 0), got {t!r}"
            )
        if not all(math.isfinite(v) for v in tuple(t)[:6]):
            raise ValueError(f"OutputGrid: the transform must be finite, got {t!r}")
        rows, cols = (int(v) for v in self.shape)
        if rows <= 0 or cols <= 0:
            raise ValueError(f"OutputGrid: shape must be positive, got {self.shape!r}")
        object.__setattr__(self, "crs", crs)
        object.__setattr__(self, "transform", t)
        object.__setattr__(self, "shape", (rows, cols))

    # ------------------------------------------------------------------ constructors
    @classmethod
    def from_bounds(
        cls,
        crs: pyproj.CRS | str | int,
        bounds: tuple[float, float, float, float],
        resolution: float | tuple[float, float],
        *,
        align: bool = False,
    ) -> OutputGrid:
        """gdalwarp's ``-t_srs CRS -tr XRES YRES -te XMIN YMIN XMAX YMAX [-tap]`` grid.

        Parameters
        ----------
        crs : pyproj.CRS or str or int
            Output CRS.
        bounds : (float, float, float, float)
            ``(xmin, ymin, xmax, ymax)`` in CRS units.
        resolution : float or (float, float)
            Pixel size ``xres`` (and ``yres``), CRS units, positive.
        align : bool
            gdalwarp's ``-tap``: snap the bounds outward to multiples of the resolution first.

        Returns
        -------
        OutputGrid
            Origin ``(xmin, ymax)``; ``cols = max(1, round((xmax - xmin) / xres))`` and
            ``rows = max(1, round((ymax - ymin) / yres))``, rounding half away from zero, as
            in GDAL's ``GDALWarpCreateOutput`` (module docstring).
        """
        xres, yres = _resolution_pair(resolution)
        xmin, ymin, xmax, ymax = (float(v) for v in bounds)
        if not all(math.isfinite(v) for v in (xmin, ymin, xmax, ymax)):
            raise GridError(f"from_bounds: bounds must be finite, got {bounds!r}",
                            parameter="bounds")
        if not (xmax > xmin and ymax > ymin):
            raise GridError(f"from_bounds: need xmin < xmax and ymin < ymax, got {bounds!r}",
                            parameter="bounds")
        if align:
            xmin = math.floor(xmin / xres + _TAP_EPS) * xres
            xmax = math.ceil(xmax / xres - _TAP_EPS) * xres
            ymin = math.floor(ymin / yres + _TAP_EPS) * yres
            ymax = math.ceil(ymax / yres - _TAP_EPS) * yres
        cols = max(1, _round_half_away((xmax - xmin) / xres))
        rows = max(1, _round_half_away(abs(ymax - ymin) / yres))
        return cls(_crs(crs, "OutputGrid"), Affine(xres, 0.0, xmin, 0.0, -yres, ymax),
                   (rows, cols))

    @classmethod
    def for_model(
        cls,
        model: SensorModel,
        dem: EngineDem,
        *,
        crs: pyproj.CRS | str | int | None = None,
        resolution: float | tuple[float, float] | None = None,
        bounds: tuple[float, float, float, float] | None = None,
        align: bool = True,
        max_pixels: int | None = MAX_PIXELS,
    ) -> OutputGrid:
        """The default output grid of an image: its UTM zone, its GSD, its footprint.

        Parameters
        ----------
        model : SensorModel
            Only ``shape``, ``height_range``, ``backproject`` and ``footprint`` are used.
        dem : DemSource, float, or anything geoblock.open_dem opens
            Terrain heights above the ellipsoid (a number means a constant DEM).
        crs : pyproj.CRS or str or int, optional
            Default: :func:`geoblock.coords.utm_crs` of the footprint.
        resolution : float or (float, float), optional
            CRS units. Default: the ground sample distance at the image centre, in CRS units,
            rounded to the nearest nice number ``{1, 2, 2.5, 5} x 10**k``
            (:func:`nice_resolution`: 1.99987... m gives 2 m, 0.31 m gives 0.25 m), so that
            orthos of one sensor made with the defaults share the resolution (and, with
            ``align``, the grid) and mosaic together. The GSD is ``sqrt(|det J|)`` where
            ``J = d(x, y)/d(col, row)`` is the central difference of the backprojection of
            the centre pixel's neighbours (+-0.5 px) at the DEM height there, i.e. the side
            of the square with the area of the centre pixel on the ground. Pass
            ``resolution`` for any other value.
        bounds : (float, float, float, float), optional
            ``(xmin, ymin, xmax, ymax)`` in CRS units. Default: the bounding box, in the output
            CRS, of the image outline (pixel edges, ``model.footprint``) backprojected at the
            minimum and at the maximum DEM height over the scene, which contains the footprint
            on the terrain.
        align : bool
            Snap the bounds outward to multiples of the resolution (gdalwarp ``-tap``).
        max_pixels : int or None
            The grid is checked (:meth:`check`) with this limit; None skips the check.

        Returns
        -------
        OutputGrid

        Raises
        ------
        GridError
            The grid is impossible (:meth:`check`), or the CRS, resolution or bounds are
            invalid.
        """
        from geoblock.dem.intersect import as_dem_source, localize

        dem = as_dem_source(dem)
        rows, cols = model.shape
        rc, cc = (rows - 1) / 2.0, (cols - 1) / 2.0
        centre, _ = localize(model, rc, cc, dem, warn=False)
        h_centre = float(centre.h)
        if not math.isfinite(h_centre):  # no DEM under the centre: the model's mid height
            h_centre = 0.5 * (model.height_range[0] + model.height_range[1])

        if crs is None or bounds is None:
            lon, lat = _scene_outline(model, dem, h_centre)
            if crs is None:
                crs = coords.utm_crs(lon, lat)
        crs = _crs(crs, "OutputGrid.for_model")
        if resolution is None:
            resolution = nice_resolution(_gsd(model, rc, cc, h_centre, crs))
        if bounds is None:
            x, y = coords.transformer("EPSG:4326", crs).transform(lon, lat)
            x, y = np.asarray(x), np.asarray(y)
            ok = np.isfinite(x) & np.isfinite(y)
            if not ok.any():
                raise GridError(
                    "OutputGrid.for_model: the image outline does not project into the CRS "
                    f"{crs.name!r}", parameter="crs"
                )
            bounds = (x[ok].min(), y[ok].min(), x[ok].max(), y[ok].max())
        grid = cls.from_bounds(crs, bounds, resolution, align=align)
        if max_pixels is not None:
            grid.check(max_pixels=max_pixels)
        return grid

    def check(
        self,
        *,
        max_pixels: int = MAX_PIXELS,
        names: Mapping[str, str] | None = None,
    ) -> OutputGrid:
        """Refuse a grid that cannot be meant, before anything is computed on it.

        Parameters
        ----------
        max_pixels : int
            Largest number of pixels (``rows * cols``).
        names : mapping of str to str, optional
            How to name ``"resolution"``, ``"bounds"`` and ``"max_pixels"`` in the message
            (the command line passes ``{"resolution": "--res", ...}``).

        Returns
        -------
        OutputGrid
            ``self``.

        Raises
        ------
        GridError
            In a geographic CRS, pixels larger than 1 degree (``parameter="resolution"``);
            more than ``2**31 - 1`` pixels per side or more than ``max_pixels`` in all, or
            fewer than 2 x 2 pixels (``parameter="resolution"``). The message says the size
            the grid would have had.
        """
        rows, cols = self.shape
        res = self.resolution
        res_name, bounds_name = _name(names, "resolution"), _name(names, "bounds")
        crs_name = self.crs.to_string() if self.crs.to_epsg() else self.crs.name
        where = (f"{res_name} {_fmt_res(res)} over {bounds_name} "
                 f"({', '.join(f'{v:.10g}' for v in self.bounds)}) in {crs_name}")
        size = f"{rows} x {cols} pixels"
        if self.crs.is_geographic and max(res) > MAX_DEGREES:
            raise GridError(
                f"{res_name} {_fmt_res(res)}: {crs_name} is a geographic CRS, its resolution is "
                f"in degrees, and pixels larger than {MAX_DEGREES:g} degree are refused (the "
                f"grid would be {size}); give the resolution in degrees (1e-05 degree is "
                "about 1.1 m) or choose a projected CRS", parameter="resolution")
        if max(rows, cols) > MAX_SIDE:
            raise GridError(
                f"{where} would make a grid of {size}: more than 2**31 - 1 = {MAX_SIDE} pixels "
                f"per side; pass a coarser {res_name} or smaller {bounds_name}",
                parameter="resolution")
        if rows * cols > max_pixels:
            raise GridError(
                f"{where} would make a grid of {size} ({rows * cols:.3g} pixels): more than "
                f"{_name(names, 'max_pixels')} = {max_pixels} ({max_pixels:.3g}); pass a coarser "
                f"{res_name} or smaller {bounds_name}, or raise {_name(names, 'max_pixels')}",
                parameter="resolution")
        if min(rows, cols) < MIN_SIDE:
            raise GridError(
                f"{where} would make a grid of {size}: fewer than {MIN_SIDE} x {MIN_SIDE}; pass "
                f"a finer {res_name} or larger {bounds_name}", parameter="resolution")
        return self

    # ------------------------------------------------------------------ geometry
    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """``(xmin, ymin, xmax, ymax)`` of the pixel edges, CRS units."""
        t = self.transform
        rows, cols = self.shape
        return (t.c, t.f + t.e * rows, t.c + t.a * cols, t.f)

    @property
    def resolution(self) -> tuple[float, float]:
        """``(xres, yres)``, positive, CRS units."""
        return (self.transform.a, -self.transform.e)

    @property
    def width(self) -> int:
        """Number of columns."""
        return self.shape[1]

    @property
    def height(self) -> int:
        """Number of rows."""
        return self.shape[0]

    def xy(self, rows: ArrayLike, cols: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Map coordinates of pixel centres.

        Parameters
        ----------
        rows, cols : array_like, (*S,)
            Pixel coordinates (integers at pixel centres), broadcast together.

        Returns
        -------
        x, y : ndarray, (*S,) float64
            CRS units.
        """
        r, c = np.broadcast_arrays(
            np.asarray(rows, dtype=np.float64), np.asarray(cols, dtype=np.float64)
        )
        return pixel_to_map(self.transform, r, c)

    def rowcol(self, x: ArrayLike, y: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Pixel coordinates (float, integers at centres) of map points; inverse of :meth:`xy`.

        Parameters
        ----------
        x, y : array_like, (*S,)
            CRS units, broadcast together.

        Returns
        -------
        rows, cols : ndarray, (*S,) float64
        """
        t = self.transform
        x, y = np.broadcast_arrays(np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64))
        return corner_to_centre((y - t.f) / t.e, (x - t.c) / t.a)

    def lonlat(self, rows: ArrayLike, cols: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """WGS84 longitude and latitude (degrees) of pixel centres, (*S,) each."""
        x, y = self.xy(rows, cols)
        lon, lat = coords.transformer(self.crs, "EPSG:4326").transform(x, y)
        return np.asarray(lon, dtype=np.float64), np.asarray(lat, dtype=np.float64)

    # ------------------------------------------------------------------ tiling
    def __getitem__(self, key: Any) -> OutputGrid:
        """``grid[r0:r1, c0:c1]``: the sub-grid (same CRS and resolution, shifted origin).

        Slices follow Python's rules (negative indices, clipping); steps other than 1 and
        empty results raise ``IndexError``.
        """
        if not (
            isinstance(key, tuple) and len(key) == 2 and all(isinstance(k, slice) for k in key)
        ):
            raise TypeError(
                f"OutputGrid indices must be two slices (grid[r0:r1, c0:c1]), got {key!r}"
            )
        starts = []
        sizes = []
        for k, n in zip(key, self.shape, strict=True):
            start, stop, step = k.indices(n)
            if step != 1:
                raise IndexError(f"OutputGrid slices must have step 1, got {k!r}")
            if stop <= start:
                raise IndexError(f"OutputGrid slice {k!r} is empty for size {n}")
            starts.append(start)
            sizes.append(stop - start)
        t = self.transform
        new = Affine(t.a, 0.0, t.c + t.a * starts[1], 0.0, t.e, t.f + t.e * starts[0])
        return OutputGrid(self.crs, new, (sizes[0], sizes[1]))

    def chunks(self, size: int | tuple[int, int]) -> list[tuple[slice, slice]]:
        """Tiles covering the grid, row-major.

        Parameters
        ----------
        size : int or (int, int)
            Tile ``(rows, cols)``; the last tile of a row or column may be smaller.

        Returns
        -------
        list of (slice, slice)
            ``(row_slice, col_slice)`` with explicit starts and stops, no overlap.
        """
        if np.ndim(size) == 0:
            sr = sc = int(size)  # type: ignore[arg-type]
        else:
            sr, sc = (int(v) for v in size)  # type: ignore[union-attr]
        if sr <= 0 or sc <= 0:
            raise ValueError(f"chunks: size must be positive, got {size!r}")
        rows, cols = self.shape
        return [
            (slice(r, min(r + sr, rows)), slice(c, min(c + sc, cols)))
            for r in range(0, rows, sr)
            for c in range(0, cols, sc)
        ]

    # ------------------------------------------------------------------ value semantics
    def to_dict(self) -> dict[str, Any]:
        """JSON-safe state:
        ``{"crs": WKT, "transform": [a, b, c, d, e, f], "shape": [rows, cols]}``."""
        return {
            "crs": self.crs.to_wkt(),
            "transform": [float(v) for v in tuple(self.transform)[:6]],
            "shape": [int(self.shape[0]), int(self.shape[1])],
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> OutputGrid:
        """Rebuild a grid from :meth:`to_dict` output."""
        return cls(
            pyproj.CRS.from_wkt(data["crs"]), Affine(*data["transform"]), tuple(data["shape"])
        )

    def _key(self) -> str:
        return json.dumps(self.to_dict(), sort_keys=True, separators=(",", ":"))

    def __eq__(self, other: object) -> bool:
        if type(other) is not type(self):
            return NotImplemented
        return self._key() == other._key()

    def __hash__(self) -> int:
        return hash(self._key())

    def __reduce__(
        self,
    ) -> tuple[Callable[[Mapping[str, Any]], OutputGrid], tuple[dict[str, Any]]]:
        return (type(self).from_dict, (self.to_dict(),))

    def __dask_tokenize__(self) -> tuple[str, str]:
        return ("geoblock.OutputGrid", self._key())

    def __repr__(self) -> str:
        rows, cols = self.shape
        xres, yres = self.resolution
        name = self.crs.to_string() if self.crs.to_epsg() else self.crs.name
        xmin, ymin, xmax, ymax = self.bounds
        return (
            f"<OutputGrid {rows}x{cols} px, {name}, res ({xres:g}, {yres:g}), "
            f"bounds ({xmin:.6g}, {ymin:.6g}, {xmax:.6g}, {ymax:.6g})>"
        )


def _scene_outline(
    model: SensorModel, dem: DemSource, h_centre: float
) -> tuple[np.ndarray, np.ndarray]:
    """``(lon, lat)`` of the image outline at the DEM's min and max heights over the scene.

    The DEM height range is looked up over the outline's lon/lat box; as the box itself depends
    on the heights, this is repeated (at most 4 times) until the height range stops growing.
    """
    lo = hi = h_centre
    lon, lat = _outline_at(model, lo, hi)
    for _ in range(4):
        box = (float(lon.min()), float(lat.min()), float(lon.max()), float(lat.max()))
        new_lo, new_hi = (float(v) for v in dem.height_range(box))
        if not (math.isfinite(new_lo) and math.isfinite(new_hi)):
            break  # no DEM there: keep the outline at the centre height
        new_lo, new_hi = min(new_lo, lo), max(new_hi, hi)
        if new_lo == lo and new_hi == hi:
            break
        lo, hi = new_lo, new_hi
        lon, lat = _outline_at(model, lo, hi)
    return lon, lat


def _outline_at(model: SensorModel, lo: float, hi: float) -> tuple[np.ndarray, np.ndarray]:
    """Finite ``(lon, lat)`` of the image outline (pixel edges) at heights ``lo`` and ``hi``."""
    pts = [image_outline(model, h, n=32) for h in sorted({lo, hi})]
    lon = np.concatenate([p.lon for p in pts])
    lat = np.concatenate([p.lat for p in pts])
    ok = np.isfinite(lon) & np.isfinite(lat)
    if not ok.any():
        raise ValueError("OutputGrid.for_model: the image outline does not backproject")
    return lon[ok], lat[ok]


def check_oversampling(grid: OutputGrid, model: SensorModel, dem: Any,
                       names: Mapping[str, str] | None = None) -> float | None:
    """Warn when ``grid``'s pixels are over :data:`OVERSAMPLING_LIMIT` (10) times finer than
    the image's ground sample distance (a likely typo: ``--res 0.02`` on a 0.5 m image).

    Parameters
    ----------
    grid : OutputGrid
    model : SensorModel
        The image's model (its GSD is taken at the image centre, on the DEM).
    dem : DemSource or anything :func:`geoblock.localize` takes
    names : mapping of str to str, optional
        How to name ``"resolution"`` in the message (the command line: ``--res``).

    Returns
    -------
    float or None
        The image's GSD in ``grid``'s CRS units, or None when it cannot be computed (no
        warning then).

    Warns
    -----
    ResolutionWarning
        Naming the resolution asked for and the image's GSD.
    """
    import warnings

    from geoblock.dem.intersect import as_dem_source
    from geoblock.errors import ResolutionWarning

    rows, cols = model.shape
    rc, cc = (rows - 1) / 2.0, (cols - 1) / 2.0
    try:
        h = _centre_height(model, rc, cc, as_dem_source(dem))
        gsd = _gsd(model, rc, cc, h, grid.crs)
    except (ValueError, ArithmeticError):  # no GSD at the centre: nothing to compare with
        return None
    finest = min(grid.resolution)
    if finest * OVERSAMPLING_LIMIT < gsd:
        units = "degree" if grid.crs.is_geographic else "m"
        warnings.warn(
            f"{_name(names, 'resolution')} {_fmt_res(grid.resolution)} is "
            f"{gsd / finest:.0f} times finer than the image's ground sample distance "
            f"({gsd:.3g} {units} at its centre): {grid.shape[0]} x {grid.shape[1]} output "
            "pixels, no more detail than at the GSD; check the value (a typo such as 0.02 "
            "for 0.2?)", ResolutionWarning, stacklevel=2)
    return gsd


#: Fixed-point steps of :func:`_centre_height`.
_CENTRE_HEIGHT_STEPS = 3


def _centre_height(model: SensorModel, rc: float, cc: float, dem: Any) -> float:
    """The DEM height near the ground point of image point ``(rc, cc)``, metres: a few
    fixed-point steps (backproject at ``h``, read the DEM there) from the model's mid height.

    For the GSD only: the ground sample distance changes with the height by about
    ``dh / range`` (1e-3 for 1 km on a 700 km orbit), so a height within the terrain's relief
    is enough, and this avoids the ray-DEM intersection's kernels (a fixed cost per command).
    The mid height when the DEM gives no height there."""
    h = 0.5 * (float(model.height_range[0]) + float(model.height_range[1]))
    for _ in range(_CENTRE_HEIGHT_STEPS):
        g = model.backproject(np.array([rc]), np.array([cc]), np.array([h]))
        if not (np.isfinite(g.lon).all() and np.isfinite(g.lat).all()):
            break
        dem_h = float(np.asarray(dem.height(g.lon, g.lat), dtype=np.float64)[0])
        if not math.isfinite(dem_h) or abs(dem_h - h) < 1.0:
            h = dem_h if math.isfinite(dem_h) else h
            break
        h = dem_h
    return h


def _gsd(model: SensorModel, rc: float, cc: float, h: float, crs: pyproj.CRS) -> float:
    """Ground sample distance (CRS units) at image point ``(rc, cc)`` on height ``h``."""
    r = np.array([rc, rc, rc - 0.5, rc + 0.5])
    c = np.array([cc - 0.5, cc + 0.5, cc, cc])
    g = model.backproject(r, c, np.full(4, h))
    x, y = coords.transformer("EPSG:4326", crs).transform(g.lon, g.lat)
    x, y = np.asarray(x), np.asarray(y)
    # d(x, y)/d(col) and d(x, y)/d(row), per pixel
    jc = np.array([x[1] - x[0], y[1] - y[0]])
    jr = np.array([x[3] - x[2], y[3] - y[2]])
    gsd = math.sqrt(abs(jc[0] * jr[1] - jc[1] * jr[0]))
    if not (math.isfinite(gsd) and gsd > 0):
        raise ValueError(
            "OutputGrid.for_model: cannot compute the ground sample distance at the image "
            "centre; pass resolution="
        )
    return gsd
