"""``geoblock ortho --no-crop``: the model is used as it is, whatever the image's shape or its
pixel-unit geotransform (the CLI reconciles the model once; ``orthorectify`` must not redo it
with the default ``crop=True``)."""

from __future__ import annotations

import warnings

import numpy as np
import pyproj
import pytest
import rasterio
from rasterio.errors import NotGeoreferencedWarning

import geoblock
from geoblock.testing.synthetic import AffineCamera

SCENE = (60, 80)
IMAGE = (40, 50)


def _coordinate_image(path, transform=None):
    """Two float64 bands holding each pixel's own (row, col), no CRS."""
    rows, cols = np.mgrid[0:IMAGE[0], 0:IMAGE[1]].astype(np.float64)
    profile = {"driver": "GTiff", "width": IMAGE[1], "height": IMAGE[0], "count": 2,
               "dtype": "float64"}
    if transform is not None:
        profile["transform"] = transform
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NotGeoreferencedWarning)
        with rasterio.open(path, "w", **profile) as ds:
            ds.write(np.stack([rows, cols]))
    return str(path)


@pytest.mark.parametrize("transform", [None, rasterio.Affine(1, 0, 20, 0, 1, 10)],
                         ids=["raw", "pixel-unit-geotransform"])
def test_no_crop_uses_the_model_unshifted(runner, cli, tmp_path, transform):
    model = AffineCamera.example(SCENE)
    model_path = str(geoblock.write_model(model, tmp_path / "model.json"))
    image = _coordinate_image(tmp_path / "image.tif", transform)
    out = tmp_path / "ortho.tif"
    result = runner.invoke(cli, ["ortho", image, str(out), "--dem", "const:150", "--model",
                                 model_path, "--no-crop", "--tolerance", "0", "--chunks", "16",
                                 "--no-progress", "--scheduler", "synchronous"])
    assert result.exit_code == 0, result.output
    assert "crop at" not in result.output and "Error" not in result.output
    with rasterio.open(out) as ds:
        sampled, t, crs = ds.read(), ds.transform, ds.crs
    rows, cols = sampled.shape[1:]
    x = t.c + t.a * (np.arange(cols) + 0.5)
    y = t.f + t.e * (np.arange(rows) + 0.5)
    xx, yy = np.meshgrid(x, y)
    lon, lat = pyproj.Transformer.from_crs(crs.to_wkt(), "EPSG:4326",
                                           always_xy=True).transform(xx, yy)
    row, col = model.project(lon, lat, np.full(lon.shape, 150.0))
    valid = np.isfinite(sampled).all(axis=0)
    inside = (row > 1) & (row < IMAGE[0] - 2) & (col > 1) & (col < IMAGE[1] - 2)
    assert inside.sum() > 100
    assert np.array_equal(valid & inside, inside)  # every pixel over the image was sampled
    # image pixel (r, c) is model pixel (r, c): no shift (bilinear reproduces it exactly)
    err = np.hypot(sampled[0] - row, sampled[1] - col)[valid]
    assert err.max() < 1e-6, err.max()


def test_without_no_crop_the_raw_image_is_still_refused(runner, cli, tmp_path):
    model_path = str(geoblock.write_model(AffineCamera.example(SCENE), tmp_path / "model.json"))
    image = _coordinate_image(tmp_path / "image.tif")
    out = tmp_path / "ortho.tif"
    result = runner.invoke(cli, ["ortho", image, str(out), "--dem", "const:150", "--model",
                                 model_path, "--no-progress", "--scheduler", "synchronous"])
    assert result.exit_code == 1, result.output
    assert "--no-crop" in result.output and "crop=False" not in result.output
    assert not out.exists()


def test_orthorectify_crop_arguments(tmp_path):
    """``orthorectify(crop=False)`` takes the model as it is; ``crop_offset=`` shifts it."""
    model = AffineCamera.example(SCENE)
    dem = geoblock.open_dem("const:150")
    image = _coordinate_image(tmp_path / "image.tif")
    grid = geoblock.ortho.OutputGrid.for_model(model, dem)
    with pytest.raises(geoblock.models.crop.CropError):
        geoblock.orthorectify(image, model, dem, grid)
    plain = geoblock.orthorectify(image, model, dem, grid, crop=False, tolerance_px=0)
    shifted = geoblock.orthorectify(image, model, dem, grid, crop_offset=(10.0, 20.0),
                                    tolerance_px=0)
    a = plain.compute(scheduler="synchronous").values
    b = shifted.compute(scheduler="synchronous").values
    both = np.isfinite(a).all(axis=0) & np.isfinite(b).all(axis=0)
    assert both.sum() > 50
    # the same ground point is model pixel p: crop pixel p in a, p - (10, 20) in b
    assert np.allclose(a[0][both] - b[0][both], 10.0, atol=1e-6)
    assert np.allclose(a[1][both] - b[1][both], 20.0, atol=1e-6)
