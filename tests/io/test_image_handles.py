"""Source images read through one dataset per file and thread
(:func:`geoblock.io.rasters.cached_dataset`, shared with the DEM), and their georeferencing
read once by :func:`geoblock.io.images.open_image`."""

from __future__ import annotations

import os
import pickle
import threading
import time

import numpy as np
import pytest
import rasterio
from dask.base import tokenize

from geoblock.errors import GeoblockIOError
from geoblock.io.images import open_image, write_ortho
from geoblock.io.rasters import cached_dataset
from geoblock.ortho.mosaic import open_ortho


def _write(path, value, crs="EPSG:32631"):
    with rasterio.open(path, "w", driver="GTiff", width=40, height=30, count=1, dtype="uint8",
                       crs=crs, transform=rasterio.Affine(2, 0, 500000, 0, -2, 4800000)) as ds:
        ds.write(np.full((1, 30, 40), value, np.uint8))
    return str(path)


def test_one_handle_per_thread_reopened_when_the_file_changes(tmp_path):
    path = _write(tmp_path / "a.tif", 1)
    first = cached_dataset(path)
    assert cached_dataset(path) is first
    other = []
    thread = threading.Thread(target=lambda: other.append(cached_dataset(path)))
    thread.start()
    thread.join()
    assert other[0] is not first  # GDAL datasets are not shared between threads
    time.sleep(0.01)
    os.replace(_write(tmp_path / "b.tif", 7), path)
    again = cached_dataset(path)
    assert again is not first and first.closed
    assert int(again.read(1)[0, 0]) == 7


def test_reads_see_a_rewritten_file(tmp_path):
    path = _write(tmp_path / "a.tif", 1)
    image = open_image(path)
    assert int(image.read((0, 2, 0, 2)).max()) == 1
    time.sleep(0.01)
    os.replace(_write(tmp_path / "b.tif", 9), path)
    assert int(image.read((0, 2, 0, 2)).max()) == 9


def test_image_source_georeferencing_pickles_and_tokenizes(tmp_path):
    path = _write(tmp_path / "a.tif", 1)
    image = open_image(path)
    assert image.crs == rasterio.crs.CRS.from_epsg(32631)
    assert image.transform == rasterio.Affine(2, 0, 500000, 0, -2, 4800000)
    back = pickle.loads(pickle.dumps(image))
    assert back == image and hash(back) == hash(image)
    assert tokenize(back) == tokenize(image)
    assert open_ortho(path).shape == (1, 30, 40)


def test_open_ortho_of_a_source_made_by_hand(tmp_path):
    path = _write(tmp_path / "a.tif", 3)
    full = open_image(path)
    bare = type(full)(full.path, full.shape, full.bands, full.dtype, full.nodata)
    a, b = open_ortho(full, chunks=16), open_ortho(bare, chunks=16)
    assert a.spatial_ref.attrs == b.spatial_ref.attrs
    assert np.array_equal(a.compute(scheduler="synchronous"), b.compute(scheduler="synchronous"))


def test_an_input_read_error_is_not_reported_as_a_write_error(tmp_path):
    path = _write(tmp_path / "a.tif", 3)
    data = open_ortho(path, chunks=16)
    os.remove(path)
    out = tmp_path / "out.tif"
    with pytest.raises(GeoblockIOError, match="cannot read the image") as info:
        write_ortho(data, out, scheduler="synchronous")
    assert "cannot write" not in str(info.value)
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_write_ortho_missing_directory(tmp_path):
    data = open_ortho(_write(tmp_path / "a.tif", 3))
    with pytest.raises(GeoblockIOError, match="does not exist"):
        write_ortho(data, tmp_path / "no" / "out.tif")


def test_handles_per_thread_are_bounded(tmp_path, monkeypatch):
    import geoblock.io.rasters as r

    monkeypatch.setattr(r, "MAX_HANDLES_PER_THREAD", 3)
    paths = [_write(tmp_path / f"{i}.tif", i) for i in range(5)]
    opened = [cached_dataset(p) for p in paths]
    assert [ds.closed for ds in opened] == [True, True, False, False, False]
    assert cached_dataset(paths[2]) is opened[2]  # most recently used now
    cached_dataset(paths[0])
    assert opened[3].closed and not opened[2].closed
    assert int(cached_dataset(paths[1]).read(1)[0, 0]) == 1


def test_read_band_is_float_with_nan_where_nodata(tmp_path):
    from geoblock.io.images import open_image, read_band

    pixels = np.arange(12, dtype=np.uint16).reshape(3, 4)
    image = open_image(pixels, nodata=5)
    band = read_band(image)
    assert band.dtype == np.float64 and np.isnan(band[1, 1]) and np.isnan(band).sum() == 1
    assert band[0, 0] == 0.0 and band[2, 3] == 11.0
    window = read_band(image, (1, 3, 0, 2))
    assert window.shape == (2, 2) and np.isnan(window[0, 1])
    band[0, 0] = -1.0  # a copy: the image is untouched
    assert read_band(image)[0, 0] == 0.0
