"""Coordinate containers and per-point status codes.

Conventions (docs/explanation/conventions.md):

* image coordinates ``(row, col)`` in pixels, integers at pixel centres: ``(0, 0)`` is the
  centre of ``array[0, 0]`` and an image of ``rows x cols`` pixels covers
  ``[-0.5, rows - 0.5) x [-0.5, cols - 0.5)``;
* ground coordinates ``(lon, lat, h)``: degrees and metres above the WGS84 ellipsoid
  (EPSG:4979);
* ECEF coordinates ``(x, y, z)`` in metres (EPSG:4978).

Every array is float64 and all arrays of one container share the broadcast shape ``S`` of the
inputs that produced them.
"""

from __future__ import annotations

import enum
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "ArrayLike",
    "BoolArray",
    "EcefCoords",
    "Float64Array",
    "GroundCoords",
    "ImageCoords",
    "IndexArray",
    "LineOfSight",
    "Status",
    "StatusArray",
    "StrArray",
]

Float64Array = NDArray[np.float64]
"""A float64 array: coordinates, residuals, sigmas, partials."""
BoolArray = NDArray[np.bool_]
"""A boolean array: masks and flags."""
IndexArray = NDArray[np.intp]
"""An integer index array (``np.intp``): positions into another array."""
StrArray = NDArray[np.str_]
"""A unicode string array: point ids, image ids, point kinds."""
StatusArray = NDArray[np.uint8]
"""A per-point :class:`Status` array, stored as ``uint8``."""


class ImageCoords(NamedTuple):
    """Image coordinates, pixels, pixel-centre convention."""

    row: Float64Array
    """(*S,) row (line) coordinate, pixels; 0 is the centre of the first row."""
    col: Float64Array
    """(*S,) column (sample) coordinate, pixels; 0 is the centre of the first column."""


class GroundCoords(NamedTuple):
    """Geodetic coordinates on WGS84 (EPSG:4979)."""

    lon: Float64Array
    """(*S,) longitude, degrees east."""
    lat: Float64Array
    """(*S,) latitude, degrees north."""
    h: Float64Array
    """(*S,) height above the WGS84 ellipsoid, metres."""


class EcefCoords(NamedTuple):
    """Earth-centred, Earth-fixed Cartesian coordinates on WGS84 (EPSG:4978), metres."""

    x: Float64Array
    y: Float64Array
    z: Float64Array


class Status(enum.IntEnum):
    """Per-point outcome of a computation; stored as ``uint8`` arrays.

    Every point whose status is not ``CONVERGED`` is NaN in the coordinates returned with it.
    """

    CONVERGED = 0
    """The point was computed (and, for iterative solvers, met the tolerance)."""
    MAX_ITERATIONS = 1
    """The iteration cap was reached before the tolerance was met."""
    DIVERGED = 2
    """The iteration left the model's domain or produced non-finite values."""
    OUT_OF_DOMAIN = 3
    """The input lies outside the model's validity domain."""
    NO_DEM = 4
    """No DEM height is available at the point."""
    NO_INTERSECTION = 5
    """The line of sight does not meet the DEM."""
    INVALID_INPUT = 6
    """An input coordinate was NaN or infinite."""


class LineOfSight(NamedTuple):
    """A line of sight (CSM's imaging locus) in ECEF."""

    origin: Float64Array
    """(*S, 3) a point on the line, metres ECEF (at the top of the model's height range)."""
    direction: Float64Array
    """(*S, 3) unit vector pointing down the line of sight (towards the ground)."""
