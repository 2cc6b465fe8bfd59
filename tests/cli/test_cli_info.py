"""geoblock info."""

from __future__ import annotations

import json

import numpy as np

import geoblock
from geoblock.testing.synthetic import AffineCamera, ConstantVelocityPushbroom


def test_info_text(runner, cli, model_path):
    result = runner.invoke(cli, ["info", model_path])
    assert result.exit_code == 0, result.output
    out = result.stdout
    assert "synthetic-affine" in out
    assert "1000 rows x 1200 cols" in out
    assert "-500 .. 3000 m" in out
    assert "8 (8 adjustable)" in out
    assert "row_n" in out and "px/m" in out and "free" in out
    assert "footprint at h = 1250 m" in out
    for corner in ("top-left", "top-right", "bottom-right", "bottom-left"):
        assert corner in out
    assert "2.000 m" in out  # the example is a 2 m GSD camera
    assert result.stderr == ""


def test_info_json(runner, cli, model_path, affine):
    result = runner.invoke(cli, ["info", model_path, "--json"])
    assert result.exit_code == 0, result.output
    data = json.loads(result.stdout)
    assert data["model"] == "synthetic-affine"
    assert data["shape"] == {"rows": 1000, "cols": 1200, "stated": True}
    assert data["height_range"] == [-500.0, 3000.0]
    params = {p["name"]: p for p in data["parameters"]}
    assert list(params) == list(affine.parameters.names)
    assert params["row_n"] == {
        "name": "row_n", "value": -0.5, "unit": "px/m", "sigma": None, "adjustable": True
    }
    expected = affine.footprint(n=1)
    corners = data["footprint"]["corners"]
    names = [c["corner"] for c in corners]
    assert names == ["top-left", "top-right", "bottom-right", "bottom-left"]
    np.testing.assert_allclose([c["lon"] for c in corners], expected.lon, rtol=0, atol=1e-9)
    np.testing.assert_allclose([c["lat"] for c in corners], expected.lat, rtol=0, atol=1e-9)
    assert data["footprint"]["h"] == 1250.0
    assert abs(data["gsd"]["row_m"] - 2.0) < 0.01
    assert abs(data["gsd"]["col_m"] - 2.0) < 0.01


def test_info_height_and_model_option(runner, cli, tmp_path):
    model = ConstantVelocityPushbroom.example()
    path = str(geoblock.write_model(model, tmp_path / "pushbroom.json"))
    result = runner.invoke(
        cli, ["info", path, "--model-type", "synthetic-pushbroom", "--height", "0", "--json"]
    )
    assert result.exit_code == 0, result.output
    data = json.loads(result.stdout)
    assert data["model"] == "synthetic-pushbroom"
    assert data["shape"] == {"rows": model.shape[0], "cols": model.shape[1],
                             "stated": True}
    assert data["footprint"]["h"] == 0.0 and data["gsd"]["h"] == 0.0
    assert data["gsd"]["mean_m"] > 0
    assert [p["name"] for p in data["parameters"]] == list(model.parameters.names)

    result = runner.invoke(cli, ["info", path, "--model-type", "no-such-model"])
    assert result.exit_code == 1
    assert len(result.stderr.splitlines()) == 1
    assert "no-such-model" in result.stderr and "synthetic-affine" in result.stderr


def test_info_finite_sigma_shown(runner, cli, tmp_path, affine):
    model = AffineCamera(affine.shape, (7.05, 43.70, 100.0), affine.coefficients,
                         affine.height_range, sigmas=[0.5] * 4 + [np.inf] * 4)
    path = str(geoblock.write_model(model, tmp_path / "m.json"))
    result = runner.invoke(cli, ["info", path])
    assert result.exit_code == 0, result.output
    row_0 = next(ln for ln in result.stdout.splitlines() if ln.strip().startswith("row_0"))
    col_0 = next(ln for ln in result.stdout.splitlines() if ln.strip().startswith("col_0"))
    assert "0.5" in row_0.split()[3] and col_0.split()[3] == "free"


def test_unreadable_model_file(runner, cli, tmp_path):
    path = tmp_path / "notes.txt"
    path.write_text("not a model\n")
    result = runner.invoke(cli, ["info", str(path)])
    assert result.exit_code == 1
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("Error: ") and "notes.txt" in lines[0]
