"""The timing and memory helpers shared by the benchmarks: best-of-N wall time after a
warm-up call and tracemalloc's peak of one call (numpy's allocations; not numba's or GDAL's)
for the point-throughput benchmarks (bench_core, bench_linescan, bench_spot); the process's
resident memory and its peak, resettable, for the whole-job ones (bench_simulate,
bench_adjust)."""

from __future__ import annotations

import time
import tracemalloc
from pathlib import Path


def timed(func) -> float:
    """Wall time of one call, seconds."""
    t0 = time.perf_counter()
    func()
    return time.perf_counter() - t0


def measure(label: str, func, n_points: int, repeat: int = 3) -> float:
    """Print one line: best-of-``repeat`` time, throughput and peak memory; return the best."""
    func()  # warm up
    best = min(timed(func) for _ in range(repeat))
    tracemalloc.start()
    func()
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    print(
        f"{label:58s} {best * 1e3:9.2f} ms  {n_points / best / 1e6:8.3f} Mpt/s  "
        f"peak {peak / 2**20:7.1f} MiB ({peak / max(n_points, 1):6.0f} B/pt)"
    )
    return best


def rss_kib(field: str) -> int | None:
    """A ``/proc/self/status`` memory field in KiB (``VmRSS``, ``VmHWM``); None elsewhere."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith(field + ":"):
                return int(line.split()[1])
    except OSError:
        return None
    return None


def reset_peak() -> bool:
    """Reset the process's peak RSS (``VmHWM``) where Linux allows it; False otherwise."""
    try:
        Path("/proc/self/clear_refs").write_text("5")
        return True
    except OSError:
        return False
