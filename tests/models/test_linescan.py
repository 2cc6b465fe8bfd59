"""The generic state-vector pushbroom model (geoblock.models.linescan)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from geoblock import coords
from geoblock.errors import GeoblockError, SerializationError
from geoblock.io import open_model, write_model
from geoblock.models import ParameterSet, get_registry
from geoblock.models.linescan import (
    PARAMETER_NAMES,
    Attitude,
    Ephemeris,
    LinescanModel,
    LineTimes,
    LookDirections,
    matrix_to_quaternion,
    orbital_frame,
    quaternion_to_matrix,
    rotation_xyz,
)
from geoblock.testing.contract import SensorModelContract
from geoblock.testing.strategies import ground_points, heights, image_points
from geoblock.typing import Status

FAST = settings(max_examples=30, deadline=None, database=None,
                suppress_health_check=[HealthCheck.too_slow])

ORBITAL = LinescanModel.example()
ECEF = LinescanModel.example(frame="ecef")
#: every parameter non-zero: 1-2 m position biases, 0.1-0.2 m/s drifts, 10-20 urad, 1-2 urad/s
VALUES = np.linspace(1.0, 2.0, 12) * np.repeat([1.0, 0.1, 1e-5, 1e-6], 3)
CORRECTED = ORBITAL.with_parameters(VALUES)


def reverse() -> LinescanModel:
    """The example scanned backwards (DigitalGlobe SCANDIRECTION Reverse): the times fall as
    the row rises; row r sees what the forward example's row (rows - 1 - r) sees. (A function:
    a refusal fails the tests that use it, not the module's collection.)"""
    lt = ORBITAL.line_times
    return ORBITAL.replace(line_times=LineTimes(lt.reference_row, lt.reference_time_s,
                                                -lt.line_period_s))


GSD = 2.5  # metres, the example's nominal ground sample distance
ALTITUDE = 700e3


# ============================================================================ conformance
class TestLinescanContract(SensorModelContract):
    parameter_set_options = {"dg": {"accuracy_m": 10.0}, "physical": {"accuracy_m": 10.0},
                             "jitter": {"accuracy_m": 10.0}}

    @pytest.fixture(params=["orbital", "ecef", "corrected", "dg-subset", "reverse",
                            "reverse-corrected"])
    def model(self, request):
        if request.param == "dg-subset":
            # a restricted set with finite sigmas, as the DG adjustment builds
            names = ("dp_along", "dp_across", "dp_radial", "dp_along_rate")
            params = ParameterSet(names, [3.0, -2.0, 1.0, 0.5], ("m", "m", "m", "m/s"),
                                  sigmas=[10.0, 10.0, 10.0, 1.0])
            return ORBITAL.replace(parameters=params)
        if request.param.startswith("reverse"):
            model = reverse()
            return model if request.param == "reverse" else model.with_parameters(VALUES)
        return {"orbital": ORBITAL, "ecef": ECEF, "corrected": CORRECTED}[request.param]


def test_registered_and_listed():
    assert get_registry().get("linescan") is LinescanModel


# ============================================================================ round trips
@pytest.mark.parametrize("name", ["orbital", "corrected", "reverse"])
def test_image_ground_image_round_trip(name):
    model = reverse() if name == "reverse" else {"orbital": ORBITAL, "corrected": CORRECTED}[name]

    @FAST
    @given(point=image_points(model), h=heights(model))
    def round_trip(point, h):
        lon, lat, h_out = model.backproject(*point, h)
        assert float(h_out) == h
        r, c = model.project(lon, lat, h)
        assert abs(float(r) - point[0]) <= 1e-6 and abs(float(c) - point[1]) <= 1e-6

    round_trip()


@pytest.mark.parametrize("name", ["orbital", "ecef", "reverse"])
def test_ground_image_ground_round_trip(name):
    model = reverse() if name == "reverse" else {"orbital": ORBITAL, "ecef": ECEF}[name]

    @FAST
    @given(ground=ground_points(model))
    def round_trip(ground):
        r, c = model.project(*ground)
        lon, lat, _ = model.backproject(r, c, ground.h)
        assert abs(float(lon) - float(ground.lon)) <= 1e-9
        assert abs(float(lat) - float(ground.lat)) <= 1e-9

    round_trip()


def test_full_scene_converges_at_every_height():
    """A 6000 x 6000 scene: a dense grid over the whole image at -500, 0, 4000 and 9000 m."""
    model = LinescanModel.example(shape=(6000, 6000)).with_parameters(VALUES)
    r, c, h = np.meshgrid(np.linspace(-0.5, 5999.5, 121), np.linspace(-0.5, 5999.5, 121),
                          [-500.0, 0.0, 4000.0, 9000.0], indexing="ij")
    g, status = model.backproject_with_status(r, c, h)
    assert np.all(status == Status.CONVERGED)
    (row, col), status = model.project_with_status(g.lon, g.lat, g.h)
    assert np.all(status == Status.CONVERGED)
    assert np.max(np.abs(row - r)) < 1e-6
    assert np.max(np.abs(col - c)) < 1e-6


def test_out_of_domain_outside_the_imaged_time_span():
    model = ORBITAL
    centre = model.backproject((model.shape[0] - 1) / 2, (model.shape[1] - 1) / 2, 0.0)
    # 1 degree of latitude (~111 km, ~44 000 rows) along the track; and the antipode
    lon = np.array([float(centre.lon), float(centre.lon), float(centre.lon) + 180.0])
    lat = np.array([float(centre.lat), float(centre.lat) + 1.0, -float(centre.lat)])
    (row, col), status = model.project_with_status(lon, lat, np.zeros(3))
    assert status.tolist() == [Status.CONVERGED, Status.OUT_OF_DOMAIN, Status.OUT_OF_DOMAIN]
    assert np.isnan(row[1:]).all() and np.isnan(col[1:]).all()
    # rows far beyond the ephemeris cannot be backprojected
    _, status = model.backproject_with_status([0.0, 1e6], [0.0, 0.0], 0.0)
    assert status.tolist() == [Status.CONVERGED, Status.OUT_OF_DOMAIN]


def test_no_intersection_when_looking_past_the_limb():
    # at 700 km the Earth's limb is ~64 degrees off nadir: a 86 degree roll looks into space
    model = LinescanModel.example(roll=1.5)
    _, status = model.backproject_with_status([0.0, 400.0], [0.0, 500.0], 0.0)
    assert np.all(status == Status.NO_INTERSECTION)


# ============================================================================ building blocks
def test_hermite_exact_at_samples_and_for_a_cubic_trajectory():
    rng = np.random.default_rng(1)
    coef = rng.normal(size=(4, 3)) * [[7e6], [7e3], [3.0], [0.1]]
    t = np.array([-4.0, -1.5, 0.0, 2.0, 5.0])

    def cubic(x):
        x = np.asarray(x)[..., None]
        return coef[0] + coef[1] * x + coef[2] * x**2 + coef[3] * x**3

    def d_cubic(x):
        x = np.asarray(x)[..., None]
        return coef[1] + 2 * coef[2] * x + 3 * coef[3] * x**2

    eph = Ephemeris(t, cubic(t), d_cubic(t))
    p, v = eph.at(t)
    np.testing.assert_array_equal(p, cubic(t))  # exact at the samples
    np.testing.assert_allclose(v, d_cubic(t), rtol=1e-12)
    x = np.linspace(-4.0, 5.0, 101)
    p, v = eph.at(x)
    np.testing.assert_allclose(p, cubic(x), rtol=0, atol=1e-6)
    np.testing.assert_allclose(v, d_cubic(x), rtol=0, atol=1e-8)
    # one interval of extrapolation is allowed, farther is NaN
    p, _ = eph.at([-6.5, -6.6, 8.0, 8.1])
    assert np.isfinite(p[[0, 2]]).all() and np.isnan(p[[1, 3]]).all()
    np.testing.assert_allclose(eph.at(7.0)[0], cubic(7.0), atol=1e-5)
    assert eph.at(np.zeros((2, 3)))[0].shape == (2, 3, 3)


def test_hermite_is_c1_at_the_samples():
    eph = ORBITAL.ephemeris
    t = eph.time_s[2]
    eps = 1e-7
    (p_lo, v_lo), (p_hi, v_hi) = eph.at(t - eps), eph.at(t + eps)
    np.testing.assert_allclose(p_lo, p_hi, atol=1e-2)
    np.testing.assert_allclose(v_lo, v_hi, atol=1e-4)


def _axis_angle(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    return np.concatenate([[np.cos(angle / 2)], np.sin(angle / 2) * axis])


def test_slerp_interpolates_the_angle_linearly():
    axis = [1.0, 2.0, -0.5]
    # the second quaternion is given with the opposite sign: the same rotation
    att = Attitude([0.0, 2.0], [_axis_angle(axis, 0.1), -_axis_angle(axis, 0.5)])
    for s in (0.0, 0.25, 0.5, 1.0):
        want = quaternion_to_matrix(_axis_angle(axis, 0.1 + s * 0.4))
        np.testing.assert_allclose(att.matrix(2.0 * s), want, atol=1e-14)
    # held up to one interval beyond the ends, NaN farther
    np.testing.assert_allclose(att.matrix(3.9), att.matrix(2.0), atol=0)
    assert np.isnan(att.matrix(4.1)).all()
    const = Attitude([0.0], [_axis_angle(axis, 0.3)])
    np.testing.assert_allclose(const.matrix([-1e6, 1e6]),
                               np.broadcast_to(quaternion_to_matrix(_axis_angle(axis, 0.3)),
                                               (2, 3, 3)))


@FAST
@given(q=st.lists(st.floats(-1, 1), min_size=4, max_size=4).filter(
    lambda v: np.linalg.norm(v) > 0.1))
def test_quaternion_matrix_round_trip(q):
    q = np.array(q) / np.linalg.norm(q)
    r = quaternion_to_matrix(q)
    np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-14)
    assert np.linalg.det(r) == pytest.approx(1.0)
    back = matrix_to_quaternion(r)
    assert back[0] >= 0
    # q and -q are the same rotation (w == 0 leaves the sign open)
    assert min(np.abs(back - q).max(), np.abs(back + q).max()) < 1e-12
    np.testing.assert_allclose(quaternion_to_matrix(back), r, atol=1e-14)


def test_quaternion_convention_is_active_hamilton():
    r = quaternion_to_matrix(_axis_angle([0, 0, 1], np.pi / 2))  # 90 degrees about z
    np.testing.assert_allclose(r @ [1.0, 0, 0], [0, 1.0, 0], atol=1e-15)
    # rotation_xyz is Rx @ Ry @ Rz
    a, b, c = 0.1, -0.2, 0.3
    want = (quaternion_to_matrix(_axis_angle([1, 0, 0], a))
            @ quaternion_to_matrix(_axis_angle([0, 1, 0], b))
            @ quaternion_to_matrix(_axis_angle([0, 0, 1], c)))
    np.testing.assert_allclose(rotation_xyz(a, b, c), want, atol=1e-15)


def test_orbital_frame_textbook_case():
    # equatorial prograde orbit over (0 E, 0 N): x_o is the velocity (east), z_o points to
    # the Earth's centre, y_o = z_o x x_o is south (the negative orbit normal)
    m = orbital_frame([7e6, 0, 0], [0, 7.5e3, 0])
    np.testing.assert_allclose(m, [[0, 0, -1], [1, 0, 0], [0, -1, 0]], atol=1e-15)
    rng = np.random.default_rng(0)
    p = rng.normal(size=(50, 3)) * 7e6
    v = rng.normal(size=(50, 3)) * 7e3
    m = orbital_frame(p, v)
    np.testing.assert_allclose(m @ np.swapaxes(m, -1, -2), np.broadcast_to(np.eye(3), m.shape),
                               atol=1e-14)
    np.testing.assert_allclose(np.linalg.det(m), 1.0)
    np.testing.assert_allclose(m[..., 2], -p / np.linalg.norm(p, axis=-1, keepdims=True))
    assert np.all(np.sum(m[..., 0] * v, axis=-1) > 0)  # x_o about the flight direction


def test_look_directions_interpolate_and_invert():
    look = LookDirections.from_tan_angles([0.01, 0.0, 0.02], [-0.1, 0.0, 0.15])
    np.testing.assert_allclose(look.at([0.0, 1.0, 2.0]), look.vectors, atol=0)
    np.testing.assert_allclose(np.linalg.norm(look.at([-3.0, 0.3, 1.7, 5.0]), axis=-1), 1.0)
    cols = np.array([-2.0, -0.5, 0.0, 0.4, 1.0, 1.6, 2.5, 4.0])
    v = look.at(cols)
    col, tan_x, _ = look.invert(v[:, 1] / v[:, 2])
    np.testing.assert_allclose(col, cols, atol=1e-12)
    np.testing.assert_allclose(tan_x, v[:, 0] / v[:, 2], atol=1e-15)
    # a decreasing table works too
    flipped = LookDirections(look.vectors[::-1])
    col, _, _ = flipped.invert(v[:, 1] / v[:, 2])
    np.testing.assert_allclose(col, 2.0 - cols, atol=1e-12)
    # the derivatives of the tangents in col are those of the interpolation
    _, _, dtan = look.invert(np.array([-0.05, 0.1]))
    step = 1e-6
    for k, c in enumerate(look.invert(np.array([-0.05, 0.1]))[0]):
        a, b = look.at(c - step), look.at(c + step)
        numeric = [(b[i] / b[2] - a[i] / a[2]) / (2 * step) for i in (0, 1)]
        np.testing.assert_allclose(dtan[k], numeric, rtol=1e-6)
    with pytest.raises(GeoblockError, match=r"tan_x \(3,\) and tan_y \(2,\)"):
        LookDirections.from_tan_angles([0.0, 0.0, 0.0], [0.1, 0.2])


def test_the_building_blocks_are_modules_of_the_package_and_reexported():
    import geoblock.models.linescan as ls
    from geoblock.models.linescan import attitude, ephemeris, line_times, look, model, rotations

    assert ls.Ephemeris is ephemeris.Ephemeris and ls.ORBIT_RADIUS_M is ephemeris.ORBIT_RADIUS_M
    assert ls.Attitude is attitude.Attitude and ls.LookDirections is look.LookDirections
    assert ls.LineTimes is line_times.LineTimes and ls.LinescanModel is model.LinescanModel
    assert ls.dg_parameters is model.dg_parameters
    assert ls.quaternion_to_matrix is rotations.quaternion_to_matrix
    assert sorted(ls.__all__) == sorted(n for n in ls.__all__ if hasattr(ls, n))
    assert LinescanModel.__module__ == "geoblock.models.linescan.model"


def test_line_times():
    lt = LineTimes(reference_row=10.0, reference_time_s=5.0, line_period_s=0.5)
    assert float(lt.time(12.0)) == 6.0
    np.testing.assert_allclose(lt.row(lt.time([-0.5, 3.25])), [-0.5, 3.25])


def test_reverse_line_times_fall_as_the_row_rises():
    lt = LineTimes(reference_row=0.0, reference_time_s=0.0, line_period_s=-0.5)
    assert lt.reverse and lt.period_magnitude_s == 0.5
    assert float(lt.time(4.0)) == -2.0
    assert lt.span(0.0, 4.0) == (-2.0, 0.0)
    np.testing.assert_allclose(lt.row(lt.time([-0.5, 3.25])), [-0.5, 3.25])
    assert not LineTimes(0.0, 0.0, 0.5).reverse


def test_a_reverse_scan_sees_the_forward_scan_flipped():
    """Row r of the reverse-scanned example is exposed when the forward example's row
    (rows - 1 - r) is: same ground, both ways, to float64 precision."""
    rows, cols = ORBITAL.shape
    backwards = reverse()
    rr, cc = np.meshgrid(np.linspace(-0.5, rows - 0.5, 15), np.linspace(-0.5, cols - 0.5, 15),
                         indexing="ij")
    for h in (-300.0, 2500.0):
        g = backwards.backproject(rr, cc, h)
        gf = ORBITAL.backproject(rows - 1 - rr, cc, h)
        assert np.max(np.abs(g.lon - gf.lon)) < 1e-12 and np.max(np.abs(g.lat - gf.lat)) < 1e-12
        p, status = backwards.project_with_status(g.lon, g.lat, h)
        assert np.all(status == Status.CONVERGED)
        assert np.max(np.abs(p.row - rr)) < 1e-6 and np.max(np.abs(p.col - cc)) < 1e-6


def test_a_reverse_scan_has_the_forward_scans_presets_and_partials():
    """The preset sigmas scale with the image's duration, |period| x rows, whatever the scan
    direction; the row partials change sign with the period."""
    backwards = reverse()
    for preset in ("dg", "physical"):
        fwd = ORBITAL.with_parameter_set(preset, accuracy_m=10.0).parameters.sigmas
        rev = backwards.with_parameter_set(preset, accuracy_m=10.0).parameters.sigmas
        assert np.all(rev > 0)
        np.testing.assert_allclose(rev, fwd, rtol=1e-9)
    rows, cols = ORBITAL.shape
    g = ORBITAL.backproject(100.0, 300.0, 50.0)
    gr = backwards.backproject(rows - 1 - 100.0, 300.0, 50.0)
    jf, jr = ORBITAL.partials_ground(*g), backwards.partials_ground(*gr)
    np.testing.assert_allclose(jr[..., 0, :], -jf[..., 0, :], rtol=1e-6, atol=1e-12)
    np.testing.assert_allclose(jr[..., 1, :], jf[..., 1, :], rtol=1e-6, atol=1e-12)


# ============================================================================ parameters
def _centre_ground(model):
    rows, cols = model.shape
    return model.backproject((rows - 1) / 2, (cols - 1) / 2, 0.0)


def _motion(model, **values):
    g = _centre_ground(model)
    r0, c0 = model.project(*g)
    r1, c1 = model.with_parameters(values).project(*g)
    return float(r1 - r0), float(c1 - c0)


def test_dp_along_moves_the_image_along_rows():
    # moving the satellite 10 m forward images the ground point 10 m (4 lines) earlier
    d_row, d_col = _motion(ORBITAL, dp_along=10.0)
    assert d_row == pytest.approx(-10.0 / GSD, rel=0.03)
    assert abs(d_col) < 0.05
    d_row, d_col = _motion(ORBITAL, dp_across=10.0)
    assert abs(d_col) == pytest.approx(10.0 / GSD, rel=0.03)
    assert abs(d_row) < 0.05


def test_roll_bias_moves_the_image_across_columns():
    angle = 2e-5  # 14 m at 700 km
    d_row, d_col = _motion(ORBITAL, roll_bias=angle)
    # the example looks 0.05 rad off nadir: the slant range is ~ altitude / cos(roll)
    expected = ALTITUDE / np.cos(0.05) * angle / (GSD / np.cos(0.05) ** 1)
    assert d_col == pytest.approx(expected, rel=0.05)
    assert d_col > 0  # Rx(+roll) tilts the boresight to -y: the point is seen at larger col
    assert abs(d_row) < 0.05 * abs(d_col)
    d_row, _ = _motion(ORBITAL, pitch_bias=angle)
    assert abs(d_row) == pytest.approx(ALTITUDE * angle / GSD, rel=0.05)


def test_rates_act_through_the_time_from_the_reference():
    model = ORBITAL
    rows, cols = model.shape
    g = model.backproject([0.0, rows - 1.0], [cols / 2, cols / 2], 0.0)
    r0, _ = model.project(*g)
    r1, _ = model.with_parameters({"dp_along_rate": 100.0}).project(*g)
    dt = model.line_times.time(r0) - model.line_times.reference_time_s
    np.testing.assert_allclose(r1 - r0, -100.0 * dt / GSD, rtol=0.05)


def test_sensor_state_applies_the_corrections():
    base = ORBITAL
    moved = base.with_parameters({"dp_radial": 10.0, "yaw_bias": 1e-3})
    p0, v0, r0 = base.sensor_state(base.line_times.reference_row)
    p1, v1, r1 = moved.sensor_state(base.line_times.reference_row)
    assert np.linalg.norm(p1) - np.linalg.norm(p0) == pytest.approx(10.0, abs=1e-6)
    np.testing.assert_allclose(v1, v0)
    np.testing.assert_allclose(r1, r0 @ rotation_xyz(0, 0, 1e-3), atol=1e-15)
    p, v, r = base.sensor_state(np.zeros((2, 3)))
    assert p.shape == v.shape == (2, 3, 3) and r.shape == (2, 3, 3, 3)
    np.testing.assert_allclose(p0, base.ephemeris.at(base.line_times.reference_time_s)[0])


def test_with_parameters_accepts_a_mapping_and_keeps_sigmas():
    params = ORBITAL.parameters.with_sigmas(np.full(12, 2.0))
    model = ORBITAL.replace(parameters=params).with_parameters({"roll_bias": 1e-5})
    assert model.parameters["roll_bias"] == 1e-5
    assert np.all(model.parameters.sigmas == 2.0)
    assert model.parameters.names == PARAMETER_NAMES


# ============================================================================ bad inputs
def _parts():
    m = ORBITAL
    return m.ephemeris, m.attitude, m.look, m.line_times


@pytest.mark.parametrize(("build", "field"), [
    (lambda: Ephemeris([0.0, 1.0, 1.0], np.zeros((3, 3)), np.zeros((3, 3))), "Ephemeris.time_s"),
    (lambda: Ephemeris([0.0], np.zeros((1, 3)), np.zeros((1, 3))), "Ephemeris.time_s"),
    (lambda: Ephemeris([0.0, 1.0], np.zeros((2, 2)), np.zeros((2, 3))), "Ephemeris.position_m"),
    (lambda: Ephemeris([0.0, 1.0], np.zeros((2, 3)), [[0, 0, 0], [0, np.nan, 0]]),
     "Ephemeris.velocity_m_s"),
    (lambda: Ephemeris([0.0, 1.0], np.zeros((3, 3)), np.zeros((3, 3))), "Ephemeris.position_m"),
    (lambda: Attitude([0.0], [[1.0, 0, 0, 0]], frame="eci"), "Attitude.frame"),
    (lambda: Attitude([0.0], [[2.0, 0, 0, 0]]), "Attitude.quaternion"),
    (lambda: Attitude([1.0, 0.0], [[1.0, 0, 0, 0]] * 2), "Attitude.time_s"),
    (lambda: LookDirections.from_tan_angles([0, 0, 0], [0.0, 0.1, 0.05]), "LookDirections"),
    (lambda: LookDirections([[0, 0, -1.0], [0, 0.1, -1.0]]), "LookDirections"),
    (lambda: LineTimes(0.0, 0.0, 0.0), "LineTimes.line_period_s"),
    (lambda: LineTimes(0.0, np.nan, 1.0), "LineTimes.reference_time_s"),
    (lambda: LinescanModel((800, 999), *_parts()), "look-direction table has 1000 detectors, "
                                                    "the image has 999 columns"),
    (lambda: LinescanModel((800, 1000), *_parts(), height_range=(10.0, 0.0)), "height_range"),
    (lambda: LinescanModel((800, 1000), *_parts(),
                           parameters=ParameterSet(("roll",), [0.0])), "roll"),
    (lambda: LinescanModel((800, 1000), _parts()[1], *_parts()[1:]), "LinescanModel.ephemeris"),
])
def test_bad_inputs_raise_naming_the_field(build, field):
    with pytest.raises(GeoblockError, match=field.replace("(", r"\(")):
        build()


def test_from_dict_errors_are_serialization_errors():
    data = ORBITAL.to_dict()
    del data["ephemeris"]
    with pytest.raises(SerializationError, match="ephemeris"):
        LinescanModel.from_dict(data)
    data = ORBITAL.to_dict()
    data["line_times"]["line_period_s"] = 0.0  # (a negative period is a reverse scan)
    with pytest.raises(SerializationError, match="line_period_s"):
        LinescanModel.from_dict(data)


# ============================================================================ serialisation
def test_json_round_trip_through_geoblock_io(tmp_path):
    path = write_model(CORRECTED, tmp_path / "scene.json")
    back = open_model(path)
    assert type(back) is LinescanModel
    assert back == CORRECTED
    assert back.to_dict() == json.loads(json.dumps(CORRECTED.to_dict()))
    g = _centre_ground(CORRECTED)
    np.testing.assert_array_equal(back.project(*g), CORRECTED.project(*g))
    assert back.epoch == CORRECTED.epoch and back.attitude.frame == "orbital"


def test_geodetic_helpers_agree():
    # sanity of the example: the scene centre is near Nice and the GSD is ~2.5 m
    g = _centre_ground(ORBITAL)
    assert abs(float(g.lat) - 43.7) < 1.0
    a = np.stack(coords.geodetic_to_ecef(*ORBITAL.backproject(400, 500, 0.0)))
    b = np.stack(coords.geodetic_to_ecef(*ORBITAL.backproject(400, 501, 0.0)))
    c = np.stack(coords.geodetic_to_ecef(*ORBITAL.backproject(401, 500, 0.0)))
    assert np.linalg.norm(b - a) == pytest.approx(GSD / np.cos(0.05) ** 2, rel=0.02)
    assert np.linalg.norm(c - a) == pytest.approx(GSD, rel=0.02)
