"""Orthorectification as whole commands: ``geoblock ortho`` against the ``gdalwarp`` program.

Run: ``python benchmarks/bench_ortho_cli.py [--case coarse|rugged|fine|all] [--repeat N]
[--keep DIR] [--quick]``.

What users time is the command, start-up included, so every method here is one process
started from the shell, timed by its wall clock (best and median of ``--repeat`` rounds after
one untimed run of each that warms the page cache and numba's on-disk kernel cache; the
commands interleaved within each round), with its own peak RSS (``wait4``), side by side in
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
* **rugged** (c): case (a)'s scene and output on the issue-30 rugged DEM: 400 x 400 posts over
  1.6 x 1.2 deg centred on the scene, ``750 + 600 sin(6x) cos(5y) + 100 sin(23x + 3y)`` m
  with ``x = 2 pi (lon - west) / 1.6``, ``y = 2 pi (lat - south) / 1.2`` (degrees, at post
  centres; :func:`rugged_heights`): the lattice refines, DEM sampling weighs;
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
def make_coarse(directory: Path, rugged: bool = False) -> dict:
    """Case (a): the SPOT-2 RPC on a 6000 x 6000 texture, a 400 x 400 DEM, 9 m output.

    ``rugged``: case (c), the same scene and output on :func:`rugged_heights`'s DEM."""
    import rasterio
    from affine import Affine
    from bench_ortho import _write_raster
    from geoblock_rpc.export import export_rpc

    import geoblock
    from geoblock import coords

    directory.mkdir(parents=True, exist_ok=True)
    source = directory / "spot2.tif"
    dem = directory / ("rugged400.tif" if rugged else "dem400.tif")
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
    if not dem.exists() and rugged:
        _write_rugged(dem, float(g.lon[4]), float(g.lat[4]))
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
    return {"name": "rugged" if rugged else "coarse", "source": str(source), "dem": str(dem),
            "crs": crs.to_string(), "res": res, "size": size,
            "bounds": [x0 - half, y0 - half, x0 + half, y0 + half]}


#: The rugged DEM (case c): posts, extent (degrees of longitude, latitude) around the scene.
RUGGED_POSTS, RUGGED_EXTENT_DEG = 400, (1.6, 1.2)


def rugged_heights(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Case (c)'s heights, metres above the WGS84 ellipsoid, at normalised coordinates
    ``x, y`` in radians: ``750 + 600 sin(6x) cos(5y) + 100 sin(23x + 3y)``.

    ``x = 2 pi (lon - west) / 1.6``, ``y = 2 pi (lat - south) / 1.2`` (lon, lat in degrees)
    at each post centre: over the DEM's 1.6 x 1.2 deg, 6 x 5 waves of 600 m (a wavelength of
    ~30 km east-west, ~27 km north-south) and 23 x 3 waves of 100 m (~8 km), 150-1450 m; slopes
    up to ~10 deg. About 0.55 x 0.55 deg of it lies under the 60 km SPOT-2 scene."""
    return 750.0 + 600.0 * np.sin(6.0 * x) * np.cos(5.0 * y) + 100.0 * np.sin(23.0 * x + 3.0 * y)


def _write_rugged(path: Path, lon_c: float, lat_c: float) -> None:
    """:func:`rugged_heights` on ``RUGGED_POSTS``^2 posts over ``RUGGED_EXTENT_DEG`` centred on
    ``(lon_c, lat_c)``, float32, EPSG:4979 (ellipsoidal heights), pixel-is-area."""
    import rasterio
    from affine import Affine

    n = RUGGED_POSTS
    width, height = RUGGED_EXTENT_DEG
    west, north = lon_c - width / 2, lat_c + height / 2
    south = north - height
    dx, dy = width / n, height / n
    lon = west + dx * (np.arange(n) + 0.5)  # post centres
    lat = north - dy * (np.arange(n) + 0.5)
    LON, LAT = np.meshgrid(lon, lat)
    h = rugged_heights(2 * np.pi * (LON - west) / width, 2 * np.pi * (LAT - south) / height)
    with rasterio.open(path, "w", driver="GTiff", width=n, height=n, count=1,
                       dtype="float32", crs="EPSG:4979",
                       transform=Affine(dx, 0.0, west, 0.0, -dy, north)) as ds:
        ds.write(h.astype(np.float32)[None])


def make_rugged(directory: Path) -> dict:
    """Case (c): case (a)'s scene (shared with it, in ``../coarse``) and output grid on the
    rugged DEM."""
    directory.mkdir(parents=True, exist_ok=True)
    return make_coarse(directory.parent / "coarse", rugged=True)


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
    return run_rss(cmd, env)[0]


def run_rss(cmd: list[str], env=None) -> tuple[float, float]:
    """Wall seconds and peak RSS (MB, the process's own, from ``wait4``) of one command."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            env=env or ENV)
    _, status, usage = os.wait4(proc.pid, 0)
    seconds = time.perf_counter() - t0
    proc.returncode = os.waitstatus_to_exitcode(status)
    err = proc.stderr.read().decode(errors="replace") if proc.stderr else ""
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd[:3])}... failed: {err.strip()[-400:]}")
    return seconds, usage.ru_maxrss / 1024.0


def timed_interleaved(cmds: list[tuple[str, list[str]]], repeat: int,
                      out: str) -> list[tuple[str, dict]]:
    """Each command once untimed (page cache, numba's on-disk cache, GDAL's), then
    ``repeat`` rounds of all of them in turn: best and median wall time, peak RSS, the output
    size."""
    for _, cmd in cmds:
        run(cmd)
    times: dict[str, list[float]] = {label: [] for label, _ in cmds}
    rss: dict[str, float] = dict.fromkeys(times, 0.0)
    size: dict[str, int | None] = dict.fromkeys(times)
    for _ in range(repeat):
        for label, cmd in cmds:
            seconds, mb = run_rss(cmd)
            times[label].append(seconds)
            rss[label] = max(rss[label], mb)
            size[label] = os.path.getsize(out) if os.path.exists(out) else None
            if os.path.exists(out):
                os.remove(out)
    return [(label, {"best": min(times[label]), "median": statistics.median(times[label]),
                     "rss": rss[label], "bytes": size[label]}) for label, _ in cmds]


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


def bench_case(case: dict, directory: Path, repeat: int,
               exact: bool = True) -> list[tuple[str, dict]]:
    out = str(directory / f"out-{case['name']}.tif")
    cmds = [
        ("geoblock ortho (defaults)", geoblock_cmd(case, out)),
        ("gdalwarp -et 0.125", gdalwarp_cmd(case, out, 0.125)),
        ("geoblock ortho --compress none", geoblock_cmd(case, out, ["--compress", "none"])),
    ]
    if exact:
        cmds.append(("gdalwarp exact (-et 0)", gdalwarp_cmd(case, out, 0.0)))
    return timed_interleaved(cmds, repeat, out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--case", choices=["coarse", "rugged", "fine", "all"], default="all")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--keep", type=Path, default=None, help="data directory, kept")
    ap.add_argument("--quick", action="store_true", help="one timed run per command")
    ap.add_argument("--no-exact", action="store_true", help="leave out exact gdalwarp (-et 0)")
    ap.add_argument("--no-cold", action="store_true",
                    help="leave out the first command with an empty numba cache")
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
    cases = {"coarse": make_coarse, "rugged": make_rugged, "fine": make_fine}
    names = list(cases) if args.case == "all" else [args.case]
    for name in names:
        case = cases[name](directory / name)
        n = case["size"] ** 2
        print(f"\n## case {name}: {case['size']} x {case['size']} output at {case['res']} m, "
              f"DEM {Path(case['dem']).name}; lattice error at --tolerance 0.01: "
              f"{lattice_error(case):.4f} px")
        print(f"load before: {os.getloadavg()[0]:.2f} (1-min average)")
        rows = bench_case(case, directory / name, repeat, exact=not args.no_exact)
        ref = dict(rows)
        print(f"{'command':40s} {'best s':>8s} {'median s':>9s} {'Mpix/s':>8s} {'MB out':>8s}"
              f" {'peak RSS MB':>12s} {'vs -et 0.125 (best, median)':>28s}")
        g = ref["gdalwarp -et 0.125"]
        for label, r in rows:
            mb = f"{r['bytes'] / 1e6:8.1f}" if r["bytes"] else "       -"
            print(f"{label:40s} {r['best']:8.2f} {r['median']:9.2f} {n / r['best'] / 1e6:8.1f}"
                  f" {mb} {r['rss']:12.0f} {g['best'] / r['best']:13.2f}x"
                  f" {g['median'] / r['median']:13.2f}x")
        print(f"load after: {os.getloadavg()[0]:.2f} (1-min average)")
        if not args.no_cold:
            print(f"{'first geoblock ortho, empty numba cache':40s} "
                  f"{cold_first_command(case, directory / name):8.2f}")
    if args.keep is None:
        shutil.rmtree(directory, ignore_errors=True)


if __name__ == "__main__":
    main()
