"""The per-pixel accuracy layer (issue 28, item 3): propagation, lattice, geolocation, jobs."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from affine import Affine

import geoblock
from geoblock import coords
from geoblock.io import open_model
from geoblock.models import ImageCorrection
from geoblock.models.uncertainty import (
    AccuracyWarning,
    ModelPosterior,
    NoAccuracyError,
    ground_error,
    model_accuracy,
)
from geoblock.ortho import OutputGrid
from geoblock.ortho.accuracy import (
    ACCURACY_TAG,
    accuracy_chunk,
    accuracy_job,
    accuracy_layer,
    accuracy_path,
)
from geoblock.pixels import pixel_to_map

VENTOUX_RPC = "shareloc/rpc/phr_ventoux/RPC_PHR1B_P_201308051042194_SEN_690908101-001.XML"
SRTM = "shareloc/dtm/srtm_ventoux/srtm90_non_void_filled/N44E005.hgt"
GEOID = "shareloc/dtm/geoid/egm96_15.gtx"


def _refined_rpc(data_dir):
    """The Ventoux RPC under an RPCV-1 correction, and a posterior of its six parameters
    (0.3/0.4 px shifts correlated 0.5, 1e-3 for the slopes)."""
    rpc = open_model(data_dir / VENTOUX_RPC)
    model = ImageCorrection(rpc, order=1)
    cov = np.diag([0.3, 1e-3, 2e-3, 0.4, 1e-3, 1e-3]) ** 2
    cov[0, 3] = cov[3, 0] = 0.5 * 0.3 * 0.4
    return model, ModelPosterior(model.parameters.names, cov, 0.9, 40, "test")


def _enu_scatter(model, values, row, col, h, ref):
    """(D, N, 2) east/north offsets of image points located with each row of ``values``."""
    out = []
    for v in values:
        g = model.with_parameters(v).backproject(row, col, h)
        de, dn, _ = coords.enu_offsets(ref.lon, ref.lat, ref.h, g.lon, g.lat, g.h)
        out.append(np.stack([de, dn], axis=-1))
    return np.array(out)


@pytest.mark.parametrize("which", ["rpc", "spot5"])
def test_propagation_matches_monte_carlo(data_dir, which):
    """The ground scatter of image points located with parameters drawn from the covariance
    (through its Cholesky factor) matches the predicted model-part covariance."""
    if which == "rpc":
        model, post = _refined_rpc(data_dir)
        names, cov = post.names, post.covariance
    else:
        model = open_model(data_dir / "cosicorr3d/test_dataset/SPOT5.DIM")
        acc = model_accuracy(model)
        names, cov = acc.names, acc.covariance
    rows, cols = model.shape
    row = np.array([0.1 * rows, 0.5 * rows, 0.9 * rows])
    col = np.array([0.8 * cols, 0.5 * cols, 0.1 * cols])
    h = np.array([300.0, 900.0, 1500.0])
    ref = model.backproject(row, col, h)
    pred = ground_error(model, names, cov, image=(row, col, h))
    idx = [model.parameters.index(n) for n in names]
    rng = np.random.default_rng(28)
    draws = 1500
    z = rng.standard_normal((draws, len(names))) @ np.linalg.cholesky(cov).T
    values = np.tile(model.parameters.values, (draws, 1))
    values[:, idx] += z
    scatter = _enu_scatter(model, values, row, col, h, ref)  # (D, N, 2)
    for k in range(row.size):
        got = np.cov(scatter[:, k].T)
        want = pred.model[k]
        # sampling error of a variance with 1500 draws: sqrt(2/1500) = 3.7 %
        assert np.trace(got) == pytest.approx(np.trace(want), rel=0.08)
        assert got[0, 0] == pytest.approx(want[0, 0], rel=0.12)
        assert got[1, 1] == pytest.approx(want[1, 1], rel=0.12)
        corr = lambda c: c[0, 1] / math.sqrt(c[0, 0] * c[1, 1])  # noqa: E731
        assert corr(got) == pytest.approx(corr(want), abs=0.06)
    np.testing.assert_allclose(pred.sigma, np.sqrt(np.trace(pred.covariance, axis1=1, axis2=2)))


def test_dem_term_is_tan_incidence_on_a_simulated_view():
    """A simulated SPOT-1A view at 10 deg incidence: |J_g^-1 J_h| is tan(10 deg) at the scene
    centre, and the DEM part is sigma_DEM^2 tan^2 along the view's azimuth."""
    from geoblock.simulate.sensors import SPOT1A_SMALL, incidence_angle, simulate_sensor

    true = simulate_sensor(SPOT1A_SMALL).true_model
    rows, cols = true.shape
    rc, cc = (rows - 1) / 2.0, (cols - 1) / 2.0
    h = SPOT1A_SMALL.centre_h
    inc = abs(incidence_angle(true, rc, cc, h))
    assert inc == pytest.approx(10.0, abs=0.05)
    err = ground_error(true, (), np.zeros((0, 0)), image=([rc], [cc], [h]), dem_sigma=7.0)
    tan = math.tan(math.radians(inc))
    assert float(np.hypot(*err.displacement[0])) == pytest.approx(tan, rel=1e-4)
    assert float(np.trace(err.dem[0])) == pytest.approx((7.0 * tan) ** 2, rel=2e-4)
    assert np.all(err.model == 0)


@pytest.mark.parametrize("path", [VENTOUX_RPC, "cosicorr3d/test_dataset/SPOT5.DIM",
                                  "stereopipeline/tests/dg_example1.xml"])
def test_dem_term_follows_the_line_of_sight(data_dir, path):
    """On real models the displacement per metre of height is tan of the angle between the
    line of sight (``los``, from backprojections at two heights) and the ellipsoid normal."""
    model = open_model(data_dir / path)
    rows, cols = model.shape
    row = np.array([0.0, rows / 2, rows - 1.0])
    col = np.array([cols - 1.0, cols / 2, 0.0])
    lo, hi = model.height_range
    h = np.full(3, 0.5 * (lo + hi))
    err = ground_error(model, (), np.zeros((0, 0)), image=(row, col, h), dem_sigma=1.0)
    up = coords.enu_rotation(err.lon, err.lat)[:, 2]
    cos = -np.sum(model.los(row, col).direction * up, axis=1)
    np.testing.assert_allclose(np.hypot(*err.displacement.T), np.tan(np.arccos(cos)),
                               rtol=2e-3)


def test_sources_of_the_statement(data_dir):
    model, post = _refined_rpc(data_dir)
    acc = model_accuracy(model, post)
    assert acc.kind == "posterior" and acc.names == post.names
    # an RPC with ERR_BIAS: its stated location accuracy, isotropic
    dg = open_model(data_dir / "gdal-autotest/gcore/data/md_dg.RPB")
    acc = model_accuracy(dg)
    assert acc.kind == "a-priori" and acc.location_sigma_m == dg.location_accuracy_m
    err = ground_error(dg, acc.names, acc.covariance, ground=([dg.ground_seed()[0]],
                       [dg.ground_seed()[1]], [50.0]), location_sigma_m=acc.location_sigma_m)
    assert err.sigma[0] == pytest.approx(math.sqrt(2) * dg.location_accuracy_m)
    # a linescan preset: its finite sigmas
    spot = open_model(data_dir / "cosicorr3d/test_dataset/SPOT5.DIM").with_parameter_set("dg")
    acc = model_accuracy(spot)
    assert acc.kind == "a-priori" and len(acc.names) == 12
    # nothing stated: refused, saying how to get one
    with pytest.raises(NoAccuracyError, match="geoblock adjust"):
        model_accuracy(model)
    with pytest.raises(NoAccuracyError, match="does not have"):
        model_accuracy(model.model, post)
    # adjustable parameters with infinite sigma are left out, with a warning
    partial = ImageCorrection(model.model, 0, sigmas=[0.5, np.inf])
    with pytest.warns(AccuracyWarning, match="b0"):
        acc = model_accuracy(partial)
    assert acc.names == ("a0",) and acc.left_out == ("b0",)


def _coarse(grid, factor):
    t = grid.transform
    return OutputGrid(grid.crs, Affine(t.a * factor, 0, t.c, 0, t.e * factor, t.f),
                      (grid.shape[0] // factor, grid.shape[1] // factor))


def _ventoux_dem(data_dir):
    return geoblock.open_dem(data_dir / SRTM, geoid=data_dir / GEOID, nodata="fill")


@pytest.mark.parametrize("case", ["ventoux", "spot5", "dg"])
def test_lattice_agrees_with_exact(data_dir, case):
    """The lattice value agrees with the exact per-pixel value to 1 % (real models; the
    Ventoux RPC over the real SRTM relief)."""
    if case == "ventoux":
        model, post = _refined_rpc(data_dir)
        dem = _ventoux_dem(data_dir)
        grid = OutputGrid.from_bounds("EPSG:32631", (672000, 4894000, 680000, 4902000), 20.0)
    else:
        path = {"spot5": "cosicorr3d/test_dataset/SPOT5.DIM",
                "dg": "stereopipeline/tests/dg_example1.xml"}[case]
        model, post = open_model(data_dir / path), None
        dem = 1500.0 if case == "dg" else 800.0
        full = OutputGrid.for_model(model, geoblock.open_dem(f"const:{dem}"))
        grid = _coarse(full, max(full.shape) // 160 + 1)
    job = accuracy_job(model, dem, grid, dem_sigma=5.0, posterior=post, chunks=4096)
    window = (0, grid.shape[0], 0, grid.shape[1])
    lattice = accuracy_chunk(job.model, job.accuracy, job.dem, 5.0, grid, window,
                             job.tolerance)[0]
    exact = accuracy_chunk(job.model, job.accuracy, job.dem, 5.0, grid, window, 0.0)[0]
    ok = np.isfinite(exact)
    assert ok.mean() > 0.5
    np.testing.assert_array_equal(np.isfinite(lattice), ok)
    assert float(np.nanmax(np.abs(lattice / exact - 1))) < 0.01
    # and the value is the propagation's at the pixel's ground point
    r, c = np.argwhere(ok)[len(np.argwhere(ok)) // 2]
    x, y = pixel_to_map(grid.transform, r, c)  # pixel centres at integers
    lon, lat = coords.transformer(grid.crs, "EPSG:4326").transform(x, y)
    h = job.dem.height(lon, lat)
    e = ground_error(job.model, job.accuracy.names, job.accuracy.covariance,
                     ground=([lon], [lat], [h]), dem_sigma=5.0,
                     location_sigma_m=job.accuracy.location_sigma_m)
    assert float(exact[r, c]) == pytest.approx(float(e.sigma[0]), rel=1e-6)


def test_layer_on_the_ortho_grid_and_chunk_independent(data_dir):
    """The layer has the ortho's grid exactly, nodata exactly where the ortho has none, and
    the same values whatever the chunking and through dask or the job."""
    model, post = _refined_rpc(data_dir)
    image = data_dir / "shareloc/image/phr_ventoux/left_image.tif"
    dem = _ventoux_dem(data_dir)
    ortho, layer = geoblock.ortho.orthorectify(image, model, dem, accuracy=True,
                                               dem_sigma=4.0, posterior=post, chunks=128)
    assert layer.dims == ("band", "y", "x") and layer.sizes["band"] == 1
    assert layer.dtype == np.float32
    np.testing.assert_array_equal(layer.x, ortho.x)
    np.testing.assert_array_equal(layer.y, ortho.y)
    assert layer.spatial_ref.attrs == ortho.spatial_ref.attrs
    o, a = (v.values for v in __import__("dask").compute(ortho, layer))
    valid = o[0] != ortho.attrs["_FillValue"]
    np.testing.assert_array_equal(np.isfinite(a[0]), valid)
    assert 0.5 < float(np.nanmin(a)) <= float(np.nanmax(a)) < 1.5
    assert layer.attrs["tags"][f"{ACCURACY_TAG}_COVARIANCE"] == "posterior"
    # other chunks, unmasked: the same values where the ortho is valid
    other = accuracy_layer(model, dem, _grid_of(ortho), dem_sigma=4.0, posterior=post,
                           chunks=(77, 300)).values
    np.testing.assert_array_equal(other[0][valid], a[0][valid])
    # the job's chunks without dask: the same bytes
    job = accuracy_job(model, dem, _grid_of(ortho), dem_sigma=4.0, posterior=post,
                       chunks=200)
    tiles = np.full(a.shape, np.nan, np.float32)
    for w in job.windows():
        tiles[:, w[0]:w[1], w[2]:w[3]] = job.chunk(w)
    np.testing.assert_array_equal(tiles[0][valid], a[0][valid])


def _grid_of(data):
    from geoblock.ortho.mosaic import _grid_of as grid_of

    return grid_of(data, 0)


def test_dem_sigma_is_required_and_checked(data_dir):
    model, post = _refined_rpc(data_dir)
    with pytest.raises(ValueError, match="dem_sigma"):
        geoblock.ortho.orthorectify(np.zeros((10, 10), np.uint8), model, 0.0, accuracy=True,
                                    crop=False, posterior=post)
    for bad in (-1.0, float("nan"), True):
        with pytest.raises(ValueError, match="dem_sigma"):
            accuracy_job(model, 0.0, dem_sigma=bad, posterior=post)


def test_accuracy_path():
    assert accuracy_path("a/b.tif") == "a/b_accuracy.tif"
    assert accuracy_path("c.TIFF") == "c_accuracy.tif"


def test_no_warning_from_a_full_statement(data_dir):
    model, post = _refined_rpc(data_dir)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        model_accuracy(model, post)
