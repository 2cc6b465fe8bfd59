"""ortho_job: the orthorectifier's chunks without dask (what ``geoblock ortho`` runs on local
threads), the same bytes as the dask graph; write_ortho's compression and creation options."""

from __future__ import annotations

import subprocess
import sys
import textwrap
import warnings
from pathlib import Path

import numpy as np
import pyproj
import pytest
import rasterio
from affine import Affine

from geoblock.dem import GridDem
from geoblock.io import write_ortho
from geoblock.ortho import OrthoJob, OutputGrid, ortho_job, orthorectify
from geoblock.testing.synthetic import ConstantVelocityPushbroom

ROWS, COLS = 240, 300


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    """(image path, pushbroom model, rough GridDem, output grid)."""
    tmp = tmp_path_factory.mktemp("job")
    rng = np.random.default_rng(3)
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
    grid = OutputGrid.for_model(model, dem)
    return str(path), model, dem, grid


def test_job_chunks_are_the_graph_tasks(scene):
    path, model, dem, grid = scene
    job = ortho_job(path, model, dem, grid, kernel="bicubic", chunks=100)
    assert isinstance(job, OrthoJob)
    assert job.shape == (2, *grid.shape) and job.dtype == np.uint16
    windows = job.windows()
    assert windows[0] == (0, 100, 0, 100) and len(windows) == len(job.row_chunks) * len(
        job.col_chunks)
    full = orthorectify(path, model, dem, grid, kernel="bicubic", chunks=100).compute(
        scheduler="synchronous").values
    for r0, r1, c0, c1 in (windows[0], windows[len(windows) // 2], windows[-1]):
        np.testing.assert_array_equal(job.chunk((r0, r1, c0, c1)), full[:, r0:r1, c0:c1])


@pytest.mark.parametrize("compress", [None, "zstd"])
def test_job_on_threads_writes_the_bytes_of_the_dask_graph(scene, tmp_path, compress):
    path, model, dem, grid = scene
    job = ortho_job(path, model, dem, grid, chunks=100)
    a = write_ortho(job, tmp_path / "job.tif", scheduler="threads", blocksize=64,
                    compress=compress)
    b = write_ortho(orthorectify(path, model, dem, grid, chunks=100), tmp_path / "dask.tif",
                    scheduler="synchronous", blocksize=64, compress=compress)
    c = write_ortho(job, tmp_path / "processes.tif", scheduler="processes", blocksize=64,
                    compress=compress)  # a job off local threads goes through its graph
    assert a.read_bytes() == b.read_bytes() == c.read_bytes()
    with rasterio.open(a) as ds:
        assert ds.transform == grid.transform and ds.nodata == 0
        assert pyproj.CRS.from_wkt(ds.crs.to_wkt()) == grid.crs


def test_job_path_imports_neither_dask_nor_xarray(scene, tmp_path):
    """The command-line path: a job written on local threads never imports dask, xarray or
    distributed (0.6 s, 0.3 s and 0.3 s of start-up)."""
    path, model, dem, grid = scene
    out = tmp_path / "o.tif"
    code = textwrap.dedent(f"""
        import sys
        from affine import Affine
        import numpy as np
        from geoblock.dem import GridDem
        from geoblock.io import write_ortho
        from geoblock.ortho import ortho_job, OutputGrid
        from geoblock.testing.synthetic import ConstantVelocityPushbroom
        model = ConstantVelocityPushbroom.example(({ROWS}, {COLS}))
        rng = np.random.default_rng(3)
        rng.random((2, {ROWS}, {COLS}))
        dem = GridDem(rng.uniform(100.0, 900.0, (30, 30)),
                      Affine(0.004, 0.0, 6.99, 0.0, -0.004, 43.76), "EPSG:4326")
        grid = OutputGrid.for_model(model, dem)
        write_ortho(ortho_job({path!r}, model, dem, grid, chunks=100), {str(out)!r})
        print(sorted(m for m in ("dask", "xarray", "distributed", "pandas") if m in sys.modules))
    """)
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=True)
    assert proc.stdout.strip().splitlines()[-1] == "[]"
    expected = write_ortho(orthorectify(path, model, dem, grid, chunks=100),
                           tmp_path / "ref.tif", scheduler="synchronous")
    assert out.read_bytes() == expected.read_bytes()


def _compression(path: Path) -> tuple[str | None, str | None]:
    with rasterio.open(path) as ds:
        tags = ds.tags(ns="IMAGE_STRUCTURE")
        return tags.get("COMPRESSION"), tags.get("PREDICTOR")


def test_default_compression_is_fast_zstd_and_options_win(scene, tmp_path):
    path, model, dem, grid = scene
    job = ortho_job(path, model, dem, grid, chunks=100)
    ref = job.chunk((0, grid.shape[0], 0, grid.shape[1]))
    cases = {
        "default.tif": ({}, ("ZSTD", None)),
        "none.tif": ({"compress": None}, (None, None)),
        "none2.tif": ({"compress": "none"}, (None, None)),
        "deflate.tif": ({"compress": "deflate", "level": 6}, ("DEFLATE", None)),
        "co.tif": ({"COMPRESS": "LZW", "predictor": 2}, ("LZW", "2")),
    }
    for name, (kwargs, expected) in cases.items():
        out = write_ortho(job, tmp_path / name, **kwargs)
        assert _compression(out) == expected, name
        with rasterio.open(out) as ds:
            np.testing.assert_array_equal(ds.read(), ref)  # lossless whatever the option
    sizes = {n: (tmp_path / n).stat().st_size for n in cases}
    assert sizes["default.tif"] < sizes["none.tif"]
    cog = write_ortho(job, tmp_path / "cog.tif", driver="COG", compress="deflate",
                      OVERVIEWS="NONE")
    with rasterio.open(cog) as ds:
        assert ds.tags(ns="IMAGE_STRUCTURE")["LAYOUT"] == "COG"
        assert ds.overviews(1) == []
        np.testing.assert_array_equal(ds.read(), ref)
    assert _compression(cog)[0] == "DEFLATE"


@pytest.mark.parametrize("kwargs, match", [
    ({"compress": "jpeg2000"}, "compress must be one of"),
    ({"compress": "lzw", "level": 3}, "lzw has no compression level"),
    ({"BLOCKXSIZE": "100"}, "BLOCKXSIZE must be a positive multiple of 16"),
])
def test_bad_write_options_are_refused_before_computing(scene, tmp_path, kwargs, match):
    path, model, dem, grid = scene
    job = ortho_job(path, model, dem, grid, chunks=100)
    with pytest.raises(ValueError, match=match):
        write_ortho(job, tmp_path / "bad.tif", **kwargs)
    assert list(tmp_path.iterdir()) == []
