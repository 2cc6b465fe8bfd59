"""The block engine with a many-parameter set whose knots a measurement touches four per axis
(issue 27): time and peak memory of ``adjust`` on a simulated 3-strip SPOT-5 block, with and
without the set, and its scaling with the number of knots and of tie points.

Run: ``python benchmarks/bench_jitter.py [--quick] [--cases CASE ...] [--src DIR]
[--cache DIR]``.

**Block**: the ``teo2010-spot5`` preset, full size (three SPOT-5 supermode strips of
24000 x 24000 px at 2.5 m, 10-15 % overlaps, ridged terrain 0-3800 m, a 40 m DEM with
RMSEz 5 m, 9 GCPs and 20 ICPs per strip, the simulator's realistic on-board errors),
simulated by :mod:`geoblock.simulate.scene` with
``N/2`` tie points in each of the two overlaps (``N`` = 10^4 by default: 2 10^4 TP
measurements), no ICTPs, no rendering. Simulated once per ``N`` and pickled (``--cache``).
The images are the on-board linescan models (``LinescanModel``).

**Parameter sets** (case ``SET@SPACING/N``):

* ``dg``: each strip's ``with_parameter_set("dg")`` (Teo et al.'s direct-georeferencing set,
  9 adjustable parameters per image): the block without the jitter set;
* ``jitter@S``: ``with_parameter_set("jitter", knot_lines=S)``: the dg set plus roll, pitch
  and yaw cubic B-splines in time with knots every ``S`` lines and their amplitude and
  smoothness prior (``9 + 3 (ceil(24000 / S) + 3)``-ish parameters per image; a measurement
  touches 9 + 12); ``jitter@50`` takes the engine's sparse path (K above ``DENSE_LIMIT``);
* ``affine``: each strip's on-board model wrapped in an order-1 ``ImageCorrection``
  (6 free parameters per image): the block without the many-parameter set;
* ``spline@S``: the same affine correction plus three cubic B-splines along the rows with
  knots every ``S`` lines (a row shift, a column shift and a column scale about the centre
  column, as pitch, roll and yaw jitter move a pushbroom's pixels; a-priori sigma 1 px per
  coefficient): ``6 + 3 (ceil(23999 / S) + 3)`` parameters per image (735 at ``S = 100``),
  of which a measurement touches 18: a test model (``tests/adjust/row_spline_model.py``)
  that runs on engines that predate the linescan models' jitter set. This is the test model of
  ``tests/adjust/row_spline_model.py`` (the linescan models' own jitter set, issue 27 item 2,
  had not landed when this was written): for the engine it is the same problem, a parameter
  set whose partials are nonzero in four knots per axis.

**Timed**: ``adjust(block)`` with its defaults (DEM control as observations, floating TP
priors, statistics and the (K, K) posterior covariance included), in a process of its own
after a warm-up adjustment of the same block with 100 TPs (which loads the numba kernels);
*peak MiB* is the process's peak resident memory during the call (``VmHWM`` reset through
``/proc/self/clear_refs`` before it). ``--src DIR`` runs the workers on another checkout's
``src`` (e.g. a worktree of the revision before the engine change) to compare engines.
"""

from __future__ import annotations

import argparse
import json
import os
import pickle
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _measure import reset_peak, rss_kib  # benchmarks/_measure.py (run as a script)

ROOT = Path(__file__).resolve().parents[1]
#: case -> (set, knot spacing in lines or 0, tie points)
FULL = ["dg@0/10000", "jitter@100/10000",
        "jitter@800/10000", "jitter@400/10000", "jitter@200/10000", "jitter@50/10000",
        "jitter@100/2500", "jitter@100/5000", "jitter@100/20000",
        "dg@0/2500", "dg@0/5000", "dg@0/20000"]
QUICK = ["dg@0/2500", "jitter@100/2500"]


def _parse(case: str) -> tuple[str, float, int]:
    name, rest = case.split("@")
    spacing, n = rest.split("/")
    return name, float(spacing), int(n)


# ------------------------------------------------------------------------------ block
def simulate(n_tp: int, path: Path) -> None:
    """Simulate the block with ``n_tp`` tie points and pickle it to ``path``."""
    from geoblock.simulate.scenario import preset_dict, scenario_from_dict
    from geoblock.simulate.scene import (
        scene_dem,
        scene_grid,
        scene_points,
        scene_sensors,
        true_terrain,
    )

    data = preset_dict("teo2010-spot5", "full")
    data["points"].update(tp=[n_tp // 2, n_tp // 2], ictp=[0, 0])
    data["onboard_errors"] = "realistic"
    data["render"]["enabled"] = False
    scenario = scenario_from_dict(data)
    sensors = scene_sensors(scenario)
    truth = true_terrain(scenario, scene_grid(scenario, sensors))
    dem = scene_dem(scenario, truth, 0).to_dem()
    points = scene_points(scenario, sensors, truth.to_dem())
    ground, meas = points.observations()
    meas = meas.resolve_kinds(ground)
    onboard = {i: s.onboard_model for i, s in sensors.items()}
    path.write_bytes(pickle.dumps({"models": onboard, "ground": ground, "measurements": meas,
                                   "dem": dem}))


def _row_spline():
    import importlib.util

    spec = importlib.util.spec_from_file_location(
        "row_spline_model", ROOT / "tests" / "adjust" / "row_spline_model.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.RowSplineCorrection


def _block(data: dict, name: str, spacing: float, keep_tps: int | None = None):
    import numpy as np

    from geoblock.adjust import Block
    from geoblock.models.corrections import ImageCorrection

    meas = data["measurements"]
    if keep_tps is not None:
        tp_ids = np.unique(meas.id[meas.kind == "tp"])[:keep_tps]
        meas = meas.subset((meas.kind != "tp") | np.isin(meas.id, tp_ids))
    if name == "affine":
        models = {i: ImageCorrection(m, order=1) for i, m in data["models"].items()}
    elif name == "dg":
        models = {i: m.with_parameter_set("dg") for i, m in data["models"].items()}
    elif name == "jitter":
        models = {i: m.with_parameter_set("jitter", knot_lines=int(spacing))
                  for i, m in data["models"].items()}
    else:
        spline = _row_spline()
        models = {i: spline(m, spacing) for i, m in data["models"].items()}
    return Block(models, meas, data["ground"], data["dem"], 5.0)


# ------------------------------------------------------------------------------ worker
def worker(case: str, cache: Path) -> dict:
    import numpy as np

    from geoblock.adjust import adjust

    name, spacing, n_tp = _parse(case)
    data = pickle.loads((cache / f"block_{n_tp}.pkl").read_bytes())
    adjust(_block(data, name, spacing, keep_tps=100))  # warm-up: loads the numba kernels
    block = _block(data, name, spacing)
    reset_ok = reset_peak()
    t0 = time.perf_counter()
    result = adjust(block)
    wall = time.perf_counter() - t0
    peak = rss_kib("VmHWM")
    k = result.covariance.shape[0]
    icp = np.char.lower(result.check.kind.astype(str)) == "icp"
    return {"case": case, "seconds": wall, "peak_mib": (peak or 0) / 1024.0,
            "peak_reset": reset_ok, "params": k, "params_per_image": k // len(block.models),
            "tp": int(np.unique(block.measurements.id[block.measurements.kind == "tp"]).size),
            "measurements": int(np.sum(np.isin(block.measurements.kind, ("gcp", "tp")))),
            "iterations": result.iterations, "converged": result.converged,
            "sigma0": result.sigma0,
            "icp_rmse_m": float(np.sqrt(np.mean(result.check.e[icp] ** 2
                                                + result.check.n[icp] ** 2)))}


# ------------------------------------------------------------------------------ driver
def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--cases", nargs="*", help="SET@SPACING/N, e.g. spline@100/10000")
    parser.add_argument("--src", help="run the workers on this checkout's src directory")
    parser.add_argument("--cache", default=os.path.join(tempfile.gettempdir(),
                                                        "geoblock-bench-jitter"))
    parser.add_argument("--timeout", type=float, default=3600.0)
    parser.add_argument("--worker", help=argparse.SUPPRESS)
    parser.add_argument("--simulate", type=int, help=argparse.SUPPRESS)
    args = parser.parse_args()
    cache = Path(args.cache)
    if args.simulate is not None:
        simulate(args.simulate, cache / f"block_{args.simulate}.pkl")
        return
    if args.worker:
        print(json.dumps(worker(args.worker, cache)))
        return
    cache.mkdir(parents=True, exist_ok=True)
    cases = args.cases or (QUICK if args.quick else FULL)
    env = dict(os.environ)
    if args.src:
        env["PYTHONPATH"] = os.pathsep.join([args.src, env.get("PYTHONPATH", "")])
    print(f"load average {os.getloadavg()[0]:.2f}; engine src: {args.src or 'installed'}")
    print(f"{'case':20s} {'K/image':>8s} {'TPs':>6s} {'meas':>6s} {'iter':>4s} "
          f"{'seconds':>8s} {'peak MiB':>9s} {'sigma0':>7s} {'ICP m':>6s}")
    for case in cases:
        n_tp = _parse(case)[2]
        if not (cache / f"block_{n_tp}.pkl").exists():
            t0 = time.perf_counter()
            subprocess.run([sys.executable, __file__, "--cache", str(cache), "--simulate",
                            str(n_tp)], check=True)
            print(f"  (simulated the block with {n_tp} TPs in {time.perf_counter() - t0:.0f} s)")
        try:
            out = subprocess.run([sys.executable, __file__, "--cache", str(cache), "--worker",
                                  case], env=env, capture_output=True, text=True, check=True,
                                 timeout=args.timeout)
        except subprocess.TimeoutExpired:
            print(f"{case:20s} timed out after {args.timeout:.0f} s")
            continue
        except subprocess.CalledProcessError as exc:
            print(f"{case:20s} failed: {exc.stderr.strip().splitlines()[-1:]}")
            continue
        r = json.loads(out.stdout.strip().splitlines()[-1])
        print(f"{case:20s} {r['params_per_image']:8d} {r['tp']:6d} {r['measurements']:6d} "
              f"{r['iterations']:4d} {r['seconds']:8.2f} {r['peak_mib']:9.0f} "
              f"{r['sigma0']:7.3f} {r['icp_rmse_m']:6.2f}", flush=True)


if __name__ == "__main__":
    main()
