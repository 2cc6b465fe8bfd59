"""NASA Ames Stereo Pipeline's camera tests (``src/asp/Camera/tests/``), re-expressed against
geoblock's public API.

Source: https://github.com/NeoGeographyToolkit/StereoPipeline at commit
55bf460225c1436a3b41afc006cb87ea53678369 (``../shared/data/MANIFEST.md``); each test names the
file and line. ASP's pixels (x = col, y = row) put pixel centres at integers, as geoblock does:
no conversion. Not re-expressed: ``TestSpotCameraModel.cxx`` (its file is a cropped parser
fixture on which the manifest forbids a full-scene model), ``dg_example4.xml`` /
``wv_mvp_*.xml`` (not in shared/data), the disabled ``sample.RPB`` test, and attributes geoblock
does not expose (covariance counts, detector origin and pitch, principal distance).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import geoblock
from geoblock.coords import geodetic_to_ecef

SRC = "NeoGeographyToolkit/StereoPipeline@55bf460225c1 src/asp/Camera/tests"


@pytest.fixture(scope="module")
def asp(data_dir) -> Path:
    return data_dir / "stereopipeline/tests"


@pytest.fixture(scope="module")
def dg1(asp):
    return geoblock.open_model(asp / "dg_example1.xml")


def test_dg_xml_reading_image_and_times(dg1):
    """TestDGCameraModel.cxx l.101-109 (StereoSessionDG.XMLReading): TLC (0, 0 s) and
    (23708, 1.975667 s) within 1e-8; image 35170 cols x 23708 rows. geoblock keeps the TLC as
    ``line_times`` (reference row, time, period): the time of row 23708 is asserted."""
    assert dg1.shape == (23708, 35170)
    lt = dg1.line_times
    t = lt.reference_time_s + (23708 - lt.reference_row) * lt.line_period_s
    t0 = lt.reference_time_s + (0 - lt.reference_row) * lt.line_period_s
    assert abs(t - t0 - 1.975667) <= 1e-8


def test_dg_xml_reading_ephemeris(dg1):
    """TestDGCameraModel.cxx l.84-98: 840 ephemeris samples 0.02 s apart, the first position
    (-1.150529111070304e+06, -4.900037170821411e+06, 4.673402253879593e+06) m within 1e-6."""
    eph = dg1.ephemeris
    t = np.asarray(eph.time_s)
    assert t.shape[0] == 840
    assert np.allclose(np.diff(t), 0.02, atol=1e-6)
    np.testing.assert_allclose(np.asarray(eph.position_m)[0],
                               [-1.150529111070304e06, -4.900037170821411e06, 4.673402253879593e06],
                               atol=1e-6, rtol=0)


def test_dg_xml_reading_attitude(dg1):
    """TestDGCameraModel.cxx l.68-80: 840 attitude samples 0.02 s apart."""
    t = np.asarray(dg1.attitude.time_s)
    assert t.shape[0] == 840
    assert np.allclose(np.diff(t), 0.02, atol=1e-6)


def _closest(l1, l2):
    p1, d1, p2, d2 = (np.asarray(v, float) for v in (l1.origin, l1.direction, l2.origin, l2.direction))
    w = p1 - p2
    a, b, c, d, e = d1 @ d1, d1 @ d2, d2 @ d2, d1 @ w, d2 @ w
    s, t = (b * e - c * d) / (a * c - b * b), (a * e - b * d) / (a * c - b * b)
    q1, q2 = p1 + s * d1, p2 + t * d2
    return (q1 + q2) / 2, float(np.linalg.norm(q1 - q2))


def test_dg_create_camera_triangulation(asp, dg1):
    """TestDGCameraModel.cxx l.114-139 (DGCameraModel.CreateCamera): pixels (x 27728, y 10702)
    in dg_example1 and (30090, 10366) in dg_example2 triangulate with a ray miss below 5 m, the
    point below the camera, and reproject within 4 px. Triangulated here from the public
    ``SensorModel.los`` (closest point of the two rays)."""
    dg2 = geoblock.open_model(asp / "dg_example2.xml")
    m1, m2 = (10702.0, 27728.0), (10366.0, 30090.0)  # (row, col)
    x, miss = _closest(dg1.los(*m1), dg2.los(*m2))
    assert miss < 5.0
    assert np.linalg.norm(x) < np.linalg.norm(np.asarray(dg1.los(*m1).origin, float))
    from geoblock.coords import ecef_to_geodetic

    g = ecef_to_geodetic(*x)
    for model, m in ((dg1, m1), (dg2, m2)):
        ic = model.project(g.lon, g.lat, g.h)
        assert np.hypot(ic.row - m[0], ic.col - m[1]) < 4.0


def test_dg_create_camera_triangulate_api(asp, dg1):
    """The same ASP assertion (miss < 5 m) through ``geoblock.triangulate`` (issue 26 item 8)."""
    dg2 = geoblock.open_model(asp / "dg_example2.xml")
    result = geoblock.triangulate({"1": dg1, "2": dg2}, ["p", "p"], ["1", "2"],
                                  [10702.0, 10366.0], [27728.0, 30090.0])
    assert float(np.max(np.asarray(result.miss_m))) < 5.0


def test_dg_project_out_and_back(dg1):
    """TestDGCameraModel.cxx l.146-154: for pixels on a 500 px grid (x < 30000, y < 24000), the
    point 2e4 m along the pixel's ray from the camera centre reprojects to the pixel within
    0.1 px. Difference: that point is ~600 km above the ground, outside geoblock's height domain
    (the model's ``height_range`` plus its margin; projection there is refused, OUT_OF_DOMAIN).
    Any point of the ray is equivalent for this check, so the point taken is on the ray at the
    middle of the height range (``backproject``)."""
    x, y = np.meshgrid(np.arange(0, 30000, 500.0), np.arange(0, 24000, 500.0))
    row, col = y.ravel(), x.ravel()
    lo, hi = dg1.height_range
    g = dg1.backproject(row, col, np.full(row.shape, (lo + hi) / 2))
    ic = dg1.project(g.lon, g.lat, g.h)
    assert np.isfinite(ic.row).all()
    np.testing.assert_array_less(np.hypot(ic.row - row, ic.col - col), 0.1)


def test_dg_single_tlc_entry(asp):
    """TestDGCameraModel.cxx l.156-159: a camera with a single TLC entry (dg_example3.xml) loads
    without error."""
    assert geoblock.open_model(asp / "dg_example3.xml").shape == (54272, 35840)


def test_rpcxml_read_rpc(asp):
    """TestRPCStereoModel.cxx l.101-123 (RPCXML.ReadRPC) and l.148-154: the RPB of
    dg_example1.xml: xy offset (17564, 11856) and scale (17927, 12384) 1e-6; lon/lat/h offset
    (-105.2903, 39.7454, 2281) and scale (.1345, .1003, 637) 1e-6; first and last coefficients
    1e-6. ASP's x is the sample (col), y the line (row)."""
    r = geoblock.open_model(asp / "dg_example1.xml", model="rpc").rpc
    np.testing.assert_allclose([r.samp_off, r.line_off], [17564, 11856], atol=1e-6)
    np.testing.assert_allclose([r.samp_scale, r.line_scale], [17927, 12384], atol=1e-6)
    np.testing.assert_allclose([r.long_off, r.lat_off, r.height_off], [-105.2903, 39.7454, 2281], atol=1e-6)
    np.testing.assert_allclose([r.long_scale, r.lat_scale, r.height_scale], [.1345, .1003, 637], atol=1e-6)
    np.testing.assert_allclose(
        [r.line_num[0], r.line_num[19], r.line_den[0], r.line_den[19],
         r.samp_num[0], r.samp_num[19], r.samp_den[0], r.samp_den[19]],
        [4.683662e-3, 4.395393e-6, 1, -3.71156e-8, -7.306375e-3, -1.585929e-6, 1, -1.211995e-7],
        atol=1e-6)


def test_rpc_jacobian_and_round_trip(asp):
    """TestRPCStereoModel.cxx l.156-170 (StereoSessionRPC.InstantiateTest): at (-105.29, 39.745,
    2281) the analytic ground partials match numerical ones (relative 1e-5); pixel (0, 0) to
    ground at h 10 m and back within 1e-9 px. ASP's Jacobian is in lon/lat/h, geoblock's
    ``partials_ground`` in ECEF (CSM's order): the numerical reference is taken in ECEF, with
    ASP's step 1e-4 as metres."""
    model = geoblock.open_model(asp / "dg_example1.xml", model="rpc")
    lon, lat, h = -105.29, 39.745, 2281.0
    je = np.asarray(model.partials_ground(lon, lat, h), float).reshape(2, 3)
    from geoblock.coords import ecef_to_geodetic

    e = geodetic_to_ecef(lon, lat, h)
    x0 = np.array([float(e.x), float(e.y), float(e.z)])
    jn = np.zeros((2, 3))
    for k in range(3):
        d = np.zeros(3)
        d[k] = 1e-1
        gp, gm = ecef_to_geodetic(*(x0 + d)), ecef_to_geodetic(*(x0 - d))
        ip, im = model.project(gp.lon, gp.lat, gp.h), model.project(gm.lon, gm.lat, gm.h)
        jn[:, k] = [(ip.row - im.row) / 2e-1, (ip.col - im.col) / 2e-1]
    assert np.max(np.abs(je - jn)) / np.max(np.abs(je)) < 1e-5
    g = model.backproject(0.0, 0.0, 10.0)
    ic = model.project(g.lon, g.lat, 10.0)
    assert np.hypot(ic.row, ic.col) < 1e-9
