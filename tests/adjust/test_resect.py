"""ImageCorrection (RPCV-0 / RPCV-1 / order 2) fitted with resect on synthetic GCPs."""

from __future__ import annotations

import numpy as np
import pytest

from geoblock import ImageCorrection
from geoblock.adjust import AccuracyStats, ControlPoints, resect
from geoblock.errors import ObservationError, SingularSystemError, TooFewPointsError

TRUE = {
    0: [3.0, -2.0],
    1: [3.0, 1.5, -0.7, -2.0, 0.4, 2.2],
    2: [3.0, 1.5, -0.7, 0.3, -0.2, 0.5, -2.0, 0.4, 2.2, 0.1, 0.2, -0.4],
}


def simulate(base, order, n, rng, noise_px=0.0, rows=None, cols=None):
    """GCPs: true ground of random pixels through the *corrected* model, noisy measurements."""
    truth = ImageCorrection(base, order, TRUE[order])
    r = rng.uniform(0, base.shape[0] - 1, n) if rows is None else rows
    c = rng.uniform(0, base.shape[1] - 1, n) if cols is None else cols
    h = rng.uniform(0, 2000, n)
    g = truth.backproject(r, c, h)
    ids = [f"p{i}" for i in range(n)]
    return ControlPoints(
        ids, g.lon, g.lat, g.h,
        r + rng.normal(0, noise_px, n) if noise_px else r,
        c + rng.normal(0, noise_px, n) if noise_px else c,
        sigma_row=max(noise_px, 0.5), sigma_col=max(noise_px, 0.5),
    )


@pytest.mark.parametrize("order", [0, 1, 2])
def test_recovers_known_correction_exactly_without_noise(synthetic_model, order):
    rng = np.random.default_rng(order)
    gcps = simulate(synthetic_model, order, 10, rng)
    result = resect(ImageCorrection(synthetic_model, order), gcps)
    assert result.converged and result.iterations <= 3
    assert np.allclose(result.values, TRUE[order], rtol=0, atol=1e-7)
    assert np.max(np.abs(result.gcp.row)) < 1e-7 and np.max(np.abs(result.gcp.col)) < 1e-7
    assert result.gcp.stats.rmse_2d < 1e-6  # metres
    assert result.model == ImageCorrection(synthetic_model, order, result.values)


@pytest.mark.parametrize("order", [0, 1, 2])
def test_noisy_gcps_give_estimates_within_their_posterior_sigmas(affine_camera, order):
    """Over 200 noisy trials the normalised errors (estimate - truth) / sigma are N(0, 1)."""
    rng = np.random.default_rng(10 + order)
    z, s0 = [], []
    for _ in range(200):
        gcps = simulate(affine_camera, order, 15, rng, noise_px=0.5)
        result = resect(ImageCorrection(affine_camera, order), gcps)
        z.append((result.values - TRUE[order]) / result.sigmas)
        s0.append(result.sigma0)
    z = np.array(z)
    assert 0.85 < np.std(z) < 1.2, np.std(z)
    assert abs(np.mean(z)) < 0.15
    assert 0.9 < np.mean(s0) < 1.1  # sigma0 ~ 1 when the a-priori sigma is right
    assert np.mean(np.abs(z) < 1.0) > 0.6  # about 68 % within one sigma


@pytest.mark.parametrize(("order", "minimum"), [(0, 1), (1, 3), (2, 6)])
def test_too_few_points_state_the_minimum(affine_camera, order, minimum):
    rng = np.random.default_rng(0)
    gcps = simulate(affine_camera, order, minimum - 1 if minimum > 1 else 1, rng)
    if minimum == 1:
        gcps = gcps.subset(np.zeros(1, bool))  # no GCP at all
    with pytest.raises(TooFewPointsError, match=f"need at least {minimum} GCPs"):
        resect(ImageCorrection(affine_camera, order), gcps)
    # exactly the minimum is enough (order 2 with well-spread points)
    gcps = simulate(affine_camera, order, minimum, np.random.default_rng(5))
    result = resect(ImageCorrection(affine_camera, order), gcps)
    assert result.dof == 2 * minimum - len(TRUE[order])


def test_collinear_gcps_for_order_1_name_the_undetermined_parameters(affine_camera):
    rng = np.random.default_rng(0)
    t = np.linspace(0, 1, 8)
    gcps = simulate(affine_camera, 1, 8, rng, rows=100 + 800 * t, cols=50 + 1000 * t)
    with pytest.raises(
        SingularSystemError, match=r"cannot determine parameters .*a1, a2, .*b1, b2"
    ) as err:
        resect(ImageCorrection(affine_camera, 1), gcps)
    # the line passes near the image centre, so the shifts a0, b0 are (almost) determined
    assert {"a1", "a2", "b1", "b2"} <= set(err.value.undetermined)
    assert "not collinear" in str(err.value)
    # a-priori sigmas on the affine terms resolve it
    constrained = ImageCorrection(affine_camera, 1, sigmas=[np.inf, 1.0, 1.0, np.inf, 1.0, 1.0])
    assert resect(constrained, gcps).converged


def test_prior_sigmas_are_pseudo_observations(affine_camera):
    # with tight priors at zero and one GCP, the order-1 terms stay near zero
    rng = np.random.default_rng(3)
    gcps = simulate(affine_camera, 0, 1, rng)
    model = ImageCorrection(affine_camera, 1, sigmas=[np.inf, 1e-6, 1e-6, np.inf, 1e-6, 1e-6])
    result = resect(model, gcps)
    assert np.allclose(result.values, [3, 0, 0, -2, 0, 0], atol=1e-4)


def test_ground_sigmas_inflate_the_weights(affine_camera):
    rng = np.random.default_rng(4)
    gcps = simulate(affine_camera, 0, 10, rng)
    fixed = resect(ImageCorrection(affine_camera, 0), gcps)
    loose = ControlPoints(
        gcps.id, gcps.lon, gcps.lat, gcps.h, gcps.row, gcps.col, 0.5, 0.5, 3.0, 3.0, 3.0,
    )
    free = resect(ImageCorrection(affine_camera, 0), loose)
    # 3 m ground sigma at 2 m GSD adds ~1.5 px in quadrature: sigmas grow about 3.2x
    ratio = np.sqrt(np.diag(free.cofactor) / np.diag(fixed.cofactor))
    assert np.all((ratio > 2.5) & (ratio < 4.0)), ratio


def test_icp_statistics(pushbroom):
    rng = np.random.default_rng(7)
    gcps = simulate(pushbroom, 1, 9, rng, noise_px=0.3)
    icps = simulate(pushbroom, 1, 30, rng)
    result = resect(ImageCorrection(pushbroom, 1), gcps, icps)
    s = result.icp.stats
    assert s.n == 30 and 0 < s.rmse_2d < 2.5  # metres, 2.5 m GSD with 0.3 px noise
    assert np.isclose(s.rmse_2d, np.hypot(s.rmse_e, s.rmse_n))
    report = result.report()
    assert "ICP" in report and "sigma0" in report and "a1" in report


def test_accuracy_stats_definition():
    s = AccuracyStats.from_errors([1.0, -3.0, np.nan], [0.0, 2.0, 1.0])
    assert s.n == 2 and s.max_e == -3.0 and s.max_n == 2.0
    assert np.isclose(s.rmse_e, np.sqrt(5.0)) and np.isclose(s.mean_e, -1.0)
    assert np.isclose(s.max_2d, np.hypot(3.0, 2.0))


def test_invalid_control_points_name_the_point():
    with pytest.raises(ObservationError, match=r"lon must be finite \(points b\)"):
        ControlPoints(["a", "b"], [1.0, np.nan], [0, 0], [0, 0], [0, 0], [0, 0])
    with pytest.raises(ObservationError, match="sigma_row must be finite and > 0"):
        ControlPoints(["a"], [1.0], [0], [0], [0], [0], sigma_row=0.0)
    with pytest.raises(ObservationError, match="duplicate point ids"):
        ControlPoints(["a", "a"], [1.0, 1.0], [0, 0], [0, 0], [0, 0], [0, 0])
    with pytest.raises(ObservationError, match=r"row has shape \(3,\)"):
        ControlPoints(["a", "b"], [1.0, 1.0], [0, 0], [0, 0], [0, 0, 0], [0, 0])


def test_gcps_all_measured_at_one_pixel_are_refused(affine_camera):
    """Issue 12 item 4: six GCPs measured at one pixel used to 'converge' (sigma0 1e-14) to a
    model mapping the whole image onto that pixel."""
    rng = np.random.default_rng(5)
    good = simulate(affine_camera, 1, 6, rng)
    one_pixel = ControlPoints(good.id, good.lon, good.lat, good.h, np.full(6, 400.0),
                              np.full(6, 500.0))
    with pytest.raises(SingularSystemError, match="p0.*within 1 px of one image point.*a1"):
        resect(ImageCorrection(affine_camera, 1), one_pixel)
    # a shift (RPCV-0) is all such points can give, and is allowed
    assert resect(ImageCorrection(affine_camera, 0), one_pixel).converged


def test_gcps_measured_on_one_line_are_refused_for_order_2(affine_camera):
    rng = np.random.default_rng(6)
    t = np.linspace(0.0, 1.0, 8)
    good = simulate(affine_camera, 2, 8, rng)
    on_line = ControlPoints(good.id, good.lon, good.lat, good.h, 100 + 700 * t, 100 + 900 * t)
    with pytest.raises(SingularSystemError, match="lie on one line"):
        resect(ImageCorrection(affine_camera, 2), on_line)


def test_a_solution_that_collapses_the_image_is_refused(affine_camera):
    """Measurements of a different geometry (mirrored image): the affinity 'fits' by folding
    the image; the degenerate solution is refused instead of written."""
    from geoblock.errors import AdjustmentError

    rng = np.random.default_rng(7)
    good = simulate(affine_camera, 1, 9, rng)
    squeezed = ControlPoints(good.id, good.lon, good.lat, good.h, 400 + 0.01 * (good.row - 400),
                             500 + 0.01 * (good.col - 500))
    with pytest.raises(AdjustmentError, match="degenerate.*scales image areas"):
        resect(ImageCorrection(affine_camera, 1), squeezed)
