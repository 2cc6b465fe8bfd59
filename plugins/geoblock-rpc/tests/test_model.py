"""The RPC00B model: kernels against references, localisation on hard cases, GDAL's values."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from geoblock_rpc import RpcModel, reference

import geoblock
from geoblock import Status
from geoblock.models import SensorModelBase
from geoblock.testing import SensorModelContract

DATA = Path(
    os.environ.get(
        "GEOBLOCK_TEST_DATA", Path(__file__).resolve().parents[4] / "shared" / "data"
    )
)

#: RPC files of every format in ../shared/data (the readers' tests check each opens)
FILES = [
    "gdal-autotest/gcore/data/rpc.vrt",
    "gdal-autotest/gcore/data/rpc_5395.vrt",
    "gdal-autotest/gcore/data/test_rpc.txt",
    "gdal-autotest/gcore/data/md_dg.RPB",
    "gdal-autotest/extracted/transformer_11_rpc.vrt",
    "gdal-autotest/extracted/transformer_15_rpc.vrt",
    "rpcm/test_rpc_files/20191015_073816_ssc1d3_0011_basic_l1a_panchromatic_dn_RPC.TXT",
    "rpcm/test_rpc_files/rpc_IKONOS.txt",
    "rpcm/test_rpc_files/rpc_PLEIADES.xml",
    "rpcm/test_rpc_files/rpc_WV2.xml",
    "shareloc/rpc/PHR1B_P_201709281038393_SEN_PRG_FC_178609-001.geom",
    "shareloc/rpc/PHR1B_P_201709281038393_SEN_PRG_FC_178609-001.tif",
    "shareloc/rpc/RPC_PHR1B_P_201709281038393_SEN_PRG_FC_178609-001.XML",
    "shareloc/rpc/wv3_20.NTF",
]


def open_rpc(relative: str) -> RpcModel:
    path = DATA / relative
    if not path.is_file():
        pytest.skip(f"real test data not found: {path} (set GEOBLOCK_TEST_DATA)")
    # model="rpc": PHRDIMAP_*.XML also carries a physical model, which geoblock-spot reads
    # first when no model is named
    model = geoblock.open_model(path, model="rpc")
    assert isinstance(model, RpcModel)
    return model


def image_sample(model: RpcModel, n: int, seed: int = 0):
    """Random image points over the whole image (pixel edges included) and height range."""
    rng = np.random.default_rng(seed)
    rows, cols = model.shape
    return (
        rng.uniform(-0.5, rows - 0.5, n),
        rng.uniform(-0.5, cols - 0.5, n),
        rng.uniform(*model.height_range, n),
    )


# ---------------------------------------------------------------------- kernels vs reference
@pytest.mark.parametrize("relative", [None, *FILES])
def test_numba_projection_equals_the_numpy_reference(relative):
    model = RpcModel.example() if relative is None else open_rpc(relative)
    r, c, h = image_sample(model, 2000)
    g, status = model.backproject_with_status(r, c, h)
    ok = status == Status.CONVERGED
    (row, col), _ = model.project_with_status(g.lon, g.lat, g.h)
    ref_row, ref_col = reference.project(model.rpc, g.lon, g.lat, g.h)
    scale = max(abs(model.rpc.line_scale), abs(model.rpc.samp_scale))
    assert np.max(np.abs(row[ok] - ref_row[ok])) <= 1e-12 * scale + 1e-9
    assert np.max(np.abs(col[ok] - ref_col[ok])) <= 1e-12 * scale + 1e-9


#: RPCs with image regions that no ground point maps to (checked below by a dense search)
DEGENERATE = {"stereopipeline/tests/sample.RPB": 0.95}  # ASP disabled its own test of it


def test_localisation_round_trip_on_10k_points(rpc_file):
    """Every RPC file: <= 1e-6 px over the image and the height range; a status for the rest,
    never an exception."""
    model = open_rpc(rpc_file)
    r, c, h = image_sample(model, 10_000, seed=1)
    g, status = model.backproject_with_status(r, c, h)
    ok = status == Status.CONVERGED
    assert ok.mean() >= DEGENERATE.get(rpc_file, 0.99), np.bincount(status)
    (row, col), pstatus = model.project_with_status(g.lon, g.lat, g.h)
    assert np.all(pstatus[ok] == Status.CONVERGED)
    assert np.max(np.hypot(row[ok] - r[ok], col[ok] - c[ok])) <= 1e-6
    assert np.all(np.isnan(g.lon[~ok])) and np.all(np.isnan(g.h[~ok]))


def test_points_that_fail_on_a_degenerate_rpc_have_no_solution():
    """sample.RPB (denominators with -7 P^2 terms) folds: image points without a ground
    point get MAX_ITERATIONS, and a dense search confirms none lies within 1 px."""
    model = open_rpc("stereopipeline/tests/sample.RPB")
    rpc = model.rpc
    r, c, h = image_sample(model, 2000, seed=1)
    _, status = model.backproject_with_status(r, c, h)
    failed = np.flatnonzero(status != Status.CONVERGED)[:4]
    assert failed.size
    big_l, big_p = np.meshgrid(np.linspace(-1.5, 1.5, 601), np.linspace(-1.5, 1.5, 601))
    lon, lat = rpc.long_off + big_l * rpc.long_scale, rpc.lat_off + big_p * rpc.lat_scale
    for i in failed:
        row, col = reference.project(rpc, lon, lat, np.full(lon.shape, h[i]))
        assert np.nanmin(np.hypot(row - r[i], col - c[i])) > 1.0


def test_numba_localisation_agrees_with_the_generic_newton():
    """The base class's Newton (numeric Jacobian, independent code) finds the same points."""
    model = RpcModel.example()
    r, c, h = image_sample(model, 500, seed=2)
    fast = model.backproject(r, c, h)
    lon, lat, status = SensorModelBase._newton_image_to_ground(model, r, c, h)
    assert np.all(status == Status.CONVERGED)
    assert np.max(np.abs(fast.lon - lon)) < 1e-10 and np.max(np.abs(fast.lat - lat)) < 1e-10


def test_analytic_partials_equal_numeric_ones():
    model = RpcModel.example()
    g = model.backproject(*image_sample(model, 50, seed=3))
    analytic = model.partials_ground(g.lon, g.lat, g.h)
    numeric = SensorModelBase.partials_ground(model, g.lon, g.lat, g.h)
    assert np.max(np.abs(analytic - numeric)) <= 1e-6 * np.max(np.abs(analytic))


# ---------------------------------------------------------------------- domain and statuses
def test_points_outside_the_domain_get_a_status_not_an_exception():
    model = RpcModel.example()
    rpc = model.rpc
    lon = rpc.long_off + np.array([0.0, 1.6, -3.0, 0.0, 0.0]) * rpc.long_scale
    lat = rpc.lat_off + np.array([0.0, 0.0, 0.0, 1.7, 0.0]) * rpc.lat_scale
    h = rpc.height_off + np.array([0.0, 0.0, 0.0, 0.0, 6.0]) * rpc.height_scale
    (row, col), status = model.project_with_status(lon, lat, h)
    assert list(status) == [Status.CONVERGED] + [Status.OUT_OF_DOMAIN] * 4
    assert np.isfinite(row[0]) and np.isnan(row[1:]).all()
    with pytest.warns(geoblock.errors.OutOfBoundsWarning, match="4 of 5 points"):
        model.project(lon, lat, h)
    _, status = model.backproject_with_status(
        [0.0, -30000.0, 0.0], [0.0, 0.0, 0.0], [500.0, 500.0, 1e5]
    )
    assert status[0] == Status.CONVERGED and status[1] != Status.CONVERGED
    assert status[2] == Status.OUT_OF_DOMAIN
    _, status = model.project_with_status([np.nan, 7.05], 43.7, 500.0)
    assert list(status) == [Status.INVALID_INPUT, Status.CONVERGED]


def test_domain_limits_are_part_of_the_value(tmp_path):
    model = RpcModel(RpcModel.example().rpc, (10000, 12000), domain_limit=1.2, height_limit=2.0)
    again = geoblock.open_model(geoblock.write_model(model, tmp_path / "m.json"))
    assert again == model and again.domain_limit == 1.2
    assert again != RpcModel.example()


# ---------------------------------------------------------------------- conformance kit
class TestRpcContract(SensorModelContract):
    check_options = {"n": 4}

    @pytest.fixture(params=[None, FILES[2], FILES[12], FILES[5], FILES[1]],
                    ids=["example", "rpc-txt", "dimap", "antimeridian", "gdal-5395"])
    def model(self, request):
        return RpcModel.example() if request.param is None else open_rpc(request.param)


# ---------------------------------------------------------------------- GDAL's test values
def test_gdal_transformer_5_quickbird():
    """autotest/gcore/transformer.py::test_transformer_5 (abs 1e-6 degree there).

    GDAL's pixel/line (20.5, 10.5) is geoblock's (row 10, col 20).
    """
    model = open_rpc("gdal-autotest/gcore/data/rpc.vrt")
    g = model.backproject(10.0, 20.0, 0.0)
    assert abs(g.lon - 125.64830100509131) < 1e-6 and abs(g.lat - 39.869433991997553) < 1e-6
    g = model.backproject(10.0, 20.0, 30.0)
    assert abs(g.lon - 125.64828521533849) < 1e-6 and abs(g.lat - 39.869345204440144) < 1e-6
    row, col = model.project(125.64828521533849, 39.869345204440144, 30.0)
    assert abs(row - 10.0) < 0.05 and abs(col - 20.0) < 0.05  # GDAL's threshold in that test


def test_gdal_transformer_6_ill_conditioned_rpc_of_bug_5395():
    model = open_rpc("gdal-autotest/gcore/data/rpc_5395.vrt")
    g, status = model.backproject_with_status(0.0, 0.0, 0.0)
    assert status == Status.CONVERGED
    assert abs(g.lon - 28.26163232) < 1e-4 and abs(g.lat - -27.79853245) < 1e-4
    row, col = model.project(g.lon, g.lat, 0.0)
    assert abs(row) < 1e-6 and abs(col) < 1e-6


def test_gdal_transformer_11_heights_outside_the_fit():
    """(0, 0) at RPC_HEIGHT 1150 -> GDAL's value (abs 1e-7); at 4000 GDAL fails, so do we."""
    model = open_rpc("gdal-autotest/extracted/transformer_11_rpc.vrt")
    g, status = model.backproject_with_status(-0.5, -0.5, 1150.0)
    assert status == Status.CONVERGED
    assert abs(g.lon - 77.350939956024618) < 1e-7 and abs(g.lat - 38.739703990877814) < 1e-7
    g, status = model.backproject_with_status(-0.5, -0.5, 4000.0)
    assert status == Status.OUT_OF_DOMAIN and np.isnan(g.lon)


def test_gdal_transformer_15_antimeridian():
    """LONG_OFF 179.9: GDAL gives lon 180.0228 (iterating to 0.1 px); geoblock wraps to
    [-180, 180) and solves to 1e-8 px, so the two agree within GDAL's threshold."""
    model = open_rpc("gdal-autotest/extracted/transformer_15_rpc.vrt")
    g, status = model.backproject_with_status(-0.5, -0.5, 50.0)
    assert status == Status.CONVERGED and -180.0 <= g.lon < 180.0
    assert abs((g.lon - 180.02280735469199 + 180.0) % 360.0 - 180.0) < 1e-6
    assert abs(g.lat - 0.061069145746997976) < 1e-6
    for lon in (180.02280735469199, 180.02280735469199 - 360.0):  # both sides of the line
        row, col = model.project(lon, 0.061069145746997976, 50.0)
        assert abs(row + 0.5) < 0.1 and abs(col + 0.5) < 0.1
    row, col = model.project(g.lon, g.lat, 50.0)
    assert abs(row + 0.5) < 1e-6 and abs(col + 0.5) < 1e-6


def test_skysat_rpc_that_rpcm_cannot_localise_at_70_m():
    """rpcm's test_localization: (col 0, row 0) at h 70 raises MaxLocalizationIterationsError
    in rpcm; geoblock converges, at 90 m too."""
    model = open_rpc(FILES[6])
    for h in (70.0, 90.0):
        g, status = model.backproject_with_status(0.0, 0.0, h)
        assert status == Status.CONVERGED
        row, col = model.project(g.lon, g.lat, h)
        assert abs(row) < 1e-6 and abs(col) < 1e-6


class TestRefinedRpcContract(SensorModelContract):
    """RPCV-0, RPCV-1 and order 2 around a real RPC pass the kit too."""

    check_options = {"n": 4}

    @pytest.fixture(params=[0, 1, 2], ids=["RPCV-0", "RPCV-1", "order-2"])
    def model(self, request):
        base = open_rpc(FILES[12])
        values = {0: [1.5, -0.7], 1: [1.5, 0.3, -0.2, -0.7, 0.1, 0.4],
                  2: [1.5, 0.3, -0.2, 0.05, -0.02, 0.03, -0.7, 0.1, 0.4, 0.01, 0.02, -0.03]}
        return geoblock.ImageCorrection(base, request.param, values[request.param], sigmas=1.0)


def test_serial_and_parallel_kernels_agree_bit_for_bit():
    """The thread-local twins run the same per-point code as the prange kernels."""
    import threading

    from geoblock_rpc import _kernels
    from geoblock_rpc.model import PARALLEL_MIN_POINTS, parallel_ok

    model = RpcModel.example()
    rng = np.random.default_rng(3)
    n = 5000
    row = rng.uniform(-50, model.shape[0] + 50, n)
    col = rng.uniform(-50, model.shape[1] + 50, n)
    h = rng.uniform(-100, 3000, n)
    row[:5] = np.nan
    outs = []
    for kernel in (_kernels.localise, _kernels.localise_serial):
        lon, lat, st = np.empty(n), np.empty(n), np.empty(n, np.uint8)
        kernel(row, col, h, model._prm, model._coef, 1e-8, 1e-7, 30, lon, lat, st)
        outs.append((lon, lat, st))
    for a, b in zip(*outs, strict=True):
        assert a.tobytes() == b.tobytes()
    lon, lat = outs[0][0], outs[0][1]
    outs = []
    for kernel in (_kernels.project, _kernels.project_serial):
        r, c, st = np.empty(n), np.empty(n), np.empty(n, np.uint8)
        kernel(lon, lat, h, model._prm, model._coef, r, c, st)
        outs.append((r, c, st))
    for a, b in zip(*outs, strict=True):
        assert a.tobytes() == b.tobytes()
    ok = np.isfinite(lon)
    parts = []
    for kernel in (_kernels.partials_geodetic, _kernels.partials_geodetic_serial):
        out = np.empty((int(ok.sum()), 2, 3))
        kernel(lon[ok], lat[ok], h[ok], model._prm, model._coef, out)
        parts.append(out)
    # (fastmath kernels: the same to rounding, not necessarily to the bit)
    np.testing.assert_allclose(parts[0], parts[1], rtol=1e-12, atol=0)
    assert parallel_ok(PARALLEL_MIN_POINTS) and not parallel_ok(PARALLEL_MIN_POINTS - 1)
    seen = []
    worker = threading.Thread(target=lambda: seen.append(parallel_ok(10**7)))
    worker.start()
    worker.join()
    assert seen == [False]
