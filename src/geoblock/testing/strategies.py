"""Hypothesis strategies over a sensor model's image and height range.

Usable with ``@given`` in property tests of any :class:`~geoblock.models.SensorModel`::

    from hypothesis import given, settings
    from geoblock.testing.strategies import ground_points, image_points, heights

    MODEL = MyModel(...)

    @settings(max_examples=50, deadline=None)
    @given(point=image_points(MODEL), h=heights(MODEL))
    def test_round_trip(point, h):
        row, col = point
        lon, lat, _ = MODEL.backproject(row, col, h)
        r, c = MODEL.project(lon, lat, h)
        assert abs(r - row) < 1e-6 and abs(c - col) < 1e-6

The image strategies draw from pixel edge to pixel edge (``-0.5 .. rows - 0.5``), both ends
included, so hypothesis tries the image border first. Needs the ``testing`` extra (hypothesis).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from hypothesis import assume
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from geoblock.typing import GroundCoords, Status

__all__ = ["ground_points", "heights", "image_points"]


def _floats(lo: float, hi: float, shape: int | tuple[int, ...] | None) -> st.SearchStrategy:
    elements = st.floats(lo, hi, allow_nan=False, allow_infinity=False)
    if shape is None:
        return elements
    return hnp.arrays(np.float64, shape, elements=elements)


def image_points(
    model: Any, *, shape: int | tuple[int, ...] | None = None
) -> st.SearchStrategy[tuple[Any, Any]]:
    """``(row, col)`` inside the image, pixel edges included.

    Parameters
    ----------
    model : SensorModel
        Gives ``shape`` (rows, cols).
    shape : int or tuple of int, optional
        ``None`` (default) draws Python floats; otherwise float64 arrays of this shape.

    Returns
    -------
    SearchStrategy of (row, col)
        Pixels, pixel-centre convention, ``-0.5 <= row <= rows - 0.5`` and
        ``-0.5 <= col <= cols - 0.5``.
    """
    rows, cols = (int(v) for v in model.shape)
    return st.tuples(_floats(-0.5, rows - 0.5, shape), _floats(-0.5, cols - 0.5, shape))


def heights(
    model: Any, *, shape: int | tuple[int, ...] | None = None
) -> st.SearchStrategy[Any]:
    """Heights within the model's ``height_range``, both ends included.

    Parameters
    ----------
    model : SensorModel
    shape : int or tuple of int, optional
        ``None`` (default) draws Python floats; otherwise float64 arrays of this shape.

    Returns
    -------
    SearchStrategy of float or ndarray
        Metres above the WGS84 ellipsoid.
    """
    h0, h1 = (float(v) for v in model.height_range)
    return _floats(h0, h1, shape)


def ground_points(
    model: Any, *, shape: int | tuple[int, ...] | None = None
) -> st.SearchStrategy[GroundCoords]:
    """Ground points seen by the image: backprojections of :func:`image_points` at :func:`heights`.

    Draws whose backprojection fails (a non-CONVERGED status) are rejected with
    ``hypothesis.assume``; a conforming model never fails inside its image.

    Parameters
    ----------
    model : SensorModel
    shape : int or tuple of int, optional
        ``None`` (default) draws 0-d points (``float(lon)`` works); otherwise arrays of this
        shape.

    Returns
    -------
    SearchStrategy of GroundCoords
        ``lon, lat`` degrees and ``h`` metres above the WGS84 ellipsoid.
    """

    @st.composite
    def _ground(draw: st.DrawFn) -> GroundCoords:
        row, col = draw(image_points(model, shape=shape))
        h = draw(heights(model, shape=shape))
        ground, status = model.backproject_with_status(row, col, h)
        assume(bool(np.all(np.asarray(status) == Status.CONVERGED)))
        return GroundCoords(*(np.asarray(a, dtype=np.float64) for a in ground))

    return _ground()
