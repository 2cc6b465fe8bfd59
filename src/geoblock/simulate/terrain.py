"""Synthetic terrain with known truth: fractal and ridged DEMs, and "measured" DEMs from them.

* :class:`Grid` is a north-up raster grid (affine transform, shape, CRS);
  :meth:`Grid.from_bounds` and :meth:`Grid.around` build one.
* :func:`fractal_terrain` (spectral fBm) and :func:`ridged_terrain` (ridged multifractal) make
  a :class:`Terrain` whose heights span exactly the requested relief range and, optionally,
  whose steepest slope is the requested one (Teo et al.'s Taiwan block: 0-3800 m, slopes to
  about 70 degrees; Aguilar et al.'s Almeria: 50-850 m). The same seed gives the same terrain.
* :func:`measured_dem` derives a DEM as a producer would deliver it: the truth resampled to a
  coarser grid spacing plus spatially correlated and white noise, scaled so that its RMSEz
  against the truth is the requested one (Aguilar et al.: 2 / 5 / 20 m spacing with 0.31 /
  1.75 / 5.82 m RMSEz; Teo et al.: a 40 m DEM).

A :class:`Terrain` becomes a DEM source with :meth:`Terrain.to_dem` and a GeoTIFF with
:meth:`Terrain.write` (through :func:`geoblock.io.write_dem`, which records the vertical datum).
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pyproj
import scipy.fft as _fft
from affine import Affine

from geoblock import coords
from geoblock._affine import apply as affine_apply
from geoblock.dem.grid import GridDem, _is_lonlat
from geoblock.dem.sampling import sample
from geoblock.errors import DemError
from geoblock.pixels import centre_to_corner, corner_to_centre, pixel_centres

__all__ = ["Grid", "Terrain", "fractal_terrain", "measured_dem", "ridged_terrain"]

_DEG_M = math.radians(1.0) * coords.WGS84_A  # metres per degree of latitude (sphere of radius a)
_WORKERS = -1  # scipy.fft threads: all cores (the transforms' values do not depend on it)


def _horizontal(crs: pyproj.CRS) -> pyproj.CRS:
    return crs.sub_crs_list[0] if crs.is_compound else crs


# ---------------------------------------------------------------------------- grid
@dataclass(frozen=True, eq=False)
class Grid:
    """A north-up raster grid.

    Attributes
    ----------
    transform : affine.Affine
        GDAL-style geotransform (pixel corners) with no rotation and a negative y step.
    shape : (int, int)
        ``(rows, cols)``.
    crs : pyproj.CRS
        Horizontal CRS, geographic (degrees) or projected (metres).
    """

    transform: Affine
    shape: tuple[int, int]
    crs: pyproj.CRS

    def __post_init__(self) -> None:
        t = self.transform
        t = t if isinstance(t, Affine) else Affine(*tuple(t)[:6])
        if t.b != 0 or t.d != 0 or t.a <= 0 or t.e >= 0:
            raise DemError(f"Grid: the transform must be north-up (a > 0, e < 0, no rotation), "
                           f"got {tuple(t)[:6]}")
        shape = (int(self.shape[0]), int(self.shape[1]))
        if min(shape) < 2:
            raise DemError(f"Grid: shape must be at least 2 x 2, got {self.shape}")
        crs = pyproj.CRS.from_user_input(self.crs)
        object.__setattr__(self, "transform", t)
        object.__setattr__(self, "shape", shape)
        object.__setattr__(self, "crs", _horizontal(crs))

    @classmethod
    def from_bounds(cls, bounds: tuple[float, float, float, float], resolution: float,
                    crs: Any = "EPSG:4326") -> Grid:
        """The grid of square cells of side ``resolution`` covering ``bounds``.

        Parameters
        ----------
        bounds : (west, south, east, north)
            In ``crs`` units (degrees or metres); the grid starts at the north-west corner and
            covers at least the bounds (whole cells).
        resolution : float
            Cell side in ``crs`` units.
        crs : pyproj.CRS or str
        """
        w, s, e, n = (float(v) for v in bounds)
        res = float(resolution)
        if not (res > 0 and e > w and n > s):
            raise DemError(f"Grid.from_bounds: need east > west, north > south and resolution > 0, "
                           f"got bounds {bounds} and resolution {resolution}")
        cols = max(2, math.ceil((e - w) / res - 1e-9))
        rows = max(2, math.ceil((n - s) / res - 1e-9))
        return cls(Affine(res, 0.0, w, 0.0, -res, n), (rows, cols), crs)

    @classmethod
    def around(cls, lon: float, lat: float, size_m: float | tuple[float, float],
               resolution_m: float, crs: Any = None) -> Grid:
        """A grid of about ``size_m`` (east, north) metres centred on ``(lon, lat)``.

        Parameters
        ----------
        lon, lat : float
            Centre, degrees.
        size_m : float or (float, float)
            Extent east-west and north-south, metres.
        resolution_m : float
            Cell side, metres (converted to degrees at ``lat`` for a geographic ``crs``).
        crs : pyproj.CRS or str, optional
            Default: the UTM zone of the centre.
        """
        size = np.broadcast_to(np.asarray(size_m, dtype=np.float64), (2,))  # one or a pair
        sx, sy = float(size[0]), float(size[1])
        crs = coords.utm_crs(lon, lat) if crs is None else pyproj.CRS.from_user_input(crs)
        horizontal = _horizontal(crs)
        if horizontal.is_geographic:
            if not _is_lonlat(horizontal):
                raise DemError("Grid.around: a geographic CRS must be WGS84 longitude/latitude")
            res = resolution_m / _DEG_M
            hx = 0.5 * sx / (_DEG_M * math.cos(math.radians(lat)))
            hy = 0.5 * sy / _DEG_M
            return cls.from_bounds((lon - hx, lat - hy, lon + hx, lat + hy), res, horizontal)
        x, y = coords.transformer("EPSG:4326", horizontal).transform(lon, lat)
        return cls.from_bounds((x - sx / 2, y - sy / 2, x + sx / 2, y + sy / 2), resolution_m,
                               horizontal)

    @property
    def is_geographic(self) -> bool:
        """Whether the grid's coordinates are degrees of longitude/latitude."""
        return bool(self.crs.is_geographic)

    @property
    def resolution(self) -> tuple[float, float]:
        """``(x, y)`` cell size in CRS units (both positive)."""
        return float(self.transform.a), float(-self.transform.e)

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """``(west, south, east, north)`` of the grid's outer edges, CRS units."""
        rows, cols = self.shape
        t = self.transform
        return (t.c, t.f + rows * t.e, t.c + cols * t.a, t.f)

    def xy(self) -> tuple[np.ndarray, np.ndarray]:
        """CRS coordinates of the cell centres: ``x`` (cols,), ``y`` (rows,)."""
        return pixel_centres(self.transform, self.shape)

    def lonlat(self) -> tuple[np.ndarray, np.ndarray]:
        """WGS84 longitude and latitude of every cell centre, degrees, (R, C) each."""
        x, y = self.xy()
        xx, yy = np.meshgrid(x, y)
        if _is_lonlat(self.crs):
            return xx, yy
        lon, lat = coords.transformer(self.crs, "EPSG:4326").transform(xx, yy)
        return np.asarray(lon, float), np.asarray(lat, float)

    def spacing_m(self) -> tuple[np.ndarray, float]:
        """Metric cell size: ``dx`` per row (rows,) and ``dy``, metres.

        Projected CRSs: the CRS units (metres assumed, as UTM). Geographic: on the sphere
        of radius WGS84 ``a``, ``dx`` shrinking with the cosine of each row's latitude.
        """
        rx, ry = self.resolution
        rows = self.shape[0]
        if self.is_geographic:
            _, y = self.xy()
            return rx * _DEG_M * np.cos(np.radians(y)), ry * _DEG_M
        factor = float(self.crs.axis_info[0].unit_conversion_factor or 1.0)
        return np.full(rows, rx * factor), ry * factor

    def with_spacing_m(self, spacing_m: float) -> Grid:
        """A grid over the same area (inside its outer edges) with cells of ``spacing_m`` metres."""
        w, s, e, n = self.bounds
        if self.is_geographic:
            lat = 0.5 * (s + n)
            step_y = spacing_m / _DEG_M
            step_x = step_y / math.cos(math.radians(lat))
        else:
            factor = float(self.crs.axis_info[0].unit_conversion_factor or 1.0)
            step_x = step_y = spacing_m / factor
        cols = int(math.floor((e - w) / step_x + 1e-9))
        rows = int(math.floor((n - s) / step_y + 1e-9))
        if min(rows, cols) < 2:
            raise DemError(f"a {spacing_m} m spacing leaves fewer than 2 x 2 posts in the grid "
                           f"{self.shape} of bounds {self.bounds}")
        return Grid(Affine(step_x, 0.0, w, 0.0, -step_y, n), (rows, cols), self.crs)


# ---------------------------------------------------------------------------- terrain
@dataclass(frozen=True, eq=False)
class Terrain:
    """Heights on a :class:`Grid`, with their vertical datum.

    Attributes
    ----------
    heights : ndarray, (R, C)
        Metres above ``vertical``, read-only float64.
    grid : Grid
    vertical : {"ellipsoid", "geoid"}
        The WGS84 ellipsoid, or the EGM96 geoid (then :meth:`to_dem` needs the geoid grid).
    """

    heights: np.ndarray
    grid: Grid
    vertical: str = "ellipsoid"

    def __post_init__(self) -> None:
        h = np.array(self.heights, dtype=np.float64)
        if h.shape != self.grid.shape:
            raise DemError(f"Terrain: heights {h.shape} do not match the grid {self.grid.shape}")
        if self.vertical not in ("ellipsoid", "geoid"):
            raise DemError(f"Terrain: vertical must be 'ellipsoid' or 'geoid', got "
                           f"{self.vertical!r}")
        h.flags.writeable = False
        object.__setattr__(self, "heights", h)

    @classmethod
    def _owning(cls, heights: np.ndarray, grid: Grid, vertical: str) -> Terrain:
        """A Terrain on ``heights`` (float64, C-contiguous, made here and referenced nowhere
        else) without the defensive copy of the constructor: a 2 m grid over 20 km is
        about 1 GB."""
        if heights.dtype != np.float64 or not heights.flags.c_contiguous:
            return cls(heights, grid, vertical)
        if heights.shape != grid.shape:
            raise DemError(f"Terrain: heights {heights.shape} do not match the grid {grid.shape}")
        if vertical not in ("ellipsoid", "geoid"):
            raise DemError(f"Terrain: vertical must be 'ellipsoid' or 'geoid', got {vertical!r}")
        heights.flags.writeable = False
        terrain = object.__new__(cls)
        object.__setattr__(terrain, "heights", heights)
        object.__setattr__(terrain, "grid", grid)
        object.__setattr__(terrain, "vertical", vertical)
        return terrain

    @property
    def transform(self) -> Affine:
        return self.grid.transform

    @property
    def crs(self) -> pyproj.CRS:
        return self.grid.crs

    @property
    def shape(self) -> tuple[int, int]:
        return self.grid.shape

    @property
    def relief(self) -> tuple[float, float]:
        """``(min, max)`` of the finite heights, metres above :attr:`vertical`."""
        return float(np.nanmin(self.heights)), float(np.nanmax(self.heights))

    def slope_deg(self) -> np.ndarray:
        """(R, C) terrain slope, degrees, from central differences (one-sided at the edges)."""
        dx, dy = self.grid.spacing_m()
        out = np.empty(self.shape)
        for r0, r1 in _strips(self.shape):
            out[r0:r1] = _slope_rows(self.heights, dx, dy, r0, r1)
        return out

    def to_dem(self, geoid: Any = None, interpolation: str = "bilinear") -> GridDem:
        """The terrain as a :class:`~geoblock.dem.GridDem` (heights above the ellipsoid).

        Parameters
        ----------
        geoid : Geoid, str or os.PathLike, optional
            For ``vertical="geoid"``: the EGM96 grid (default found by
            :func:`~geoblock.dem.find_geoid`).
        interpolation : {"bilinear", "nearest", "bicubic"}
        """
        undulation = None
        if self.vertical == "geoid":
            from geoblock.dem.geoid import find_geoid

            undulation = find_geoid(geoid)
        return GridDem(self.heights, self.grid.transform, self.grid.crs, geoid=undulation,
                       interpolation=interpolation)

    def with_vertical(self, vertical: str, geoid: Any = None) -> Terrain:
        """The same surface with heights above another datum (EGM96 undulation added/removed)."""
        if vertical == self.vertical:
            return self
        if vertical not in ("ellipsoid", "geoid"):
            raise DemError(f"Terrain: vertical must be 'ellipsoid' or 'geoid', got {vertical!r}")
        from geoblock.dem.geoid import find_geoid

        lon, lat = self.grid.lonlat()
        n = find_geoid(geoid).undulation(lon, lat)
        sign = -1.0 if vertical == "geoid" else 1.0
        return Terrain(self.heights + sign * n, self.grid, vertical)

    def write(self, path: str | os.PathLike[str], *, nodata: float = -9999.0,
              dtype: str = "float32") -> Path:
        """Write a GeoTIFF through :func:`geoblock.io.write_dem` (the datum is in the file)."""
        from geoblock.io.dem import write_dem

        return write_dem(path, self.heights, self.grid.transform, self.grid.crs, self.vertical,
                         nodata=nodata, dtype=dtype)

    def __repr__(self) -> str:
        lo, hi = self.relief
        return (f"<Terrain {self.shape[0]}x{self.shape[1]} {self.crs.name} heights {lo:.1f}.."
                f"{hi:.1f} m above the {self.vertical}>")


# ---------------------------------------------------------------------------- synthesis
def _padded(shape: tuple[int, int]) -> tuple[int, int]:
    """FFT size: the grid plus a quarter on each axis, so that the periodic field does not wrap."""
    pad = max(shape) // 4 + 8
    return shape[0] + pad, shape[1] + pad


def _wavenumbers(shape: tuple[int, int]) -> np.ndarray:
    """|k| in cycles per pixel for an rfft2 of ``shape`` (0 at DC)."""
    ky = np.fft.fftfreq(shape[0])[:, None]
    kx = np.fft.rfftfreq(shape[1])[None, :]
    return np.hypot(kx, ky)


#: posts per strip of the strip-wise loops (about 32 MB of float64): the memory of a pass is
#: a few strips, not a few grids
_STRIP_POSTS = 1 << 22


def _strips(shape: tuple[int, ...]) -> Iterator[tuple[int, int]]:
    """``(r0, r1)`` row ranges of about ``_STRIP_POSTS`` posts covering ``shape[0]`` rows."""
    rows, cols = shape[0], shape[1]
    step = max(1, _STRIP_POSTS // max(cols, 1))
    for r0 in range(0, rows, step):
        yield r0, min(rows, r0 + step)


def _slope_rows(h: np.ndarray, dx: np.ndarray, dy: float, r0: int, r1: int,
                degrees: bool = True) -> np.ndarray:
    """Slope of rows ``r0:r1`` of ``h`` exactly as :func:`numpy.gradient` on the whole grid
    gives it (one row of halo either side, one-sided differences at the grid's edges):
    degrees, or the gradient's norm (rise over run) with ``degrees=False``."""
    a, b = max(0, r0 - 1), min(h.shape[0], r1 + 1)
    gy, gx = np.gradient(h[a:b])
    gy, gx = gy[r0 - a: r1 - a], gx[r0 - a: r1 - a]
    gx /= dx[r0:r1, None]
    gy /= dy
    np.hypot(gx, gy, out=gx)
    return np.degrees(np.arctan(gx, out=gx), out=gx) if degrees else gx


def _scaled(field: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """``field`` (a fresh array, overwritten) scaled to span ``lo..hi`` exactly; C-contiguous."""
    zmin, zmax = float(field.min()), float(field.max())
    if not zmax > zmin:
        return np.full(field.shape, lo)
    out = np.ascontiguousarray(field, dtype=np.float64)
    out -= zmin
    out *= (hi - lo) / (zmax - zmin)
    out += lo
    return out


def _max_slope(h: np.ndarray, dx: np.ndarray, dy: float) -> float:
    """Steepest slope of ``h``, degrees (strip by strip: no full-size gradient arrays)."""
    steepest = max(float(_slope_rows(h, dx, dy, r0, r1, degrees=False).max())
                   for r0, r1 in _strips(h.shape))
    return float(np.degrees(np.arctan(steepest)))


def _finish(raw: np.ndarray, grid: Grid, relief: tuple[float, float], max_slope_deg: float | None,
            vertical: str, tolerance_deg: float = 0.25, max_iterations: int = 60) -> Terrain:
    """Scale ``raw`` (padded) to the relief range; tilt its spectrum to reach the slope target.

    The spectrum is multiplied by ``|k| ** -gamma`` (``gamma > 0`` smooths, ``< 0`` roughens);
    ``gamma`` is found by bisection (tolerance ``tolerance_deg`` on the steepest slope, at most
    ``max_iterations`` steps) because the steepest slope falls monotonically as ``gamma`` grows.
    """
    lo, hi = (float(v) for v in relief)
    if not (math.isfinite(lo) and math.isfinite(hi) and hi > lo):
        raise DemError(f"terrain: relief must be (low, high) with high > low, got {relief}")
    rows, cols = grid.shape
    if max_slope_deg is None:
        return Terrain._owning(_scaled(raw[:rows, :cols], lo, hi), grid, vertical)
    if not 0.0 < float(max_slope_deg) < 90.0:
        raise DemError(f"terrain: max_slope_deg must be in (0, 90), got {max_slope_deg}")
    dx, dy = grid.spacing_m()
    size = raw.shape
    spectrum = _fft.rfft2(raw, workers=_WORKERS)
    del raw  # the caller passes its only reference: the padded field is freed here
    # the tilt |k / k_ref| ** -gamma as exp(-gamma log|k / k_ref|), pivoting on the longest
    # wavelength; one real and one complex scratch array serve every bisection step
    log_k = _wavenumbers(size)
    log_k[0, 0] = 1.0
    log_k *= max(size)
    np.log(log_k, out=log_k)
    tilt = np.empty_like(log_k)
    tilted = np.empty_like(spectrum)

    def surface(gamma: float) -> np.ndarray:
        np.multiply(log_k, -gamma, out=tilt)
        np.exp(tilt, out=tilt)
        np.multiply(spectrum, tilt, out=tilted)
        z = _fft.irfft2(tilted, s=size, workers=_WORKERS)
        return _scaled(z[:rows, :cols], lo, hi)

    target = float(max_slope_deg)
    g_lo, g_hi = -1.5, 8.0  # slope(g_lo) high, slope(g_hi) low
    s_lo, s_hi = _max_slope(surface(g_lo), dx, dy), _max_slope(surface(g_hi), dx, dy)
    if not s_hi <= target <= s_lo:
        raise DemError(
            f"terrain: a steepest slope of {target} degrees is out of reach for a relief of "
            f"{hi - lo:.0f} m on this grid (reachable {s_hi:.1f}..{s_lo:.1f} degrees): change the "
            "relief, the grid extent or its resolution"
        )
    best: np.ndarray | None = None
    for _ in range(max_iterations):
        g = 0.5 * (g_lo + g_hi)
        best = None  # free the previous surface before making the next
        best = surface(g)
        s = _max_slope(best, dx, dy)
        if abs(s - target) <= tolerance_deg:
            break
        if s > target:
            g_lo = g
        else:
            g_hi = g
    if best is None:
        raise DemError(f"terrain: max_iterations must be >= 1, got {max_iterations}")
    return Terrain._owning(best, grid, vertical)


def fractal_terrain(
    grid: Grid,
    relief: tuple[float, float] = (0.0, 1000.0),
    *,
    hurst: float = 0.8,
    max_slope_deg: float | None = None,
    seed: int = 0,
    vertical: str = "ellipsoid",
) -> Terrain:
    """Fractional Brownian terrain by spectral synthesis.

    White Gaussian noise is filtered in the Fourier domain by ``|k| ** -(hurst + 1)`` (power
    spectrum ``|k| ** -(2 hurst + 2)``) on a grid padded by a quarter (so that the periodic
    field does not wrap), cropped, and scaled so that its lowest and highest posts are
    exactly ``relief``.

    Parameters
    ----------
    grid : Grid
    relief : (float, float)
        Lowest and highest height, metres above ``vertical``.
    hurst : float
        Hurst exponent in (0, 1): 0.8 rolling hills, 0.5 rougher.
    max_slope_deg : float, optional
        The steepest slope wanted (degrees, from central differences on the grid): the
        spectrum is tilted until the steepest post has it (within 0.25 degree).
    seed : int
        Same seed, same terrain.
    vertical : {"ellipsoid", "geoid"}

    Returns
    -------
    Terrain

    Raises
    ------
    DemError
        Invalid relief or slope, or a slope out of reach on this grid.
    """
    if not 0.0 < hurst < 1.5:
        raise DemError(f"fractal_terrain: hurst must be in (0, 1.5), got {hurst}")
    # the padded field is passed without a name here, so that _finish can free it
    return _finish(_fbm(_padded(grid.shape), hurst, np.random.default_rng(seed)), grid, relief,
                   max_slope_deg, vertical)


def _fbm(size: tuple[int, int], hurst: float, rng: np.random.Generator) -> np.ndarray:
    """The padded fBm field of :func:`fractal_terrain` (filters applied in place)."""
    spectrum = _fft.rfft2(rng.standard_normal(size), workers=_WORKERS)
    k = _wavenumbers(size)
    k[0, 0] = np.inf
    np.power(k, -(hurst + 1.0), out=k)
    spectrum *= k
    del k
    return _fft.irfft2(spectrum, s=size, workers=_WORKERS, overwrite_x=True)


def ridged_terrain(
    grid: Grid,
    relief: tuple[float, float] = (0.0, 3000.0),
    *,
    octaves: int = 7,
    hurst: float = 0.9,
    gain: float = 2.0,
    max_slope_deg: float | None = None,
    seed: int = 0,
    vertical: str = "ellipsoid",
) -> Terrain:
    """Ridged multifractal terrain: sharp crests and valleys, like young mountain ranges.

    Musgrave's ridged multifractal, with band-limited spectral noise as the basis: octave
    ``i`` takes Gaussian noise of wavelength about ``L / 2**(i+1)`` (``L`` the padded grid
    size), normalised to unit deviation, makes it a ridge ``(1 - |n|) ** 2``, weights it by
    the previous octave's signal (``clip(gain * previous, 0, 1)``, so that detail grows on
    crests, not in valleys) and by ``2 ** (-i hurst)``. The sum is scaled to ``relief``.

    Parameters
    ----------
    grid : Grid
    relief : (float, float)
        Lowest and highest height, metres above ``vertical``.
    octaves : int
        Number of noise bands (each halves the wavelength).
    hurst : float
        Amplitude decay per octave (``2 ** -hurst``).
    gain : float
        Weight of a crest on the next octave's detail.
    max_slope_deg : float, optional
        Steepest slope wanted, as in :func:`fractal_terrain`.
    seed : int
    vertical : {"ellipsoid", "geoid"}

    Returns
    -------
    Terrain
    """
    if octaves < 1:
        raise DemError(f"ridged_terrain: octaves must be >= 1, got {octaves}")
    # the padded field is passed without a name here, so that _finish can free it
    return _finish(_ridged(_padded(grid.shape), octaves, hurst, gain, np.random.default_rng(seed)),
                   grid, relief, max_slope_deg, vertical)


def _ridged(size: tuple[int, int], octaves: int, hurst: float, gain: float,
            rng: np.random.Generator) -> np.ndarray:
    """The padded field of :func:`ridged_terrain`: three full-size arrays (sum, weight, the
    octave's signal) and two half-spectrum scratch arrays, every step in place."""
    log_k = _wavenumbers(size)
    np.maximum(log_k, 1e-12, out=log_k)
    np.log(log_k, out=log_k)
    band = np.empty_like(log_k)
    total = np.zeros(size)
    weight = np.ones(size)
    for i in range(octaves):
        centre = 2.0 ** (i + 1) / max(size)  # cycles per pixel
        if centre > 0.5:
            break
        # Gaussian band in log |k| around the centre
        np.subtract(log_k, math.log(centre), out=band)
        band /= 0.35
        np.square(band, out=band)
        band *= -0.5
        np.exp(band, out=band)
        band[0, 0] = 0.0
        spectrum = _fft.rfft2(rng.standard_normal(size), workers=_WORKERS)
        spectrum *= band
        n = _fft.irfft2(spectrum, s=size, workers=_WORKERS, overwrite_x=True)
        del spectrum
        n /= n.std()
        # signal = (1 - min(|n|, 1)) ** 2 * weight, in n
        np.abs(n, out=n)
        np.minimum(n, 1.0, out=n)
        np.subtract(1.0, n, out=n)
        np.square(n, out=n)
        n *= weight
        np.multiply(n, gain, out=weight)
        np.clip(weight, 0.0, 1.0, out=weight)
        n *= 2.0 ** (-i * hurst)
        total += n
        del n
    return total


# ---------------------------------------------------------------------------- measured DEM
def measured_dem(
    truth: Terrain,
    spacing_m: float,
    rmse_z: float,
    *,
    correlation_length_m: float | None = None,
    white_fraction: float = 0.3,
    seed: int = 0,
) -> Terrain:
    """A DEM as a producer would deliver it: the truth resampled, plus noise of a given RMSEz.

    The truth is sampled (bilinear) at the posts of a grid of ``spacing_m`` over the same area
    and CRS. Noise is added at the posts: a Gaussian random field of correlation length
    ``correlation_length_m`` (Gaussian covariance) and white noise, mixed so that a fraction
    ``white_fraction`` of the noise variance is white. The noise is scaled so that the
    measured DEM and the truth, both interpolated bilinearly (as a
    :class:`~geoblock.dem.GridDem` samples them) at random check points inside the measured
    grid, differ by ``rmse_z`` RMS: the resampling error of the coarser spacing is part of
    the budget, as when a DEM's RMSEz is checked against field points.

    Parameters
    ----------
    truth : Terrain
    spacing_m : float
        Post spacing, metres (converted to degrees for a geographic grid).
    rmse_z : float
        RMSE of the heights against the truth, metres.
    correlation_length_m : float, optional
        Default ``10 * spacing_m``.
    white_fraction : float
        Share of the noise variance that is white, in [0, 1].
    seed : int

    Returns
    -------
    Terrain
        Same CRS and vertical datum as ``truth``.

    Raises
    ------
    DemError
        The resampling error alone exceeds ``rmse_z`` (use a finer spacing or a larger
        RMSEz), or invalid arguments.
    """
    if not (spacing_m > 0 and rmse_z >= 0 and 0.0 <= white_fraction <= 1.0):
        raise DemError(f"measured_dem: need spacing_m > 0, rmse_z >= 0 and white_fraction in "
                       f"[0, 1], got {spacing_m}, {rmse_z}, {white_fraction}")
    grid = truth.grid.with_spacing_m(spacing_m)
    rng = np.random.default_rng(seed)
    length = 10.0 * spacing_m if correlation_length_m is None else float(correlation_length_m)
    noise = _noise_field(grid.shape, length / spacing_m, white_fraction, rng)  # float32
    heights = _resampled(truth, grid)  # float64, becomes the measured DEM's heights

    # the measured DEM against the truth surface at random check points (bilinear, as a
    # GridDem samples both), with and without noise: solve for the noise scale
    n_check = min(400_000, max(50_000, truth.heights.size))
    pr = rng.uniform(0.0, grid.shape[0] - 1.0, n_check)
    pc = rng.uniform(0.0, grid.shape[1] - 1.0, n_check)
    line, pixel = centre_to_corner(pr, pc)
    cx, cy = affine_apply(grid.transform, pixel, line)
    col_c, row_c = affine_apply(~truth.grid.transform, cx, cy)
    true_h = sample(truth.heights, *corner_to_centre(row_c, col_c), "bilinear")
    r_err = sample(heights, pr, pc, "bilinear") - true_h
    n_err = _bilinear_at(noise, pr, pc)
    ok = np.isfinite(r_err) & np.isfinite(n_err)
    if not ok.any():
        raise DemError("measured_dem: no check point has a truth height inside the measured grid")
    r_err, n_err = r_err[ok], n_err[ok]
    a, b, c = np.mean(n_err**2), 2.0 * np.mean(r_err * n_err), np.mean(r_err**2) - rmse_z**2
    disc = b * b - 4.0 * a * c
    if c > 0 and (disc < 0 or b >= 0):
        raise DemError(
            f"measured_dem: resampling the truth to {spacing_m} m alone gives an RMSEz of "
            f"{math.sqrt(np.mean(r_err**2)):.3f} m, more than the {rmse_z} m asked: use a finer "
            "spacing or a larger rmse_z"
        )
    scale = (-b + math.sqrt(max(disc, 0.0))) / (2.0 * a) if a > 0 else 0.0
    for r0, r1 in _strips(grid.shape):
        heights[r0:r1] += scale * noise[r0:r1].astype(np.float64)
    del noise
    return Terrain._owning(heights, grid, truth.vertical)


def _axis_taps(position: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Bilinear taps along one axis of ``n`` posts: the lower post (so that the upper one,
    ``+ 1``, is inside) and the weight of the upper one, for pixel-centre ``position``
    clipped to the posts (edge extension)."""
    p = np.clip(position, 0.0, n - 1.0)
    lower = np.minimum(np.floor(p).astype(np.intp), n - 2)
    return lower, p - lower


def _resampled(truth: Terrain, grid: Grid) -> np.ndarray:
    """``truth`` sampled bilinearly at the posts of ``grid`` (same CRS, north-up), (R, C)
    float64. Separable: a post's truth row depends on its y only and its column on its x
    only, so the taps are two 1-D index vectors and the grid is filled strip by strip. Posts
    in the half cell between the truth's outer centres and its edge take the edge value."""
    t = truth.grid.transform
    x, y = grid.xy()
    rows_t, cols_t = truth.shape
    row, col = corner_to_centre((y - t.f) / t.e, (x - t.c) / t.a)  # each post's truth row/col
    r_lo, r_w = _axis_taps(row, rows_t)
    c_lo, c_w = _axis_taps(col, cols_t)
    c_w1 = 1.0 - c_w
    out = np.empty(grid.shape)
    for r0, r1 in _strips((grid.shape[0], cols_t)):
        top = truth.heights[r_lo[r0:r1]]  # (h, cols_t) rows above and below the posts
        bottom = truth.heights[r_lo[r0:r1] + 1]
        top *= (1.0 - r_w[r0:r1])[:, None]
        bottom *= r_w[r0:r1, None]
        top += bottom
        del bottom
        strip = out[r0:r1]
        np.multiply(top[:, c_lo], c_w1, out=strip)
        strip += top[:, c_lo + 1] * c_w
    return out


def _bilinear_at(array: np.ndarray, row: np.ndarray, col: np.ndarray) -> np.ndarray:
    """Bilinear values (float64) of ``array`` (any dtype or layout: no copy of it) at pixel
    coordinates inside ``[0, R-1] x [0, C-1]``."""
    r, wr = _axis_taps(row, array.shape[0])
    c, wc = _axis_taps(col, array.shape[1])
    top = array[r, c] * (1.0 - wc) + array[r, c + 1] * wc
    bottom = array[r + 1, c] * (1.0 - wc) + array[r + 1, c + 1] * wc
    return top * (1.0 - wr) + bottom * wr


def _noise_field(shape: tuple[int, int], length_px: float, white_fraction: float,
                 rng: np.random.Generator) -> np.ndarray:
    """The unit-variance noise of :func:`measured_dem`, float32 ``shape``.

    A Gaussian random field of Gaussian covariance ``exp(-d**2 / L**2)`` (``L`` =
    ``length_px`` posts; amplitude spectrum ``exp(-(pi k L)**2 / 2)``, that is white noise
    convolved with a Gaussian of standard deviation ``L / 2``), standardised over the grid,
    mixed with white noise so that ``white_fraction`` of the variance is white.

    The Gaussian filter is separable: white noise on a grid padded by ``4 L`` (twice the
    kernel's +-4 sigma reach, so that the periodic transform does not wrap into the grid) is
    filtered along x strip of rows by strip of rows, then along y strip of columns by strip
    of columns, in float32 and in place: one padded float32 array, no 2-D transform.
    """
    rows, cols = shape
    pad = min(math.ceil(4.0 * length_px) + 8, max(shape))
    size = (_fft.next_fast_len(rows + pad, real=True), _fft.next_fast_len(cols + pad, real=True))
    field = np.empty(size, dtype=np.float32)
    rng.standard_normal(dtype=np.float32, out=field)

    def gain(n: int) -> np.ndarray:
        return np.exp(-0.5 * (np.pi * length_px * np.fft.rfftfreq(n)) ** 2).astype(np.float32)

    along_x, along_y = gain(size[1]), gain(size[0])[:, None]
    for r0, r1 in _strips(size):
        spectrum = _fft.rfft(field[r0:r1], axis=1, workers=_WORKERS)
        spectrum *= along_x
        field[r0:r1] = _fft.irfft(spectrum, n=size[1], axis=1, workers=_WORKERS)
    step = max(1, _STRIP_POSTS // size[0])
    for c0 in range(0, cols, step):  # only the grid's columns and rows are needed from here
        c1 = min(cols, c0 + step)
        spectrum = _fft.rfft(field[:, c0:c1], axis=0, workers=_WORKERS)
        spectrum *= along_y
        field[:rows, c0:c1] = _fft.irfft(spectrum, n=size[0], axis=0, workers=_WORKERS)[:rows]
    del spectrum
    noise = field[:rows, :cols]
    strips = list(_strips(shape))
    mean = sum(float(noise[r0:r1].sum(dtype=np.float64)) for r0, r1 in strips) / noise.size
    var = sum(float(np.square(noise[r0:r1] - np.float32(mean), dtype=np.float64).sum())
              for r0, r1 in strips) / noise.size
    k_corr = math.sqrt(1.0 - white_fraction) / (math.sqrt(var) or 1.0)
    k_white = np.float32(math.sqrt(white_fraction))
    for r0, r1 in strips:
        block = noise[r0:r1]
        block -= np.float32(mean)
        block *= np.float32(k_corr)
        block += k_white * rng.standard_normal((r1 - r0, cols), dtype=np.float32)
    return noise
