"""The one pixel-convention helper against rasterio's own centre/corner arithmetic."""

from __future__ import annotations

import numpy as np
import pytest
import rasterio.transform
from affine import Affine
from hypothesis import given
from hypothesis import strategies as st

from geoblock import pixels

TRANSFORMS = [
    Affine(10.0, 0.0, 500000.0, 0.0, -10.0, 4800000.0),
    Affine(0.5, 0.1, 300.0, -0.2, -0.5, 900.0),  # rotated and sheared
]


@pytest.mark.parametrize("transform", TRANSFORMS)
def test_pixel_to_map_is_rasterios_centre(transform):
    rows, cols = np.meshgrid(np.arange(5), np.arange(7), indexing="ij")
    x, y = pixels.pixel_to_map(transform, rows, cols)
    xs, ys = rasterio.transform.xy(transform, rows.ravel(), cols.ravel(), offset="center")
    np.testing.assert_allclose(x.ravel(), xs, rtol=0, atol=1e-9)
    np.testing.assert_allclose(y.ravel(), ys, rtol=0, atol=1e-9)


@pytest.mark.parametrize("transform", TRANSFORMS)
@given(
    row=st.floats(-1e4, 1e4, allow_nan=False), col=st.floats(-1e4, 1e4, allow_nan=False)
)
def test_map_to_pixel_inverts_pixel_to_map(transform, row, col):
    r, c = pixels.map_to_pixel(transform, *pixels.pixel_to_map(transform, row, col))
    assert r == pytest.approx(row, abs=1e-7) and c == pytest.approx(col, abs=1e-7)


def test_corner_of_first_pixel_is_its_top_left_and_domain_is_half_open():
    t = TRANSFORMS[0]
    assert pixels.pixel_to_map(t, -0.5, -0.5) == (t.c, t.f)
    assert pixels.centre_to_corner(0.0, 0.0) == (0.5, 0.5)
    assert pixels.corner_to_centre(0.5, 0.5) == (0.0, 0.0)
    assert pixels.image_domain((3, 4)) == (-0.5, -0.5, 2.5, 3.5)
    inside = pixels.inside_image([-0.5, 2.5, 2.6, np.nan], [0.0, 3.5, 0.0, 0.0], (3, 4))
    assert inside.tolist() == [True, True, False, False]
    assert not pixels.inside_image(2.5, 0.0, (3, 4), closed=False)


def test_pixel_centres_of_a_north_up_grid_and_refusal_of_a_rotated_one():
    x, y = pixels.pixel_centres(TRANSFORMS[0], (2, 3))
    assert x.tolist() == [500005.0, 500015.0, 500025.0]
    assert y.tolist() == [4799995.0, 4799985.0]
    with pytest.raises(ValueError, match="north-up"):
        pixels.pixel_centres(TRANSFORMS[1], (2, 3))
