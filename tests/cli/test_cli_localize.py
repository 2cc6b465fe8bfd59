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
        cli, ["localize", model_path, "--dem", str(dem), "--dem-vertical", "ellipsoid",
              "--intersection", "ray-tracing"],
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


def test_localize_crop_offset_without_image(runner, cli, model_path, affine, tmp_path):
    """--crop-offset alone shifts the points into the scene; outside the scene it is refused;
    --no-crop needs --image."""
    points = tmp_path / "image.csv"
    points.write_text("row,col\n10.5,20.25\n")
    out = tmp_path / "ground.csv"
    args = ["localize", model_path, str(points), "--dem", "const:250", "-o", str(out),
            "--overwrite"]
    result = runner.invoke(cli, [*args, "--crop-offset", "100", "200"])
    assert result.exit_code == 0, result.output
    row = _read_csv(out.read_text())[0]
    (r, c), _ = affine.project_with_status(float(row["lon"]), float(row["lat"]), 250.0)
    np.testing.assert_allclose([r, c], [110.5, 220.25], atol=1e-6)
    rows, cols = affine.shape
    for offset in (["1e300", "0"], ["0", str(cols)], ["-5", "0"]):
        result = runner.invoke(cli, [*args, "--crop-offset", *offset])
        assert result.exit_code == 1, result.output
        assert "does not lie inside" in result.output and "--crop-offset" in result.output
        assert "Traceback" not in result.output
    result = runner.invoke(cli, [*args, "--no-crop"])
    assert result.exit_code == 2 and "--no-crop needs --image" in result.output, result.output
    result = runner.invoke(cli, [*args, "--no-crop", "--crop-offset", "1", "2"])
    assert result.exit_code == 2, result.output
