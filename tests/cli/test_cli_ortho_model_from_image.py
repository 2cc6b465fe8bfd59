"""``geoblock ortho IMAGE OUT --dem ...`` with no ``--model``: the RPC read from IMAGE's tags.

A 120 x 100 window of the shareloc Ventoux crop (same origin, so the crop's RPC applies as is)
is written as a GeoTIFF carrying the RPC in its GDAL RPC tags; the CLI output must be the
same, byte for byte, as with ``--model`` pointing at the model JSON, and as the Python API.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import rasterio
from rasterio.errors import NotGeoreferencedWarning

import geoblock
from geoblock.ortho import OutputGrid, orthorectify

UTM = "EPSG:32631"


@pytest.fixture
def rpc_image(data_dir, tmp_path):
    shareloc = data_dir / "shareloc"
    crop = shareloc / "image/phr_ventoux/left_image.tif"
    model = geoblock.open_model(shareloc / "rpc/phr_ventoux/left_image.geom", image=crop,
                                crop_from_geotransform=True)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NotGeoreferencedWarning)
        with rasterio.open(crop) as ds:
            pixels = ds.read(1)[:120, :100]
        path = tmp_path / "scene.tif"
        with rasterio.open(path, "w", driver="GTiff", width=100, height=120, count=1,
                           dtype=pixels.dtype) as ds:
            ds.write(pixels, 1)
    geoblock.write_model(model, path, format="gtiff")
    return str(path), model


def test_ortho_reads_the_model_from_the_image(runner, cli, tmp_path, rpc_image):
    image, crop_model = rpc_image
    model = geoblock.open_model(image)  # what the CLI reads: the RPC tags, the raster's shape
    assert model.shape == (120, 100)
    assert model.rpc.line_off == pytest.approx(crop_model.rpc.line_off)
    assert model.rpc.samp_off == pytest.approx(crop_model.rpc.samp_off)
    dem = geoblock.open_dem("const:600")
    x0, y0, x1, y1 = OutputGrid.for_model(model, dem, crs=UTM, resolution=1.0).bounds
    grid_args = ["--crs", UTM, "--res", "1", "--bounds", repr(x0), repr(y0), repr(x1), repr(y1)]

    out = tmp_path / "ortho.tif"
    result = runner.invoke(cli, ["ortho", image, str(out), "--dem", "const:600", *grid_args,
                                 "--no-progress", "--chunks", "32"])
    assert result.exit_code == 0, result.output
    with rasterio.open(out) as ds:
        assert ds.crs.to_epsg() == 32631 and ds.res == (1.0, 1.0)
        assert ds.dtypes[0] == "uint16"
        ours = ds.read()
    assert np.count_nonzero(ours) > 0.5 * ours.size

    # the same as with --model (the model JSON) ...
    json_path = str(geoblock.write_model(model, tmp_path / "model.json"))
    out_model = tmp_path / "ortho_model.tif"
    result = runner.invoke(cli, ["ortho", image, str(out_model), "--dem", "const:600",
                                 *grid_args, "--model", json_path, "--no-progress"])
    assert result.exit_code == 0, result.output
    with rasterio.open(out_model) as ds:
        np.testing.assert_array_equal(ds.read(), ours)

    # ... and as the Python API on gdalwarp's -te/-tr grid
    grid = OutputGrid.from_bounds(UTM, (x0, y0, x1, y1), 1.0)
    expected = orthorectify(image, model, dem, grid, kernel="bilinear", tolerance_px=0.01).values
    np.testing.assert_array_equal(expected, ours)
