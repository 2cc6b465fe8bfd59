"""Raw images rendered from a sensor model and a DEM: a ground texture draped over the terrain.

For each image pixel, the line of sight of the (TRUE) model is intersected with the (TRUE)
terrain and a deterministic procedural texture of the ground position gives the pixel's
brightness, shaded by the terrain's relief (hillshade). The result is a raw image in the
model's geometry: orthorectified with the true model it lands exactly on the texture; with a
model carrying errors, the misregistration shows on roads, rivers and field borders.

Speed
    Intersecting every pixel's line of sight (:func:`geoblock.localize`) costs about 20 us
    per pixel. :func:`pixel_ground` intersects a lattice of pixels (every ``lattice_step``
    pixels), interpolates longitude and latitude bilinearly in between, checks the
    interpolation at the centre pixel of every lattice cell against the exact intersection,
    and intersects every pixel of the cells that miss ``tolerance_px`` (and of the cells
    touching a failed node: occlusions, DEM edges) exactly. Rows are processed in chunks of
    about ``chunk_pixels`` pixels, so memory stays bounded whatever the image size.

Files
    :func:`render` writes the image as a GeoTIFF (:func:`geoblock.io.write_image`: no
    georeferencing) and the model beside it as JSON (:func:`geoblock.io.write_model`), so that
    ``geoblock ortho IMAGE OUT --model MODEL.json --dem DEM`` works on it.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from geoblock.dem.intersect import localize
from geoblock.errors import GeoblockError
from geoblock.typing import BoolArray, Float64Array, Status

__all__ = ["ConstantTexture", "ProceduralTexture", "RenderedImage", "Texture", "pixel_ground",
           "render", "render_image"]

_DEG_M = math.radians(1.0) * 6378137.0  # metres per degree of latitude (sphere of radius a)


class Texture(Protocol):
    """Ground albedo: ``texture(lon, lat) -> (*S,)`` values in [0, 1] (degrees in)."""

    def __call__(self, lon: np.ndarray, lat: np.ndarray) -> np.ndarray: ...


@dataclass(frozen=True)
class ConstantTexture:
    """The same albedo everywhere (for checks: a flat constant scene renders constant)."""

    value: float = 0.5

    def __call__(self, lon: np.ndarray, lat: np.ndarray) -> np.ndarray:
        return np.full(np.shape(lon), float(self.value))


def _hash01(i: np.ndarray, j: np.ndarray, salt: int) -> np.ndarray:
    """A deterministic hash of integer cell indices to [0, 1) (splitmix64 finaliser)."""
    shape = np.shape(i)
    i, j = np.atleast_1d(i), np.atleast_1d(j)  # arrays: uint64 products wrap silently
    x = (i.astype(np.int64).astype(np.uint64) * np.uint64(0x9E3779B97F4A7C15)) ^ (
        j.astype(np.int64).astype(np.uint64) * np.uint64(0xC2B2AE3D27D4EB4F)
    ) ^ np.uint64((salt * 0x2545F4914F6CDD1D) & 0xFFFFFFFFFFFFFFFF)
    x ^= x >> np.uint64(30)
    x *= np.uint64(0xBF58476D1CE4E5B9)
    x ^= x >> np.uint64(27)
    x *= np.uint64(0x94D049BB133111EB)
    x ^= x >> np.uint64(31)
    return ((x >> np.uint64(11)).astype(np.float64) * 2.0**-53).reshape(shape)


@dataclass(frozen=True)
class ProceduralTexture:
    """Fields, roads and rivers: a deterministic ground pattern in local metres.

    Ground positions are turned into east/north metres from ``origin`` (equirectangular, fine
    over a few tens of kilometres). The pattern:

    * **fields**: the Voronoi cells of a jittered grid of ``field_size_m``, each with its own
      albedo (0.25-0.75) and crop rows (a faint stripe of random direction and period), with
      dark hedges along the borders;
    * **roads**: two families of straight bright lines, ``road_spacing_m`` apart;
    * **rivers**: dark meandering bands, one every ``river_spacing_m`` northwards.

    Parameters
    ----------
    origin : (float, float)
        ``(lon, lat)`` of the pattern's origin, degrees.
    seed : int
        Same seed, same pattern.
    field_size_m, road_spacing_m, road_width_m, river_spacing_m, river_width_m : float
        Metres.
    """

    origin: tuple[float, float]
    seed: int = 0
    field_size_m: float = 150.0
    road_spacing_m: float = 800.0
    road_width_m: float = 8.0
    river_spacing_m: float = 3000.0
    river_width_m: float = 25.0

    def __call__(self, lon: np.ndarray, lat: np.ndarray) -> np.ndarray:
        lon = np.asarray(lon, float)
        lat = np.asarray(lat, float)
        lon0, lat0 = self.origin
        e = (lon - lon0) * (_DEG_M * math.cos(math.radians(lat0)))
        n = (lat - lat0) * _DEG_M
        size = self.field_size_m
        ci, cj = np.floor(e / size), np.floor(n / size)
        # nearest and second-nearest jittered seeds among the 3 x 3 neighbouring cells
        d1 = np.full(e.shape, np.inf)
        d2 = np.full(e.shape, np.inf)
        best_i = np.zeros(e.shape)
        best_j = np.zeros(e.shape)
        for di in (-1.0, 0.0, 1.0):
            for dj in (-1.0, 0.0, 1.0):
                ii, jj = ci + di, cj + dj
                sx = (ii + 0.15 + 0.7 * _hash01(ii, jj, self.seed * 8 + 1)) * size
                sy = (jj + 0.15 + 0.7 * _hash01(ii, jj, self.seed * 8 + 2)) * size
                d = np.hypot(e - sx, n - sy)
                closer = d < d1
                d2 = np.where(closer, d1, np.minimum(d2, d))
                d1 = np.where(closer, d, d1)
                best_i = np.where(closer, ii, best_i)
                best_j = np.where(closer, jj, best_j)
        albedo = 0.25 + 0.5 * _hash01(best_i, best_j, self.seed * 8 + 3)
        theta = np.pi * _hash01(best_i, best_j, self.seed * 8 + 4)
        period = 6.0 + 14.0 * _hash01(best_i, best_j, self.seed * 8 + 5)
        across = e * np.cos(theta) + n * np.sin(theta)
        albedo = albedo + 0.06 * np.sin(2 * np.pi * across / period)
        albedo = np.where(d2 - d1 < 4.0, albedo * 0.55, albedo)  # hedges
        # roads: two families of straight lines
        for k, angle in enumerate((np.radians(17.0), np.radians(103.0))):
            u = e * np.cos(angle) + n * np.sin(angle)
            spacing = self.road_spacing_m * (1.0 + 0.3 * k)
            offset = spacing * _hash01(np.array(k), np.array(0), self.seed * 8 + 6)
            dist = np.abs(np.mod(u + offset, spacing) - 0.5 * spacing)
            albedo = np.where(dist < 0.5 * self.road_width_m, 0.9, albedo)
        # rivers: meanders along east, repeated northwards
        lam = 2.3 * self.river_spacing_m
        v = n - 0.12 * self.river_spacing_m * (np.sin(2 * np.pi * e / lam)
                                               + 0.5 * np.sin(2 * np.pi * e / (0.37 * lam) + 1.0))
        dist = np.abs(np.mod(v, self.river_spacing_m) - 0.5 * self.river_spacing_m)
        albedo = np.where(dist < 0.5 * self.river_width_m, 0.08, albedo)
        return np.clip(albedo, 0.0, 1.0)


@dataclass(frozen=True, eq=False)
class RenderedImage:
    """A rendered raw image and how it was computed.

    Attributes
    ----------
    pixels : ndarray, (rows, cols)
        ``uint8`` or ``uint16``; 0 where the line of sight meets no terrain (nodata).
    exact_fraction : float
        Fraction of the pixels intersected exactly (lattice nodes and refined cells).
    lattice_error_px : float
        The largest interpolation error found at the check pixels of the cells kept
        interpolated, pixels (ground distance over the local ground sampling distance).
    """

    pixels: np.ndarray
    exact_fraction: float
    lattice_error_px: float


def _exact(model: Any, dem: Any, row: np.ndarray,
           col: np.ndarray) -> tuple[Float64Array, Float64Array, BoolArray]:
    ground, status = localize(model, row, col, dem, warn=False)
    return ground.lon, ground.lat, status == Status.CONVERGED


def _axis_nodes(start: int, stop: int, step: int) -> np.ndarray:
    nodes = np.arange(start, stop, step)
    if nodes[-1] != stop - 1:
        nodes = np.append(nodes, stop - 1)
    return nodes


def pixel_ground(
    model: Any,
    dem: Any,
    row_start: int = 0,
    row_stop: int | None = None,
    *,
    lattice_step: int = 8,
    tolerance_px: float = 0.05,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, float]]:
    """Ground position of every pixel of rows ``[row_start, row_stop)``, on the terrain.

    Parameters
    ----------
    model : SensorModel
    dem : DemSource
    row_start, row_stop : int
        Rows of the image (pixel centres), ``row_stop`` excluded (default: the last row).
    lattice_step : int
        Pixels between exactly intersected lattice nodes; 1 intersects every pixel.
    tolerance_px : float
        Largest interpolation error accepted at a cell's check pixel, in pixels of ground
        sampling distance; cells beyond it are intersected pixel by pixel.

    Returns
    -------
    lon, lat : ndarray, (R, cols)
        Degrees; NaN where the line of sight meets no terrain.
    ok : ndarray of bool, (R, cols)
    stats : dict
        ``exact`` (pixels intersected exactly), ``pixels``, ``max_error_px`` (largest error at
        the check pixels of the cells kept interpolated).
    """
    rows, cols = model.shape
    row_stop = rows if row_stop is None else int(row_stop)
    if not 0 <= row_start < row_stop <= rows:
        raise GeoblockError(f"pixel_ground: rows [{row_start}, {row_stop}) outside the image's "
                            f"{rows} rows")
    step = int(lattice_step)
    if step < 1:
        raise GeoblockError(f"pixel_ground: lattice_step must be >= 1, got {lattice_step}")
    n_rows = row_stop - row_start
    if step == 1:
        rr, cc = np.meshgrid(np.arange(row_start, row_stop, dtype=float),
                             np.arange(cols, dtype=float), indexing="ij")
        lon, lat, ok = _exact(model, dem, rr, cc)
        return lon, lat, ok, {"exact": float(rr.size), "pixels": float(rr.size),
                              "max_error_px": 0.0}
    rn = _axis_nodes(row_start, row_stop, step)
    cn = _axis_nodes(0, cols, step)
    nr, nc = np.meshgrid(rn.astype(float), cn.astype(float), indexing="ij")
    node_lon, node_lat, node_ok = _exact(model, dem, nr, nc)
    # interpolation: each pixel's cell (between consecutive nodes) and its fractions
    pr = np.arange(row_start, row_stop)
    pc = np.arange(cols)
    ci_r = np.clip(np.searchsorted(rn, pr, side="right") - 1, 0, rn.size - 2) if rn.size > 1 \
        else np.zeros(pr.size, int)
    ci_c = np.clip(np.searchsorted(cn, pc, side="right") - 1, 0, cn.size - 2) if cn.size > 1 \
        else np.zeros(pc.size, int)
    if rn.size > 1:
        tr = (pr - rn[ci_r]) / (rn[ci_r + 1] - rn[ci_r])
    else:
        tr = np.zeros(pr.size)
    tc = (pc - cn[ci_c]) / (cn[ci_c + 1] - cn[ci_c]) if cn.size > 1 else np.zeros(pc.size)
    r1 = np.minimum(ci_r + 1, rn.size - 1)
    c1 = np.minimum(ci_c + 1, cn.size - 1)

    def interp(nodes: np.ndarray) -> np.ndarray:
        top = nodes[ci_r][:, ci_c] * (1 - tc) + nodes[ci_r][:, c1] * tc
        bottom = nodes[r1][:, ci_c] * (1 - tc) + nodes[r1][:, c1] * tc
        return top * (1 - tr)[:, None] + bottom * tr[:, None]

    lon = interp(node_lon)
    lat = interp(node_lat)
    # cells: bad when a corner failed; check the others at their centre pixel
    ncr, ncc = max(rn.size - 1, 1), max(cn.size - 1, 1)
    good_node = node_ok & np.isfinite(node_lon)
    corner_ok = (good_node[:ncr, :ncc] & good_node[-ncr:, :ncc] & good_node[:ncr, -ncc:]
                 & good_node[-ncr:, -ncc:])
    bad = ~corner_ok
    cr = np.round(0.5 * (rn[:ncr] + rn[-ncr:])).astype(int)
    cc = np.round(0.5 * (cn[:ncc] + cn[-ncc:])).astype(int)
    check_r, check_c = np.meshgrid(cr, cc, indexing="ij")
    check = corner_ok.copy()
    ex_lon, ex_lat, ex_ok = _exact(model, dem, check_r[check].astype(float),
                                   check_c[check].astype(float))
    in_lon = lon[check_r[check] - row_start, check_c[check]]
    in_lat = lat[check_r[check] - row_start, check_c[check]]
    coslat = np.cos(np.radians(ex_lat))
    err_m = np.hypot((in_lon - ex_lon) * coslat, in_lat - ex_lat) * _DEG_M
    # ground sampling distance of the cell: node spacing in metres over pixels
    i0, j0 = np.nonzero(check)
    i1 = np.minimum(i0 + 1, rn.size - 1)
    j1 = np.minimum(j0 + 1, cn.size - 1)
    gsd_c = np.hypot((node_lon[i0, j1] - node_lon[i0, j0]) * coslat,
                     node_lat[i0, j1] - node_lat[i0, j0]) * _DEG_M / np.maximum(cn[j1] - cn[j0], 1)
    gsd_r = np.hypot((node_lon[i1, j0] - node_lon[i0, j0]) * coslat,
                     node_lat[i1, j0] - node_lat[i0, j0]) * _DEG_M / np.maximum(rn[i1] - rn[i0], 1)
    gsd = np.maximum(np.fmax(gsd_c, gsd_r), 1e-6)
    with np.errstate(invalid="ignore"):
        err_px = err_m / gsd
        fails = ~ex_ok | ~(err_px <= tolerance_px)
    bad[i0[fails], j0[fails]] = True
    kept = ~fails
    max_err = float(np.max(err_px[kept])) if kept.any() else 0.0
    ok = np.ones((n_rows, cols), bool)
    exact = float(rn.size * cn.size + check.sum())
    if bad.any():
        # every pixel of a bad cell (pixels on a shared edge belong to the cell found above)
        pix_bad = bad[ci_r][:, ci_c]
        br, bc = np.nonzero(pix_bad)
        e_lon, e_lat, e_ok = _exact(model, dem, (br + row_start).astype(float),
                                    bc.astype(float))
        lon[br, bc] = e_lon
        lat[br, bc] = e_lat
        ok[br, bc] = e_ok
        exact += float(br.size)
    ok &= np.isfinite(lon) & np.isfinite(lat)
    lon[~ok] = np.nan
    lat[~ok] = np.nan
    return lon, lat, ok, {"exact": exact, "pixels": float(n_rows * cols), "max_error_px": max_err}


def _shade(dem: Any, lon: np.ndarray, lat: np.ndarray, azimuth_deg: float,
           elevation_deg: float) -> np.ndarray:
    """Lambertian shade ``max(0, normal . sun)`` of the DEM surface at the points."""
    res = float(getattr(dem, "resolution_m", 0.0) or 0.0)
    step = max(res, 1.0)
    dlat = step / _DEG_M
    dlon = dlat / np.maximum(np.cos(np.radians(lat)), 1e-6)
    hx = (dem.height(lon + dlon, lat) - dem.height(lon - dlon, lat)) / (2 * step)
    hy = (dem.height(lon, lat + dlat) - dem.height(lon, lat - dlat)) / (2 * step)
    hx = np.nan_to_num(hx)
    hy = np.nan_to_num(hy)
    az, el = math.radians(azimuth_deg), math.radians(elevation_deg)
    sun = (math.sin(az) * math.cos(el), math.cos(az) * math.cos(el), math.sin(el))
    norm = np.sqrt(hx * hx + hy * hy + 1.0)
    return np.maximum((-hx * sun[0] - hy * sun[1] + sun[2]) / norm, 0.0)


def render_image(
    model: Any,
    dem: Any,
    *,
    texture: Texture | None = None,
    hillshade: bool = True,
    sun_azimuth_deg: float = 315.0,
    sun_elevation_deg: float = 45.0,
    ambient: float = 0.3,
    dtype: str = "uint8",
    noise_dn: float = 0.0,
    seed: int = 0,
    lattice_step: int = 8,
    tolerance_px: float = 0.05,
    chunk_pixels: int = 1 << 18,
) -> RenderedImage:
    """Render the raw image a model sees of a textured terrain.

    Parameters
    ----------
    model : SensorModel
        The image's TRUE model (only ``shape``, ``height_range`` and ``backproject`` are used).
    dem : DemSource, Terrain or float
        The TRUE terrain: a number is a constant height above the ellipsoid, a
        :class:`~geoblock.simulate.terrain.Terrain` is converted with ``to_dem()``.
    texture : Texture, optional
        Albedo in [0, 1] of a ground position; default a :class:`ProceduralTexture` centred on
        the image's footprint.
    hillshade : bool
        Shade by the terrain's slope towards the sun, so that the relief shows.
    sun_azimuth_deg, sun_elevation_deg : float
        Sun direction, degrees clockwise from north and above the horizon.
    ambient : float
        Share of the light that is not directional (shadowed slopes keep it).
    dtype : {"uint8", "uint16"}
        Pixel type: values 1..255 (or 1..65535); 0 is nodata (no terrain in the line of sight).
    noise_dn : float
        Standard deviation of Gaussian sensor noise added, digital numbers (seeded by ``seed``).
    seed : int
    lattice_step, tolerance_px : int, float
        The lattice of :func:`pixel_ground`.
    chunk_pixels : int
        About this many pixels are processed at a time (peak memory about 500 bytes each).

    Returns
    -------
    RenderedImage
    """
    from geoblock.simulate.terrain import Terrain

    if isinstance(dem, Terrain):
        dem = dem.to_dem()
    elif isinstance(dem, int | float):
        from geoblock.dem.constant import ConstantDem

        dem = ConstantDem(float(dem))
    if dtype not in ("uint8", "uint16"):
        raise GeoblockError(f"render_image: dtype must be 'uint8' or 'uint16', got {dtype!r}")
    rows, cols = model.shape
    if texture is None:
        fp = model.footprint()
        texture = ProceduralTexture((float(np.nanmean(fp.lon)), float(np.nanmean(fp.lat))), seed)
    top = float(np.iinfo(np.dtype(dtype)).max)
    out = np.zeros((rows, cols), dtype=dtype)
    step = max(int(lattice_step), 1)
    chunk_rows = max(step, (int(chunk_pixels) // max(cols, 1)) // step * step)
    rng = np.random.default_rng(seed)
    exact = 0.0
    max_err = 0.0
    flat = math.sin(math.radians(sun_elevation_deg))
    for r0 in range(0, rows, chunk_rows):
        r1 = min(rows, r0 + chunk_rows)
        lon, lat, ok, stats = pixel_ground(model, dem, r0, r1, lattice_step=step,
                                           tolerance_px=tolerance_px)
        exact += stats["exact"]
        max_err = max(max_err, stats["max_error_px"])
        value = np.zeros(lon.shape)
        albedo = np.asarray(texture(lon[ok], lat[ok]), float)
        if hillshade:
            light = ambient + (1.0 - ambient) * _shade(dem, lon[ok], lat[ok], sun_azimuth_deg,
                                                       sun_elevation_deg) / max(flat, 1e-6)
            albedo = albedo * light
        value[ok] = albedo
        dn = 1.0 + np.clip(value, 0.0, 1.0) * (top - 1.0)
        if noise_dn > 0:
            dn = dn + rng.normal(0.0, noise_dn, dn.shape)
        dn = np.clip(np.round(dn), 1.0, top)
        dn[~ok] = 0.0
        out[r0:r1] = dn.astype(dtype)
    return RenderedImage(out, exact / (rows * cols), max_err)


def render(
    model: Any,
    dem: Any,
    path: str | os.PathLike[str],
    *,
    model_path: str | os.PathLike[str] | None = None,
    **options: Any,
) -> tuple[Path, Path, RenderedImage]:
    """Render an image (:func:`render_image`) and write it with its model beside it.

    Parameters
    ----------
    model : SensorModel
        The model the image is rendered with (the TRUE one); written as JSON.
    dem : DemSource or Terrain
    path : str or os.PathLike
        The image GeoTIFF (raw: no georeferencing; nodata 0).
    model_path : str or os.PathLike, optional
        The model JSON; default ``path`` with the suffix ``.json``.
    **options
        Passed to :func:`render_image`.

    Returns
    -------
    (pathlib.Path, pathlib.Path, RenderedImage)
        The image path, the model path and the rendering.
    """
    from geoblock.io.images import write_image
    from geoblock.io.models import write_model

    path = Path(path)
    model_path = path.with_suffix(".json") if model_path is None else Path(model_path)
    rendered = render_image(model, dem, **options)
    write_image(path, rendered.pixels, nodata=0,
                tags={"GEOBLOCK_SIMULATED": "rendered by geoblock.simulate.render",
                      "GEOBLOCK_MODEL": model_path.name})
    write_model(model, model_path)
    return path, model_path, rendered
