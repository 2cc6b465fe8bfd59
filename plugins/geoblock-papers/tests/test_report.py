"""The experiments' report builder and registry: estimates over seeds, side-by-side tables,
results.json, and the errors they raise (no experiment is simulated here)."""

from __future__ import annotations

import json
import math
import sys
import types

import numpy as np
import pytest
from geoblock_papers import registry
from geoblock_papers.registry import (
    EXPERIMENTS,
    ExperimentError,
    experiment_module,
    run_experiment,
)
from geoblock_papers.report import Estimate, GridRow, Report, Row, estimate
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from scipy import stats

from geoblock.errors import GeoblockError


def _report(tmp_path, seeds=(0, 1, 2)) -> Report:
    return Report("demo", "A title", "Someone 2024", variant="small", seeds=seeds,
                  outdir=tmp_path / "out")


def _figure() -> Figure:
    fig = Figure(figsize=(2, 2))
    FigureCanvasAgg(fig)
    fig.add_subplot().plot([0, 1], [1, 0])
    return fig


# ------------------------------------------------------------------------------ Estimate
def test_estimate_is_the_mean_and_student_t_interval_of_the_finite_values():
    values = [4.0, 5.0, 7.0, math.nan]
    est = estimate(values)
    assert est.values[:3] == (4.0, 5.0, 7.0) and math.isnan(est.values[3])
    assert est.mean == pytest.approx(16.0 / 3.0)
    half = stats.t.ppf(0.975, 2) * np.std([4.0, 5.0, 7.0], ddof=1) / math.sqrt(3)
    assert est.interval == pytest.approx((16 / 3 - half, 16 / 3 + half))
    assert est.format(1) == f"5.3 m ({16 / 3 - half:.1f} to {16 / 3 + half:.1f})"
    assert est.format(1, unit=False).startswith("5.3 (")
    assert str(est) == est.format(2)


def test_estimate_single_value_equal_values_and_failures():
    one = estimate([2.5], "px")
    assert math.isnan(one.interval[0]) and one.format() == "2.50 px"
    same = estimate([9.0, 9.0, 9.0], "")
    assert same.format(0) == "9"  # no interval of zero width
    failed = estimate([math.nan, math.inf])
    assert math.isnan(failed.mean) and failed.format() == "failed"
    assert failed.to_json() == {"mean": None, "ci95": [None, None], "n": 0, "unit": "m",
                                "values": [None, None]}


def test_estimate_json_has_every_value():
    est = Estimate((1.0, 2.0, math.nan), "m")
    data = est.to_json()
    assert data["values"] == [1.0, 2.0, None] and data["n"] == 2
    assert data["mean"] == 1.5 and data["ci95"][0] < 1.5 < data["ci95"][1]
    json.dumps(data, allow_nan=False)


# ------------------------------------------------------------------------------ tables
def test_compare_puts_the_paper_beside_ours_and_records_it(tmp_path):
    r = _report(tmp_path)
    r.compare("factor", [Row("ICTP single / block", "7.0", estimate([4.0, 5.0, 6.0], ""),
                             "clear"),
                         Row("count", "9", 9.0), Row("text", "-", "n/a")],
              title="Factors", note="A note.")
    md = r.markdown()
    assert "**Factors**" in md and "A note." in md
    assert "| quantity | paper | geoblock (mean, 95 % CI over 3 seeds) | verdict |" in md
    assert "| ICTP single / block | 7.0 | 5.00 (" in md and "| count | 9 | 9.00 |" in md
    assert r.results["factor"][0]["paper"] == "7.0"
    assert r.results["factor"][0]["geoblock"]["values"] == [4.0, 5.0, 6.0]
    assert r.results["factor"][1]["geoblock"] == 9.0
    with pytest.raises(ExperimentError, match="factor"):
        r.compare("factor", [])


def test_grid_splits_each_column_into_paper_and_ours(tmp_path):
    r = _report(tmp_path)
    rows = [GridRow("MBA block ICTP", ["1.22", "1.68"], [estimate([1.0, 2.0, 3.0]), "-"])]
    r.grid("table_III", ["strips 1 & 2 E", "strips 1 & 2 N"], rows, title="Table III (m)")
    md = r.markdown()
    assert ("|  | strips 1 & 2 E: paper | strips 1 & 2 E: geoblock | strips 1 & 2 N: paper "
            "| strips 1 & 2 N: geoblock |") in md
    assert "| MBA block ICTP | 1.22 | 2.00 (" in md  # no unit inside a grid
    assert " m (" not in md.split("MBA block ICTP")[1]
    got = r.results["table_III"]
    assert got["columns"] == ["strips 1 & 2 E", "strips 1 & 2 N"]
    assert got["rows"][0]["paper"] == ["1.22", "1.68"]
    assert got["rows"][0]["geoblock"][0]["mean"] == 2.0 and got["rows"][0]["geoblock"][1] == "-"
    with pytest.raises(ExperimentError, match="row 'bad' has 1 paper and 2 geoblock cells"):
        r.grid("other", ["a", "b"], [GridRow("bad", ["1"], [1.0, 2.0])])


def test_series_put_one_column_of_ours_per_condition_beside_the_paper(tmp_path):
    r = _report(tmp_path)
    series = ("realistic", "bias-drift")
    r.compare("factor", [Row("ICTP single / block", "7.0", estimate([4.0, 5.0, 6.0], ""),
                             "a: small; b: small", alt=[estimate([1.0, 2.0, 3.0], "")])],
              series=series)
    r.grid("table_III", ["strips 1 & 2 E"],
           [GridRow("MBA block ICTP", ["1.22"], [estimate([1.0, 2.0, 3.0])],
                    alt=[[estimate([3.0, 4.0, 5.0])]])], series=series)
    md = r.markdown()
    assert ("| quantity | paper | geoblock, realistic | geoblock, bias-drift | verdict |"
            in md)
    assert "| ICTP single / block | 7.0 | 5.00 (" in md and "| 2.00 (" in md
    assert ("|  | strips 1 & 2 E: paper | strips 1 & 2 E: geoblock realistic | strips 1 & 2 E: "
            "geoblock bias-drift |") in md
    assert "| MBA block ICTP | 1.22 | 2.00 (" in md and ") | 4.00 (" in md
    row = r.results["factor"][0]
    assert row["geoblock"]["mean"] == 5.0 and row["series"]["bias-drift"]["mean"] == 2.0
    grid = r.results["table_III"]
    assert grid["series"] == list(series)
    assert grid["rows"][0]["series"]["realistic"][0]["mean"] == 2.0
    assert grid["rows"][0]["series"]["bias-drift"][0]["mean"] == 4.0
    with pytest.raises(ExperimentError, match="row 'q' has 0 further series for 1"):
        r.compare("other", [Row("q", "1", 1.0)], series=series)
    with pytest.raises(ExperimentError, match="two or more series or none"):
        r.compare("other2", [Row("q", "1", 1.0)], series=("one",))
    with pytest.raises(ExperimentError, match="row 'bad' has 1 paper and 1 geoblock cells"):
        r.grid("other3", ["a", "b"], [GridRow("bad", ["1"], [1.0], alt=[[1.0, 2.0]])],
               series=series)


def test_findings_may_carry_one_verdict_per_series(tmp_path):
    r = _report(tmp_path)
    r.finding("f1", "block helps", None, "**a:** 2x. **b:** 5x",
              series={"a": None, "b": True})
    r.finding("f2", "ICPs rise", False, "no", series={"a": False, "b": False})
    with pytest.raises(ExperimentError, match="must name two or more and start with"):
        r.finding("f3", "x", True, "y", series={"a": False, "b": True})
    with pytest.raises(ExperimentError, match="differ from the other findings'"):
        r.finding("f4", "x", True, "y", series={"b": True, "a": True})
    with pytest.raises(ExperimentError, match="differ from the other findings'"):
        r.finding("f5", "x", True, "y")
    md = r.markdown()
    assert "| finding (paper) | here, a | here, b | evidence |" in md
    assert "| block helps | partly | reproduced | **a:** 2x. **b:** 5x |" in md
    paths = r.write()
    data = json.loads(paths["results"].read_text())
    assert data["findings"][0]["series"] == {"a": None, "b": True}
    assert data["findings"][0]["reproduced"] is None


def test_plain_table_checks_its_shape_and_escapes_cells(tmp_path):
    r = _report(tmp_path)
    r.table(["method", "value"], [["a|b", estimate([1.0, 3.0])]], key="plain")
    assert "| a\\|b | 2.00 m (" in r.markdown()
    assert r.results["plain"]["rows"][0][1]["mean"] == 2.0
    with pytest.raises(ExperimentError, match="2 cells for 3 columns"):
        r.table(["a", "b", "c"], [[1, 2]])
    with pytest.raises(ExperimentError, match="align"):
        r.table(["a", "b"], [[1, 2]], align="lx")
    with pytest.raises(ExperimentError, match="plain"):
        r.record("plain", 1)


def test_report_rejects_a_bad_variant_or_no_seed(tmp_path):
    with pytest.raises(ExperimentError, match="variant"):
        Report("x", "t", "c", variant="huge", seeds=[0], outdir=tmp_path)
    with pytest.raises(ExperimentError, match="variant must be one of 'small', 'full'"):
        Report("x", "t", "c", variant="case2", seeds=[0], outdir=tmp_path)
    r = Report("x", "t", "c", variant="case2", seeds=[0], outdir=tmp_path,
               variants=("small", "full", "case2"))
    assert r.variant == "case2"
    with pytest.raises(ExperimentError, match="no seed"):
        Report("x", "t", "c", variant="small", seeds=[], outdir=tmp_path)


def test_figures_are_plain_png_names_written_once(tmp_path):
    r = _report(tmp_path)
    path = r.figure(_figure(), "errors.png", "The errors")
    assert path == tmp_path / "out" / "errors.png" and path.read_bytes()[:4] == b"\x89PNG"
    assert "![The errors](errors.png)" in r.markdown()
    for bad in ("../up.png", "sub/x.png", "x.svg", ".png"):
        with pytest.raises(ExperimentError, match="plain file name"):
            r.figure(_figure(), bad, "bad")
    with pytest.raises(ExperimentError, match="twice"):
        r.figure(_figure(), "errors.png", "again")


def test_write_puts_findings_first_and_every_number_in_results_json(tmp_path):
    r = _report(tmp_path)
    r.section("Table II", "Text.")
    r.compare("t2", [Row("q", "1", estimate([1.0, math.nan, 2.0]))])
    r.finding("f1", "block helps", True, "5x")
    r.finding("f2", "ICPs rise", False, "they fall | here")
    r.finding("f3", "collocation", None, "untestable")
    with pytest.raises(ExperimentError, match="f1"):
        r.finding("f1", "again", True, "")
    r.record("arrays", {"a": np.array([1.0, np.nan]), "b": np.float32(2.5), 3: (1, 2)})
    paths = r.write(seconds=12.3)
    md = paths["report"].read_text()
    assert md.index("## Findings") < md.index("## Table II")
    assert "| block helps | reproduced | 5x |" in md
    assert "| ICPs rise | NOT reproduced | they fall \\| here |" in md
    assert "| collocation | partly | untestable |" in md
    assert "Run time: 12 s." in md and "seeds 0, 1, 2" in md
    data = json.loads(paths["results"].read_text())
    assert data["experiment"] == "demo" and data["variant"] == "small"
    assert data["seeds"] == [0, 1, 2] and data["seconds"] == 12.3
    assert [f["reproduced"] for f in data["findings"]] == [True, False, None]
    assert data["results"]["t2"][0]["geoblock"]["values"] == [1.0, None, 2.0]
    assert data["results"]["arrays"] == {"a": [1.0, None], "b": 2.5, "3": [1, 2]}
    assert data["figures"] == []


# ------------------------------------------------------------------------------ registry
def test_unknown_experiment_lists_the_known_ones():
    with pytest.raises(ExperimentError, match="unknown experiment 'nope'; known: teo2010, "
                                              "chen2008, chen1993, aguilar2007"):
        experiment_module("nope")
    assert isinstance(ExperimentError("x"), GeoblockError | ValueError)


@pytest.fixture
def fake(monkeypatch):
    """A tiny experiment registered as ``fake``: one table of its seeds."""
    module = types.ModuleType("fake_experiment")
    module.TITLE = "Fake"
    module.CITATION = "Nobody 2000"
    module.SEEDS = {"small": 2, "full": 5}
    calls = []

    def run(report, *, full, seeds, progress):
        calls.append((full, tuple(seeds)))
        progress("running")
        report.compare("seeds", [Row("seed", "-", estimate(seeds, ""))])
        report.figure(_figure(), "fig.png", "A figure")

    module.run = run
    monkeypatch.setitem(sys.modules, "fake_experiment", module)
    monkeypatch.setitem(EXPERIMENTS, "fake", registry._Entry("fake_experiment", "a fake"))
    return module, calls


def test_run_experiment_runs_the_seeds_and_writes_the_report(tmp_path, fake):
    _, calls = fake
    said = []
    result = run_experiment("fake", tmp_path / "o", seed=10, progress=said.append)
    assert calls == [(False, (10, 11))]
    assert result.report.is_file() and result.results.is_file()
    assert [p.name for p in result.figures] == ["fig.png"] and result.seconds >= 0
    assert said[0].startswith("experiment fake (small, 2 seeds): Fake") and "running" in said
    data = json.loads(result.results.read_text())
    assert data["seeds"] == [10, 11] and data["results"]["seeds"][0]["geoblock"]["mean"] == 10.5
    run_experiment("fake", tmp_path / "o", full=True, repeats=3)
    assert calls[-1] == (True, (0, 1, 2))


def test_an_experiment_with_more_variants_gets_the_variant(tmp_path, fake, monkeypatch):
    module, calls = fake
    module.SEEDS = {"small": 2, "full": 5, "case2": 1, "case2-full": 3}
    got = []

    def run(report, *, full, seeds, progress, variant):
        got.append((variant, full, tuple(seeds)))
        report.compare("seeds", [Row("seed", "-", estimate(seeds, ""))])

    module.run = run
    monkeypatch.setitem(EXPERIMENTS, "fake", registry._Entry(
        "fake_experiment", "a fake", more_variants={"case2": "II", "case2-full": "II, full"}))
    assert EXPERIMENTS["fake"].variants == ("small", "full", "case2", "case2-full")
    assert "case2-full" in registry.all_variants()
    result = run_experiment("fake", tmp_path / "o", variant="case2")
    run_experiment("fake", tmp_path / "p", variant="case2-full")
    run_experiment("fake", tmp_path / "q", full=True)
    assert got == [("case2", False, (0,)), ("case2-full", True, (0, 1, 2)),
                   ("full", True, (0, 1, 2, 3, 4))]
    assert json.loads(result.results.read_text())["variant"] == "case2"
    with pytest.raises(ExperimentError, match="experiment fake has no variant 'case3'; its "
                                              "variants: small, full, case2, case2-full"):
        run_experiment("fake", tmp_path / "r", variant="case3")
    del module.SEEDS["case2"]
    with pytest.raises(ExperimentError, match="'case2': n"):
        run_experiment("fake", tmp_path / "s", variant="case2")
    assert registry.is_full("full") and registry.is_full("case2-full")
    assert not registry.is_full("case2") and not registry.is_full("small")


def test_run_experiment_checks_its_options_before_running(tmp_path, fake):
    module, calls = fake
    with pytest.raises(ExperimentError, match="repeats must be >= 1"):
        run_experiment("fake", tmp_path, repeats=0)
    with pytest.raises(ExperimentError, match="seed must be >= 0"):
        run_experiment("fake", tmp_path, seed=-1)
    (tmp_path / "file").write_text("x")
    with pytest.raises(ExperimentError, match="is not a directory"):
        run_experiment("fake", tmp_path / "file")
    assert calls == []
    del module.CITATION
    module.SEEDS = {"small": 0}
    with pytest.raises(ExperimentError, match="lacks CITATION, SEEDS = "):
        run_experiment("fake", tmp_path)
