"""Light-path corrections (aberration, light time, refraction) and the focal scale of the
linescan model (geoblock.models.linescan.light, LinescanModel(corrections=...))."""

from __future__ import annotations

import numpy as np
import pytest

from geoblock.errors import ModelFormatError
from geoblock.models import ParameterSet
from geoblock.models.linescan import CORRECTIONS, LinescanModel
from geoblock.models.linescan.light import (
    SPEED_OF_LIGHT_M_S,
    apparent_direction,
    geometric_direction,
    refraction_coefficient,
)
from geoblock.plugins import from_dict
from geoblock.testing.contract import SensorModelContract

ORBITAL = LinescanModel.example()
LIGHT = ORBITAL.replace(corrections=CORRECTIONS)
FOCAL = LIGHT.with_parameter_set("physical", accuracy_m=5.0).with_parameters(
    {"focal_scale": 2e-4, "roll_bias": 1e-5})
GSD = 2.5


class TestCorrectedLinescanContract(SensorModelContract):
    parameter_set_options = {"dg": {"accuracy_m": 10.0}, "physical": {"accuracy_m": 10.0},
                             "jitter": {"accuracy_m": 10.0}}

    @pytest.fixture(params=["light", "focal"])
    def model(self, request):
        return {"light": LIGHT, "focal": FOCAL}[request.param]


def _state(row):
    pos, vel, _ = ORBITAL.sensor_state(np.asarray(row, float))
    return pos, vel


def test_saastamoinen_coefficient_has_its_published_size():
    # 700 km orbit, sea-level ground: 2335 / 700 * 1e-6 (the second term vanishes above ~100 km)
    assert refraction_coefficient(700e3, 0.0) == pytest.approx(2335 / 700 * 1e-6, rel=1e-6)
    # higher ground, thinner air above it: ~12 % less per km
    ratio = refraction_coefficient(700e3, 1000.0) / refraction_coefficient(700e3, 0.0)
    assert 0.87 < ratio < 0.89


@pytest.mark.parametrize("corrections", [("aberration",), ("light-time",), ("refraction",),
                                         CORRECTIONS])
def test_apparent_direction_inverts_geometric_direction(corrections):
    rng = np.random.default_rng(1)
    rows = rng.uniform(0, 799, 200)
    pos, vel = _state(rows)
    u = ORBITAL.backproject_ecef(rows, rng.uniform(0, 999, 200), 300.0)
    g = np.stack([np.asarray(c) for c in u], axis=-1)
    diff = g - pos
    rng_m = np.linalg.norm(diff, axis=-1)
    u_geo = diff / rng_m[:, None]
    h = np.full(200, 300.0)
    u_app = apparent_direction(u_geo, pos, vel, h, corrections)
    back = geometric_direction(u_app, pos, vel, h, corrections)
    assert np.max(np.linalg.norm(back - u_geo, axis=-1)) < 1e-14  # radians
    shift = np.linalg.norm(u_app - u_geo, axis=-1)
    if corrections == ("aberration",):  # |V_inertial| / c, less its component along the ray
        speed = np.linalg.norm(vel, axis=-1)
        assert np.all(shift < 1.1 * speed / SPEED_OF_LIGHT_M_S)
        assert np.all(shift > 0.8 * speed / SPEED_OF_LIGHT_M_S)
    elif corrections == ("light-time",):  # |omega x G| / c < 1.6e-6 rad
        assert np.all(shift < 1.6e-6) and np.all(shift > 1e-7)


def test_each_correction_moves_the_ground_by_its_documented_size():
    rows, cols = np.array([400.0, 10.0, 790.0]), np.array([500.0, 990.0, 5.0])
    base = ORBITAL.backproject_ecef(rows, cols, 0.0)
    base = np.stack([np.asarray(c) for c in base], axis=-1)
    sizes = {}
    for name in CORRECTIONS:
        g = ORBITAL.replace(corrections=(name,)).backproject_ecef(rows, cols, 0.0)
        g = np.stack([np.asarray(c) for c in g], axis=-1)
        sizes[name] = np.linalg.norm(g - base, axis=-1)
    # 700 km altitude, ~7.5 km/s, 3 degrees roll: aberration 15-20 m, light time ~0.5-1.2 m,
    # refraction below 0.5 m this close to nadir
    assert np.all((sizes["aberration"] > 14) & (sizes["aberration"] < 20))
    assert np.all((sizes["light-time"] > 0.3) & (sizes["light-time"] < 1.5))
    assert np.all((sizes["refraction"] > 0.01) & (sizes["refraction"] < 0.5))


def test_corrected_model_round_trips_to_a_thousandth_of_a_pixel():
    rng = np.random.default_rng(2)
    rows, cols = rng.uniform(0, 799, 500), rng.uniform(0, 999, 500)
    h = rng.uniform(-100, 3000, 500)
    for model in (LIGHT, FOCAL):
        g = model.backproject(rows, cols, h)
        p = model.project(g.lon, g.lat, h)
        assert np.max(np.hypot(p.row - rows, p.col - cols)) < 1e-3


def test_refraction_follows_each_points_height():
    """The refraction of a high point is smaller: a model at the scene's mean height would
    be off by the difference (~0.1 m here, 0.3 px for a 0.5 m sensor at 30 degrees)."""
    only = ORBITAL.replace(corrections=("refraction",))
    rows, cols = np.full(2, 400.0), np.full(2, 999.0)
    shifts = []
    for h in (0.0, 3000.0):
        a = np.stack([np.asarray(c) for c in ORBITAL.backproject_ecef(rows, cols, h)], -1)
        b = np.stack([np.asarray(c) for c in only.backproject_ecef(rows, cols, h)], -1)
        shifts.append(np.linalg.norm(a - b, axis=-1)[0])
    assert shifts[1] < 0.75 * shifts[0]


def test_focal_scale_scales_the_look_tangents():
    scaled = ORBITAL.replace(parameters=ParameterSet(("focal_scale",), [1e-3]))
    g = ORBITAL.backproject(400.0, 999.0, 0.0)
    p = scaled.project(g.lon, g.lat, 0.0)
    # col 999 is 499.5 px from the centre: a 1e-3 longer focal length enlarges the image,
    # 0.4995 px farther from the centre
    assert float(p.col) == pytest.approx(999.0 + 0.4995, abs=0.02)
    # a preset keeps a non-zero focal scale (fixed), so it never changes a projection
    for name in ("linescan", "dg"):
        kept = scaled.with_parameter_set(name, **({"accuracy_m": 5.0} if name == "dg" else {}))
        assert kept.parameters["focal_scale"] == pytest.approx(1e-3)
        q = kept.project(g.lon, g.lat, 0.0)
        assert float(q.col) == pytest.approx(float(p.col), abs=1e-9)


def test_physical_set_adjusts_what_toutin_adjusts():
    params = ORBITAL.with_parameter_set("physical", accuracy_m=5.0).parameters
    free = [n for n, a in zip(params.names, params.adjustable, strict=True) if a]
    assert free == ["dp_along", "dp_across", "roll_bias", "pitch_bias", "yaw_bias",
                    "roll_rate", "pitch_rate", "yaw_rate", "focal_scale"]
    # a 1-sigma focal scale moves the swath's edge by the accuracy: 5 m / ~1.25 km
    assert params.sigmas[params.names.index("focal_scale")] == pytest.approx(5 / 1250, rel=0.05)


def test_corrections_survive_json_and_are_absent_when_off():
    assert "corrections" not in ORBITAL.to_dict()
    data = FOCAL.to_dict()
    assert data["corrections"] == list(CORRECTIONS)
    again = from_dict(data)
    assert again.corrections == CORRECTIONS and again == FOCAL


@pytest.mark.parametrize("bad", ["aberration", ["aberation"], 3])
def test_bad_corrections_are_refused_naming_the_field(bad):
    with pytest.raises(ModelFormatError, match="LinescanModel.corrections"):
        ORBITAL.replace(corrections=bad)


def test_focal_scale_must_leave_a_positive_principal_distance():
    with pytest.raises(ModelFormatError, match="focal_scale"):
        ORBITAL.replace(parameters=ParameterSet(("focal_scale",), [-0.95]))
