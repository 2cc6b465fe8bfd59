"""The block adjustment engine on synthetic blocks whose truth is known (geoblock.testing.blocks).

The on-board cameras differ from the true ones by an affine image-space error that an order-1
ImageCorrection represents exactly, so the estimator's accuracy can be compared with what its
own covariance predicts.
"""

from __future__ import annotations

import numpy as np
import pytest

from geoblock import coords
from geoblock.adjust import (
    Block,
    ControlPoints,
    GroundPoints,
    ImagePoints,
    adjust,
    resect,
)
from geoblock.errors import (
    AdjustmentError,
    ObservationError,
    SingularSystemError,
    TooFewPointsError,
)
from geoblock.models.corrections import ImageCorrection
from geoblock.testing.blocks import affine_block


def icp_rmse(result) -> float:
    icp = np.char.lower(result.check.kind.astype(str)) == "icp"
    return float(np.sqrt(np.mean(result.check.e[icp] ** 2 + result.check.n[icp] ** 2)))


def icp_predicted(result) -> float:
    icp = np.char.lower(result.check.kind.astype(str)) == "icp"
    return float(np.sqrt(np.mean(np.sum(result.predicted_sigma[icp] ** 2, axis=1))))


def true_errors_px(sb, result) -> float:
    """Largest difference, pixels, between adjusted and true projections of the ICTPs."""
    worst = 0.0
    for image, true in sb.true_models.items():
        lon, lat, h = sb.truth_lon, sb.truth_lat, sb.truth_h
        r0, c0 = true.project(lon, lat, h)
        r1, c1 = result.models[image].project(lon, lat, h)
        inside = (r0 > 0) & (r0 < true.shape[0]) & (c0 > 0) & (c0 < true.shape[1])
        worst = max(worst, float(np.max(np.hypot(r1 - r0, c1 - c0)[inside])))
    return worst


# ----------------------------------------------------------------------------- correctness
def test_single_image_equals_resect():
    # (resect eliminates the GCPs' ground errors by linearisation at the surveyed points;
    # with near error-free GCPs both solve the same problem)
    sb = affine_block((1, 1), gcps=8, icps=4, tps=0, ictps=0, seed=3, sigma_ground_m=1e-3)
    block = sb.block
    result = adjust(block, mode="single")
    gcps = block.measurements.control_points(block.ground, "img00")
    reference = resect(block.models["img00"], gcps)
    np.testing.assert_allclose(result.parameters["img00"].values, reference.values,
                               rtol=0, atol=1e-6)
    np.testing.assert_allclose(result.parameters["img00"].sigmas, reference.sigmas, rtol=1e-4)
    assert result.sigma0 == pytest.approx(reference.sigma0, rel=1e-6)


def test_noise_free_block_reaches_the_truth():
    sb = affine_block(sigma_px=1e-6, sigma_ground_m=1e-3, seed=4)
    result = adjust(sb.block)
    assert result.converged
    assert true_errors_px(sb, result) < 2e-3


def test_block_beats_single_on_ictps_and_reaches_its_predicted_accuracy():
    sb = affine_block(gcps=3, seed=5)
    single = adjust(sb.block, mode="single")
    block = adjust(sb.block)
    ictp_single = np.sqrt(np.mean(single.ictp.distance_2d ** 2))
    ictp_block = np.sqrt(np.mean(block.ictp.distance_2d ** 2))
    assert ictp_block * 1.5 < ictp_single
    assert 0.8 < block.sigma0 < 1.2


def test_icp_rmse_matches_the_posterior_covariance_over_20_seeds():
    actual, predicted = [], []
    for seed in range(20):
        result = adjust(affine_block(seed=100 + seed, tps=150).block)
        actual.append(icp_rmse(result) ** 2)
        predicted.append(icp_predicted(result) ** 2)
    ratio = np.sqrt(np.mean(actual) / np.mean(predicted))
    assert 0.9 < ratio < 1.1, ratio


def test_fixed_tp_priors_pull_the_block_to_the_onboard_positions_floating_do_not():
    sb = affine_block(seed=1, error_px=30.0)
    floating = adjust(sb.block)
    fixed = adjust(sb.block, tp_prior="fixed")
    assert 0.8 < floating.sigma0 < 1.2
    assert fixed.sigma0 > 1.5 * floating.sigma0
    assert icp_rmse(fixed) > 1.5 * icp_rmse(floating)


# ----------------------------------------------------------------------------- DEM control
def weak_block(seed=7):
    """Nearly parallel rays (1 degree off nadir at most): TP heights are weakly determined."""
    return affine_block(offnadir_deg=1.0, gcps=4, seed=seed, dem_sigma_m=1.0)


def tp_height_errors(sb, result) -> np.ndarray:
    tp = result.points.kind == "tp"
    k = np.searchsorted(sb.point_id, result.points.id[tp], sorter=np.argsort(sb.point_id))
    k = np.argsort(sb.point_id)[k]
    return result.points.h[tp] - sb.truth_h[k]


@pytest.mark.parametrize("control", ["observation", "iterate"])
def test_without_dem_control_tp_heights_drift(control):
    sb = weak_block()
    free = adjust(sb.block, dem_control="none")
    held = adjust(sb.block, dem_control=control)
    rms_free = np.sqrt(np.mean(tp_height_errors(sb, free) ** 2))
    rms_held = np.sqrt(np.mean(tp_height_errors(sb, held) ** 2))
    assert rms_free > 20.0  # tens of metres with nearly parallel rays
    assert rms_held < 3.0  # the DEM's accuracy (1 m stated, exact terrain here)
    # and the posterior sigmas say so
    tp = held.points.kind == "tp"
    assert np.median(held.points.sigma_enu[tp, 2]) < np.median(free.points.sigma_enu[
        free.points.kind == "tp", 2]) / 5


def test_dem_control_modes_agree_on_the_parameters():
    sb = weak_block(seed=8)
    a = adjust(sb.block, dem_control="observation")
    b = adjust(sb.block, dem_control="iterate")
    assert a.converged and b.converged and b.iterations < 15
    assert true_errors_px(sb, a) < 1.0 and true_errors_px(sb, b) < 1.0
    assert icp_rmse(a) == pytest.approx(icp_rmse(b), rel=0.1)


# ----------------------------------------------------------------------------- robustness
@pytest.mark.parametrize("robust", ["cauchy", "snooping"])
def test_blunders_are_flagged_and_do_not_spoil_the_block(robust):
    # 60 % overlap: most TPs are seen by three images or more, so a blunder is attributable
    clean = affine_block((3, 3), overlap=0.6, tps=300, seed=11, shape=(600, 600))
    dirty = affine_block((3, 3), overlap=0.6, tps=300, seed=11, shape=(600, 600),
                         blunder_fraction=0.05)
    reference = adjust(clean.block)
    result = adjust(dirty.block, robust=robust)
    flagged = result.measurements.flagged
    tp = result.measurements.kind == "tp"
    good = tp & ~dirty.blunder
    assert flagged[dirty.blunder].mean() >= 0.95
    assert flagged[good].mean() <= 0.01
    assert icp_rmse(result) == pytest.approx(icp_rmse(reference), rel=0.1)
    assert 0.8 < result.sigma0 < 1.2


def test_two_ray_blunders_flag_both_rays_as_ambiguous():
    sb = affine_block(tps=300, seed=12, blunder_fraction=0.05)
    result = adjust(sb.block, robust="cauchy")
    m = result.measurements
    assert m.flagged[sb.blunder].mean() >= 0.95
    # partners of two-ray blunders are flagged too, but marked ambiguous
    good = (m.kind == "tp") & ~sb.blunder
    assert (m.flagged[good] & ~m.ambiguous[good]).mean() <= 0.01
    assert m.ambiguous[m.flagged].any()


def test_least_squares_without_robust_estimation_is_spoiled_by_blunders():
    sb = affine_block((3, 3), overlap=0.6, tps=300, seed=11, shape=(600, 600),
                      blunder_fraction=0.05)
    plain = adjust(sb.block)
    robust = adjust(sb.block, robust="cauchy")
    assert plain.sigma0 > 5 * robust.sigma0


# ----------------------------------------------------------------------------- collocation
def test_collocation_wraps_every_model_and_keeps_the_accuracy():
    sb = affine_block(seed=13)
    plain = adjust(sb.block)
    col = adjust(sb.block, collocation=True)
    assert all(m.name == "collocation" for m in col.models.values())
    assert icp_rmse(col) < 1.1 * icp_rmse(plain)


# ----------------------------------------------------------------------------- bad input
def small():
    return affine_block((1, 2), gcps=6, icps=2, tps=30, ictps=0, seed=21)


def test_tp_in_one_image_is_refused_with_its_name():
    sb = small()
    m = sb.block.measurements
    first_tp = np.flatnonzero(m.kind == "tp")[0]
    keep = np.ones(len(m), bool)
    keep[(m.id == m.id[first_tp]) & (m.image != m.image[first_tp])] = False
    block = Block(sb.block.models, m.subset(keep), sb.block.ground, sb.block.dem)
    with pytest.raises(ObservationError, match=f"{m.id[first_tp]}.*one image"):
        adjust(block)


def test_measurement_of_an_unknown_image_is_refused():
    sb = small()
    m = sb.block.measurements
    image = m.image.tolist()
    image[0] = "nowhere"
    bad = ImagePoints(m.id, image, m.row, m.col, m.sigma_row, m.sigma_col, m.kind)
    with pytest.raises(ObservationError, match=f"{m.id[0]}.*'nowhere'"):
        Block(sb.block.models, bad, sb.block.ground, sb.block.dem)


def test_image_without_points_is_refused():
    sb = small()
    models = dict(sb.block.models)
    models["lonely"] = next(iter(models.values()))
    with pytest.raises(TooFewPointsError, match="lonely"):
        adjust(Block(models, sb.block.measurements, sb.block.ground, sb.block.dem))


def test_block_without_control_or_tie_points_is_refused():
    sb = affine_block((1, 2), gcps=0, icps=3, tps=0, ictps=0, seed=24)
    with pytest.raises(TooFewPointsError, match="no GCP or TP measurement"):
        adjust(sb.block)


def test_too_few_gcps_for_single_mode_names_the_image_and_parameters():
    sb = affine_block((1, 1), gcps=2, icps=0, tps=0, ictps=0, seed=22)
    with pytest.raises(TooFewPointsError, match="img00.*a0"):
        adjust(sb.block, mode="single")


def test_collinear_gcps_give_a_singular_system_naming_the_parameters():
    sb = affine_block((1, 1), gcps=0, icps=0, tps=0, ictps=0, seed=23)
    model = sb.true_models["img00"]
    rows = np.array([100.0, 300.0, 500.0, 700.0])
    cols = np.array([100.0, 300.0, 500.0, 700.0])  # on one line
    g = model.backproject(rows, cols, 300.0)
    ground = GroundPoints([f"g{i}" for i in range(4)], "gcp", g.lon, g.lat, g.h, 0.5, 0.5, 0.5)
    meas = ImagePoints([f"g{i}" for i in range(4)], "img00", rows, cols)
    block = Block({"img00": ImageCorrection(model, order=1)}, meas, ground)
    with pytest.raises(SingularSystemError, match="img00:a"):
        adjust(block, mode="single")


def test_a_gcp_far_from_its_measurement_is_named():
    sb = small()
    g = sb.block.ground
    lat = g.lat.copy()
    lat[0] = 89.9  # thousands of km away: an affine camera still projects it, far outside
    ground = GroundPoints(g.id, g.kind, g.lon, lat, g.h, g.sigma_e, g.sigma_n, g.sigma_h)
    block = Block(sb.block.models, sb.block.measurements, ground, sb.block.dem)
    # robust weights cannot absorb a point with that leverage: it is refused by name
    with pytest.raises(ObservationError, match=f"more than an image size.*{g.id[0]}"):
        adjust(block, robust="cauchy")


@pytest.mark.parametrize("kwargs, match", [
    ({"mode": "both"}, "mode"), ({"dem_control": "maybe"}, "dem_control"),
    ({"robust": "l1"}, "robust"), ({"tp_prior": "loose"}, "tp_prior"),
    ({"alpha": 1.5}, "alpha"), ({"tp_sigma_factor": -1.0}, "tp_sigma_factor"),
])
def test_bad_options_are_named(kwargs, match):
    with pytest.raises(AdjustmentError, match=match):
        adjust(small().block, **kwargs)


def test_control_points_view_matches_the_tables():
    sb = small()
    cp = sb.block.measurements.control_points(sb.block.ground, "img00")
    assert isinstance(cp, ControlPoints) and len(cp) > 0
    sel = (sb.block.measurements.image == "img00") & (sb.block.measurements.kind == "gcp")
    assert set(cp.id) == set(sb.block.measurements.id[sel])


def test_observation_tables_refuse_bad_values():
    with pytest.raises(ObservationError, match="sigma_row.*p2"):
        ImagePoints(["p1", "p2"], "a", [1.0, 2.0], [1.0, 2.0], [0.5, -1.0], 0.5)
    with pytest.raises(ObservationError, match="measured twice"):
        ImagePoints(["p1", "p1"], "a", [1.0, 2.0], [1.0, 2.0])
    with pytest.raises(ObservationError, match="kind.*tie points"):
        GroundPoints(["p1"], ["tp"], [7.0], [44.0], [0.0])
    with pytest.raises(ObservationError, match="lat.*p1"):
        GroundPoints(["p1"], ["gcp"], [7.0], [144.0], [0.0])


def test_posterior_point_covariances_are_in_local_enu_at_the_point():
    sb = small()
    result = adjust(sb.block)
    p = result.points
    gcp = p.kind == "gcp"
    # GCPs: ground sigma 0.5 m, pulled tighter by the rays horizontally, never looser
    assert np.all(p.sigma_enu[gcp] <= 0.5 + 1e-9)
    assert np.all(np.isfinite(p.covariance))
    e, n, u = coords.enu_offsets(p.lon, p.lat, p.h, p.lon, p.lat, p.h)
    assert np.allclose(e, 0) and np.allclose(u, 0)
