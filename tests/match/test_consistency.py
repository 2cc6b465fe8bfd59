"""The outlier test: offsets = a low-order bias + a height parallax along the epipolar
direction + noise; wrong matches injected across and along the epipolar direction."""

from __future__ import annotations

import numpy as np
import pytest

from geoblock.errors import MatchError
from geoblock.match.consistency import (
    Bias,
    consensus,
    consistent,
    fit_bias,
    scale_of,
    split_residuals,
)

SHAPE = (1000, 1000)


def synthetic(n=400, seed=0, epi=(0.15, 0.05), sigma_px=0.2, sigma_h=6.0):
    """Matches whose offsets follow an affine bias, a height parallax of ``sigma_h`` metres
    along ``epi`` (pixels per metre) and ``sigma_px`` of noise."""
    rng = np.random.default_rng(seed)
    centre, scale = scale_of(SHAPE)
    row = rng.uniform(0, SHAPE[0] - 1, n)
    col = rng.uniform(0, SHAPE[1] - 1, n)
    truth = Bias(np.array([[4.0, 0.8, -0.5], [-7.0, 0.3, 1.2]]), centre, scale)
    br, bc = truth(row, col)
    epi_row = np.full(n, epi[0]) * rng.uniform(0.8, 1.2, n)
    epi_col = np.full(n, epi[1]) * rng.uniform(0.8, 1.2, n)
    t = rng.normal(0, sigma_h, n)
    d_row = br + t * epi_row + rng.normal(0, sigma_px, n)
    d_col = bc + t * epi_col + rng.normal(0, sigma_px, n)
    return dict(row=row, col=col, d_row=d_row, d_col=d_col, epi_row=epi_row, epi_col=epi_col,
                truth=truth, centre=centre, scale=scale)


def run(m, start=None, **kw):
    start = np.ones(m["row"].size, bool) if start is None else start
    return consistent(m["row"], m["col"], m["d_row"], m["d_col"], m["epi_row"], m["epi_col"],
                      start, centre=m["centre"], scale=m["scale"], **kw)


def test_split_residuals_is_a_rotation_into_the_epipolar_frame():
    perp, par, norm = split_residuals(np.array([3.0, 0.0]), np.array([4.0, 2.0]),
                                      np.array([0.6, 0.0]), np.array([0.8, 0.0]))
    assert np.allclose([par[0], perp[0], norm[0]], [5.0, 0.0, 1.0])
    # no epipolar direction (|e| = 0): the along axis is the row axis
    assert np.allclose([par[1], perp[1], norm[1]], [0.0, 2.0, 0.0])


def test_the_bias_is_recovered_and_the_scales_measured():
    m = synthetic()
    out = run(m)
    assert out.converged
    assert out.inlier.mean() > 0.97
    # along the epipolar direction the bias is known as well as the mean height parallax
    # (6 m x 0.16 px/m per match)
    assert np.allclose(out.bias.coefficients, m["truth"].coefficients, atol=0.15)
    assert out.sigma_px == pytest.approx(0.2, rel=0.2)
    assert out.sigma_h_m == pytest.approx(6.0, rel=0.2)


def test_wrong_matches_are_rejected_by_the_test_that_sees_them():
    m = synthetic(seed=1)
    n = m["row"].size
    rng = np.random.default_rng(5)
    # 40 matches moved 1.5-8 px across the epipolar direction, 40 moved 30-50 m of height
    # along it: both would pass a homography fitted with a few pixels' tolerance
    across = np.arange(40)
    along = np.arange(40, 80)
    e = np.stack([m["epi_row"], m["epi_col"]], axis=-1)
    u = e / np.linalg.norm(e, axis=1, keepdims=True)
    nrm = np.stack([-u[:, 1], u[:, 0]], axis=-1)
    push = rng.uniform(1.5, 8.0, 40) * rng.choice([-1, 1], 40)
    m["d_row"][across] += push * nrm[across, 0]
    m["d_col"][across] += push * nrm[across, 1]
    lift = rng.uniform(30.0, 50.0, 40) * rng.choice([-1, 1], 40)
    m["d_row"][along] += lift * e[along, 0]
    m["d_col"][along] += lift * e[along, 1]
    start = consensus(m["d_row"], m["d_col"], m["epi_row"], m["epi_col"], tolerance_px=3.0,
                      height_tolerance_m=30.0)
    out = run(m, start)
    assert out.epipolar[across].all()
    assert out.height[along].mean() > 0.9
    good = np.arange(80, n)
    assert out.inlier[good].mean() > 0.97
    assert np.allclose(out.bias.coefficients, m["truth"].coefficients, atol=0.15)


def test_weak_convergence_makes_the_test_isotropic():
    """Two views from nearly the same direction (|e| ~ 0): a wrong match along any direction
    is rejected."""
    m = synthetic(epi=(1e-12, 0.0), sigma_h=0.0)
    m["d_row"][:10] += 2.0
    m["d_col"][10:20] += 2.0
    out = run(m)
    assert not out.inlier[:20].any()
    assert out.inlier[20:].mean() > 0.97


def test_consensus_finds_the_majority_offset_among_random_matches():
    m = synthetic(n=200, seed=2)
    rng = np.random.default_rng(0)
    wrong = rng.random(200) < 0.45  # 45 % random offsets within +-60 px
    m["d_row"][wrong] = rng.uniform(-60, 60, wrong.sum())
    m["d_col"][wrong] = rng.uniform(-60, 60, wrong.sum())
    agree = consensus(m["d_row"], m["d_col"], m["epi_row"], m["epi_col"], tolerance_px=3.0,
                      height_tolerance_m=20.0)
    assert agree[~wrong].mean() > 0.9
    assert agree[wrong].mean() < 0.05


def test_fit_bias_lowers_its_order_with_few_points_and_refuses_none():
    m = synthetic(n=5)
    bias = fit_bias(m["row"], m["col"], m["d_row"], m["d_col"], m["epi_row"], m["epi_col"],
                    order=2, sigma_px=0.1, sigma_h_m=6.0, centre=m["centre"], scale=m["scale"])
    assert bias.order == 0
    # 10 matches per term: an affine bias from 30, a quadratic one from 60
    m = synthetic(n=100)
    for n, order, expected in ((29, 1, 0), (30, 1, 1), (59, 2, 1), (60, 2, 2)):
        bias = fit_bias(m["row"][:n], m["col"][:n], m["d_row"][:n], m["d_col"][:n],
                        m["epi_row"][:n], m["epi_col"][:n], order=order, sigma_px=0.1,
                        sigma_h_m=6.0, centre=m["centre"], scale=m["scale"])
        assert bias.order == expected, (n, order)
    with pytest.raises(MatchError, match="no match"):
        fit_bias(m["row"][:0], m["col"][:0], m["d_row"][:0], m["d_col"][:0], m["epi_row"][:0],
                 m["epi_col"][:0], order=1, sigma_px=1, sigma_h_m=1, centre=(0, 0), scale=1)
    with pytest.raises(MatchError, match="order"):
        fit_bias(m["row"], m["col"], m["d_row"], m["d_col"], m["epi_row"], m["epi_col"],
                 order=3, sigma_px=1, sigma_h_m=1, centre=(0, 0), scale=1)


def test_the_bias_mean_is_its_value_where_the_pixels_are_not_at_the_centre():
    centre, scale = scale_of(SHAPE)
    bias = Bias(np.array([[4.0, 0.8, -0.5], [-7.0, 0.3, 1.2]]), centre, scale)
    # pixels in the image's lower-right corner (an overlap at its edge): y = x = 0.9
    row = np.full(3, centre[0] + 0.9 * scale) + np.array([-1.0, 0.0, 1.0])
    col = np.full(3, centre[1] + 0.9 * scale)
    assert bias.mean(row, col) == pytest.approx((4.0 + 0.72 - 0.45, -7.0 + 0.27 + 1.08))
    assert bias.mean(np.array([centre[0]]), np.array([centre[1]])) == pytest.approx((4.0, -7.0))
    assert np.isnan(bias.mean(row[:0], col[:0])).all()


def test_matches_rejected_earlier_never_enter_the_bias_fit():
    """Candidates an earlier test rejected (ratio, correlation) may lie close to the bias by
    chance; they get residuals but must neither move the bias nor widen the scales."""
    m = synthetic(n=300, seed=3)
    rng = np.random.default_rng(4)
    extra = 300
    stale = {key: np.concatenate([m[key], m[key][:extra]]) for key in
             ("row", "col", "epi_row", "epi_col")}
    # the same pixels, offsets 0.4 px off the bias across the board: within the tests' reach
    stale["d_row"] = np.concatenate([m["d_row"], m["d_row"][:extra] + 0.4])
    stale["d_col"] = np.concatenate([m["d_col"], m["d_col"][:extra] + rng.normal(0, 0.3, extra)])
    eligible = np.r_[np.ones(300, bool), np.zeros(extra, bool)]
    both = dict(m, **stale)
    out = run(both, eligible=eligible)
    alone = run(m)
    assert not out.inlier[~eligible].any()
    assert np.allclose(out.bias.coefficients, alone.bias.coefficients)
    assert out.sigma_px == pytest.approx(alone.sigma_px)
    assert out.perp.shape == (600,) and np.isfinite(out.perp).all()
    # without the mask they would have been taken: the bias moves by about 0.2 px
    mixed = run(both)
    assert mixed.inlier[~eligible].mean() > 0.5
    assert abs(mixed.bias.coefficients[0, 0] - alone.bias.coefficients[0, 0]) > 0.1
