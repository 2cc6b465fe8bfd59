"""Vectorised numpy references of the DEM service's compiled paths (for the tests only).

The compiled (numba) samplers of :mod:`geoblock.dem.sampling` and :mod:`geoblock.dem.raster`
are held bit-identical to these plain numpy versions by the test suite; nothing in geoblock
calls them.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from geoblock.dem.cache import BLOCK_CACHE
from geoblock.dem.grid import lonlat_to_crs
from geoblock.dem.raster import _HALO, RasterDem
from geoblock.dem.sampling import _keys, sample
from geoblock.pixels import PIXEL_CENTRE, inside_image, map_to_pixel

__all__ = ["pixel_coords_reference", "sample_array_reference", "sample_reference"]


def sample_array_reference(
    array: np.ndarray, row: np.ndarray, col: np.ndarray, n: int
) -> np.ndarray:
    """The bilinear (``n = 2``) / bicubic (``n = 4``) path of
    :func:`geoblock.dem.sampling.sample` by (M, n, n) gathers (NaN outside the array)."""
    rows, cols = array.shape
    out = np.full(row.shape, np.nan)
    finite = np.isfinite(row) & np.isfinite(col)
    with np.errstate(invalid="ignore"):
        r0 = np.floor(row)
        c0 = np.floor(col)
    first = 0 if n == 2 else -1
    ok = finite & (r0 + first >= 0) & (r0 + first + n - 1 < rows)
    ok &= (c0 + first >= 0) & (c0 + first + n - 1 < cols)
    if not ok.any():
        return out
    ri = r0[ok].astype(np.intp) + first
    ci = c0[ok].astype(np.intp) + first
    tr = row[ok] - r0[ok]
    tc = col[ok] - c0[ok]
    if n == 2:
        wr = np.stack([1.0 - tr, tr], axis=-1)
        wc = np.stack([1.0 - tc, tc], axis=-1)
    else:
        wr = _keys(tr)
        wc = _keys(tc)
    taps = array[ri[:, None, None] + np.arange(n)[None, :, None],
                 ci[:, None, None] + np.arange(n)[None, None, :]]  # (M, n, n)
    out[ok] = np.einsum("mi,mij,mj->m", wr, taps, wc)
    return out


def pixel_coords_reference(
    dem: RasterDem, lon: np.ndarray, lat: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """:meth:`RasterDem.pixel_coords <geoblock.dem.RasterDem.pixel_coords>` in numpy:
    pixel-centre ``(row, col)`` of WGS84 points, longitudes wrapped from the raster's west
    edge for a geographic raster."""
    x, y = lonlat_to_crs(dem.crs, np.asarray(lon, float), np.asarray(lat, float))
    if dem._lonlat:
        west = dem.transform.c
        x = west + (np.asarray(x, float) - west) % 360.0
    row, col = map_to_pixel(dem.transform, x, y)
    return np.asarray(row, float), np.asarray(col, float)


def sample_reference(
    dem: RasterDem, lon: np.ndarray, lat: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """``RasterDem._sample`` in numpy: ellipsoidal heights (NaN for none) and the mask of the
    points outside the raster, per-block groups sampled by
    :func:`~geoblock.dem.sampling.sample` from the shared block cache."""
    rows, cols = dem.shape
    row, col = pixel_coords_reference(dem, lon, lat)
    with np.errstate(invalid="ignore"):
        inside = inside_image(row, col, (rows, cols))
    out = np.full(lon.shape, np.nan)
    if not inside.any():
        return out, ~inside
    idx = np.flatnonzero(inside)
    r = np.clip(row[idx], 0.0, rows - 1.0)
    c = np.clip(col[idx], 0.0, cols - 1.0)
    b = dem._block
    if dem.interpolation == "nearest":  # the block of the pixel holding the point
        br, bc = np.floor(r + PIXEL_CENTRE) // b, np.floor(c + PIXEL_CENTRE) // b
    else:
        br = np.minimum(np.floor(r), rows - 1) // b
        bc = np.minimum(np.floor(c), cols - 1) // b
    keys = (br * dem._nbc + bc).astype(np.int64)
    values = np.empty(idx.size)
    groups: list[tuple[int, slice | np.ndarray]]
    if keys.size and keys.min() == keys.max():
        groups = [(int(keys[0]), slice(None))]
    else:
        order = np.argsort(keys, kind="stable")
        uniq, starts = np.unique(keys[order], return_index=True)
        ends = np.append(starts[1:], order.size)
        groups = [(int(k), order[s:e]) for k, s, e in zip(uniq, starts, ends, strict=True)]
    for key, sel in groups:
        kr, kc = divmod(key, dem._nbc)
        block = BLOCK_CACHE.get((*dem._cache_key, kr, kc), _loader(dem, kr, kc))
        values[sel] = sample(block, r[sel] - (kr * b - _HALO), c[sel] - (kc * b - _HALO),
                             dem.interpolation)
    if dem.geoid is not None:
        values = values + dem.geoid.undulation(lon[idx], lat[idx])
    out[idx] = values
    return out, ~inside


def _loader(dem: RasterDem, kr: int, kc: int) -> Callable[[], np.ndarray]:
    return lambda: dem._load_block(kr, kc)
