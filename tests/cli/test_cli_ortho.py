"""``geoblock ortho``: help, a smoke run, gdalwarp-style grids, errors."""

from __future__ import annotations

import warnings

import numpy as np
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
