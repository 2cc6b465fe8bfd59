"""geoblock refine: GCP/ICP files in, report out, refined model written (any model)."""

from __future__ import annotations

import csv
import json
import re
import warnings
from pathlib import Path

import numpy as np
import pytest

import geoblock
from geoblock import ImageCorrection
from geoblock.errors import GeoblockWarning

TRUE = {0: [2.0, -1.5], 1: [2.0, 1.2, -0.7, -1.5, 0.4, 2.2]}


def _simulate(model, order, n, seed):
    """Points of ``ImageCorrection(model, order, TRUE)``: random image points, random heights."""
    distorted = ImageCorrection(model, order, TRUE[order])
    rng = np.random.default_rng(seed)
    rows, cols = model.shape
    lo, hi = model.height_range
    row = rng.uniform(0, rows - 1, n)
    col = rng.uniform(0, cols - 1, n)
    h = rng.uniform(lo, hi, n)
    (lon, lat, _), status = distorted.backproject_with_status(row, col, h)
    assert np.all(status == 0)
    return lon, lat, h, row, col


def _write(path, model, order, n, seed, prefix="p", kinds=None):
    lon, lat, h, row, col = _simulate(model, order, n, seed)
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["id", "lon", "lat", "h", "row", "col"] + (["kind"] if kinds else []))
        for i in range(n):
            extra = [kinds[i]] if kinds else []
            w.writerow([f"{prefix}{i}", *(repr(float(v[i])) for v in (lon, lat, h, row, col)),
                        *extra])
    return str(path)


@pytest.fixture
def points(tmp_path, affine):
    return {
        "gcps": _write(tmp_path / "gcps.csv", affine, 1, 8, 1, "g"),
        "icps": _write(tmp_path / "icps.csv", affine, 1, 12, 2, "c"),
    }


def test_refine_order1_with_icps(runner, cli, model_path, points, tmp_path):
    out = tmp_path / "out.json"
    result = runner.invoke(cli, ["refine", model_path, "--gcps", points["gcps"], "--icps",
                                 points["icps"], "--order", "1", "-o", str(out)])
    assert result.exit_code == 0, result.output
    text = result.stdout
    for word in ("a0", "b2", "GCP residuals", "g7", "RMSE 2D", "mean E", "max N", "ICP"):
        assert word in text
    icp_line = next(line for line in text.splitlines() if line.startswith("ICP "))
    assert int(icp_line.split()[1]) == 12
    assert f"refined model written to {out} (json)" in text
    refined = geoblock.open_model(out)
    assert isinstance(refined, ImageCorrection) and refined.order == 1
    np.testing.assert_allclose(refined.parameters.values, TRUE[1], atol=1e-6)


def test_refine_default_output_beside_model(runner, cli, model_path, points, tmp_path):
    result = runner.invoke(cli, ["refine", model_path, "--gcps", points["gcps"], "--order", "0"])
    assert result.exit_code == 0, result.output
    out = tmp_path / "affine.refined.json"
    assert out.is_file() and str(out) in result.stdout
    assert geoblock.open_model(out).order == 0
    assert not any(line.startswith("ICP ") for line in result.stdout.splitlines())


def test_refine_points_with_kind_column(runner, cli, model_path, affine, tmp_path):
    kinds = ["gcp", "icp", "GCP", "icp", "gcp", "gcp", "icp", "gcp", "icp", "gcp"]
    path = _write(tmp_path / "all.csv", affine, 1, 10, 3, kinds=kinds)
    out = tmp_path / "r.json"
    result = runner.invoke(cli, ["refine", model_path, "--points", path, "-o", str(out)])
    assert result.exit_code == 0, result.output
    counts = {line.split()[0]: int(line.split()[1]) for line in result.stdout.splitlines()
              if re.match(r"(GCP|ICP) +\d", line)}
    assert counts == {"GCP": 6, "ICP": 4}
    np.testing.assert_allclose(geoblock.open_model(out).parameters.values, TRUE[1], atol=1e-6)


def test_refine_too_few_gcps_states_minimum(runner, cli, model_path, affine, tmp_path):
    gcps = _write(tmp_path / "two.csv", affine, 1, 2, 4)
    result = runner.invoke(cli, ["refine", model_path, "--gcps", gcps, "--order", "1",
                                 "-o", str(tmp_path / "x.json")])
    assert result.exit_code == 1
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("Error: ")
    assert "at least 3 GCPs" in lines[0]
    assert not (tmp_path / "x.json").exists()


def test_refine_sigma_px_scales_sigma0(runner, cli, model_path, affine, tmp_path):
    lon, lat, h, row, col = _simulate(affine, 1, 10, 5)
    rng = np.random.default_rng(0)
    path = tmp_path / "noisy.csv"
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["id", "lon", "lat", "h", "row", "col"])
        for i in range(10):
            w.writerow([i, lon[i], lat[i], h[i], row[i] + rng.normal(0, 0.5),
                        col[i] + rng.normal(0, 0.5)])

    def sigma0(extra):
        result = runner.invoke(cli, ["refine", model_path, "--gcps", str(path),
                                     "-o", str(tmp_path / "s.json"), "--overwrite", *extra])
        assert result.exit_code == 0, result.output
        return float(result.stdout.split("sigma0 ")[1].split(",")[0])

    assert sigma0(["--sigma-px", "0.25"]) == pytest.approx(2 * sigma0([]), rel=1e-3)


def test_refine_write_reports_plugin_messages(runner, cli, model_path, points, tmp_path,
                                              monkeypatch):
    import geoblock.io

    calls = []
    real = geoblock.io.write_model

    def fake(model, path, format=None, **options):
        calls.append((format, Path(path).name))
        if format == "fake-rpc":
            Path(path).write_text("fake\n")
            warnings.warn(
                f"{path}: RPC00B approximate (refit): max error 1e-07 px", GeoblockWarning,
                stacklevel=2,
            )
            return path
        return real(model, path, format=format, **options)

    monkeypatch.setattr(geoblock.io, "write_model", fake)
    out = tmp_path / "extra.json"
    result = runner.invoke(cli, ["refine", model_path, "--gcps", points["gcps"],
                                 "-o", str(tmp_path / "main.json"),
                                 "--write", f"fake-rpc:{tmp_path / 'x_RPC.TXT'}",
                                 "--write", f"json:{out}"])
    assert result.exit_code == 0, result.output
    assert calls[1:] == [("fake-rpc", "x_RPC.TXT"), ("json", out.name)]
    # the message names the destination, not the staging file the writer was given
    assert f"  {tmp_path / 'x_RPC.TXT'}: RPC00B approximate (refit): max error 1e-07 px" in (
        result.stdout)
    assert out.is_file() and (tmp_path / "x_RPC.TXT").read_text() == "fake\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "affine.json", "extra.json", "gcps.csv", "icps.csv", "main.json", "x_RPC.TXT"]


def test_refine_write_unknown_format_is_one_error_line(runner, cli, model_path, points, tmp_path):
    result = runner.invoke(cli, ["refine", model_path, "--gcps", points["gcps"],
                                 "-o", str(tmp_path / "m.json"),
                                 "--write", f"no-such-format:{tmp_path / 'x.txt'}"])
    assert result.exit_code == 1
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("Error: ") and "no-such-format" in lines[0]
    assert str(tmp_path / "x.txt") in lines[0]  # the destination, not a staging path
    assert not (tmp_path / "m.json").exists()  # every output is checked before any is written
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".geoblock-refine")]


@pytest.mark.parametrize("args, message", [
    (["--write", ":x.json"], "FORMAT:PATH"),
    (["--order", "3"], "--order"),
    ([], "missing --gcps"),
])
def test_refine_usage_errors(runner, cli, model_path, args, message):
    result = runner.invoke(cli, ["refine", model_path, *args])
    assert result.exit_code == 2 and message in result.stderr


def test_refine_points_and_gcps_are_exclusive(runner, cli, model_path, points):
    result = runner.invoke(cli, ["refine", model_path, "--gcps", points["gcps"],
                                 "--points", points["icps"]])
    assert result.exit_code == 2 and "not both" in result.stderr


def test_refine_points_need_kind(runner, cli, model_path, points):
    result = runner.invoke(cli, ["refine", model_path, "--points", points["gcps"]])
    assert result.exit_code == 1 and "'kind' column" in result.stderr


def test_refine_help_has_example(runner, cli):
    result = runner.invoke(cli, ["refine", "--help"])
    assert result.exit_code == 0
    assert "Examples:" in result.stdout and "geoblock refine scene.json --gcps" in result.stdout
    assert "refine" in runner.invoke(cli, ["--help"]).stdout


# ------------------------------------------------------------------ issue 12, item 11
def test_refine_write_checks_every_format_before_writing_anything(
        runner, cli, model_path, points, tmp_path):
    """A failing later --write leaves no file behind: not -o, not the earlier --write."""
    main, first = tmp_path / "main.json", tmp_path / "first.json"
    first.write_text("keep me\n")  # an existing destination is not touched either
    result = runner.invoke(cli, ["refine", model_path, "--gcps", points["gcps"], "-o", str(main),
                                 "--write", f"json:{first}"])
    assert result.exit_code == 1 and "--overwrite" in result.stderr, result.output
    assert "GCP" not in result.stdout  # refused before any work
    assert not main.exists() and first.read_text() == "keep me\n"
    result = runner.invoke(cli, ["refine", model_path, "--gcps", points["gcps"], "-o", str(main),
                                 "--write", f"json:{first}", "--overwrite",
                                 "--write", f"nitf:{tmp_path / 'x.ntf'}"])
    assert result.exit_code == 1, result.output
    assert "nitf" in result.stderr and str(tmp_path / "x.ntf") in result.stderr
    assert not main.exists() and first.read_text() == "keep me\n"
    assert not (tmp_path / "x.ntf").exists()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".geoblock-refine")]
    result = runner.invoke(cli, ["refine", model_path, "--gcps", points["gcps"], "-o", str(main),
                                 "--write", f"{tmp_path / 'x.txt'}"])
    assert result.exit_code == 1 and "cannot infer a model format" in result.stderr
    assert not main.exists()


def test_refine_same_output_twice_is_refused(runner, cli, model_path, points, tmp_path):
    out = tmp_path / "m.json"
    result = runner.invoke(cli, ["refine", model_path, "--gcps", points["gcps"], "-o", str(out),
                                 "--write", f"json:{out}"])
    assert result.exit_code == 1 and "is also written as" in result.stderr and not out.exists()


def test_unknown_model_name_in_json_is_named_with_the_file(tmp_path, model_path, runner, cli):
    from geoblock.errors import UnknownModelError

    data = json.loads(Path(model_path).read_text())
    data["model"] = "no-such-model"
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(data))
    with pytest.raises(UnknownModelError) as info:
        geoblock.open_model(bad)
    assert "no-such-model" in str(info.value) and str(bad) in str(info.value)
    result = runner.invoke(cli, ["refine", str(bad), "--gcps", model_path])
    assert result.exit_code == 1
    assert "no-such-model" in result.stderr and str(bad) in result.stderr


@pytest.fixture(scope="module")
def simulated(tmp_path_factory):
    """A small simulated SPOT-1 block (``geoblock simulate``'s files)."""
    from geoblock.simulate.scenario import preset_dict, scenario_from_dict
    from geoblock.workflows import run_scenario

    out = tmp_path_factory.mktemp("sim")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        run_scenario(scenario_from_dict(preset_dict("chen1993-spot1a", "small")), out,
                     render=False)
    return out


def _icp_rms_px(model, ground_csv, image_csv, image_id):
    """RMS image discrepancy (pixels) of ``model`` at the ICPs of ``image_id``."""
    from geoblock.adjust import GroundPoints, ImagePoints
    from geoblock.io import read_points

    ground = GroundPoints.from_columns(read_points(ground_csv))
    icps = ImagePoints.from_columns(read_points(image_csv)).control_points(
        ground, image_id, ("icp",))
    assert len(icps.id) >= 5
    row, col = model.project(icps.lon, icps.lat, icps.h)
    return float(np.sqrt(np.mean((row - icps.row) ** 2 + (col - icps.col) ** 2)))


def test_refine_reads_the_point_files_simulate_writes(runner, cli, simulated, tmp_path):
    ground, image = simulated / "points" / "ground.csv", simulated / "points" / "image.csv"
    onboard = simulated / "images" / "spot1a_onboard.json"
    out = tmp_path / "refined.json"
    result = runner.invoke(cli, ["refine", str(onboard), "--ground-points", str(ground),
                                 "--image-points", str(image), "--order", "1", "-o", str(out)])
    assert result.exit_code == 0, result.output
    n_gcp = sum(1 for line in ground.read_text().splitlines() if line.endswith(",gcp"))
    n_icp = sum(1 for line in ground.read_text().splitlines() if line.endswith(",icp"))
    assert f"image spot1a: {n_gcp} GCPs, {n_icp} ICPs" in result.stdout
    icp_line = next(line for line in result.stdout.splitlines() if line.startswith("ICP "))
    assert int(icp_line.split()[1]) == n_icp
    before = _icp_rms_px(geoblock.open_model(onboard), ground, image, "spot1a")
    after = _icp_rms_px(geoblock.open_model(out), ground, image, "spot1a")
    assert after < 0.5 * before, (before, after)
    # --image-id names the image explicitly: same result
    out2 = tmp_path / "refined2.json"
    result = runner.invoke(cli, ["refine", str(onboard), "--ground-points", str(ground), "--image-points",
                                 str(image), "--image-id", "spot1a", "-o", str(out2)])
    assert result.exit_code == 0, result.output
    assert json.loads(out2.read_text()) == json.loads(out.read_text())


def test_refine_image_file_with_several_images_needs_image_id(runner, cli, simulated, tmp_path):
    ground, image = simulated / "points" / "ground.csv", simulated / "points" / "image.csv"
    onboard = simulated / "images" / "spot1a_onboard.json"
    lines = image.read_text().splitlines()
    two = tmp_path / "image2.csv"
    two.write_text("\n".join([*lines, *(line.replace(",spot1a,", ",spot1b,")
                                        for line in lines[1:])]) + "\n")
    result = runner.invoke(cli, ["refine", str(onboard), "--ground-points", str(ground),
                                 "--image-points", str(two), "-o", str(tmp_path / "r.json")])
    assert result.exit_code == 2
    assert "spot1a, spot1b" in result.stderr and "--image-id" in result.stderr
    assert not (tmp_path / "r.json").exists()
    result = runner.invoke(cli, ["refine", str(onboard), "--ground-points", str(ground),
                                 "--image-points", str(two), "--image-id", "spot9"])
    assert result.exit_code == 2 and "'spot9'" in result.stderr and "spot1a, spot1b" in (
        result.stderr)
    result = runner.invoke(cli, ["refine", str(onboard), "--ground-points", str(ground),
                                 "--image-points", str(two), "--image-id", "spot1b",
                                 "-o", str(tmp_path / "r.json")])
    assert result.exit_code == 0, result.output
    assert (tmp_path / "r.json").is_file()


@pytest.mark.parametrize("args, message", [
    (["--ground-points", "g.csv"], "--ground-points and --image-points go together"),
    (["--image-points", "i.csv"], "--ground-points and --image-points go together"),
    (["--ground", "g.csv"], "--ground-points and --image-points go together"),  # deprecated
    (["--ground-points", "g.csv", "--image-points", "i.csv", "--gcps", "x.csv"], "not several"),
    (["--gcps", "x.csv", "--image-id", "a"], "--image-id selects"),
])
def test_refine_block_file_usage_errors(runner, cli, model_path, args, message):
    result = runner.invoke(cli, ["refine", model_path, *args])
    assert result.exit_code == 2 and message in result.stderr, result.output
