"""The vertical check's predicted covariance (geoblock.adjust._vertical): the first-order
propagation against a Monte Carlo of the posterior, and the DEM's error common to a block
whose heights rest on the DEM alone (issue 28: LE90 predicted 3-4x below the empirical one
in the reference study, the DEM's correlated error averaged away by the posterior).

The blocks are geoblock.testing.blocks.affine_block's affine cameras with a known truth."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from geoblock import coords
from geoblock.adjust._vertical import dem_common_sigma
from geoblock.adjust.block import Block, adjust
from geoblock.dem.grid import GridDem
from geoblock.testing.blocks import affine_block
from geoblock.triangulation import triangulate


def _dem_only_block(offset_m: float) -> Block:
    """Control whose heights are the DEM's (as a reference ortho's control is: located on
    it, sigma_h the DEM's, 4 m), over a DEM whose error is ``offset_m`` common to the block;
    30 deg off nadir and 0.1 px pointing: the posterior alone predicts 0.8 m up."""
    b = affine_block((2, 2), gcps=8, icps=40, tps=300, ictps=0, sigma_px=0.1,
                     offnadir_deg=30.0, dem_sigma_m=4.0, seed=0).block
    assert isinstance(b.dem, GridDem) and b.ground is not None
    dem = GridDem(np.asarray(b.dem.array) + offset_m, b.dem.transform, b.dem.crs)
    g = b.ground
    gcp = g.kind == "gcp"
    h = np.where(gcp, dem.height(g.lon, g.lat), g.h)
    sigma_h = np.where(gcp, b.dem_sigma_m, g.sigma_h)
    return dataclasses.replace(b, dem=dem, ground=dataclasses.replace(g, h=h, sigma_h=sigma_h))


def test_the_dem_common_error_is_stated_where_the_heights_rest_on_the_dem():
    # A DEM 1 sigma (4 m) off everywhere, its error common to the block: the adjusted heights
    # follow it metre for metre (measured 1.000) and the prediction must cover it. Measured:
    # 86 ICPs intersected, RMS vertical error 4.00 m; the posterior alone predicted 0.80 m
    # (5x below), with the DEM's sigma as a common error 4.08 m
    base, off = _dem_only_block(0.0), _dem_only_block(4.0)
    assert dem_common_sigma(off) == off.dem_sigma_m == 4.0
    r0, r = adjust(base), adjust(off)
    v0, v = r0.vertical, r.vertical
    assert v0 is not None and v is not None and len(v) > 50
    assert v.id.tolist() == v0.id.tolist()
    assert float(np.nanmean(v.u - v0.u)) == pytest.approx(4.0, abs=0.05)  # response 1
    assert np.all(v.sigma_up >= off.dem_sigma_m)
    rms_u = float(np.sqrt(np.nanmean(v.u**2)))
    rms_sigma = float(np.sqrt(np.nanmean(v.sigma_up**2)))
    assert rms_u / rms_sigma == pytest.approx(1.0, abs=0.2)
    st = r.accuracy_statement()
    assert st.le90_predicted >= 1.6449 * off.dem_sigma_m


def test_better_height_control_than_the_dem_adds_no_common_term():
    b = affine_block((2, 2), gcps=8, icps=10, tps=100, ictps=0, seed=1).block
    assert b.ground is not None and b.dem is not None
    assert np.all(b.ground.sigma_h[b.ground.kind == "gcp"] < b.dem_sigma_m)
    assert dem_common_sigma(b) == 0.0
    assert dem_common_sigma(dataclasses.replace(b, dem=None)) == 0.0
    # one height better than the DEM's among DEM-height control: the block's heights no
    # longer rest on the DEM alone
    g = b.ground
    sigma_h = np.array(np.where(g.kind == "gcp", 2.0 * b.dem_sigma_m, g.sigma_h))
    only_dem = dataclasses.replace(b, ground=dataclasses.replace(g, sigma_h=sigma_h))
    assert dem_common_sigma(only_dem) == b.dem_sigma_m
    better = sigma_h.copy()
    better[np.flatnonzero(g.kind == "gcp")[0]] = 0.1
    one = dataclasses.replace(b, ground=dataclasses.replace(g, sigma_h=better))
    assert dem_common_sigma(one) == 0.0


def test_the_propagation_matches_a_monte_carlo_of_the_posterior():
    # the first-order covariance of the intersected ICPs against the spread of their
    # re-intersection through models drawn from the posterior (200 draws): hypothesis (2) of
    # the LE90 finding, a term missing from the propagation, is not it. Measured on the
    # study's rpc4 and teo blocks: median ratio 0.99 (up), 0.96 at teo's B/H of 0.01
    b = affine_block((2, 2), gcps=8, icps=30, tps=200, ictps=0, seed=2).block
    assert b.ground is not None
    r = adjust(b)
    v = r.vertical
    assert v is not None and len(v) > 10
    assert dem_common_sigma(b) == 0.0  # the covariance is the propagation alone
    m = b.measurements
    sel = (m.kind == "icp") & np.isin(m.id, v.id)
    t0 = triangulate(dict(r.models), m.id[sel], m.image[sel], m.row[sel], m.col[sel],
                     sigma_px=1.0, warn=False)
    assert t0.id.tolist() == v.id.tolist()
    q = np.asarray(r.covariance)
    chol = np.linalg.cholesky(q + 1e-15 * np.trace(q) * np.eye(q.shape[0]))
    where = {key: k for k, key in enumerate(r.parameter_index)}
    rng = np.random.default_rng(0)
    draws = []
    for _ in range(200):  # a loop over Monte Carlo draws
        dp = chol @ rng.normal(size=q.shape[0])
        models = {}
        for name, model in r.models.items():
            values = np.array(model.parameters.values, dtype=np.float64)
            for k, pname in enumerate(model.parameters.names):
                if (name, pname) in where:
                    values[k] += dp[where[(name, pname)]]
            models[name] = model.with_parameters(values)
        t = triangulate(models, m.id[sel], m.image[sel],
                        m.row[sel] + rng.normal(size=sel.sum()) * m.sigma_row[sel],
                        m.col[sel] + rng.normal(size=sel.sum()) * m.sigma_col[sel],
                        sigma_px=1.0, warn=False)
        draws.append(np.stack(coords.enu_offsets(t0.lon, t0.lat, t0.h, t.lon, t.lat, t.h), -1))
    spread = np.std(np.array(draws), axis=0)  # (L, 3)
    survey = np.stack([b.ground.sigma_e, b.ground.sigma_n, b.ground.sigma_h], -1)
    g = np.array([np.flatnonzero(b.ground.id == i)[0] for i in v.id])
    predicted = np.sqrt(np.einsum("lii->li", v.covariance) - survey[g] ** 2)
    ratio = np.median(spread / predicted, axis=0)
    assert ratio == pytest.approx(np.ones(3), abs=0.1)
