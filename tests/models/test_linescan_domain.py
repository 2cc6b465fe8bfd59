"""Linescan models give a status, not an answer, far outside their domain (issue 12, item 3):
heights far outside ``height_range`` (both directions) and points that are no place on the
Earth (``lon=1e300``) are OUT_OF_DOMAIN."""

from __future__ import annotations

import numpy as np
import pytest

from geoblock.models.linescan import LinescanModel
from geoblock.typing import Status


@pytest.fixture(scope="module")
def model() -> LinescanModel:
    return LinescanModel.example()


def _limits(model: LinescanModel) -> tuple[float, float]:
    h0, h1 = model.height_range
    margin = max(h1 - h0, model.height_margin_m)
    return h0 - margin, h1 + margin


@pytest.fixture(scope="module")
def centre(model):
    rows, cols = model.shape
    g = model.backproject((rows - 1) / 2.0, (cols - 1) / 2.0, 0.0)
    return float(g.lon), float(g.lat)


def test_backprojection_far_outside_the_height_range_is_out_of_domain(model):
    lo, hi = _limits(model)
    h = np.array([0.0, model.height_range[0], model.height_range[1], lo + 1.0, hi - 1.0,
                  -1e6, 1e6, lo - 1.0, hi + 1.0, 1e300, -1e300])
    g, status = model.backproject_with_status(np.full(h.size, 400.0), np.full(h.size, 500.0), h)
    assert list(status[:5]) == [Status.CONVERGED] * 5
    assert list(status[5:]) == [Status.OUT_OF_DOMAIN] * 6
    assert np.isnan(g.lon[5:]).all() and np.isnan(g.lat[5:]).all()


def test_projection_far_outside_the_height_range_is_out_of_domain(model, centre):
    lon, lat = centre
    lo, hi = _limits(model)
    h = np.array([0.0, 5000.0, -1e6, lo - 1.0, hi + 1.0, 1e300])
    (row, col), status = model.project_with_status(lon, lat, h)
    assert list(status[:2]) == [Status.CONVERGED] * 2
    assert list(status[2:]) == [Status.OUT_OF_DOMAIN] * 4
    assert np.isnan(row[2:]).all() and np.isnan(col[2:]).all()


def test_points_that_are_no_place_on_the_earth_are_out_of_domain(model, centre):
    lon, lat = centre
    lons = np.array([lon, lon + 360.0, 1e300, -1e300, lon + 360.0 * 1e6, lon, lon])
    lats = np.array([lat, lat, lat, lat, lat, 1e300, 90.5])
    (row, col), status = model.project_with_status(lons, lats, 0.0)
    assert list(status[:2]) == [Status.CONVERGED] * 2  # lon + 360 is the same place
    assert np.allclose(row[1], row[0]) and np.allclose(col[1], col[0])
    assert list(status[2:]) == [Status.OUT_OF_DOMAIN] * 5
    assert np.isnan(row[2:]).all()


def test_the_margin_scales_with_the_height_range(model):
    wide = model.replace(height_range=(-500.0, 30000.0))
    _, status = wide.backproject_with_status([400.0] * 2, [500.0] * 2, [60000.0, 61000.0])
    assert list(status) == [Status.CONVERGED, Status.OUT_OF_DOMAIN]


def test_an_ephemeris_that_is_not_an_orbit_is_refused(tmp_path):
    import json

    import geoblock
    from geoblock.errors import GeoblockError, ModelFormatError
    from geoblock.models.linescan import Ephemeris, LinescanModel

    t = np.array([0.0, 1.0, 2.0])
    p = np.array([[7.0e6, 0, 0], [7.0e6, 7.5e3, 0], [7.0e6, 1.5e4, 0]])
    v = np.array([[0, 7.5e3, 0]] * 3, dtype=float)
    Ephemeris(t, p, v)  # a plausible low orbit
    with pytest.raises(ModelFormatError, match="position_m.*sample 1.*not an orbit"):
        Ephemeris(t, np.where(np.arange(3)[:, None] == 1, 1.0, p), v)
    with pytest.raises(ModelFormatError, match="velocity_m_s.*speed"):
        Ephemeris(t, p, v * 100)
    # from geoblock's model JSON: the file is named
    data = LinescanModel.example().to_dict()
    data["ephemeris"]["position_m"] = (np.asarray(data["ephemeris"]["position_m"]) * 1e-3).tolist()
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(data))
    with pytest.raises(GeoblockError, match="bad.json.*not an orbit|not an orbit.*bad.json"):
        geoblock.open_model(path)


@pytest.mark.parametrize("heights", ["abc", "12", (1.0,), (1.0, 2.0, 3.0), ("a", 1.0), 7, None])
def test_height_range_that_is_not_two_numbers_is_a_model_format_error(heights):
    from geoblock.errors import ModelFormatError
    from geoblock.models.linescan import LinescanModel

    with pytest.raises(ModelFormatError, match="height_range"):
        LinescanModel.example().replace(height_range=heights)
