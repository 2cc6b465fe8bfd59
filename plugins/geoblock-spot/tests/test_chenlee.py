"""Chen & Lee's (1993) SPOT model, its mba set, the fit to other models, and the paper's
bundle-adjustment experiment reproduced on a simulated SPOT 1A scene."""

from __future__ import annotations

import math

import numpy as np
import pytest
from geoblock_spot.chenlee import (
    COEFFICIENT_NAMES,
    MBA_NAMES,
    SPOT_LOCATION_ACCURACY_M,
    TABLE1_COEFFICIENTS,
    ChenLeeModel,
    Interior,
    rotation_matrix,
)
from geoblock_spot.fit import fit_chenlee

import geoblock
from geoblock import Status, coords
from geoblock.adjust import ControlPoints, resect
from geoblock.errors import ModelFormatError, SerializationError
from geoblock.plugins import from_dict
from geoblock.testing import SensorModelContract
from geoblock.testing.synthetic import ConstantVelocityPushbroom


@pytest.fixture(scope="module")
def table1() -> ChenLeeModel:
    return ChenLeeModel.table1()


# ---------------------------------------------------------------------- the published equations
def test_table1_holds_the_papers_values():
    c = dict(zip(COEFFICIENT_NAMES, TABLE1_COEFFICIENTS, strict=True))
    assert c["x0"] == -35164.57 and c["y1"] == -1577.94 and c["z2"] == -0.52
    assert c["omega0"] == pytest.approx(math.radians(10.399883), abs=1e-15)
    assert c["phi1"] == pytest.approx(math.radians(-0.000291), abs=1e-18)
    assert c["kappa2"] == pytest.approx(math.radians(0.000039), abs=1e-18)
    assert c["sy"] == 1.0


def test_rotation_is_r3_kappa_r2_phi_r1_omega():
    omega, phi, kappa = 0.3, -0.2, 1.1
    r1 = np.array([[1, 0, 0], [0, math.cos(omega), math.sin(omega)],
                   [0, -math.sin(omega), math.cos(omega)]])
    r2 = np.array([[math.cos(phi), 0, -math.sin(phi)], [0, 1, 0],
                   [math.sin(phi), 0, math.cos(phi)]])
    r3 = np.array([[math.cos(kappa), math.sin(kappa), 0], [-math.sin(kappa), math.cos(kappa), 0],
                   [0, 0, 1]])
    np.testing.assert_allclose(rotation_matrix(omega, phi, kappa), r3 @ r2 @ r1, atol=1e-15)


def _collinearity(model: ChenLeeModel, p: np.ndarray, t: float) -> tuple[float, float]:
    """Chen & Lee eq. 2 evaluated directly: (x, Sy * y) in metres at time t."""
    c = model.coefficients
    pos = np.array([c[0] + c[1] * t + c[2] * t * t, c[3] + c[4] * t + c[5] * t * t,
                    c[6] + c[7] * t + c[8] * t * t])
    ang = [c[9 + 3 * k] + c[10 + 3 * k] * t + c[11 + 3 * k] * t * t for k in range(3)]
    u = rotation_matrix(*ang) @ (p - pos)
    f = model.interior.focal_length_m
    return -f * u[0] / u[2], -f * u[1] / u[2]


def test_projection_satisfies_equations_1_2_and_6(table1):
    """row = t / 0.0015 with x(t) = 0; col = paper's pixel number - 1 with
    y = (pixel_no - (N + 1) / 2) * 13 um."""
    rng = np.random.default_rng(3)
    g = table1.backproject(rng.uniform(0, 5999, 5), rng.uniform(0, 5999, 5),
                           rng.uniform(0, 3000, 5))
    row, col = table1.project(g.lon, g.lat, g.h)
    p = np.stack(table1.frame.from_geodetic(g.lon, g.lat, g.h), axis=-1)  # (5, 3) work frame
    for i in range(5):
        x, sy_y = _collinearity(table1, p[i], row[i] * 0.0015)
        assert abs(x) < 1e-12  # metres in the focal plane: 1e-7 px
        pixel_no = col[i] + 1.0
        assert sy_y == pytest.approx((pixel_no - 6001 / 2) * 13e-6, abs=1e-14)


def test_centre_pixel_looks_along_the_view_axis(table1):
    """Paper pixel (N + 1) / 2 (y = 0) is geoblock col (N - 1) / 2 = 2999.5."""
    g = table1.backproject(1000.0, 2999.5, 0.0)
    p = np.stack(table1.frame.from_geodetic(g.lon, g.lat, g.h), axis=-1)
    t = 1000 * 0.0015
    _, sy_y = _collinearity(table1, p, t)
    assert abs(sy_y) < 1e-12


def test_table1_scene_lies_in_central_west_taiwan(table1):
    g = table1.backproject(2999.5, 2999.5, 0.0)
    assert 120.6 < g.lon < 120.9 and 24.3 < g.lat < 24.5
    # 10 m pixels, flying SSW as a descending SPOT pass
    a = table1.backproject([3000.0, 3001.0, 3000.0], [3000.0, 3000.0, 3001.0], 0.0)
    de, dn, _ = coords.enu_offsets(a.lon[0], a.lat[0], 0.0, a.lon, a.lat, 0.0)
    assert 9.5 < math.hypot(de[1], dn[1]) < 10.5 and 9.5 < math.hypot(de[2], dn[2]) < 10.5
    assert 190 < math.degrees(math.atan2(de[1], dn[1])) % 360 < 197


def test_work_frame_axes():
    enu = coords.LocalFrame(10.0, 45.0, 100.0)  # azimuth 90: X east, Y north, Z up
    np.testing.assert_allclose(enu.rotation, coords.enu_rotation(10.0, 45.0), atol=1e-15)
    south = coords.LocalFrame(10.0, 45.0, 100.0, 180.0)  # X south, Y east
    east, north, up = coords.enu_rotation(10.0, 45.0)
    np.testing.assert_allclose(south.rotation, np.stack([-north, east, up]), atol=1e-15)
    p = south.from_geodetic(10.01, 45.02, 300.0)
    g = south.to_geodetic(*p)
    assert g.lon == pytest.approx(10.01, abs=1e-12) and g.h == pytest.approx(300.0, abs=1e-7)


def test_the_model_works_in_a_local_frame_and_its_json_layout_is_unchanged(table1):
    assert type(table1.frame) is coords.LocalFrame
    assert table1.frame == coords.LocalFrame(121.91, 24.62, 0.0, 180.0)
    # the 0.1 JSON layout of the frame (WorkFrame.to_dict) still loads, and is still written
    data = table1.to_dict()
    assert data["frame"] == {"lon0": 121.91, "lat0": 24.62, "h0": 0.0, "azimuth_deg": 180.0}
    assert ChenLeeModel.from_dict(data) == table1
    data["frame"] = {"lon0": 121.91, "lat0": 24.62}  # h0 and azimuth_deg default
    assert ChenLeeModel.from_dict(data).frame == coords.LocalFrame(121.91, 24.62)
    data["frame"] = {"lon0": 121.91, "lat0": 124.62, "h0": 0.0}
    with pytest.raises(SerializationError, match="lat0"):
        ChenLeeModel.from_dict(data)
    with pytest.raises(ModelFormatError, match="LocalFrame"):
        ChenLeeModel(TABLE1_COEFFICIENTS, (121.91, 24.62))


def test_work_frame_is_a_deprecated_local_frame_with_the_old_methods(table1):
    from geoblock.errors import GeoblockDeprecationWarning

    with pytest.warns(GeoblockDeprecationWarning, match="LocalFrame"):
        from geoblock_spot.chenlee import WorkFrame

        old = WorkFrame(121.91, 24.62, 0.0, 180.0)
    assert isinstance(old, coords.LocalFrame)
    p = old.from_geodetic([121.9, 122.0], [24.6, 24.7], [0.0, 10.0])  # (..., 3) as in 0.1
    assert p.shape == (2, 3)
    np.testing.assert_array_equal(p, np.stack(table1.frame.from_geodetic(
        [121.9, 122.0], [24.6, 24.7], [0.0, 10.0]), axis=-1))
    assert old.to_geodetic(p).h == pytest.approx([0.0, 10.0], abs=1e-7)
    np.testing.assert_allclose(old.to_ecef(old.from_ecef(old.to_ecef(p))), old.to_ecef(p))
    model = ChenLeeModel(TABLE1_COEFFICIENTS, old)
    assert type(model.frame) is coords.LocalFrame and model == table1


# ---------------------------------------------------------------------- convergence and domain
@pytest.mark.parametrize("h", [-500.0, 9000.0])
def test_ground_to_image_converges_over_the_whole_scene(table1, h):
    """Every 20th pixel of the 6000 x 6000 scene (pixel edges included), heights -500 and
    9000 m: Newton on the sampling time converges and inverts backprojection to 1e-6 px."""
    r = np.r_[-0.5, np.arange(0.0, 6000.0, 20.0), 5999.5]
    rr, cc = np.meshgrid(r, r, indexing="ij")
    g, s = table1.backproject_with_status(rr, cc, h)
    assert np.all(s == Status.CONVERGED)
    (row, col), status = table1.project_with_status(g.lon, g.lat, g.h)
    assert np.all(status == Status.CONVERGED)
    assert np.max(np.hypot(row - rr, col - cc)) < 1e-6


def test_points_off_the_scene_get_statuses(table1):
    lon = np.array([120.75, 120.75, 120.75, -59.25, 100.0, 120.75, np.nan])
    lat = np.array([26.9, 21.9, 24.4, -24.4, 24.4, 24.4, 24.4])
    h = np.array([0.0, 0.0, 2.0e6, 0.0, 0.0, 0.0, 0.0])
    # 2.5 degrees north and south: beyond two scene lengths along track; above the sensor;
    # the antipode (behind the Earth); 20 degrees west (beyond 45 degrees across track)
    (row, col), status = table1.project_with_status(lon, lat, h)
    assert status.tolist() == [Status.OUT_OF_DOMAIN] * 5 + [Status.CONVERGED, Status.INVALID_INPUT]
    assert np.isnan(row[:5]).all() and np.isfinite(row[5])
    with pytest.warns(geoblock.errors.OutOfBoundsWarning, match="5 of 7"):
        table1.project(lon, lat, h)
    # image -> ground: rows beyond the domain, columns beyond 45 degrees, a surface above
    # the sensor
    _, status = table1.backproject_with_status([-20000.0, 3000.0, 3000.0], [3000.0, 1e6, 3000.0],
                                               [0.0, 0.0, 1e6])
    assert status.tolist() == [Status.OUT_OF_DOMAIN, Status.OUT_OF_DOMAIN, Status.NO_INTERSECTION]


def test_newton_tolerance_is_tighter_than_the_papers():
    assert ChenLeeModel.time_tolerance_s <= 1e-6


# ---------------------------------------------------------------------- parameter sets
def test_mba_sigmas_follow_the_stated_accuracy(table1):
    s = SPOT_LOCATION_ACCURACY_M[1]
    sig = dict(zip(MBA_NAMES, table1.mba_sigmas(s), strict=True))
    t = 6000 * 0.0015
    assert sig["d_x0"] == sig["d_y0"] == sig["d_z0"] == 350.0
    assert sig["d_y1"] == pytest.approx(350.0 / t) and sig["d_z2"] == pytest.approx(350.0 / t**2)
    slant = 350.0 / sig["d_omega0"]
    assert 830e3 < slant < 860e3  # slant range at 10.4 degrees incidence from 828 km
    assert sig["d_phi0"] == sig["d_omega0"]
    assert sig["d_phi1"] == pytest.approx(sig["d_phi0"] / t)
    half_swath = slant * 3000 * 13e-6 / 1.082
    assert sig["d_kappa0"] == pytest.approx(350.0 / half_swath)
    assert sig["d_sy"] == pytest.approx(350.0 / half_swath)


def test_mba_set_is_corrections_to_the_coefficients(table1):
    mba = table1.mba(350.0)
    assert mba.parameters.names == MBA_NAMES
    assert np.all(mba.parameters.values == 0) and np.all(np.isfinite(mba.parameters.sigmas))
    assert mba.parameters.units[:3] == ("m", "m/s", "m/s^2") and mba.parameters.units[-1] == "1"
    values = np.zeros(19)
    values[COEFFICIENT_NAMES.index("y0")] = 25.0
    moved = mba.with_parameters(values)
    np.testing.assert_array_equal(moved.nominal_coefficients, TABLE1_COEFFICIENTS)
    assert moved.coefficients[3] == TABLE1_COEFFICIENTS[3] + 25.0
    folded = moved.with_parameter_set("coefficients")
    assert folded.parameters.names == COEFFICIENT_NAMES
    g = table1.backproject([10.0, 5000.0], [20.0, 4000.0], [0.0, 900.0])
    np.testing.assert_allclose(np.stack(folded.project(g.lon, g.lat, g.h)),
                               np.stack(moved.project(g.lon, g.lat, g.h)), atol=1e-9)
    assert np.all(np.isinf(folded.parameters.sigmas))


def test_json_round_trip_through_the_registry(table1, tmp_path):
    mba = table1.mba(350.0).with_parameters(np.linspace(-1e-6, 1e-6, 19))
    again = from_dict(mba.to_dict())
    assert type(again) is ChenLeeModel and again == mba and again.parameter_set == "mba"
    path = geoblock.write_model(mba, tmp_path / "spot.json")
    assert geoblock.open_model(path) == mba
    assert "spot-chenlee" in geoblock.plugins.get_registry()


def test_bad_input_raises_errors_naming_the_field(table1):
    with pytest.raises(ModelFormatError, match="19 finite values"):
        ChenLeeModel(np.zeros(18), table1.frame)
    with pytest.raises(ModelFormatError, match="parameter_set"):
        ChenLeeModel(TABLE1_COEFFICIENTS, table1.frame, parameter_set="dg")
    with pytest.raises(ModelFormatError, match="pixel_size_m"):
        Interior(pixel_size_m=0.0)
    data = table1.to_dict()
    del data["frame"]
    with pytest.raises(SerializationError, match="frame"):
        ChenLeeModel.from_dict(data)


# ---------------------------------------------------------------------- conformance kit
class TestChenLeeContract(SensorModelContract):
    check_options = {"n": 4}
    parameter_set_options = {"mba": {"accuracy_m": 350.0}}

    @pytest.fixture(params=["coefficients", "mba", "mba-spot5-moved"])
    def model(self, request):
        base = ChenLeeModel.table1()
        if request.param == "coefficients":  # Table 1, with SPOT 1A's a-priori sigmas
            return base.with_parameter_set("coefficients", sigmas=base.mba_sigmas(350.0))
        if request.param == "mba":
            return base.mba(350.0)
        moved = base.mba(50.0)
        return moved.with_parameters(0.3 * moved.parameters.sigmas)


class TestChenLeeFreeCoefficients(SensorModelContract):
    """The published form with free coefficients (no a-priori sigma)."""

    check_options = {"n": 4}
    parameter_set_options = {"mba": {"accuracy_m": 350.0}}

    @pytest.fixture
    def model(self):
        return ChenLeeModel.table1()

    @pytest.mark.skip(reason="for a free parameter the check probes a step of 1e-3 parameter "
                      "units: for phi2 that is a pitch excursion of 4.6 degrees over the scene, "
                      "after which no time images most of the scene; the analytic partials "
                      "are checked by test_parameter_partials and with finite sigmas above")
    def test_parameter_perturbation(self, model): ...


# ---------------------------------------------------------------------- MBA on Chen & Lee's scene
def _terrain(lon, lat):
    """Smooth relief from 0 to 950 m over the scene (Chen & Lee's check points span 950 m)."""
    x, y = (lon - 120.75) / 0.3, (lat - 24.40) / 0.3
    return 475.0 + 475.0 * np.sin(1.7 * x + 0.4) * np.cos(1.3 * y - 0.3)


def _control(truth, n_rows, n_cols, prefix, rng):
    """Points on a jittered n_rows x n_cols grid over the image, on the terrain, with 0.2 px
    image pointing noise and 1 m ground noise (east, north, up)."""
    r = (np.arange(n_rows) + rng.uniform(0.1, 0.9, n_rows)) * 6000 / n_rows - 0.5
    c = (np.arange(n_cols) + rng.uniform(0.1, 0.9, n_cols)) * 6000 / n_cols - 0.5
    rr, cc = (a.ravel() for a in np.meshgrid(r, c, indexing="ij"))
    h = np.full(rr.shape, 475.0)
    for _ in range(15):  # ray / terrain intersection by fixed point (10 degrees incidence)
        g = truth.backproject(rr, cc, h)
        h = _terrain(g.lon, g.lat)
    g = truth.backproject(rr, cc, h)
    xyz = np.stack(coords.geodetic_to_ecef(g.lon, g.lat, g.h), axis=-1)
    noise_enu = rng.normal(0, 1.0, (rr.size, 3))
    xyz += np.einsum("nij,ni->nj", coords.enu_rotation(g.lon, g.lat), noise_enu)
    noisy = coords.ecef_to_geodetic(*xyz.T)
    return ControlPoints([f"{prefix}{i}" for i in range(rr.size)], noisy.lon, noisy.lat, noisy.h,
                         rr + rng.normal(0, 0.2, rr.size), cc + rng.normal(0, 0.2, cc.size),
                         sigma_row=0.2, sigma_col=0.2, sigma_e=1.0, sigma_n=1.0, sigma_h=1.0)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_mba_resection_reproduces_chen_and_lee_tables_2_and_5(table1, seed):
    """21 GCPs and 24 check points over 950 m of relief, the orientation of Table 1 as truth,
    a start perturbed by SPOT 1A's stated accuracy (350 m): the image residuals at the GCPs
    are ~0.2 px RMS (Table 2: 0.19 / 0.18 px) and the check points are within Table 5's
    0.61 / 0.45 px."""
    rng = np.random.default_rng(seed)
    gcps = _control(table1, 3, 7, "gcp", rng)
    ckps = _control(table1, 4, 6, "ckp", rng)
    assert np.ptp(np.r_[gcps.h, ckps.h]) > 800
    sig = table1.mba_sigmas(350.0)
    start = ChenLeeModel(table1.coefficients + rng.normal(0, 1, 19) * sig, table1.frame).mba(350.0)
    (r0, c0) = start.project(gcps.lon, gcps.lat, gcps.h)
    assert np.max(np.hypot(r0 - gcps.row, c0 - gcps.col)) > 20  # tens of pixels off at start
    result = resect(start, gcps, ckps)
    assert result.converged and result.names == MBA_NAMES
    gcp_row, gcp_col = result.gcp.rmse_px
    ckp_row, ckp_col = result.icp.rmse_px
    assert 0.1 < gcp_row < 0.3 and 0.1 < gcp_col < 0.3
    assert ckp_row < 0.61 and ckp_col < 0.61
    assert 0.5 < result.sigma0 < 1.5


# ---------------------------------------------------------------------- fitting other models
def test_fit_reproduces_a_constant_velocity_pushbroom():
    """The synthetic pushbroom does not publish its interior: given explicitly (its
    ``example``'s 2.5 m pixels from 700 km at 7 km/s)."""
    interior = Interior(pixel_size_m=1.082 * 2.5 / 700e3, focal_length_m=1.082,
                        line_period_s=2.5 / 7000.0)
    fit = fit_chenlee(ConstantVelocityPushbroom.example(roll=0.1), interior=interior)
    assert fit.interior_source == "given" and fit.model.interior == interior
    assert fit.model.coefficients[18] == pytest.approx(1.0, abs=1e-6)  # Sy: the right pixel
    assert fit.converged and fit.iterations <= 5
    assert fit.max_px < 1e-6 and fit.check_max_px < 1e-6
    assert fit.n_points == 15 * 15 * 5


def test_fit_recovers_chen_and_lee_coefficients(table1):
    truth = table1.with_parameters(TABLE1_COEFFICIENTS * (1 + 1e-4 * np.sin(np.arange(19))))
    fit = fit_chenlee(truth, frame=truth.frame, location_accuracy_m=350.0)
    assert fit.max_px < 1e-6
    assert fit.model.parameter_set == "mba" and np.all(np.isfinite(fit.model.parameters.sigmas))
    coefficients = fit.model.coefficients
    assert np.max(np.abs(coefficients[:9] - truth.coefficients[:9])) < 1e-3  # metres
    assert np.max(np.abs(coefficients[9:12] - truth.coefficients[9:12])) < 1e-9  # radians
    assert coefficients[18] == pytest.approx(truth.coefficients[18], abs=1e-9)


def _spot_like_linescan():
    """A SPOT 1A geometry built by hand on the core's generic linescan model: circular
    822 km orbit heading 192 degrees over Taiwan, 10 degrees of roll in the orbital frame,
    6000 pinhole detectors of 13 um behind 1082 mm, 1.5 ms per line."""
    ls = pytest.importorskip("geoblock.models.linescan")
    alt = 822e3
    lon0, lat0 = math.radians(120.7), math.radians(24.4)
    centre = np.array([math.cos(lat0) * math.cos(lon0), math.cos(lat0) * math.sin(lon0),
                       math.sin(lat0)])
    enu = coords.enu_rotation(120.7, 24.4)
    heading = math.radians(192.0)
    along = math.sin(heading) * enu[0] + math.cos(heading) * enu[1]
    radius = coords.WGS84_A + alt
    omega = math.sqrt(3.986004418e14 / radius**3)
    t = np.arange(-10.0, 11.0, 1.0)
    ang = omega * t
    pos = radius * (np.cos(ang)[:, None] * centre + np.sin(ang)[:, None] * along)
    vel = radius * omega * (-np.sin(ang)[:, None] * centre + np.cos(ang)[:, None] * along)
    rot = ls.rotation_xyz(math.radians(10.0), 0.002, 0.001)
    attitude = ls.Attitude(np.array([0.0]), ls.matrix_to_quaternion(rot)[None], frame="orbital")
    c = np.arange(6000) - 2999.5
    look = ls.LookDirections.from_tan_angles(np.zeros(6000), c * 13e-6 / 1.082)
    return ls.LinescanModel((6000, 6000), ls.Ephemeris(t, pos, vel), attitude, look,
                            ls.LineTimes(2999.5, 0.0, 1.5e-3), height_range=(-500.0, 4000.0))


def test_fit_to_a_hand_built_linescan_model():
    source = _spot_like_linescan()
    fit = fit_chenlee(source)
    assert fit.converged
    assert fit.max_px < 0.01 and fit.check_max_px < 0.01
    g = source.backproject([0.0, 5999.0], [0.0, 5999.0], [0.0, 3000.0])
    row, col = fit.model.project(g.lon, g.lat, g.h)
    np.testing.assert_allclose(row, [0.0, 5999.0], atol=0.01)
    np.testing.assert_allclose(col, [0.0, 5999.0], atol=0.01)


def test_fit_reports_what_the_polynomial_form_cannot_represent():
    """LinescanModel.example() has detectors curved along track and a 0.3 Hz attitude
    wobble: the fit error says so instead of hiding it."""
    ls = pytest.importorskip("geoblock.models.linescan")
    fit = fit_chenlee(ls.LinescanModel.example(), interior=Interior(2.5e-6, 0.7, 1.5e-3))
    assert fit.converged
    assert 1.0 < fit.max_px < 20.0 and fit.rms_px < fit.max_px
