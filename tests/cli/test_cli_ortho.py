"""``geoblock ortho``: help, a smoke run, gdalwarp-style grids, errors."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import rasterio

import geoblock
from geoblock.testing.synthetic import AffineCamera


def _image(path, shape):
    data = (np.arange(shape[0] * shape[1]) % 251).astype(np.uint8).reshape((1,) + shape)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
        with rasterio.open(path, "w", driver="GTiff", width=shape[1], height=shape[0], count=1,
                           dtype="uint8") as ds:
            ds.write(data)
    return str(path)


def test_help(runner, cli):
    result = runner.invoke(cli, ["ortho", "--help"])
    assert result.exit_code == 0, result.output
    for option in ("--dem", "--dem-vertical", "--geoid", "--model", "--crs", "--res",
                   "--bounds", "--resampling", "--tolerance", "--chunks", "--scheduler"):
        assert option in result.output
    assert "ortho" in runner.invoke(cli, ["--help"]).output


def test_smoke(runner, cli, tmp_path):
    model = AffineCamera.example((60, 80))
    model_path = str(geoblock.write_model(model, tmp_path / "model.json"))
    image = _image(tmp_path / "scene.tif", (60, 80))
    out = tmp_path / "ortho.tif"
    result = runner.invoke(cli, ["ortho", image, str(out), "--dem", "const:150", "--model",
                                 model_path, "--chunks", "32", "--resampling", "bicubic"])
    assert result.exit_code == 0, result.output
    with rasterio.open(out) as ds:
        assert ds.count == 1 and ds.dtypes[0] == "uint8" and ds.crs is not None
        assert ds.read().any()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["model.json", "ortho.tif", "scene.tif"]


def test_gdalwarp_grid(runner, cli, tmp_path):
    model = AffineCamera.example((60, 80))
    model_path = str(geoblock.write_model(model, tmp_path / "model.json"))
    image = _image(tmp_path / "scene.tif", (60, 80))
    out = tmp_path / "ortho.tif"
    grid = geoblock.ortho.OutputGrid.for_model(model, geoblock.open_dem("const:150"))
    x0, y0, x1, y1 = grid.bounds
    result = runner.invoke(cli, [
        "ortho", image, str(out), "--dem", "const:150", "--model", model_path,
        "--crs", "EPSG:32632", "--res", "3", "--bounds", str(x0), str(y0), str(x1), str(y1),
        "--tolerance", "0", "--no-progress", "--scheduler", "synchronous",
    ])
    assert result.exit_code == 0, result.output
    with rasterio.open(out) as ds:
        assert ds.transform.a == 3 and ds.transform.c == x0 and ds.transform.f == y1
        assert ds.width == round((x1 - x0) / 3)


def test_errors(runner, cli, tmp_path):
    image = _image(tmp_path / "scene.tif", (20, 20))
    result = runner.invoke(cli, ["ortho", image, str(tmp_path / "o.tif"), "--dem", "const:0"])
    assert result.exit_code == 1 and "Error:" in result.output
    result = runner.invoke(cli, ["ortho", image, str(tmp_path / "o.tif")])
    assert result.exit_code == 2
    assert not (tmp_path / "o.tif").exists()


# ---------------------------------------------------------------------- issue 12, items 2 and 6
def _scene(tmp_path):
    """(image, model JSON) of a 60 x 80 AffineCamera scene near Nice (2 m GSD)."""
    model = AffineCamera.example((60, 80))
    model_path = str(geoblock.write_model(model, tmp_path / "model.json"))
    return _image(tmp_path / "scene.tif", (60, 80)), model_path


def _dem(path, west, north, value, nodata=-32768.0):
    """A 20 x 20 float32 ellipsoidal DEM, 0.001 degree posts."""
    from affine import Affine

    with rasterio.open(path, "w", driver="GTiff", width=20, height=20, count=1,
                       dtype="float32", crs="EPSG:4979",
                       transform=Affine(0.001, 0.0, west, 0.0, -0.001, north),
                       nodata=nodata) as ds:
        ds.write(np.full((1, 20, 20), value, np.float32))
    return str(path)


@pytest.mark.parametrize(("args", "option"), [
    (["--res", "0"], "--res"),
    (["--res=-2"], "--res"),
    (["--res", "nan"], "--res"),
    (["--chunks", "0"], "--chunks"),
    (["--bounds", "1", "1", "0", "0"], "--bounds"),
    (["--bounds", "0", "0", "inf", "1"], "--bounds"),
    (["--crs", "garbage"], "--crs"),
    (["--tolerance", "-1"], "--tolerance"),
    (["--max-pixels", "0"], "--max-pixels"),
])
def test_bad_options_are_usage_errors(runner, cli, tmp_path, args, option):
    """Item 6: one usage error naming the option, no ValueError/CRSError, nothing written."""
    image, model_path = _scene(tmp_path)
    out = tmp_path / "o.tif"
    result = runner.invoke(cli, ["ortho", image, str(out), "--dem", "const:150",
                                 "--model", model_path, "--no-progress", *args])
    assert result.exit_code == 2, result.output
    errors = [line for line in result.output.splitlines() if line.startswith("Error:")]
    assert len(errors) == 1 and option in errors[0], result.output
    assert "Traceback" not in result.output and "ValueError" not in result.output
    assert not out.exists()


@pytest.mark.parametrize(("args", "words"), [
    (["--crs", "EPSG:4326", "--res", "1000"], ["--res 1000", "degree", "1 x 1"]),
    (["--res", "1e-6"], ["--res 1e-06", "pixels", "--max-pixels"]),  # ~10^16 pixels
    (["--res", "1000"], ["--res 1000", "1 x 1 pixels", "2 x 2"]),
    (["--max-pixels", "1000"], ["--res 2 ", "62 x 82 pixels", "--max-pixels = 1000"]),
    (["--crs", "EPSG:32632", "--res", "0.001", "--bounds", "0", "0", "3e6", "10"],
     ["--res 0.001", "10000 x 3000000000", "2**31 - 1"]),
])
def test_impossible_grids_refused_up_front(runner, cli, tmp_path, args, words):
    """Item 2: a grid no one means is refused before any work, with the size it would have."""
    image, model_path = _scene(tmp_path)
    out = tmp_path / "o.tif"
    result = runner.invoke(cli, ["ortho", image, str(out), "--dem", "const:150",
                                 "--model", model_path, "--no-progress", *args])
    assert result.exit_code == 1, result.output
    errors = [line for line in result.output.splitlines() if line.startswith("Error:")]
    assert len(errors) == 1, result.output
    for word in words:
        assert word in errors[0], errors[0]
    assert "--verbose" not in errors[0]  # a GeoblockError (GridError), not a stray exception
    assert sorted(p.name for p in tmp_path.iterdir()) == ["model.json", "scene.tif"]


@pytest.mark.parametrize(("case", "reason"), [
    ("dem_elsewhere", "DEM has no valid height"),
    ("dem_all_nodata", "DEM has no valid height"),
    ("bounds_miss", "do not overlap the image footprint"),
])
def test_empty_ortho_fails_unless_allowed(runner, cli, tmp_path, case, reason):
    """Item 2: no valid pixel is an error (nothing under OUT), or a warning with --allow-empty."""
    image, model_path = _scene(tmp_path)
    if case == "dem_elsewhere":
        args = ["--dem", _dem(tmp_path / "dem.tif", 10.0, 40.0, 100.0)]
    elif case == "dem_all_nodata":  # covers the scene (7.05 E, 43.70 N), every post a void
        args = ["--dem", _dem(tmp_path / "dem.tif", 7.04, 43.71, -32768.0)]
    else:
        args = ["--dem", "const:150", "--bounds", "0", "0", "1000", "1000"]
    out = tmp_path / "o.tif"
    base = ["ortho", image, str(out), "--model", model_path, "--no-progress", *args]
    result = runner.invoke(cli, base)
    assert result.exit_code == 1, result.output
    errors = [line for line in result.output.splitlines() if line.startswith("Error:")]
    assert len(errors) == 1 and "no valid pixel" in errors[0] and reason in errors[0], errors
    assert "--allow-empty" in errors[0]
    assert not out.exists()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temporaries

    result = runner.invoke(cli, base + ["--allow-empty"])
    assert result.exit_code == 0, result.output
    assert "Warning:" in result.output and "no valid pixel" in result.output
    with rasterio.open(out) as ds:
        assert ds.nodata == 0 and not ds.read().any()


def test_dem_partly_covering_is_not_empty(runner, cli, tmp_path):
    """A DEM with some heights over the scene gives a (partial) ortho, exit 0, no warning."""
    image, model_path = _scene(tmp_path)
    dem = _dem(tmp_path / "dem.tif", 7.0505, 43.71, 150.0)  # the eastern part of the scene
    out = tmp_path / "o.tif"
    result = runner.invoke(cli, ["ortho", image, str(out), "--model", model_path, "--dem", dem,
                                 "--no-progress"])
    assert result.exit_code == 0, result.output
    assert "Warning" not in result.output
    with rasterio.open(out) as ds:
        data = ds.read(1)
    assert data.any() and not data.all()
