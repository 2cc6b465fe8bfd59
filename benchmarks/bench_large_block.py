"""Large blocks: ``adjust`` of 10^2-10^4 simulated SPOT-like images with 10^5-2 x 10^6 TPs.

Run: ``python benchmarks/bench_large_block.py [--quick] [--cases N[xTPS] ...] [--cache DIR]
[--timeout S] [--profile] [--method dg]``.

**Blocks**: :func:`geoblock.simulate.large.large_block` of the ``continental-spot-1000``
preset scaled to N images (``large_preset(images=N)``: 20 x 50 strips x scenes at 1000;
``continental-spot-10000``, 100 x 100, for N = 10^4): SPOT-like 20 m scenes of 60 x 60 km
with realistic on-board errors (30 m RMSE), 25 % side and 10 % along-track overlap, a coarse
DEM, GCPs, ICPs and ICTPs, TPs scaled with N: 1000 per image up to 10^3 images (10^6 TPs),
then ``10^6 (N / 1000) ** log10(2)`` (2 x 10^6 at 10^4 images). Each block is built once in
a process of its own (*build s*, its peak RSS) and cached on disk as a pickle of the
:class:`geoblock.adjust.Block` and the ICPs' truth (``--cache``, default
``$TMPDIR/geoblock_bench_large``; never in the repository).

**adjust**: every case runs ``adjust(block)`` (the defaults: DEM control as observation,
floating TP priors, statistics and covariances as the engine computes them) with the
``dg`` method (12 parameters per image) in a fresh process: *load s* (unpickling), a warm-up
on a 2 x 2-image block (the numba kernels' cache), then the timed call: *adjust s* (wall),
*iterations*, *s/iteration* (the iterations' mean, from the engine's per-iteration progress
lines: Jacobians, normal equations, reduction, solve), *set-up s* (from the call to the first
iteration's end minus one iteration) and *after s* (from the last iteration to the result:
statistics, covariances), *peak GB* (the process's resident peak during the call, reset
before it through ``/proc/self/clear_refs``), the *solver* the result states (``result.solver``
or the report's, when the engine says), *ICP RMSE* (2-D, metres, the adjusted models at the
ICP measurements, ``result.stats("icp")``) against the on-board models' (*on-board m*).
A case that runs past ``--timeout`` (default 1800 s) is killed and reported so.

The machine's load (``uptime``) is printed before and after each case: the 2 cores are
shared. ``PYTHONDONTWRITEBYTECODE`` is removed from the workers' environment. ``--profile``:
cProfile of the timed call, the top 25 functions by own time on standard error.
``--quick``: 100 and 300 images.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import pickle
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _measure import reset_peak, rss_kib  # benchmarks/_measure.py (run as a script)

FULL = [100, 300, 1000, 3000, 10000]
QUICK = [100, 300]


def default_tps(images: int) -> int:
    """TPs of a case: 1000 per image up to 10^3 images, then 10^6 (N/1000)^log10(2)."""
    if images <= 1000:
        return 1000 * images
    return int(round(1e6 * (images / 1000) ** math.log10(2), -3))


def _spec(images: int, tps: int):
    from geoblock.simulate.large import large_preset

    if images == 10000:
        return large_preset("continental-spot-10000", tps=tps)
    if images == 1000:
        return large_preset("continental-spot-1000", tps=tps)
    return large_preset("continental-spot-1000", images=images, tps=tps)


def _cache_path(cache: str, images: int, tps: int, method: str) -> Path:
    """The cached block of a case, named by a hash of its spec and of the simulator's source
    (a changed spec or simulator is a new file)."""
    import hashlib

    import geoblock.simulate.large as large
    import geoblock.simulate.sensors as sensors

    text = repr(_spec(images, tps).replace(method=method)) + "".join(
        Path(m.__file__).read_text() for m in (large, sensors) if m.__file__)
    key = hashlib.sha256(text.encode()).hexdigest()
    return Path(cache) / f"large_{images}_{tps}_{method}_{key[:12]}.pkl"


# ------------------------------------------------------------------------------ workers
def _worker_build(images: int, tps: int, cache: str, method: str) -> dict:
    import numpy as np

    from geoblock.simulate.large import large_block

    spec = _spec(images, tps).replace(method=method)
    t0 = time.perf_counter()
    lb = large_block(spec, progress=lambda m: print(
        f"{m} [RSS {rss_kib('VmRSS') / 2**20:.2f} GB, peak {rss_kib('VmHWM') / 2**20:.2f}]",
        file=sys.stderr, flush=True))
    t_build = time.perf_counter() - t0
    block = lb.block()
    print(f"block: RSS {rss_kib('VmRSS') / 2**20:.2f} GB, peak {rss_kib('VmHWM') / 2**20:.2f}",
          file=sys.stderr, flush=True)
    g = lb.points.ground
    icp = g.kind == "icp"
    # the on-board models' ICP error: each ICP measurement located at the true height
    m = lb.points.image
    index = {p: i for i, p in enumerate(g.id.tolist())}
    sel = np.flatnonzero(m.kind == "icp")
    k = np.array([index[p] for p in m.id[sel].tolist()], dtype=np.intp)
    d2 = []
    import pyproj

    geod = pyproj.Geod(ellps="WGS84")
    for image in np.unique(m.image[sel]).tolist():
        mine = m.image[sel] == image
        got = lb.sensors[image].onboard_model.backproject(m.row[sel][mine], m.col[sel][mine],
                                                          g.h_true[k[mine]])
        _, _, d = geod.inv(got.lon, got.lat, g.lon_true[k[mine]], g.lat_true[k[mine]])
        d2.append(np.asarray(d) ** 2)
    onboard_rmse = float(np.sqrt(np.mean(np.concatenate(d2)))) if d2 else float("nan")
    path = _cache_path(cache, images, tps, method)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    with open(tmp, "wb") as f:
        pickle.dump({"block": block, "spec": spec, "timings": lb.timings,
                     "onboard_icp_rmse": onboard_rmse, "icps": int(icp.sum()),
                     "measurements": len(m), "points": len(g)}, f,
                    protocol=pickle.HIGHEST_PROTOCOL)
    tmp.replace(path)
    return {"build_s": t_build, "timings": lb.timings, "images": spec.images,
            "strips": spec.strips, "scenes": spec.scenes, "measurements": len(m),
            "points": len(g), "peak_kib": rss_kib("VmHWM"), "bytes": path.stat().st_size}


def _tiny_block():
    from geoblock.simulate.large import LargeBlockSpec, large_block

    return large_block(LargeBlockSpec(name="warm", strips=2, scenes=2, tps=500, gcps=8,
                                      icps=4, relief=(0.0, 800.0), seed=1)).block()


def _solver_of(result) -> str:
    for name in ("solver", "solver_used", "solver_name", "solver_report"):
        value = getattr(result, name, None)
        if value:
            return str(value)
    for note in getattr(result, "notes", []) or []:
        if "solver" in str(note).lower() or "cholesky" in str(note).lower() \
                or "conjugate" in str(note).lower():
            return str(note)[:80]
    return "n/a"


def _worker_adjust(images: int, tps: int, cache: str, method: str, profile: bool) -> dict:
    from geoblock.adjust import adjust

    t0 = time.perf_counter()
    with open(_cache_path(cache, images, tps, method), "rb") as f:
        data = pickle.load(f)
    t_load = time.perf_counter() - t0
    block = data["block"]
    adjust(_tiny_block())  # warm-up: numba kernels from their on-disk cache
    stamps: list[float] = []

    def progress(message: str) -> None:
        if ": iteration" in message:
            stamps.append(time.perf_counter())
        print(f"{time.strftime('%H:%M:%S')} {message}", file=sys.stderr, flush=True)

    reset = reset_peak()
    prof = None
    if profile:
        import cProfile

        prof = cProfile.Profile()
        prof.enable()
    t0 = time.perf_counter()
    result = adjust(block, progress=progress)
    t_end = time.perf_counter()
    if prof is not None:
        import pstats

        prof.disable()
        pstats.Stats(prof, stream=sys.stderr).sort_stats("tottime").print_stats(25)
    peak = rss_kib("VmHWM") if reset else None
    wall = t_end - t0
    its = [b - a for a, b in zip(stamps, stamps[1:], strict=False)]
    per_it = (sum(its) / len(its)) if its else (wall / max(result.iterations, 1))
    setup = (stamps[0] - t0 - per_it) if stamps else float("nan")
    after = (t_end - stamps[-1]) if stamps else float("nan")
    try:
        icp = result.stats("icp")
        icp_rmse, icp_n = float(icp.rmse_2d), int(icp.n)
    except Exception:  # noqa: BLE001 - a statistic the engine does not give: say n/a
        icp_rmse, icp_n = float("nan"), 0
    return {"load_s": t_load, "adjust_s": wall, "iterations": int(result.iterations),
            "converged": bool(result.converged), "per_iteration_s": per_it,
            "setup_s": setup, "after_s": after, "peak_kib": peak, "solver": _solver_of(result),
            "icp_rmse": icp_rmse, "icp_n": icp_n, "onboard_icp_rmse": data["onboard_icp_rmse"],
            "sigma0": float(result.sigma0), "measurements": data["measurements"],
            "points": data["points"]}


# ------------------------------------------------------------------------------ driver
def _env() -> dict:
    env = dict(os.environ)
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    return env


def _run(args: list[str], timeout: float) -> tuple[dict | None, float, float, str]:
    """Run this script as a worker: (its JSON answer or None, wall s, peak RSS MiB, error)."""
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, __file__, "--worker", *args],
                            stdout=subprocess.PIPE, text=True, env=_env(),
                            start_new_session=True)
    try:
        out, _ = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.communicate()
        return None, time.perf_counter() - t0, float("nan"), f"timeout after {timeout:.0f} s"
    wall = time.perf_counter() - t0
    import resource

    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        return None, wall, usage.ru_maxrss / 1024, f"exit code {proc.returncode}"
    return json.loads(out.strip().splitlines()[-1]), wall, usage.ru_maxrss / 1024, ""


def _uptime() -> str:
    try:
        return subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    except OSError:
        return "uptime: n/a"


def _gb(kib) -> str:
    return f"{kib / 2**20:.2f}" if kib else "n/a"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="100 and 300 images only")
    parser.add_argument("--cases", nargs="*", default=None,
                        help="N or NxTPS, e.g. 1000 or 300x30000 (default TPs: see the doc)")
    parser.add_argument("--cache", default=os.path.join(tempfile.gettempdir(),
                                                        "geoblock_bench_large"),
                        help="folder of the cached blocks (outside the repository)")
    parser.add_argument("--timeout", type=float, default=1800.0,
                        help="seconds allowed to each build and each adjust")
    parser.add_argument("--method", default="dg", help="adjustment method (default dg)")
    parser.add_argument("--rebuild", action="store_true", help="ignore cached blocks")
    parser.add_argument("--build-only", action="store_true",
                        help="build and cache the blocks, do not adjust")
    parser.add_argument("--profile", action="store_true",
                        help="cProfile the timed adjust() (stderr)")
    parser.add_argument("--worker", nargs="*", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker is not None:
        kind, images, tps = args.worker
        if kind == "build":
            answer = _worker_build(int(images), int(tps), args.cache, args.method)
        else:
            answer = _worker_adjust(int(images), int(tps), args.cache, args.method,
                                    args.profile)
        print(json.dumps(answer))
        return

    import numpy as np
    import scipy

    import geoblock

    print(f"geoblock {geoblock.__version__}, numpy {np.__version__}, scipy {scipy.__version__}, "
          f"{os.cpu_count()} CPUs; {time.strftime('%Y-%m-%d %H:%M:%S %Z')}")
    head = subprocess.run(["git", "-C", str(Path(__file__).parent), "log", "--oneline", "-1"],
                          capture_output=True, text=True).stdout.strip()
    print(f"commit: {head}")
    print(f"load: {_uptime()}")
    if args.cases:
        cases = [(int(c.split("x")[0]), int(c.split("x")[1]) if "x" in c else
                  default_tps(int(c))) for c in args.cases]
    else:
        cases = [(n, default_tps(n)) for n in (QUICK if args.quick else FULL)]
    rows = []
    print("| images | TPs | measurements | build s (GB) | adjust s | iterations | s/iteration | "
          "set-up s | after s | peak GB | solver | ICP RMSE m (on-board) |", flush=True)
    print("|" + "---:|" * 11 + "---|", flush=True)
    for images, tps in cases:
        path = _cache_path(args.cache, images, tps, args.method)
        common = ["--cache", args.cache, "--method", args.method]
        build = "cached"
        if args.rebuild or not path.exists():
            b, _, b_peak, err = _run(["build", str(images), str(tps), *common], args.timeout)
            if b is None:
                print(f"| {images} | {tps} | build failed: {err} |", flush=True)
                continue
            build = f"{b['build_s']:.0f} ({_gb(b['peak_kib'])})"
            print(f"  built {images} images ({b['strips']} x {b['scenes']}), "
                  f"{b['measurements']} measurements in {b['build_s']:.1f} s "
                  f"{ {k: round(v, 1) for k, v in b['timings'].items()} }, peak "
                  f"{_gb(b['peak_kib'])} GB, cache {b['bytes'] / 2**30:.2f} GiB", flush=True)
        if args.build_only:
            continue
        before = _uptime()
        a, wall, _, err = _run(["adjust", str(images), str(tps), *common]
                               + (["--profile"] if args.profile else []), args.timeout)
        after = _uptime()
        if a is None:
            print(f"| {images} | {tps} | | {build} | {err} | | | | | | | |  load {before}",
                  flush=True)
            continue
        conv = "" if a["converged"] else " (not converged)"
        row = (f"| {images} | {tps} | {a['measurements']} | {build} | **{a['adjust_s']:.1f}** | "
               f"{a['iterations']}{conv} | {a['per_iteration_s']:.2f} | {a['setup_s']:.1f} | "
               f"{a['after_s']:.1f} | {_gb(a['peak_kib'])} | {a['solver']} | "
               f"{a['icp_rmse']:.2f} ({a['onboard_icp_rmse']:.1f}) |")
        print(row, flush=True)
        print(f"  load before: {before}\n  load after:  {after}; load {a['load_s']:.1f} s, "
              f"sigma0 {a['sigma0']:.3f}, {a['icp_n']} ICP measurements, process wall "
              f"{wall:.0f} s", flush=True)
        rows.append((images, a))
    if len(rows) >= 2:
        n = np.array([r[0] for r in rows], float)
        t = np.array([r[1]["per_iteration_s"] for r in rows], float)
        slope = np.polyfit(np.log(n), np.log(t), 1)[0]
        print(f"\ntime per iteration ~ images^{slope:.2f} (log-log fit over "
              f"{', '.join(str(int(v)) for v in n)} images)")


if __name__ == "__main__":
    main()
