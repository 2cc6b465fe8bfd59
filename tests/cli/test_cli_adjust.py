"""``geoblock adjust``: a simulated block adjusted from its block file, outputs, and refusals."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

import geoblock
from geoblock.io import read_points, write_points
from geoblock.simulate.scenario import preset_dict, scenario_from_dict
from geoblock.workflows import run_scenario


@pytest.fixture(scope="module")
def simulated(tmp_path_factory):
    """teo2010-spot5 small, without images (its block.toml says method 'dg')."""
    out = tmp_path_factory.mktemp("teo")
    run_scenario(scenario_from_dict(preset_dict("teo2010-spot5", "small")), out, render=False)
    return out


@pytest.fixture
def block_dir(simulated, tmp_path):
    """A private copy of the simulated block (tests edit its files)."""
    target = tmp_path / "block"
    shutil.copytree(simulated, target)
    return target


def test_adjust_writes_models_reports_and_figures(runner, cli, block_dir):
    out = block_dir / "adj"
    result = runner.invoke(cli, ["adjust", str(block_dir / "block.toml"), "-o", str(out),
                                 "--compare-single"])
    assert result.exit_code == 0, result.output
    assert "iteration" in result.output  # progress lines (stderr is mixed in by CliRunner)
    assert "converged" in result.output and "ICTP strip1 & strip2" in result.output
    for image in ("strip1", "strip2", "strip3"):
        model = geoblock.open_model(out / "models" / f"{image}.json")
        # the dg method ends with least-squares collocation around the adjusted model
        assert model.name == "collocation" and model.model.name == "linescan"
        assert (out / f"errors_{image}.png").stat().st_size > 10_000
        assert (out / f"residuals_{image}.png").stat().st_size > 10_000
    report = json.loads((out / "report.json").read_text())
    # image residuals per image and kind: the statistics of the measurements' own residuals
    v = [(m["v_row"], m["v_col"]) for m in report["measurements"]
         if m["image"] == "strip2" and m["kind"] == "tp"]
    tp = report["statistics"]["image_residuals_px"]["strip2"]["tp"]
    assert tp["n"] == len(v)
    assert tp["rmse_2d"] == pytest.approx(np.sqrt(np.mean([r * r + c * c for r, c in v])))
    assert set(report["statistics"]["image_residuals_px"]["strip2"]) == {"gcp", "icp", "tp",
                                                                         "all"}
    assert report["converged"] and 0.7 < report["sigma0"] < 1.3
    assert report["mode"] == "block" and report["dem_control"] == "observation"
    assert {m["kind"] for m in report["measurements"]} == {"gcp", "icp", "tp", "ictp"}
    tps = [p for p in report["points"] if p["kind"] == "tp"]
    assert tps and all(len(p["covariance_enu_m2"]) == 3 for p in tps)
    assert set(report["statistics"]["ictp"]) == {"strip1 & strip2", "strip2 & strip3"}
    assert "single" in report
    text = (out / "report.md").read_text()
    for heading in ("Accuracy at control and check points", "Relative accuracy at ICTPs",
                    "## Image residuals", "| strip2 | TP |",
                    "Single versus block adjustment", "| dp_along | m |"):
        assert heading in text


def test_adjusted_model_is_better_than_the_onboard_one(runner, cli, block_dir):
    out = block_dir / "adj"
    assert runner.invoke(cli, ["adjust", str(block_dir / "block.toml"), "-o",
                               str(out)]).exit_code == 0
    truth = read_points(block_dir / "points" / "truth.csv")
    sel = (truth["kind"] == "icp") & (truth["image"] == "strip3")
    lon, lat, h = (truth[k].astype(float)[sel] for k in ("lon_true", "lat_true", "h_true"))
    errors = {}
    for name, path in (("onboard", block_dir / "images" / "strip3_onboard.json"),
                       ("adjusted", out / "models" / "strip3.json")):
        r, c = geoblock.open_model(path).project(lon, lat, h)
        errors[name] = np.sqrt(np.mean((r - truth["row_true"].astype(float)[sel]) ** 2
                                       + (c - truth["col_true"].astype(float)[sel]) ** 2))
    assert errors["adjusted"] < errors["onboard"] / 5


def test_options_override_the_file(runner, cli, block_dir):
    out = block_dir / "adj"
    result = runner.invoke(cli, ["adjust", str(block_dir / "block.toml"), "-o", str(out),
                                 "--mode", "single", "--no-figures"])
    assert result.exit_code == 0, result.output
    assert json.loads((out / "report.json").read_text())["mode"] == "single"
    assert not list(out.glob("*.png"))


def test_failure_writes_nothing_and_names_the_point(runner, cli, block_dir):
    image = read_points(block_dir / "points" / "image.csv")
    tp = np.flatnonzero(image["kind"] == "tp")
    victim = image["id"][tp[0]]
    keep = ~((image["id"] == victim) & (image["image"] != image["image"][tp[0]]))
    write_points(block_dir / "points" / "image.csv", {k: v[keep] for k, v in image.items()})
    out = block_dir / "adj"
    result = runner.invoke(cli, ["adjust", str(block_dir / "block.toml"), "-o", str(out)])
    assert result.exit_code == 1
    assert victim in result.output and "one image" in result.output
    assert not out.exists()
    assert not [p for p in block_dir.iterdir() if p.name.startswith(".adj")]


def test_failure_keeps_a_previous_output(runner, cli, block_dir):
    out = block_dir / "adj"
    out.mkdir()
    (out / "report.md").write_text("previous")  # a previous adjustment's output
    text = (block_dir / "block.toml").read_text().replace('method = "dg"', 'method = "mba"')
    (block_dir / "block.toml").write_text(text)
    result = runner.invoke(cli, ["adjust", str(block_dir / "block.toml"), "-o", str(out),
                                 "--overwrite"])
    assert result.exit_code == 1
    assert "'mba'" in result.output and "'dg'" in result.output  # the sets the model offers
    assert (out / "report.md").read_text() == "previous"


def test_an_output_directory_with_the_users_files_is_refused_not_replaced(runner, cli, block_dir):
    """A run must not replace a directory holding files it did not write (a mistyped -o
    would otherwise delete them), even with --overwrite, and says so before adjusting; an
    existing output needs --overwrite, and then a previous output is replaced."""
    out = block_dir / "mine"
    out.mkdir()
    (out / "thesis.txt").write_text("precious")
    result = runner.invoke(cli, ["adjust", str(block_dir / "block.toml"), "-o", str(out)])
    assert result.exit_code == 1
    assert "exists and is not empty" in result.output and "--overwrite" in result.output
    assert "iteration" not in result.output  # refused before any work
    result = runner.invoke(cli, ["adjust", str(block_dir / "block.toml"), "-o", str(out),
                                 "--overwrite"])
    assert result.exit_code == 1
    assert "'thesis.txt'" in result.output and "choose another directory" in result.output
    assert "iteration" not in result.output  # refused before any work
    assert [p.name for p in out.iterdir()] == ["thesis.txt"]
    again = block_dir / "again"
    result = runner.invoke(cli, ["adjust", str(block_dir / "block.toml"), "-o", str(again),
                                 "--no-figures"])
    assert result.exit_code == 0, result.output
    before = (again / "report.json").read_bytes()
    result = runner.invoke(cli, ["adjust", str(block_dir / "block.toml"), "-o", str(again),
                                 "--no-figures"])  # the first run's output is not replaced
    assert result.exit_code == 1 and "--overwrite" in result.output
    assert (again / "report.json").read_bytes() == before
    result = runner.invoke(cli, ["adjust", str(block_dir / "block.toml"), "-o", str(again),
                                 "--no-figures", "--overwrite"])
    assert result.exit_code == 0, result.output
    assert sorted(p.name for p in again.iterdir()) == ["models", "report.json", "report.md"]


@pytest.mark.parametrize("edit, words", [
    (('method = "dg"', 'method = "bundle"'), ["block.toml", "method", "bundle", "rpcv1"]),
    (('method = "dg"', 'method = "dg"\n[options]\nrobustness = "huber"'),
     ["options.robustness", "unknown option"]),
    (('method = "dg"', 'method = "dg"\n[options]\nmax_iterations = "ten"'),
     ["options.max_iterations", "int"]),
    (("sigma = 5.0", "sigma = -5.0"), ["dem.sigma", "> 0"]),
    (('id = "strip2"', 'id = "strip2"\ncorrection = 3'), ["images[1]", "correction", "0, 1 or 2"]),
    (('method = "dg"', 'method = "dg"\nmode = "both"'), ["mode", "'block' or 'single'"]),
    (('id = "strip2"', 'id = "strip2"\nsigmas = { warp = 1.0 }'),
     ["strip2", "no parameter 'warp'"]),
])
def test_block_file_errors_name_the_file_and_field(runner, cli, block_dir, edit, words):
    path = block_dir / "block.toml"
    text = path.read_text()
    assert edit[0] in text
    path.write_text(text.replace(edit[0], edit[1], 1))
    result = runner.invoke(cli, ["adjust", str(path), "-o", str(block_dir / "adj")])
    assert result.exit_code == 1, result.output
    line = [ln for ln in result.output.splitlines() if ln.startswith("Error:")]
    assert len(line) == 1, result.output
    for word in words:
        assert word in line[0], line[0]
    assert not (block_dir / "adj").exists()


def test_simulate_then_adjust_with_relative_paths(runner, cli, tmp_path, monkeypatch):
    """The README's two lines, from a working directory, with relative paths."""
    monkeypatch.chdir(tmp_path)
    scenario = tmp_path / "tiny.toml"
    scenario.write_text('preset = "teo2010-spot5"\n[render]\nenabled = false\n')
    assert runner.invoke(cli, ["simulate", "tiny.toml", "teo"]).exit_code == 0
    text = (tmp_path / "teo" / "block.toml").read_text()
    assert 'ground = "points/ground.csv"' in text  # relative to the block file
    result = runner.invoke(cli, ["adjust", "teo/block.toml"])
    assert result.exit_code == 0, result.output
    assert (tmp_path / "teo" / "adjusted" / "report.md").exists()


def test_help(runner, cli):
    result = runner.invoke(cli, ["adjust", "--help"])
    assert result.exit_code == 0
    for word in ("BLOCK.toml", "--output", "--mode", "--robust", "--dem-control",
                 "--collocation", "--compare-single", "report.json"):
        assert word in result.output
