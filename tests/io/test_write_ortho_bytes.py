"""write_ortho: the same pixels give the same file bytes, whatever the chunking, the scheduler
and the order in which chunks finish (issue 12 item 9).

GDAL appends each compressed tile to a tiled GeoTIFF when it is complete, so a writer that
writes chunks as they finish puts the tiles in completion order: with chunks a multiple of the
512 tile (the default 1024), the bytes changed from run to run and between chunk sizes.
"""

from __future__ import annotations

import hashlib
import time
import warnings
from pathlib import Path

import dask.array as da
import numpy as np
import pytest
import rasterio
import xarray as xr
from affine import Affine

from geoblock.dem import GridDem
from geoblock.io import write_ortho
from geoblock.ortho import OutputGrid, orthorectify
from geoblock.testing.synthetic import ConstantVelocityPushbroom

ROWS, COLS = 240, 300


def _sha(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    """(image path, model, DEM, output grid of 1977 x 2444: 4 x 5 tiles of 512, edge tiles
    partial in both directions)."""
    tmp = tmp_path_factory.mktemp("bytes")
    rng = np.random.default_rng(0)
    data = (rng.random((2, ROWS, COLS)) * 60000).astype(np.uint16)
    path = tmp / "scene.tif"
    with warnings.catch_warnings():  # a raw image has no geotransform
        warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
        with rasterio.open(path, "w", driver="GTiff", width=COLS, height=ROWS, count=2,
                           dtype="uint16") as ds:
            ds.write(data)
    model = ConstantVelocityPushbroom.example((ROWS, COLS))
    dem = GridDem(rng.uniform(100.0, 900.0, (30, 30)),
                  Affine(0.004, 0.0, 6.99, 0.0, -0.004, 43.76), "EPSG:4326")
    coarse = OutputGrid.for_model(model, dem)
    grid = OutputGrid.for_model(model, dem, resolution=coarse.resolution[0] / 8)
    assert grid.shape[0] > 3 * 512 and grid.shape[1] > 4 * 512
    return str(path), model, dem, grid


def _write(scene, out: Path, chunks: int, **kwargs) -> str:
    path, model, dem, grid = scene
    write_ortho(orthorectify(path, model, dem, grid, chunks=chunks), out, **kwargs)
    return _sha(out)


def test_same_bytes_for_every_chunk_size(scene, tmp_path):
    digests = {size: _write(scene, tmp_path / f"c{size}.tif", size, scheduler="threads")
               for size in (512, 1024, 1536, 700)}
    assert len(set(digests.values())) == 1, digests
    again = _write(scene, tmp_path / "again.tif", 1024, scheduler="threads")
    assert again == digests[1024]


def test_same_bytes_for_every_scheduler(scene, tmp_path):
    distributed = pytest.importorskip("distributed")
    expected = _write(scene, tmp_path / "threads.tif", 1024, scheduler="threads")
    assert _write(scene, tmp_path / "sync.tif", 512, scheduler="synchronous") == expected
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        got = {size: _write(scene, tmp_path / f"dist{size}.tif", size, scheduler=client)
               for size in (512, 1024)}
    assert got == {512: expected, 1024: expected}


def test_same_cog_bytes_for_every_chunk_size(scene, tmp_path):
    digests = {size: _write(scene, tmp_path / f"c{size}.tif", size, scheduler="threads",
                            driver="COG") for size in (512, 1024)}
    assert len(set(digests.values())) == 1, digests


def _late_first(block: np.ndarray, block_info=None) -> np.ndarray:
    """The identity, slowest for the first chunks: they finish last."""
    (r0, _), (c0, _) = block_info[0]["array-location"][1:]
    time.sleep(max(0.0, 0.08 - 0.004 * (r0 // 256 * 8 + c0 // 256)))
    return block


def _lazy(values: np.ndarray, chunks: int) -> xr.DataArray:
    array = da.from_array(values, chunks=(-1, chunks, chunks)).map_blocks(
        _late_first, dtype=values.dtype)
    out = xr.DataArray(array, dims=("band", "y", "x"))
    ref = xr.DataArray(0, attrs={"crs_wkt": rasterio.crs.CRS.from_epsg(32632).to_wkt(),
                                 "GeoTransform": "500000 1 0 4800000 0 -1"})
    return out.assign_coords(spatial_ref=ref)


@pytest.mark.parametrize("dtype", ["uint8", "float32"])
def test_completion_order_does_not_reach_the_file(tmp_path, dtype):
    """Chunks that finish in reverse order, several chunk sizes and tile sizes: one file."""
    rng = np.random.default_rng(1)
    values = (rng.random((3, 1100, 1300)) * 200).astype(dtype)
    digests = {}
    for chunks in (256, 512, 768, 300):
        for blocksize in (256, 512):
            out = tmp_path / f"{chunks}_{blocksize}.tif"
            write_ortho(_lazy(values, chunks), out, scheduler="threads", in_flight=8,
                        blocksize=blocksize)
            digests.setdefault(blocksize, set()).add(_sha(out))
            with rasterio.open(out) as ds:
                np.testing.assert_array_equal(ds.read(), values)
    assert all(len(d) == 1 for d in digests.values()), digests


def test_tiles_in_row_major_file_order(scene, tmp_path):
    out = tmp_path / "o.tif"
    _write(scene, out, 1024, scheduler="threads")
    with rasterio.open(out) as ds:
        ny, nx = (-(-n // 512) for n in ds.shape)
        offsets = [int(ds.get_tag_item(f"BLOCK_OFFSET_{j}_{i}", "TIFF", bidx=1))
                   for i in range(ny) for j in range(nx)]
        assert ds.tags() == {"AREA_OR_POINT": "Area"}  # no date or other run-dependent tag
    assert offsets == sorted(offsets)
