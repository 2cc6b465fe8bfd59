"""``geoblock adjust --solver/--start/--components`` and the block file's ``[options]``."""

from __future__ import annotations

import json
import shutil

import pytest

from geoblock.simulate.scenario import preset_dict, scenario_from_dict
from geoblock.workflows import run_scenario


@pytest.fixture(scope="module")
def simulated(tmp_path_factory):
    out = tmp_path_factory.mktemp("teo")
    run_scenario(scenario_from_dict(preset_dict("teo2010-spot5", "small")), out, render=False)
    return out


def test_solver_and_warm_start_from_the_written_output(runner, cli, simulated, tmp_path):
    block = tmp_path / "block"
    shutil.copytree(simulated, block)
    first = runner.invoke(cli, ["adjust", str(block / "block.toml"), "-o", str(tmp_path / "a"),
                                "--no-figures", "--solver", "direct"])
    assert first.exit_code == 0, first.output
    cold = json.loads((tmp_path / "a" / "report.json").read_text())
    assert "sparse LDL" in cold["solver"]
    assert "Normal equations: sparse LDL" in (tmp_path / "a" / "report.md").read_text()
    again = runner.invoke(cli, ["adjust", str(block / "block.toml"), "-o", str(tmp_path / "b"),
                                "--no-figures", "--start", str(tmp_path / "a")])
    assert again.exit_code == 0, again.output
    warm = json.loads((tmp_path / "b" / "report.json").read_text())
    assert warm["iterations"] < cold["iterations"]
    assert any(n.startswith("warm start from") for n in warm["notes"])
    assert abs(warm["sigma0"] - cold["sigma0"]) < 1e-6 * cold["sigma0"]


def test_block_file_options_solver_and_components(runner, cli, simulated, tmp_path):
    block = tmp_path / "block"
    shutil.copytree(simulated, block)
    text = (block / "block.toml").read_text()
    if "[options]" in text:
        pytest.skip("the preset's block file has its own [options] table")
    (block / "block.toml").write_text(
        text + '\n[options]\nsolver = "iterative"\ncomponents = "separate"\n')
    result = runner.invoke(cli, ["adjust", str(block / "block.toml"), "-o",
                                 str(tmp_path / "a"), "--no-figures"])
    assert result.exit_code == 0, result.output
    assert "PCG" in json.loads((tmp_path / "a" / "report.json").read_text())["solver"]
    bad = block / "bad.toml"
    bad.write_text((block / "block.toml").read_text().replace('"separate"', '"merge"'))
    result = runner.invoke(cli, ["adjust", str(bad), "-o", str(tmp_path / "c")])
    assert result.exit_code != 0
    assert "components must be one of" in result.output
