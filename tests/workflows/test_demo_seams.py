"""The seam measurement (:mod:`geoblock.match.seams`, which ``geoblock demo`` re-exports) on
known shifts, its outcomes, the orthos placed on one grid, and the small demo's orthos lined up
at the seams after the block adjustment."""

from __future__ import annotations

import math

import numpy as np
import pytest
from affine import Affine
from scipy import ndimage

import geoblock.match.seams as seams
from geoblock.errors import GridError, MosaicError, ShapeMismatchError
from geoblock.match.seams import (
    SEAM_SEGMENTS,
    on_common_grid,
    overlapping_pairs,
    seam_shift,
    smoothed_overlap,
)
from geoblock.workflows.demo import run_demo

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
    with pytest.raises(GridError, match="north-up"):
        seam_shift(a, b, Affine(RES, 0.0, 0.0, 0.0, RES, 0.0), ("x", "y"))


def test_seam_shift_outcome_at_the_iteration_cap(monkeypatch):
    monkeypatch.setattr(seams, "SEAM_MAX_ITERATIONS", 1)
    s = seam_shift(*_pair(0.3, -0.2), TRANSFORM)
    # with robust weights a match cannot converge at its first iteration
    assert s.status == "not converged" and s.iterations == 1 and math.isnan(s.e)
    assert set(s.segment_status) == {"not converged"}


def test_the_demo_re_exports_the_seam_measurement():
    import geoblock.workflows.demo as demo

    assert demo.seam_shift is seam_shift and demo.SeamShift is seams.SeamShift
    assert {"seam_shift", "SeamShift"} <= set(demo.__all__)


def test_orthos_on_a_common_grid_and_their_overlaps():
    rng = np.random.default_rng(2)
    one, two, far = (rng.uniform(1, 2, (30, 40)) for _ in range(3))
    t_one = Affine(RES, 0.0, 1000.0, 0.0, -RES, 5000.0)
    t_two = Affine(RES, 0.0, 1000.0 + 25 * RES, 0.0, -RES, 5000.0 - 4 * RES)  # 4 rows down
    t_far = Affine(RES, 0.0, 1000.0 + 70 * RES, 0.0, -RES, 5000.0)
    grids, transform = on_common_grid({"one": (one, t_one), "two": (two, t_two),
                                       "far": (far, t_far)})
    assert tuple(transform)[:6] == (RES, 0.0, 1000.0, 0.0, -RES, 5000.0)
    assert all(g.shape == (34, 110) and g.dtype == np.float32 for g in grids.values())
    np.testing.assert_array_equal(grids["two"][4:34, 25:65], two.astype(np.float32))
    assert np.isnan(grids["two"][:4]).all() and np.isnan(grids["two"][:, :25]).all()
    # one and two share 30 - 4 rows x 40 - 25 columns; far touches neither
    assert overlapping_pairs(grids) == [("one", "two")]
    assert overlapping_pairs(grids, min_pixels=26 * 15 + 1) == []
    found = smoothed_overlap(grids["one"], grids["two"], 2)
    assert found is not None and found.origin == (2, 23)
    assert found.a.shape == found.b.shape == found.core.shape == (26 + 4, 15 + 4)
    assert found.core.sum() == (26 - 4) * (15 - 4)  # 2 px inside the overlap's edges
    assert smoothed_overlap(grids["one"], grids["far"], 2) is None
    with pytest.raises(MosaicError, match="two.*pixel-aligned"):
        on_common_grid({"one": (one, t_one), "two": (two, t_two @ Affine.translation(0.5, 0))})
    with pytest.raises(MosaicError, match="two.*resolution"):
        on_common_grid({"one": (one, t_one), "two": (two, t_two @ Affine.scale(2.0))})
    with pytest.raises(MosaicError, match="no ortho"):
        on_common_grid({})


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
