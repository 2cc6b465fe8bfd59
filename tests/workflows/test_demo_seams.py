"""The demo's seam measurement (``seam_shift``) on known shifts, and the small demo's orthos
lined up at the seams after the block adjustment."""

from __future__ import annotations

import math

import numpy as np
import pytest
from affine import Affine
from scipy import ndimage

from geoblock.errors import ShapeMismatchError
from geoblock.workflows.demo import SEAM_SEGMENTS, run_demo, seam_shift

RES = 10.0
TRANSFORM = Affine(RES, 0.0, 500_000.0, 0.0, -RES, 2_600_000.0)


def _pair(d_row: float, d_col: float, *, rows: int = 240, cols: int = 160, gain: float = 1.0,
          offset: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Two overlapping 'orthos' of one band-limited texture, ``b``'s content moved by
    ``(d_row, d_col)`` pixels: ``b(x) = gain * a(x - d) + offset``; ``a`` has no pixel right
    of column 100, ``b`` none left of column 40."""
    rng = np.random.default_rng(5)
    texture = ndimage.gaussian_filter(rng.normal(size=(rows + 40, cols + 40)), 2.0) * 60 + 120
    a = texture[20:-20, 20:-20].copy()
    moved = ndimage.shift(texture, (d_row, d_col), order=3, mode="nearest")
    b = gain * moved[20:-20, 20:-20] + offset
    a[:, 100:] = np.nan
    b[:, :40] = np.nan
    return a, b


@pytest.mark.parametrize(("d_row", "d_col"), [(0.0, 0.0), (0.3, -0.2), (-0.7, 1.1)])
def test_seam_shift_recovers_a_known_shift(d_row, d_col):
    a, b = _pair(d_row, d_col, gain=1.1, offset=-5.0)
    s = seam_shift(a, b, TRANSFORM, ("a", "b"))
    assert s.status == "converged" and s.images == ("a", "b")
    # metres along east (columns) and north (rows run south)
    assert s.e == pytest.approx(d_col * RES, abs=0.02)
    assert s.n == pytest.approx(-d_row * RES, abs=0.02)
    assert s.shift == pytest.approx(math.hypot(d_row, d_col) * RES, abs=0.03)
    assert s.segment_e.shape == s.segment_n.shape == (SEAM_SEGMENTS,)
    assert list(s.segment_status) == ["converged"] * SEAM_SEGMENTS
    np.testing.assert_allclose(s.segment_e, d_col * RES, atol=0.05)
    np.testing.assert_allclose(s.segment_n, -d_row * RES, atol=0.05)
    assert s.segment_rms == pytest.approx(s.shift, abs=0.05)
    # the segments run along the overlap (columns 40-99), in map coordinates
    assert np.all((s.segment_x > 500_000 + 40 * RES) & (s.segment_x < 500_000 + 100 * RES))
    assert np.ptp(s.segment_y) > 0.6 * 240 * RES
    assert s.as_dict()["segments"][0]["status"] == "converged"


def test_seam_shift_minus_a_reference():
    moved = seam_shift(*_pair(0.3, -0.2), TRANSFORM)
    reference = seam_shift(*_pair(0.1, 0.1), TRANSFORM)
    d = moved.minus(reference)
    assert d.e == pytest.approx(-0.3 * RES, abs=0.03) and d.n == pytest.approx(-0.2 * RES,
                                                                               abs=0.03)
    np.testing.assert_allclose(d.segment_e, -0.3 * RES, atol=0.06)
    assert d.status == "converged" and d.pixels == moved.pixels
    a, _ = _pair(0.0, 0.0)
    empty = seam_shift(a, np.full_like(a, np.nan), TRANSFORM)
    assert empty.status == "too few pixels"
    with pytest.raises(ShapeMismatchError, match="segments"):
        moved.minus(empty)


def test_seam_shift_outcomes():
    a, b = _pair(0.2, 0.1)
    # no overlap: nothing to match
    far = np.full_like(b, np.nan)
    s = seam_shift(a, far, TRANSFORM)
    assert s.status == "too few pixels" and s.pixels == 0 and math.isnan(s.shift)
    assert s.segment_e.size == 0 and math.isnan(s.segment_rms)
    assert s.as_dict()["e"] is None
    # a uniform overlap has no texture to match
    flat = np.where(np.isnan(a), np.nan, 100.0)
    flat_b = np.where(np.isnan(b), np.nan, 100.0)
    s = seam_shift(flat, flat_b, TRANSFORM)
    assert s.status == "no texture" and math.isnan(s.e)
    assert set(s.segment_status) == {"no texture"}
    # beyond the largest shift followed
    a, b = _pair(0.0, 6.0)
    assert seam_shift(a, b, TRANSFORM).status in ("diverged", "not converged")
    with pytest.raises(ShapeMismatchError, match="x and y"):
        seam_shift(a, b[:-1], TRANSFORM, ("x", "y"))


@pytest.mark.slow
def test_small_demo_orthos_line_up_after_the_block_adjustment(tmp_path):
    result = run_demo(tmp_path / "demo", size="small")
    pairs = [("strip1", "strip2"), ("strip2", "strip3")]
    for key in ("true", "onboard", "block"):
        assert list(result.seams[key]) == pairs
    for pair in pairs:
        true, before, after = (result.seams[k][pair] for k in ("true", "onboard", "block"))
        assert {true.status, before.status, after.status} == {"converged"}
        # as measured: misregistered by tens of metres on-board; after, as close as the
        # true-model orthos (the measurement's own error on these images, a few metres)
        assert before.shift > 25.0 and after.shift < min(6.0, before.shift / 5)
        assert true.shift < 6.0 and after.segment_rms < before.segment_rms / 3
        # less the true-model orthos' shift: along the whole seam
        before, after = (result.seam_discrepancies[k][pair] for k in ("onboard", "block"))
        assert before.shift > 25.0 and after.shift < 3.0
        assert list(after.segment_status) == ["converged"] * SEAM_SEGMENTS
        assert after.segment_rms < 6.0 < 25.0 < before.segment_rms
