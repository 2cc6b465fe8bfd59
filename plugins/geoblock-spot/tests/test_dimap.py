"""The SPOT DIMAP v1 reader: ASP's expected values, pixel conversion, robustness."""

from __future__ import annotations

import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from geoblock_spot.dimap import (
    REQUIRED_FIELDS,
    DimapFormatError,
    SpotDimap,
    is_spot_dimap,
    read_dimap,
)
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from geoblock.errors import GeoblockError, ModelFormatError
from geoblock.io import open_model
from geoblock.models.linescan import LinescanModel

SPOT = {i: f"cosicorr3d/test_dataset/SPOT{i}.DIM" for i in range(1, 6)}
ASP = "stereopipeline/tests/spot_example1.xml"
ALL = [*SPOT.values(), ASP]


def _time(d: SpotDimap, seconds: float) -> np.datetime64:
    """Seconds since the epoch back to a microsecond UTC time."""
    return np.datetime64(d.epoch.rstrip("Z"), "us") + np.timedelta64(round(seconds * 1e6), "us")


@pytest.fixture(scope="module")
def example(data_dir) -> SpotDimap:
    return read_dimap(data_dir / ASP)


# ---------------------------------------------------------------------- ASP's expected values
def test_asp_example_parse_values(example):
    """MANIFEST.md: ASP TestSpotCameraModel.cxx l.33-83 on spot_example1.xml."""
    d = example
    assert d.shape == (96168, 300)  # ASP: size 300 x 96168 (cols x rows)
    # ASP's corners are (col, row) 1-based: (1,1), (300,1), (300,96168), (1,96168)
    expected = [(-75.519946, -76.636309, 0, 0), (-71.924271, -77.389028, 0, 299),
                (-88.569672, -80.241112, 96167, 299), (-91.818476, -79.298919, 96167, 0)]
    for v, (lon, lat, row, col) in zip(d.vertices, expected, strict=True):
        assert (v.lon, v.lat, v.row, v.col) == (lon, lat, row, col)
    assert d.line_period_s == 7.5199705115e-04
    assert _time(d, d.scene_center_time_s) == np.datetime64("2008-03-04T12:31:39.349737")
    assert (d.scene_center_row, d.scene_center_col) == (48084.0, 6000.0)  # ASP: 0-based
    assert (d.psi_x[9], d.psi_y[9]) == (3.4977741700e-01, -7.1264930800e-02)  # angle #10
    att = d.corrected_angles
    assert _time(d, att.time_s[0]) == np.datetime64("2008-03-04T12:31:03.206912")
    assert _time(d, att.time_s[-1]) == np.datetime64("2008-03-04T12:32:15.331747")
    np.testing.assert_array_equal(att.angles[0], [1.1621635280e-03, -9.5496029568e-04,
                                                  -1.7549389832e-05])
    np.testing.assert_array_equal(att.angles[-1], [1.2001004714e-03, -9.5696493468e-04,
                                                   -2.4331461036e-05])
    assert _time(d, d.ephemeris_time_s[0]) == np.datetime64("2008-03-04T12:28:27")
    np.testing.assert_array_equal(d.position_m[0], [1.7495691231e06, -2.2672541162e06,
                                                    -6.6183333707e06])
    np.testing.assert_array_equal(d.velocity_m_s[0], [-6.2538959540e03, 3.1331303950e03,
                                                      -2.7272519760e03])
    assert d.epoch == "2008-03-04T12:28:27.000000Z"
    assert (d.mission, d.instrument, d.profile) == (5, "HRS1", "SPOTSEGMENT_1A")
    assert d.look_detector_col.size == 300 and d.quaternions.shape == (57, 4)


def test_asp_example_full_model_refused(data_dir, example):
    """The crop's 300-entry look table cannot make a model of its 12000-column scene."""
    assert example.scene_width == 12000  # tie points at column 12000, centre column 6001
    with pytest.raises(DimapFormatError, match="doesn't cover the image") as info:
        example.look_angles()
    assert info.value.field.endswith("Look_Angles") and ASP in info.value.path
    with pytest.raises(DimapFormatError, match="300 entries.*12000 columns"):
        open_model(data_dir / ASP)


# ---------------------------------------------------------------------- every file
@pytest.mark.parametrize("name", ALL)
def test_every_spot_file_parses(data_dir, name):
    d = read_dimap(data_dir / name)
    assert is_spot_dimap(data_dir / name)
    rows, cols = d.shape
    assert len(d.vertices) == 4 and d.scene_center is not None
    assert d.ephemeris_time_s.size >= 8 and np.all(np.diff(d.ephemeris_time_s) > 0)
    t, ypr, kind = d.attitude_angles()
    assert kind == ("corrected" if d.mission == 5 else "integrated")
    assert np.all(np.abs(ypr) < 0.01) and np.all(np.diff(t) > 0)
    # the image's time span lies within the ephemeris
    t0 = d.scene_center_time_s - d.scene_center_row * d.line_period_s
    assert d.ephemeris_time_s[0] < t0 < t0 + rows * d.line_period_s < d.ephemeris_time_s[-1]


@pytest.mark.parametrize("mission", sorted(SPOT))
def test_every_spot_scene_opens_as_a_model(data_dir, mission):
    model = open_model(data_dir / SPOT[mission])
    d = read_dimap(data_dir / SPOT[mission])
    assert isinstance(model, LinescanModel) and model.shape == d.shape
    assert model.epoch == d.epoch


def test_velocity_frames(data_dir):
    """SPOT 1-4 velocities are inertial on ECEF axes, SPOT 5 Earth-fixed (measured, not assumed)."""
    for mission, name in SPOT.items():
        d = read_dimap(data_dir / name)
        assert d.velocity_frame == ("earth-fixed" if mission == 5 else "inertial"), name
        ef = d.earth_fixed_velocity_m_s()
        # the Earth-fixed velocity is the derivative of the positions (central differences
        # over the 30/60 s spacing are good to a few m/s)
        t, p = d.ephemeris_time_s, d.position_m
        fd = (p[2:] - p[:-2]) / (t[2:] - t[:-2])[:, None]
        assert np.max(np.abs(fd - ef[1:-1])) < 10.0, name


@pytest.mark.parametrize("mission", [1, 2, 3, 4])
def test_spot14_attitude_integration_closes(data_dir, mission):
    """The integrated gyro speeds reach the second absolute AOCS angle sample (< 1e-6 rad)."""
    d = read_dimap(data_dir / SPOT[mission])
    t, ypr, kind = d.attitude_angles()
    assert kind == "integrated"
    assert t[0] == d.raw_angles.time_s[0] and t[-1] == d.raw_angles.time_s[-1]
    np.testing.assert_array_equal(ypr[0], d.raw_angles.angles[0])
    drift = np.abs(ypr[-1] - d.raw_angles.angles[-1])
    integral = np.abs(ypr[-1] - ypr[0])
    assert np.all(drift < 1e-6) and np.any(integral > 5 * drift.max())


def test_product_directory(data_dir, tmp_path):
    (tmp_path / "METADATA.DIM").symlink_to(data_dir / SPOT[2])
    assert read_dimap(tmp_path).shape == (6000, 6000)
    assert is_spot_dimap(tmp_path)
    with pytest.raises(GeoblockError, match="no METADATA.DIM"):
        read_dimap(tmp_path / "..")


def test_not_spot_dimap_v1(data_dir):
    spot6 = data_dir / "cosicorr3d/test_dataset/SPOT6.XML"
    assert not is_spot_dimap(spot6)
    with pytest.raises(DimapFormatError, match="METADATA_FORMAT.*not DIMAP version 1"):
        read_dimap(spot6)
    assert not is_spot_dimap(data_dir / "stereopipeline/tests/dg_example1.xml")


# ---------------------------------------------------------------------- pixel convention
def _mutated(src: Path, directory: Path, edit) -> Path:
    tree = ET.parse(src)
    edit(tree.getroot())
    out = directory / "METADATA.DIM"
    tree.write(out, encoding="utf-8", xml_declaration=True)
    return out


def test_pixel_conversion(data_dir, tmp_path):
    """DIMAP (1-based POINT) -> geoblock 0-based centres: minus PIXEL_ORIGIN, minus 0.5 for CELL."""
    src = data_dir / SPOT[1]
    root = ET.parse(src).getroot()
    base = read_dimap(src)
    frame = root.findall("Dataset_Frame/Vertex")
    for v, xml in zip(base.vertices, frame, strict=True):
        assert v.row == float(xml.findtext("FRAME_ROW")) - 1
        assert v.col == float(xml.findtext("FRAME_COL")) - 1
    assert base.vertices[2].row == base.vertices[2].col == 5999  # the last pixel
    assert base.scene_center.row == base.scene_center_row == 2999
    assert base.tie_points[2].row == base.tie_points[2].col == 5999
    assert base.look_detector_col.tolist() == [0, 5999]

    def origin_zero(r):
        r.find("Raster_CS/PIXEL_ORIGIN").text = "0"

    def cell(r):
        r.find("Raster_CS/RASTER_CS_TYPE").text = "CELL"

    zero = read_dimap(_mutated(src, tmp_path, origin_zero))
    assert zero.vertices[2].row == 6000 and zero.scene_center_row == 3000
    corner = read_dimap(_mutated(src, tmp_path, cell))
    assert corner.vertices[0].row == -0.5 and corner.scene_center_col == 2998.5


# ---------------------------------------------------------------------- inconsistent metadata
def _drop(path: str):
    def edit(root):
        parent_path, _, tag = path.rpartition("/")
        for parent in root.findall(parent_path) if parent_path else [root]:
            for child in parent.findall(tag):
                parent.remove(child)
    return edit


def test_inconsistent_velocities(data_dir, tmp_path):
    def scale(root):
        for v in root.findall("Data_Strip/Ephemeris/Points/Point/Velocity/X"):
            v.text = repr(float(v.text) * 1.1)

    with pytest.raises(DimapFormatError, match="Velocity.*disagree with the positions"):
        read_dimap(_mutated(data_dir / SPOT[1], tmp_path, scale))


def test_unordered_ephemeris(data_dir, tmp_path):
    def swap(root):
        times = root.findall("Data_Strip/Ephemeris/Points/Point/TIME")
        times[2].text, times[3].text = times[3].text, times[2].text

    with pytest.raises(DimapFormatError, match="TIME: times are not strictly increasing"):
        read_dimap(_mutated(data_dir / SPOT[1], tmp_path, swap))


def test_missing_look_angle_refused(data_dir, tmp_path):
    def drop_one(root):
        parent = root.find("Data_Strip/Sensor_Configuration/Instrument_Look_Angles_List/"
                           "Instrument_Look_Angles/Look_Angles_List")
        parent.remove(parent.findall("Look_Angles")[-1])

    d = read_dimap(_mutated(data_dir / SPOT[5], tmp_path, drop_one))
    with pytest.raises(DimapFormatError, match=r"detectors 1\.\.11999 .* 12000 columns"):
        d.look_angles()


def test_level_1b_refused(data_dir, tmp_path):
    def level(root):
        root.find("Data_Processing/PROCESSING_LEVEL").text = "1B"

    with pytest.raises(DimapFormatError, match="PROCESSING_LEVEL.*only level 1A"):
        read_dimap(_mutated(data_dir / SPOT[3], tmp_path, level))


@pytest.fixture(scope="module")
def spot1_text(data_dir) -> str:
    return (data_dir / SPOT[1]).read_text(encoding="utf-8")


@settings(max_examples=len(REQUIRED_FIELDS) * 2, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(field=st.sampled_from(REQUIRED_FIELDS), garble=st.booleans())
def test_fuzz_required_fields(data_dir, field, garble):
    """Dropping (or garbling) any required element gives DimapFormatError naming it."""
    src = data_dir / SPOT[1]

    def edit(root):
        if garble:
            for e in root.findall(field):
                leaves = [c for c in e.iter() if len(c) == 0]  # e itself, or its first leaf
                leaves[0].text = "not-a-number"
        else:
            _drop(field)(root)

    with tempfile.TemporaryDirectory() as tmp:
        path = _mutated(src, Path(tmp), edit)
        try:
            d = read_dimap(path)
            d.attitude_angles()
            d.look_angles()
        except DimapFormatError as exc:
            assert exc.path == str(path)
            named = field.rsplit("/", 1)[-1]
            assert named in exc.field or named in str(exc), (field, str(exc))
        else:
            pytest.fail(f"dropping/garbling {field} was accepted")


@settings(max_examples=15, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(fraction=st.floats(0.0, 0.999))
def test_fuzz_truncated_file(spot1_text, fraction):
    """A truncated METADATA.DIM raises ModelFormatError naming the file, never anything else."""
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "METADATA.DIM"
        path.write_text(spot1_text[: int(fraction * len(spot1_text))], encoding="utf-8")
        with pytest.raises(ModelFormatError, match="METADATA.DIM"):
            read_dimap(path)
