"""Start-up of the ``geoblock`` command: whole commands as a user times them.

Three parts, each printed as a table:

1. **Whole commands**, each a new process, interleaved with the peer baseline
   ``gdalinfo --version`` (a C program that loads GDAL) after one warm-up round: ``geoblock
   --help``, ``geoblock plugins`` and ``geoblock project`` of 10 points with the Pleiades RPC of
   ``/work/shared/data/shareloc`` (a GeoTIFF whose RPC tags are read with rasterio). Min and
   median of ``--runs`` runs.
2. **The cold ``project`` breakdown**, in a new process, timed in-process: the imports
   (``geoblock``, ``geoblock.io``, the CLI), opening the model (rasterio, the plugin's reader,
   its plausibility check), the first projection and a second one (the work). Twice: as the
   command runs (10 points take the RPC plugin's numpy path, no numba), and with numba's
   kernels forced first (importing numba, building its registries: what a batch above the
   small-batch limit, or any other kernel, pays), each cost on a row of its own.
3. **The first command after an install**: ``geoblock project`` with ``NUMBA_CACHE_DIR``
   pointed at a new empty directory, so that every kernel the command calls is compiled
   (what a user meets once, on the first command after ``pip install``), then the same
   command again with that cache.

``--before TREE`` also runs every command with ``PYTHONPATH=TREE/src:TREE/plugins/*/src``
(another checkout of geoblock and its plugins, e.g. ``git worktree add /tmp/before <commit>``),
interleaved with the current one, so that both are measured under the same load (the
"before" figures of ``benchmarks/README.md``). ``PYTHONDONTWRITEBYTECODE``
is removed from the children's environment: users have ``.pyc`` files.

Usage: ``python benchmarks/bench_startup.py [--runs 7] [--cold-runs 2]``
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

DATA = Path("/work/shared/data")
RPC = DATA / "shareloc/rpc/PHR1B_P_201709281038393_SEN_PRG_FC_178609-001.tif"
#: ten image positions of the Pleiades scene (rows, cols), localised at h = 100 m for the CSV
ROWS = (100.0, 2000.0, 5000.0, 10000.0, 20000.0, 30000.0, 1000.0, 15000.0, 25000.0, 3000.0)
COLS = (100.0, 3000.0, 5000.0, 9000.0, 12000.0, 16000.0, 2000.0, 3000.0, 7000.0, 20000.0)


#: ``PYTHONPATH`` of the "before" tree's runs (``--before``), else None
VERSIONS: dict[str, str | None] = {"": None}


def _env(version: str = "", **extra: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items()
           if k not in ("PYTHONDONTWRITEBYTECODE", "GEOBLOCK_PLUGIN_MODULES", "PYTHONPATH")}
    if VERSIONS.get(version):
        env["PYTHONPATH"] = str(VERSIONS[version])
    env.update(extra)
    return env


def _geoblock() -> list[str]:
    script = Path(sys.executable).with_name("geoblock")
    return [str(script)] if script.exists() else [sys.executable, "-m", "geoblock.cli"]


def _wall(cmd: list[str], env: dict[str, str]) -> float:
    t0 = time.perf_counter()
    subprocess.run(cmd, env=env, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    return time.perf_counter() - t0


def _points_csv(directory: Path) -> Path:
    """Ten ground points inside the Pleiades scene (its RPC localised at h = 100 m)."""
    code = textwrap.dedent(f"""
        import numpy as np, geoblock
        m = geoblock.open_model({str(RPC)!r})
        lon, lat = m.image_to_ground(np.array({ROWS!r}), np.array({COLS!r}), np.full(10, 100.0))[:2]
        print("id,lon,lat,h")
        for i in range(10):
            print(f"p{{i}},{{float(lon[i])!r}},{{float(lat[i])!r}},100.0")
    """)
    path = directory / "p10.csv"
    out = subprocess.run([sys.executable, "-c", code], env=_env(), check=True,
                         capture_output=True, text=True).stdout
    path.write_text(out)
    return path


def whole_commands(points: Path, runs: int) -> dict[str, list[float]]:
    """Interleaved runs of every command (one warm-up round first)."""
    gb = _geoblock()
    commands: dict[str, tuple[list[str], dict[str, str]]] = {
        "gdalinfo --version (peer)": (["gdalinfo", "--version"], _env()),
    }
    for version in VERSIONS:
        commands.update({
            f"geoblock --help{version}": ([*gb, "--help"], _env(version)),
            f"geoblock plugins{version}": ([*gb, "plugins"], _env(version)),
            f"geoblock project (10 points){version}": (
                [*gb, "project", str(RPC), str(points)], _env(version)),
        })
    times: dict[str, list[float]] = {name: [] for name in commands}
    for round_ in range(runs + 1):
        for name, (cmd, env) in commands.items():
            t = _wall(cmd, env)
            if round_:  # round 0 is the warm-up
                times[name].append(t)
    return dict(sorted(times.items(), key=lambda item: item[0].removesuffix(" (before)")))


_BREAKDOWN = """
import json, sys, time
import numpy as np
t = [time.perf_counter()]
import geoblock, geoblock.io
from geoblock.cli.main import build_cli
build_cli()
t.append(time.perf_counter())
if {kernels}:  # the compiled path: what a batch above the plugin's small-batch limit pays
    import numba
    t.append(time.perf_counter())
    from geoblock._array import all_finite
    all_finite(np.zeros(1), np.zeros(1))  # any cached kernel: numba builds its registries
else:
    t.append(t[-1])  # no numba import; the registries row follows
t.append(time.perf_counter())
model = geoblock.open_model({rpc!r})
t.append(time.perf_counter())
table = geoblock.read_points({points!r})
t.append(time.perf_counter())
model.ground_to_image(table["lon"], table["lat"], table["h"])
t.append(time.perf_counter())
model.ground_to_image(table["lon"], table["lat"], table["h"])
t.append(time.perf_counter())
steps = ["imports (geoblock, geoblock.io, the CLI)", "kernels: import numba",
         "kernels: numba's registries (first call of a cached kernel)",
         "model: open (rasterio, reader, plausibility check)", "read points",
         "first projection", "second projection"]
out = dict(zip(steps, (b - a for a, b in zip(t, t[1:]))))
out["total"] = t[-1] - t[0]
out.update({{"numba imported at the end": "numba" in sys.modules,
            "scipy.linalg imported": "scipy.linalg" in sys.modules}})
print(json.dumps(out))
"""

#: the two breakdowns: the command as it runs, and with numba's kernels forced
PATHS = {"as the command runs": False, "kernels forced": True}


def breakdown(points: Path, runs: int) -> dict[str, list[dict[str, float]]]:
    out: dict[str, list[dict[str, float]]] = {}
    for _ in range(runs):
        for path, kernels in PATHS.items():
            code = _BREAKDOWN.format(rpc=str(RPC), points=str(points), kernels=kernels)
            for version in VERSIONS:
                proc = subprocess.run([sys.executable, "-c", code], env=_env(version),
                                      check=True, capture_output=True, text=True)
                out.setdefault(f", {path}{version}", []).append(
                    json.loads(proc.stdout.strip().splitlines()[-1]))
    return out


def first_command(points: Path, runs: int) -> dict[str, list[float]]:
    """``geoblock project`` with an empty numba cache, then again with the cache it wrote."""
    cmd = [*_geoblock(), "project", str(RPC), str(points)]
    times: dict[str, list[float]] = {}
    for _ in range(runs):
        for version in VERSIONS:
            cache = tempfile.mkdtemp(prefix="geoblock-numba-cache-")
            try:
                env = _env(version, NUMBA_CACHE_DIR=cache)
                times.setdefault(f"empty kernel cache{version}", []).append(_wall(cmd, env))
                times.setdefault(f"same cache, second run{version}", []).append(
                    _wall(cmd, env))
            finally:
                shutil.rmtree(cache, ignore_errors=True)
    return times


def _row(name: str, values: list[float], peer: float | None = None) -> str:
    lo, med = min(values), statistics.median(values)
    ratio = f" | {med / peer:.1f}x |" if peer else " |"
    return f"| {name} | {lo:.3f} | {med:.3f}{ratio}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=7)
    parser.add_argument("--cold-runs", type=int, default=2)
    parser.add_argument("--before", type=Path, default=None,
                        help="another geoblock tree, run interleaved as '(before)'")
    args = parser.parse_args()
    if args.before is not None:  # its geoblock and its plugins, ahead of the installed ones
        tree = args.before.resolve()
        paths = [tree / "src", *sorted(tree.glob("plugins/*/src"))]
        VERSIONS[" (before)"] = os.pathsep.join(str(p) for p in paths)
    if not RPC.exists():
        sys.exit(f"skipped: {RPC} is absent")
    import geoblock

    print(f"geoblock from {Path(geoblock.__file__).parent}"
          f"{'; before: ' + str(VERSIONS[' (before)']) if args.before else ''}; "
          f"load: {os.getloadavg()[0]:.2f} {os.getloadavg()[1]:.2f} {os.getloadavg()[2]:.2f}; "
          f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}")
    with tempfile.TemporaryDirectory() as tmp:
        points = _points_csv(Path(tmp))

        times = whole_commands(points, args.runs)
        peer = statistics.median(times["gdalinfo --version (peer)"])
        print(f"\n### Whole commands ({args.runs} runs, interleaved, after a warm-up)\n")
        print("| command | min s | median s | median / gdalinfo |")
        print("| --- | --- | --- | --- |")
        for name, values in times.items():
            print(_row(name, values, peer))

        by_version = breakdown(points, args.runs)
        print(f"\n### Cold `project` breakdown, in-process ({args.runs} processes each)\n")
        print("| step | min s | median s |")
        print("| --- | --- | --- |")
        keys = [k for k, v in next(iter(by_version.values()))[0].items()
                if not isinstance(v, bool)]
        for key in keys:
            for version, rows in by_version.items():
                print(_row(key + version, [r[key] for r in rows]))
        for version, rows in by_version.items():
            flags = {k: v for k, v in rows[0].items() if isinstance(v, bool)}
            print(f"\n{version.strip() or '(now)'}: {flags}")

        first = first_command(points, args.cold_runs)
        print(f"\n### First command after an install ({args.cold_runs} runs, each with a new "
              "empty NUMBA_CACHE_DIR)\n")
        print("| `geoblock project` (10 points) | min s | median s |")
        print("| --- | --- | --- |")
        for name, values in first.items():
            print(_row(name, values))
    print(f"\nload after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
