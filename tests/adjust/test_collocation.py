"""Least-squares collocation of residual vectors (Teo et al. 2010, eqs. 4-5) and the
CollocationCorrection layer around any sensor model."""

from __future__ import annotations

import json
import pickle

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import geoblock.adjust.collocation as collocation_module
from geoblock.adjust.collocation import (
    GAUSS_FACTOR,
    Collocation,
    CollocationCorrection,
    default_d_max,
    fit_collocation,
    gaussian_covariance,
)
from geoblock.dem import ConstantDem
from geoblock.errors import (
    AdjustmentError,
    ObservationError,
    ShapeMismatchError,
    TooFewPointsError,
)
from geoblock.models import get_registry
from geoblock.models.linescan import LinescanModel
from geoblock.ortho import OutputGrid, source_coordinates
from geoblock.plugins import from_dict
from geoblock.testing.contract import SensorModelContract
from geoblock.testing.synthetic import ConstantVelocityPushbroom

SIZE = 1000.0


def smooth_row(r, c):
    """A low-order residual field, pixels (half a period across the image)."""
    return 2.0 * np.sin(np.pi * r / SIZE) + 1.5 * np.cos(np.pi * c / SIZE + 0.3) + 0.5


def smooth_col(r, c):
    return 1.2 * np.cos(2 * np.pi * r / SIZE) * np.sin(np.pi * c / SIZE) - 0.4


def rms(*arrays):
    return float(np.sqrt(np.mean(np.concatenate([np.ravel(a) ** 2 for a in arrays]))))


def random_points(rng, n):
    return rng.uniform(0.0, SIZE - 1.0, n), rng.uniform(0.0, SIZE - 1.0, n)


# ----------------------------------------------------------------------------- eq. 5
def test_covariance_function_values():
    mu, d_max, r_n = 2.5, 300.0, 0.2
    assert gaussian_covariance(0.0, mu, d_max, r_n) == mu
    c_max = gaussian_covariance(d_max, mu, d_max, r_n)
    assert c_max == pytest.approx(0.01 * (1 - r_n) * mu, rel=1e-3)
    assert np.exp(-GAUSS_FACTOR**2) == pytest.approx(0.01, rel=1e-3)
    d = np.array([1e-9, 10.0, 100.0, 300.0, 1000.0])
    c = gaussian_covariance(d, mu, d_max, r_n)
    assert c[0] == pytest.approx((1 - r_n) * mu)  # the signal limit: the nugget is r_n mu
    assert np.all(np.diff(c) < 0)


def test_fitted_covariance_per_axis():
    rng = np.random.default_rng(1)
    r, c = random_points(rng, 30)
    colloc = fit_collocation(r, c, 3.0 * rng.normal(size=30), rng.normal(size=30), d_max=250.0)
    dr = colloc.d_row - colloc.d_row.mean()
    assert colloc.mu[0] == pytest.approx(np.mean(dr**2))
    cov = colloc.covariance([0.0, 250.0])
    assert cov.shape == (2, 2)
    assert np.allclose(cov[0], colloc.mu)
    assert np.allclose(cov[1], 0.01 * 0.8 * colloc.mu, rtol=1e-3)


def test_prediction_is_eq4_at_new_points():
    """s(P) = m + C_P^T Sigma^-1 (l - m), with Sigma built literally from eq. 5."""
    rng = np.random.default_rng(2)
    r, c = random_points(rng, 25)
    l_row, l_col = smooth_row(r, c), rng.normal(size=25)
    colloc = fit_collocation(r, c, l_row, l_col, filtering_ratio=0.3, d_max=400.0)
    pr, pc = random_points(rng, 7)
    got = colloc.predict(pr, pc)
    d = np.hypot(r[:, None] - r[None], c[:, None] - c[None])
    d_p = np.hypot(pr[:, None] - r[None], pc[:, None] - c[None])
    for k, l_obs in enumerate((l_row, l_col)):
        mu = np.var(l_obs)
        sigma = gaussian_covariance(d, mu, 400.0, 0.3)
        c_p = gaussian_covariance(d_p, mu, 400.0, 0.3)
        expected = l_obs.mean() + c_p @ np.linalg.solve(sigma, l_obs - l_obs.mean())
        np.testing.assert_allclose(got[k], expected, rtol=0, atol=1e-10)


def test_default_d_max_is_the_largest_distance():
    r, c = np.array([0.0, 30.0, 0.0]), np.array([0.0, 40.0, 10.0])
    assert default_d_max(r, c) == pytest.approx(50.0)
    assert fit_collocation(r, c, [1.0, 2.0, 0.0], [0.0, 1.0, 0.0]).d_max == pytest.approx(50.0)
    assert fit_collocation(r, c, [1.0, 2.0, 0.0], [0.0, 1.0, 0.0], d_max=7.0).d_max == 7.0


# ----------------------------------------------------------------------------- behaviour
def test_smooth_field_is_predicted_at_independent_points():
    rng = np.random.default_rng(3)
    r, c = random_points(rng, 60)
    colloc = fit_collocation(r, c, smooth_row(r, c) + rng.normal(0, 0.1, 60),
                             smooth_col(r, c) + rng.normal(0, 0.1, 60))
    qr, qc = random_points(rng, 2000)
    true_r, true_c = smooth_row(qr, qc), smooth_col(qr, qc)
    pred_r, pred_c = colloc.predict(qr, qc)
    before, after = rms(true_r, true_c), rms(true_r - pred_r, true_c - pred_c)
    assert before / after >= 3.0, (before, after)


def test_smaller_d_max_resolves_a_finer_field():
    """A full period across the image: the default (the points' extent) smooths it; a
    correlation distance of ~10 nearest-neighbour spacings follows it."""
    rng = np.random.default_rng(4)

    def field(r, c):
        return 2.0 * np.sin(2 * np.pi * r / SIZE) + 1.5 * np.cos(2 * np.pi * c / 800.0 + 0.3)

    r, c = random_points(rng, 60)
    l_obs = field(r, c) + rng.normal(0, 0.1, 60)
    qr, qc = random_points(rng, 2000)
    before = rms(field(qr, qc))
    d = np.hypot(r[:, None] - r[None], c[:, None] - c[None])
    np.fill_diagonal(d, np.inf)
    spacing = float(np.median(d.min(axis=1)))
    errors = {}
    for label, d_max in (("default", None), ("fine", 10 * spacing)):
        colloc = fit_collocation(r, c, l_obs, np.zeros(60), d_max=d_max)
        errors[label] = rms(field(qr, qc) - colloc.predict(qr, qc)[0])
    assert before / errors["fine"] >= 3.0
    assert errors["fine"] < errors["default"]


def test_white_noise_is_not_propagated():
    """Zero-mean white noise: the corrected error at independent points stays within ~10 %."""
    ratios = []
    for seed in range(5):
        rng = np.random.default_rng(100 + seed)
        r, c = random_points(rng, 60)
        colloc = fit_collocation(r, c, rng.normal(size=60), rng.normal(size=60))
        qr, qc = random_points(rng, 2000)
        noise_r, noise_c = rng.normal(size=2000), rng.normal(size=2000)
        pred_r, pred_c = colloc.predict(qr, qc)
        ratios.append(rms(noise_r - pred_r, noise_c - pred_c) / rms(noise_r, noise_c))
        assert rms(pred_r, pred_c) < 0.5 * rms(noise_r, noise_c)
    assert np.mean(ratios) <= 1.10, ratios
    assert max(ratios) <= 1.2, ratios


def test_prediction_smooths_at_control_points():
    """The filtering ratio makes it a smoothing prediction: residual noise is not reproduced."""
    rng = np.random.default_rng(5)
    r, c = random_points(rng, 40)
    noise = rng.normal(0, 0.3, 40)
    colloc = fit_collocation(r, c, smooth_row(r, c) + noise, np.zeros(40))
    pred = colloc.predict(r, c)[0]
    assert rms(pred - smooth_row(r, c)) < rms(noise)
    # continuous through the control points (no jump to the observed value at d = 0)
    near = colloc.predict(r + 1e-6, c)[0]
    np.testing.assert_allclose(pred, near, atol=1e-6)
    assert colloc.predict(r, c)[1] == pytest.approx(np.zeros(40))


def test_predict_shapes_broadcast_and_nan():
    rng = np.random.default_rng(6)
    r, c = random_points(rng, 10)
    colloc = fit_collocation(r, c, rng.normal(size=10), rng.normal(size=10))
    d_row, d_col = colloc.predict(np.zeros((3, 1)), np.arange(4.0))
    assert d_row.shape == d_col.shape == (3, 4)
    assert colloc.predict(5.0, 6.0)[0].shape == ()
    assert colloc.predict(np.empty(0), np.empty(0))[0].shape == (0,)
    d_row, d_col = colloc.predict([np.nan, 3.0, np.inf, 1e300], [1.0, 2.0, 0.0, 0.0])
    assert np.all(np.isnan(d_row[[0, 2]])) and np.all(np.isnan(d_col[[0, 2]]))
    assert np.isfinite(d_row[1]) and d_row[3] == pytest.approx(colloc.mean[0])  # far: the trend
    jac = colloc.gradient([np.nan, 3.0, -np.inf, 1e300], [1.0, 2.0, 0.0, 0.0])
    assert np.all(np.isnan(jac[[0, 2]])) and np.all(np.isfinite(jac[[1, 3]]))
    with pytest.raises(ShapeMismatchError):
        colloc.predict(np.zeros(3), np.zeros(4))
    assert colloc.gradient(np.zeros((2, 5)), np.ones(5)).shape == (2, 5, 2, 2)


def test_chunked_prediction_is_identical(monkeypatch):
    rng = np.random.default_rng(7)
    r, c = random_points(rng, 50)
    colloc = fit_collocation(r, c, smooth_row(r, c), smooth_col(r, c))
    qr, qc = random_points(rng, 1003)
    whole = colloc.predict(qr, qc)
    grad = colloc.gradient(qr, qc)
    monkeypatch.setattr(collocation_module, "_MAX_PAIRS", 50 * 7)  # 7 points per chunk
    chunked = colloc.predict(qr, qc)
    np.testing.assert_array_equal(whole[0], chunked[0])
    np.testing.assert_array_equal(whole[1], chunked[1])
    np.testing.assert_array_equal(grad, colloc.gradient(qr, qc))


def test_gradient_matches_finite_differences():
    rng = np.random.default_rng(8)
    r, c = random_points(rng, 30)
    colloc = fit_collocation(r, c, smooth_row(r, c), smooth_col(r, c), d_max=300.0)
    qr, qc = random_points(rng, 20)
    jac = colloc.gradient(qr, qc)
    h = 1e-3
    for j, (dr, dc) in enumerate(((h, 0.0), (0.0, h))):
        plus = np.stack(colloc.predict(qr + dr, qc + dc), -1)
        minus = np.stack(colloc.predict(qr - dr, qc - dc), -1)
        np.testing.assert_allclose(jac[..., j], (plus - minus) / (2 * h), rtol=0, atol=1e-8)


def test_constant_axis_gives_its_mean():
    r, c = np.array([0.0, 100.0, 0.0, 100.0]), np.array([0.0, 0.0, 100.0, 100.0])
    colloc = fit_collocation(r, c, [1.0, 2.0, 0.5, 0.0], [0.7, 0.7, 0.7, 0.7])
    assert colloc.mu[1] == 0.0 and np.all(colloc.weights[1] == 0.0)
    assert colloc.predict(50.0, 50.0)[1] == pytest.approx(0.7)


def test_collocation_dict_round_trip():
    rng = np.random.default_rng(9)
    r, c = random_points(rng, 12)
    colloc = fit_collocation(r, c, rng.normal(size=12), rng.normal(size=12),
                             filtering_ratio=0.35)
    data = json.loads(json.dumps(colloc.to_dict(), allow_nan=False))
    again = Collocation.from_dict(data)
    assert again == colloc and hash(again) == hash(colloc)
    assert again.filtering_ratio == 0.35 and again.d_max == colloc.d_max
    np.testing.assert_array_equal(again.weights, colloc.weights)
    assert again != fit_collocation(r, c, colloc.d_row, colloc.d_col)  # another r_n
    assert pickle.loads(pickle.dumps(colloc)) == colloc


def test_collocation_arrays_are_read_only():
    colloc = fit_collocation([0.0, 10.0], [0.0, 0.0], [1.0, 2.0], [0.0, 0.0])
    with pytest.raises(ValueError, match="read-only"):
        colloc.weights[0, 0] = 1.0


# ----------------------------------------------------------------------------- validation
GOOD = {
    "row": [0.0, 10.0, 20.0],
    "col": [0.0, 5.0, 30.0],
    "d_row": [0.1, -0.2, 0.3],
    "d_col": [0.0, 0.4, -0.1],
}


@pytest.mark.parametrize(
    ("changes", "options", "error", "match"),
    [
        ({"row": [0.0, np.nan, 20.0]}, {}, ObservationError, r"row is not finite.*\[1\]"),
        ({"d_col": [0.0, np.inf, 1.0]}, {}, ObservationError, "d_col is not finite"),
        ({"col": [0.0, 5.0]}, {}, ObservationError, r"col \(2,\)"),
        ({"d_row": [[0.1, -0.2, 0.3]]}, {}, ObservationError, r"d_row \(1, 3\)"),
        ({"row": [0.0, 0.0, 20.0], "col": [5.0, 5.0, 30.0]}, {}, ObservationError,
         r"coincident.*\(0, 1\)"),
        ({"row": ["a", "b", "c"]}, {}, ObservationError, "row is not numeric"),
        ({k: v[:1] for k, v in GOOD.items()}, {}, TooFewPointsError, "at least 2"),
        ({}, {"filtering_ratio": 0.0}, ObservationError, "filtering_ratio"),
        ({}, {"filtering_ratio": 1.0}, ObservationError, "filtering_ratio"),
        ({}, {"filtering_ratio": np.nan}, ObservationError, "filtering_ratio"),
        ({}, {"d_max": 0.0}, ObservationError, "d_max"),
        ({}, {"d_max": -5.0}, ObservationError, "d_max"),
        ({}, {"d_max": np.inf}, ObservationError, "d_max"),
    ],
)
def test_bad_inputs_name_the_field(changes, options, error, match):
    args = {**GOOD, **changes}
    with pytest.raises(error, match=match) as info:
        fit_collocation(args["row"], args["col"], args["d_row"], args["d_col"], **options)
    assert isinstance(info.value, AdjustmentError) and isinstance(info.value, ValueError)


def test_bad_dictionary():
    from geoblock.errors import SerializationError

    with pytest.raises(SerializationError, match="d_max"):
        Collocation.from_dict({k: v for k, v in GOOD.items()} | {"filtering_ratio": 0.2})
    data = CollocationCorrection.example().to_dict()
    del data["collocation"]
    with pytest.raises(SerializationError, match="collocation"):
        CollocationCorrection.from_dict(data)


# ----------------------------------------------------------------------------- the model layer
_EXAMPLE = CollocationCorrection.example()


@pytest.fixture(scope="module")
def corrected():
    return _EXAMPLE


def test_project_is_base_plus_prediction(corrected):
    base = corrected.model
    rng = np.random.default_rng(10)
    r, c = rng.uniform(0, 999, 50), rng.uniform(0, 1199, 50)
    h = rng.uniform(0, 2000, 50)
    g = base.backproject(r, c, h)
    row, col = corrected.project(g.lon, g.lat, g.h)
    d_row, d_col = corrected.collocation.predict(r, c)
    np.testing.assert_allclose(row, r + d_row, atol=1e-8)
    np.testing.assert_allclose(col, c + d_col, atol=1e-8)
    assert np.max(np.hypot(d_row, d_col)) > 0.5  # the example's correction is not trivial


def test_project_backproject_round_trip(corrected):
    rng = np.random.default_rng(11)
    rows, cols = corrected.shape
    r, c = rng.uniform(-0.5, rows - 0.5, (20, 10)), rng.uniform(-0.5, cols - 0.5, (20, 10))
    h = rng.uniform(*corrected.height_range, (20, 10))
    g = corrected.backproject(r, c, h)
    row, col = corrected.project(g.lon, g.lat, g.h)
    assert row.shape == (20, 10)
    assert np.max(np.abs(row - r)) < 1e-6 and np.max(np.abs(col - c)) < 1e-6


@settings(max_examples=30, deadline=None)
@given(
    row=st.floats(-0.5, 999.5),
    col=st.floats(-0.5, 1199.5),
    h=st.floats(-500.0, 3000.0),
)
def test_round_trip_property(row, col, h):
    model = _EXAMPLE
    (lon, lat, hh), status = model.backproject_with_status(row, col, h)
    assert status == 0
    (r, c), status = model.project_with_status(lon, lat, hh)
    assert status == 0
    assert abs(r - row) < 1e-6 and abs(c - col) < 1e-6


def test_serialisation_pickle_registry(corrected):
    data = corrected.to_dict()
    assert data["model"] == "collocation" and data["schema_version"] == 1
    assert data["base"] == corrected.model.to_dict()
    text = json.dumps(data, allow_nan=False)
    again = CollocationCorrection.from_dict(json.loads(text))
    assert again == corrected and again.to_dict() == data
    assert pickle.loads(pickle.dumps(corrected)) == corrected
    assert from_dict(json.loads(text)) == corrected
    assert get_registry().get("collocation") is CollocationCorrection
    assert type(from_dict(data).model) is LinescanModel  # the base model is rebuilt too


def test_no_parameters(corrected):
    assert len(corrected.parameters) == 0
    assert corrected.with_parameters([]) == corrected
    with pytest.raises(ValueError, match="expected 0 values"):
        corrected.with_parameters([1.0])
    assert corrected.partials_parameters(np.zeros(4), 43.7, 0.0).shape == (4, 2, 0)


def test_partials_ground_chain_rule(corrected):
    base = corrected.model
    g = base.backproject([10.0, 500.0, 900.0], [20.0, 600.0, 1100.0], 300.0)
    (r, c), _ = base.project_with_status(g.lon, g.lat, g.h)
    jac = corrected.collocation.gradient(r, c) + np.eye(2)
    np.testing.assert_allclose(corrected.partials_ground(g.lon, g.lat, g.h),
                               jac @ base.partials_ground(g.lon, g.lat, g.h), rtol=1e-12)


def test_ortho_source_coordinates(corrected):
    """It orthorectifies like any model: the lattice reproduces the exact projection."""
    dem = ConstantDem(250.0)
    grid = OutputGrid.for_model(corrected, dem)[:64, :64]
    row, col, valid = source_coordinates(corrected, dem, grid, tolerance_px=0.01)
    lon, lat = grid.lonlat(*np.mgrid[0:64, 0:64])
    r, c = corrected.project(lon, lat, np.full(lon.shape, 250.0))
    ok = valid & np.isfinite(r)
    assert ok.mean() > 0.5
    assert np.max(np.abs(row[ok] - r[ok])) < 0.01 and np.max(np.abs(col[ok] - c[ok])) < 0.01


def _pushbroom_case():
    base = ConstantVelocityPushbroom.example(roll=0.01)
    rows, cols = base.shape
    rng = np.random.default_rng(12)
    r, c = rng.uniform(0, rows - 1, 15), rng.uniform(0, cols - 1, 15)
    colloc = fit_collocation(r, c, np.sin(r / rows * 3.0), 0.5 * np.cos(c / cols * 3.0))
    return CollocationCorrection(base, colloc)


class TestCollocationContract(SensorModelContract):
    """The conformance kit around a ground->image model and an image->ground one."""

    @pytest.fixture(params=["affine", "pushbroom"])
    def model(self, request):
        if request.param == "affine":
            return _EXAMPLE
        return _pushbroom_case()
