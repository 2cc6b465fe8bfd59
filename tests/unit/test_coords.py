import numpy as np
import pyproj
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from geoblock import coords
from geoblock.errors import CoordinateError, GeoblockError, ShapeMismatchError


def _pyproj_ecef(lon, lat, h):
    t = pyproj.Transformer.from_crs("EPSG:4979", "EPSG:4978", always_xy=True)
    return np.array(t.transform(lon, lat, h))


def test_geodetic_to_ecef_matches_pyproj():
    rng = np.random.default_rng(1)
    lon = rng.uniform(-180, 180, 20000)
    lat = rng.uniform(-90, 90, 20000)
    h = rng.uniform(-500, 900e3, 20000)  # ground to orbit
    ours = np.array(coords.geodetic_to_ecef(lon, lat, h))
    assert np.max(np.abs(ours - _pyproj_ecef(lon, lat, h))) < 1e-6


def test_ecef_to_geodetic_matches_pyproj_near_the_surface():
    rng = np.random.default_rng(2)
    lon = rng.uniform(-180, 180, 20000)
    lat = rng.uniform(-90, 90, 20000)
    h = rng.uniform(-500, 3000, 20000)  # PROJ's inverse drifts above (1e-6 m at 10 km)
    x, y, z = _pyproj_ecef(lon, lat, h)
    t = pyproj.Transformer.from_crs("EPSG:4978", "EPSG:4979", always_xy=True)
    ref = np.array(t.transform(x, y, z))
    ours = coords.ecef_to_geodetic(x, y, z)
    assert np.max(np.abs(ours.h - ref[2])) < 1e-6
    assert np.max(np.abs(ours.lat - ref[1])) < 1e-11  # 1e-11 degree ~ 1e-6 m
    assert np.max(np.abs(((ours.lon - ref[0]) + 180) % 360 - 180)) < 1e-11


def test_ecef_to_geodetic_is_exact_up_to_orbit():
    # PROJ's inverse is an approximation that drifts by millimetres at orbital heights
    # (measured: 6.5 mm at 900 km); ours is closed form: check it by the round trip.
    rng = np.random.default_rng(3)
    lon = rng.uniform(-180, 180, 20000)
    lat = rng.uniform(-90, 90, 20000)
    h = rng.uniform(-500, 900e3, 20000)
    x, y, z = coords.geodetic_to_ecef(lon, lat, h)
    ours = coords.ecef_to_geodetic(x, y, z)
    assert np.max(np.abs(ours.h - h)) < 1e-8
    back = np.array(coords.geodetic_to_ecef(*ours))
    assert np.max(np.abs(back - np.array([x, y, z]))) < 1e-8


@pytest.mark.parametrize(
    ("lon", "lat", "h", "expected"),
    [
        # shareloc tests/test_proj_utils.py l.37-51 (../shared/data/MANIFEST.md), atol 1e-5 m there
        (7.05396752, 43.73000865, 4900.0, (4584837.334948, 567331.361674, 4389850.562378)),
        (7.05860411, 43.72347311, -30.0, (4581754.08394, 567326.291517, 4385917.904472)),
    ],
)
def test_wgs84_to_ecef_shareloc_values(lon, lat, h, expected):
    assert np.allclose(coords.geodetic_to_ecef(lon, lat, h), expected, rtol=0, atol=1e-5)


def test_poles_and_equator():
    x, y, z = coords.geodetic_to_ecef([0, 0, 90], [0, 90, -90], 0.0)
    assert np.allclose(x, [coords.WGS84_A, 0, 0], atol=1e-9)
    assert np.allclose(z, [0, coords.WGS84_B, -coords.WGS84_B], atol=1e-9)
    g = coords.ecef_to_geodetic(0.0, 0.0, coords.WGS84_B + 10.0)
    assert abs(g.lat - 90.0) < 1e-12 and abs(g.h - 10.0) < 1e-9


@settings(max_examples=200, deadline=None)
@given(
    lon0=st.floats(-180, 180), lat0=st.floats(-89.9, 89.9), h0=st.floats(-400, 9000),
    e=st.floats(-2e5, 2e5), n=st.floats(-2e5, 2e5), u=st.floats(-1e3, 1e4),
)
def test_enu_round_trip(lon0, lat0, h0, e, n, u):
    """ENU -> ECEF -> ENU to 1e-9 m; through degrees to 1e-8 m.

    float64 degrees cannot do better: one unit in the last place of a longitude near 180
    degrees is 2.8e-14 degree, 3.2e-9 m on the equator.
    """
    frame = coords.LocalFrame(lon0, lat0, h0)
    back = frame.from_ecef(*frame.to_ecef(e, n, u))
    assert np.allclose(back, (e, n, u), rtol=0, atol=1e-9)
    back = frame.from_geodetic(*frame.to_geodetic(e, n, u))
    assert np.allclose(back, (e, n, u), rtol=0, atol=1e-8)


@settings(max_examples=100, deadline=None)
@given(lat0=st.floats(-89.9, 89.9), u=st.floats(1e4, 9e5))
def test_enu_round_trip_at_orbital_heights(lat0, u):
    """Satellite positions: the ECEF magnitude (7e6 m) limits float64 to a few nanometres."""
    frame = coords.LocalFrame(7.0, lat0, 0.0)
    back = frame.from_geodetic(*frame.to_geodetic(1e5, -2e5, u))
    assert np.allclose(back, (1e5, -2e5, u), rtol=0, atol=1e-8)


def test_enu_rotation_is_orthonormal_and_up_is_normal():
    r = coords.enu_rotation([10.0, -100.0], [45.0, -30.0])
    assert r.shape == (2, 3, 3)
    assert np.allclose(r @ np.swapaxes(r, -1, -2), np.eye(3), atol=1e-15)
    # "up" equals the ellipsoid normal: the direction of increasing h
    j = coords.geodetic_to_ecef_jacobian(10.0, 45.0, 0.0)
    assert np.allclose(j[:, 2], r[0, 2], atol=1e-15)
    assert np.allclose(coords.enu_to_ecef_jacobian(10.0, 45.0), r[0].T)


def test_geodetic_jacobian_matches_finite_differences():
    lon, lat, h = 7.0, 43.7, 500.0
    jac = coords.geodetic_to_ecef_jacobian(lon, lat, h)
    steps = (1e-6, 1e-6, 1e-3)
    for k, step in enumerate(steps):
        plus = [lon, lat, h]
        minus = [lon, lat, h]
        plus[k] += step
        minus[k] -= step
        fd = (
            np.array(coords.geodetic_to_ecef(*plus)) - np.array(coords.geodetic_to_ecef(*minus))
        ) / (2 * step)
        assert np.allclose(jac[:, k], fd, rtol=1e-7, atol=1e-6)


def test_local_frame_centred_on_points():
    frame = coords.LocalFrame.centred_on([7.0, 7.2], [43.6, 43.8], [100.0, 300.0])
    assert abs(frame.lon0 - 7.1) < 1e-3 and abs(frame.lat0 - 43.7) < 1e-3
    assert frame.h0 == 200.0
    with pytest.raises(CoordinateError, match="finite"):
        coords.LocalFrame.centred_on(np.nan, 0.0, 0.0)
    turned = coords.LocalFrame.centred_on([7.0, 7.2], [43.6, 43.8], [100.0, 300.0], 200.0)
    assert (turned.lon0, turned.lat0, turned.h0) == (frame.lon0, frame.lat0, frame.h0)
    assert turned.azimuth_deg == 200.0


def test_local_frame_default_axes_are_east_north_up_exactly():
    frame = coords.LocalFrame(10.0, 45.0, 100.0)
    assert frame.azimuth_deg == 90.0
    np.testing.assert_array_equal(frame.rotation, coords.enu_rotation(10.0, 45.0))
    e, n, u = frame.from_geodetic(10.01, 45.02, 300.0)
    de, dn, du = coords.enu_offsets(10.0, 45.0, 100.0, 10.01, 45.02, 300.0)
    np.testing.assert_allclose((e, n, u), (de, dn, du), rtol=0, atol=1e-9)


@pytest.mark.parametrize("azimuth", [0.0, 90.0, 180.0, 193.6, 270.0, -45.0])
def test_local_frame_turned_by_an_azimuth(azimuth):
    """X points at the azimuth (clockwise from north), Y = Z x X, Z up; conversions invert."""
    frame = coords.LocalFrame(10.0, 45.0, 100.0, azimuth)
    east, north, up = coords.enu_rotation(10.0, 45.0)
    a = np.radians(azimuth)
    x_axis = np.sin(a) * east + np.cos(a) * north
    np.testing.assert_allclose(frame.rotation, np.stack([x_axis, np.cross(up, x_axis), up]),
                               atol=1e-15)
    assert not frame.rotation.flags.writeable
    x, y, z = frame.from_geodetic(10.01, 45.02, 300.0)
    g = frame.to_geodetic(x, y, z)
    assert g.lon == pytest.approx(10.01, abs=1e-12) and g.h == pytest.approx(300.0, abs=1e-7)
    # the stacked (..., 3) conversions give the same numbers as the per-axis ones
    ecef = np.stack(coords.geodetic_to_ecef([10.01, 9.9], [45.02, 44.9], [300.0, 0.0]), -1)
    local = frame.from_ecef_xyz(ecef)
    np.testing.assert_array_equal(local, np.stack(frame.from_ecef(*ecef.T), axis=-1))
    np.testing.assert_allclose(frame.to_ecef_xyz(local), ecef, rtol=0, atol=1e-8)
    np.testing.assert_array_equal(frame.to_ecef_xyz(local),
                                  np.stack(frame.to_ecef(*local.T), axis=-1))


def test_local_frame_south_axes():
    south = coords.LocalFrame(10.0, 45.0, 100.0, 180.0)  # X south, Y east
    east, north, up = coords.enu_rotation(10.0, 45.0)
    np.testing.assert_allclose(south.rotation, np.stack([-north, east, up]), atol=1e-15)


def test_local_frame_dict_round_trip_and_errors():
    frame = coords.LocalFrame(121.91, 24.62, 0.0, 180.0)
    data = frame.to_dict()
    assert data == {"lon0": 121.91, "lat0": 24.62, "h0": 0.0, "azimuth_deg": 180.0}
    assert coords.LocalFrame.from_dict(data) == frame
    assert coords.LocalFrame.from_dict({"lon0": 1.0, "lat0": 2.0}) == coords.LocalFrame(1, 2)
    with pytest.raises(CoordinateError, match="azimuth"):
        coords.LocalFrame.from_dict({"lon0": 1.0, "lat0": 2.0, "azimut": 3.0})
    with pytest.raises(CoordinateError, match="lat0"):
        coords.LocalFrame(0.0, 91.0)
    with pytest.raises(CoordinateError, match="azimuth_deg"):
        coords.LocalFrame(0.0, 0.0, 0.0, float("nan"))
    with pytest.raises(CoordinateError, match="h0"):
        coords.LocalFrame(0.0, 0.0, "abc")  # type: ignore[arg-type]
    assert issubclass(CoordinateError, GeoblockError) and issubclass(CoordinateError, ValueError)


def test_enu_offsets():
    frame = coords.LocalFrame(7.0, 43.7, 0.0)
    lon, lat, h = frame.to_geodetic(3.0, -4.0, 5.0)
    de, dn, du = coords.enu_offsets(7.0, 43.7, 0.0, lon, lat, h)
    assert np.allclose((de, dn, du), (3.0, -4.0, 5.0), atol=1e-9)


def test_broadcasting_and_shape_errors():
    x, y, z = coords.geodetic_to_ecef(np.zeros((3, 1)), np.zeros((1, 4)), 0.0)
    assert x.shape == (3, 4) and x.dtype == np.float64
    with pytest.raises(ShapeMismatchError, match=r"lon \(3,\), lat \(4,\)"):
        coords.geodetic_to_ecef(np.zeros(3), np.zeros(4), 0.0)
    x, y, z = coords.geodetic_to_ecef(np.nan, 0.0, 0.0)
    assert np.isnan(x)


@pytest.mark.parametrize(
    ("lon", "lat", "epsg"),
    [
        (7.05, 43.7, 32632),  # Nice
        (-75.5, -76.6, 32718),
        (5.0, 60.0, 32632),  # Norway exception (zone 31 -> 32)
        (15.0, 78.0, 32633),  # Svalbard
        ([179.5, -179.5], [10.0, 10.0], 32601),  # footprint across the antimeridian
    ],
)
def test_utm_crs(lon, lat, epsg):
    assert coords.utm_crs(lon, lat).to_epsg() == epsg


def test_transformer_is_cached_per_thread():
    a = coords.transformer("EPSG:4326", 32632)
    assert a is coords.transformer("EPSG:4326", 32632)
    x, y = a.transform(9.0, 0.0)
    assert abs(x - 500000.0) < 1e-6


def test_non_finite_in_nan_out_silently():
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for bad in (np.nan, np.inf, -np.inf):
            assert np.all(np.isnan(coords.geodetic_to_ecef(bad, 0.0, 0.0)))
            assert np.all(np.isnan(coords.ecef_to_geodetic(bad, 0.0, 0.0)[1:]))
            assert np.isnan(coords.enu_rotation(bad, 0.0)).any()
            assert np.isnan(coords.geodetic_to_ecef_jacobian(0.0, bad, 0.0)).any()


def test_ecef_to_geodetic_jacobian_inverts_the_forward_one():
    lon = np.array([7.0, -120.0, 179.9])
    lat = np.array([43.7, -60.0, 0.1])
    h = np.array([0.0, 5000.0, 7e5])
    inv = coords.ecef_to_geodetic_jacobian(lon, lat, h)
    fwd = coords.geodetic_to_ecef_jacobian(lon, lat, h)
    assert np.allclose(inv @ fwd, np.eye(3), atol=1e-10)


def test_intersect_height_hits_the_height_surface_and_reports_misses():
    """Rays from orbit to h: the ground point's geodetic height is h; rays pointing away
    from the Earth or passing it by get NO_INTERSECTION."""
    from geoblock.typing import Status

    rng = np.random.default_rng(5)
    n = 200
    lon = rng.uniform(-180, 180, n)
    lat = rng.uniform(-85, 85, n)
    h = rng.uniform(-500, 9000, n)
    target = np.stack(coords.geodetic_to_ecef(lon, lat, h), axis=-1)
    sat = np.stack(coords.geodetic_to_ecef(lon + rng.normal(0, 1, n), lat + rng.normal(0, 1, n),
                                           np.full(n, 700e3)), axis=-1)
    d = target - sat
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    d[0] = -d[0]  # away from the Earth
    d[1] = np.cross(sat[1], [0.0, 0.0, 1.0])  # horizontal: passes the Earth by
    d[1] /= np.linalg.norm(d[1])
    g_lon, g_lat, s, status = coords.intersect_height(sat, d, h)
    assert status[0] == Status.NO_INTERSECTION and status[1] == Status.NO_INTERSECTION
    assert np.isnan(g_lon[:2]).all()
    ok = slice(2, None)
    assert (status[ok] == Status.CONVERGED).all()
    np.testing.assert_allclose(g_lon[ok], lon[ok], atol=1e-9)
    np.testing.assert_allclose(g_lat[ok], lat[ok], atol=1e-9)
    p = sat[ok] + s[ok, None] * d[ok]
    np.testing.assert_allclose(coords.ecef_to_geodetic(*p.T).h, h[ok], atol=1e-6)
