"""``geoblock experiment aguilar2007``: the report beside Aguilar et al.'s tables and figures,
and the findings that reproduce on the small variant.

One module-scoped run of the command (2 seeds, about 15 s) serves every test; each finding
asserted here holds seed by seed, not only on average.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

pytest.importorskip("geoblock_rpc", reason="RPCV-0/1 and RFM-1 need the geoblock-rpc plugin")

from click.testing import CliRunner  # noqa: E402
from geoblock_papers import _aguilar_paper as paper  # noqa: E402
from geoblock_papers import _aguilar_sim as sim  # noqa: E402

from geoblock.adjust import ControlPoints  # noqa: E402
from geoblock.cli.main import build_cli  # noqa: E402

REPEATS = 2
FIGURES = ("aguilar2007_rmse_vs_gcps.png", "aguilar2007_fig4_distance.png",
           "aguilar2007_fig5_vectors.png", "aguilar2007_fig6_sampling.png",
           "aguilar2007_fig7_few_gcps.png", "aguilar2007_ortho_budget.png")


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    out = tmp_path_factory.mktemp("aguilar2007")
    result = CliRunner().invoke(build_cli(), ["experiment", "aguilar2007", str(out),
                                              "--repeats", str(REPEATS)])
    assert result.exit_code == 0, result.output + repr(result.exception)
    data = json.loads((out / "results.json").read_text())
    return {"out": out, "data": data, "md": (out / "report.md").read_text(),
            "findings": {f["key"]: f for f in data["findings"]},
            "seed": {k: np.array([math.nan if v is None else v for v in values], dtype=float)
                     for k, values in data["results"]["per_seed"].items()}}


def test_the_command_writes_the_report_the_results_and_the_figures(run):
    assert run["data"]["seeds"] == [0, 1] and run["data"]["variant"] == "small"
    for name in FIGURES:
        assert (run["out"] / name).stat().st_size > 10_000, name
        assert f"]({name})" in run["md"]
    assert run["md"].index("## Findings") < run["md"].index("Table 3")


def test_table_3_stands_beside_the_papers(run):
    table = run["data"]["results"]["table_3"]
    assert table["columns"] == ["RMSE X (m)", "RMSE Y (m)", "RMSE 2D (m)"]
    rows = {r["label"]: r for r in table["rows"]}
    assert len(rows) == len(sim.MODELS) * len(sim.COUNTS)
    assert rows["RPCV-0, 18 GCPs"]["paper"] == ["0.61", "1.08", "1.24"]
    assert rows["CCRS / physical, 45 GCPs"]["paper"] == ["0.39", "0.52", "0.65"]
    cell = rows["RPCV-0, 18 GCPs"]["geoblock"][2]
    assert cell["n"] == REPEATS
    line = next(ln for ln in run["md"].splitlines() if ln.startswith("| RPCV-0, 18 GCPs |")
                and "| 1.24 |" in ln)
    assert f"{cell['mean']:.2f}" in line


def test_the_orthoimage_tables_follow_the_variants_dems(run):
    results = run["data"]["results"]
    for key, table in (("table_4", paper.TABLE_4), ("table_5", paper.TABLE_5)):
        rows = {r["label"]: r["paper"] for r in results[key]["rows"]}
        assert rows["RFM-1, 18 GCPs"] == list(table[("RFM-1", 18)])
    assert "table_6" not in results  # no 2 m DEM in the small variant: said so
    assert "Table 6: RMSE at the 79 ICPs on the orthoimage" in run["md"]
    t7 = {r["label"]: r for r in results["table_7"]["rows"]}
    assert t7["RPCV-0, Mean"]["paper"] == ["0.43", "0.57", "1.05"]
    assert t7["RPCV-0, Mean"]["geoblock"][0] == "not in the small variant"


def test_rfm1_and_the_physical_model_beat_rpcv0(run):
    s = run["seed"]
    for n in (18, 27, 36, 45):
        for model in ("RFM-1", "physical", "RPCV-1"):
            assert np.all(s[f"t3/{model}/{n}/2d"] < 0.7 * s[f"t3/RPCV-0/{n}/2d"]), (model, n)
    # RPCV-0's systematic error lies along track (north here, a near-polar orbit)
    assert np.all(s["t3/RPCV-0/18/y"] > 1.8 * s["t3/RPCV-0/18/x"])
    assert run["findings"]["rpcv0_worst"]["reproduced"] is True


def test_more_than_18_gcps_do_not_help_much(run):
    s = run["seed"]
    for model in ("RPCV-0", "RPCV-1", "physical"):  # RFM-1 still gains a little: said so
        change = s[f"t3/{model}/18/2d"] / s[f"t3/{model}/45/2d"] - 1.0
        assert np.all(np.abs(change) < 0.2), (model, change)
    assert run["findings"]["eighteen_enough"]["reproduced"] in (True, None)
    # but nine are too few for RFM-1's 14 unknowns (nine stratified samples per seed)
    assert np.all(s["sampling/RFM-1/9/SR/mean"] > 1.2 * s["sampling/RFM-1/18/SR/mean"])
    assert run["findings"]["rfm1_nine"]["reproduced"] is True


def test_stratified_sampling_beats_random_sampling(run):
    s = run["seed"]
    key = "sampling/RFM-1/9/{}/{}"
    assert np.all(s[key.format("R", "mean")] > 1.2 * s[key.format("SR", "mean")])
    assert np.all(s[key.format("R", "half")] > s[key.format("SR", "half")])
    assert np.mean(s[key.format("R", "half")] / s[key.format("SR", "half")]) > 1.5
    # with 18 GCPs the design matters much less
    gap9 = s[key.format("R", "mean")] / s[key.format("SR", "mean")]
    gap18 = s["sampling/RFM-1/18/R/mean"] / s["sampling/RFM-1/18/SR/mean"]
    assert np.all(gap18 < gap9)
    assert run["findings"]["sampling"]["reproduced"] in (True, None)


def test_rpcv0_residuals_grow_with_the_distance_from_the_centre(run):
    s = run["seed"]
    assert np.all(s["fig4/RPCV-0/slope"] > 0.05) and np.all(s["fig4/RPCV-0/r2"] > 0.15)
    assert np.all(s["fig4/RPCV-0/along/r2"] > 0.15)
    for model in ("RPCV-1", "RFM-1", "physical"):
        assert np.all(s[f"fig4/{model}/r2"] < 0.1), model
    assert run["findings"]["distance_growth"]["reproduced"] is True


def test_orthoimage_error_follows_the_budget(run):
    s = run["seed"]
    for model in sim.MODELS:
        previous = np.zeros(REPEATS)
        for dem in ("dem5", "dem20"):
            ortho = s[f"ortho/{dem}/{model}/18/2d"]
            predicted = np.hypot(s[f"t3/{model}/18/2d"], s[f"dem/{dem}/sigma_pred"])
            assert np.all(np.abs(ortho / predicted - 1.0) < 0.1), (model, dem)
            # the DEM's planimetric share is RMSEz tan(theta), not RMSEz
            share = s[f"shift/{dem}/{model}/18/2d"]
            assert np.all(np.abs(share / s[f"dem/{dem}/sigma_pred"] - 1.0) < 0.1)
            assert np.all(ortho > previous)  # rises with the DEM's error
            previous = ortho
    assert np.all(np.abs(s["view/tan_rms"] - math.tan(math.radians(8.6))) < 0.01)
    assert run["findings"]["ortho_budget"]["reproduced"] is True


def test_what_does_not_reproduce_says_why(run):
    found = run["findings"]
    assert found["rpcv1_between"]["reproduced"] is False
    assert "affine" in found["rpcv1_between"]["evidence"]
    for f in found.values():
        assert f["evidence"], f["key"]


def test_cells_of_the_stratified_design():
    pts = ControlPoints(["a", "b", "c", "d"], [0.0] * 4, [0.0] * 4, [0.0] * 4,
                        row=[-0.5, 99.4, 100.0, 299.4], col=[0.0, 150.0, 299.0, 100.0])
    assert sim.cells_of(pts, (300, 300)).tolist() == [0, 1, 5, 7]
