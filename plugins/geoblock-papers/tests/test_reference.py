"""The reference-control study (geoblock_papers.reference, issue 28): without surveyed GCPs,
control from a reference ortho misregistered by a known shift brings the ICPs to the
reference's error, not better; the posterior predicts it only when the shift is counted as
an error common to the control points."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from geoblock_papers import _reference_sim as sim
from geoblock_papers import reference
from geoblock_papers.registry import EXPERIMENTS, run_experiment


def _tiny() -> dict:
    """One SPOT-5-like 2.5 m image of 1 km (400 x 400 px) over 100-600 m of ridged terrain:
    a block that simulates, renders and adjusts in a few seconds."""
    return {"name": "reference-tiny", "method": "dg",
            "images": [{"id": "tiny", "preset": "spot5-strip2", "shape": [400, 400],
                        "onboard_rmse_m": 20.0}],
            "terrain": {"kind": "ridged", "relief": [100.0, 600.0], "resolution_m": 10.0,
                        "max_slope_deg": 35.0, "vertical": "ellipsoid", "margin_m": 600.0},
            "dems": [{"name": "dem30", "spacing_m": 30.0, "rmse_z": 4.0}],
            **sim._common(28)}


TINY = sim.BlockDesign("one 2.5 m image, 1 km", _tiny, "dg")


@pytest.fixture(scope="module")
def tiny():
    return sim.make_scene("tiny-test", TINY)


def test_a_misregistered_reference_brings_the_icps_to_its_error_not_better(tiny, tmp_path):
    """One seed, a 10 m reference misregistered by 4 m: ICP RMSE within 1.2x of the 4 m and
    not below what a block without any information on the shift can reach; the engine's
    posterior with independent control points is far too optimistic, the consider
    covariance of the common error is not."""
    case = sim.Case(10.0, 4.0)
    out = sim.run_case(tiny, case, 3, tmp_path)
    v = out.values
    assert not out.failure
    assert math.hypot(v["shift/e"], v["shift/n"]) == pytest.approx(4.0)
    assert v["control/n"] >= 20
    # the matches: within a reference pixel of the truth once the shift is removed, never
    # with it (4 m of a 10 m pixel: within, here)
    assert v["control/within_1px_removed"] >= 0.95
    assert v["control/rms_removed_m"] < 0.3 * case.gsd_m
    for route in ("own", "independent", "shift"):
        icp = v[f"{route}/icp_rmse_m"]
        assert 4.0 / 1.2 <= icp <= 4.0 * 1.2, (route, icp)
    icp = v["own/icp_rmse_m"]
    # the common shift is on every control point: the block follows it (response ~1 m per m)
    assert v["own/response"] == pytest.approx(1.0, abs=0.1)
    # independent points: 12-60x too optimistic in the study; here at least 5x
    assert v["independent/icp_pred_m"] < v["independent/icp_rmse_m"] / 5
    # the common error propagated: the prediction holds
    assert v["own/icp_pred_consider_m"] == pytest.approx(icp, rel=0.2)


def test_a_perfect_reference_leaves_the_matching_and_model_floor(tiny, tmp_path):
    out = sim.run_case(tiny, sim.Case(10.0, 0.0), 3, tmp_path, weightings=("own",),
                       consider=False)
    v = out.values
    assert (v["shift/e"], v["shift/n"]) == (0.0, 0.0)
    # no shift: what is left is the matching error averaged over the points and the model
    assert v["own/icp_rmse_m"] < 1.0


def test_the_reference_is_rendered_where_the_truth_says(tiny, tmp_path):
    """The control's ground positions, the shift removed, land on the true ground point of
    their image positions: the renderer's shift and the matcher's geometry agree in sign
    and size (a wrong sign would leave 8 m, twice the shift)."""
    out = sim.run_case(tiny, sim.Case(5.0, 4.0), 4, tmp_path, weightings=(), consider=False)
    v = out.values
    assert abs(v["control/mean_e_removed_m"]) < 0.5
    assert abs(v["control/mean_n_removed_m"]) < 0.5
    # with the shift included the matches are 4 m off: within a 5 m pixel, not a 2.5 m one
    assert v["control/within_1px_included"] > 0.5


@pytest.mark.parametrize("count", [1, 5, 20])
def test_stratified_sizes_have_the_population_rms(count):
    sigma = 2.0
    r = np.array([sim.stratified_radius(sigma, k, count) for k in range(count)])
    assert np.sqrt(np.mean(r**2)) == pytest.approx(math.sqrt(2) * sigma, rel=1e-12)
    assert np.all(np.diff(r) > 0)
    if count == 20:
        # the median cell holds the Rayleigh median, sigma sqrt(2 ln 2)
        assert r[9] < sigma * math.sqrt(2 * math.log(2)) < r[10]


def test_stated_ce90_is_that_of_the_error_rms():
    assert sim.stated_ce90(4.0) == pytest.approx(4.0 * 2.1459660 / math.sqrt(2), rel=1e-6)
    assert sim.stated_ce90(0.0) == sim.MIN_CE90_M


def test_the_cases_of_a_design():
    d = reference.DESIGNS["small"]
    assert sim.Case(2.5, 4.0) not in d.cases("teo")
    assert sim.Case(2.5, 4.0) in d.cases("aguilar")
    full = reference.DESIGNS["full"]
    cases = full.cases("teo")
    assert len(cases) == len(set(cases)) == 8  # 4 GSDs at 4 m, 4 errors at 10 m
    assert full.layer_seeds >= 20


def test_registered():
    assert "reference" in EXPERIMENTS
    assert set(reference.SEEDS) == {"small", "full"}


@pytest.mark.slow
def test_the_quick_study_reports_a_to_e(tmp_path):
    """The small variant (the quick one, ~30-60 s): every section, the findings that must
    hold on one seed, the figures."""
    result = run_experiment("reference", tmp_path)
    md = result.report.read_text()
    for part in ("(a), (c)", "(b) The posterior", "(d) Against the reference's GSD",
                 "(e) The accuracy layer", "Run times"):
        assert part in md, part
    for name in ("reference-error.png", "reference-gsd.png", "reference-layer.png"):
        assert (tmp_path / name).stat().st_size > 5000, name
    data = json.loads(result.results.read_text())
    findings = {f["key"]: f["reproduced"] for f in data["findings"]}
    assert findings["icp_consider"] is True
    assert findings["icp_independent"] is True
    assert findings["matches"] is True
    assert findings["posterior_independent"] is False
    assert findings["posterior_consider"] is True
    # fewer than 20 repetitions: the layer's bands are reported, not tested
    assert findings["layer_consider"] is None
