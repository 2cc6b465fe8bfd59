"""Synthetic terrain: relief and slopes as requested, determinism, measured DEMs of a set RMSEz,
and the GeoTIFFs written opening in geoblock and rasterio with their vertical datum."""

from __future__ import annotations

import math

import numpy as np
import pytest
import rasterio

from geoblock.dem import GridDem, RasterDem
from geoblock.errors import DemError
from geoblock.io import open_dem
from geoblock.simulate.terrain import Grid, Terrain, fractal_terrain, measured_dem, ridged_terrain


@pytest.fixture(scope="module")
def taiwan_grid():
    """Teo et al.'s block in miniature: 40 m posts in UTM 51N."""
    return Grid.around(121.0, 24.0, (8000.0, 6000.0), 40.0)


@pytest.fixture(scope="module")
def almeria():
    """Aguilar et al.'s relief (50-850 m) on a 2 m grid, 2 km square."""
    return fractal_terrain(Grid.around(-2.4, 36.8, 2000.0, 2.0), (50.0, 850.0), seed=3)


@pytest.mark.parametrize("make", [ridged_terrain, fractal_terrain])
def test_relief_and_steepest_slope_as_requested(taiwan_grid, make):
    t = make(taiwan_grid, (0.0, 3800.0), max_slope_deg=70.0, seed=1)
    assert t.shape == taiwan_grid.shape == (150, 200)
    assert t.relief == pytest.approx((0.0, 3800.0), abs=1e-9)
    assert t.slope_deg().max() == pytest.approx(70.0, abs=0.25)
    assert t.heights.flags.writeable is False


def test_relief_without_slope_target(almeria):
    assert almeria.relief == pytest.approx((50.0, 850.0), abs=1e-9)
    assert almeria.vertical == "ellipsoid"
    assert almeria.crs.to_epsg() == 32630


def test_same_seed_same_terrain_other_seed_other_terrain(taiwan_grid):
    a = ridged_terrain(taiwan_grid, (0, 3800), max_slope_deg=60, seed=7)
    b = ridged_terrain(taiwan_grid, (0, 3800), max_slope_deg=60, seed=7)
    c = ridged_terrain(taiwan_grid, (0, 3800), max_slope_deg=60, seed=8)
    np.testing.assert_array_equal(a.heights, b.heights)
    assert np.abs(a.heights - c.heights).max() > 100.0


def test_slope_of_known_planes():
    """A 30 degree plane in UTM, and one in a geographic grid (metric spacing from degrees)."""
    g = Grid.from_bounds((500000.0, 4000000.0, 501000.0, 4001000.0), 10.0, "EPSG:32631")
    x, _ = g.xy()
    plane = Terrain(np.broadcast_to(x * math.tan(math.radians(30)), g.shape) - 5e4, g)
    np.testing.assert_allclose(plane.slope_deg(), 30.0, atol=1e-9)
    gg = Grid.from_bounds((5.0, 44.0, 5.01, 44.01), 0.0001, "EPSG:4326")
    _, lat = gg.xy()
    h = (lat - 44.0) * math.radians(1.0) * 6378137.0 * math.tan(math.radians(30))
    geo = Terrain(np.broadcast_to(h[:, None], gg.shape), gg)
    np.testing.assert_allclose(geo.slope_deg(), 30.0, atol=1e-6)


def test_unreachable_slope_and_bad_relief_are_refused(taiwan_grid):
    with pytest.raises(DemError, match="out of reach"):
        fractal_terrain(taiwan_grid, (0.0, 10.0), max_slope_deg=80.0)
    with pytest.raises(DemError, match="relief"):
        fractal_terrain(taiwan_grid, (100.0, 100.0))
    with pytest.raises(DemError, match="north-up"):
        Grid((1.0, 0.5, 0.0, 0.0, -1.0, 0.0), (10, 10), "EPSG:32631")


@pytest.mark.parametrize(("spacing", "rmse"), [(2.0, 0.31), (5.0, 1.75), (20.0, 5.82)])
def test_measured_dem_rmsez_against_truth(almeria, spacing, rmse):
    """Aguilar et al.'s three DEMs: RMSEz checked at independent random points."""
    measured = measured_dem(almeria, spacing, rmse, seed=11)
    assert measured.grid.resolution == pytest.approx((spacing, spacing))
    assert measured.crs == almeria.crs and measured.vertical == almeria.vertical
    truth_dem, dem = almeria.to_dem(), measured.to_dem()
    rng = np.random.default_rng(99)
    x, y = measured.grid.xy()
    margin = spacing  # inside the measured posts' hull
    px = rng.uniform(x[0] + margin, x[-1] - margin, 20000)
    py = rng.uniform(y[-1] + margin, y[0] - margin, 20000)
    from geoblock.coords import transformer

    lon, lat = transformer(almeria.crs, "EPSG:4326").transform(px, py)
    dz = dem.height(lon, lat) - truth_dem.height(lon, lat)
    assert np.isfinite(dz).all()
    assert np.sqrt(np.mean(dz**2)) == pytest.approx(rmse, rel=0.08)
    assert abs(np.mean(dz)) < 0.5 * rmse


def test_measured_dem_refuses_an_rmsez_below_the_resampling_error(taiwan_grid):
    truth = ridged_terrain(taiwan_grid, (0, 3800), seed=1)
    with pytest.raises(DemError, match="resampling the truth to 400.0 m alone"):
        measured_dem(truth, 400.0, 0.5)


def test_to_dem_samples_the_posts(almeria):
    dem = almeria.to_dem()
    assert isinstance(dem, GridDem)
    lon, lat = almeria.grid.lonlat()
    np.testing.assert_allclose(dem.height(lon[5:9, 7:12], lat[5:9, 7:12]),
                               almeria.heights[5:9, 7:12], atol=1e-6)


@pytest.mark.parametrize("crs", ["EPSG:32651", "EPSG:4326"])
def test_written_terrain_opens_with_its_datum(tmp_path, crs):
    if crs == "EPSG:4326":
        grid = Grid.from_bounds((121.0, 24.0, 121.05, 24.04), 0.0005, crs)
    else:
        grid = Grid.around(121.0, 24.0, 4000.0, 50.0, crs)
    t = fractal_terrain(grid, (0.0, 3800.0), seed=4)
    path = t.write(tmp_path / "dem.tif")
    dem = open_dem(path)
    assert isinstance(dem, RasterDem) and dem.vertical == "ellipsoid"
    lon, lat = grid.lonlat()
    np.testing.assert_allclose(dem.height(lon, lat), t.heights, atol=1e-3)  # float32 in the file
    with rasterio.open(path) as ds:
        assert ds.shape == grid.shape and ds.dtypes[0] == "float32"
        assert ds.tags(1)["GEOBLOCK_VERTICAL"] == "ellipsoid"
        np.testing.assert_allclose(ds.read(1), t.heights, atol=1e-3)


def test_geoid_terrain_round_trip(tmp_path, data_dir):
    egm96 = data_dir / "shareloc" / "dtm" / "geoid" / "egm96_15.gtx"
    grid = Grid.around(7.05, 43.70, 3000.0, 30.0)
    ell = fractal_terrain(grid, (100.0, 900.0), seed=5)
    geo = ell.with_vertical("geoid", egm96)
    assert geo.vertical == "geoid"
    n = geo.heights - ell.heights
    assert -60 < n.mean() < -40  # EGM96 is ~48-50 m above the ellipsoid near Nice
    lon, lat = (a[1:-1, 1:-1] for a in grid.lonlat())  # GridDem: NaN past the outer centres
    np.testing.assert_allclose(geo.to_dem(egm96).height(lon, lat), ell.heights[1:-1, 1:-1],
                               atol=1e-6)
    dem = open_dem(geo.write(tmp_path / "geoid.tif"), geoid=egm96)
    assert dem.vertical == "geoid"
    np.testing.assert_allclose(dem.height(lon, lat), ell.heights[1:-1, 1:-1], atol=1e-3)


# ---------------------------------------------------------------------------- lean measured DEM
def test_measured_dem_is_deterministic_and_finite_to_its_edges():
    """Same seed, same DEM; another seed, another. A 2 m DEM from a 4 m truth has posts in the
    half cell past the truth's outer centres: they take the edge value (no NaN border)."""
    truth = fractal_terrain(Grid.around(-2.4, 36.8, 1200.0, 4.0), (50.0, 850.0), seed=3)
    a = measured_dem(truth, 2.0, 0.5, seed=5)
    b = measured_dem(truth, 2.0, 0.5, seed=5)
    c = measured_dem(truth, 2.0, 0.5, seed=6)
    np.testing.assert_array_equal(a.heights, b.heights)
    assert np.abs(a.heights - c.heights).max() > 0.1
    assert a.shape == (600, 600) and np.isfinite(a.heights).all()
    assert a.heights.flags.writeable is False and a.heights.dtype == np.float64


def test_separable_resampling_matches_pointwise_bilinear(almeria):
    """The strip-wise, 1-D-index resampling against geoblock's point sampler on every post."""
    from geoblock._affine import apply as affine_apply
    from geoblock.dem.sampling import sample
    from geoblock.simulate import terrain as t

    grid = almeria.grid.with_spacing_m(4.7)
    x, y = grid.xy()
    xx, yy = np.meshgrid(x, y)
    col, row = affine_apply(~almeria.grid.transform, xx, yy)
    rows, cols = almeria.shape
    expected = sample(almeria.heights, np.clip(row - 0.5, 0, rows - 1.000001),
                      np.clip(col - 0.5, 0, cols - 1.000001), "bilinear")
    np.testing.assert_allclose(t._resampled(almeria, grid), expected, rtol=0, atol=1e-6)


def test_noise_field_has_the_gaussian_covariance_asked():
    """Unit variance; lag-L correlation exp(-1) (covariance exp(-d^2 / L^2)) along both axes;
    white noise uncorrelated at lag 1."""
    from geoblock.simulate.terrain import _noise_field

    length = 8.0
    corr = _noise_field((700, 650), length, 0.0, np.random.default_rng(1)).astype(float)
    assert corr.dtype == np.float64 and corr.shape == (700, 650)
    assert corr.mean() == pytest.approx(0.0, abs=1e-6) and corr.std() == pytest.approx(1.0, 1e-5)
    lag = int(length)
    assert np.mean(corr[:, lag:] * corr[:, :-lag]) == pytest.approx(math.exp(-1.0), abs=0.06)
    assert np.mean(corr[lag:] * corr[:-lag]) == pytest.approx(math.exp(-1.0), abs=0.06)
    assert np.mean(corr[:, 4:] * corr[:, :-4]) == pytest.approx(math.exp(-0.25), abs=0.06)
    white = _noise_field((300, 300), length, 1.0, np.random.default_rng(2)).astype(float)
    assert white.std() == pytest.approx(1.0, abs=0.02)
    assert abs(np.mean(white[:, 1:] * white[:, :-1])) < 0.02


def test_strip_wise_slope_equals_the_whole_grid_gradient(almeria, monkeypatch):
    from geoblock.simulate import terrain as t

    monkeypatch.setattr(t, "_STRIP_POSTS", 7 * almeria.shape[1])  # strips of 7 rows
    dx, dy = almeria.grid.spacing_m()
    gy, gx = np.gradient(almeria.heights)
    expected = np.degrees(np.arctan(np.hypot(gx / dx[:, None], gy / dy)))
    np.testing.assert_allclose(almeria.slope_deg(), expected, rtol=0, atol=1e-12)
    assert t._max_slope(almeria.heights, dx, dy) == pytest.approx(expected.max(), abs=1e-12)
