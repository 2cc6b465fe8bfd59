"""docs/user-guide/walkthrough-ventoux.md runs as written, and says what the run gives.

Every ``$ `` line of the page's ``console`` blocks is run in order in an empty directory,
the way a user pastes them into a shell: ``export`` sets a variable, ``cat > FILE <<EOF``
writes the here-document (variables expanded), the page's one ``sed`` line deletes lines,
and ``geoblock ...`` runs the command line (click's runner, in this process). Then the
outputs are checked, and so are the figures the page quotes: a page whose numbers no longer
match the run fails.
"""

from __future__ import annotations

import json
import re
import shlex
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

import geoblock
from geoblock.cli.main import build_cli
from geoblock.io import read_points

PAGE = Path(__file__).resolve().parents[2] / "docs" / "user-guide" / "walkthrough-ventoux.md"


def _steps(text: str) -> list[tuple[str, str | None]]:
    """``(command, here-document or None)`` of every ``$`` line of the ``console`` blocks."""
    steps: list[tuple[str, str | None]] = []
    for block in re.findall(r"```console\n(.*?)```", text, flags=re.S):
        lines = block.splitlines()
        k = 0
        while k < len(lines):
            line = lines[k]
            k += 1
            if not line.startswith("$ "):
                continue  # output shown in the block
            command = line[2:].strip()
            heredoc = None
            if command.endswith("<<EOF"):
                end = lines.index("EOF", k)
                heredoc, k = "\n".join(lines[k:end]) + "\n", end + 1
            steps.append((command, heredoc))
    return steps


def _expand(text: str, env: dict[str, str]) -> str:
    def value(m: re.Match[str]) -> str:
        name = m.group(1) or m.group(2)
        if name not in env:
            raise AssertionError(f"the page uses ${name} before setting it")
        return env[name]

    return re.sub(r"\$\{(\w+)\}|\$(\w+)", value, text)


def _run_page(data_dir: Path, workdir: Path) -> dict[str, str]:
    cli, runner = build_cli(), CliRunner()
    env: dict[str, str] = {}
    outputs: dict[str, str] = {}
    for command, heredoc in _steps(PAGE.read_text(encoding="utf-8")):
        if command.startswith("export "):
            name, value = command[len("export "):].split("=", 1)
            # the page's placeholder for the data folder is this machine's
            env[name] = (str(data_dir / "shareloc") if value == "/path/to/shared/data/shareloc"
                         else _expand(value, env))
        elif command.startswith("cat > ") and heredoc is not None:
            name = command.split()[2]
            (workdir / name).write_text(_expand(heredoc, env), encoding="utf-8")
        elif command.startswith("sed "):
            words = shlex.split(command)
            patterns = re.findall(r"/\^(\w+)/d", command)
            source, target = words[-3], words[-1]
            assert words[-2] == ">" and patterns, command
            kept = [line for line in (workdir / source).read_text().splitlines(keepends=True)
                    if not any(line.startswith(p) for p in patterns)]
            (workdir / target).write_text("".join(kept))
        elif command.startswith("geoblock "):
            args = shlex.split(_expand(command, env))[1:]
            result = runner.invoke(cli, args, catch_exceptions=False)
            assert result.exit_code == 0, (command, result.output)
            outputs[args[0] + ":" + (args[1] if len(args) > 1 else "")] = result.output
        else:
            raise AssertionError(f"the test does not know how to run: {command}")
    return outputs


@pytest.fixture(scope="module")
def walkthrough(data_dir, tmp_path_factory, monkeypatch_module):
    pytest.importorskip("geoblock_rpc", reason="the Ventoux RPCs need the geoblock-rpc plugin")
    for name in ("image/phr_ventoux/left_image.tif", "image/phr_ventoux/right_image.tif",
                 "rpc/phr_ventoux/left_image.geom", "rpc/phr_ventoux/right_image.geom",
                 "dtm/srtm_ventoux/srtm90_non_void_filled/N44E005.hgt",
                 "dtm/geoid/egm96_15.gtx"):
        if not (data_dir / "shareloc" / name).exists():
            pytest.skip(f"real data not found: {data_dir / 'shareloc' / name}")
    workdir = tmp_path_factory.mktemp("ventoux")
    monkeypatch_module.chdir(workdir)
    outputs = _run_page(data_dir, workdir)
    return workdir, outputs


@pytest.fixture(scope="module")
def monkeypatch_module():
    with pytest.MonkeyPatch.context() as mp:
        yield mp


def _quoted(pattern: str) -> float:
    """A number the page quotes (the first group of ``pattern``)."""
    m = re.search(pattern, PAGE.read_text(encoding="utf-8"))
    assert m, f"the page no longer says {pattern!r}"
    return float(m.group(1))


def test_every_command_ran_and_wrote_its_files(walkthrough):
    workdir, outputs = walkthrough
    for name in ("before_left.tif", "before_right.tif", "before_mosaic.tif", "tp.csv",
                 "block.toml", "block0.toml", "after_left.tif", "after_right.tif",
                 "after_mosaic.tif", "adjusted/report.md", "adjusted/models/right.json",
                 "adjusted/residuals_right.png", "vendor/report.json"):
        assert (workdir / name).is_file(), name
    assert "correction" not in (workdir / "block0.toml").read_text()


def test_tie_points_and_their_residuals_are_what_the_page_says(walkthrough):
    workdir, outputs = walkthrough
    tp = read_points(workdir / "tp.csv")
    n_points = np.unique(tp["id"]).size
    assert abs(n_points - _quoted(r"(\d+) tie points, ")) <= 0.1 * n_points
    ictp = np.unique(tp["id"][tp["kind"] == "ictp"]).size
    assert ictp == pytest.approx(_quoted(r"at the (\d+) ICTPs"), rel=0.1)
    report = json.loads((workdir / "adjusted" / "report.json").read_text())
    assert report["converged"]
    residuals = report["statistics"]["image_residuals_px"]
    for image in ("left", "right"):
        rms = residuals[image]["tp"]["rmse_2d"]
        assert rms < 0.2  # sub-pixel: the requirement
        assert rms == pytest.approx(_quoted(r"\*\*(0\.\d+) px RMS\*\*"), abs=0.02)
    a0, _, _, b0, _, _ = (p["value"] for p in report["parameters"]["right"])
    assert (a0, b0) == pytest.approx((_quoted(r"a0, b0 = \((-?\d+\.\d+),"),
                                      _quoted(r"a0, b0 = \(-?\d+\.\d+, (-?\d+\.\d+)\)")),
                                     abs=0.1)
    # not quoted by the page (no command prints it), checked for the run's consistency: the
    # correction where the crops overlap, the adjusted model against the vendor RPC at the
    # right image's tie points, is about the offset geoblock match reported (the page quotes)
    adjusted = geoblock.open_model(workdir / "adjusted" / "models" / "right.json")
    right = tp["image"] == "right"
    ground = adjusted.model.backproject(tp["row"][right], tp["col"][right], 500.0)
    r0, c0 = adjusted.model.project(ground.lon, ground.lat, ground.h)
    r1, c1 = adjusted.project(ground.lon, ground.lat, ground.h)
    shift = float(np.mean(r1 - r0)), float(np.mean(c1 - c0))
    match_output = next(v for k, v in outputs.items() if k.startswith("match:"))
    said = re.search(r"kept .*?models' offset ([-+]?[\d.]+), ([-+]?[\d.]+) px", match_output)
    assert said, match_output
    assert (float(said[1]), float(said[2])) == pytest.approx(
        (_quoted(r"`geoblock match` printed \((-?\d+\.\d+),"),
         _quoted(r"`geoblock match` printed \(-?\d+\.\d+, (-?\d+\.\d+) px\)")), abs=0.02)
    # within 0.15 px (measured 0.13 along rows): RPCV-1 trades part of a shift along the
    # epipolar direction for the tie points' heights, which the SRTM holds only within 10 m
    assert (float(said[1]), float(said[2])) == pytest.approx(shift, abs=0.2)
    rms = residuals["right"]["tp"]
    assert (rms["rmse_row"], rms["rmse_col"]) == pytest.approx(
        (_quoted(r"RMS\nrow (\d\.\d+) px"), _quoted(r"RMS\nrow \d\.\d+ px, col (\d\.\d+) px")),
        abs=0.003)
    overlap = re.search(r"(\d+) % of left overlaps right", match_output)
    assert overlap and int(overlap[1]) == _quoted(r"\((\d+) % of the left\ncrop")
    assert report["parameters"]["left"] == []  # the reference image is held


def test_the_ictps_agree_after_the_adjustment_as_the_page_says(walkthrough):
    workdir, _ = walkthrough
    stats = {name: json.loads((workdir / folder / "report.json").read_text())["statistics"]
             ["ictp"]["left & right"] for name, folder in (("vendor", "vendor"),
                                                          ("after", "adjusted"))}
    bias = {k: np.hypot(s["mean_e"], s["mean_n"]) for k, s in stats.items()}
    # the mean of n discrepancies is known to about rmse / sqrt(n) (0.25 m here): the vendor
    # RPCs' systematic disagreement is many times that, and none is left after the adjustment
    se = {k: s["rmse_2d"] / np.sqrt(s["n"]) for k, s in stats.items()}
    assert bias["vendor"] > 5 * se["vendor"] and bias["after"] < 2 * se["after"], (bias, se)
    assert stats["vendor"]["rmse_2d"] == pytest.approx(
        _quoted(r"\| vendor RPCs \| [-\d.]+ \| [-\d.]+ \| (\d+\.\d+) \|"), rel=0.1)
    assert stats["after"]["rmse_2d"] == pytest.approx(
        _quoted(r"\| after the block adjustment \| [-\d.]+ \| [-\d.]+ \| (\d+\.\d+) \|"),
        rel=0.1)


def test_the_orthos_misregistration_is_what_the_page_says(walkthrough):
    """Section 4 quotes the ICTP discrepancies as the two orthos' misregistration."""
    workdir, _ = walkthrough
    stats = {name: json.loads((workdir / folder / "report.json").read_text())["statistics"]
             ["ictp"]["left & right"] for name, folder in (("vendor", "vendor"),
                                                          ("after", "adjusted"))}
    vendor, after = stats["vendor"], stats["after"]
    assert vendor["rmse_2d"] == pytest.approx(_quoted(r"feature (\d+\.\d+) m apart"), abs=0.05)
    assert np.hypot(vendor["mean_e"], vendor["mean_n"]) == pytest.approx(
        _quoted(r"RMS\), (\d+\.\d+) m of it a shift"), abs=0.05)
    for name, s in stats.items():
        for axis in ("e", "n"):
            # the table's mean columns, also quoted in section 4
            row = "vendor RPCs" if name == "vendor" else "after the block adjustment"
            skip = "" if axis == "e" else r" -?\d+\.\d+ \|"
            quoted = _quoted(rf"\| {row} \|{skip}" + r" (-?\d+\.\d+) \|")
            assert s[f"mean_{axis}"] == pytest.approx(quoted, abs=0.01)
    page = PAGE.read_text(encoding="utf-8")
    for name, s in stats.items():
        prose = f"mean {s['mean_e']:.2f} m E, {s['mean_n']:.2f} m N"
        assert prose in page, prose
    assert after["rmse_2d"] == pytest.approx(
        _quoted(r"still differ by (\d+\.\d+) m RMS"), abs=0.05)
    assert after["max_2d"] == pytest.approx(_quoted(r"RMS, up to (\d+\.\d+) m"), abs=0.05)
