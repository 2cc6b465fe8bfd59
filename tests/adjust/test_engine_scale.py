"""The engine at scale: solver choice stated, covariances computed only as asked, the
per-image grouping of the hot path."""

from __future__ import annotations

import numpy as np
import pytest

import geoblock.adjust._engine as engine_module
from geoblock.adjust import adjust
from geoblock.adjust._engine import _Engine
from geoblock.errors import AdjustmentError
from geoblock.testing.blocks import affine_block


@pytest.fixture(scope="module")
def sb():
    return affine_block((2, 3), gcps=3, icps=3, tps=150, ictps=0, seed=11)


@pytest.fixture(scope="module")
def full(sb):
    return adjust(sb.block)


@pytest.mark.parametrize("solver, says", [("dense", "dense Cholesky"),
                                          ("direct", "sparse LDL"),
                                          ("iterative", "PCG")])
def test_solvers_agree_and_are_stated(sb, full, solver, says):
    r = adjust(sb.block, solver=solver)
    assert says in r.solver
    assert f"solver: {r.solver}" in r.report_text()
    for image, est in full.parameters.items():
        # the same answer to 1e-6 of a posterior sigma
        assert np.all(np.abs(r.parameters[image].values - est.values) < 1e-6 * est.sigmas)


def test_unknown_solver_is_refused(sb):
    with pytest.raises(AdjustmentError, match="solver must be one of"):
        adjust(sb.block, solver="magic")


def test_covariance_of_selected_images_only(sb, full):
    r = adjust(sb.block, covariance=["img00", "img01"], solver="direct")
    assert {i for i, _ in r.parameter_index} == {"img00", "img01"}
    n = len(r.parameter_index)
    assert r.covariance.shape == (n, n)
    for image in ("img00", "img01"):
        np.testing.assert_allclose(r.parameter_covariance(image)[1],
                                   full.parameter_covariance(image)[1], rtol=1e-6, atol=1e-12)
    names, cov = r.parameter_covariance("img02")
    assert names == full.parameters["img02"].names and np.all(np.isnan(cov))
    assert np.all(np.isnan(r.parameters["img02"].sigmas))
    assert any("covariances:" in note and "NaN" in note for note in r.notes)
    np.testing.assert_allclose(r.parameters["img02"].values, full.parameters["img02"].values,
                               atol=1e-9)


def test_auto_computes_no_covariance_above_the_dense_limit(sb, full, monkeypatch):
    monkeypatch.setattr(engine_module, "DENSE_LIMIT", 10)  # 36 parameters here
    r = adjust(sb.block)
    assert r.covariance.shape == (0, 0)
    assert np.all(np.isnan(r.measurements.test)) and np.all(np.isnan(r.points.covariance))
    assert any("covariances: 36 parameters" in note for note in r.notes)
    np.testing.assert_allclose(r.sigma0, full.sigma0, rtol=1e-9)
    with pytest.raises(AdjustmentError, match="snooping.*full parameter cofactor"):
        adjust(sb.block, robust="snooping")


def test_the_grouped_slices_are_the_measurements_of_each_image(sb):
    b = sb.block
    eng = _Engine(b, b.image_ids, use_tps=True, dem_control="observation",
                  tp_sigma_factor=10.0, tp_sigma_m=None, tp_prior="floating", notes=[])
    s = eng.s
    for i in range(len(b.image_ids)):
        np.testing.assert_array_equal(s.of_image(i), np.flatnonzero(s.image_of == i))
    # the evaluation through the slices is the per-image projection (reference)
    ev = eng.evaluate(s.prior_x, s.x0)
    for i, model in enumerate(ev.models):
        mine = np.flatnonzero(s.image_of == i)
        j = s.point_of[mine]
        (r, c), _ = model.project_with_status(ev.lon[j], ev.lat[j], ev.h[j])
        np.testing.assert_array_equal(ev.v[mine, 0], s.obs[mine, 0] - r)
        np.testing.assert_array_equal(ev.v[mine, 1], s.obs[mine, 1] - c)
