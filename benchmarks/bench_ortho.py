"""Orthorectification: geoblock against gdalwarp (GDALWarp) and rasterio.warp.reproject.

Run: ``python benchmarks/bench_ortho.py [--size N] [--quick] [--memory-run] [--profile]``.

Synthetic data, written once into a temporary directory (``--keep DIR`` reuses/keeps it):

* **source**: a 10000 x 12000 uint16 tiled GeoTIFF (a textured pattern) carrying the RPC00B
  tags of ``RpcModel.example()`` (0.5 m GSD near Nice), written with
  ``geoblock.write_model(model, tif, format="gtiff")``, so GDAL warps it with the same RPC;
* **ramp**: the same geometry with two uint16 bands ``col`` and ``row`` (coordinate image,
  for the geometric agreement);
* **DEM**: a rough synthetic terrain (0 .. ~1100 m, ridges + 30 m noise) at 1" posts, EPSG:4979
  (ellipsoidal heights: GDAL's RPC_DEM and geoblock read the same numbers, no geoid);
* **output grid**: UTM 32N, the central 5 km x 5 km of the scene at ``5000 / N`` m (N = 10000:
  0.5 m, the source's GSD), gdalwarp's ``-tr RES RES -te XMIN YMIN XMAX YMAX`` grid.

Each method runs in its own subprocess, which reports its wall time and its peak RSS
(``resource.getrusage(RUSAGE_SELF).ru_maxrss``: numpy, numba, GDAL allocations included; the
baseline of an interpreter with the imports is reported too). Output Mpix/s = N^2 / wall time
(file written, uncompressed tiled GeoTIFF, 512 x 512 tiles, for every method but reproject,
which fills an in-memory array).

Methods: geoblock ``orthorectify(..., tolerance_px=0.01)`` written with ``write_ortho``
(dask threads, 2 cores); GDALWarp (rasterio's libgdal, through ctypes: the library behind
``gdalwarp``) with ``-rpc -to RPC_DEM=dem -r bilinear -multi -wo NUM_THREADS=2`` and ``-et 0``
(exact) or ``-et 0.125`` (its default approximation); ``rasterio.warp.reproject`` with
``rpcs=``, ``RPC_DEM=``, ``tolerance=0`` / ``0.125`` and ``num_threads=2``.

Geometric agreement: the ramp image warped by GDALWarp (``-ot Float32``, bilinear: a linear ramp
is reproduced exactly, value = source pixel-centre coordinate) on a full-width strip of the
output grid, compared with geoblock's ``source_coordinates`` (tolerance 0.01 and exact) on the
same pixels.

``--memory-run``: geoblock alone on a 40000 x 40000 output (0.125 m: the source magnified 4x),
written to a temporary file and deleted; wall time and peak RSS.

``--profile``: cProfile of ``orthorectify`` + ``write_ortho`` on a 4000 x 4000 output, single
thread (``scheduler="synchronous"``), top functions by cumulative and internal time.
"""

from __future__ import annotations

import argparse
import ctypes
import glob
import json
import os
import platform
import resource
import shutil
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve()
SCENE_SIDE_M = 5000.0  # output grid: the central 5 km x 5 km of the scene
UTM = "EPSG:32632"
TARGET_MPIX = 80.0  # issue 16 (was 40)
TARGET_PEAK_MIB = 1024.0
TILE = 512


# ------------------------------------------------------------------------------ data
def _model():
    from geoblock_rpc import RpcModel

    return RpcModel.example()


def _write_raster(path: Path, shape, bands: int, fill_strip) -> None:
    """A tiled uint16 GeoTIFF written strip by strip (``fill_strip(r0, r1) -> (bands, h, w)``)."""
    import rasterio
    from rasterio.windows import Window

    rows, cols = shape
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
        with rasterio.open(path, "w", driver="GTiff", width=cols, height=rows, count=bands,
                           dtype="uint16", tiled=True, blockxsize=TILE, blockysize=TILE) as ds:
            for r0 in range(0, rows, TILE):
                r1 = min(r0 + TILE, rows)
                ds.write(fill_strip(r0, r1), window=Window(0, r0, cols, r1 - r0))


def make_data(directory: Path) -> dict:
    """Write source, ramp and DEM (if missing) and return their paths and the output bounds."""
    import rasterio
    from affine import Affine

    import geoblock
    from geoblock import coords

    model = _model()
    rows, cols = model.shape
    paths = {"source": directory / "source.tif", "ramp": directory / "ramp.tif",
             "dem": directory / "dem.tif"}
    if not paths["source"].exists():
        rng = np.random.default_rng(1)
        noise = rng.integers(0, 4000, (TILE, cols), dtype=np.uint16)

        def texture(r0, r1):
            r = np.arange(r0, r1)[:, None]
            c = np.arange(cols)[None, :]
            base = (2000 + 1500 * np.sin(r / 37.0) * np.cos(c / 53.0)
                    + 8 * ((r // 64 + c // 64) % 2) * 1000)
            return (base + noise[: r1 - r0]).astype(np.uint16)[None]

        _write_raster(paths["source"], (rows, cols), 1, texture)
        geoblock.write_model(model, paths["source"], format="gtiff")
    if not paths["ramp"].exists():
        def ramp(r0, r1):
            c = np.broadcast_to(np.arange(cols, dtype=np.uint16)[None, :], (r1 - r0, cols))
            r = np.broadcast_to(np.arange(r0, r1, dtype=np.uint16)[:, None], (r1 - r0, cols))
            return np.stack([c, r])

        _write_raster(paths["ramp"], (rows, cols), 2, ramp)
        geoblock.write_model(model, paths["ramp"], format="gtiff")
    if not paths["dem"].exists():
        # 1" posts over the scene and a margin; ridges + smooth hills + post-scale noise
        step = 1.0 / 3600.0
        west, north, ncols, nrows = 6.95, 43.80, 900, 900
        rng = np.random.default_rng(2)
        lon = west + step * (np.arange(ncols) + 0.5)
        lat = north - step * (np.arange(nrows) + 0.5)
        LON, LAT = np.meshgrid(lon, lat)
        h = (500 + 300 * np.sin(LON * 180.0) * np.cos(LAT * 150.0)
             + 250 * np.abs(np.sin((LON + LAT) * 400.0))
             + rng.normal(0.0, 30.0, LON.shape))
        profile = dict(driver="GTiff", width=ncols, height=nrows, count=1, dtype="float32",
                       crs="EPSG:4979", transform=Affine(step, 0.0, west, 0.0, -step, north),
                       tiled=True, blockxsize=256, blockysize=256)
        with rasterio.open(paths["dem"], "w", **profile) as ds:
            ds.write(h.astype(np.float32)[None])
    # output bounds: the central 5 km square around the image centre at the mean DEM height
    g = model.backproject(np.array([(rows - 1) / 2.0]), np.array([(cols - 1) / 2.0]),
                          np.array([500.0]))
    x, y = coords.transformer("EPSG:4326", UTM).transform(g.lon, g.lat)
    x0, y0 = round(float(x[0])), round(float(y[0]))
    half = SCENE_SIDE_M / 2
    return {k: str(v) for k, v in paths.items()} | {
        "bounds": [x0 - half, y0 - half, x0 + half, y0 + half]}


def _grid(data: dict, size: int):
    from geoblock.ortho import OutputGrid

    return OutputGrid.from_bounds(UTM, tuple(data["bounds"]), SCENE_SIDE_M / size)


# ------------------------------------------------------------------------------ GDAL
def _libgdal():
    """rasterio's own libgdal through ctypes (GDALWarp: the library behind gdalwarp)."""
    import rasterio

    libs = glob.glob(os.path.join(os.path.dirname(os.path.dirname(rasterio.__file__)),
                                  "rasterio.libs", "libgdal*"))
    if not libs:
        raise RuntimeError("rasterio's bundled libgdal not found")
    lib = ctypes.CDLL(libs[0])
    lib.GDALAllRegister()
    vp, cp = ctypes.c_void_p, ctypes.c_char_p
    lib.GDALOpen.restype, lib.GDALOpen.argtypes = vp, [cp, ctypes.c_int]
    lib.GDALWarpAppOptionsNew.restype = vp
    lib.GDALWarpAppOptionsNew.argtypes = [ctypes.POINTER(cp), vp]
    lib.GDALWarpAppOptionsFree.argtypes = [vp]
    lib.GDALWarp.restype = vp
    lib.GDALWarp.argtypes = [cp, vp, ctypes.c_int, ctypes.POINTER(vp), vp,
                             ctypes.POINTER(ctypes.c_int)]
    lib.GDALClose.argtypes = [vp]
    return lib


def gdalwarp(src: str, dst: str, dem: str, grid, et: float, extra=()) -> None:
    lib = _libgdal()
    xmin, ymin, xmax, ymax = grid.bounds
    res = grid.resolution[0]
    args = ["-overwrite", "-of", "GTiff", "-co", "TILED=YES", "-co", f"BLOCKXSIZE={TILE}",
            "-co", f"BLOCKYSIZE={TILE}", "-co", "BIGTIFF=IF_SAFER", "-t_srs", UTM,
            "-tr", repr(res), repr(res), "-te", repr(xmin), repr(ymin), repr(xmax), repr(ymax),
            "-r", "bilinear", "-rpc", "-to", f"RPC_DEM={dem}", "-et", repr(et), "-multi",
            "-wo", "NUM_THREADS=2", "-dstnodata", "0", *extra]
    argv = (ctypes.c_char_p * (len(args) + 1))(*[a.encode() for a in args], None)
    opts = lib.GDALWarpAppOptionsNew(argv, None)
    handle = lib.GDALOpen(src.encode(), 0)
    err = ctypes.c_int(0)
    out = lib.GDALWarp(dst.encode(), None, 1, (ctypes.c_void_p * 1)(handle), opts,
                       ctypes.byref(err))
    if not out:
        raise RuntimeError("GDALWarp failed")
    lib.GDALClose(out)
    lib.GDALClose(handle)
    lib.GDALWarpAppOptionsFree(opts)


# ------------------------------------------------------------------------------ workers
def _rss_mib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def run_method(method: str, data: dict, size: int, out_dir: str) -> dict:
    """One method in this process: wall time, peak RSS."""
    grid = _grid(data, size)
    out = os.path.join(out_dir, f"{method}.tif")
    extra = {}
    if method == "baseline":
        import dask  # noqa: F401
        import rasterio  # noqa: F401
        import xarray  # noqa: F401

        import geoblock.ortho  # noqa: F401
        return {"seconds": 0.0, "peak_mib": _rss_mib()}
    if method.startswith("geoblock"):
        import geoblock
        from geoblock.io import write_ortho
        from geoblock.ortho import orthorectify

        model = _model()
        dem = geoblock.open_dem(data["dem"])
        # the first, cold call: loading the compiled kernels from numba's on-disk cache
        # (or compiling them), GDAL and the thread pool, on a 64 x 64 corner of the grid
        t0 = time.perf_counter()
        warm = os.path.join(out_dir, "warm.tif")
        write_ortho(orthorectify(data["source"], model, dem, grid[:64, :64], chunks=64), warm,
                    compress=None, scheduler="threads", blocksize=64)
        os.remove(warm)
        extra["first_call_s"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        arr = orthorectify(data["source"], model, dem, grid, kernel="bilinear",
                           tolerance_px=0.01, chunks=1024)
        write_ortho(arr, out, compress=None, scheduler="threads", blocksize=TILE)
        seconds = time.perf_counter() - t0
    elif method.startswith("gdalwarp"):
        et = 0.0 if method.endswith("exact") else 0.125
        t0 = time.perf_counter()
        gdalwarp(data["source"], out, data["dem"], grid, et)
        seconds = time.perf_counter() - t0
    elif method.startswith("reproject"):
        import rasterio
        from rasterio.enums import Resampling
        from rasterio.warp import reproject

        tol = 0.0 if method.endswith("exact") else 0.125
        dst = np.zeros(grid.shape, np.uint16)
        t0 = time.perf_counter()
        with rasterio.open(data["source"]) as src:
            reproject(rasterio.band(src, 1), dst, rpcs=src.rpcs, src_crs="EPSG:4326",
                      dst_transform=grid.transform, dst_crs=UTM, dst_nodata=0,
                      resampling=Resampling.bilinear, num_threads=2, RPC_DEM=data["dem"],
                      tolerance=tol)
        seconds = time.perf_counter() - t0
        extra["nonzero"] = int(np.count_nonzero(dst))
    else:
        raise ValueError(method)
    if os.path.exists(out):
        os.remove(out)
    return {"seconds": seconds, "peak_mib": _rss_mib(), **extra}


def subprocess_run(method: str, data: dict, size: int, out_dir: str, timeout=3600) -> dict:
    cmd = [sys.executable, str(HERE), "--worker", method, "--size", str(size),
           "--data", json.dumps(data), "--out-dir", out_dir]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    if proc.returncode != 0:
        return {"error": (proc.stderr.strip().splitlines() or ["?"])[-1]}
    return json.loads(proc.stdout.strip().splitlines()[-1])


# ------------------------------------------------------------------------------ agreement
def agreement(data: dict, size: int, out_dir: str, strip_rows: int) -> dict:
    """Source coordinates: GDAL (ramp warp, exact and -et 0.125) vs geoblock, on a strip."""
    import rasterio

    import geoblock
    from geoblock.ortho.lattice import source_coordinates

    full = _grid(data, size)
    r0 = (size - strip_rows) // 2
    strip = full[r0:r0 + strip_rows, :]
    model = _model()
    dem = geoblock.open_dem(data["dem"])
    gb_r, gb_c, gb_ok = source_coordinates(model, dem, full, tolerance_px=0.01,
                                           window=(slice(r0, r0 + strip_rows), slice(None)))
    ex_r, ex_c, ex_ok = source_coordinates(model, dem, full, tolerance_px=0.0,
                                           window=(slice(r0, r0 + strip_rows), slice(None)))
    res = {"strip": f"{strip_rows} x {size} px (rows {r0}..{r0 + strip_rows})"}
    rows, cols = model.shape

    def stats(dr, dc, ok):
        d = np.maximum(np.abs(dr), np.abs(dc))[ok]
        return {"max_px": float(d.max()), "p99_px": float(np.percentile(d, 99)),
                "median_px": float(np.median(d)), "mean_drow": float(np.mean(dr[ok])),
                "mean_dcol": float(np.mean(dc[ok])), "n": int(ok.sum())}

    res["geoblock_0.01_vs_geoblock_exact"] = stats(gb_r - ex_r, gb_c - ex_c, gb_ok & ex_ok)
    for et in (0.0, 0.125):
        out = os.path.join(out_dir, f"ramp_{et}.tif")
        # XSCALE/YSCALE=1: GDAL widens its bilinear kernel when a chunk's source window is
        # larger than the chunk (a sheared scene), which no longer reproduces a linear ramp
        gdalwarp(data["ramp"], out, data["dem"], strip, et,
                 extra=("-ot", "Float32", "-dstnodata", "-1", "-wo", "XSCALE=1", "-wo", "YSCALE=1"))
        with rasterio.open(out) as ds:
            gc, gr = ds.read().astype(np.float64)
        os.remove(out)
        # a bilinear ramp reproduces the coordinate inside the image; stay 2 px from the edges
        ok = (gc >= 0) & (gr >= 0) & ex_ok & (ex_r > 2) & (ex_r < rows - 3) & (ex_c > 2) \
            & (ex_c < cols - 3)
        key = "exact" if et == 0 else "et0.125"
        res[f"geoblock_0.01_vs_gdal_{key}"] = stats(gb_r - gr, gb_c - gc, ok)
        res[f"geoblock_exact_vs_gdal_{key}"] = stats(ex_r - gr, ex_c - gc, ok)
        if et:
            res["gdal_et0.125_vs_geoblock_exact"] = stats(gr - ex_r, gc - ex_c, ok)
    return res


# ------------------------------------------------------------------------------ profile
def profile(data: dict, size: int, out_dir: str) -> None:
    import cProfile
    import pstats

    import geoblock
    from geoblock.io import write_ortho
    from geoblock.ortho import orthorectify
    from geoblock.ortho.lattice import source_coordinates

    grid = _grid(data, size)
    model = _model()
    dem = geoblock.open_dem(data["dem"])
    source_coordinates(model, dem, grid[:64, :64])
    out = os.path.join(out_dir, "profile.tif")
    for sched in ("synchronous", "threads"):
        t0 = time.perf_counter()
        write_ortho(orthorectify(data["source"], model, dem, grid, chunks=1024), out,
                    compress=None, scheduler=sched, blocksize=TILE)
        dt = time.perf_counter() - t0
        print(f"{size} x {size}, {sched}: {dt:.2f} s, {size * size / dt / 1e6:.1f} Mpix/s")
    t0 = time.perf_counter()
    source_coordinates(model, dem, grid)
    dt = time.perf_counter() - t0
    print(f"source_coordinates alone, whole grid, 1 thread: {dt:.2f} s, "
          f"{size * size / dt / 1e6:.1f} Mpix/s")
    prof = cProfile.Profile()
    prof.enable()
    write_ortho(orthorectify(data["source"], model, dem, grid, chunks=1024), out,
                compress=None, scheduler="synchronous", blocksize=TILE)
    prof.disable()
    os.remove(out)
    st = pstats.Stats(prof)
    st.sort_stats("tottime").print_stats(18)


# ------------------------------------------------------------------------------ main
def _fmt(v, spec=".1f"):
    return "-" if v is None or (isinstance(v, float) and not np.isfinite(v)) else format(v, spec)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=None, help="output side N (default 10000)")
    ap.add_argument("--quick", action="store_true", help="N = 2000, no reproject rows")
    ap.add_argument("--memory-run", action="store_true", help="geoblock on a 40000^2 output")
    ap.add_argument("--memory-size", type=int, default=40000)
    ap.add_argument("--profile", action="store_true", help="cProfile on a 4000^2 output")
    ap.add_argument("--keep", type=Path, default=None, help="data directory to reuse/keep")
    ap.add_argument("--strip-rows", type=int, default=1000)
    ap.add_argument("--worker", default=None, help=argparse.SUPPRESS)
    ap.add_argument("--data", default=None, help=argparse.SUPPRESS)
    ap.add_argument("--out-dir", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args()

    if args.worker:
        res = run_method(args.worker, json.loads(args.data), args.size, args.out_dir)
        print(json.dumps(res))
        return

    size = args.size or (2000 if args.quick else 10000)
    tmp = Path(tempfile.mkdtemp(prefix="bench_ortho_"))
    data_dir = args.keep or tmp
    data_dir.mkdir(parents=True, exist_ok=True)
    try:
        t0 = time.perf_counter()
        data = make_data(data_dir)
        print(f"data in {data_dir} ({time.perf_counter() - t0:.1f} s); "
              f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
              f"python {platform.python_version()}")
        if args.profile:
            profile(data, args.size or 4000, str(tmp))
            return
        if args.memory_run:
            n = args.memory_size
            res = subprocess_run("geoblock", data, n, str(tmp), timeout=7200)
            print(f"memory run: geoblock {n} x {n} output ({SCENE_SIDE_M / n:g} m), "
                  f"written uncompressed then deleted: {res}")
            if "seconds" in res:
                print(f"  {n * n / res['seconds'] / 1e6:.1f} Mpix/s, "
                      f"peak RSS {res['peak_mib']:.0f} MiB")
            return
        methods = ["baseline", "geoblock", "gdalwarp-exact", "gdalwarp-et0.125"]
        if not args.quick:
            methods += ["reproject-exact", "reproject-et0.125"]
        results = {}
        for m in methods:
            results[m] = subprocess_run(m, data, size, str(tmp))
            print(m, results[m], flush=True)
        print(f"\n### {size} x {size} output (UTM 32N, {SCENE_SIDE_M / size:g} m), bilinear, "
              f"RPC + DEM, 2 threads\n")
        print("| method | wall s | Mpix/s | peak RSS MiB |")
        print("|---|---:|---:|---:|")
        for m in methods:
            r = results[m]
            if "error" in r:
                print(f"| {m} | unavailable: {r['error']} | | |")
                continue
            mp = size * size / r["seconds"] / 1e6 if r["seconds"] else float("nan")
            print(
                f"| {m} | {_fmt(r['seconds'], '.2f')} | {_fmt(mp)} "
                f"| {_fmt(r['peak_mib'], '.0f')} |"
            )
        g = results.get("geoblock", {})
        if "seconds" in g:
            mp = size * size / g["seconds"] / 1e6
            cold = size * size / (g["seconds"] + g["first_call_s"]) / 1e6
            print(f"\ntarget >= {TARGET_MPIX:g} Mpix/s at <= 0.01 px, <= {TARGET_PEAK_MIB:g} MiB: "
                  f"{mp:.1f} Mpix/s, {g['peak_mib']:.0f} MiB (first call, kernels loaded from "
                  f"numba's cache: {g['first_call_s']:.2f} s; {cold:.1f} Mpix/s with it)")
        agree = agreement(data, size, str(tmp), min(args.strip_rows, size))
        print("\n### geometric agreement (source coordinates, px; d = max(|drow|, |dcol|))\n")
        print(f"strip: {agree.pop('strip')}\n")
        print("| comparison | max | p99 | median | mean drow | mean dcol | n |")
        print("|---|---:|---:|---:|---:|---:|---:|")
        for k, s in agree.items():
            print(f"| {k} | {s['max_px']:.4f} | {s['p99_px']:.4f} | {s['median_px']:.4f} | "
                  f"{s['mean_drow']:+.4f} | {s['mean_dcol']:+.4f} | {s['n']} |")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
