"""geoblock.localize on synthetic terrain with analytic answers.

The test camera has straight lines of sight in a transverse Mercator plane centred on the
scene: ``x = x0 + gsd * col - k * h``, ``y = y0 - gsd * row``. Looking east (``k > 0``: the
ray moves east as it descends), at ``k`` metres per metre of height. The DEMs are GridDems in
the same plane whose heights depend on ``x`` only and are linear between post centres, so
bilinear interpolation reproduces the profile exactly and the first intersection from the
sensor (the one with the largest height) is computed here segment by segment, independently.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np
import pytest

import geoblock
from geoblock import ParameterSet, SensorModelBase, Status
from geoblock.dem import ConstantDem, GridDem
from geoblock.errors import ConvergenceWarning, GeoblockError, NoIntersectionWarning

TMERC = "+proj=tmerc +lat_0=43.7 +lon_0=7.05 +k=1 +x_0=0 +y_0=0 +ellps=WGS84 +units=m +no_defs"
GSD = 10.0
POST = 30.0  # DEM post spacing, metres


class LineCamera(SensorModelBase):
    """Straight rays in the TMERC plane: x = x0 + gsd col - k h, y = y0 - gsd row."""

    name: ClassVar[str] = "test-line-camera"

    def __init__(self, k: float, x0: float = -2000.0, y0: float = 1000.0) -> None:
        self.k, self.x0, self.y0 = float(k), float(x0), float(y0)

    shape = (200, 400)
    height_range = (-100.0, 3000.0)
    parameters = ParameterSet.empty()

    def with_parameters(self, values):
        return self

    def to_dict(self) -> dict[str, Any]:
        return {"model": self.name, "k": self.k, "x0": self.x0, "y0": self.y0}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]):
        return cls(data["k"], data["x0"], data["y0"])

    def xy(self, row, col, h):
        return (
            self.x0 + GSD * np.asarray(col) - self.k * np.asarray(h),
            self.y0 - GSD * np.asarray(row),
        )

    def image_to_ground(self, row, col, h):
        x, y = self.xy(row, col, h)
        lon, lat = geoblock.coords.transformer(TMERC, "EPSG:4326").transform(x, y)
        return np.asarray(lon), np.asarray(lat)


def profile_dem(z_of_x, x_min=-4000.0, x_max=4000.0, rows=100, interpolation="bilinear"):
    """GridDem in TMERC whose heights are z_of_x at post centres (constant along y)."""
    cols = int((x_max - x_min) / POST)
    xc = x_min + (np.arange(cols) + 0.5) * POST
    heights = np.tile(z_of_x(xc), (rows, 1))
    top = 1000.0 + rows * POST / 2
    dem = GridDem(heights, (POST, 0, x_min, 0, -POST, top), TMERC, interpolation=interpolation)
    return dem, xc, z_of_x(xc)


def first_hit(cam: LineCamera, col: float, xc: np.ndarray, zc: np.ndarray) -> float:
    """Height of the first intersection from the sensor of the ray of ``col`` with the
    piecewise-linear profile through ``(xc, zc)``: the largest h over all segments."""
    best = -math.inf
    xg = cam.x0 + GSD * col  # x at h = 0; the ray is x = xg - k h
    for i in range(len(xc) - 1):
        x1, x2, z1, z2 = xc[i], xc[i + 1], zc[i], zc[i + 1]
        s = (z2 - z1) / (x2 - x1)
        # h = z1 + s (xg - k h - x1)  ->  h (1 + s k) = z1 + s (xg - x1)
        den = 1.0 + s * cam.k
        if den == 0:
            continue
        h = (z1 + s * (xg - x1)) / den
        x = xg - cam.k * h
        if x1 - 1e-9 <= x <= x2 + 1e-9:
            best = max(best, h)
    return best


def check_on_ray_and_dem(cam, dem, row, col, g, tol=1e-3):
    x, y = geoblock.coords.transformer("EPSG:4326", TMERC).transform(g.lon, g.lat)
    xe, ye = cam.xy(row, col, g.h)
    np.testing.assert_allclose(x, xe, atol=1e-6)
    np.testing.assert_allclose(y, ye, atol=1e-6)
    assert np.all(np.abs(g.h - dem.height(g.lon, g.lat)) <= tol)


# ---------------------------------------------------------------- basic behaviour
def test_planar_slope_matches_analytic_answer():
    cam = LineCamera(k=0.4)
    slope = math.tan(math.radians(35))
    dem, xc, zc = profile_dem(lambda x: 800.0 + slope * x)
    col = np.linspace(50, 350, 31)
    row = np.full_like(col, 100.0)
    g, status = geoblock.localize(cam, row, col, dem)
    assert np.all(status == Status.CONVERGED)
    xg = cam.x0 + GSD * col
    truth = (800.0 + slope * xg) / (1 + slope * cam.k)  # independent closed form
    np.testing.assert_allclose(g.h, truth, atol=2e-3)
    check_on_ray_and_dem(cam, dem, row, col, g)


@pytest.mark.parametrize("interpolation", ["nearest", "bilinear", "bicubic"])
def test_constant_dem_and_every_interpolation(interpolation):
    cam = LineCamera(k=0.3)
    dem, _, _ = profile_dem(lambda x: np.full_like(x, 432.1), interpolation=interpolation)
    g, status = geoblock.localize(cam, [20.0, 100.0], [100.0, 300.0], dem)
    assert np.all(status == 0)
    np.testing.assert_allclose(g.h, 432.1, atol=1e-3)
    g2, s2 = geoblock.localize(cam, [20.0, 100.0], [100.0, 300.0], ConstantDem(432.1))
    np.testing.assert_allclose(g2.lon, g.lon, atol=1e-9)
    g3, _ = geoblock.localize(cam, 20.0, 100.0, 432.1)  # a number is a constant DEM
    assert g3.lon.shape == ()


def test_synthetic_models_random_terrain(affine_camera, pushbroom):
    """Any registered model: the point is on the line of sight and on the DEM to 1 mm."""
    res = 30.0 / 111_000
    lon0, lat0 = 6.9, 43.65
    ny, nx = 400, 800
    rng = np.random.default_rng(3)
    base = rng.normal(size=(ny // 20, nx // 20))
    z = 600 + 300 * np.kron(base, np.ones((20, 20)))  # blocky: steep steps
    dem = GridDem(z, (res, 0, lon0, 0, -res, lat0 + ny * res), "EPSG:4326")
    for model in (affine_camera, pushbroom):
        rows, cols = model.shape
        row = rng.uniform(0, rows - 1, 300)
        col = rng.uniform(0, cols - 1, 300)
        g, status = geoblock.localize(model, row, col, dem, warn=False)
        ok = status == 0
        assert ok.mean() > 0.9, np.bincount(status)
        assert np.all(np.isin(status[~ok], [Status.NO_DEM]))
        assert np.all(np.abs(g.h[ok] - dem.height(g.lon[ok], g.lat[ok])) <= 1e-3)
        (r2, c2), _ = model.project_with_status(g.lon[ok], g.lat[ok], g.h[ok])
        assert np.max(np.abs(r2 - row[ok])) < 1e-6 and np.max(np.abs(c2 - col[ok])) < 1e-6


def test_shapes_nan_and_errors():
    cam = LineCamera(k=0.3)
    dem, _, _ = profile_dem(lambda x: 100.0 + 0.1 * x)
    g, status = geoblock.localize(cam, np.full((2, 3), 50.0), [[10.0, np.nan, 30.0]], dem)
    assert g.lon.shape == g.h.shape == status.shape == (2, 3)
    assert np.all(status[:, 1] == Status.INVALID_INPUT) and np.all(np.isnan(g.h[:, 1]))
    assert np.all(status[:, [0, 2]] == 0)
    with pytest.raises(GeoblockError, match="method"):
        geoblock.localize(cam, 1, 1, dem, method="newton")
    with pytest.raises(GeoblockError, match="tolerance"):
        geoblock.localize(cam, 1, 1, dem, tolerance_m=0)


def test_small_slabs_give_the_same_answer():
    cam = LineCamera(k=1.5)
    dem, _, _ = profile_dem(lambda x: 500 + 300 * np.sin(x / 200.0))
    row, col = np.full(50, 80.0), np.linspace(10, 390, 50)
    g1, s1 = geoblock.localize(cam, row, col, dem, warn=False)
    g2, s2 = geoblock.localize(cam, row, col, dem, max_evaluations=7, warn=False)
    np.testing.assert_array_equal(s1, s2)
    np.testing.assert_allclose(g1.h, g2.h, atol=2e-3, equal_nan=True)


# ---------------------------------------------------------------- statuses
def test_outside_dem_is_no_dem():
    cam = LineCamera(k=0.3, x0=50_000.0)  # the footprint is 50 km east of the DEM
    dem, _, _ = profile_dem(lambda x: np.full_like(x, 100.0))
    with pytest.warns(NoIntersectionWarning, match="2 of 2 points have no DEM height"):
        g, status = geoblock.localize(cam, [10.0, 20.0], [10.0, 20.0], dem)
    assert np.all(status == Status.NO_DEM) and np.all(np.isnan(g.lon))


def test_fill_height_covers_outside_and_voids():
    cam = LineCamera(k=0.3)
    dem, _, _ = profile_dem(lambda x: np.where(x > 0, np.nan, 200.0))  # east half void
    col = np.array([100.0, 300.0])  # west (DEM) and east (void) of x = 0
    with pytest.warns(NoIntersectionWarning):
        _, status = geoblock.localize(cam, [100.0, 100.0], col, dem)
    assert list(status) == [Status.CONVERGED, Status.NO_DEM]
    g, status = geoblock.localize(cam, [100.0, 100.0], col, dem, fill_height=0.0)
    assert list(status) == [0, 0]
    np.testing.assert_allclose(g.h, [200.0, 0.0], atol=1e-3)


def test_all_nodata_dem_is_no_dem():
    cam = LineCamera(k=0.3)
    dem, _, _ = profile_dem(lambda x: np.full_like(x, np.nan))
    for method in ("robust", "ray-tracing"):
        with pytest.warns(NoIntersectionWarning, match="no DEM height"):
            _, status = geoblock.localize(cam, [10.0, 50.0], [10.0, 300.0], dem, method=method)
        assert np.all(status == Status.NO_DEM)


def test_ray_crossing_the_terrain_inside_a_void_is_no_dem():
    cam = LineCamera(k=0.5)
    # the answer of col 200 lies near x = 0 - 0.5 * 300; blank the posts there
    dem, _, _ = profile_dem(lambda x: np.where(np.abs(x + 150) < 200, np.nan, 300.0))
    with pytest.warns(NoIntersectionWarning):
        _, status = geoblock.localize(cam, 100.0, 200.0, dem)
    assert status == Status.NO_DEM


def test_model_failure_status_is_kept():
    """The model's own status comes through where it cannot backproject (far outside)."""
    from geoblock_rpc.model import RpcModel

    rpc = RpcModel.example()
    _, own = rpc.backproject_with_status(1e6, 6000.0, 500.0)
    assert own not in (Status.CONVERGED, Status.NO_DEM)
    with pytest.warns(geoblock.GeoblockWarning):
        _, status = geoblock.localize(rpc, [5000.0, 1e6], [6000.0, 6000.0], ConstantDem(500.0))
    assert list(status) == [Status.CONVERGED, own]


# ---------------------------------------------------------------- steep terrain
def cliff(x):
    """Flat at 100 m, then a 70 degree cliff up to 1100 m, then a plateau."""
    s = math.tan(math.radians(70.0))
    return np.clip(100.0 + s * (x - 0.0), 100.0, 1100.0)


def test_70_degree_cliff_robust_exact_ray_tracing_fails():
    cam = LineCamera(k=math.tan(math.radians(25.0)))  # slope * k = 1.28 > 1
    dem, xc, zc = profile_dem(cliff)
    col = np.linspace(160, 260, 41)  # rays that hit the valley floor, the face and the top
    row = np.full_like(col, 60.0)
    g, status = geoblock.localize(cam, row, col, dem)
    assert np.all(status == 0)
    truth = np.array([first_hit(cam, c, xc, zc) for c in col])
    np.testing.assert_allclose(g.h, truth, atol=2e-3)
    check_on_ray_and_dem(cam, dem, row, col, g)
    on_face = (truth > 150) & (truth < 1050)
    assert on_face.sum() >= 5
    # the papers' iteration cannot converge on a face steeper than the rays (|s k| > 1)
    with pytest.warns(ConvergenceWarning):
        g_rt, s_rt = geoblock.localize(cam, row, col, dem, method="ray-tracing")
    assert np.all(s_rt[on_face] != 0)
    assert np.all(np.isin(s_rt[on_face], [Status.DIVERGED, Status.MAX_ITERATIONS]))


def test_narrow_ridge_first_surface_seen():
    """A 600 m ridge with 70 degree flanks and a 145 m crest, in front of a valley: robust
    finds the ridge; the papers' iteration does not converge on the flanks, and for rays that
    meet the crest it lands on the valley floor behind the ridge (the wrong surface)."""

    def ridge(x):
        return 100.0 + np.clip(800.0 - math.tan(math.radians(70.0)) * np.abs(x), 0.0, 600.0)

    cam = LineCamera(k=1.0)  # 45 degree rays
    dem, xc, zc = profile_dem(ridge)
    # col such that the ray passes the crest region: x(h) = x0 + 10 col - h
    col = np.linspace(150, 300, 31)
    row = np.full_like(col, 60.0)
    g, status = geoblock.localize(cam, row, col, dem)
    assert np.all(status == 0)
    truth = np.array([first_hit(cam, c, xc, zc) for c in col])
    np.testing.assert_allclose(g.h, truth, atol=2e-3)
    on_ridge = truth > 150
    assert on_ridge.sum() >= 5
    g_rt, s_rt = geoblock.localize(cam, row, col, dem, method="ray-tracing", warn=False)
    wrong = (s_rt != 0) | (np.abs(g_rt.h - truth) > 1.0)
    assert np.all(wrong[on_ridge])
    # where it converges on those rays, it is on the valley floor behind the ridge
    landed = on_ridge & (s_rt == 0)
    assert landed.any() and np.all(np.abs(g_rt.h[landed] - 100.0) < 1e-2)


def test_grazing_ray_along_a_slope():
    """Terrain descending away from the sensor almost as steeply as the rays: f'(h) = 0.05.
    The papers' iteration contracts by 0.95 per step and hits the cap."""
    k = 1.2
    s = 0.95 / k
    cam = LineCamera(k=k)
    dem, xc, zc = profile_dem(lambda x: np.clip(2000.0 - s * (x + 3000.0), 100.0, 2000.0))
    col = np.linspace(141, 151, 11)  # answers from 1900 m down to 200 m
    row = np.full_like(col, 30.0)
    g, status = geoblock.localize(cam, row, col, dem)
    assert np.all(status == 0)
    truth = np.array([first_hit(cam, c, xc, zc) for c in col])
    np.testing.assert_allclose(g.h, truth, atol=2e-2)  # 1 mm vertical = 20 mm along h here
    check_on_ray_and_dem(cam, dem, row, col, g)
    with pytest.warns(ConvergenceWarning):
        _, s_rt = geoblock.localize(cam, row, col, dem, method="ray-tracing", h0=2000.0)
    assert np.all(s_rt == Status.MAX_ITERATIONS)


def test_ray_tracing_agrees_on_gentle_terrain():
    cam = LineCamera(k=0.3)
    dem, xc, zc = profile_dem(lambda x: 400 + 150 * np.sin(x / 500.0))
    col = np.linspace(20, 380, 37)
    row = np.full_like(col, 50.0)
    g1, s1 = geoblock.localize(cam, row, col, dem)
    g2, s2 = geoblock.localize(cam, row, col, dem, method="ray-tracing")
    assert np.all(s1 == 0) and np.all(s2 == 0)
    truth = np.array([first_hit(cam, c, xc, zc) for c in col])
    np.testing.assert_allclose(g1.h, truth, atol=2e-3)
    np.testing.assert_allclose(g2.h, truth, atol=5e-3)


def test_nearest_dem_vertical_step():
    """Nearest-neighbour DEMs are step functions: the answer on a step is the wall."""
    cam = LineCamera(k=0.5)
    dem, _, _ = profile_dem(lambda x: np.where(x < 0, 100.0, 700.0), interpolation="nearest")
    g, status = geoblock.localize(cam, 50.0, 150.0, dem)  # x(h) = -500 - 0.5 h
    assert status == 0
    np.testing.assert_allclose(g.h, 100.0, atol=1e-3)
    # posts at x = -25 (100 m) and 5 (700 m): the wall is halfway, at x = -10; the ray
    # x(h) = 600 - 2 h meets it at h = 305
    cam2 = LineCamera(k=2.0)
    g, status = geoblock.localize(cam2, 50.0, 260.0, dem)
    assert status == 0
    x, _ = geoblock.coords.transformer("EPSG:4326", TMERC).transform(g.lon, g.lat)
    assert abs(float(x) + 10.0) < 1e-2 and abs(float(g.h) - 305.0) < 1e-2
