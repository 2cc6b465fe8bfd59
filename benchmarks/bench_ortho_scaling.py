"""Orthorectification on dask.distributed: wall time and output bytes, local schedulers against
``LocalCluster`` worker processes.

Run: ``python benchmarks/bench_ortho_scaling.py [--size N] [--data JSON | --keep DIR]
[--chunks C] [--repeat R] [--out-dir DIR]``.

Data: ``bench_ortho_cli.py``'s *fine* case, a 10000 x 12000 uint16 tiled GeoTIFF carrying
``RpcModel.example()`` as RPC tags (0.5 m GSD) and a 1" DEM (EPSG:4979, ellipsoidal heights).
``--data JSON`` names prebuilt data (``{"source", "dem", "crs", "res", "bounds"}``, as
``bench_ortho_cli.make_fine`` returns them); otherwise they are written by ``make_fine`` into
``--keep DIR`` (or a temporary directory). The output grid is the top-left ``N x N`` pixels
(``grid[:N, :N]``) of the fine case's 10000 x 10000, 0.5 m UTM 32N grid; ``--size 10000`` is
the whole of it.

One lazy DataArray, ``orthorectify(source, open_model(source), open_dem(dem), grid,
kernel="bilinear", tolerance_px=0.01, chunks=C)`` (one task per output chunk, no dependencies;
a task carries the image and the DEM by path, the model, the full grid and its window), is
written by ``geoblock.io.write_ortho(data, path, compress=None)`` (uncompressed tiled GeoTIFF,
512 x 512 tiles) under each configuration:

* ``threads``: ``scheduler="threads"``, the in-process reference (one thread per core);
* ``synchronous``: ``scheduler="synchronous"`` with ``numba.set_num_threads(1)`` (the tasks run
  on the main thread, where the RPC kernels would otherwise use numba's thread pool for large
  batches): one core;
* ``LocalCluster`` with ``processes=True``: 1 worker x 1 thread, 2 workers x 1 thread, and
  1 worker x 2 threads (the same graph, threads inside one worker process); the ``Client`` is
  passed as ``scheduler``, so ``write_ortho`` submits up to ``in_flight`` chunks ahead (default
  2 per core of this machine) and writes them in row-major order in this process.

Each configuration first writes a warm-up grid (``grid[:256, :256]`` in 64-pixel chunks) and,
on a cluster, runs one 64 x 64 chunk on every worker (``Client.run``), so that numba's
compiled kernels are loaded from its on-disk cache in every process before the timed runs.
Reported: wall time of ``write_ortho`` (best of ``--repeat``; cluster start-up excluded and
given apart), output Mpix/s = N^2 / wall time, speed-up against the 1-worker cluster, the
sha256 of the written file (every timed run is hashed; a configuration whose runs differ is
flagged), whether it equals the ``threads`` file, the peak RSS of the processes that compute
(``threads`` / ``synchronous``: this process, which also writes, its peak reset before the
configuration where Linux allows it; clusters: the largest worker's ``VmHWM``, warm-up
included; ``ru_maxrss`` is not used, as it survives ``execve`` and a spawned worker's would
include this process's), and the 1-minute load average after the configuration (this
benchmark's own processes included: a figure above the cores means other processes shared
the CPUs, and a warning follows the table).

Per chunk (the full-size chunk nearest the grid's centre): the pickled size of its
task (the graph's tuple ``(ortho_chunk, image, model, dem, grid, window, kernel, tolerance,
fill, block_px)``, through ``distributed.protocol.pickle.dumps``, what a scheduler sends), of
each argument, the result chunk's bytes, the source window it reads (the bounding box of its
finite source coordinates padded by the kernel radius + 1, as ``ortho_chunk`` computes it) and
the source tiles that window touches, its time on one thread, and its memory: tracemalloc's
peak in this process (numpy allocations: what GDAL reads into, the coordinates, the output;
not numba's own) and, in a fresh process (spawned, kernels loaded by a 64 x 64 warm-up chunk),
the RSS high-water mark after the task above the resident size before it (everything,
allocator slack included). The task runs on a worker thread, as dask runs it.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import logging
import math
import multiprocessing
import os
import pickle
import platform
import shutil
import sys
import tempfile
import time
import tracemalloc
from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor
from contextlib import ExitStack
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve()
sys.path.insert(0, str(HERE.parent))

TILE = 512
WARM_SIDE = 256  # warm-up grid side, output pixels
WARM_CHUNK = 64  # warm-up chunk side

#: (label, local scheduler or None, LocalCluster keyword arguments or None)
CONFIGS = [
    ("threads (in-process reference)", "threads", None),
    ("synchronous (1 core)", "synchronous", None),
    ("LocalCluster 1 worker x 1 thread", None, {"n_workers": 1, "threads_per_worker": 1}),
    ("LocalCluster 2 workers x 1 thread", None, {"n_workers": 2, "threads_per_worker": 1}),
    ("LocalCluster 1 worker x 2 threads", None, {"n_workers": 1, "threads_per_worker": 2}),
]
BASELINE = "LocalCluster 1 worker x 1 thread"  # the speed-up's denominator


# ------------------------------------------------------------------------------ data
def load_data(args: argparse.Namespace) -> tuple[dict, Path | None]:
    """The data description, and the temporary directory to delete (if one was made)."""
    if args.data:
        return json.loads(Path(args.data).read_text()), None
    from bench_ortho_cli import make_fine

    directory = args.keep or Path(tempfile.mkdtemp(prefix="bench-ortho-scaling-data-"))
    return make_fine(directory), None if args.keep else directory


def inputs(data: dict, size: int):
    """Model, DEM, and the ``size x size`` sub-grid of the case's output grid."""
    import geoblock
    from geoblock.ortho import OutputGrid

    model = geoblock.open_model(data["source"])
    dem = geoblock.open_dem(data["dem"])
    full = OutputGrid.from_bounds(data["crs"], tuple(data["bounds"]), data["res"])
    if size > min(full.shape):
        raise SystemExit(f"--size {size} exceeds the case's grid {full.shape}")
    return model, dem, full[:size, :size]


# ------------------------------------------------------------------------------ helpers
def sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 22), b""):
            h.update(block)
    return h.hexdigest()


def _warm_worker(image, model, dem, grid) -> str:
    """One small chunk in this (worker) process: numba's kernels loaded, GDAL opened."""
    from geoblock.ortho.graph import ortho_chunk

    ortho_chunk(image, model, dem, grid, (0, WARM_CHUNK, 0, WARM_CHUNK), "bilinear", 0.01, 0)
    return "ok"


def _proc_status_kib(field: str) -> int | None:
    """A ``/proc/self/status`` field in KiB (self-contained: also runs on dask workers)."""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith(field + ":"):
                    return int(line.split()[1])
    except OSError:
        return None
    return None


def _worker_peak_mib() -> float | None:
    """This process's peak RSS, MiB (``VmHWM``: ``ru_maxrss`` survives ``execve``, so a
    spawned worker's would include its parent's)."""
    hwm = _proc_status_kib("VmHWM")
    return None if hwm is None else hwm / 1024.0


def _chunk_rss(task: tuple, warm_args: tuple) -> tuple:
    """In a fresh process: resident bytes after a warm-up chunk, and the high-water mark
    after the task (run on a worker thread, as dask runs it); the DEM block cache's bytes and
    blocks then."""
    _warm_worker(*warm_args)
    before = _proc_status_kib("VmRSS")
    with ThreadPoolExecutor(1) as pool:
        pool.submit(task[0], *task[1:]).result()
    after = _proc_status_kib("VmHWM")
    from geoblock.dem.cache import BLOCK_CACHE

    return (None if before is None else before * 1024, None if after is None else after * 1024,
            BLOCK_CACHE.nbytes, len(BLOCK_CACHE))


def task_of(array, index: tuple[int, int]) -> tuple:
    """The graph's task tuple of output chunk ``index`` (row, col) of a dask array."""
    graph = dict(array.__dask_graph__())
    key = (array.name, 0, *index)
    task = graph[key]
    if not isinstance(task, tuple):  # dask's Task objects (newer graphs): their arguments
        task = (task.func, *[getattr(a, "value", a) for a in task.args])
    return task


# ------------------------------------------------------------------------------ one chunk
def chunk_report(arr, model, dem, grid, warm_args: tuple) -> dict:
    """Sizes and memory of the central chunk's task, computed in this process."""
    import rasterio
    from distributed.protocol.pickle import dumps as dask_dumps

    from geoblock._array import finite_bounds
    from geoblock.ortho.graph import ortho_chunk
    from geoblock.ortho.kernels import KERNEL_RADIUS
    from geoblock.ortho.lattice import source_coordinates

    nr, nc = len(arr.data.chunks[1]), len(arr.data.chunks[2])

    def central(sizes: tuple[int, ...]) -> int:  # the full-size chunk nearest the centre
        full = [i for i, s in enumerate(sizes) if s == max(sizes)]
        return min(full, key=lambda i: abs(i - (len(sizes) - 1) / 2))

    index = (central(arr.data.chunks[1]), central(arr.data.chunks[2]))
    task = task_of(arr.data, index)
    func, image, t_model, t_dem, t_grid, window, kernel, tol, fill, block_px = task
    names = ["image", "model", "dem", "grid", "window, kernel, tolerance, fill, block_px"]
    parts = [image, t_model, t_dem, t_grid, (window, kernel, tol, fill, block_px)]
    rep = {"index": index, "window": window, "task_bytes": len(dask_dumps(task)),
           "task_bytes_pickle": len(pickle.dumps(task, protocol=5)),
           "args": {n: len(dask_dumps(p)) for n, p in zip(names, parts, strict=True)},
           "n_tasks": nr * nc}
    r0, r1, c0, c1 = window
    # the source window ortho_chunk reads (its own computation, repeated here)
    row, col, _ = source_coordinates(model, dem, grid, tolerance_px=tol,
                                     window=(slice(r0, r1), slice(c0, c1)), block_px=block_px)
    rows, cols = image.shape
    pad = KERNEL_RADIUS[kernel] + 1
    lo_r, hi_r, lo_c, hi_c = finite_bounds(row, col)
    if math.isfinite(lo_r) and math.isfinite(lo_c):
        wr0, wr1 = max(math.floor(lo_r) - pad, 0), min(math.ceil(hi_r) + pad + 1, rows)
        wc0, wc1 = max(math.floor(lo_c) - pad, 0), min(math.ceil(hi_c) + pad + 1, cols)
    else:
        wr0 = wr1 = wc0 = wc1 = 0
    itemsize = np.dtype(image.dtype).itemsize
    rep["source_window"] = (wr0, wr1, wc0, wc1)
    rep["source_window_bytes"] = (wr1 - wr0) * (wc1 - wc0) * image.bands * itemsize
    with rasterio.open(image.path) as ds:
        by, bx = ds.block_shapes[0]
        rep["source_block"] = (by, bx)
        rep["source_compression"] = ds.compression.value if ds.compression else "none"
    if wr1 > wr0 and wc1 > wc0:
        ty = (wr1 - 1) // by - wr0 // by + 1
        tx = (wc1 - 1) // bx - wc0 // bx + 1
    else:
        ty = tx = 0
    rep["source_tiles"] = ty * tx
    rep["source_tile_bytes"] = ty * tx * by * bx * image.bands * itemsize
    del row, col

    # on a worker thread, as in a dask task (the RPC kernels run serially off the main thread)
    pool = ThreadPoolExecutor(1)

    def run():
        return pool.submit(func, image, t_model, t_dem, t_grid, window, kernel, tol, fill,
                           block_px).result()

    out = run()  # warm (kernels, GDAL)
    rep["chunk_shape"] = out.shape
    rep["chunk_bytes"] = int(out.nbytes)
    rep["chunk_pickled"] = len(dask_dumps(out))
    del out
    t0 = time.perf_counter()
    run()
    rep["chunk_seconds"] = time.perf_counter() - t0
    tracemalloc.start()
    run()
    rep["tracemalloc_peak"] = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    # the resident memory one task adds, in a fresh process (here freed memory is reused)
    with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as proc:
        (rep["rss_before"], rep["rss_peak"], rep["dem_cache_bytes"],
         rep["dem_cache_blocks"]) = proc.submit(_chunk_rss, task, warm_args).result()
    rep["source_file_bytes"] = os.path.getsize(image.path)
    rep["dem_file_bytes"] = os.path.getsize(t_dem.path) if hasattr(t_dem, "path") else None
    pool.shutdown()
    assert func is ortho_chunk
    return rep


# ------------------------------------------------------------------------------ configurations
def run_config(label: str, scheduler, cluster_kw, arr, warm, warm_args, out_dir: Path,
               repeat: int) -> dict:
    import numba
    from _measure import reset_peak

    from geoblock.io import write_ortho

    res: dict = {"label": label}
    out = out_dir / "out.tif"
    warm_out = out_dir / "warm.tif"
    with ExitStack() as stack:
        if cluster_kw is not None:
            from distributed import Client, LocalCluster

            t0 = time.perf_counter()
            cluster = stack.enter_context(LocalCluster(
                processes=True, dashboard_address=None, silence_logs=logging.CRITICAL,
                **cluster_kw))
            client = stack.enter_context(Client(cluster))
            res["startup_s"] = time.perf_counter() - t0
            target = client
        else:
            target = scheduler
            if scheduler == "synchronous":
                previous = numba.get_num_threads()
                numba.set_num_threads(1)
                stack.callback(numba.set_num_threads, previous)
            res["rss_reset"] = reset_peak()
        t0 = time.perf_counter()
        write_ortho(warm, warm_out, scheduler=target, compress=None, blocksize=WARM_CHUNK)
        if cluster_kw is not None:
            client.run(_warm_worker, *warm_args)
        res["warm_s"] = time.perf_counter() - t0
        warm_out.unlink(missing_ok=True)
        times, hashes = [], []
        for _ in range(repeat):
            t0 = time.perf_counter()
            write_ortho(arr, out, scheduler=target, compress=None, blocksize=TILE)
            times.append(time.perf_counter() - t0)
            hashes.append(sha256(out))
            res["file_bytes"] = out.stat().st_size
            out.unlink()
        if cluster_kw is not None:
            res["peak_mib"] = max(client.run(_worker_peak_mib).values())
        else:
            hwm = _proc_status_kib("VmHWM")
            res["peak_mib"] = hwm / 1024.0 if hwm is not None and res["rss_reset"] else None
    res["best_s"] = min(times)
    res["times"] = times
    res["sha256"] = hashes[0]
    res["stable"] = len(set(hashes)) == 1
    return res


# ------------------------------------------------------------------------------ main
def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--size", type=int, default=10000, help="output side, pixels")
    src = ap.add_mutually_exclusive_group()
    src.add_argument("--data", help="JSON describing prebuilt data (source, dem, crs, res, "
                                    "bounds)")
    src.add_argument("--keep", type=Path, default=None,
                     help="build the data with bench_ortho_cli.make_fine into DIR and keep it")
    ap.add_argument("--chunks", type=int, default=1024, help="output chunk side, pixels")
    ap.add_argument("--repeat", type=int, default=3, help="timed runs per configuration")
    ap.add_argument("--out-dir", type=Path, default=None,
                    help="where the outputs are written (and deleted); default a temporary "
                         "directory")
    ap.add_argument("--only", nargs="*", default=None,
                    help="run only the configurations whose label contains one of these")
    args = ap.parse_args()

    import dask
    import distributed
    import numba

    from geoblock.ortho import orthorectify

    data, data_tmp = load_data(args)
    out_dir = args.out_dir or Path(tempfile.mkdtemp(prefix="bench-ortho-scaling-"))
    out_dir.mkdir(parents=True, exist_ok=True)
    try:
        n = args.size
        model, dem, grid = inputs(data, n)
        print(f"# {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
              f"Python {platform.python_version()}, dask {dask.__version__}, distributed "
              f"{distributed.__version__}, numba {numba.__version__} "
              f"({numba.config.NUMBA_NUM_THREADS} threads)")
        print(f"# source {data['source']}, DEM {data['dem']}; output {n} x {n} at "
              f"{grid.resolution[0]:g} m ({grid.crs.to_string()}), chunks {args.chunks}, "
              f"bilinear, tolerance 0.01 px, uncompressed, {TILE} x {TILE} tiles; "
              f"best of {args.repeat}; load average (1 min) before: {os.getloadavg()[0]:.2f}",
              flush=True)
        arr = orthorectify(data["source"], model, dem, grid, kernel="bilinear",
                           tolerance_px=0.01, chunks=args.chunks)
        warm = orthorectify(data["source"], model, dem, grid[:WARM_SIDE, :WARM_SIDE],
                            kernel="bilinear", tolerance_px=0.01, chunks=WARM_CHUNK)
        t0 = time.perf_counter()
        warm_task = task_of(warm.data, (0, 0))
        warm_args = warm_task[1:5]  # image, model, dem, grid
        _warm_worker(*warm_args)
        print(f"# first chunk in this process (numba kernels from the on-disk cache): "
              f"{time.perf_counter() - t0:.2f} s", flush=True)

        chunk = chunk_report(arr, model, dem, grid, warm_args)

        results = []
        for label, scheduler, cluster_kw in CONFIGS:
            if args.only and not any(s in label for s in args.only):
                continue
            r = run_config(label, scheduler, cluster_kw, arr, warm, warm_args, out_dir,
                           args.repeat)
            r["load"] = os.getloadavg()[0]
            results.append(r)
            print(f"{label}: best {r['best_s']:.2f} s, runs "
                  f"{', '.join(f'{t:.2f}' for t in r['times'])}, sha256 {r['sha256'][:16]}"
                  + (f", cluster start {r['startup_s']:.2f} s" if "startup_s" in r else "")
                  + f", warm-up {r['warm_s']:.2f} s, load average (1 min) {r['load']:.2f}",
                  flush=True)

        by_label = {r["label"]: r for r in results}
        ref = by_label.get(CONFIGS[0][0])
        base = by_label.get(BASELINE)
        print(f"\n### {n} x {n} output ({n * n / 1e6:g} Mpix), {chunk['n_tasks']} tasks of "
              f"{args.chunks} x {args.chunks}, {os.cpu_count()} cores\n")
        print("| configuration | wall s | Mpix/s | speed-up vs 1 worker | peak RSS MiB | "
              "sha256[:16] | identical to threads | load avg after |")
        print("|---|---:|---:|---:|---:|---|---|---:|")
        for r in results:
            speed = f"{base['best_s'] / r['best_s']:.2f}x" if base else "-"
            same = "-" if ref is None else ("yes" if r["sha256"] == ref["sha256"] else "**no**")
            if not r["stable"]:
                same += " (runs differ!)"
            peak = f"{r['peak_mib']:.0f}" if r.get("peak_mib") else "-"
            print(f"| {r['label']} | {r['best_s']:.2f} | {n * n / r['best_s'] / 1e6:.1f} | "
                  f"{speed} | {peak} | `{r['sha256'][:16]}` | {same} | {r['load']:.2f} |")
        starts = [f"{r['label'][13:]}: {r['startup_s']:.1f} s" for r in results
                  if "startup_s" in r]
        if starts:
            print(f"\ncluster start-up (not in the wall times): {'; '.join(starts)}")
        busy = [r["label"] for r in results if r["load"] > os.cpu_count() + 0.5]
        if busy:
            print(f"\nWARNING: the 1-min load average exceeded {os.cpu_count()} cores + 0.5 "
                  f"after: {'; '.join(busy)}. Other processes shared the CPUs: the wall times "
                  f"and speed-ups are not the scaling; re-run on an idle machine (the bytes and "
                  f"the per-task sizes are unaffected).")
        if results:
            print(f"output file: {results[0]['file_bytes'] / 1e6:.1f} MB; every output "
                  f"pixel written once, by this process")

        c = chunk
        print(f"\n### one task: chunk {c['index']} (output window {c['window']})\n")
        print(f"- task pickled (distributed.protocol.pickle): {c['task_bytes']} B "
              f"(plain pickle: {c['task_bytes_pickle']} B); by argument: "
              + ", ".join(f"{k} {v} B" for k, v in c["args"].items()))
        print(f"- whole graph: {c['n_tasks']} tasks, ~{c['n_tasks'] * c['task_bytes'] / 1e6:.2f}"
              f" MB if every task is sent on its own")
        print(f"- result chunk: {c['chunk_shape']} {np.dtype(arr.dtype).name}, "
              f"{c['chunk_bytes']} B ({c['chunk_bytes'] / 2**20:.2f} MiB; pickled "
              f"{c['chunk_pickled']} B)")
        wr0, wr1, wc0, wc1 = c["source_window"]
        print(f"- source window read: rows {wr0}:{wr1}, cols {wc0}:{wc1} = {wr1 - wr0} x "
              f"{wc1 - wc0} px, {c['source_window_bytes']} B "
              f"({c['source_window_bytes'] / 2**20:.2f} MiB, "
              f"{c['source_window_bytes'] / c['chunk_bytes']:.2f}x the chunk); source tiles "
              f"{c['source_block'][0]} x {c['source_block'][1]} ({c['source_compression']}): "
              f"{c['source_tiles']} touched, {c['source_tile_bytes'] / 2**20:.2f} MiB "
              f"decoded")
        pixels = c["chunk_shape"][1] * c["chunk_shape"][2]
        mem = (f"- memory of one task: tracemalloc peak {c['tracemalloc_peak'] / 2**20:.1f} MiB"
               f" ({c['tracemalloc_peak'] / pixels:.0f} B per output pixel)")
        if c["rss_before"] is not None and c["rss_peak"] is not None:
            inc = c["rss_peak"] - c["rss_before"]
            mem += (f"; in a fresh process, RSS {c['rss_before'] / 2**20:.0f} MiB after a "
                    f"warm-up chunk, high-water mark {c['rss_peak'] / 2**20:.0f} MiB after the "
                    f"task: +{inc / 2**20:.1f} MiB ({inc / pixels:.0f} B per output pixel)")
        print(mem)
        dem_file = (f"{c['dem_file_bytes'] / 2**20:.1f} MiB file; "
                    if c["dem_file_bytes"] else "")
        print(f"- DEM in a worker process after the warm-up chunk and this task: {dem_file}"
              f"block cache {c['dem_cache_bytes'] / 2**20:.1f} MiB in {c['dem_cache_blocks']} "
              f"block(s), read once per process and kept (LRU, GEOBLOCK_DEM_CACHE_MB); "
              f"source file {c['source_file_bytes'] / 2**20:.0f} MiB")
        print(f"- one task on one worker thread, warm: {c['chunk_seconds']:.3f} s "
              f"({pixels / c['chunk_seconds'] / 1e6:.1f} Mpix/s)")
    finally:
        if args.out_dir is None:
            shutil.rmtree(out_dir, ignore_errors=True)
        if data_tmp is not None:
            shutil.rmtree(data_tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
