"""Crops of a scene (issue 12, item 1): CroppedModel, ImageSource.crop_offset, model_for_image.

A crop's pixel (r, c) is its scene's pixel (r + row0, c + col0), for any model; an image whose
shape differs from its model's with no crop offset is refused, never placed silently.
"""

from __future__ import annotations

import pickle
import warnings

import numpy as np
import pytest
import rasterio
from affine import Affine
from dask.base import tokenize
from rasterio.errors import NotGeoreferencedWarning

import geoblock
from geoblock.errors import GeoblockError, SerializationError
from geoblock.io.images import ImageSource, open_image, pixel_crop_offset
from geoblock.models import get_registry
from geoblock.models.crop import CropError, CroppedModel, model_for_image
from geoblock.testing.synthetic import AffineCamera, ConstantVelocityPushbroom

SCENE = (1000, 1200)


@pytest.fixture(params=["affine", "pushbroom"])
def scene(request):
    """A scene model of each direction (ground->image kernel, image->ground kernel)."""
    if request.param == "affine":
        return AffineCamera.example(SCENE)
    return ConstantVelocityPushbroom.example(SCENE, roll=0.01)


def _raster(path, shape=(30, 40), transform=None, crs=None):
    profile = {"driver": "GTiff", "width": shape[1], "height": shape[0], "count": 1,
               "dtype": "uint8"}
    if transform is not None:
        profile["transform"] = transform
    if crs is not None:
        profile["crs"] = crs
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NotGeoreferencedWarning)
        with rasterio.open(path, "w", **profile) as ds:
            ds.write(np.ones((1,) + shape, np.uint8))
    return str(path)


def _source(shape, crop_offset=None):
    return ImageSource("crop.tif", shape, 1, "uint8", None, crop_offset)


# ---------------------------------------------------------------------- CroppedModel
def test_crop_is_the_scene_shifted(scene):
    crop = CroppedModel(scene, (100.0, 200.5), (300, 400))
    assert crop.shape == (300, 400) and crop.height_range == scene.height_range
    rows, cols = np.meshgrid(np.linspace(-0.5, 299.5, 7), np.linspace(-0.5, 399.5, 9))
    h = np.linspace(-100.0, 900.0, rows.size).reshape(rows.shape)
    ground = scene.backproject(rows + 100.0, cols + 200.5, h)
    assert np.allclose(np.stack(crop.backproject(rows, cols, h)), np.stack(ground),
                       rtol=0, atol=1e-12)
    r, c = crop.project(*ground)
    assert np.abs(r - rows).max() < 1e-6 and np.abs(c - cols).max() < 1e-6
    (_, _), status = crop.project_with_status(np.nan, 43.7, 0.0)
    assert status != 0  # the wrapped model's status, NaN isolated
    assert np.array_equal(crop.partials_ground(*ground), scene.partials_ground(*ground))
    assert crop.parameters == scene.parameters


def test_crop_of_a_crop_is_one_crop(scene):
    inner = CroppedModel(scene, (100, 200), (500, 600))
    outer = CroppedModel(inner, (10, 20), (50, 60))
    assert outer.model is scene and outer.offset == (110.0, 220.0) and outer.shape == (50, 60)


def test_crop_serialises_through_the_registry(tmp_path, scene):
    crop = CroppedModel(scene, (100, 200), (300, 400))
    assert get_registry().get("crop") is CroppedModel
    path = geoblock.write_model(crop, tmp_path / "crop.json")
    again = geoblock.open_model(path)
    assert again == crop and again.offset == (100.0, 200.0) and again.model == scene
    assert pickle.loads(pickle.dumps(crop)) == crop
    assert tokenize(crop) != tokenize(CroppedModel(scene, (100, 201), (300, 400)))
    moved = crop.with_parameters(scene.parameters.values * 1.0)
    assert isinstance(moved, CroppedModel) and moved.offset == crop.offset


@pytest.mark.parametrize(("offset", "shape"), [
    ((np.nan, 0), (10, 10)), ((0, np.inf), (10, 10)), ((0,), (10, 10)), ((0, 0), (0, 10)),
    ((0, 0), (10.5, 10)), ((0, 0), "ab"),
])
def test_crop_refuses_bad_values(scene, offset, shape):
    with pytest.raises(CropError) as info:
        CroppedModel(scene, offset, shape)
    assert isinstance(info.value, GeoblockError | ValueError)
    data = CroppedModel(scene, (1, 2), (3, 4)).to_dict()
    data["offset"] = [float("nan"), 0.0]
    with pytest.raises(SerializationError, match="crop"):
        CroppedModel.from_dict(data)


# ---------------------------------------------------------------------- open_image
def test_pixel_crop_offset():
    assert pixel_crop_offset(Affine(1, 0, 5000, 0, 1, 4000)) == (4000.0, 5000.0)
    assert pixel_crop_offset(Affine.identity()) is None  # GDAL's default: says nothing
    assert pixel_crop_offset(Affine(0.5, 0, 5000, 0, -0.5, 4000)) is None  # a map grid
    assert pixel_crop_offset(Affine(1, 0, 0.5, 0, -1, -0.5)) is None  # flipped: no crop
    assert pixel_crop_offset(Affine(1, 0, 10, 0, 1, 20), rasterio.CRS.from_epsg(32631)) is None


def test_open_image_reads_the_crop_offset(tmp_path):
    crop = open_image(_raster(tmp_path / "crop.tif", transform=Affine(1, 0, 5000, 0, 1, 4000)))
    assert crop.crop_offset == (4000.0, 5000.0) and crop.shape == (30, 40)
    assert open_image(_raster(tmp_path / "raw.tif")).crop_offset is None
    mapped = _raster(tmp_path / "map.tif", transform=Affine(1, 0, 5000, 0, 1, 4000),
                     crs="EPSG:32631")
    assert open_image(mapped).crop_offset is None
    # the offset is part of the dask token (a different crop is a different source)
    assert tokenize(crop) != tokenize(ImageSource(crop.path, crop.shape, 1, "uint8", None))


# ---------------------------------------------------------------------- model_for_image
def test_same_shape_no_offset_is_the_model(scene):
    assert model_for_image(scene, _source(SCENE)) is scene


def test_shape_mismatch_without_offset_is_refused(scene):
    with pytest.raises(CropError) as info:
        model_for_image(scene, _source((30, 40)))
    message = str(info.value)
    for words in ("crop.tif", "30 x 40", "1000 x 1200", "crop_offset=", "crop=False"):
        assert words in message, message
    with pytest.raises(CropError, match="--crop-offset ROW COL.*--no-crop"):
        model_for_image(scene, _source((30, 40)),
                        names={"crop_offset": "--crop-offset ROW COL", "no_crop": "--no-crop"})


def test_stated_offset_crops_the_model(scene):
    model = model_for_image(scene, _source((30, 40), (100.0, 200.0)))
    assert isinstance(model, CroppedModel)
    assert model.model is scene and model.offset == (100.0, 200.0) and model.shape == (30, 40)


def test_stated_offset_with_the_crops_own_model_is_not_applied_twice(scene):
    own = CroppedModel(scene, (100, 200), (30, 40))  # e.g. crop_from_geotransform=True
    assert model_for_image(own, _source((30, 40), (100.0, 200.0))) is own


def test_explicit_offset_wins_and_crop_false_opts_out(scene):
    model = model_for_image(scene, _source((30, 40), (100.0, 200.0)), crop_offset=(7, 8))
    assert model.offset == (7.0, 8.0)
    model = model_for_image(scene, _source((30, 40)), crop_offset=(7, 8))
    assert model.offset == (7.0, 8.0)
    assert model_for_image(scene, _source((30, 40), (100.0, 200.0)), crop=False) is scene
    assert model_for_image(scene, _source((30, 40)), crop=False) is scene


@pytest.mark.parametrize("offset", [(990.0, 0.0), (0.0, 1190.0), (-5.0, 0.0)])
def test_crop_outside_the_scene_is_refused(scene, offset):
    with pytest.raises(CropError, match="does not lie inside the model's 1000 x 1200 px scene"):
        model_for_image(scene, _source((30, 40), offset))
    with pytest.raises(CropError, match="does not lie inside"):
        model_for_image(scene, _source((30, 40)), crop_offset=offset)


def test_offset_given_to_the_crops_own_model_is_refused(scene):
    own = CroppedModel(scene, (100, 200), (30, 40))
    with pytest.raises(CropError, match="already describes the crop"):
        model_for_image(own, _source((30, 40)), crop_offset=(100, 200))


def test_orthorectify_places_a_crop_with_the_scene_model(tmp_path):
    """The Python API reconciles too: a crop raster with the full-scene model gives the same
    ortho as with the crop's own model; a mismatched raster without offset is refused."""
    scene = AffineCamera.example(SCENE)
    crop = _raster(tmp_path / "crop.tif", shape=(60, 80), transform=Affine(1, 0, 300, 0, 1, 200))
    with rasterio.open(crop, "r+") as ds:
        ds.write(np.arange(60 * 80, dtype=np.uint16).reshape(1, 60, 80).astype(np.uint8))
    own = CroppedModel(scene, (200.0, 300.0), (60, 80))
    a = geoblock.orthorectify(crop, scene, geoblock.open_dem("const:250")).compute()
    b = geoblock.orthorectify(crop, own, geoblock.open_dem("const:250")).compute()
    assert a.shape == b.shape and a.shape[1] < 200  # the crop's footprint, not the scene's
    np.testing.assert_array_equal(a.values, b.values)
    plain = _raster(tmp_path / "plain.tif", shape=(60, 80))
    with pytest.raises(CropError, match="60 x 80|60, 80"):
        geoblock.orthorectify(plain, scene, geoblock.open_dem("const:250"))


# ---------------------------------------------------------------------- review fixes
def test_crop_outside_its_scene_is_refused_on_construction_and_load(scene):
    with pytest.raises(CropError, match="does not lie inside the model's 1000 x 1200 px scene"):
        CroppedModel(scene, (1e300, 0), (3, 4))
    with pytest.raises(CropError, match="does not lie inside"):
        CroppedModel(CroppedModel(scene, (100, 200), (50, 60)), (10, 20), (50, 60))
    data = CroppedModel(scene, (1, 2), (3, 4)).to_dict()
    data["offset"] = [1e300, 0.0]
    with pytest.raises(SerializationError, match="does not lie inside"):
        CroppedModel.from_dict(data)


@pytest.mark.parametrize("shape", [(v for v in (3.5, 4)), (True, True), (3, 4, 5), "34"])
def test_crop_shape_is_read_once_and_strictly(scene, shape):
    with pytest.raises(CropError, match="CroppedModel"):
        CroppedModel(scene, (0, 0), shape)
    assert CroppedModel(scene, (0, 0), (v for v in (3, 4))).shape == (3, 4)


def test_image_shape_helper():
    from geoblock.errors import ModelFormatError
    from geoblock.models import image_shape

    assert image_shape((v for v in ("2920.0", np.int64(4))), "f") == (2920, 4)
    for bad in [(v for v in (3.5, 4)), (True, 2), (np.bool_(True), 2), (0, 2), (2, np.nan),
                (10**7 + 1, 2), (1e300, 2), "ab", 12, (1,), (" ", 2)]:
        with pytest.raises(ModelFormatError, match="^somewhere: image"):
            image_shape(bad, "somewhere")
    assert image_shape((5, 6), "f", maximum=6) == (5, 6)
    with pytest.raises(ModelFormatError, match="cols 7"):
        image_shape((5, 7), "f", maximum=6)


def test_crop_has_one_delegation_path(scene):
    crop = CroppedModel(scene, (100.0, 200.5), (300, 400))
    assert "project_with_status" not in vars(CroppedModel)
    assert "backproject_with_status" not in vars(CroppedModel)
    rows = np.array([[0.0, np.nan], [10.0, 299.0]])
    cols = np.array([[0.0, 5.0], [np.inf, 399.0]])
    (lon, lat, h), status = crop.backproject_with_status(rows, cols, 100.0)
    (lon_s, lat_s, h_s), status_s = scene.backproject_with_status(rows + 100.0, cols + 200.5,
                                                                  100.0)
    np.testing.assert_array_equal(status, status_s)
    np.testing.assert_array_equal(np.stack([lon, lat, h]), np.stack([lon_s, lat_s, h_s]))
    (r, c), status = crop.project_with_status(lon, lat, h)
    (r_s, c_s), status_s = scene.project_with_status(lon, lat, h)
    np.testing.assert_array_equal(status, status_s)
    np.testing.assert_array_equal(np.stack([r, c]), np.stack([r_s - 100.0, c_s - 200.5]))
    assert crop.parameter_sets == tuple(scene.parameter_sets)


def test_crop_names_are_public():
    import geoblock.errors
    import geoblock.models

    assert geoblock.models.CroppedModel is CroppedModel
    assert geoblock.models.model_for_image is model_for_image
    assert geoblock.errors.CropError is CropError
