"""``geoblock match BLOCK.toml`` on every scheduler: times, peak memory, and the CSVs' sha256.

Run: ``python benchmarks/bench_match_scale.py [BLOCK.toml] [--keep DIR] [--skip-cluster]``.

Without BLOCK.toml, the simulated block of tests/match (three 300 x 300 px SPOT-5-like views
of one ridged scene) is built in a temporary directory; ``geoblock simulate
continental-spot-100 DIR`` writes the ~100-image rendered block (``DIR/block.toml``).

Per scheduler, the command as a user runs it, in its own process:

* ``--pairs-only``: the pair graph alone (footprints, candidates, selection);
* ``--scheduler threads``, ``--scheduler processes``: the whole matching; wall time and the
  peak RSS of the command's process tree (``os.wait4``: the largest process);
* ``--scheduler tcp://...``: a ``distributed.LocalCluster(n_workers=2, threads_per_worker=1,
  processes=True)`` started by this script (its start-up not timed); the command's peak RSS
  and each worker's (``resource.getrusage`` on the workers);

then the sha256 of each CSV: they must be equal. Nothing is asserted; the figures go into
benchmarks/README.md.
"""

from __future__ import annotations

import argparse
import hashlib
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
GEOBLOCK = [str(Path(sys.executable).parent / "geoblock")]


def _command(args: list[str]) -> tuple[float, float, str]:
    """Run ``geoblock ARGS``: wall seconds, peak RSS (MiB) of its tree (the largest process:
    Linux propagates a reaped child's peak to its parent), standard error then output."""
    with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err:
        t0 = time.perf_counter()
        proc = subprocess.Popen([*GEOBLOCK, *args], stdout=out, stderr=err)
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - t0
        proc.returncode = os.waitstatus_to_exitcode(status)
        out.seek(0)
        err.seek(0)
        text = err.read() + out.read()
    if proc.returncode:
        sys.exit(f"geoblock {' '.join(args)} failed:\n{text[-3000:]}")
    return wall, usage.ru_maxrss / 1024, text


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _triplet(directory: Path) -> Path:
    """Build tests/match's block in a child process (this one stays small: a forked
    command's peak RSS starts from its parent's)."""
    subprocess.run([sys.executable, __file__, "--build-triplet", str(directory)], check=True)
    return directory / "block.toml"


def _build_triplet(directory: Path) -> None:
    sys.path.insert(0, str(HERE.parent / "tests" / "match"))
    from conftest import scenario  # tests/match's simulated block

    from geoblock.simulate.scenario import scenario_from_dict
    from geoblock.workflows import run_scenario

    run_scenario(scenario_from_dict(scenario()), directory)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("block", nargs="?", help="block file (default: tests/match's block)")
    parser.add_argument("--keep", help="directory for the CSVs (default: temporary)")
    parser.add_argument("--skip-cluster", action="store_true")
    parser.add_argument("--build-triplet", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.build_triplet:
        _build_triplet(Path(args.build_triplet))
        return
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(args.keep or tmp)
        out.mkdir(parents=True, exist_ok=True)
        block = Path(args.block) if args.block else _triplet(Path(tmp) / "triplet")
        print(f"block: {block}")
        wall, rss, text = _command(["match", str(block), "--pairs-only"])
        print(f"{'pairs only':24s} {wall:8.2f} s  peak RSS {rss:7.0f} MiB")
        print("  " + text.splitlines()[0])
        rows = []
        for scheduler in ("threads", "processes"):
            csv = out / f"tp-{scheduler}.csv"
            wall, rss, text = _command(["match", str(block), "-o", str(csv), "--overwrite",
                                        "--scheduler", scheduler])
            rows.append((scheduler, wall, rss, csv))
            print(f"{scheduler:24s} {wall:8.2f} s  peak RSS {rss:7.0f} MiB  "
                  f"{_sha256(csv)[:16]}  {text.strip().splitlines()[-1][:90]}", flush=True)
        if not args.skip_cluster:
            import resource

            from distributed import Client, LocalCluster

            t0 = time.perf_counter()
            with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                              dashboard_address=None) as cluster, Client(cluster) as client:
                up = time.perf_counter() - t0
                csv = out / "tp-cluster.csv"
                wall, rss, text = _command(["match", str(block), "-o", str(csv), "--overwrite",
                                            "--scheduler", cluster.scheduler_address])
                workers = client.run(
                    lambda: resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)
            rows.append(("LocalCluster(2)", wall, rss, csv))
            print(f"{'LocalCluster(2 workers)':24s} {wall:8.2f} s  peak RSS {rss:7.0f} MiB "
                  f"(workers {', '.join(f'{v:.0f}' for v in workers.values())} MiB; cluster "
                  f"start-up {up:.1f} s, not timed)  {_sha256(csv)[:16]}")
        digests = {_sha256(r[3]) for r in rows}
        lines = sum(1 for _ in rows[0][3].open()) - 1
        print(f"{lines} measurements; sha256 {'identical' if len(digests) == 1 else 'DIFFER'}: "
              + ", ".join(sorted(digests)))


if __name__ == "__main__":
    main()
