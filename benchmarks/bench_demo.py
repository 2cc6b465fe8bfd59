"""Time and peak memory of the whole ``geoblock demo`` command.

Run: ``python benchmarks/bench_demo.py [--repeat N] [--size small|tiny] [--keep DIR]``.

Each run is the console command itself, ``geoblock demo OUTDIR --variant SIZE`` (the script
beside this Python, else ``python -m geoblock.cli``), in its own process with a fresh
OUTDIR: the interpreter's start-up, the imports and numba's cache loading are in the time,
as a user sees them. Printed per run: the wall time and the child's peak resident set size
(``os.wait4``'s rusage, ``ru_maxrss``), and the demo's own stage times (``results.json``);
then the best wall time and the largest peak of the runs. The machine's load average is
printed first: on a shared machine the times vary from run to run, the best is the
least disturbed. Nothing is asserted; the figures go into benchmarks/README.md.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def _command(outdir: Path, size: str) -> list[str]:
    script = Path(sys.executable).with_name("geoblock")
    head = [str(script)] if script.is_file() else [sys.executable, "-m", "geoblock.cli"]
    return [*head, "demo", str(outdir), "--variant", size]


def run_once(outdir: Path, size: str) -> tuple[float, float, dict]:
    """One ``geoblock demo``: (wall seconds, peak RSS MiB of the child, its results.json)."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(_command(outdir, size), stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True)
    stderr = proc.stderr.read() if proc.stderr else ""  # to its end; not reaped yet
    _, status, usage = os.wait4(proc.pid, 0)  # reaps it, with its own rusage
    proc.returncode = os.waitstatus_to_exitcode(status)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise SystemExit(f"geoblock demo failed with exit code {proc.returncode}:\n{stderr}")
    peak_kib = usage.ru_maxrss / (1024 if sys.platform == "darwin" else 1)  # macOS: bytes
    return wall, peak_kib / 1024, json.loads((outdir / "results.json").read_text())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=3, help="runs (default 3)")
    parser.add_argument("--size", choices=("small", "tiny"), default="small")
    parser.add_argument("--keep", type=Path, default=None,
                        help="keep the last run's OUTDIR here (replaced)")
    args = parser.parse_args()
    load = os.getloadavg() if hasattr(os, "getloadavg") else (float("nan"),) * 3
    print(f"geoblock demo --variant {args.size}: {args.repeat} runs, {os.cpu_count()} CPUs, "
          f"load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}")
    walls, peaks = [], []
    with tempfile.TemporaryDirectory(prefix="bench-demo-") as tmp:
        for k in range(args.repeat):
            outdir = Path(tmp) / f"run{k}"  # fresh: absent, as on a first run
            wall, peak, results = run_once(outdir, args.size)
            walls.append(wall)
            peaks.append(peak)
            stages = ", ".join(f"{name} {t:.1f}" for name, t in results["timings"].items())
            print(f"run {k + 1}: {wall:6.1f} s wall, peak RSS {peak:6.0f} MiB; the demo's "
                  f"stages (s): {stages}; in-process total {results['seconds']:.1f} s")
            if args.keep is not None and k == args.repeat - 1:
                shutil.rmtree(args.keep, ignore_errors=True)
                shutil.copytree(outdir, args.keep)
            shutil.rmtree(outdir)
    print(f"best {min(walls):.1f} s wall (median {sorted(walls)[len(walls) // 2]:.1f} s), "
          f"peak RSS {max(peaks):.0f} MiB")


if __name__ == "__main__":
    main()
