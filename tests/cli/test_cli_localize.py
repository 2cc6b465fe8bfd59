"""geoblock localize: CSV in, CSV out, statuses."""

from __future__ import annotations

import csv
import io

import numpy as np


def _read_csv(text: str) -> list[dict[str, str]]:
    return list(csv.DictReader(io.StringIO(text)))


def test_localize_on_constant_dem(runner, cli, model_path, affine, tmp_path):
    points = tmp_path / "image.csv"
    points.write_text("id,row,col,note\np1,10.5,20.25,a\np2,500,600,b\np3,nan,3,c\n")
    out = tmp_path / "ground.csv"
    result = runner.invoke(cli, ["localize", model_path, str(points), "--dem", "const:250",
                                 "-o", str(out)])
    assert result.exit_code == 0, result.output
    rows = _read_csv(out.read_text())
    assert list(rows[0]) == ["id", "row", "col", "note", "lon", "lat", "h", "status"]
    assert [r["status"] for r in rows] == ["converged", "converged", "invalid_input"]
    h = np.array([float(r["h"]) for r in rows[:2]])
    np.testing.assert_allclose(h, 250.0, atol=1e-3)
    (row, col), _ = affine.project_with_status(
        [float(r["lon"]) for r in rows[:2]], [float(r["lat"]) for r in rows[:2]], h
    )
    np.testing.assert_allclose(row, [10.5, 500.0], atol=1e-6)
    np.testing.assert_allclose(col, [20.25, 600.0], atol=1e-6)


def test_localize_stdin_ray_tracing_and_warning(runner, cli, model_path, tmp_path):
    import rasterio
    from affine import Affine

    dem = tmp_path / "dem.tif"
    with rasterio.open(dem, "w", driver="GTiff", width=10, height=10, count=1, dtype="float32",
                       crs="EPSG:4326", transform=Affine(1e-4, 0, 10.0, 0, -1e-4, 10.0)) as dst:
        dst.write(np.full((1, 10, 10), 100.0, "float32"))
    result = runner.invoke(
        cli, ["localize", model_path, "--dem", str(dem), "--vertical", "ellipsoid",
              "--method", "ray-tracing"],
        input="row,col\n1,2\n",
    )
    assert result.exit_code == 0, result.output
    rows = _read_csv(result.stdout)
    assert rows[0]["status"] == "no_dem" and rows[0]["lon"] == "nan"
    assert "Warning: localize with 'synthetic-affine': 1 of 1 points have no DEM height" in (
        result.stderr
    )


def test_localize_needs_dem(runner, cli, model_path):
    result = runner.invoke(cli, ["localize", model_path], input="row,col\n1,2\n")
    assert result.exit_code == 2 and "--dem" in result.output
