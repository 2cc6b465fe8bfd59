"""Sub-pixel refinement (correlation, then least-squares matching) on images whose shift is
known exactly: a smooth random texture resampled at a known offset."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.ndimage import gaussian_filter

from geoblock.errors import MatchError
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
