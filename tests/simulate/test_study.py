"""gcp_count_study / refined_errors on a model whose error is a known image-space affinity."""

from __future__ import annotations

import numpy as np
import pytest

from geoblock.adjust import ControlPoints
from geoblock.errors import GeoblockError
from geoblock.models import ImageCorrection
from geoblock.simulate.study import CheckPoints, gcp_count_study, refined_errors
from geoblock.testing.synthetic import AffineCamera


def _points(truth, n, seed):
    rng = np.random.default_rng(seed)
    rows, cols = truth.shape
    r = rng.uniform(0, rows - 1, n)
    c = rng.uniform(0, cols - 1, n)
    h = rng.uniform(0, 800, n)
    g = truth.backproject(r, c, h)
    return g.lon, g.lat, h, r, c


@pytest.fixture(scope="module")
def case():
    truth = AffineCamera.example()
    # the "on-board" model: the truth seen through a shift plus an along-track scale error
    # (3 px at the image edge, in normalised image coordinates)
    onboard = ImageCorrection(truth, 1, values=[4.0, 3.0, 0.0, -3.0, 0.0, 0.0])
    lon, lat, h, r, c = _points(truth, 45, 1)
    gcps = ControlPoints(id=[f"g{k}" for k in range(45)], lon=lon, lat=lat, h=h, row=r, col=c,
                         sigma_row=0.1, sigma_col=0.1)
    icps = CheckPoints(*_points(truth, 60, 2))
    return onboard, gcps, icps


def test_order_one_recovers_an_affine_error_order_zero_does_not(case):
    onboard, gcps, icps = case
    e1 = refined_errors(onboard, gcps, icps, 1)
    e0 = refined_errors(onboard, gcps, icps, 0)
    assert np.sqrt(np.mean(e1**2)) < 1e-6  # noise-free GCPs: exact
    # order 0 leaves the scale error, which grows with the distance from the image centre
    rows = icps.row
    slope = np.polyfit(np.abs(rows - rows.mean()), e0, 1)[0]
    assert np.sqrt(np.mean(e0**2)) > 0.1 and slope > 0


def test_gcp_count_study_shapes_and_minimums(case):
    onboard, gcps, icps = case
    st = gcp_count_study(onboard, gcps, icps, counts=(2, 3, 9, 45, 100), repeats=4, seed=3)
    assert st.counts.tolist() == [2, 3, 9, 45]  # 100 > the 45 GCPs: dropped
    assert set(st.rmse_m) == {0, 1} and st.rmse_m[0].shape == (4, 4)
    assert np.isnan(st.rmse_m[1][:, 0]).all()  # 2 GCPs cannot fix an affinity (needs 3)
    assert np.all(st.rmse_m[1][:, 1:] < 1e-6)
    assert np.all(st.rmse_m[0][:, 0] > 0.1)
    assert np.all(st.rmse_m[0][:, 3] == st.rmse_m[0][0, 3])  # all GCPs: one subset
    assert "RPCV-0" in st.table() and set(st.series()) == {"RPCV-0 (shift)", "RPCV-1 (affine)"}
    again = gcp_count_study(onboard, gcps, icps, counts=(2, 3, 9, 45), repeats=4, seed=3)
    assert np.array_equal(again.rmse_m[0], st.rmse_m[0], equal_nan=True)


def test_gcp_count_study_refuses_nothing_to_do(case):
    onboard, gcps, icps = case
    with pytest.raises(GeoblockError, match="no GCP count"):
        gcp_count_study(onboard, gcps, icps, counts=(0, 100))
