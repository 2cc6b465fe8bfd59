"""``geoblock mosaic``: help, priority and feather runs on GeoTIFF orthos, errors."""

from __future__ import annotations

import numpy as np
import rasterio
from affine import Affine


def _ortho(path, col0, row0, value, crs="EPSG:32631", shape=(20, 24)):
    data = np.full((1,) + shape, value, np.uint8)
    transform = Affine(10.0, 0.0, 500000.0 + 10 * col0, 0.0, -10.0, 4800000.0 - 10 * row0)
    with rasterio.open(path, "w", driver="GTiff", width=shape[1], height=shape[0], count=1,
                       dtype="uint8", crs=crs, transform=transform, nodata=0) as ds:
        ds.write(data)
    return str(path)


def test_help(runner, cli):
    result = runner.invoke(cli, ["mosaic", "--help"])
    assert result.exit_code == 0, result.output
    for option in ("--method", "--feather", "--contribution", "--nodata", "--chunks"):
        assert option in result.output
    assert "mosaic" in runner.invoke(cli, ["--help"]).output


def test_priority_with_contribution(runner, cli, tmp_path):
    a = _ortho(tmp_path / "a.tif", 0, 0, 100)
    b = _ortho(tmp_path / "b.tif", 10, 6, 200)
    out, contrib = tmp_path / "mosaic.tif", tmp_path / "contrib.tif"
    result = runner.invoke(cli, ["mosaic", str(out), a, b, "--contribution", str(contrib),
                                 "--chunks", "16", "--no-progress"])
    assert result.exit_code == 0, result.output
    with rasterio.open(out) as ds:
        assert (ds.height, ds.width) == (26, 34) and ds.nodata == 0
        assert ds.transform == Affine(10.0, 0.0, 500000.0, 0.0, -10.0, 4800000.0)
        assert ds.crs.to_epsg() == 32631
        values = ds.read(1)
    with rasterio.open(contrib) as ds:
        assert ds.dtypes[0] == "uint8" and ds.nodata == 0
        c = ds.read(1)
    assert values[10, 15] == 100 and c[10, 15] == 1  # overlap: the first ortho wins
    assert values[25, 33] == 200 and c[25, 33] == 2
    assert values[25, 0] == 0 and c[25, 0] == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "a.tif", "b.tif", "contrib.tif", "mosaic.tif"]


def test_feather(runner, cli, tmp_path):
    a = _ortho(tmp_path / "a.tif", 0, 0, 100)
    b = _ortho(tmp_path / "b.tif", 10, 0, 200)
    out = tmp_path / "mosaic.tif"
    result = runner.invoke(cli, ["mosaic", str(out), a, b, "--method", "feather",
                                 "--feather", "4", "--no-progress", "--scheduler", "synchronous"])
    assert result.exit_code == 0, result.output
    with rasterio.open(out) as ds:
        row = ds.read(1)[10]
    # columns 10..23 overlap; A's weight at col 20 is 4 (edge at 24), B's is 4 (edge at 9): mean
    assert row[20] == 150
    # col 10: A capped at 4, B at 1 -> (4 * 100 + 1 * 200) / 5 = 120
    assert row[10] == 120 and row[5] == 100 and row[30] == 200


def test_crs_mismatch(runner, cli, tmp_path):
    a = _ortho(tmp_path / "a.tif", 0, 0, 100)
    b = _ortho(tmp_path / "b.tif", 10, 6, 200, crs="EPSG:32632")
    out = tmp_path / "mosaic.tif"
    result = runner.invoke(cli, ["mosaic", str(out), a, b, "--no-progress"])
    assert result.exit_code == 1
    assert "Error:" in result.output and "CRS" in result.output
    assert not out.exists()


def test_chunks_zero_is_a_usage_error(runner, cli, tmp_path):
    a = _ortho(tmp_path / "a.tif", 0, 0, 100)
    result = runner.invoke(cli, ["mosaic", str(tmp_path / "m.tif"), a, "--chunks", "0"])
    assert result.exit_code == 2 and "--chunks" in result.output
    assert "ValueError" not in result.output


def _raw_image(path, shape, value):
    import warnings

    data = np.full((1,) + shape, value, np.uint8)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
        with rasterio.open(path, "w", driver="GTiff", width=shape[1], height=shape[0], count=1,
                           dtype="uint8") as ds:
            ds.write(data)
    return str(path)


def test_default_orthos_mosaic(runner, cli, tmp_path):
    """Item 10: 'geoblock ortho', 'geoblock ortho', 'geoblock mosaic' with default options.

    Two scenes of one 2 m camera, overlapping, 100 m apart: their exact GSDs differ in the
    last digits (UTM scale factor, Earth curvature), so orthos at the exact GSD cannot be
    mosaicked; the default grid (GSD rounded to a nice number, aligned to its multiples) can.
    """
    import geoblock
    from geoblock.testing.synthetic import AffineCamera

    shape = (60, 80)
    coefficients = [[(shape[0] - 1) / 2, 0.0, -0.5, 0.05], [(shape[1] - 1) / 2, 0.5, 0.0, -0.02]]
    orthos = []
    for name, lon, value in (("a", 7.0500, 100), ("b", 7.0513, 200)):
        model = AffineCamera(shape, (lon, 43.70, 100.0), coefficients, (-500.0, 3000.0))
        model_path = str(geoblock.write_model(model, tmp_path / f"{name}.json"))
        image = _raw_image(tmp_path / f"{name}.tif", shape, value)
        out = tmp_path / f"{name}_ortho.tif"
        result = runner.invoke(cli, ["ortho", image, str(out), "--dem", "const:150",
                                     "--model", model_path, "--no-progress"])
        assert result.exit_code == 0, result.output
        orthos.append(str(out))
    out = tmp_path / "mosaic.tif"
    result = runner.invoke(cli, ["mosaic", str(out), *orthos, "--no-progress"])
    assert result.exit_code == 0, result.output
    with rasterio.open(orthos[0]) as a, rasterio.open(orthos[1]) as b:
        assert a.transform.a == b.transform.a == 2.0  # the 2 m GSD, rounded
        assert a.transform.c % 2.0 == 0 and b.transform.f % 2.0 == 0  # aligned
    with rasterio.open(out) as ds:
        assert ds.transform.a == 2.0
        values = set(np.unique(ds.read(1)).tolist())
    assert {100, 200} <= values


def test_empty_mosaic_fails_unless_allowed(runner, cli, tmp_path):
    a = _ortho(tmp_path / "a.tif", 0, 0, 0)  # every pixel nodata (0)
    out = tmp_path / "mosaic.tif"
    result = runner.invoke(cli, ["mosaic", str(out), a, "--no-progress"])
    assert result.exit_code == 1 and "no valid pixel" in result.output
    assert not out.exists()
    result = runner.invoke(cli, ["mosaic", str(out), a, "--no-progress", "--allow-empty"])
    assert result.exit_code == 0 and "Warning:" in result.output and out.exists()
