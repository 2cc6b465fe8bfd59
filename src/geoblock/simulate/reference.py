"""Reference orthoimages rendered from a scene's ground truth, optionally misregistered.

A reference ortho (Sentinel-2's Global Reference Image, a national ortho, an earlier adjusted
mosaic) is a map-projected image whose content sits where the ground is, up to its stated
accuracy. :func:`render_reference` renders one from the simulator's ground texture (a
function of longitude and latitude, :class:`~geoblock.simulate.render.ProceduralTexture`,
the same texture the simulated raw images are rendered with), so that matching a simulated
image against it has a known truth:

* **grid**: north-up, square pixels of ``gsd_m`` metres in a projected CRS (UTM by default);
  the GeoTIFF's transform maps pixel *corners*, as GDAL and rasterio do, so pixel
  ``(row, col)`` of the array, whose centre is at integer ``(row, col)`` in geoblock's
  convention (:mod:`geoblock.pixels`), covers map ``x`` in ``[c + col a, c + (col + 1) a)``
  and is centred on ``x = c + (col + 0.5) a`` (``y`` likewise with ``f`` and ``e < 0``);
* **area-averaged**: each pixel is the mean of ``supersample x supersample`` texture samples
  at the centres of equal sub-cells of the pixel (a sensor integrates over its footprint:
  without it, features finer than a pixel alias);
* **misregistered** by a known ``shift_en_m = (de, dn)``: a feature whose true position is
  ``X`` appears at ``X + shift``, the shift in metres along the local east and north of the
  ellipsoid at each point (not along the map grid, which turns from true north by the
  meridian convergence). The pixel centred on ``P`` thus shows the ground at ``P - shift``:
  :meth:`RenderedReference.true_lonlat` removes the shift from a position read on the reference,
  :meth:`RenderedReference.displaced_lonlat` adds it;
* optionally **shaded** by a terrain (the same Lambertian hillshade as
  :func:`~geoblock.simulate.render.render_image`), at the true ground position of the
  pixel's centre, so that the reference shows the relief the raw images show.

Pixel values follow :func:`~geoblock.simulate.render.render_image`: ``1 + value * (top - 1)``
for ``uint8``/``uint16`` (0 is never used: it is the nodata of the raw images), or the value in
[0, 1] itself for ``float32``.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pyproj
from affine import Affine

from geoblock import coords
from geoblock.dem.grid import _is_lonlat
from geoblock.errors import GeoblockError
from geoblock.simulate.render import Texture, _shade
from geoblock.simulate.terrain import Grid, Terrain
from geoblock.typing import Float64Array

__all__ = ["RenderedReference", "default_supersample", "render_reference", "shift_lonlat"]

_DEG_M = math.radians(1.0) * coords.WGS84_A  # metres per degree of latitude (sphere of radius a)
#: target spacing of the texture samples inside a pixel, metres (the procedural texture's
#: finest features at its default scale: 4 m hedges, 8 m roads, crop rows of 6-20 m period)
_SUBSAMPLE_M = 3.5
_MAX_SUPERSAMPLE = 8
_DTYPES = ("uint8", "uint16", "float32")


def shift_lonlat(lon: Any, lat: Any, de: float | np.ndarray, dn: float | np.ndarray
                 ) -> tuple[Float64Array, Float64Array]:
    """Move ground positions by ``de`` metres east and ``dn`` metres north.

    Parameters
    ----------
    lon, lat : array_like, (*S,)
        Degrees (WGS84).
    de, dn : float or array_like, (*S,)
        Metres along the local east and north of the ellipsoid at each point (its radii of
        curvature in the prime vertical and the meridian: exact to first order; the
        second-order terms, ``d**2 tan(lat) / (2 R)``, are 13 micrometres for a 10 m move at
        60 degrees of latitude, 0.3 mm for 50 m).

    Returns
    -------
    lon, lat : ndarray, (*S,)
        Degrees.
    """
    lon = np.asarray(lon, dtype=np.float64)
    lat = np.asarray(lat, dtype=np.float64)
    s2 = np.sin(np.radians(lat)) ** 2
    w = np.sqrt(1.0 - coords.WGS84_E2 * s2)
    n_radius = coords.WGS84_A / w  # prime vertical
    m_radius = coords.WGS84_A * (1.0 - coords.WGS84_E2) / w**3  # meridian
    dlat = np.degrees(np.asarray(dn, dtype=np.float64) / m_radius)
    dlon = np.degrees(np.asarray(de, dtype=np.float64)
                      / (n_radius * np.cos(np.radians(lat))))
    return lon + dlon, lat + dlat


def default_supersample(gsd_m: float) -> int:
    """Texture samples per pixel side for a pixel of ``gsd_m`` metres: about one every
    3.5 m, at least 2 and at most 8 (2.5 and 5 m: 2; 10 m: 3; 20 m: 6)."""
    return int(min(_MAX_SUPERSAMPLE, max(2, math.ceil(float(gsd_m) / _SUBSAMPLE_M - 1e-9))))


@dataclass(frozen=True, eq=False)
class RenderedReference:
    """A rendered reference ortho.

    Attributes
    ----------
    pixels : ndarray, (rows, cols)
        ``uint8``, ``uint16`` or ``float32``.
    grid : Grid
        Its north-up grid (transform of the pixel corners, shape, CRS).
    shift_en_m : (float, float)
        The misregistration: a feature truly at ``X`` appears at ``X + shift``, metres east
        and north.
    supersample : int
        Texture samples per pixel side.
    path : pathlib.Path or None
        The GeoTIFF, when written.
    """

    pixels: np.ndarray
    grid: Grid
    shift_en_m: tuple[float, float]
    supersample: int
    path: Path | None = None

    @property
    def transform(self) -> Affine:
        """The GeoTIFF's transform: map coordinates of pixel corners."""
        return self.grid.transform

    @property
    def crs(self) -> pyproj.CRS:
        return self.grid.crs

    @property
    def gsd_m(self) -> float:
        """Pixel side, metres (projected CRS) or its size in metres at the grid's centre."""
        rx, ry = self.grid.resolution
        if self.grid.is_geographic:
            return float(ry * _DEG_M)
        return float(rx)

    def pixel_lonlat(self, row: Any, col: Any) -> tuple[Float64Array, Float64Array]:
        """Ground position (degrees) of pixel positions ``(row, col)`` of the reference
        (pixel centres at integers), as the reference states it (shift included)."""
        t = self.grid.transform
        x = t.c + t.a * (np.asarray(col, dtype=np.float64) + 0.5)
        y = t.f + t.e * (np.asarray(row, dtype=np.float64) + 0.5)
        return _to_lonlat(self.grid.crs, x, y)

    def lonlat_pixel(self, lon: Any, lat: Any) -> tuple[Float64Array, Float64Array]:
        """Pixel position ``(row, col)`` (centres at integers) of ground positions as the
        reference states them (the inverse of :meth:`pixel_lonlat`)."""
        x, y = _from_lonlat(self.grid.crs, lon, lat)
        t = self.grid.transform
        return (y - t.f) / t.e - 0.5, (x - t.c) / t.a - 0.5

    def true_lonlat(self, lon: Any, lat: Any) -> tuple[Float64Array, Float64Array]:
        """Where a feature the reference shows at ``(lon, lat)`` truly is: the shift
        removed."""
        de, dn = self.shift_en_m
        return shift_lonlat(lon, lat, -de, -dn)

    def displaced_lonlat(self, lon: Any, lat: Any) -> tuple[Float64Array, Float64Array]:
        """Where the reference shows a feature truly at ``(lon, lat)``: the shift added."""
        de, dn = self.shift_en_m
        return shift_lonlat(lon, lat, de, dn)


def _to_lonlat(crs: pyproj.CRS, x: np.ndarray, y: np.ndarray) -> tuple[Float64Array, Float64Array]:
    if _is_lonlat(crs):
        return np.asarray(x, np.float64), np.asarray(y, np.float64)
    lon, lat = coords.transformer(crs, "EPSG:4326").transform(x, y)
    return np.asarray(lon, np.float64), np.asarray(lat, np.float64)


def _from_lonlat(crs: pyproj.CRS, lon: Any, lat: Any) -> tuple[Float64Array, Float64Array]:
    lon = np.asarray(lon, np.float64)
    lat = np.asarray(lat, np.float64)
    if _is_lonlat(crs):
        return lon, lat
    x, y = coords.transformer("EPSG:4326", crs).transform(lon, lat)
    return np.asarray(x, np.float64), np.asarray(y, np.float64)


def _reference_grid(bounds: tuple[float, float, float, float], gsd_m: float,
                    crs: pyproj.CRS) -> Grid:
    w, s, e, n = (float(v) for v in bounds)
    if not (e > w and n > s):
        raise GeoblockError(f"render_reference: bounds must be (west, south, east, north) with "
                            f"east > west and north > south, got {bounds}")
    if crs.is_geographic:
        if not _is_lonlat(crs):
            raise GeoblockError(f"render_reference: a geographic CRS must be WGS84 "
                                f"longitude/latitude, got {crs.name}")
        lat0 = 0.5 * (s + n)
        ry = gsd_m / _DEG_M
        rx = ry / math.cos(math.radians(lat0))
        cols = max(2, math.ceil((e - w) / rx - 1e-9))
        rows = max(2, math.ceil((n - s) / ry - 1e-9))
        return Grid(Affine(rx, 0.0, w, 0.0, -ry, n), (rows, cols), crs)
    factor = float(crs.axis_info[0].unit_conversion_factor or 1.0)
    res = gsd_m / factor
    # whole multiples of the pixel: references of the same GSD over overlapping areas share
    # their pixel edges, as a tiled product's do
    w = math.floor(w / res + 1e-9) * res
    s = math.floor(s / res + 1e-9) * res
    e = math.ceil(e / res - 1e-9) * res
    n = math.ceil(n / res - 1e-9) * res
    return Grid.from_bounds((w, s, e, n), res, crs)


def render_reference(
    texture: Texture,
    bounds: tuple[float, float, float, float],
    gsd_m: float,
    crs: Any,
    *,
    shift_en_m: tuple[float, float] = (0.0, 0.0),
    path: str | os.PathLike[str] | None = None,
    supersample: int | None = None,
    terrain: Any = None,
    sun_azimuth_deg: float = 315.0,
    sun_elevation_deg: float = 45.0,
    ambient: float = 0.3,
    dtype: str = "uint8",
    noise_dn: float = 0.0,
    seed: int = 0,
    chunk_samples: int = 1 << 21,
) -> RenderedReference:
    """Render a reference ortho of a ground texture, misregistered by a known shift.

    Parameters
    ----------
    texture : Texture
        Albedo in [0, 1] of a ground position (degrees in): the scene's texture
        (:func:`~geoblock.simulate.scene.scene_texture`), the one its raw images show.
    bounds : (west, south, east, north)
        Area to cover, in ``crs`` units; in a projected CRS the grid's edges are snapped
        outwards to whole multiples of ``gsd_m``.
    gsd_m : float
        Pixel side, metres (> 0). In a geographic CRS: ``gsd_m`` of latitude, and the same
        metres of longitude at the bounds' centre.
    crs : pyproj.CRS, str or int
        The reference's CRS, e.g. ``coords.utm_crs(lon, lat)``.
    shift_en_m : (float, float)
        The misregistration ``(de, dn)``, metres east and north: a feature truly at ``X``
        appears at ``X + shift`` (module docstring).
    path : str or os.PathLike, optional
        Write the reference there as a GeoTIFF (CRS, corner transform, tags
        ``GEOBLOCK_REFERENCE_SHIFT_E_M``/``_N_M`` and ``GEOBLOCK_REFERENCE_GSD_M``),
        atomically.
    supersample : int, optional
        Texture samples per pixel side (area averaging); default
        :func:`default_supersample` of ``gsd_m``; 1 samples the pixel centre only.
    terrain : Terrain or DemSource, optional
        Shade the texture by this terrain's relief (as the raw images are); none by default.
    sun_azimuth_deg, sun_elevation_deg, ambient : float
        The shading (:func:`~geoblock.simulate.render.render_image`).
    dtype : {"uint8", "uint16", "float32"}
        Pixel type (module docstring).
    noise_dn : float
        Gaussian noise added, digital numbers (integer types only), seeded by ``seed``.
    seed : int
    chunk_samples : int
        About this many texture samples are evaluated at a time (memory: ~100 bytes each).

    Returns
    -------
    RenderedReference

    Raises
    ------
    GeoblockError
        Invalid bounds, GSD, shift, supersample, dtype or noise, or a geographic CRS other
        than WGS84 longitude/latitude.
    GeoblockIOError
        ``path`` cannot be written.
    """
    gsd = float(gsd_m)
    if not (math.isfinite(gsd) and gsd > 0):
        raise GeoblockError(f"render_reference: gsd_m must be a finite number > 0, got {gsd_m!r}")
    de, dn = (float(v) for v in shift_en_m)
    if not (math.isfinite(de) and math.isfinite(dn)):
        raise GeoblockError(f"render_reference: shift_en_m must be two finite numbers, got "
                            f"{shift_en_m!r}")
    if dtype not in _DTYPES:
        raise GeoblockError(f"render_reference: dtype must be one of {', '.join(_DTYPES)}, got "
                            f"{dtype!r}")
    n_sub = default_supersample(gsd) if supersample is None else supersample
    if isinstance(n_sub, bool) or not isinstance(n_sub, int | np.integer) or n_sub < 1:
        raise GeoblockError(f"render_reference: supersample must be an integer >= 1, got "
                            f"{supersample!r}")
    n_sub = int(n_sub)
    if not (math.isfinite(noise_dn) and noise_dn >= 0):
        raise GeoblockError(f"render_reference: noise_dn must be >= 0, got {noise_dn!r}")
    horizontal = pyproj.CRS.from_user_input(crs)
    horizontal = horizontal.sub_crs_list[0] if horizontal.is_compound else horizontal
    grid = _reference_grid(bounds, gsd, horizontal)
    dem = terrain.to_dem() if isinstance(terrain, Terrain) else terrain
    rows, cols = grid.shape
    t = grid.transform
    # sub-cell centres, in pixels from the pixel's centre: (k + 0.5) / n - 0.5
    frac = (np.arange(n_sub, dtype=np.float64) + 0.5) / n_sub - 0.5
    fy, fx = np.meshgrid(frac, frac, indexing="ij")  # (n, n)
    value = np.empty((rows, cols), dtype=np.float64)
    chunk_rows = max(1, int(chunk_samples) // max(1, cols * n_sub * n_sub))
    flat = math.sin(math.radians(sun_elevation_deg))
    x = t.c + t.a * (np.arange(cols, dtype=np.float64) + 0.5)
    for r0 in range(0, rows, chunk_rows):
        r1 = min(rows, r0 + chunk_rows)
        # pixel centres of rows r0-1 .. r1 (one more each side for the derivatives), then
        # the shift: the pixel at P shows the ground at P - shift
        yy = t.f + t.e * (np.arange(r0 - 1, r1 + 1, dtype=np.float64) + 0.5)
        lon_c, lat_c = _to_lonlat(horizontal, *np.meshgrid(x, yy))
        lon_c, lat_c = shift_lonlat(lon_c, lat_c, -de, -dn)
        # the sub-samples from the centres through the local derivatives per pixel (central
        # differences of the centres: the CRS's second-order terms over a pixel are
        # micrometres), instead of projecting every sub-sample
        d_col = [np.gradient(a, axis=1)[1:-1] if cols > 1 else np.zeros((r1 - r0, 1))
                 for a in (lon_c, lat_c)]
        d_row = [0.5 * (a[2:] - a[:-2]) for a in (lon_c, lat_c)]
        lon0, lat0 = lon_c[1:-1], lat_c[1:-1]  # (R, C)
        lon = (lon0[:, None, :, None] + d_row[0][:, None, :, None] * fy[None, :, None, :]
               + d_col[0][:, None, :, None] * fx[None, :, None, :])  # (R, n, C, n)
        lat = (lat0[:, None, :, None] + d_row[1][:, None, :, None] * fy[None, :, None, :]
               + d_col[1][:, None, :, None] * fx[None, :, None, :])
        albedo = np.clip(np.asarray(texture(lon, lat), dtype=np.float64), 0.0, 1.0)
        mean = albedo.mean(axis=(1, 3))
        if dem is not None:
            # the relief's shading varies over the terrain's posts, not within a pixel: taken
            # at the pixel's centre
            light = ambient + (1.0 - ambient) * _shade(dem, lon0, lat0, sun_azimuth_deg,
                                                       sun_elevation_deg) / max(flat, 1e-6)
            mean = np.clip(mean * light, 0.0, 1.0)
        value[r0:r1] = mean
    if dtype == "float32":
        pixels = value.astype(np.float32)
    else:
        top = float(np.iinfo(np.dtype(dtype)).max)
        dn_values = 1.0 + value * (top - 1.0)
        if noise_dn > 0:
            dn_values = dn_values + np.random.default_rng(seed).normal(0.0, noise_dn,
                                                                       dn_values.shape)
        pixels = np.clip(np.round(dn_values), 1.0, top).astype(dtype)
    out_path = None
    if path is not None:
        out_path = _write(Path(path), pixels, grid, (de, dn), gsd)
    return RenderedReference(pixels, grid, (de, dn), n_sub, out_path)


def _write(path: Path, pixels: np.ndarray, grid: Grid, shift: tuple[float, float],
           gsd: float) -> Path:
    from geoblock.io.images import write_image

    return write_image(path, pixels, crs=grid.crs, transform=grid.transform,
                       tags={"GEOBLOCK_SIMULATED": "reference ortho rendered by "
                                                   "geoblock.simulate.reference",
                             "GEOBLOCK_REFERENCE_SHIFT_E_M": repr(shift[0]),
                             "GEOBLOCK_REFERENCE_SHIFT_N_M": repr(shift[1]),
                             "GEOBLOCK_REFERENCE_GSD_M": repr(gsd)})
