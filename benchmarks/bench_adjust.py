"""Block adjustment of RPC images: geoblock's ``adjust`` against scipy's ``least_squares``.

Run: ``python benchmarks/bench_adjust.py [--quick] [--cases IMAGESxTPS ...] [--no-scipy-above N]
[--cache DIR] [--profile]``.

**Blocks**: :func:`geoblock.testing.blocks.affine_block` (grids of 2 x 5 = 10, 5 x 6 = 30,
10 x 10 = 100 and 15 x 20 = 300 images of 1000 x 1000 px, 30 % overlap, 6 GCPs and 10 ICPs per
image, TPs seen by 2-4 images, 20 ICTPs, DEM of the true terrain), with every on-board
affine camera replaced by an RPC00B fitted to it (``geoblock_rpc.fit.fit_rpc``, default
21 x 21 x 9 grid; check-grid error ~1e-9 px) through ``affine_block(wrap=...)``: each image is
a vendor RPC (``RpcModel``) wrapped in an order-1 ``ImageCorrection`` (RPCV-1), so the
adjustment evaluates real RPC projections and analytic RPC partials of every image. Each
image has its own RPC (the cameras differ in origin, tilt and on-board error, so one RPC
cannot serve two images); fitting takes ~50 ms per image, so the fitted RPCs are cached on
disk (``--cache``, keyed by the camera's parameters) and their cost is not in any timing.

**geoblock**: ``adjust(block)`` with its defaults (DEM control as observations, floating TP
priors, statistics and covariance included), timed as the user calls it: Jacobians,
normal equations, Schur reduction, iterations and the result's statistics. Block
construction (``affine_block`` with cached RPCs) is reported separately.

**scipy**: ``scipy.optimize.least_squares(method="trf")`` on the same problem, with an
analytic sparse Jacobian (CSR) built from the same models' partials
(``partials_parameters``, ``partials_ground``) and the same initial values (the engine's
set-up: TPs localised on the DEM). Its residuals, all whitened by their sigmas:

* image measurements of GCPs and TPs (2 rows each);
* GCP ground observations (3 rows per GCP, the surveyed position with its sigmas);
* the TPs' DEM rows ``(h - DEM(E, N)) / dem_sigma`` with the DEM slope by central
  differences, as geoblock's ``dem_control="observation"`` (the engine's ``_dem_rows``);
* parameter priors: none (the RPCV-1 corrections are free, as in geoblock).

geoblock's floating TP pseudo-observations are re-centred on the estimate at every iteration,
so they vanish at convergence: both minimise the same cost. Timed: the engine set-up (the same
initial values geoblock computes) plus ``least_squares``. *Agreement*: the largest difference
between the two solutions, of the correction parameters (pixels) and of the ground points
(metres, local frame).

Every case runs in two processes of its own (geoblock, scipy), so that the peak RSS is the
case's: *peak MiB* is the peak during the timed call (reset through ``/proc/self/clear_refs``
before it; the process's peak elsewhere). *geoblock s* is the process's first ``adjust``
call (after a warm-up on a 10-image block that loads the numba kernels), in parentheses the
best of two more calls. ``--quick``: 10 images x 10^3 and 30 x 2 10^4 TPs.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _measure import reset_peak, rss_kib  # benchmarks/_measure.py (run as a script)

GRIDS = {10: (2, 5), 30: (5, 6), 100: (10, 10), 300: (15, 20)}
FULL = [(10, 1000), (10, 10000), (10, 100000), (100, 1000), (100, 10000), (100, 100000),
        (300, 1000), (300, 10000), (300, 100000), (30, 20000)]
QUICK = [(10, 1000), (30, 20000)]
#: least_squares' ftol, xtol and gtol
SCIPY_TOL = 1e-12


# ------------------------------------------------------------------------------ workers
def _rpc_wrapper(cache: Path):
    """``wrap`` for affine_block: an RpcModel fitted to the camera, cached on disk."""
    from geoblock_rpc.fit import fit_rpc
    from geoblock_rpc.model import RpcModel

    cache.mkdir(parents=True, exist_ok=True)

    def wrap(camera):
        key = hashlib.sha256(json.dumps(camera.to_dict(), sort_keys=True).encode()).hexdigest()
        path = cache / f"{key[:32]}.json"
        if path.exists():
            return RpcModel.from_dict(json.loads(path.read_text()))
        rpc, stats = fit_rpc(camera)
        if stats.max_px > 1e-3:
            raise SystemExit(f"RPC fit error {stats.max_px} px")
        model = RpcModel(rpc, camera.shape)
        path.write_text(json.dumps(model.to_dict()))
        return model

    return wrap


def _make_block(images: int, tps: int, cache: str):
    from geoblock.testing.blocks import affine_block

    return affine_block(GRIDS[images], tps=tps, ictps=20, seed=1,
                        wrap=_rpc_wrapper(Path(cache)))


def _engine(block):
    from geoblock.adjust.block import _Engine

    return _Engine(block, block.image_ids, use_tps=True, dem_control="observation",
                   tp_sigma_factor=10.0, tp_sigma_m=None, tp_prior="floating", notes=[])


def _worker_geoblock(images: int, tps: int, cache: str, out: str, profile: bool) -> dict:
    from geoblock.adjust.block import adjust

    t0 = time.perf_counter()
    sb = _make_block(images, tps, cache)
    t_block = time.perf_counter() - t0
    # the numba kernels' first call loads them from the on-disk cache: a tiny block first
    _warm(cache)
    reset = reset_peak()
    t0 = time.perf_counter()
    result = adjust(sb.block)
    t_adjust = time.perf_counter() - t0
    peak = rss_kib("VmHWM") if reset else None
    again = []
    for _ in range(2):  # the first call pays first-touch costs; report the best of 2 more
        t0 = time.perf_counter()
        adjust(sb.block)
        again.append(time.perf_counter() - t0)
    if profile:
        import cProfile
        import pstats

        prof = cProfile.Profile()
        prof.enable()
        adjust(sb.block)
        prof.disable()
        pstats.Stats(prof, stream=sys.stderr).sort_stats("tottime").print_stats(25)
    eng = _engine(sb.block)  # the solution, in the same local frame as scipy's
    s = eng.s
    x = _params(result.models, s)
    lon = dict(zip(result.points.id.tolist(), result.points.lon.tolist(), strict=True))
    lat = dict(zip(result.points.id.tolist(), result.points.lat.tolist(), strict=True))
    hh = dict(zip(result.points.id.tolist(), result.points.h.tolist(), strict=True))
    ids = s.p_id.tolist()
    import numpy as np

    pts = np.stack(s.frame.from_geodetic(np.array([lon[i] for i in ids]),
                                         np.array([lat[i] for i in ids]),
                                         np.array([hh[i] for i in ids])), -1)
    np.savez(out, x=x, pts=pts)
    meas = sb.block.measurements
    return {"block_s": t_block, "time_s": t_adjust, "best_s": min(again), "peak_kib": peak,
            "iterations": result.iterations, "converged": result.converged,
            "sigma0": result.sigma0, "measurements": int(s.obs.shape[0]),
            "all_measurements": len(meas), "points": int(s.p_id.size),
            "unknowns": int(s.n_params + 3 * s.p_id.size)}


def _warm(cache: str) -> None:
    from geoblock.adjust.block import adjust

    adjust(_make_block(10, 200, cache).block)


def _params(models, s):
    import numpy as np

    x = np.zeros(s.n_params)
    for i, image in enumerate(s.ids):
        m = models[image]
        x[s.gidx[i, : s.adj[i].size]] = m.parameters.values[s.adj[i]]
    return x


def _worker_scipy(images: int, tps: int, cache: str, out: str) -> dict:
    import numpy as np
    import scipy.optimize
    import scipy.sparse

    from geoblock.typing import Status

    sb = _make_block(images, tps, cache)
    _warm(cache)
    reset = reset_peak()
    t0 = time.perf_counter()
    eng = _engine(sb.block)
    s = eng.s
    k, n_pts = s.n_params, s.p_id.size
    m_count = s.obs.shape[0]
    kmax = s.gidx.shape[1]
    rot_t = s.frame.rotation.T
    gcp = np.flatnonzero(s.p_kind == "gcp")
    g_sqrt = np.linalg.cholesky(s.g_weight[gcp])  # W = L L^T: rows L^T (x - c)
    dem_sigma = sb.block.dem_sigma_m
    by_image = [np.flatnonzero(s.image_of == i) for i in range(len(s.ids))]
    # Jacobian structure: image rows (2M), GCP rows (3 G), DEM rows (J, zero where none)
    g_cols = s.gidx[s.image_of]  # (M, Kmax)
    rows_img = np.repeat(np.arange(2 * m_count), kmax + 3)
    cols_img = np.concatenate([np.repeat(g_cols[:, None, :], 2, 1),
                               k + 3 * np.repeat(s.point_of[:, None, None], 2, 1)
                               + np.arange(3)], axis=2).ravel()
    ok_img = np.concatenate([np.repeat((g_cols >= 0)[:, None, :], 2, 1),
                             np.ones((m_count, 2, 3), bool)], axis=2).ravel()
    r0 = 2 * m_count
    rows_g = r0 + np.repeat(np.arange(3 * gcp.size), 3)
    cols_g = (k + 3 * np.repeat(gcp, 9) + np.tile(np.arange(3), 3 * gcp.size))
    r1 = r0 + 3 * gcp.size
    rows_d = r1 + np.repeat(np.arange(n_pts), 3)
    cols_d = k + np.arange(3 * n_pts)
    rows = np.concatenate([rows_img[ok_img], rows_g, rows_d])
    cols = np.concatenate([cols_img[ok_img], cols_g, cols_d])
    n_rows = r1 + n_pts
    cache_state: dict = {}

    def state(z):
        key = z.tobytes()
        if cache_state.get("key") != key:
            x, pts = z[:k], z[k:].reshape(-1, 3)
            models = [m.with_parameters(_values(m, s.adj[i], x[s.gidx[i, : s.adj[i].size]]))
                      if s.adj[i].size else m for i, m in enumerate(s.models)]
            g = s.frame.to_geodetic(pts[:, 0], pts[:, 1], pts[:, 2])
            lon, lat, h = np.asarray(g.lon), np.asarray(g.lat), np.asarray(g.h)
            cache_state.clear()
            cache_state.update(key=key, x=x, pts=pts, models=models, lon=lon, lat=lat, h=h)
        return cache_state

    def fun(z):
        st = state(z)
        computed = np.empty((m_count, 2))
        for i, model in enumerate(st["models"]):
            mine = by_image[i]
            j = s.point_of[mine]
            (r, c), status = model.project_with_status(st["lon"][j], st["lat"][j], st["h"][j])
            computed[mine, 0], computed[mine, 1] = r, c
            if np.any(status != Status.CONVERGED):
                computed[mine[status != Status.CONVERGED]] = np.nan
        img = (computed - s.obs) / s.sigma  # computed minus observed
        dg = st["pts"][gcp] - s.g_center[gcp]
        ground = np.einsum("gki,gk->gi", g_sqrt, dg)  # L^T (x - c)
        dem = eng._dem_rows(st["lon"], st["lat"], st["h"], st["pts"])
        st["dem"] = dem
        d = np.where(np.isfinite(dem["misclosure"]), -dem["misclosure"] / dem_sigma, 0.0)
        return np.concatenate([img.ravel(), ground.ravel(), d])

    def jac(z):
        st = state(z)
        a = np.zeros((m_count, 2, kmax))
        b = np.empty((m_count, 2, 3))
        for i, model in enumerate(st["models"]):
            mine = by_image[i]
            j = s.point_of[mine]
            lon, lat, h = st["lon"][j], st["lat"][j], st["h"][j]
            if s.adj[i].size:
                a[mine, :, : s.adj[i].size] = model.partials_parameters(lon, lat, h)[
                    ..., s.adj[i]]
            b[mine] = model.partials_ground(lon, lat, h) @ rot_t
        a /= s.sigma[:, :, None]
        b /= s.sigma[:, :, None]
        v_img = np.concatenate([a, b], axis=2).ravel()[ok_img]
        v_g = np.swapaxes(g_sqrt, 1, 2).ravel()  # d(L^T x)/dx = L^T
        dem = st.get("dem") or eng._dem_rows(st["lon"], st["lat"], st["h"], st["pts"])
        grad = np.where(np.isfinite(dem["misclosure"])[:, None], dem["grad"] / dem_sigma, 0.0)
        vals = np.concatenate([v_img, v_g, grad.ravel()])
        return scipy.sparse.csr_matrix((vals, (rows, cols)), shape=(n_rows, k + 3 * n_pts))

    z0 = np.concatenate([s.prior_x, s.x0.ravel()])
    t_setup = time.perf_counter() - t0
    sol = scipy.optimize.least_squares(fun, z0, jac=jac, method="trf",
                                       ftol=SCIPY_TOL, xtol=SCIPY_TOL, gtol=SCIPY_TOL)
    t_total = time.perf_counter() - t0
    peak = rss_kib("VmHWM") if reset else None
    np.savez(out, x=sol.x[:k], pts=sol.x[k:].reshape(-1, 3))
    return {"time_s": t_total, "setup_s": t_setup, "peak_kib": peak, "nfev": int(sol.nfev),
            "njev": int(sol.njev or 0), "status": int(sol.status),
            "cost": float(2 * sol.cost)}


def _values(model, adj, sub):
    import numpy as np

    values = np.array(model.parameters.values)
    values[adj] = sub
    return values


# ------------------------------------------------------------------------------ driver
def _run(args: list[str]) -> tuple[dict, float, float]:
    """Run this script as a worker; (its JSON answer, wall seconds, peak RSS MiB)."""
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, __file__, "--worker", *args],
                            stdout=subprocess.PIPE, text=True)
    out = proc.stdout.read() if proc.stdout else ""
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    code = os.waitstatus_to_exitcode(status)
    if code != 0:
        raise RuntimeError(f"worker {args} failed with exit code {code}")
    peak_kib = usage.ru_maxrss / (1024 if sys.platform == "darwin" else 1)
    return json.loads(out.strip().splitlines()[-1]), wall, peak_kib / 1024


def _mib(kib) -> str:
    return f"{kib / 1024:.0f}" if kib else "n/a"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="10 x 10^3 and 30 x 2 10^4 only")
    parser.add_argument("--cases", nargs="*", default=None,
                        help="IMAGESxTPS, e.g. 30x20000 (images: 10, 30, 100, 300)")
    parser.add_argument("--no-scipy-above", type=int, default=10**9,
                        help="skip scipy for blocks with more TPs than this")
    parser.add_argument("--cache", default=os.path.join(tempfile.gettempdir(),
                                                        "geoblock_bench_adjust_rpc"),
                        help="folder of the cached fitted RPCs")
    parser.add_argument("--profile", action="store_true",
                        help="cProfile a second adjust() of each case (stderr)")
    parser.add_argument("--worker", nargs="*", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker is not None:
        kind, images, tps, out = args.worker
        answer = (_worker_geoblock(int(images), int(tps), args.cache, out, args.profile)
                  if kind == "geoblock" else _worker_scipy(int(images), int(tps), args.cache,
                                                           out))
        print(json.dumps(answer))
        return

    import numpy as np
    import scipy

    import geoblock

    print(f"geoblock {geoblock.__version__}, numpy {np.__version__}, scipy {scipy.__version__}, "
          f"{os.cpu_count()} CPUs")
    if args.cases:
        cases = [tuple(int(v) for v in c.lower().split("x")) for c in args.cases]
    else:
        cases = QUICK if args.quick else FULL
    head = ("| images | TPs | measurements | unknowns | block s | geoblock s | iterations | "
            "peak MiB | scipy s | nfev | peak MiB | agreement px / m |")
    print(head)
    print("|" + "---:|" * 12)
    with tempfile.TemporaryDirectory(prefix="bench_adjust_") as tmp:
        for images, tps in cases:
            extra = ["--cache", args.cache] + (["--profile"] if args.profile else [])
            g_out = os.path.join(tmp, f"g{images}_{tps}.npz")
            g, _, g_proc = _run(["geoblock", str(images), str(tps), g_out, *extra])
            row = (f"| {images} | {tps} | {g['measurements']} | {g['unknowns']} | "
                   f"{g['block_s']:.1f} | **{g['time_s']:.2f}** ({g['best_s']:.2f}) | "
                   f"{g['iterations']}"
                   f"{'' if g['converged'] else ' (not converged)'} | {_mib(g['peak_kib'])} |")
            if tps > args.no_scipy_above:
                print(row + " skipped | | | |", flush=True)
                continue
            s_out = os.path.join(tmp, f"s{images}_{tps}.npz")
            try:
                sp, _, s_proc = _run(["scipy", str(images), str(tps), s_out, *extra])
            except RuntimeError as exc:
                print(row + f" failed: {exc} | | | |", flush=True)
                continue
            a, b = np.load(g_out), np.load(s_out)
            dx = float(np.max(np.abs(a["x"] - b["x"])))
            dp = float(np.max(np.abs(a["pts"] - b["pts"])))
            print(row + f" {sp['time_s']:.2f} | {sp['nfev']} | {_mib(sp['peak_kib'])} | "
                  f"{dx:.1e} / {dp:.1e} |", flush=True)


if __name__ == "__main__":
    main()
