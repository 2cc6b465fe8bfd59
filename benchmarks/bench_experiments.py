"""Time and peak memory of ``geoblock experiment``: the papers' experiments as whole commands.

Run: ``python benchmarks/bench_experiments.py [--only NAME ...] [--repeat N] [--full]
[--keep DIR]``.

Each case is one ``geoblock experiment NAME OUTDIR`` process (``python -m geoblock.cli``,
start-up included), timed by its wall clock; its peak resident set size comes from
``os.wait4``'s rusage, so it is the command's own. The command's progress lines (stderr) give
the time of each seed's simulation and adjustments, printed under the case.

Cases: ``teo2010`` and ``chen2008`` (small variant, the default number of seeds; each in its
own process, so chen2008 does not reuse teo2010's simulations as it does in one Python
process). ``--only`` picks cases by experiment name (any of ``geoblock experiment``'s, e.g.
``chen1993`` or ``aguilar2007``). ``--full`` adds ``teo2010 --variant full --repeats 1`` (one seed of
the papers' image sizes: about 20 s and 1.1 GB). The first run of each case also warms
numba's on-disk kernel cache; ``--repeat N`` runs each case N times and reports the best and
the median. ``--blas-threads N`` sets ``OPENBLAS_NUM_THREADS`` (and ``OMP_NUM_THREADS``) in
the commands: on a machine whose cores are busy with other jobs, OpenBLAS's threads spin on
the experiments' many small matrix operations (RPC fits, the adjustments' cofactors) and one
thread is much faster. Nothing is asserted; the figures go into benchmarks/README.md.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

CASES = ("teo2010", "chen2008")


def run_case(args: list[str], outdir: Path,
             blas_threads: int | None = None) -> tuple[float, float, list[str]]:
    """Run ``geoblock experiment ARGS OUTDIR`` (with ``OPENBLAS_NUM_THREADS`` and
    ``OMP_NUM_THREADS`` set to ``blas_threads`` if given); its wall time (s), peak RSS (MiB)
    and progress lines."""
    command = [sys.executable, "-m", "geoblock.cli", "experiment", args[0], str(outdir),
               *args[1:], "--overwrite"]  # every repeat writes the same OUTDIR
    env = dict(os.environ)
    if blas_threads is not None:
        env.update(OPENBLAS_NUM_THREADS=str(blas_threads), OMP_NUM_THREADS=str(blas_threads))
    t0 = time.perf_counter()
    proc = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            text=True, env=env)
    assert proc.stderr is not None
    err = proc.stderr.read()
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit(f"{' '.join(command)} failed:\n{err}")
    peak_mib = usage.ru_maxrss / (2**20 if sys.platform == "darwin" else 1024)
    return wall, peak_mib, [line for line in err.splitlines() if "seed" in line]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="*", default=None, metavar="NAME",
                        help=f"experiments to run (default: {' '.join(CASES)})")
    parser.add_argument("--repeat", type=int, default=1, metavar="N",
                        help="runs of each case (default 1)")
    parser.add_argument("--full", action="store_true",
                        help="also one seed of teo2010's full variant")
    parser.add_argument("--blas-threads", type=int, default=None, metavar="N",
                        help="OPENBLAS_NUM_THREADS and OMP_NUM_THREADS of the commands "
                        "(default: inherited)")
    parser.add_argument("--keep", default=None, metavar="DIR",
                        help="write the reports under DIR (default: a temporary folder)")
    args = parser.parse_args()
    cases = [[name] for name in (args.only or CASES)]
    if args.full:
        cases.append(["teo2010", "--variant", "full", "--repeats", "1"])
    root = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="bench-exp-"))
    threads = "inherited" if args.blas_threads is None else str(args.blas_threads)
    print(f"python {sys.version.split()[0]}, {os.cpu_count()} CPUs, BLAS threads {threads}, "
          f"load average {os.getloadavg()[0]:.1f}, outputs in {root}")
    print(f"{'case':42s} {'best':>8s} {'median':>8s} {'peak RSS':>10s}")
    for case in cases:
        label = "geoblock experiment " + " ".join(case)
        out = root / "-".join(c.lstrip("-") for c in case)
        walls, peaks, lines = [], [], []
        for _ in range(max(1, args.repeat)):
            wall, peak, lines = run_case(case, out, args.blas_threads)
            walls.append(wall)
            peaks.append(peak)
        print(f"{label:42s} {min(walls):7.1f}s {statistics.median(walls):7.1f}s "
              f"{max(peaks):7.0f} MiB")
        for line in lines:
            print(f"    {line.strip()}")


if __name__ == "__main__":
    main()
