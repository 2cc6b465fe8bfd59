"""The compiled bilinear/bicubic DEM sampling agrees with its numpy reference."""

import numpy as np
import pytest

from geoblock.dem._reference import sample_array_reference
from geoblock.dem.sampling import sample


@pytest.mark.parametrize(("interpolation", "n"), [("bilinear", 2), ("bicubic", 4)])
def test_compiled_sampling_equals_the_numpy_reference(interpolation, n):
    rng = np.random.default_rng(0)
    array = rng.normal(500.0, 200.0, (60, 70))
    array[10, 20] = np.nan  # a void: taps touching it give NaN in both paths
    row = rng.uniform(-3.0, 63.0, 20000)
    col = rng.uniform(-3.0, 73.0, 20000)
    row[:5] = np.nan
    fast = sample(array, row, col, interpolation)
    ref = sample_array_reference(array, row, col, n)
    assert np.array_equal(np.isnan(fast), np.isnan(ref))
    ok = ~np.isnan(ref)
    assert ok.sum() > 15000
    assert np.max(np.abs(fast[ok] - ref[ok])) < 1e-9
