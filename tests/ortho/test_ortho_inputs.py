"""orthorectify and mosaic take the source image as a path, an open rasterio dataset, an
xarray.DataArray or a numpy array (and the DEM as anything open_dem opens): the same values,
and the same file bytes, as the path route. Anything else is an InputTypeError naming it."""

from __future__ import annotations

import contextlib
import hashlib
import pickle
import warnings
from pathlib import Path

import numpy as np
import pytest
import rasterio
import xarray as xr
from affine import Affine
from dask.base import tokenize
from rasterio.io import MemoryFile

from geoblock.dem import GridDem
from geoblock.errors import GeoblockError, InputTypeError
from geoblock.io import open_image, open_quietly, write_ortho
from geoblock.io.images import ArrayImage, ImageSource
from geoblock.ortho import OutputGrid, mosaic, orthorectify
from geoblock.testing.synthetic import ConstantVelocityPushbroom

ROWS, COLS = 160, 200


def _write(path: Path, data: np.ndarray, nodata=None, transform=None) -> str:
    with warnings.catch_warnings():  # a raw image has no geotransform
        warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
        with rasterio.open(path, "w", driver="GTiff", width=data.shape[2], height=data.shape[1],
                           count=data.shape[0], dtype=data.dtype, nodata=nodata,
                           transform=transform) as ds:
            ds.write(data)
    return str(path)


@contextlib.contextmanager
def _quiet():
    """rasterio's warning for a raw image (no geotransform: expected) silenced."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
        yield


def _digest(array) -> str:
    return hashlib.sha256(np.ascontiguousarray(array).tobytes()).hexdigest()


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    """(image path, pixels, pushbroom model, DEM file, GridDem of it, output grid)."""
    tmp = tmp_path_factory.mktemp("inputs")
    rng = np.random.default_rng(3)
    data = (rng.random((2, ROWS, COLS)) * 60000).astype(np.uint16)
    data[:, 40:60, 50:90] = 7  # a nodata hole
    path = _write(tmp / "scene.tif", data, nodata=7)
    model = ConstantVelocityPushbroom.example((ROWS, COLS))
    heights = rng.uniform(100.0, 900.0, (30, 30))
    transform = Affine(0.004, 0.0, 6.99, 0.0, -0.004, 43.76)
    dem = GridDem(heights, transform, "EPSG:4326")
    dem_path = tmp / "dem.tif"
    with rasterio.open(dem_path, "w", driver="GTiff", width=30, height=30, count=1,
                       dtype="float64", crs="EPSG:4979", transform=transform) as ds:
        ds.write(heights, 1)
    grid = OutputGrid.for_model(model, dem)
    return path, data, model, dem_path, dem, grid


def _values(image, scene, **kw):
    _, _, model, _, dem, grid = scene
    return orthorectify(image, model, dem, grid, chunks=64, **kw).compute(
        scheduler="threads").values


def test_every_image_form_gives_the_paths_values(scene):
    path, data, *_ = scene
    expected = _values(path, scene)
    assert (expected == 7).any() and (expected != 7).any()  # nodata kept, pixels found
    with open_quietly(path) as ds:
        assert open_image(ds) == open_image(path)  # a file dataset: by its name
        assert _digest(_values(ds, scene)) == _digest(expected)
    with open(path, "rb") as f, MemoryFile(f.read()) as mem, _quiet(), mem.open() as ds:
        image = open_image(ds)
        assert isinstance(image, ArrayImage) and image.nodata == 7.0
        assert _digest(_values(ds, scene)) == _digest(expected)
    assert _digest(_values(open_image(data, nodata=7), scene)) == _digest(expected)
    assert _digest(_values(data, scene, nodata=7)) == _digest(
        _values(open_image(data), scene, nodata=7))
    stated = xr.DataArray(data, dims=("band", "y", "x"), attrs={"_FillValue": 7})
    assert _digest(_values(stated, scene)) == _digest(expected)
    assert _digest(_values(stated.chunk(50), scene)) == _digest(expected)  # computed once
    one_band = _values(open_image(xr.DataArray(data[0], dims=("y", "x")), nodata=7), scene)
    assert _digest(one_band) == _digest(expected[:1])


def test_array_source_writes_the_same_bytes(scene, tmp_path):
    path, data, model, _, dem, grid = scene
    files = []
    for name, image in (("path", path), ("array", open_image(data, nodata=7))):
        out = orthorectify(image, model, dem, grid, chunks=100, kernel="bicubic")
        files.append(write_ortho(out, tmp_path / f"{name}.tif", blocksize=64,
                                 scheduler="threads").read_bytes())
    assert files[0] == files[1]


def test_dem_given_as_a_path_or_dataset(scene):
    path, _, model, dem_path, _, grid = scene
    from geoblock import open_dem

    expected = orthorectify(path, model, open_dem(dem_path), grid, chunks=64).compute().values
    got = orthorectify(path, model, dem_path, grid, chunks=64).compute().values
    assert _digest(got) == _digest(expected)
    with rasterio.open(dem_path) as ds:
        got = orthorectify(path, model, ds, grid, chunks=64).compute().values
    assert _digest(got) == _digest(expected)


def test_array_image_pickles_and_tokenizes_by_value(scene):
    _, data, *_ = scene
    image = open_image(data, nodata=7)
    again = pickle.loads(pickle.dumps(image))
    assert np.array_equal(again.read(), data) and again.nodata == 7.0
    assert tokenize(again) == tokenize(image)
    assert tokenize(open_image(data + 1, nodata=7)) != tokenize(image)
    assert not image.array.flags.writeable
    assert np.array_equal(image.read((10, 20, 30, 45)), data[:, 10:20, 30:45])


def test_array_source_on_a_distributed_cluster(scene):
    """The in-memory image travels to worker processes with the tasks: same values."""
    distributed = pytest.importorskip("distributed")
    _, data, model, _, dem, grid = scene
    out = orthorectify(open_image(data, nodata=7), model, dem, grid, chunks=100)
    expected = _digest(out.compute(scheduler="threads").values)
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        assert _digest(out.compute(scheduler=client).values) == expected


def test_array_with_a_pixel_unit_transform_is_a_crop(scene):
    """As for a file: a pixel-unit geotransform states where the crop lies in the scene."""
    path, data, model, _, dem, grid = scene
    crop = data[:, 30:130, 40:180]
    stated = open_image(crop, nodata=7, transform=Affine(1.0, 0.0, 40.0, 0.0, 1.0, 30.0))
    assert stated.crop_offset == (30.0, 40.0)
    got = orthorectify(stated, model, dem, grid, chunks=64).compute().values
    given = orthorectify(open_image(crop, nodata=7), model, dem, grid, chunks=64,
                         crop_offset=(30, 40)).compute().values
    assert _digest(got) == _digest(given)
    assert (got != 7).any()


def test_mosaic_of_array_pairs(scene):
    path, data, model, dem_path, dem, grid = scene
    from_paths = mosaic([(path, model)], grid, dem=dem_path, chunks=64).compute()
    from_arrays = mosaic([(open_image(data, nodata=7), model)], grid, dem=dem_path,
                         chunks=64).compute()
    assert _digest(from_arrays.mosaic.values) == _digest(from_paths.mosaic.values)


def test_what_cannot_be_an_image_is_named(scene):
    path, data, model, _, dem, grid = scene
    with pytest.raises(InputTypeError, match=r"cannot use an object of type dict as an image; "
                                             r"accepted: a path") as info:
        orthorectify({"pixels": data}, model, dem, grid)
    assert isinstance(info.value, TypeError) and isinstance(info.value, GeoblockError)
    with pytest.raises(InputTypeError, match="describe an in-memory array"):
        open_image(path, nodata=0)
    with pytest.raises(InputTypeError, match=r"\(R, C\) or \(bands, R, C\)"):
        open_image(np.zeros((1, 2, 3, 4)))
    with pytest.raises(InputTypeError, match="as a DEM"):
        orthorectify(path, model, object(), grid)
    with open_quietly(path) as ds:
        pass
    with pytest.raises(InputTypeError, match="closed"):
        open_image(ds)
    assert isinstance(open_image(path), ImageSource)


def test_dataarray_images_band_last_pixel_index_coords_and_crs_codes():
    """(y, x, band) dims are reordered, pixel-index coordinates of a raw image are not a crop
    offset, and a CRS given as a code is read (not a rasterio traceback)."""
    import xarray as xr

    from geoblock.io import open_image

    pixels = np.arange(100 * 80 * 3, dtype=np.uint16).reshape(100, 80, 3)
    raw = xr.DataArray(pixels, dims=("y", "x", "band"),
                       coords={"y": np.arange(100), "x": np.arange(80)})
    image = open_image(raw)
    assert image.array.shape == (3, 100, 80)
    np.testing.assert_array_equal(image.array[1], pixels[:, :, 1])
    assert image.crop_offset is None
    crop = raw.assign_coords(y=np.arange(100) + 5000.5, x=np.arange(80) + 7000.5)
    assert open_image(crop).crop_offset == (5000.0, 7000.0)  # a pixel-unit window
    mapped = raw.assign_coords(y=4.8e6 - 10 * np.arange(100), x=5e5 + 10 * np.arange(80))
    mapped.attrs["crs"] = "EPSG:32631"
    assert open_image(mapped).crs.to_epsg() == 32631
