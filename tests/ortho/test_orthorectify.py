"""orthorectify: lazy graph, values, determinism across chunkings and schedulers, writing;
ortho_job (the same chunks without dask, what ``geoblock ortho`` runs on local threads) and
write_ortho's compression and creation options."""

from __future__ import annotations

import hashlib
import pickle
import subprocess
import sys
import textwrap
import warnings
from pathlib import Path

import dask
import dask.array as da
import numpy as np
import pyproj
import pytest
import rasterio
import xarray as xr
from affine import Affine

import geoblock
from geoblock.dem import ConstantDem, GridDem
from geoblock.io import open_image, write_ortho
from geoblock.ortho import OrthoJob, OutputGrid, ortho_job, orthorectify, source_coordinates
from geoblock.ortho import graph as graph_module
from geoblock.testing.synthetic import AffineCamera, ConstantVelocityPushbroom

ROWS, COLS = 240, 300


def _write(path: Path, data: np.ndarray, nodata=None) -> str:
    with warnings.catch_warnings():  # a raw image has no geotransform
        warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
        with rasterio.open(path, "w", driver="GTiff", width=data.shape[2], height=data.shape[1],
                           count=data.shape[0], dtype=data.dtype, nodata=nodata) as ds:
            ds.write(data)
    return str(path)


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    """(image path, pushbroom model, rough GridDem, output grid)."""
    tmp = tmp_path_factory.mktemp("ortho")
    rng = np.random.default_rng(0)
    data = (rng.random((2, ROWS, COLS)) * 60000).astype(np.uint16)
    path = _write(tmp / "scene.tif", data)
    model = ConstantVelocityPushbroom.example((ROWS, COLS))
    dem = GridDem(rng.uniform(100.0, 900.0, (30, 30)),
                  Affine(0.004, 0.0, 6.99, 0.0, -0.004, 43.76), "EPSG:4326")
    grid = OutputGrid.for_model(model, dem)
    return path, model, dem, grid


def _digest(array: np.ndarray) -> str:
    return hashlib.sha256(np.ascontiguousarray(array).tobytes()).hexdigest()


def test_dataarray_layout(scene):
    path, model, dem, grid = scene
    out = orthorectify(path, model, dem, grid, chunks=128)
    assert isinstance(out, xr.DataArray) and isinstance(out.data, da.Array)
    assert out.dims == ("band", "y", "x")
    assert out.shape == (2,) + grid.shape
    assert out.dtype == np.uint16
    assert out.chunks[1][0] == 128
    x, y = grid.xy(np.zeros(grid.shape[1]), np.arange(grid.shape[1]))
    np.testing.assert_allclose(out.x.values, x, rtol=0, atol=1e-6)
    x, y = grid.xy(np.arange(grid.shape[0]), np.zeros(grid.shape[0]))
    np.testing.assert_allclose(out.y.values, y, rtol=0, atol=1e-6)
    ref = out.coords["spatial_ref"].attrs
    assert ref["crs_wkt"] == grid.crs.to_wkt()
    c, a, b, f, d, e = (float(v) for v in ref["GeoTransform"].split())
    assert Affine(a, b, c, d, e, f) == grid.transform
    assert out.attrs["_FillValue"] == 0
    # deterministic keys
    again = orthorectify(path, model, dem, grid, chunks=128)
    assert again.data.name == out.data.name
    nearest = orthorectify(path, model, dem, grid, chunks=128, kernel="nearest")
    assert nearest.data.name != out.data.name


def test_building_the_graph_computes_nothing(scene, monkeypatch):
    path, model, dem, grid = scene
    calls = {"coords": 0, "resample": 0}
    real_coords, real_resample = graph_module.source_coordinates, graph_module.resample_cast

    def counting_coords(*args, **kwargs):
        calls["coords"] += 1
        return real_coords(*args, **kwargs)

    def counting_resample(*args, **kwargs):
        calls["resample"] += 1
        return real_resample(*args, **kwargs)

    monkeypatch.setattr(graph_module, "source_coordinates", counting_coords)
    monkeypatch.setattr(graph_module, "resample_cast", counting_resample)

    def refuse(*args, **kwargs):
        raise AssertionError("the graph was computed")

    with dask.config.set(scheduler=refuse):
        out = orthorectify(path, model, dem, grid, chunks=100)
        out = out.isel(band=0) + 0  # more graph, still nothing computed
    assert calls == {"coords": 0, "resample": 0}
    out.compute(scheduler="synchronous")
    n_chunks = len(grid.chunks(100))
    assert calls["coords"] == n_chunks and 0 < calls["resample"] <= n_chunks


def test_identical_bytes_whatever_the_chunking(scene):
    path, model, dem, grid = scene
    digests = {
        size: _digest(orthorectify(path, model, dem, grid, chunks=size, kernel="bicubic")
                      .compute(scheduler="threads").values)
        for size in (64, 100, 1000)  # the issue's 256 / 1000 / 4096, scaled to this grid
    }
    assert len(set(digests.values())) == 1, digests


def test_identical_bytes_threads_and_distributed_processes(scene):
    distributed = pytest.importorskip("distributed")
    path, model, dem, grid = scene
    out = orthorectify(path, model, dem, grid, chunks=100)
    expected = _digest(out.compute(scheduler="threads").values)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        got = _digest(out.compute(scheduler=client).values)
    assert got == expected


def test_values_follow_the_exact_projection(tmp_path):
    """A linear source image (value = 3 row + 5 col) resampled bilinearly gives 3 r + 5 c
    at the exact source coordinates (lattice error <= 0.01 px -> value error <= 0.08)."""
    model = AffineCamera.example((120, 150))
    rr, cc = np.mgrid[0:120, 0:150].astype(np.float32)
    path = _write(tmp_path / "ramp.tif", (3 * rr + 5 * cc)[None])
    dem = ConstantDem(250.0)
    grid = OutputGrid.for_model(model, dem)
    out = orthorectify(path, model, dem, grid, chunks=50).compute().values[0]
    r, c, valid = source_coordinates(model, dem, grid, tolerance_px=0)
    inside = valid & (r >= 0) & (r <= 119) & (c >= 0) & (c <= 149)
    assert inside.mean() > 0.8
    np.testing.assert_allclose(out[inside], (3 * r + 5 * c)[inside], atol=0.08)
    outside = ~valid | (r < -1) | (r > 120) | (c < -1) | (c > 150)
    assert np.isnan(out[outside]).all()


def test_source_nodata_and_fill(tmp_path):
    model = AffineCamera.example((80, 90))
    data = np.full((1, 80, 90), 7, np.uint8)
    data[0, :40] = 255
    path = _write(tmp_path / "nd.tif", data, nodata=255)
    assert open_image(path).nodata == 255
    dem = ConstantDem(100.0)
    out = orthorectify(path, model, dem, kernel="nearest").compute().values[0]
    assert set(np.unique(out)) == {7, 255}
    out = orthorectify(path, model, dem, kernel="nearest", nodata=0).compute().values[0]
    assert set(np.unique(out)) == {0, 7}


def test_image_source_pickles_by_path(scene):
    import pickle

    path = scene[0]
    src = open_image(path)
    assert src.shape == (ROWS, COLS) and src.bands == 2 and src.dtype == "uint16"
    assert pickle.loads(pickle.dumps(src)) == src
    assert src.read((10, 20, 30, 45)).shape == (2, 10, 15)
    with pytest.raises(geoblock.errors.GeoblockIOError):
        open_image(Path(path).with_name("missing.tif"))


def test_write_ortho_tiled_geotiff(scene, tmp_path):
    path, model, dem, grid = scene
    out = orthorectify(path, model, dem, grid, chunks=100)
    dst = write_ortho(out, tmp_path / "ortho.tif", blocksize=128, scheduler="threads")
    with rasterio.open(dst) as ds:
        assert ds.profile["tiled"] and ds.block_shapes[0] == (128, 128)
        assert pyproj.CRS.from_wkt(ds.crs.to_wkt()) == grid.crs
        assert ds.transform == grid.transform
        assert ds.nodata == 0 and ds.count == 2 and ds.dtypes[0] == "uint16"
        np.testing.assert_array_equal(ds.read(), out.compute().values)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ortho.tif"]
    cog = write_ortho(out, tmp_path / "ortho_cog.tif", driver="COG", blocksize=128)
    with rasterio.open(cog) as ds:
        np.testing.assert_array_equal(ds.read(), out.compute().values)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ortho.tif", "ortho_cog.tif"]


def test_write_ortho_is_atomic(scene, tmp_path):
    """A failure mid-write leaves nothing under the final name, and no temporary file."""
    path, model, dem, grid = scene
    out = orthorectify(path, model, dem, grid, chunks=64)
    n = 0

    def fail_late(block):
        nonlocal n
        n += 1
        if n == 5:
            raise RuntimeError("disk on fire")
        return block

    broken = out.copy(data=out.data.map_blocks(fail_late, dtype=out.dtype))
    target = tmp_path / "ortho.tif"
    with pytest.raises(RuntimeError, match="disk on fire"):
        write_ortho(broken, target, scheduler="synchronous", in_flight=2)
    assert n == 5
    assert list(tmp_path.iterdir()) == []
    # an existing file is replaced only by a complete one
    target.write_bytes(b"previous")
    n = 0
    with pytest.raises(RuntimeError):
        write_ortho(broken, target, scheduler="synchronous", in_flight=2)
    assert target.read_bytes() == b"previous"
    assert list(tmp_path.iterdir()) == [target]


def test_write_ortho_refuses_empty_outputs(scene, tmp_path):
    """Issue 12 item 2: an ortho with no valid pixel is an error (nothing written), a warning
    on request; one valid pixel is enough."""
    from geoblock.errors import EmptyOutputError, EmptyOutputWarning

    path, model, dem, grid = scene
    far = OutputGrid.from_bounds(grid.crs, (0.0, 0.0, 500.0, 400.0), 5.0)  # misses the scene
    out = orthorectify(path, model, dem, far, chunks=64)
    target = tmp_path / "ortho.tif"
    with pytest.raises(EmptyOutputError, match="no valid pixel"):
        write_ortho(out, target, scheduler="synchronous")
    assert list(tmp_path.iterdir()) == []
    with pytest.warns(EmptyOutputWarning, match="no valid pixel"):
        write_ortho(out, target, scheduler="synchronous", empty="warn")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        write_ortho(out, tmp_path / "quiet.tif", empty="ignore")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ortho.tif", "quiet.tif"]
    # float NaN nodata, and a single valid pixel
    ref = {"spatial_ref": out.coords["spatial_ref"]}
    data = xr.DataArray(np.full((1, 4, 5), np.nan, np.float32), dims=("band", "y", "x"),
                        coords=ref, attrs={"_FillValue": np.nan})
    with pytest.raises(EmptyOutputError):
        write_ortho(data, tmp_path / "nan.tif")
    data[0, 3, 4] = 7.0
    write_ortho(data, tmp_path / "nan.tif")
    # integers without nodata: every pixel is valid
    zeros = xr.DataArray(np.zeros((1, 4, 5), np.uint8), dims=("band", "y", "x"), coords=ref)
    write_ortho(zeros, tmp_path / "zeros.tif")
    with pytest.raises(ValueError, match="empty"):
        write_ortho(zeros, tmp_path / "bad.tif", empty="maybe")


# ---------------------------------------------------------------- ortho_job, output options
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
    inputs, out = tmp_path / "inputs.pkl", tmp_path / "o.tif"
    inputs.write_bytes(pickle.dumps((model, dem, grid)))
    code = textwrap.dedent(f"""
        import pickle, sys
        from geoblock.io import write_ortho
        from geoblock.ortho import ortho_job
        with open({str(inputs)!r}, "rb") as f:
            model, dem, grid = pickle.load(f)
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
