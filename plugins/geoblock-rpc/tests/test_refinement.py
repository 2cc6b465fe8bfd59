"""RPCV-0 / RPCV-1 / order-2 refinement of REAL vendor RPCs, and their RPC00B export.

A known image-space distortion is injected into a real RPC (``ImageCorrection(rpc, order,
true)``); GCPs are simulated by localising random image points of that distorted model at
random heights; :func:`geoblock.adjust.resect` must recover the distortion, and the folded or
refitted RPC00B (:func:`geoblock_rpc.fold.rpc_for`) must project like the refined model.
"""

from __future__ import annotations

import os
import re
import warnings
from pathlib import Path

import numpy as np
import pytest
from geoblock_rpc import Rpc00b, RpcModel
from geoblock_rpc.fold import rpc_for

import geoblock
from geoblock import ImageCorrection
from geoblock.adjust import ControlPoints, resect
from geoblock.errors import GeoblockError, TooFewPointsError

REPO = Path(__file__).resolve().parents[3]
DATA_DIR = Path(os.environ.get("GEOBLOCK_TEST_DATA", REPO.parent / "shared" / "data"))
PLEIADES = "shareloc/rpc/PHR1B_P_201709281038393_SEN_PRG_FC_178609-001.tif"
GDAL_TXT = "gdal-autotest/gcore/data/test_rpc.txt"

TRUE = {
    0: [3.2, -2.1],
    1: [3.2, 1.5, -0.8, -2.1, 0.6, 2.4],
    2: [3.2, 1.5, -0.8, 0.7, -0.4, 0.5, -2.1, 0.6, 2.4, -0.3, 0.9, -0.6],
}
MINIMUM = {0: 1, 1: 3, 2: 6}


@pytest.fixture(scope="session")
def data_dir() -> Path:
    if not DATA_DIR.is_dir():
        pytest.skip(f"real test data not found at {DATA_DIR} (set GEOBLOCK_TEST_DATA)")
    return DATA_DIR


def _read_txt_rpc(path: Path) -> Rpc00b:
    """Minimal ``_RPC.TXT`` parser (``KEY: value``, ``*_COEFF_n`` lists) for the fallback."""
    md: dict[str, object] = {}
    for line in path.read_text().splitlines():
        key, _, value = line.partition(":")
        match = re.fullmatch(r"(\w+_COEFF)_(\d+)", key.strip())
        if match:
            md.setdefault(match[1], []).append(value)  # type: ignore[union-attr]
        elif value.strip():
            md[key.strip()] = value
    return Rpc00b.from_gdal(md, source=str(path))


def _open(path: Path) -> RpcModel:
    """``geoblock.open_model``; while the readers are not there, the fixture reads the file
    itself (GeoTIFF RPC tags through rasterio, ``_RPC.TXT`` by a minimal parser) and the image
    shape is the RPC's extent (``ceil(OFF + SCALE + 0.5)``)."""
    try:
        model = geoblock.open_model(path)
    except GeoblockError:
        if path.suffix.lower() == ".tif":
            import rasterio
            from rasterio.errors import NotGeoreferencedWarning

            with warnings.catch_warnings():
                warnings.simplefilter("ignore", NotGeoreferencedWarning)
                with rasterio.open(path) as ds:
                    rpc = Rpc00b.from_gdal(ds.rpcs.to_gdal(), source=str(path))
        else:
            rpc = _read_txt_rpc(path)
        return RpcModel(rpc)
    while isinstance(model, ImageCorrection):
        model = model.model
    assert isinstance(model, RpcModel)
    return model


@pytest.fixture(scope="module", params=["pleiades", "gdal-txt", "common-denominator"])
def real_rpc(request, data_dir) -> RpcModel:
    """A real vendor RPC (the last one with SAMP_DEN := LINE_DEN, as common-denominator
    vendors deliver, so that RPCV-1 folds exactly)."""
    name = request.param
    path = data_dir / (GDAL_TXT if name == "gdal-txt" else PLEIADES)
    if not path.is_file():
        pytest.skip(f"{path} not found in the real test data")
    model = _open(path)
    if name == "common-denominator":
        model = RpcModel(model.rpc.replace(samp_den=model.rpc.line_den), model.shape)
    return model


def _gcps(distorted, n, seed, noise_px=0.0, prefix="g") -> ControlPoints:
    """Random image points of ``distorted`` localised at random heights (the true ground)."""
    rng = np.random.default_rng(seed)
    rows, cols = distorted.shape
    lo, hi = distorted.height_range
    row = rng.uniform(0.02, 0.98, n) * rows
    col = rng.uniform(0.02, 0.98, n) * cols
    h = rng.uniform(lo, hi, n)
    (lon, lat, _), status = distorted.backproject_with_status(row, col, h)
    assert np.all(status == 0)
    sigma = noise_px if noise_px > 0 else 0.5
    return ControlPoints(
        id=[f"{prefix}{i}" for i in range(n)], lon=lon, lat=lat, h=h,
        row=row + rng.normal(0.0, noise_px, n) if noise_px else row,
        col=col + rng.normal(0.0, noise_px, n) if noise_px else col,
        sigma_row=sigma, sigma_col=sigma,
    )


def _max_diff(a, b, seed=7) -> float:
    """Largest 2D image difference of two models at random ground points, pixels."""
    rng = np.random.default_rng(seed)
    rows, cols = a.shape
    lo, hi = a.height_range
    n = 2000
    (lon, lat, h), status = a.backproject_with_status(
        rng.uniform(0, rows - 1, n), rng.uniform(0, cols - 1, n), rng.uniform(lo, hi, n))
    ok = status == 0
    r1, c1 = a.project(lon[ok], lat[ok], h[ok])
    r2, c2 = b.project(lon[ok], lat[ok], h[ok])
    return float(np.max(np.hypot(r2 - r1, c2 - c1)))


@pytest.mark.parametrize("order", [0, 1, 2])
def test_recovers_distortion_exactly_and_exports(real_rpc, order):
    distorted = ImageCorrection(real_rpc, order, TRUE[order])
    gcps = _gcps(distorted, 12, seed=order)
    icps = _gcps(distorted, 20, seed=100 + order, prefix="c")
    result = resect(ImageCorrection(real_rpc, order), gcps, icps)
    assert result.converged
    np.testing.assert_allclose(result.values, TRUE[order], rtol=0, atol=1e-6)
    assert np.max(np.abs(np.concatenate([result.gcp.row, result.gcp.col]))) <= 1e-6
    assert result.icp is not None and result.icp.stats.rmse_2d < 1e-4  # metres

    rpc, report = rpc_for(result.model)
    folded = RpcModel(rpc, real_rpc.shape, domain_limit=10.0)
    exact = order == 0 or (order == 1 and np.array_equal(real_rpc.rpc.line_den,
                                                          real_rpc.rpc.samp_den))
    assert report.exact == exact, report
    if exact:
        assert report.max_error_px <= 1e-6
        assert _max_diff(result.model, folded) <= 1e-6
    else:
        assert report.method == "refit"
        assert report.max_error_px < 1e-3, report  # measured: see the module's report
        assert _max_diff(result.model, folded) <= 2 * report.max_error_px + 1e-9


@pytest.mark.parametrize("order", [0, 1, 2])
def test_recovers_distortion_with_noise(real_rpc, order):
    distorted = ImageCorrection(real_rpc, order, TRUE[order])
    gcps = _gcps(distorted, 25, seed=10 + order, noise_px=0.3)
    result = resect(ImageCorrection(real_rpc, order), gcps)
    assert result.converged and result.dof == 50 - len(TRUE[order])
    z = (result.values - np.asarray(TRUE[order])) / result.sigmas
    assert np.max(np.abs(z)) < 3.0, z
    assert 0.6 < result.sigma0 < 1.5


@pytest.mark.parametrize("order", [0, 1, 2])
def test_too_few_gcps_states_the_minimum(real_rpc, order):
    distorted = ImageCorrection(real_rpc, order, TRUE[order])
    gcps = _gcps(distorted, MINIMUM[order], seed=20 + order)
    with pytest.raises(TooFewPointsError, match=f"at least {MINIMUM[order]} GCPs"):
        resect(ImageCorrection(real_rpc, order), gcps.subset(np.arange(MINIMUM[order] - 1)))
    result = resect(ImageCorrection(real_rpc, order), gcps)  # the minimum is enough
    np.testing.assert_allclose(result.values, TRUE[order], rtol=0, atol=1e-6)
