"""Time and peak memory of the simulator: `measured_dem` alone and each preset's run.

Run: ``python benchmarks/bench_simulate.py [--quick] [--only NAME ...] [--keep DIR]``.

Every case runs in its own Python process, so that its peak resident set size (RSS, from
``os.wait4``'s rusage) is its own and not the benchmark's:

* ``measured_dem 2 m over S km``: a fractal truth of 4 m posts over an S km square in UTM (the
  aguilar2007-quickbird full truth is 5388 x 5494 posts of 4 m, ~21.5 km), then
  :func:`geoblock.simulate.terrain.measured_dem` at 2 m spacing and 0.31 m RMSEz (Aguilar et
  al.'s finest DEM). Printed: the truth's time, measured_dem's time, the process's RSS before
  measured_dem and its peak during it (Linux: the peak is reset through ``/proc/self/clear_refs``
  before the call; elsewhere the process's peak is shown), and the whole process's peak.
* ``<preset> <variant>``: :func:`geoblock.workflows.run_scenario` of the preset into a
  temporary folder (what ``geoblock simulate <preset> OUT --variant <variant>`` does), with
  its stage timings (``timings.json``).

``--quick``: the small variants and a 4 km measured_dem only (about a minute). The full run
(21.5 km measured_dem and the three full presets) takes about 3 minutes on 2 cores and needs
about 3 GB of free memory. Nothing is asserted; the figures go into benchmarks/README.md.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _measure import reset_peak, rss_kib  # benchmarks/_measure.py (run as a script)

PRESETS = ("aguilar2007-quickbird", "teo2010-spot5", "chen1993-spot1a")


# ------------------------------------------------------------------------------ workers
def _worker_measured_dem(size_km: float) -> dict:
    from geoblock.simulate.terrain import Grid, fractal_terrain, measured_dem

    t0 = time.perf_counter()
    truth = fractal_terrain(Grid.around(-2.4, 36.8, size_km * 1000.0, 4.0), (50.0, 850.0),
                            hurst=0.8, seed=1)
    t1 = time.perf_counter()
    before = rss_kib("VmRSS")
    reset = reset_peak()
    dem = measured_dem(truth, 2.0, 0.31, seed=2)
    t2 = time.perf_counter()
    return {"truth_shape": list(truth.shape), "dem_shape": list(dem.shape),
            "truth_s": t1 - t0, "measured_dem_s": t2 - t1,
            "rss_before_kib": before, "peak_during_kib": rss_kib("VmHWM") if reset else None}


def _worker_preset(name: str, variant: str, outdir: str) -> dict:
    from geoblock.simulate.scenario import preset
    from geoblock.workflows import run_scenario

    t0 = time.perf_counter()
    result = run_scenario(preset(name, variant), outdir)
    return {"wall_s": time.perf_counter() - t0, "timings": dict(result.timings),
            "truth_shape": list(result.truth.shape),
            "dems": {k: list(v.shape) for k, v in result.dems.items()}}


# ------------------------------------------------------------------------------ driver
def _run(args: list[str]) -> tuple[dict, float, float]:
    """Run this script as a worker; (its JSON answer, wall seconds, peak RSS MiB)."""
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, __file__, "--worker", *args],
                            stdout=subprocess.PIPE, text=True)
    out = proc.stdout.read() if proc.stdout else ""
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode != 0:
        raise SystemExit(f"worker {args} failed with exit code {proc.returncode}")
    peak_kib = usage.ru_maxrss / (1024 if sys.platform == "darwin" else 1)  # macOS: bytes
    return json.loads(out.strip().splitlines()[-1]), wall, peak_kib / 1024


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true",
                        help="small variants and a 4 km measured_dem only")
    parser.add_argument("--only", nargs="*", default=None,
                        help="cases to run: measured_dem and/or preset names")
    parser.add_argument("--keep", default=None,
                        help="write the presets' outputs under this folder (default: temporary)")
    parser.add_argument("--worker", nargs="*", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker is not None:
        kind, *rest = args.worker
        answer = (_worker_measured_dem(float(rest[0])) if kind == "measured_dem"
                  else _worker_preset(*rest))
        print(json.dumps(answer))
        return

    import numpy as np

    import geoblock

    print(f"geoblock {geoblock.__version__}, numpy {np.__version__}, {os.cpu_count()} CPUs")
    wanted = set(args.only) if args.only else {"measured_dem", *PRESETS}
    if "measured_dem" in wanted:
        size_km = 4.0 if args.quick else 21.5
        r, wall, peak = _run(["measured_dem", str(size_km)])
        during = (f"{r['peak_during_kib'] / 1024:7.0f} MiB" if r["peak_during_kib"]
                  else "    n/a    ")
        print(f"measured_dem 2 m over {size_km:g} km ({r['dem_shape'][0]} x {r['dem_shape'][1]} "
              f"posts from a {r['truth_shape'][0]} x {r['truth_shape'][1]} truth of 4 m): "
              f"{r['measured_dem_s']:6.1f} s, RSS {r['rss_before_kib'] / 1024:5.0f} MiB before, "
              f"peak during {during} (truth {r['truth_s']:.1f} s; process peak {peak:.0f} MiB, "
              f"{wall:.1f} s)")
    variant = "small" if args.quick else "full"
    with tempfile.TemporaryDirectory(prefix="bench_simulate_") as tmp:
        root = Path(args.keep) if args.keep else Path(tmp)
        for name in PRESETS:
            if name not in wanted:
                continue
            r, wall, peak = _run(["preset", name, variant, str(root / f"{name}-{variant}")])
            stages = ", ".join(f"{k} {v:.1f}" for k, v in r["timings"].items() if k != "total")
            print(f"{name} {variant}: {wall:6.1f} s wall ({r['wall_s']:.1f} s in run_scenario), "
                  f"peak RSS {peak:6.0f} MiB; truth {r['truth_shape'][0]} x "
                  f"{r['truth_shape'][1]}; stages (s): {stages}")


if __name__ == "__main__":
    main()
