"""Tests of the example plugin: geoblock's conformance kit plus the plugin's own format tests."""

from __future__ import annotations

# --8<-- [start:contract]
import numpy as np
import pytest
from geoblock_example import FrameCamera, read_frame_file, sample_file

import geoblock
from geoblock.errors import ModelFormatError, UnsupportedFormatError
from geoblock.testing import SensorModelContract, check_sensor_model


# --- the contract: one test per check, run on every model the fixture gives -------------------
class TestFrameCamera(SensorModelContract):
    @pytest.fixture
    def model(self):
        return FrameCamera.example()


class TestFrameCameraFromFile(SensorModelContract):
    @pytest.fixture
    def model(self):
        return read_frame_file(sample_file())


def test_check_sensor_model_accepts_a_tilted_camera():
    check_sensor_model(FrameCamera.example().with_parameters([5.0, -3.0, 2.0, 0.05, 0.03, 1.2]))
# --8<-- [end:contract]


# --- the model's own geometry --------------------------------------------------------------------
def test_nadir_camera_images_the_point_below_at_the_principal_point():
    cam = FrameCamera(
        (100, 200), 1000.0, (49.5, 99.5), (7.0, 45.0, 10_000.0), height_range=(0, 100)
    )
    row, col = cam.project(7.0, 45.0, 0.0)
    assert float(row) == pytest.approx(49.5, abs=1e-9)
    assert float(col) == pytest.approx(99.5, abs=1e-9)


def test_nadir_camera_is_north_up_east_right():
    cam = FrameCamera(
        (100, 200), 1000.0, (49.5, 99.5), (7.0, 45.0, 10_000.0), height_range=(0, 100)
    )
    row_n, col_n = cam.project(7.0, 45.001, 0.0)
    row_e, col_e = cam.project(7.001, 45.0, 0.0)
    assert row_n < 49.5 and col_n == pytest.approx(99.5, abs=1e-6)
    assert col_e > 99.5 and row_e == pytest.approx(49.5, abs=1e-3)


def test_points_behind_the_camera_are_nan_with_a_status():
    cam = FrameCamera.example()
    (row, col), status = cam.project_with_status(7.05, 43.70, 500_000.0)
    assert np.isnan(row) and np.isnan(col)
    assert status == geoblock.Status.OUT_OF_DOMAIN


def test_parameters_have_units_and_apriori_sigmas():
    params = FrameCamera.example().parameters
    assert params.names == ("east_offset", "north_offset", "up_offset", "omega", "phi", "kappa")
    assert params.units == ("m", "m", "m", "rad", "rad", "rad")
    assert np.all(np.isfinite(params.sigmas))


def test_rejects_a_height_range_above_the_camera():
    with pytest.raises(ModelFormatError, match="below the projection centre"):
        FrameCamera((10, 10), 100.0, (4.5, 4.5), (0.0, 0.0, 1000.0), height_range=(0, 2000))


def test_view_angle_is_vectorised_with_nan_and_a_warning_for_points_behind():
    cam = FrameCamera(
        (100, 200), 1000.0, (49.5, 99.5), (7.0, 45.0, 10_000.0), height_range=(0, 100)
    )
    assert float(cam.view_angle(7.0, 45.0, 0.0)) == pytest.approx(0.0, abs=1e-6)
    # 10 km below and ~7.9 km east: atan(7.9 / 10)
    assert float(cam.view_angle(7.1, 45.0, 0.0)) == pytest.approx(38.2, abs=0.1)
    assert cam.view_angle([7.0, 7.1], [[45.0], [45.1]], 0.0).shape == (2, 2)
    with pytest.warns(geoblock.errors.OutOfBoundsWarning, match="1 of 3"):
        angles = cam.view_angle([7.0, 7.0, np.nan], 45.0, [0.0, 20_000.0, 0.0])
    assert np.isfinite(angles[0]) and np.isnan(angles[1:]).all()
    with pytest.raises(geoblock.errors.ShapeMismatchError, match="lon"):
        cam.view_angle([7.0, 7.1], [45.0, 45.1, 45.2], 0.0)


# --- the *.frame format through geoblock.open_model ---------------------------------------------
def test_open_model_reads_the_sample_file():
    model = geoblock.open_model(sample_file())
    assert isinstance(model, FrameCamera)
    assert model == read_frame_file(sample_file())
    assert model.shape == (1100, 1650)


def test_open_model_with_another_model_name_does_not_read_it():
    with pytest.raises(UnsupportedFormatError):
        geoblock.open_model(sample_file(), model="linescan")  # core's own, always registered


def test_a_frame_file_missing_a_field_is_a_model_format_error(tmp_path):
    bad = tmp_path / "bad.frame"
    text = sample_file().read_text(encoding="utf-8")
    bad.write_text("\n".join(ln for ln in text.splitlines() if not ln.startswith("centre")))
    with pytest.raises(ModelFormatError, match="'centre'"):
        geoblock.open_model(bad)


@pytest.mark.parametrize(("old", "new", "field", "problem"), [
    ("rows = 1100", "rows = many", "rows", "must be an integer"),
    ("principal_point = 549.5 824.5", "principal_point = 549.5", "principal_point",
     "expected 2 numbers"),
    ("attitude = 0.02 -0.01 0.3", "attitude = 0.02 nan 0.3", "attitude", "not finite"),
    ("centre = 7.05 43.70 475000", "centre = 7.05 43.70 400", None, "below the projection"),
])
def test_malformed_fields_are_named(tmp_path, old, new, field, problem):
    text = sample_file().read_text(encoding="utf-8")
    assert old in text
    bad = tmp_path / "bad.frame"
    bad.write_text(text.replace(old, new))
    with pytest.raises(ModelFormatError, match=problem) as info:
        geoblock.open_model(bad)
    assert str(bad) in str(info.value)
    if field is not None:
        assert f"field {field!r}" in str(info.value)


def test_a_corner_based_principal_point_is_converted_once(tmp_path):
    text = sample_file().read_text(encoding="utf-8")
    corner = tmp_path / "corner.frame"
    corner.write_text(text.replace("principal_point = 549.5 824.5", "principal_point = 550 825")
                      + "pixel_origin = corner\n")
    assert geoblock.open_model(corner) == geoblock.open_model(sample_file())


def test_other_text_files_are_left_to_other_plugins(tmp_path):
    other = tmp_path / "notes.frame"
    other.write_text("format = something-else\n")
    with pytest.raises(UnsupportedFormatError):
        geoblock.open_model(other)


def test_model_json_round_trip(tmp_path):
    model = geoblock.open_model(sample_file())
    path = geoblock.write_model(model, tmp_path / "cam.json")
    assert geoblock.open_model(path) == model
