"""geoblock.triangulation.triangulate: synthetic round trips, the covariance against Monte
Carlo, and the peers' cases on real models.

Golden values and their sources:

* shareloc ``tests/data/triangulation/README`` (CNES/shareloc, commit df45fae6f19b; copied to
  shared/data/shareloc/triangulation/README, MANIFEST.md): the Nice pair 178608/178609
  (``.geom`` RPCs), left sensor (row 10235.9310147135, col 10121.0657280102) and right
  (row 10018.4917330251, col 10472.1832935944), in geoblock's pixel-centre convention
  (shareloc's current API adds 0.5: its ``test_rpc.py`` l.113-144 gives col 10121.5657,
  row 10236.4310 for the left one's point at 850 m); the README's backprojections at 310,
  850, 355 and 985 m and its triangulated ECEF point 4584341.53074182, 572313.952956326,
  4382784.34315186. shareloc's ``geofunctions/test_triangulation.py`` asserts
  4584341.37359843, 572313.675204275, 4382784.51356450 (abs 0.5 m via its epipolar grids
  and SIFT match, test_epi_triangulation_sift l.131-135): the same point, 0.37 m away.
* shareloc ``tests/geofunctions/test_triangulation.py`` test_sensor_triangulation
  (l.43-72): a match made by colocalisation (left (col 1000.5, row 1500.5) at 10 m into the
  right image) triangulates back to the same lon/lat (abs 1e-8), h (abs 8e-3) and distance
  0 (abs 1e-3). shareloc uses its GRID models of P1BP--2017092838284574CP and
  P1BP--2017092838319324CP, not in shared/data: the same scenes' DIMAP RPCs are used here.
* ASP ``src/asp/Camera/tests/TestDGCameraModel.cxx`` CreateCamera (l.114-162): dg_example1/2
  pixels (col 27728, row 10702) and (col 30090, row 10366) triangulate with a ray miss
  below 5 m, and reproject within 4 px.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import geoblock
from geoblock import Status, coords
from geoblock.errors import NoIntersectionWarning, ObservationError, ShapeMismatchError
from geoblock.testing.synthetic import ConstantVelocityPushbroom
from geoblock.triangulation import parameter_covariances, triangulate

LEFT = "shareloc/rpc/PHR1B_P_201709281038045_SEN_PRG_FC_178608-001.geom"
RIGHT = "shareloc/rpc/PHR1B_P_201709281038393_SEN_PRG_FC_178609-001.geom"
L_PX = (10235.9310147135147417429834604, 10121.0657280102386721409857273)  # row, col
R_PX = (10018.4917330250955274095758796, 10472.1832935943566553760319948)
README_ECEF = (4584341.53074182290583848953247, 572313.952956325956620275974274,
               4382784.34315186273306608200073)


def _pushbroom_from(east_m: float) -> ConstantVelocityPushbroom:
    """The example pushbroom moved ``east_m`` east and rolled to look at the same ground."""
    ex = ConstantVelocityPushbroom.example()
    rows, cols = ex.shape
    speed, period = 7000.0, 2.5 / 7000.0
    best = None
    for roll in (np.arctan2(east_m, 700e3), -np.arctan2(east_m, 700e3)):
        m = ConstantVelocityPushbroom(ex.shape, (7.05, 43.70),
                                      (east_m, -speed * period * rows / 2, 700e3),
                                      (0.0, speed, 0.0), period, 2.5 / 700e3, (roll, 0.0, 0.0))
        g = m.backproject((rows - 1) / 2, (cols - 1) / 2, 0.0)
        miss = abs(float(g.lon) - 7.05)
        if best is None or miss < best[0]:
            best = (miss, m)
    assert best is not None
    return best[1]


@pytest.fixture(scope="module")
def stereo():
    """Three pushbrooms over Nice, 250 km apart across track (about 20 degrees), looking at
    the same ground."""
    return {f"r{k}": _pushbroom_from(east) for k, east in enumerate((-250e3, 0.0, 250e3))}


def _measure(models, lon, lat, h):
    ids, images, rows, cols = [], [], [], []
    for name, m in models.items():
        r, c = m.project(lon, lat, h)
        ids.append(np.arange(lon.size).astype(str))
        images.append(np.full(lon.size, name))
        rows.append(r)
        cols.append(c)
    return (np.concatenate(ids), np.concatenate(images), np.concatenate(rows),
            np.concatenate(cols))


@settings(max_examples=25, deadline=None)
@given(st.floats(0.2, 0.8), st.floats(0.2, 0.8), st.floats(-300.0, 3000.0),
       st.sampled_from([("r0", "r2"), ("r0", "r1"), ("r0", "r1", "r2")]))
def test_round_trip_any_number_of_rays(stereo, u, v, h, names):
    models = {n: stereo[n] for n in names}
    base = stereo["r1"]
    rows, cols = base.shape
    g = base.backproject(u * (rows - 1), v * (cols - 1), h)
    t = triangulate(models, *_measure(models, np.atleast_1d(g.lon), np.atleast_1d(g.lat),
                                      np.atleast_1d(h)))
    assert t.status[0] == Status.CONVERGED and t.rays[0] == len(names)
    de, dn, du = coords.enu_offsets(g.lon, g.lat, h, t.lon[0], t.lat[0], t.h[0])
    assert max(abs(de), abs(dn), abs(du)) < 1e-5
    assert t.miss_m[0] < 1e-5
    assert np.max(np.abs(np.concatenate([t.v_row, t.v_col]))) < 1e-5


def test_covariance_matches_monte_carlo(stereo):
    """The predicted E/N/U sigmas from sigma_px against the scatter of 4000 noisy
    triangulations of one point (within 10 %)."""
    models = {"r0": stereo["r0"], "r2": stereo["r2"]}
    base = stereo["r1"]
    g = base.backproject(400.0, 500.0, 250.0)
    n, sigma = 4000, 0.7
    ids, images, r, c = _measure(models, np.full(n, g.lon), np.full(n, g.lat), np.full(n, 250.0))
    rng = np.random.default_rng(1)
    t = triangulate(models, ids, images, r + rng.normal(0, sigma, r.size),
                    c + rng.normal(0, sigma, c.size), sigma_px=sigma)
    assert (t.status == Status.CONVERGED).all()
    de, dn, du = coords.enu_offsets(g.lon, g.lat, 250.0, t.lon, t.lat, t.h)
    empirical = np.cov(np.stack([de, dn, du]))
    predicted = t.covariance.mean(axis=0)
    assert np.allclose(np.sqrt(np.diag(empirical)), np.sqrt(np.diag(predicted)), rtol=0.1)
    # two rays: the miss distance is the rays' separation, the residuals sum to it in pixels
    assert np.all(t.miss_m > 0) and np.median(t.miss_m) < 10 * sigma * 2.5


def test_parameter_covariance_adds_to_the_image_sigma(stereo):
    """An order-0 image correction with shift sigmas s (px) and covariance diag(s^2) is the
    same as an image sigma of sqrt(sigma^2 + s^2): the two covariances agree."""
    s = 0.8
    corrected = geoblock.ImageCorrection(stereo["r0"], 0, [0.0, 0.0], sigmas=s)
    models = {"a": corrected, "b": stereo["r2"]}
    g = stereo["r1"].backproject(np.array([100.0, 600.0]), np.array([200.0, 800.0]), 100.0)
    ids, images, r, c = _measure(models, g.lon, g.lat, g.h)
    p = len(corrected.parameters)
    with_cov = triangulate(models, ids, images, r, c, sigma_px=0.5,
                           parameter_covariance={"a": np.eye(p) * s**2})
    sig = np.where(images == "a", np.hypot(0.5, s), 0.5)
    by_sigma = triangulate(models, ids, images, r, c, sigma_px=sig)
    assert np.allclose(with_cov.covariance, by_sigma.covariance, rtol=1e-3)
    plain = triangulate(models, ids, images, r, c, sigma_px=0.5)
    assert np.all(with_cov.sigma_enu > plain.sigma_enu - 1e-12)


def test_parameter_covariances_of_a_block_result(stereo):
    class Result:  # the three fields parameter_covariances reads of a BlockResult
        models = {"a": geoblock.ImageCorrection(stereo["r0"], 1, [0.0] * 6, sigmas=1.0),
                  "b": stereo["r2"]}
        parameter_index = [("a", n) for n in models["a"].parameters.names[:2]]
        covariance = np.array([[4.0, 1.0], [1.0, 9.0]])

    covs = parameter_covariances(Result())
    assert set(covs) == {"a"} and covs["a"].shape == (6, 6)
    assert covs["a"][0, 0] == 4.0 and covs["a"][1, 0] == 1.0 and covs["a"][5, 5] == 0.0


def test_single_rays_parallel_rays_and_failures_are_per_point(stereo):
    m = stereo["r0"]
    models = {"a": m, "b": m}  # the same camera twice: parallel rays
    with pytest.warns(NoIntersectionWarning, match="fewer than two usable rays or parallel"):
        t = triangulate(models, ["p", "p", "q", "z"], ["a", "b", "a", "a"],
                        [10.0, 10.0, 20.0, np.nan], [10.0, 10.0, 20.0, 5.0])
    assert t.id.tolist() == ["p", "q", "z"]
    assert t.status.tolist() == [Status.NO_INTERSECTION] * 3
    assert t.rays.tolist() == [2, 1, 0] and np.isnan(t.lon).all()


def test_bad_input_is_named(stereo):
    models = {"a": stereo["r0"], "b": stereo["r2"]}
    with pytest.raises(ObservationError, match=r"image\(s\) \['c'\]"):
        triangulate(models, ["p", "p"], ["a", "c"], [1.0, 1.0], [1.0, 1.0])
    with pytest.raises(ObservationError, match="more than once in one image: \\['a: p'\\]"):
        triangulate(models, ["p", "p"], ["a", "a"], [1.0, 1.0], [1.0, 1.0])
    with pytest.raises(ShapeMismatchError, match="row has shape"):
        triangulate(models, ["p", "p"], ["a", "b"], [1.0], [1.0, 1.0])
    with pytest.raises(ObservationError, match="sigma_px must be positive"):
        triangulate(models, ["p", "p"], ["a", "b"], [1.0, 1.0], [1.0, 1.0], sigma_px=0.0)
    with pytest.raises(ObservationError, match="parameter_covariance of image 'a'"):
        triangulate(models, ["p", "p"], ["a", "b"], [1.0, 1.0], [1.0, 1.0],
                    parameter_covariance={"a": np.eye(2)})


# ------------------------------------------------------------------------- real data
@pytest.fixture(scope="module")
def nice_pair(data_dir):
    return {"L": geoblock.open_model(data_dir / LEFT), "R": geoblock.open_model(data_dir / RIGHT)}


def test_shareloc_readme_backprojections_and_triangulation(nice_pair):
    readme = {("L", 310.0): (7.11582885957905286744562545209, 43.6835627149440313132799929008),
              ("L", 850.0): (7.11526088296757386331137240632, 43.684281179313565246502548689),
              ("R", 355.0): (7.11549436551774139303461197414, 43.6828066638668275345480651595),
              ("R", 985.0): (7.11407954217236504490529114264, 43.6815849651619245719302853104)}
    for (name, h), (lon, lat) in readme.items():
        g = nice_pair[name].backproject(*(L_PX if name == "L" else R_PX), h)
        assert abs(g.lon - lon) < 1e-9 and abs(g.lat - lat) < 1e-9
    t = triangulate(nice_pair, ["p", "p"], ["L", "R"], [L_PX[0], R_PX[0]], [L_PX[1], R_PX[1]])
    assert t.status[0] == Status.CONVERGED
    xyz = np.array(coords.geodetic_to_ecef(t.lon[0], t.lat[0], t.h[0]))
    assert np.max(np.abs(xyz - README_ECEF)) < 1e-3  # measured: 9.4e-5 m
    # shareloc's epipolar-route value of the same match, within its 0.5 m tolerance
    shareloc_epi = (4584341.37359843123704195022583, 572313.675204274943098425865173,
                    4382784.51356450468301773071289)
    assert np.max(np.abs(xyz - shareloc_epi)) < 0.5
    # the README's match is not exact: its rays miss by 0.84 m, 0.8 px residuals
    assert 0.5 < t.miss_m[0] < 1.2 and np.max(np.abs(t.v_col)) < 1.0


@pytest.mark.parametrize("h", [10.0, 300.0])
def test_shareloc_sensor_triangulation_by_colocalisation(data_dir, h):
    left = geoblock.open_model(data_dir / "shareloc/rpc/RPC_P1BP--2017092838284574CP.XML")
    right = geoblock.open_model(data_dir / "shareloc/rpc/RPC_P1BP--2017092838319324CP.XML")
    # shareloc (col 1000.5, row 1500.5) at h: geoblock (row 1500, col 1000)
    g = left.backproject(1500.0, 1000.0, h)
    r, c = right.project(g.lon, g.lat, h)
    t = triangulate({"l": left, "r": right}, ["p", "p"], ["l", "r"], [1500.0, r], [1000.0, c])
    assert t.status[0] == Status.CONVERGED
    assert abs(t.lon[0] - g.lon) < 1e-8 and abs(t.lat[0] - g.lat) < 1e-8
    assert abs(t.h[0] - h) < 8e-3  # measured: 1e-8 m
    assert t.miss_m[0] < 1e-3


def test_asp_dg_example_pair(data_dir):
    a = geoblock.open_model(data_dir / "stereopipeline/tests/dg_example1.xml")
    b = geoblock.open_model(data_dir / "stereopipeline/tests/dg_example2.xml")
    t = triangulate({"1": a, "2": b}, ["p", "p"], ["1", "2"], [10702.0, 10366.0],
                    [27728.0, 30090.0])
    assert t.status[0] == Status.CONVERGED
    assert t.miss_m[0] < 5.0  # ASP: "Triangulation should be better than 5 meters"
    assert np.max(np.abs(np.concatenate([t.v_row, t.v_col]))) < 4.0  # ASP: within 4 px
    assert 0.0 < t.h[0] < 5000.0  # below the cameras, on the Colorado terrain


# ------------------------------------------------------------------------- ICTP route
def test_ictp_accuracy_without_dem_is_the_pairs_miss_vector(nice_pair, stereo):
    from geoblock.adjust.statistics import ictp_accuracy

    ids, images = ["p", "p"], ["L", "R"]
    rows, cols = [L_PX[0], R_PX[0]], [L_PX[1], R_PX[1]]
    d = ictp_accuracy(nice_pair, ids, images, rows, cols, None)
    t = triangulate(nice_pair, ids, images, rows, cols)
    assert (d.status_a == Status.CONVERGED).all() and (d.status_b == Status.CONVERGED).all()
    assert abs(d.distance_3d[0] - t.miss_m[0]) < 1e-3
    # the miss vector is perpendicular to both rays
    miss = np.array(coords.geodetic_to_ecef(d.lon_b, d.lat_b, d.h_b)) - np.array(
        coords.geodetic_to_ecef(d.lon_a, d.lat_a, d.h_a))
    for name, (r, c) in (("L", L_PX), ("R", R_PX)):
        los = nice_pair[name].los(r, c)
        assert abs(float(np.dot(miss[:, 0], los.direction))) < 1e-3 * t.miss_m[0] + 1e-6
    # a perfect three-image block: every pair's miss is zero
    g = stereo["r1"].backproject(np.array([100.0, 500.0]), np.array([300.0, 900.0]), 400.0)
    ids3, images3, r3, c3 = _measure(stereo, g.lon, g.lat, g.h)
    d3 = ictp_accuracy(stereo, ids3, images3, r3, c3, None)
    assert len(d3) == 6 and np.max(d3.distance_3d) < 1e-5
