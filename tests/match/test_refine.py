"""Sub-pixel refinement (correlation, then least-squares matching) on images whose shift is
known exactly: a smooth random texture resampled at a known offset; and the least-squares
matching solver it shares with the seam measurement (:mod:`geoblock.match.lsm`) on an analytic
image."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.ndimage import gaussian_filter

import geoblock.match.refine
import geoblock.match.seams
from geoblock.errors import MatchError, ShapeMismatchError
from geoblock.match.lsm import LsmStatus, least_squares_match
from geoblock.match.refine import RefineStatus, refine_matches
from geoblock.ortho.kernels import resample


def smooth_texture(shape=(160, 160), seed=3):
    rng = np.random.default_rng(seed)
    return gaussian_filter(rng.normal(size=shape), 1.5) * 60.0 + 120.0


def shifted(image, d_row, d_col):
    """``B(r, c) = A(r + d_row, c + d_col)``: A's point (ra, ca) is at (ra - d_row, ca - d_col)
    in B."""
    rr, cc = np.meshgrid(*(np.arange(n, dtype=float) for n in image.shape), indexing="ij")
    return resample(image[None], rr + d_row, cc + d_col, "bicubic")[0][0]


def grid_points(n=7, lo=25.0, hi=135.0, seed=1):
    rng = np.random.default_rng(seed)
    r, c = np.meshgrid(np.linspace(lo, hi, n), np.linspace(lo, hi, n), indexing="ij")
    return r.ravel() + rng.uniform(-0.5, 0.5, r.size), c.ravel() + rng.uniform(-0.5, 0.5, r.size)


def test_a_known_shift_is_recovered_to_a_few_hundredths_of_a_pixel():
    a = smooth_texture()
    b = shifted(a, 0.37, -0.21)
    ra, ca = grid_points()
    true_r, true_c = ra - 0.37, ca + 0.21
    # start 1-2 px away, as a keypoint of B would be
    start_r, start_c = np.round(true_r) + 0.8, np.round(true_c) - 0.6
    jac = np.tile(np.eye(2), (ra.size, 1, 1))
    out = refine_matches(a, b, ra, ca, start_r, start_c, jac)
    ok = out.status == RefineStatus.CONVERGED
    assert ok.mean() > 0.9
    err = np.hypot(out.row - true_r, out.col - true_c)[ok]
    assert np.median(err) < 0.03 and err.max() < 0.1, np.percentile(err, [50, 100])
    assert (out.score[ok] > 0.99).all()
    # the precision the least squares report is of the same order as the error
    assert np.median(out.sigma[ok]) < 0.05


def test_the_local_affinity_of_the_models_is_used():
    """B is A rotated by 20 degrees and scaled by 1.1 about a point: with that affinity the
    patches compare; with the identity they do not."""
    a = smooth_texture()
    angle, scale = np.radians(20.0), 1.1
    m = scale * np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    centre = np.array([80.0, 80.0])
    rr, cc = np.meshgrid(np.arange(160.0), np.arange(160.0), indexing="ij")
    # B(x) = A(centre + M^-1 (x - centre)): A's point p is at centre + M (p - centre) in B
    inv = np.linalg.inv(m)
    src = np.einsum("ij,jrc->irc", inv, np.stack([rr, cc]) - centre[:, None, None]) \
        + centre[:, None, None]
    b = resample(a[None], src[0], src[1], "bicubic")[0][0]
    ra, ca = grid_points(5, 55.0, 105.0)
    true = (m @ (np.stack([ra, ca]) - centre[:, None])) + centre[:, None]
    start = np.round(true)
    jac = np.tile(m, (ra.size, 1, 1))
    out = refine_matches(a, b, ra, ca, start[0], start[1], jac)
    ok = out.status == RefineStatus.CONVERGED
    assert ok.mean() > 0.9
    assert np.hypot(out.row - true[0], out.col - true[1])[ok].max() < 0.1
    plain = refine_matches(a, b, ra, ca, start[0], start[1], np.tile(np.eye(2), (ra.size, 1, 1)))
    assert (plain.status == RefineStatus.CONVERGED).mean() < 0.5


def test_edges_nodata_and_flat_patches_are_refused():
    # a vertical step edge: its correlation is a ridge along the edge (a flat one: the peak
    # walks along it out of the search area)
    edge = np.where(np.arange(100)[None, :] < 50, 50.0, 200.0) * np.ones((100, 1))
    edge = gaussian_filter(edge, 1.0)
    n = 3
    jac = np.tile(np.eye(2), (n, 1, 1))
    r = np.array([30.0, 50.0, 70.0])
    c = np.full(n, 50.0)
    out = refine_matches(edge, edge, r, c, r + 0.5, c, jac)
    assert np.isin(out.status, [RefineStatus.RIDGE, RefineStatus.EDGE]).all()
    # no data in B around the points; a flat template in A
    a = smooth_texture((100, 100))
    b = a.copy()
    b[:, 40:] = np.nan
    out = refine_matches(a, b, r, np.full(n, 60.0), r, np.full(n, 60.0), jac)
    assert (out.status == RefineStatus.NO_DATA).all()
    flat = np.full((100, 100), 7.0)
    out = refine_matches(flat, a, r, c, r, c, jac)
    assert (out.status == RefineStatus.NO_DATA).all()
    # failures keep the start
    assert np.array_equal(out.row, r) and np.array_equal(out.col, c)


def test_a_start_too_far_is_an_edge():
    a = smooth_texture()
    b = shifted(a, 0.0, 0.0)
    ra, ca = grid_points(3, 60.0, 100.0)
    jac = np.tile(np.eye(2), (ra.size, 1, 1))
    out = refine_matches(a, b, ra, ca, ra + 9.0, ca, jac, search_px=2)
    assert (out.status != RefineStatus.CONVERGED).all()


def test_options_are_checked():
    a = smooth_texture((40, 40))
    one = np.array([20.0])
    jac = np.eye(2)[None]
    with pytest.raises(MatchError, match="half_px"):
        refine_matches(a, a, one, one, one, one, jac, half_px=1)
    with pytest.raises(MatchError, match="tolerance_px"):
        refine_matches(a, a, one, one, one, one, jac, tolerance_px=0.0)


# ---------------------------------------------------------------- the least-squares solver
WAVES = np.array([[0.7, 0.3], [0.4, -0.9], [-0.25, 0.55]])  # (row, col) frequencies, rad/px


def wavy(row, col):
    """An analytic image and its derivatives along rows and columns."""
    phase = WAVES[:, 0] * np.asarray(row)[..., None] + WAVES[:, 1] * np.asarray(col)[..., None]
    return (np.sin(phase).sum(-1), (np.cos(phase) * WAVES[:, 0]).sum(-1),
            (np.cos(phase) * WAVES[:, 1]).sum(-1))


def patches(n=6, half=5, seed=4):
    """Patch centres ``(n, 2)`` and the pixel offsets of a patch ``(P, 2)``."""
    rng = np.random.default_rng(seed)
    u = np.arange(-half, half + 1.0)
    grid = np.stack(np.meshgrid(u, u, indexing="ij"), -1).reshape(-1, 2)
    return rng.uniform(0, 100, (n, 2)), grid


def sampler(centres, grid, calls=None):
    def sample(index, shift):
        if calls is not None:
            calls.append(index.copy())
        at = centres[index, None, :] + grid[None] + shift[:, None, :]
        return wavy(at[..., 0], at[..., 1])
    return sample


def test_the_solver_recovers_shift_gain_and_offset():
    centres, grid = patches()
    rng = np.random.default_rng(7)
    d = rng.uniform(-0.6, 0.6, (6, 2))
    gain, offset = rng.uniform(0.7, 1.4, 6), rng.uniform(-20, 20, 6)
    at = centres[:, None, :] + grid[None] + d[:, None, :]
    target = offset[:, None] + gain[:, None] * wavy(at[..., 0], at[..., 1])[0]
    calls = []
    out = least_squares_match(target, sampler(centres, grid, calls), np.zeros((6, 2)),
                              tolerance_px=1e-8, max_iterations=20)
    assert (out.status == LsmStatus.CONVERGED).all()
    np.testing.assert_allclose(out.shift, d, atol=1e-7)
    np.testing.assert_allclose(out.gain, gain, rtol=1e-7)
    np.testing.assert_allclose(out.offset, offset, atol=1e-5)
    assert (out.iterations >= 2).all() and (out.iterations <= 10).all()
    # an exact fit: no residual, no variance; every call asks for the patches still active
    assert np.abs(out.covariance).max() < 1e-12
    assert all(np.isin(later, earlier).all()
               for earlier, later in zip(calls[:-1], calls[1:], strict=True))
    # with noise, the covariance is the precision of the shift
    noisy = target + np.random.default_rng(8).normal(0, 0.05, target.shape)
    out = least_squares_match(noisy, sampler(centres, grid), np.zeros((6, 2)))
    err = np.abs(out.shift - d)
    sigma = np.sqrt(np.einsum("nii->ni", out.covariance))
    assert (out.status == LsmStatus.CONVERGED).all() and (err < 4 * sigma).all()
    assert (sigma < 0.05).all()


def test_robust_weights_ignore_a_part_that_differs():
    centres, grid = patches(n=4, half=8)
    d = np.array([0.3, -0.4])
    at = centres[:, None, :] + grid[None] + d
    target = wavy(at[..., 0], at[..., 1])[0]
    target[:, :40] += 3.0  # a corner of every patch is something else (a cloud)
    plain = least_squares_match(target, sampler(centres, grid), np.zeros((4, 2)),
                                max_shift_px=5.0, max_iterations=30)
    robust = least_squares_match(target, sampler(centres, grid), np.zeros((4, 2)),
                                 robust_k=2.0, max_shift_px=5.0, max_iterations=30)
    assert (robust.status == LsmStatus.CONVERGED).all()
    assert np.abs(robust.shift - d).max() < 0.02 < np.abs(plain.shift - d).max()


def test_the_solver_says_why_a_patch_failed():
    centres, grid = patches(n=5)
    d = np.array([[0.2, 0.1], [0.2, 0.1], [1.2, 1.2], [0.2, 0.1], [0.2, 0.1]])
    at = centres[:, None, :] + grid[None] + d[:, None, :]
    target = wavy(at[..., 0], at[..., 1])[0]
    sample = sampler(centres, grid)

    def holes(index, shift):
        values, gr, gc = sample(index, shift)
        values[index == 0] = np.nan  # patch 0 has no data
        for v in (values, gr, gc):  # patch 1 is flat
            v[index == 1] = 0.0 if v is not values else 5.0
        return values, gr, gc

    out = least_squares_match(target, holes, np.zeros((5, 2)), max_shift_px=1.5,
                              shift_norm="max")
    assert list(out.status[:3]) == [LsmStatus.NO_DATA, LsmStatus.NO_TEXTURE,
                                    LsmStatus.CONVERGED]
    assert np.isnan(out.covariance[:2]).all() and (out.iterations[:2] == 1).all()
    # (1.2, 1.2) is inside a square of half-side 1.5, not inside a circle of radius 1.5
    out = least_squares_match(target, sample, np.zeros((5, 2)), max_shift_px=1.5)
    assert out.status[2] == LsmStatus.DIVERGED
    out = least_squares_match(target, sample, np.zeros((5, 2)), max_iterations=1,
                              tolerance_px=1e-9)
    assert (out.status == LsmStatus.MAX_ITERATIONS).all()


def test_the_solver_checks_its_inputs():
    centres, grid = patches(n=2)
    sample = sampler(centres, grid)
    target = np.zeros((2, grid.shape[0]))
    with pytest.raises(ShapeMismatchError, match="start"):
        least_squares_match(target, sample, np.zeros((3, 2)))
    with pytest.raises(ShapeMismatchError, match="weight"):
        least_squares_match(target, sample, np.zeros((2, 2)), weight=np.ones(3))
    for bad in ({"tolerance_px": 0.0}, {"max_condition": -1.0}, {"robust_k": math.nan},
                {"max_iterations": 0}, {"shift_norm": "l1"}):
        with pytest.raises(MatchError):
            least_squares_match(target, sample, np.zeros((2, 2)), **bad)


def test_one_least_squares_matching_for_the_matcher_and_the_seams():
    assert geoblock.match.refine.least_squares_match is least_squares_match
    assert geoblock.match.seams.least_squares_match is least_squares_match
