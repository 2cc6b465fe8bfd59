"""The linescan model's "jitter" parameter set: attitude (and position) correction splines in
time (geoblock.models.linescan.jitter)."""

from __future__ import annotations

import json
import pickle

import numpy as np
import pytest

from geoblock.adjust.weights import parameter_prior, prior_weight
from geoblock.errors import ModelFormatError, ParameterSetError
from geoblock.models import ParameterSet
from geoblock.models.linescan import LinescanModel, LineTimes
from geoblock.models.linescan.jitter import (
    DEFAULT_JITTER_SIGMA_RAD,
    JitterSpline,
    attitude_correction,
    default_knot_lines,
    default_smoothness,
    position_correction,
)
from geoblock.testing.checks import check_sensor_model, numeric_partials_parameters

OPTIONS = {"dg": {"accuracy_m": 10.0}, "physical": {"accuracy_m": 10.0},
           "jitter": {"accuracy_m": 10.0}}


def reverse(model: LinescanModel) -> LinescanModel:
    """The same scene scanned the other way (row 0 exposed last)."""
    lt = model.line_times
    return model.replace(line_times=LineTimes(lt.reference_row, lt.reference_time_s,
                                              -lt.line_period_s))


def with_wander(model: LinescanModel, seed: int = 1, rad: float = 3e-6, m: float = 2.0
                ) -> LinescanModel:
    """``model`` with random nonzero spline coefficients."""
    rng = np.random.default_rng(seed)
    assert model.jitter is not None
    return model.with_parameters({n: rng.normal() * (m if n.startswith("dp_") else rad)
                                  for n in model.jitter.names})


def grid_points(model: LinescanModel, h: float = 150.0):
    rows, cols = model.shape
    r, c = np.meshgrid(np.linspace(0, rows - 1, 9), np.linspace(0, cols - 1, 5))
    g = model.backproject(r.ravel(), c.ravel(), h)
    return g.lon, g.lat, np.full(g.lon.shape, h)


def fd_steps(params: ParameterSet) -> np.ndarray:
    """Central-difference steps large enough to stand above the time search's 1e-9 lines."""
    by_unit = {"m": 1e-2, "m/s": 1e-2, "rad": 1e-7, "rad/s": 1e-6, "1": 1e-7}
    return np.array([by_unit[u] for u in params.units])


# ----------------------------------------------------------------------------- the spline
def test_basis_is_a_partition_of_unity_and_clamped():
    s = JitterSpline(-1.0, 0.25, 8)
    t = np.linspace(-3.0, 3.0, 1001)
    first, w = s.basis(t)
    assert np.allclose(w.sum(axis=1), 1.0)
    assert first.min() == 0 and first.max() == s.n_coefficients - 4
    coef = np.random.default_rng(0).normal(size=(2, s.n_coefficients))
    v = s.evaluate(coef, t)
    # held at the end values outside the grid, continuous at the grid's ends
    assert np.all(v[t <= -1.0] == v[t <= -1.0][0]) and np.all(v[t >= 1.0] == v[-1])
    assert np.allclose(s.evaluate(coef, [-1.0 - 1e-12, -1.0 + 1e-12]), s.evaluate(coef, [-1.0]),
                       atol=1e-9)
    # C2 inside: the derivative is the numerical one
    tt = np.linspace(-0.9, 0.9, 37)
    dv = s.evaluate(coef, tt, derivative=True)
    num = (s.evaluate(coef, tt + 1e-6) - s.evaluate(coef, tt - 1e-6)) / 2e-6
    assert np.allclose(dv, num, rtol=1e-6, atol=1e-6)
    assert np.all(s.evaluate(coef, [-2.0, 2.0], derivative=True) == 0.0)
    # a linear function of the knots' coefficients (c_k = k) is a straight line in time
    lin = s.evaluate(np.arange(s.n_coefficients)[None, :], tt)[:, 0]
    assert np.allclose(np.diff(lin, 2), 0.0, atol=1e-12)


def test_grid_covers_the_image_either_way():
    model = LinescanModel.example()
    for m in (model, reverse(model)):
        t0, t1 = m.line_times.span(-0.5, m.shape[0] - 0.5)
        s = JitterSpline.covering(m.line_times, m.shape[0], 100.0)
        # half an interval to spare at each end
        assert s.start_s == pytest.approx(t0 - 0.5 * s.interval_s)
        assert s.start_s + s.intervals * s.interval_s == pytest.approx(t1 + 0.5 * s.interval_s)
        assert s.knot_lines(m.line_times) == pytest.approx(100.0)
        assert s.intervals == 9  # 800 rows, knots every 100 lines, plus the margins
        assert s.names[0] == "roll_spline_000" and s.names[-1] == "yaw_spline_011"


@pytest.mark.parametrize("bad", [
    {"interval_s": 0.0}, {"interval_s": np.nan}, {"intervals": 0}, {"intervals": 1.5},
    {"start_s": "x"}])
def test_spline_refuses_bad_grids(bad):
    args = {"start_s": 0.0, "interval_s": 0.1, "intervals": 3} | bad
    with pytest.raises(ModelFormatError, match="JitterSpline"):
        JitterSpline(**args)


# ----------------------------------------------------------------------------- the set
def test_default_set_and_its_prior():
    model = LinescanModel.example()
    jit = model.with_parameter_set("jitter", accuracy_m=10.0)
    spline = jit.jitter
    # the example's attitude is sampled every 0.05 s: 134 lines
    assert default_knot_lines(model) == 134
    assert spline is not None and spline.knot_lines(model.line_times) == pytest.approx(134)
    n = spline.n_coefficients
    params = jit.parameters
    dg = model.with_parameter_set("dg", accuracy_m=10.0).parameters
    assert params.names == dg.names + spline.names
    assert list(params.adjustable) == list(dg.adjustable) + [True] * 3 * n
    info = params.information
    assert info is not None
    # the base's sigmas on the diagonal
    assert np.allclose(np.diag(info)[:12], 1.0 / dg.sigmas**2)
    # per axis: amplitude plus second differences
    s = default_smoothness(DEFAULT_JITTER_SIGMA_RAD, spline.interval_s)
    block = info[12:12 + n, 12:12 + n]
    d2 = np.diff(np.eye(n), 2, axis=0)
    assert np.allclose(block, np.eye(n) / DEFAULT_JITTER_SIGMA_RAD**2 + d2.T @ d2 / s**2)
    assert np.all(info[12:12 + n, 12 + n:] == 0)
    # the covariance is its inverse; the marginal sigmas below the amplitude sigma
    assert np.allclose(params.prior_covariance[12:, 12:] @ info[12:, 12:], np.eye(3 * n),
                       atol=1e-9)
    assert np.all(params.sigmas[12:] < DEFAULT_JITTER_SIGMA_RAD)


def test_engine_weight_is_the_information_with_overrides():
    jit = LinescanModel.example().with_parameter_set("jitter", accuracy_m=10.0)
    info = jit.parameters.information
    mask, cov = parameter_prior(jit, {})
    adj = np.flatnonzero(mask)
    w = prior_weight(cov[np.ix_(adj, adj)])
    assert np.allclose(w, info[np.ix_(adj, adj)], rtol=1e-9, atol=1e-9 * np.abs(info).max())
    # an override on a coefficient: its coupling goes, its own sigma stays; fixed and free
    name = jit.jitter.names[4]
    k = jit.parameters.index(name)
    mask, cov = parameter_prior(jit, {name: 1e-5, "dp_along": 0.0, "roll_rate": np.inf})
    adj = np.flatnonzero(mask)
    w = prior_weight(cov[np.ix_(adj, adj)])
    expect = np.array(info)
    expect[k, :] = expect[:, k] = 0.0
    expect[k, k] = 1e10
    rate = jit.parameters.index("roll_rate")
    expect[rate, :] = expect[:, rate] = 0.0
    assert not mask[jit.parameters.index("dp_along")] and mask[rate]
    assert np.isinf(cov[rate, rate])
    assert np.allclose(w, expect[np.ix_(adj, adj)], rtol=1e-9, atol=1e-9 * np.abs(info).max())


def test_zero_coefficients_project_bit_identically():
    model = LinescanModel.example()
    jit = model.with_parameter_set("jitter", accuracy_m=10.0, position=True)
    lon, lat, h = grid_points(model)
    a, b = model.project(lon, lat, h), jit.project(lon, lat, h)
    assert np.array_equal(a.row, b.row) and np.array_equal(a.col, b.col)
    g0, g1 = model.backproject(a.row, a.col, h), jit.backproject(a.row, a.col, h)
    assert np.array_equal(g0.lon, g1.lon) and np.array_equal(g0.lat, g1.lat)


def test_spline_moves_the_image_as_its_curve_says():
    """A spline equal to a constant angle everywhere is the same model as that bias."""
    model = LinescanModel.example()
    jit = model.with_parameter_set("jitter", base="linescan")
    n = jit.jitter.n_coefficients
    spline = jit.with_parameters({f"pitch_spline_{k:03d}": 4e-6 for k in range(n)})
    bias = model.with_parameters({"pitch_bias": 4e-6})
    lon, lat, h = grid_points(model)
    a, b = spline.project(lon, lat, h), bias.project(lon, lat, h)
    assert np.allclose(a.row, b.row, atol=1e-7) and np.allclose(a.col, b.col, atol=1e-7)
    t = model.line_times.time(np.array([0.0, 400.0, 799.0]))
    angles, sigmas = attitude_correction(spline, t, np.zeros((len(spline.parameters),) * 2))
    assert np.allclose(angles, [[0.0, 4e-6, 0.0]] * 3, atol=1e-18) and np.all(sigmas == 0)


@pytest.mark.parametrize("scan", ["forward", "reverse"])
@pytest.mark.parametrize("position", [False, True])
def test_partials_against_central_differences(scan, position):
    model = LinescanModel.example()
    model = reverse(model) if scan == "reverse" else model
    jit = with_wander(model.with_parameter_set("jitter", base="linescan", knot_lines=60,
                                               position=position))
    jit = jit.with_parameters({"roll_bias": 2e-5, "yaw_rate": 1e-5})
    lon, lat, h = grid_points(jit)
    analytic = jit.partials_parameters(lon, lat, h)
    numeric = numeric_partials_parameters(jit, lon, lat, h, steps=fd_steps(jit.parameters))
    names = jit.parameters.names
    spline = np.array(["_spline_" in n for n in names])
    scale = np.max(np.abs(numeric), axis=(0, 1))
    assert np.all(scale[spline] > 0)
    # relative to the axis's largest partial (the grid's end coefficients barely reach into
    # the image: their own partials are tiny, their differences noise)
    axis = np.array([n.rsplit("_spline_", 1)[0] for n in names])
    for a in np.unique(axis[spline]):
        cols = axis == a
        err = np.max(np.abs(analytic - numeric)[:, :, cols]) / scale[cols].max()
        assert err < 1e-4, a
    # four coefficients per axis and point
    nonzero = np.count_nonzero(analytic[:, :, spline], axis=-1)
    axes = 6 if position else 3
    assert nonzero.max() <= 4 * axes


def test_partials_of_an_unsolved_point_are_nan():
    jit = with_wander(LinescanModel.example().with_parameter_set("jitter", accuracy_m=10.0))
    lon, lat, h = grid_points(jit)
    out = jit.partials_parameters([lon[3], 100.0], [lat[3], 0.0], [h[3], 0.0])
    assert np.all(np.isfinite(out[0])) and np.all(np.isnan(out[1]))


def test_conformance_kit():
    jit = with_wander(LinescanModel.example().with_parameter_set("jitter", accuracy_m=10.0))
    check_sensor_model(jit, parameter_set_options=OPTIONS)


def test_conformance_kit_reverse_scan_with_position_splines():
    model = reverse(LinescanModel.example())
    jit = with_wander(model.with_parameter_set("jitter", base="linescan", position=True,
                                               knot_lines=80))
    check_sensor_model(jit, parameter_set_options=OPTIONS, n=3)


def test_round_trips():
    jit = with_wander(LinescanModel.example().with_parameter_set(
        "jitter", accuracy_m=10.0, position=True, knot_lines=150))
    data = json.loads(json.dumps(jit.to_dict(), allow_nan=False))
    assert data["jitter"]["intervals"] == jit.jitter.intervals
    again = LinescanModel.from_dict(data)
    assert again == jit and again.parameters == jit.parameters
    assert again.jitter == jit.jitter
    assert np.array_equal(again.parameters.information, jit.parameters.information)
    assert pickle.loads(pickle.dumps(jit)) == jit
    lon, lat, h = grid_points(jit)
    assert np.array_equal(again.project(lon, lat, h).row, jit.project(lon, lat, h).row)
    # an older dictionary, without the grid, still loads
    plain = LinescanModel.example().to_dict()
    assert "jitter" not in plain and LinescanModel.from_dict(plain).jitter is None


def test_other_sets_keep_the_spline():
    jit = with_wander(LinescanModel.example().with_parameter_set("jitter", accuracy_m=10.0))
    lon, lat, h = grid_points(jit)
    before = jit.project(lon, lat, h)
    for name in ("dg", "linescan", "physical"):
        other = jit.with_parameter_set(name, **OPTIONS.get(name, {}))
        assert other.jitter == jit.jitter
        k = other.parameters.index("roll_spline_003")
        assert other.parameters.values[k] == jit.parameters["roll_spline_003"]
        assert not other.parameters.adjustable[k]
        after = other.project(lon, lat, h)
        assert np.array_equal(after.row, before.row)
    # the same grid again keeps the values; another grid would drop them
    again = jit.with_parameter_set("jitter", accuracy_m=10.0, sigma_rad=1e-6)
    assert again.jitter == jit.jitter
    assert again.parameters["yaw_spline_002"] == jit.parameters["yaw_spline_002"]
    with pytest.raises(ParameterSetError, match="drop that correction"):
        jit.with_parameter_set("jitter", accuracy_m=10.0, knot_lines=50)


@pytest.mark.parametrize(("options", "match"), [
    ({"base": "mba"}, "base must be one of"),
    ({"knot_lines": 0.5}, "knot_lines must be >= 1"),
    ({"knot_lines": -3}, "knot_lines must be finite and > 0"),
    ({"knot_lines": True}, "knot_lines must be finite and > 0"),
    ({"sigma_rad": True}, "sigma_rad must be finite and > 0"),
    ({"sigma_rad": 0.0}, "sigma_rad must be finite and > 0"),
    ({"smoothness_rad": np.inf}, "smoothness_rad"),
    ({"position": "yes"}, "position must be True or False"),
    ({"knots": 10}, "has no option"),
    ({"base": "linescan", "accuracy_m": 3.0}, "takes no accuracy_m"),
])
def test_bad_options(options, match):
    model = LinescanModel.example()
    opts = {"accuracy_m": 10.0} | options if options.get("base") != "linescan" else options
    with pytest.raises(ParameterSetError, match=match):
        model.with_parameter_set("jitter", **opts)


def test_dg_base_needs_an_accuracy():
    with pytest.raises(ParameterSetError, match="location accuracy"):
        LinescanModel.example().with_parameter_set("jitter")


def test_spline_names_need_a_grid():
    model = LinescanModel.example()
    params = ParameterSet(("roll_bias", "roll_spline_000"), [0.0, 0.0])
    with pytest.raises(ModelFormatError, match="jitter grid"):
        model.replace(parameters=params)
    jit = model.with_parameter_set("jitter", accuracy_m=10.0)
    n = jit.jitter.n_coefficients
    with pytest.raises(ModelFormatError, match="unknown parameter names"):
        jit.replace(parameters=ParameterSet((f"roll_spline_{n:03d}",), [0.0]))


# ----------------------------------------------------------------------------- curves
def test_correction_curve_and_its_sigma():
    model = LinescanModel.example()
    jit = with_wander(model.with_parameter_set("jitter", accuracy_m=10.0, position=True))
    jit = jit.with_parameters({"roll_bias": 1e-5, "pitch_rate": 2e-6, "dp_across": 3.0})
    rows = np.linspace(-50.0, 850.0, 31)
    t = jit.line_times.time(rows)
    angles, sigmas = attitude_correction(jit, t)
    # the curve is the rotation the parameters add: R0^T R' = Rx Ry Rz of the angles
    _, _, r1 = jit.sensor_state(rows)
    _, _, r0 = model.sensor_state(rows)
    delta = np.swapaxes(r0, -1, -2) @ r1
    small = np.stack([delta[:, 2, 1], delta[:, 0, 2], delta[:, 1, 0]], axis=-1)
    assert np.allclose(small, angles, atol=1e-9)
    # the sigmas propagate the covariance through the basis: Monte Carlo
    params = jit.parameters
    cov = params.prior_covariance
    free = ~np.isfinite(np.diag(cov))
    assert np.all(np.isinf(sigmas[:, 0]) == False)  # noqa: E712  roll's parameters are finite
    rng = np.random.default_rng(0)
    fin = np.flatnonzero(~free)
    draws = rng.multivariate_normal(np.zeros(fin.size), cov[np.ix_(fin, fin)], size=4000)
    samples = []
    for d in draws[:400]:
        v = np.array(params.values)
        v[fin] += d
        samples.append(attitude_correction(jit.with_parameters(v), t)[0])
    spread = np.std(np.array(samples), axis=0)
    assert np.allclose(spread, sigmas, rtol=0.15)
    # a posterior of some parameters (names), the others exact
    names = ["pitch_bias"] + [n for n in params.names if n.startswith("pitch_spline_")]
    sub = np.diag(np.full(len(names), 1e-12))
    _, s = attitude_correction(jit, t, sub, names)
    assert np.all(s[:, 0] == 0) and np.all(s[:, 2] == 0) and np.all(s[:, 1] > 0)
    with pytest.raises(ValueError, match="names"):
        attitude_correction(jit, t, sub)
    offsets, _ = position_correction(jit, t, np.zeros((len(params),) * 2))
    assert np.allclose(offsets[:, 1] - 3.0,
                       jit.jitter.evaluate(
                           [[jit.parameters[f"dp_across_spline_{k:03d}"]
                             for k in range(jit.jitter.n_coefficients)]], t)[:, 0])


# ----------------------------------------------------------------------------- real products
#: product -> (plugin, default knot spacing in lines, coefficients per axis): the attitude
#: records' sampling (SPOT-5 8 Hz, Pleiades 64 Hz, WorldView-1 50 Hz) over the line period
REAL = {
    "cosicorr3d/test_dataset/SPOT5.DIM": ("geoblock_spot", 166, 77),
    "shareloc/rpc/PHRDIMAP_P1BP--2018122638935449CP.XML": ("geoblock_spot", 213, 184),
    "rpcm/test_rpc_files/rpc_WV1.xml": ("geoblock_quickbird", 480, 60),
    "cosicorr3d/test_dataset/WV1.XML": ("geoblock_quickbird", 480, 58),  # reverse scan
}


@pytest.mark.parametrize("rel", list(REAL))
def test_real_products_take_the_jitter_set(data_dir, rel):
    import geoblock

    plugin, knot_lines, per_axis = REAL[rel]
    pytest.importorskip(plugin)
    model = geoblock.open_model(data_dir / rel)
    assert isinstance(model, LinescanModel)
    options = {} if model.location_accuracy_m is not None else {"accuracy_m": 10.0}
    jit = model.with_parameter_set("jitter", **options)
    assert jit.jitter.knot_lines(model.line_times) == pytest.approx(knot_lines)
    assert jit.jitter.n_coefficients == per_axis
    rows, cols = model.shape
    r, c = np.meshgrid(np.linspace(0, rows - 1, 7), np.linspace(0, cols - 1, 5))
    h = np.full(r.size, 100.0)
    g = model.backproject(r.ravel(), c.ravel(), h)
    a, b = model.project(g.lon, g.lat, h), jit.project(g.lon, g.lat, h)
    assert np.array_equal(a.row, b.row) and np.array_equal(a.col, b.col)
    # a wander moves the image where its knots are, and the partials follow it
    wandering = with_wander(jit, rad=1e-6)
    moved = wandering.project(g.lon, g.lat, h)
    assert 0 < np.max(np.abs(moved.row - a.row)) < 20
    assert type(wandering).from_dict(wandering.to_dict()) == wandering
