"""Orthorectification as whole commands: ``geoblock ortho`` against the ``gdalwarp`` program.

Run: ``python benchmarks/bench_ortho_cli.py [--case coarse|fine|all] [--repeat N]
[--keep DIR] [--quick]``.

What users time is the command, start-up included, so every method here is one process
started from the shell, timed by its wall clock (best and median of ``--repeat`` runs after
one untimed run that warms the page cache and numba's on-disk kernel cache), side by side in
one run:

* ``geoblock ortho SRC OUT --dem DEM --crs --res --bounds --resampling bilinear
  --no-progress`` with its default output options (ZSTD level 1), and with ``--compress none``
  (an uncompressed file, as gdalwarp writes);
* ``gdalwarp -rpc -to RPC_DEM=DEM -r bilinear -multi -wo NUM_THREADS=2 -co TILED=YES
  -t_srs -tr -te`` exact (``-et 0``) and with its default approximation ``-et 0.125``
  (the Debian ``gdal-bin`` program, as installed by ``.ci/run``).

Both read the same RPC00B (GeoTIFF RPC tags) and the same DEM (ellipsoidal heights, EPSG:4979,
so no geoid enters either side) and write the same grid (``-t_srs/-tr/-te`` = ``--crs/--res/
--bounds``), tiled 512 x 512 GeoTIFF, nodata 0.

Cases (written once into ``--keep DIR``, default a temporary directory):

* **coarse** (a): a 6000 x 6000 uint16 scene carrying an RPC fitted by ``geoblock
  export-rpc`` to the real SPOT-2 HRV scene ``cosicorr3d/test_dataset/SPOT2.DIM`` from
  ``../shared/data`` (0.06 px from its physical model), a coarse DEM of 400 x 400 posts over
  the scene (~150 m posts under a 10 m scene: gdalwarp's best case, few DEM reads per pixel),
  output 6000 x 6000 at 9 m in the scene's UTM zone;
* **fine** (b): ``bench_ortho.py``'s 10000 x 12000 scene (0.5 m, ``RpcModel.example()``) on a
  1" DEM, output 10000 x 10000 at 0.5 m (a DEM as fine as the output).

Also reported: ``geoblock --help`` and ``geoblock plugins`` (a no-op command) start-up, the
first ``geoblock ortho`` with an empty numba cache (what the first command after an
install costs: the kernels are compiled into the cache), and the lattice error of geoblock's
default on each case (in-process, ``source_coordinates`` at ``--tolerance 0.01`` against
exact, over a full-width strip).
"""

from __future__ import annotations

import argparse
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve()
sys.path.insert(0, str(HERE.parent))

DATA = Path(os.environ.get("GEOBLOCK_TEST_DATA", HERE.parents[2] / "shared" / "data"))
SPOT2 = DATA / "cosicorr3d" / "test_dataset" / "SPOT2.DIM"
TILE = 512


def _geoblock_exe() -> str:
    exe = Path(sys.executable).with_name("geoblock")
    return str(exe) if exe.exists() else "geoblock"


# ------------------------------------------------------------------------------ data
def make_coarse(directory: Path) -> dict:
    """Case (a): the SPOT-2 RPC on a 6000 x 6000 texture, a 400 x 400 DEM, 9 m output."""
    import rasterio
    from affine import Affine
    from bench_ortho import _write_raster
    from geoblock_rpc.export import export_rpc

    import geoblock
    from geoblock import coords

    directory.mkdir(parents=True, exist_ok=True)
    source, dem = directory / "spot2.tif", directory / "dem400.tif"
    if source.exists():  # written by an earlier run: its RPC tags, not a second fit
        rpc = geoblock.open_model(source)
    else:
        rpc, _ = export_rpc(geoblock.open_model(SPOT2))  # fitted, ~0.06 px
    rows, cols = rpc.shape
    if not source.exists():
        rng = np.random.default_rng(1)
        noise = rng.integers(0, 400, (TILE, cols), dtype=np.uint16)

        def texture(r0, r1):
            r = np.arange(r0, r1)[:, None]
            c = np.arange(cols)[None, :]
            base = (600 + 300 * np.sin(r / 23.0) * np.cos(c / 31.0)
                    + 200 * ((r // 40 + c // 40) % 2))
            return (base + noise[: r1 - r0]).astype(np.uint16)[None]

        _write_raster(source, (rows, cols), 1, texture)
        geoblock.write_model(rpc, source, format="gtiff")
    # the scene outline at its mean height: DEM extent (with a margin) and output bounds
    r = np.array([0.0, 0.0, rows - 1.0, rows - 1.0, (rows - 1) / 2])
    c = np.array([0.0, cols - 1.0, 0.0, cols - 1.0, (cols - 1) / 2])
    g = rpc.backproject(r, c, np.full(5, 300.0))
    if not dem.exists():
        west, east = g.lon.min() - 0.05, g.lon.max() + 0.05
        south, north = g.lat.min() - 0.05, g.lat.max() + 0.05
        n = 400
        dx, dy = (east - west) / n, (north - south) / n
        lon = west + dx * (np.arange(n) + 0.5)
        lat = north - dy * (np.arange(n) + 0.5)
        LON, LAT = np.meshgrid(lon, lat)
        rng = np.random.default_rng(2)
        h = (300 + 250 * np.sin(LON * 40.0) * np.cos(LAT * 30.0)
             + 150 * np.abs(np.sin((LON + LAT) * 90.0)) + rng.normal(0.0, 10.0, LON.shape))
        with rasterio.open(dem, "w", driver="GTiff", width=n, height=n, count=1,
                           dtype="float32", crs="EPSG:4979",
                           transform=Affine(dx, 0.0, west, 0.0, -dy, north)) as ds:
            ds.write(h.astype(np.float32)[None])
    crs = coords.utm_crs(float(g.lon[4]), float(g.lat[4]))
    x, y = coords.transformer("EPSG:4326", crs).transform(g.lon[4], g.lat[4])
    res, size = 9.0, 6000
    half = res * size / 2
    x0, y0 = round(float(x) / res) * res, round(float(y) / res) * res
    return {"name": "coarse", "source": str(source), "dem": str(dem),
            "crs": crs.to_string(), "res": res, "size": size,
            "bounds": [x0 - half, y0 - half, x0 + half, y0 + half]}


def make_fine(directory: Path) -> dict:
    """Case (b): bench_ortho.py's 10000 x 12000 scene on a 1" DEM, 10000 x 10000 at 0.5 m."""
    from bench_ortho import SCENE_SIDE_M, UTM, make_data

    directory.mkdir(parents=True, exist_ok=True)
    data = make_data(directory)
    size = 10000
    return {"name": "fine", "source": data["source"], "dem": data["dem"], "crs": UTM,
            "res": SCENE_SIDE_M / size, "size": size, "bounds": data["bounds"]}


# ------------------------------------------------------------------------------ commands
def geoblock_cmd(case: dict, out: str, extra=()) -> list[str]:
    xmin, ymin, xmax, ymax = case["bounds"]
    return [_geoblock_exe(), "-q", "ortho", case["source"], out, "--dem", case["dem"],
            "--crs", case["crs"], "--res", repr(case["res"]),
            "--bounds", repr(xmin), repr(ymin), repr(xmax), repr(ymax),
            "--resampling", "bilinear", "--no-progress", "--overwrite", *extra]


def gdalwarp_cmd(case: dict, out: str, et: float) -> list[str]:
    xmin, ymin, xmax, ymax = case["bounds"]
    res = case["res"]
    return ["gdalwarp", "-q", "-overwrite", "-of", "GTiff", "-co", "TILED=YES",
            "-co", f"BLOCKXSIZE={TILE}", "-co", f"BLOCKYSIZE={TILE}", "-co", "BIGTIFF=IF_SAFER",
            "-t_srs", case["crs"], "-tr", repr(res), repr(res),
            "-te", repr(xmin), repr(ymin), repr(xmax), repr(ymax),
            "-r", "bilinear", "-rpc", "-to", f"RPC_DEM={case['dem']}", "-et", repr(et),
            "-multi", "-wo", "NUM_THREADS=2", "-dstnodata", "0", case["source"], out]


#: The commands' environment: a user's, whose installed packages have their bytecode (pip
#: compiles it at install); PYTHONDONTWRITEBYTECODE, set on some CI machines, would recompile
#: every geoblock module in every run.
ENV = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}


def run(cmd: list[str], env=None) -> float:
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env or ENV)
    seconds = time.perf_counter() - t0
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd[:3])}... failed: {proc.stderr.strip()[-400:]}")
    return seconds


def timed(cmd: list[str], repeat: int, out: str | None = None) -> dict:
    run(cmd)  # warm: page cache, numba's on-disk cache, GDAL's
    times = []
    for _ in range(repeat):
        times.append(run(cmd))
    size = os.path.getsize(out) if out and os.path.exists(out) else None
    if out and os.path.exists(out):
        os.remove(out)
    return {"best": min(times), "median": statistics.median(times), "bytes": size}


def lattice_error(case: dict, strip_rows: int = 64) -> float:
    """Largest |tolerance 0.01 - exact| source coordinate, px, over a full-width strip."""
    import geoblock
    from geoblock.ortho import OutputGrid
    from geoblock.ortho.lattice import source_coordinates

    model = geoblock.open_model(case["source"])
    dem = geoblock.open_dem(case["dem"])
    grid = OutputGrid.from_bounds(case["crs"], tuple(case["bounds"]), case["res"])
    mid = grid.shape[0] // 2
    window = (slice(mid, mid + strip_rows), slice(0, grid.shape[1]))
    r1, c1, ok1 = source_coordinates(model, dem, grid, tolerance_px=0.01, window=window)
    r0, c0, ok0 = source_coordinates(model, dem, grid, tolerance_px=0.0, window=window)
    ok = ok0 & ok1
    return float(max(np.abs(r1 - r0)[ok].max(), np.abs(c1 - c0)[ok].max()))


def startup(repeat: int) -> dict:
    exe = _geoblock_exe()
    out = {}
    for label, cmd in (("geoblock --help", [exe, "--help"]),
                       ("geoblock plugins", [exe, "plugins"]),
                       ("python -c pass", [sys.executable, "-c", "pass"])):
        run(cmd)
        out[label] = min(run(cmd) for _ in range(repeat))
    return out


def cold_first_command(case: dict, directory: Path) -> float:
    """The first ``geoblock ortho`` with an empty numba cache (NUMBA_CACHE_DIR)."""
    cache = Path(tempfile.mkdtemp(prefix="numba-cold-", dir=directory))
    out = str(directory / "cold.tif")
    try:
        env = dict(ENV, NUMBA_CACHE_DIR=str(cache))
        return run(geoblock_cmd(case, out), env=env)
    finally:
        shutil.rmtree(cache, ignore_errors=True)
        if os.path.exists(out):
            os.remove(out)


def bench_case(case: dict, directory: Path, repeat: int) -> list[tuple[str, dict]]:
    out = str(directory / f"out-{case['name']}.tif")
    rows = [
        ("geoblock ortho (defaults)", timed(geoblock_cmd(case, out), repeat, out)),
        ("geoblock ortho --compress none",
         timed(geoblock_cmd(case, out, ["--compress", "none"]), repeat, out)),
        ("gdalwarp -et 0.125", timed(gdalwarp_cmd(case, out, 0.125), repeat, out)),
        ("gdalwarp exact (-et 0)", timed(gdalwarp_cmd(case, out, 0.0), repeat, out)),
    ]
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--case", choices=["coarse", "fine", "all"], default="all")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--keep", type=Path, default=None, help="data directory, kept")
    ap.add_argument("--quick", action="store_true", help="one timed run per command")
    args = ap.parse_args()
    repeat = 1 if args.quick else args.repeat
    if shutil.which("gdalwarp") is None:
        sys.exit("gdalwarp not found: install gdal-bin (Debian) to compare with it")
    if not SPOT2.exists():
        sys.exit(f"{SPOT2} not found: set GEOBLOCK_TEST_DATA to the shared data folder")
    directory = args.keep or Path(tempfile.mkdtemp(prefix="bench-ortho-cli-"))
    gdal_version = subprocess.run(["gdalwarp", "--version"], capture_output=True,
                                  text=True).stdout.strip()
    print(f"# {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
          f"Python {platform.python_version()}, {gdal_version}; data in {directory}")
    for label, seconds in startup(max(repeat, 3)).items():
        print(f"{label:40s} {seconds:7.3f} s")
    cases = {"coarse": make_coarse, "fine": make_fine}
    names = list(cases) if args.case == "all" else [args.case]
    for name in names:
        case = cases[name](directory / name)
        n = case["size"] ** 2
        print(f"\n## case {name}: {case['size']} x {case['size']} output at {case['res']} m, "
              f"DEM {Path(case['dem']).name}; lattice error at --tolerance 0.01: "
              f"{lattice_error(case):.4f} px")
        rows = bench_case(case, directory / name, repeat)
        ref = dict(rows)
        print(f"{'command':40s} {'best s':>8s} {'median s':>9s} {'Mpix/s':>8s} {'MB out':>8s}"
              f" {'vs -et 0.125':>13s} {'vs exact':>9s}")
        for label, r in rows:
            mb = f"{r['bytes'] / 1e6:8.1f}" if r["bytes"] else "       -"
            print(f"{label:40s} {r['best']:8.2f} {r['median']:9.2f} {n / r['best'] / 1e6:8.1f}"
                  f" {mb} {ref['gdalwarp -et 0.125']['best'] / r['best']:12.2f}x"
                  f" {ref['gdalwarp exact (-et 0)']['best'] / r['best']:8.2f}x")
        print(f"{'first geoblock ortho, empty numba cache':40s} "
              f"{cold_first_command(case, directory / name):8.2f}")
    if args.keep is None:
        shutil.rmtree(directory, ignore_errors=True)


if __name__ == "__main__":
    main()
