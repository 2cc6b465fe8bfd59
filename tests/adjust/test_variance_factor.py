"""sigma0² is the variance factor of the data, not of the parameters' priors (issue 28).

The posterior covariance is ``(N_data / sigma0² + N_prior)^-1``: the image measurements and
the points' observations (GCP ground, DEM, HCP heights) are scaled by sigma0², the
parameters' a-priori pseudo-observations (ParameterSet sigmas, the sources' ``sigma_shift``)
are not. A parameter that only its prior determines keeps its prior sigma whatever sigma0;
a parameter the data determine gets ``sigma0² N^-1`` as before.

sigma0 is set by scaling the stated sigmas of the measurements (image and ground) of
geoblock.testing.blocks.affine_block against its actual noise: stated at twice the noise,
sigma0 is about 0.5; at half of it, about 2."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from geoblock.adjust import normal
from geoblock.adjust._engine import _Engine
from geoblock.adjust.block import Block, adjust
from geoblock.adjust.observations import GroundPoints
from geoblock.testing.blocks import affine_block

REF = "reference:ref.tif"
#: small enough that the TPs' floating ground pseudo-observations (10 km, counted with the
#: points' observations) inform it below 1e-6 of its variance (at 3 m: 2e-5 with 120 TPs)
SHIFT_SIGMA = 0.3


def _block(stated: float, *, shift_sigma: float = 0.0, sigmas=None, models=None,
           seed: int = 0) -> Block:
    """A 2 x 2 affine block (no DEM), its image and ground sigmas stated at ``stated`` times
    their actual noise; with ``shift_sigma``, its GCPs a reference's whose common error has
    that prior sigma east and north: unobservable next to the images' free shifts (nothing
    else sees absolute position). ``models`` replace the on-board ones (a-priori values)."""
    sb = affine_block((2, 2), gcps=6, icps=4, tps=120, ictps=0, sigma_ground_m=0.3,
                      seed=seed)
    b = sb.block
    g = b.ground
    assert g is not None
    gcp = g.kind == "gcp"
    ground = GroundPoints(g.id, g.kind, g.lon, g.lat, g.h, g.sigma_e * stated,
                          g.sigma_n * stated, g.sigma_h * stated,
                          np.where(gcp, REF, "survey"), np.where(gcp, shift_sigma, 0.0),
                          np.where(gcp, shift_sigma, 0.0), 0.0)
    m = b.measurements
    meas = dataclasses.replace(m, sigma_row=m.sigma_row * stated, sigma_col=m.sigma_col * stated)
    return Block(dict(models or b.models), meas, ground, None, b.dem_sigma_m,
                 sigmas=sigmas or {})


def _old_posterior(self, system, st, var0):
    """The posterior before the fix: sigma0² N^-1, the priors scaled too."""
    return st.q_pp * var0, st.q_xx * var0


@pytest.fixture(params=["dense", "sparse", "numpy"])
def path(request, monkeypatch):
    if request.param == "sparse":
        monkeypatch.setattr(normal, "DENSE_LIMIT", 1)
    elif request.param == "numpy":
        monkeypatch.setattr(normal, "USE_NUMBA", False)
    return request.param


@pytest.mark.parametrize("mode", ["block", "single"])
def test_an_unobservable_parameter_keeps_its_prior_sigma_whatever_sigma0(path, mode):
    # the reference's common shift next to the images' free shifts: its posterior is its
    # prior, with sigma0 0.5 or 2. Before the fix it was sigma0 times the prior (the
    # Ventoux pair: 3.17 m for a prior of 3.96 m at sigma0 0.80, 6.02 m at 1.52)
    sigmas = {}
    for stated, expect in ((2.0, 0.5), (0.5, 2.0)):
        r = adjust(_block(stated, shift_sigma=SHIFT_SIGMA), mode=mode,
                   control_shifts="estimate")
        assert r.sigma0 == pytest.approx(expect, rel=0.2)
        keys = [REF] if mode == "block" else [f"{REF} @ {i}" for i in r.models]
        for key in keys:
            sh = r.shifts[key]
            assert sh.sigmas[:2] == pytest.approx([SHIFT_SIGMA, SHIFT_SIGMA], rel=1e-6)
            assert sh.sigmas[2] == 0.0
        sigmas[stated] = np.sqrt(np.diag(r.covariance))
    # the data-determined parameters (and the image shifts' data part) are what sigma0
    # scales: stating the sigmas 4x apart changes them by the small change of the balance
    # between the data and the (unscaled) prior only
    assert sigmas[2.0] == pytest.approx(sigmas[0.5], rel=0.05)


def _relative(a, b):
    """``|a - b|`` in units of ``b``'s sigmas (``sqrt(b_ii b_jj)``)."""
    d = np.sqrt(np.diag(b))
    return np.abs(a - b) / np.outer(d, d)


def test_the_considered_shift_and_the_estimated_one_agree_whatever_sigma0():
    # considered, the shift's sigma is propagated unscaled; estimated, it is now unscaled too
    # (before: the estimated image shifts' sigmas were 1.55x the considered ones here, the
    # shift's prior scaled by sigma0 = 2)
    block = _block(0.5, shift_sigma=SHIFT_SIGMA)
    considered = adjust(block)
    estimated = adjust(block, control_shifts="estimate")
    assert estimated.sigma0 == pytest.approx(2.0, rel=0.2)
    assert _relative(estimated.covariance, considered.covariance).max() < 1e-3


def test_data_dominated_parameters_get_sigma0_squared_n_inverse(monkeypatch):
    # priors 1000 times looser than the posterior: the covariance is sigma0² N^-1 as before
    plain = adjust(_block(2.0))
    centred = plain.models  # priors centred on the estimate: consistent with the data
    loose = {image: {name: 1000.0 * float(s) for name, s in zip(p.names, p.sigmas,
                                                                 strict=True)}
             for image, p in plain.parameters.items()}
    tight = {image: {name: 0.5 * float(s) for name, s in zip(p.names, p.sigmas, strict=True)}
             for image, p in plain.parameters.items()}
    cases = (("loose", loose), ("tight", tight))
    new = {k: adjust(_block(2.0, sigmas=v, models=centred)) for k, v in cases}
    monkeypatch.setattr(_Engine, "posterior", _old_posterior)
    old = {k: adjust(_block(2.0, sigmas=v, models=centred)) for k, v in cases}
    for k in ("loose", "tight"):
        assert new[k].sigma0 == old[k].sigma0 == pytest.approx(0.5, rel=0.2)
    assert _relative(new["loose"].covariance, old["loose"].covariance).max() < 1e-3
    pts_new, pts_old = new["loose"].points.covariance, old["loose"].points.covariance
    assert np.abs(pts_new - pts_old).max() < 1e-3 * np.abs(pts_old).max()
    # the contrast: where the priors weigh (half the data's sigma), sigma0 = 0.5 no longer
    # shrinks them: the new sigmas are larger, and within the prior
    s_new = np.sqrt(np.diag(new["tight"].covariance))
    s_old = np.sqrt(np.diag(old["tight"].covariance))
    assert np.all(s_new > 1.2 * s_old)
    prior = np.concatenate([new["tight"].parameters[i].prior_sigmas
                            for i in new["tight"].parameters])
    assert np.all(s_new < prior)


def test_every_path_gives_the_same_posterior(monkeypatch):
    # priors that weigh and sigma0 = 2: the rescaled inversion runs on each path
    plain = adjust(_block(0.5))
    tight = {image: {"a0": 0.05, "b0": 0.05, "a1": 1e-5} for image in plain.models}
    cases = {}
    for name in ("dense", "sparse", "numpy"):
        with monkeypatch.context() as mp:
            if name == "sparse":
                mp.setattr(normal, "DENSE_LIMIT", 1)
            elif name == "numpy":
                mp.setattr(normal, "USE_NUMBA", False)
            cases[name] = adjust(_block(0.5, sigmas=tight, shift_sigma=SHIFT_SIGMA,
                                        models=plain.models), control_shifts="estimate")
    ref = cases["dense"]
    assert ref.sigma0 == pytest.approx(2.0, rel=0.2)
    for name in ("sparse", "numpy"):
        r = cases[name]
        assert r.covariance == pytest.approx(ref.covariance, rel=1e-6, abs=1e-12)
        assert r.points.covariance == pytest.approx(ref.points.covariance, rel=1e-6, abs=1e-9)
        assert r.shifts[REF].sigmas == pytest.approx(ref.shifts[REF].sigmas, rel=1e-6)
        assert r.predicted_sigma == pytest.approx(ref.predicted_sigma, rel=1e-6)
