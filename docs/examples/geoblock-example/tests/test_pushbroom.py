"""A pushbroom reader's model (geoblock_example.pushbroom): a LinescanModel built from vendor
arrays, which the conformance kit accepts and which reopens without this plugin."""

from __future__ import annotations

import numpy as np
import pytest
from geoblock_example.pushbroom import example_metadata, linescan_from_metadata

import geoblock
from geoblock.errors import ModelFormatError
from geoblock.models.linescan import LinescanModel
from geoblock.testing import SensorModelContract


class TestPushbroomFromMetadata(SensorModelContract):
    # "dg" and "physical" derive their sigmas from a location accuracy
    parameter_set_options = {"dg": {"accuracy_m": 10.0}, "physical": {"accuracy_m": 10.0}}

    @pytest.fixture
    def model(self):
        return linescan_from_metadata(**example_metadata((300, 400)))


def test_the_scene_is_where_the_orbit_and_the_roll_put_it():
    meta = example_metadata()
    model = linescan_from_metadata(**meta)
    assert isinstance(model, LinescanModel) and model.shape == (600, 800)
    # row 0 is imaged at the epoch, rolled 2 degrees: 700 km x tan(2 deg) = 24 km across
    # track (east or west of the point below the satellite, which flies south; the orbital
    # frame's "down" is geocentric, ~2 km along track from the ellipsoid's normal there)
    position, _, _ = model.sensor_state(0.0)
    nadir = geoblock.coords.ecef_to_geodetic(*position)
    centre = model.backproject(0.0, 399.5, 0.0)
    de, dn, _ = geoblock.coords.enu_offsets(nadir.lon, nadir.lat, 0.0, centre.lon, centre.lat,
                                            0.0)
    assert abs(float(dn)) < 3e3 and float(abs(de)) == pytest.approx(24.4e3, rel=0.03)
    # successive rows are one GSD (3 m) apart, flying south
    a, b = model.backproject([100.0, 101.0], [399.5, 399.5], 0.0)[:2]
    de, dn, _ = geoblock.coords.enu_offsets(a[0], b[0], 0.0, a[1], b[1], 0.0)
    assert np.hypot(de, dn) == pytest.approx(3.0, rel=0.01) and dn < 0


def test_it_reopens_without_the_plugin(tmp_path):
    model = linescan_from_metadata(**example_metadata((300, 400)))
    path = geoblock.write_model(model, tmp_path / "scan.json")
    assert geoblock.open_model(path) == model  # "linescan" is core's model


def test_bad_vendor_arrays_are_refused_naming_the_block():
    meta = example_metadata((300, 400))
    meta["ephemeris_time_s"] = meta["ephemeris_time_s"][::-1]
    with pytest.raises(ModelFormatError, match="Ephemeris.time_s"):
        linescan_from_metadata(**meta)
    meta = example_metadata((300, 400))
    meta["psi_y_rad"] = meta["psi_y_rad"][:-1]
    with pytest.raises(ModelFormatError, match=r"tan_x \(400,\) and tan_y \(399,\)"):
        linescan_from_metadata(**meta)
    meta["psi_x_rad"] = meta["psi_x_rad"][:-1]
    with pytest.raises(ModelFormatError, match="399 detectors"):
        linescan_from_metadata(**meta)
