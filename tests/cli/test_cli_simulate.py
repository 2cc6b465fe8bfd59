"""``geoblock simulate``: presets and TOML files, options, progress and errors."""

from __future__ import annotations

import tomllib

from geoblock.io import read_block


def _tiny_toml(tmp_path):
    """A scenario file starting from a preset, shrunk to seconds."""
    path = tmp_path / "tiny.toml"
    path.write_text(
        'preset = "chen1993-spot1a"\n'
        "seed = 11\n"
        "[terrain]\nresolution_m = 400.0\n"
        '[[dems]]\nname = "dem400"\nspacing_m = 400.0\nrmse_z = 20.0\n'
        '[[images]]\nid = "scene"\npreset = "spot1a"\nscale = 40\n'
    )
    return path


def test_help_lists_presets(runner, cli):
    result = runner.invoke(cli, ["simulate", "--help"])
    assert result.exit_code == 0
    for name in ("teo2010-spot5", "aguilar2007-quickbird", "chen1993-spot1a", "--variant",
                 "--seed", "--no-images", "--overwrite"):
        assert name in result.output
    listed = runner.invoke(cli, ["simulate", "--list"])
    assert listed.exit_code == 0 and "aguilar2007-quickbird" in listed.output
    assert "simulate" in runner.invoke(cli, ["--help"]).output


def test_simulate_toml_with_progress(runner, cli, tmp_path):
    out = tmp_path / "out"
    result = runner.invoke(cli, ["simulate", str(_tiny_toml(tmp_path)), str(out), "--seed", "5"])
    assert result.exit_code == 0, result.output
    assert "terrain: ridged" in result.stderr and "rendering scene" in result.stderr
    assert result.stdout.strip() == str(out / "report" / "report.md")
    assert (out / "images" / "scene.tif").is_file()
    assert tomllib.loads((out / "scenario.toml").read_text())["seed"] == 5
    assert [im.id for im in read_block(out / "block.toml").images] == ["scene"]
    # a non-empty OUTDIR is refused without --overwrite (--force: its deprecated spelling)
    again = runner.invoke(cli, ["simulate", str(out / "scenario.toml"), str(out)])
    assert again.exit_code == 1 and "not empty" in again.output and "--overwrite" in again.output
    forced = runner.invoke(cli, ["simulate", str(out / "scenario.toml"), str(out), "--force",
                                 "--no-images"])
    assert forced.exit_code == 0, forced.output
    assert "not rendered" in forced.stderr


def test_unknown_preset_lists_the_known_ones(runner, cli, tmp_path):
    result = runner.invoke(cli, ["simulate", "teo2011", str(tmp_path / "o")])
    assert result.exit_code == 1
    assert "Error: unknown scenario 'teo2011'" in result.output
    assert "teo2010-spot5" in result.output and "chen1993-spot1a" in result.output
    assert not (tmp_path / "o").exists()


def test_bad_file_names_the_key(runner, cli, tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text('preset = "teo2010-spot5"\n[points]\ngcps = 3\n')
    result = runner.invoke(cli, ["simulate", str(path), str(tmp_path / "o")])
    assert result.exit_code == 1
    assert f"{path}: points.gcps: unknown key" in result.output
    result = runner.invoke(cli, ["simulate", "teo2010-spot5", str(tmp_path / "o"),
                                 "--variant", "medium"])
    assert result.exit_code == 2
