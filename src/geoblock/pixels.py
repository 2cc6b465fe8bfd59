"""Image-pixel conventions: geoblock's pixel centres against GDAL's corner-based pixel/line.

geoblock's image coordinates ``(row, col)`` are float64 with integers at pixel **centres**:
``(0, 0)`` is the centre of ``array[0, 0]`` and an image of ``(rows, cols)`` pixels covers
``[-0.5, rows - 0.5) x [-0.5, cols - 0.5)`` (RPC00B's convention). GDAL's pixel/line, and the
affine geotransforms of rasterio and GDAL, are corner-based: GDAL ``(pixel, line)`` =
``(col + 0.5, row + 0.5)``. This module is the one place where the half pixel is written; use
it (or :data:`PIXEL_CENTRE` inside compiled kernels) instead of a hand-written ``± 0.5``.

All functions are vectorised over broadcastable arrays and return float64 arrays.
"""

from __future__ import annotations

import numpy as np
from affine import Affine

from geoblock.typing import ArrayLike, Float64Array

__all__ = [
    "PIXEL_CENTRE",
    "centre_to_corner",
    "corner_to_centre",
    "image_domain",
    "inside_image",
    "map_to_pixel",
    "pixel_centres",
    "pixel_to_map",
]

PIXEL_CENTRE = 0.5
"""Offset of a pixel's centre from its top-left corner, pixels (``corner = centre + 0.5``)."""


def centre_to_corner(row: ArrayLike, col: ArrayLike) -> tuple[Float64Array, Float64Array]:
    """Corner-based ``(line, pixel)`` (GDAL's order reversed) of pixel-centre ``(row, col)``.

    Returns ``(row + 0.5, col + 0.5)``: GDAL's line and pixel, in geoblock's row-first order.
    """
    return (
        np.asarray(row, dtype=np.float64) + PIXEL_CENTRE,
        np.asarray(col, dtype=np.float64) + PIXEL_CENTRE,
    )


def corner_to_centre(line: ArrayLike, pixel: ArrayLike) -> tuple[Float64Array, Float64Array]:
    """Pixel-centre ``(row, col)`` of GDAL's corner-based ``line`` and ``pixel``, pixels."""
    return (
        np.asarray(line, dtype=np.float64) - PIXEL_CENTRE,
        np.asarray(pixel, dtype=np.float64) - PIXEL_CENTRE,
    )


def pixel_to_map(
    transform: Affine, row: ArrayLike, col: ArrayLike
) -> tuple[Float64Array, Float64Array]:
    """Map coordinates ``(x, y)`` of pixel-centre image coordinates through a geotransform.

    Parameters
    ----------
    transform : affine.Affine
        A rasterio/GDAL geotransform (corner-based: it maps ``(pixel, line)`` to ``(x, y)``);
        rotated and sheared transforms are handled.
    row, col : array_like
        Image coordinates, pixels, pixel-centre convention; broadcast together.

    Returns
    -------
    x, y : ndarray
        Map coordinates in the transform's CRS units.
    """
    line, pixel = centre_to_corner(row, col)
    a, b, c, d, e, f = tuple(transform)[:6]
    return a * pixel + b * line + c, d * pixel + e * line + f


def map_to_pixel(
    transform: Affine, x: ArrayLike, y: ArrayLike
) -> tuple[Float64Array, Float64Array]:
    """Pixel-centre ``(row, col)`` of map coordinates: the inverse of :func:`pixel_to_map`."""
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    a, b, c, d, e, f = tuple(~transform)[:6]
    return corner_to_centre(d * x + e * y + f, a * x + b * y + c)


def pixel_centres(transform: Affine, shape: tuple[int, int]) -> tuple[Float64Array, Float64Array]:
    """Map ``x`` of each column's and ``y`` of each row's centre for a north-up grid.

    Returns ``(x, y)`` of shapes ``(cols,)`` and ``(rows,)``; the transform must have no
    rotation (``b == d == 0``), which is checked.
    """
    if transform.b != 0.0 or transform.d != 0.0:
        raise ValueError(f"pixel_centres needs a north-up transform, got {transform!r}")
    rows, cols = shape
    x = transform.c + transform.a * (np.arange(cols, dtype=np.float64) + PIXEL_CENTRE)
    y = transform.f + transform.e * (np.arange(rows, dtype=np.float64) + PIXEL_CENTRE)
    return x, y


def image_domain(shape: tuple[int, int]) -> tuple[float, float, float, float]:
    """``(row_min, col_min, row_max, col_max)`` an image of ``shape`` covers, pixel centres.

    The image is the half-open box ``[-0.5, rows - 0.5) x [-0.5, cols - 0.5)``.
    """
    rows, cols = shape
    return -PIXEL_CENTRE, -PIXEL_CENTRE, rows - PIXEL_CENTRE, cols - PIXEL_CENTRE


def inside_image(
    row: ArrayLike, col: ArrayLike, shape: tuple[int, int], *, closed: bool = True
) -> np.ndarray:
    """Boolean mask of the points inside an image of ``shape``.

    ``closed=True`` (the default) counts the far edges ``rows - 0.5`` and ``cols - 0.5`` as
    inside, as interpolation up to the last pixel's outer edge does; ``closed=False`` is the
    half-open domain of :func:`image_domain`. NaN is outside.
    """
    r0, c0, r1, c1 = image_domain(shape)
    row = np.asarray(row, dtype=np.float64)
    col = np.asarray(col, dtype=np.float64)
    if closed:
        return (row >= r0) & (row <= r1) & (col >= c0) & (col <= c1)
    return (row >= r0) & (row < r1) & (col >= c0) & (col < c1)
