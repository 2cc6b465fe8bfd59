"""GridDem.height_range reads only the window of posts around a box."""

from __future__ import annotations

import numpy as np
import pytest

from geoblock import coords
from geoblock.dem import GridDem


@pytest.mark.parametrize("crs", ["EPSG:32631", "EPSG:4326"])
def test_height_range_of_a_box_brackets_the_posts_inside_it(crs):
    rng = np.random.default_rng(2)
    heights = rng.uniform(0.0, 1000.0, (400, 500))
    if crs == "EPSG:4326":
        transform = (0.001, 0.0, 2.0, 0.0, -0.001, 45.0)
    else:
        transform = (30.0, 0.0, 400000.0, 0.0, -30.0, 5000000.0)
    dem = GridDem(heights, transform, crs)
    rr, cc = np.mgrid[0:400, 0:500]
    a, b, c, d, e, f = transform
    x, y = a * (cc + 0.5) + c, e * (rr + 0.5) + f
    if crs == "EPSG:4326":
        lon, lat = x, y
    else:
        lon, lat = coords.transformer(crs, "EPSG:4326").transform(x, y)
    w, s, east, n = dem.bounds
    for frac in ((0.2, 0.3, 0.25, 0.33), (0.5, 0.5, 0.9, 0.8), (0.0, 0.0, 1.0, 1.0)):
        box = (w + frac[0] * (east - w), s + frac[1] * (n - s),
               w + frac[2] * (east - w), s + frac[3] * (n - s))
        inside = (lon >= box[0]) & (lon <= box[2]) & (lat >= box[1]) & (lat <= box[3])
        lo, hi = dem.height_range(box)
        assert lo <= heights[inside].min() and hi >= heights[inside].max()
        # the window is the box plus a post or two, not the whole grid
        r = np.flatnonzero(inside.any(axis=1))
        k = np.flatnonzero(inside.any(axis=0))
        near = heights[max(r[0] - 3, 0):r[-1] + 4, max(k[0] - 3, 0):k[-1] + 4]
        assert lo >= near.min() and hi <= near.max()
    assert dem.height_range() == (heights.min(), heights.max())
    assert np.isnan(dem.height_range((100.0, 10.0, 101.0, 11.0))).all()
