"""The orbit/sensor simulator (geoblock.simulate.sensors)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from geoblock import coords
from geoblock.errors import GeoblockError
from geoblock.models.linescan import LinescanModel, orbital_frame
from geoblock.simulate.sensors import (
    EARTH_ROTATION_RAD_S,
    QUICKBIRD,
    QUICKBIRD_SMALL,
    SPOT1A,
    SPOT1A_SMALL,
    SPOT5_STRIPS,
    SPOT5_STRIPS_SMALL,
    OrbitSensorSpec,
    incidence_angle,
    onboard_error,
    simulate_sensor,
)
from geoblock.testing.contract import SensorModelContract

SMALL = {s.name: s for s in (*SPOT5_STRIPS_SMALL, QUICKBIRD_SMALL, SPOT1A_SMALL)}
SIMS = {name: simulate_sensor(spec) for name, spec in SMALL.items()}


def _centre(model):
    rows, cols = model.shape
    return (rows - 1) / 2.0, (cols - 1) / 2.0


class TestSimulatedContract(SensorModelContract):
    parameter_set_options = {"dg": {"accuracy_m": 10.0}, "physical": {"accuracy_m": 10.0}}

    @pytest.fixture(params=["spot5-strip3-small-true", "quickbird-small-onboard"])
    def model(self, request):
        if request.param.endswith("true"):
            return SIMS["spot5-strip3-small"].true_model
        return SIMS["quickbird-small"].onboard_model


@pytest.mark.parametrize("name", SMALL)
def test_scene_centre_projects_to_the_image_centre(name):
    sim = SIMS[name]
    spec = sim.spec
    assert type(sim.true_model) is LinescanModel and sim.true_model.shape == spec.shape
    r, c = sim.true_model.project(spec.centre_lon, spec.centre_lat, spec.centre_h)
    rc, cc = _centre(sim.true_model)
    assert abs(float(r) - rc) < 0.01 and abs(float(c) - cc) < 0.01


@pytest.mark.parametrize("name", SMALL)
def test_incidence_angle_as_requested(name):
    sim = SIMS[name]
    spec = sim.spec
    got = incidence_angle(sim.true_model, *_centre(sim.true_model), spec.centre_h)
    if spec.incidence_deg is not None:
        assert got == pytest.approx(spec.incidence_deg, abs=0.01)
    else:  # QuickBird: 8 degrees off nadir roll -> a slightly larger incidence (curvature)
        assert math.degrees(sim.roll_rad) == spec.roll_deg
        ratio = spec.orbit_radius_m / coords.WGS84_A
        expected = math.degrees(math.asin(ratio * math.sin(math.radians(spec.roll_deg))))
        assert got == pytest.approx(expected, abs=0.05)


def test_incidence_sign_follows_the_look_side():
    strips = [SIMS[f"spot5-strip{k}-small"] for k in (1, 2, 3)]
    rolls = [s.roll_rad for s in strips]
    assert rolls[0] > 0 and rolls[1] > 0 and rolls[2] < 0


@pytest.mark.parametrize("spec", [SPOT1A_SMALL.replace(incidence_deg=0.0), SPOT1A],
                         ids=["nadir-small", "spot1a-full"])
def test_gsd_and_line_period_as_requested(spec):
    model = simulate_sensor(spec).true_model
    rc, cc = _centre(model)
    g = model.backproject([rc, rc, rc + 1], [cc, cc + 1, cc], spec.centre_h)
    xyz = np.stack(coords.geodetic_to_ecef(*g), axis=-1)
    across = np.linalg.norm(xyz[1] - xyz[0])
    along = np.linalg.norm(xyz[2] - xyz[0])
    # off nadir (SPOT1A at 10 deg) the across-track pixel grows by ~1/cos^2(incidence)
    inc = math.radians(spec.incidence_deg or 0.0)
    assert across == pytest.approx(spec.gsd_m / math.cos(inc) ** 2, rel=0.02)
    assert along == pytest.approx(spec.gsd_m, rel=0.02)
    assert model.line_times.line_period_s == spec.line_period
    if spec is SPOT1A:
        assert model.line_times.line_period_s == 1.5e-3


@pytest.mark.parametrize("change", [{"reverse_scan": True},
                                    {"line_period_s": -QUICKBIRD_SMALL.line_period}],
                         ids=["reverse_scan", "negative-period"])
def test_a_reverse_scanned_scene_is_the_forward_scene_flipped(change):
    """A reverse scan (SCANDIRECTION Reverse): row r is exposed when the forward scene's row
    rows - 1 - r is; same on-board error, same preset sigmas; the on-board model (a
    different orbit and attitude) still solves every point."""
    fwd = SIMS["quickbird-small"]
    rev = simulate_sensor(QUICKBIRD_SMALL.replace(**change))
    assert rev.spec.line_period == -fwd.spec.line_period < 0
    assert rev.true_model.line_times.line_period_s == rev.spec.line_period
    rows, cols = fwd.true_model.shape
    rr, cc = np.meshgrid(np.linspace(-0.5, rows - 0.5, 12), np.linspace(-0.5, cols - 0.5, 12),
                         indexing="ij")
    g = rev.true_model.backproject(rr, cc, 500.0)
    gf = fwd.true_model.backproject(rows - 1 - rr, cc, 500.0)
    assert np.max(np.abs(g.lon - gf.lon)) < 1e-12 and np.max(np.abs(g.lat - gf.lat)) < 1e-12
    for model in (rev.true_model, rev.onboard_model):
        p = model.project(g.lon, g.lat, 500.0)
        assert np.all(np.isfinite(p.row))
    p = rev.true_model.project(g.lon, g.lat, 500.0)
    assert np.max(np.abs(p.row - rr)) < 1e-6 and np.max(np.abs(p.col - cc)) < 1e-6
    assert rev.onboard_error().rmse == pytest.approx(fwd.onboard_error().rmse, rel=1e-6)
    np.testing.assert_allclose(rev.onboard_model.with_parameter_set("dg").parameters.sigmas,
                               fwd.onboard_model.with_parameter_set("dg").parameters.sigmas,
                               rtol=1e-9)


def test_orbit_is_circular_keplerian_in_inertial_space():
    sim = SIMS["spot5-strip1-small"]
    eph = sim.true_model.ephemeris
    r = np.linalg.norm(eph.position_m, axis=1)
    np.testing.assert_allclose(r, sim.spec.orbit_radius_m, rtol=1e-12)
    # inertial velocity = Earth-fixed velocity + omega x P: speed sqrt(GM / r)
    omega = np.array([0.0, 0.0, EARTH_ROTATION_RAD_S])
    v_inertial = eph.velocity_m_s + np.cross(omega, eph.position_m)
    np.testing.assert_allclose(np.linalg.norm(v_inertial, axis=1),
                               sim.spec.mean_motion_rad_s * sim.spec.orbit_radius_m, rtol=1e-12)
    # descending: the satellite flies south over the scene
    _, vel, _ = sim.true_model.sensor_state(_centre(sim.true_model)[0])
    up = coords.enu_rotation(sim.spec.centre_lon, sim.spec.centre_lat)
    assert float(up[1] @ vel) < 0
    asc = simulate_sensor(SMALL["spot1a-small"].replace(ascending=True)).true_model
    _, vel, _ = asc.sensor_state(_centre(asc)[0])
    assert float(up[1] @ vel) > 0
    # the attitude is in the orbital frame, whose x axis follows the ECEF velocity
    m = orbital_frame(eph.position_m, eph.velocity_m_s)
    assert np.all(np.sum(m[..., 0] * eph.velocity_m_s, axis=-1) > 0)


@pytest.mark.parametrize("name", SMALL)
def test_onboard_rmse_as_requested(name):
    sim = SIMS[name]
    err = sim.onboard_error()
    assert err.rmse == pytest.approx(sim.spec.onboard_rmse_m, rel=0.02)
    # on a denser grid than the sizing used, still within 10 %
    dense = onboard_error(sim.true_model, sim.onboard_model, n=21, h=sim.spec.centre_h)
    assert dense.rmse == pytest.approx(sim.spec.onboard_rmse_m, rel=0.1)
    assert np.all(sim.onboard_model.parameters.values == 0)


def test_quickbird_error_grows_along_track_from_the_centre():
    sim = SIMS["quickbird-small"]
    err = onboard_error(sim.true_model, sim.onboard_model, n=11, h=0.0)
    d = np.hypot(err.de - err.de[5, 5], err.dn - err.dn[5, 5])
    # the drift part grows with |row - centre| and barely with the column
    assert d[0, 5] > 2.0 and d[10, 5] > 2.0
    assert d[5, 0] < 0.25 * d[0, 5] and d[5, 10] < 0.25 * d[0, 5]
    assert sim.errors.position_drift_m_s[0] != 0 and sim.errors.attitude_drift_rad_s[1] != 0


def test_zero_error_budget_gives_the_true_model_up_to_jitter():
    spec = SMALL["spot1a-small"].replace(onboard_rmse_m=0.0, onboard_errors="bias-drift")
    sim = simulate_sensor(spec)
    assert sim.onboard_error().rmse < 1e-6  # no jitter in this spec
    assert np.all(sim.errors.position_bias_m == 0)


def test_zero_error_budget_realistic_leaves_the_realistic_components():
    # issue 27: with realistic errors a zero budget still leaves the wander, the look-angle
    # and the orbital-period ephemeris errors (metres: SPOT-4 DIODE sizes on SPOT1A)
    spec = SMALL["spot1a-small"].replace(onboard_rmse_m=0.0)
    sim = simulate_sensor(spec)
    assert spec.onboard_errors == "realistic" and sim.realistic is not None
    assert np.all(sim.errors.position_bias_m == 0)
    assert 0.5 < sim.onboard_error().rmse < 10.0


def test_deterministic_for_a_seed():
    spec = SMALL["spot5-strip3-small"]
    a, b = simulate_sensor(spec), simulate_sensor(spec)
    assert a.true_model == b.true_model and a.onboard_model == b.onboard_model
    c = simulate_sensor(spec.replace(seed=spec.seed + 1))
    assert c.true_model != a.true_model  # jitter phases
    assert not np.allclose(c.errors.position_bias_m, a.errors.position_bias_m)


def test_small_scenes_build_and_full_presets_have_the_papers_sizes():
    # (speed is measured in benchmarks/bench_simulate.py, not asserted here)
    small = simulate_sensor(SPOT5_STRIPS_SMALL[0])
    assert small.true_model.shape == SPOT5_STRIPS_SMALL[0].shape
    assert [s.incidence_deg for s in SPOT5_STRIPS] == [5.2, 5.7, -14.8]
    assert all(s.gsd_m == 2.5 and s.altitude_m == 832e3 and s.inclination_deg == 98.7
               for s in SPOT5_STRIPS)
    assert QUICKBIRD.gsd_m == 0.62 and QUICKBIRD.altitude_m == 450e3 and QUICKBIRD.roll_deg == 8
    assert SPOT1A.shape == (6000, 6000) and SPOT1A.line_period_s == 1.5e-3
    assert SPOT5_STRIPS_SMALL[0].shape == (600, 600) and SPOT5_STRIPS_SMALL[0].gsd_m == 100.0


def test_full_size_spot5_strip_builds_and_centres():
    sim = simulate_sensor(SPOT5_STRIPS[2])
    spec = sim.spec
    r, c = sim.true_model.project(spec.centre_lon, spec.centre_lat, spec.centre_h)
    assert abs(float(r) - 11999.5) < 0.01 and abs(float(c) - 11999.5) < 0.01
    assert sim.onboard_error().rmse == pytest.approx(42.3, rel=0.02)


@pytest.mark.parametrize(("change", "field"), [
    ({"centre_lat": 85.0}, "centre_lat"),
    ({"altitude_m": 1e3}, "altitude_m"),
    ({"gsd_m": 0.0}, "gsd_m"),
    ({"onboard_drift_share": 1.0}, "onboard_drift_share"),
    ({"incidence_deg": 75.0}, "incidence_deg"),
    ({"line_period_s": 0.0}, "line_period_s"),
])
def test_bad_specs_raise_naming_the_field(change, field):
    with pytest.raises(GeoblockError, match=field):
        SPOT1A.replace(**change)


def test_spec_is_a_plain_dataclass():
    assert isinstance(SPOT1A, OrbitSensorSpec)
    assert SPOT1A.scaled(10).shape == (600, 600)
    assert SPOT1A.scaled(10).line_period_s == pytest.approx(1.5e-2)
