"""The DIMAP line-of-sight model: frames, the products' own geolocation, DG set, conformance."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
import pytest
from geoblock_spot.dimap import DimapFormatError, read_dimap
from geoblock_spot.los import (
    AXIS_PERMUTATION,
    DG_ADJUSTABLE,
    dg_parameters,
    geolocation_check,
    handbook_rotation,
    simplified_model_check,
    spot_dimap_model,
)

from geoblock.errors import ModelFormatError
from geoblock.io import open_model, write_model
from geoblock.models.linescan import LinescanModel, orbital_frame
from geoblock.testing import SensorModelContract

SPOT = {i: f"cosicorr3d/test_dataset/SPOT{i}.DIM" for i in range(1, 6)}

#: regression bounds (metres) on the products' corners + centre, as measured (see the table
#: in docs/user-guide/spot.md): SPOT 5 reproduces its DIMAP to 0.05 m; SPOT 1-4 to 3-24 m with
#: the integrated gyro attitude, 1-2 m without it
BOUND_M = {1: 12.0, 2: 5.0, 3: 30.0, 4: 30.0, 5: 0.2}
BOUND_NO_ATTITUDE_M = {1: 3.0, 2: 2.0, 3: 3.0, 4: 3.0}


@pytest.fixture(scope="module")
def dimaps(data_dir):
    return {i: read_dimap(data_dir / name) for i, name in SPOT.items()}


def _rx(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def _ry(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def _rz(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def test_handbook_rotation_is_cosicorr_rotation_order():
    """ASP/OSSIM's eq. 11 entries == COSI-Corr's Rx(-pitch) Ry(-roll) Rz(yaw)."""
    yaw, pitch, roll = 0.3, -0.2, 0.1
    np.testing.assert_allclose(handbook_rotation(yaw, pitch, roll),
                               _rx(-pitch) @ _ry(-roll) @ _rz(yaw), atol=1e-15)
    a = AXIS_PERMUTATION
    assert np.linalg.det(a) == 1.0 and np.array_equal(a @ a, np.eye(3))


@pytest.mark.parametrize("mission", [1, 5])
def test_line_of_sight_is_the_handbooks(dimaps, mission):
    """Independent handbook formula: u = [X2 Y2 Z2] M normalize(-tan psi_y, tan psi_x, -1),
    with the orbital frame from the DIMAP velocity as given (inertial for SPOT 1-4)."""
    d = dimaps[mission]
    model = spot_dimap_model(d, parameters="linescan")
    rows, cols = d.shape
    row, col = np.array([0.0, rows / 3, rows - 1.0]), np.array([0.0, cols / 2, cols - 1.0])
    pos, vel_ef, rot = model.sensor_state(row)
    u_model = np.einsum("...ij,...j->...i", rot, model.look.at(col))

    t = model.line_times.time(row)
    att_t, ypr, _ = d.attitude_angles()
    angles = np.stack([np.interp(t, att_t, ypr[:, k]) for k in range(3)], axis=-1)
    m = handbook_rotation(angles[:, 0], angles[:, 1], angles[:, 2])
    v_given = vel_ef if d.velocity_frame == "earth-fixed" else (
        vel_ef + 7.2921151467e-5 * np.stack([-pos[:, 1], pos[:, 0], 0 * pos[:, 0]], axis=-1))
    z2 = pos / np.linalg.norm(pos, axis=-1, keepdims=True)
    x2 = np.cross(v_given, z2)
    x2 /= np.linalg.norm(x2, axis=-1, keepdims=True)
    y2 = np.cross(z2, x2)
    frame = np.stack([x2, y2, z2], axis=-1)
    psi_x, psi_y = d.look_angles()
    u1 = np.stack([-np.tan(psi_y[col.astype(int)]), np.tan(psi_x[col.astype(int)]),
                   -np.ones(3)], axis=-1)
    u1 /= np.linalg.norm(u1, axis=-1, keepdims=True)
    u_handbook = np.einsum("...ij,...jk,...k->...i", frame, m, u1)
    # slerp vs linear angle interpolation and the Hermite velocity: < 1e-8 rad
    np.testing.assert_allclose(u_model, u_handbook, atol=1e-8)
    # and geoblock's orbital frame is the handbook's with axes (Y2, X2, -Z2) for SPOT 5
    if d.velocity_frame == "earth-fixed":
        np.testing.assert_allclose(orbital_frame(pos, vel_ef), frame @ AXIS_PERMUTATION,
                                   atol=1e-12)


def test_line_times(dimaps):
    d = dimaps[5]
    model = spot_dimap_model(d)
    assert model.line_times.reference_row == 6000.0  # SCENE_CENTER_LINE 6001, 1-based
    assert model.line_times.time(6000.0) == d.scene_center_time_s
    assert model.line_times.line_period_s == 7.5199643612e-04


@pytest.mark.parametrize("mission", sorted(SPOT))
def test_reproduces_product_geolocation(dimaps, mission):
    """Corner vertices and scene centre within the stated accuracy (and the measured bound)."""
    d = dimaps[mission]
    check = geolocation_check(spot_dimap_model(d), d, tie_points=True)
    assert len(check.label) == 9
    assert np.all(check.error_m < d.location_accuracy_m)
    assert np.all(check.error_m < BOUND_M[mission]), check.summary()
    gsd = 5.0 if mission == 5 else 10.0
    np.testing.assert_allclose(check.error_px, check.error_m / gsd, rtol=0.2, atol=0.01)
    if mission < 5:
        bare = geolocation_check(spot_dimap_model(d, use_attitude=False), d)
        assert np.all(bare.error_m < BOUND_NO_ATTITUDE_M[mission]), bare.summary()


@pytest.mark.parametrize("mission", sorted(SPOT))
def test_simplified_location_model(dimaps, mission):
    """The product's quadratic Direct_Location_Model agrees over the whole image (< 3 px)."""
    d = dimaps[mission]
    worst, rms = simplified_model_check(spot_dimap_model(d), d, n=11)
    assert worst < (0.5 if mission == 5 else 3.0) and rms <= worst


def test_dg_parameters(dimaps):
    d = dimaps[5]
    model = spot_dimap_model(d)
    p = model.parameters
    assert p == dg_parameters(model, 50.0)
    assert [n for n, a in zip(p.names, p.adjustable, strict=True) if a] == list(DG_ADJUSTABLE)
    assert p["dp_along"] == 0.0 and p.sigmas[p.index("dp_along")] == 50.0
    half_t = 0.5 * 12000 * d.line_period_s
    assert p.sigmas[p.index("dp_radial_rate")] == pytest.approx(50.0 / half_t)
    # 50 m at ~832 km slant range: 6e-5 rad, as the mission's 6e-5 rad attitude restitution
    assert p.sigmas[p.index("roll_bias")] == pytest.approx(6.0e-5, rel=0.01)
    # a 1-sigma yaw moves the farthest corner by about the accuracy
    yaw = p.sigmas[p.index("yaw_bias")]
    moved = model.with_parameters({"yaw_bias": yaw})
    g = moved.backproject_ecef([6000.0] * 2, [0.0, 11999.0], 0.0)
    g0 = model.backproject_ecef([6000.0] * 2, [0.0, 11999.0], 0.0)
    shift = np.linalg.norm(np.stack(g, -1) - np.stack(g0, -1), axis=-1)
    assert 0.5 * 50 < shift.max() < 1.05 * 50
    with pytest.raises(ValueError, match="accuracy_m"):
        dg_parameters(model, 0.0)
    assert spot_dimap_model(d, parameters="linescan").parameters.sigmas[0] == np.inf


def test_open_model_and_json_round_trip(data_dir, tmp_path):
    model = open_model(data_dir / SPOT[3])
    assert isinstance(model, LinescanModel)
    path = write_model(model, tmp_path / "spot3.json")
    again = open_model(path)
    lon, lat = np.array([30.9, 31.2]), np.array([40.6, 40.7])
    np.testing.assert_array_equal(again.project(lon, lat, 100.0), model.project(lon, lat, 100.0))
    with pytest.raises(ModelFormatError, match="unknown option"):
        open_model(data_dir / SPOT[3], bogus=1)
    assert open_model(data_dir / SPOT[3], parameters="linescan").parameters.sigmas[0] == np.inf


def test_attitude_must_cover_the_image(data_dir, tmp_path):
    """SPOT 5 with the corrected attitudes cut to the scene's second half is refused."""
    tree = ET.parse(data_dir / SPOT[5])
    parent = tree.getroot().find(
        "Data_Strip/Satellite_Attitudes/Corrected_Attitudes/Corrected_Attitude")
    for angles in parent.findall("Angles")[:60]:  # 0.125 s each: the first 7.5 s
        parent.remove(angles)
    tree.write(tmp_path / "METADATA.DIM", encoding="utf-8", xml_declaration=True)
    with pytest.raises(DimapFormatError, match="Satellite_Attitudes.*does not cover"):
        spot_dimap_model(tmp_path)


class TestSpotDimapContract(SensorModelContract):
    """The conformance kit with the DG parameter set (SPOT 1 inertial-velocity frame, SPOT 5)."""

    check_options = {"n": 4}

    @pytest.fixture(params=[1, 5], ids=["SPOT1-dg", "SPOT5-dg"])
    def model(self, request, data_dir):
        return spot_dimap_model(data_dir / SPOT[request.param])


@pytest.mark.parametrize(("name", "rms_px", "max_px"), [
    ("SPOT1.DIM", 0.45, 0.9), ("SPOT2.DIM", 0.4, 0.8), ("SPOT3.DIM", 0.7, 1.6),
    ("SPOT4.DIM", 0.3, 0.6), ("SPOT5.DIM", 0.15, 0.35),
])
def test_chenlee_fits_each_dimap_model(data_dir, name, rms_px, max_px):
    """fit_chenlee brings the on-board DIMAP model into Chen & Lee's polynomial form (MBA's
    start) with a sub-pixel RMS; the bounds are the figures measured here plus ~20 %."""
    from geoblock_spot.fit import fit_chenlee

    path = data_dir / "cosicorr3d" / "test_dataset" / name
    if not path.exists():
        pytest.skip(f"{path} not in the test data")
    model = open_model(path)
    fit = fit_chenlee(model, heights=np.linspace(0.0, 3000.0, 4))
    assert fit.converged
    assert fit.check_rms_px < rms_px and fit.check_max_px < max_px
    assert fit.rms_px < rms_px


@pytest.mark.parametrize("name", ["SPOT1.DIM", "SPOT5.DIM"])
@pytest.mark.parametrize("h", [-500.0, 0.0, 9000.0])
def test_ground_to_image_converges_over_the_full_scene(data_dir, name, h):
    """Every 40th pixel of the full scene (and the last row), backprojected to h and
    projected back: every point converges, round trip below 1e-8 px."""
    path = data_dir / "cosicorr3d" / "test_dataset" / name
    if not path.exists():
        pytest.skip(f"{path} not in the test data")
    model = open_model(path)
    rows, cols = model.shape
    r, c = np.meshgrid(np.arange(0, rows, 40.0), np.arange(0, cols, 40.0), indexing="ij")
    r = np.concatenate([r.ravel(), np.full(50, rows - 1.0)])
    c = np.concatenate([c.ravel(), np.linspace(0.0, cols - 1.0, 50)])
    (lon, lat, hh), status = model.backproject_with_status(r, c, np.full(r.shape, h))
    assert (status == 0).all()
    (r2, c2), status2 = model.project_with_status(lon, lat, hh)
    assert (status2 == 0).all()
    assert np.max(np.hypot(r2 - r, c2 - c)) < 1e-8


def test_direct_call_refuses_a_bad_height_range_naming_the_file(data_dir):
    path = data_dir / SPOT[3]
    if not path.exists():
        pytest.skip(f"{SPOT[3]} not in the test data")
    for heights in ("abc", (1.0,), (5.0, 1.0)):
        with pytest.raises(DimapFormatError, match="height_range") as info:
            spot_dimap_model(path, height_range=heights)
        assert str(path) in str(info.value)
    from geoblock.errors import ParameterSetError

    with pytest.raises(ParameterSetError, match="parameters must be") as info:
        spot_dimap_model(path, parameters=3)
    assert str(path) in str(info.value)
