"""``geoblock experiment chen1993``: the report beside Chen & Lee's tables, and the findings
that reproduce on the small variant.

One module-scoped run of the command (3 seeds, about 5 s) serves every test; the
rendering-free orthoimage measure is checked on its own against a direct computation.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

pytest.importorskip("geoblock_spot", reason="Chen & Lee's model is the geoblock-spot plugin's")

from click.testing import CliRunner  # noqa: E402
from geoblock_papers import _chen1993_sim as sim  # noqa: E402
from geoblock_papers import chen1993  # noqa: E402

from geoblock.adjust import ground_errors  # noqa: E402
from geoblock.cli.main import build_cli  # noqa: E402
from geoblock.dem import ConstantDem  # noqa: E402
from geoblock.testing.synthetic import ConstantVelocityPushbroom  # noqa: E402

REPEATS = 3


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    out = tmp_path_factory.mktemp("chen1993")
    result = CliRunner().invoke(build_cli(), ["experiment", "chen1993", str(out), "--repeats",
                                              str(REPEATS), "--seed", "10"])
    assert result.exit_code == 0, result.output + repr(result.exception)
    data = json.loads((out / "results.json").read_text())
    return {"out": out, "output": result.output, "data": data,
            "md": (out / "report.md").read_text(),
            "findings": {f["key"]: f for f in data["findings"]},
            "seed": {k: np.array([math.nan if v is None else v for v in values], dtype=float)
                     for k, values in data["results"]["per_seed"].items()}}


def test_the_command_writes_the_report_the_results_and_the_figure(run):
    assert run["data"]["seeds"] == [10, 11, 12] and run["data"]["variant"] == "small"
    assert "report: " in run["output"] and "results: " in run["output"]
    assert (run["out"] / "chen1993_error_vectors.png").stat().st_size > 10_000
    md = run["md"]
    assert md.index("## Findings") < md.index("Table 2")  # findings first


@pytest.mark.parametrize("key, paper_rows", [
    ("table_2", {"x (along track)": ["0.31", "-0.32", "0.19"],
                 "y (across track)": ["0.22", "-0.46", "0.18"]}),
    ("table_5", {"x (along track)": ["1.50", "-0.69", "0.61"],
                 "y (across track)": ["1.04", "-0.47", "0.45"]}),
    ("table_3", {"X (east)": ["10.6", "-10.3", "5.7"], "Y (north)": ["11.1", "-9.2", "5.4"]}),
    ("table_4", {"X (east)": ["11.3", "-11.8", "6.5"], "Y (north)": ["11.4", "-12.9", "6.6"]}),
])
def test_each_table_stands_beside_the_papers(run, key, paper_rows):
    table = run["data"]["results"][key]
    rows = {r["label"]: r for r in table["rows"]}
    assert rows.keys() == paper_rows.keys()
    for label, paper in paper_rows.items():
        assert rows[label]["paper"] == paper
        ours = rows[label]["geoblock"]
        assert all(cell["n"] == REPEATS and len(cell["values"]) == REPEATS for cell in ours)
        # the Markdown table shows the paper's figure and ours side by side
        line = next(ln for ln in run["md"].splitlines() if ln.startswith(f"| {label} |")
                    and f"| {paper[2]} |" in ln)
        assert f"{ours[2]['mean']:.2f}" in line


def test_resection_residuals_are_sub_pixel_like_the_papers(run):
    s = run["seed"]
    for axis in ("x", "y"):
        # the paper's 0.19 / 0.18 px; ours carry the preset's 0.3 px pointing noise
        assert np.all(s[f"gcp/{axis}/rms"] > 0.1) and np.all(s[f"gcp/{axis}/rms"] < 0.5)
        assert np.all(s[f"ckp/{axis}/rms"] < chen1993.TWO_THIRDS_PX)
    assert np.all(np.abs(s["sigma0"] - 1.0) < 0.5)
    assert run["findings"]["gcp_residuals"]["reproduced"] in (True, None)
    assert run["findings"]["two_thirds"]["reproduced"] is True


def test_orthoimage_error_is_the_located_error_plus_the_dtm_share(run):
    s = run["seed"]
    tan = np.tan(np.radians(s["incidence"]))
    for case in sim.CASES:
        truth = np.hypot(s[f"{case.name}/truth/X/rms"], s[f"{case.name}/truth/Y/rms"])
        ortho = np.hypot(s[f"{case.name}/X/rms"], s[f"{case.name}/Y/rms"])
        predicted = np.hypot(truth, s[f"{case.name}/dtm_rmse_z"] * tan)
        assert np.all(np.abs(ortho / predicted - 1.0) < 0.15), (case.name, ortho, predicted)
        # below two thirds of a SPOT pixel per axis, as the paper's orthoimages
        assert np.all(s[f"{case.name}/X/rms"] < 2 / 3 * sim.SPOT_PIXEL_M)
    assert np.all(s["rugged/relief"] == 540.0) and np.all(s["rolling/relief"] == 160.0)


def test_orthoimage_position_is_the_line_of_sight_on_the_dtm():
    """On a flat DTM the rendering-free orthoimage position of an image point is its
    backprojection at the DTM's height, and the error against that point is zero."""
    model = ConstantVelocityPushbroom.example(roll=0.15)  # ~9 deg off nadir
    rows, cols = model.shape
    row = np.array([10.0, rows / 2, rows - 20.0])
    col = np.array([cols - 5.0, cols / 3, 12.0])
    truth = model.backproject(row, col, np.full(3, 350.0))
    de, dn = sim.locate_on_dtm(model, row, col, ConstantDem(350.0), truth.lon, truth.lat)
    assert np.max(np.hypot(de, dn)) < 1e-3
    # a DTM 5 m too high moves it by 5 m x tan(theta), theta the viewing zenith angle
    lower = model.backproject(row, col, np.full(3, 345.0))
    per_metre = np.hypot(*ground_errors(truth.lon, truth.lat, lower.lon, lower.lat)[:2]) / 5.0
    de, dn = sim.locate_on_dtm(model, row, col, ConstantDem(350.0), lower.lon, lower.lat)
    assert np.all(per_metre > 0.1)
    np.testing.assert_allclose(np.hypot(de, dn), 5.0 * per_metre, rtol=1e-6)
