"""The reduced system's solvers at growing block size (issue 29): dense Cholesky, sparse
direct (SuperLU) and block-Jacobi conjugate gradients on synthetic strip-block systems.

A block of ``strips x scenes`` images of 6 parameters, each image tied to its 8 neighbours:
every overlapping pair adds ``D^T D`` with ``D = [A, -A + noise]`` (12 rows), so that the
tie points fix the images' relative parameters well (noise 0.01: nearly a graph Laplacian,
as tie points without ground control make it) and a block diagonal prior of ``prior`` times
the diagonal holds the rest weakly. This is the structure of the Schur-reduced ``S`` of a
points-only block, without the cost of building one from 10^6 tie points.

Each case (size x method) runs in a subprocess: wall time of the factorisation (or setup)
plus one solve, the peak RSS of the process above its state before the solver ran (VmHWM,
reset), the direct factor's size and its estimate, conjugate gradients' iterations, its
estimated error and its true error against the direct solution in the energy norm
``||x_i - x_d||_S`` (which bounds every unknown's error in posterior sigmas), and the time
of the cofactor columns of 10 images (60 columns, :class:`SelectedCofactor`; 1 image, 6
columns, by conjugate gradients, which pay a whole run per column).

``--system`` times whole :class:`~geoblock.adjust.normal.NormalSystem` s instead: a strip
block of random partials (each point seen by 2-4 of the images around one image corner),
its accumulation, reduction and solution by each solver (``auto`` included), and the
selected cofactors of 10 images with the point cofactors and hat blocks they allow.

Run: ``python benchmarks/bench_solvers.py [--sizes 1000 3000 10000] [--quick]
[--system [--points-per-image N]]``.
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import scipy.sparse

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _measure import reset_peak, rss_kib  # noqa: E402

LAYOUT = {300: (10, 30), 1000: (20, 50), 3000: (30, 100), 10000: (100, 100)}


def strip_system(strips: int, scenes: int, kb: int = 6, rows: int = 12, prior: float = 1e-4,
                 noise: float = 0.01, seed: int = 0) -> tuple[object, np.ndarray]:
    """``(S (K, K) CSC, rhs (K,))`` of a strip block (module docstring)."""
    rng = np.random.default_rng(seed)
    idx = np.arange(strips * scenes).reshape(strips, scenes)
    pa, pb = [], []
    for ds, dc in ((0, 1), (1, -1), (1, 0), (1, 1)):  # each neighbour pair once
        a = idx[: strips - ds, max(0, -dc): scenes - max(0, dc)]
        b = idx[ds: ds + a.shape[0], max(0, dc): max(0, dc) + a.shape[1]]
        pa.append(a.ravel())
        pb.append(b.ravel())
    ia, ib = np.concatenate(pa), np.concatenate(pb)
    a_rows = rng.normal(size=(ia.size, rows, kb))
    d = np.concatenate([a_rows, -a_rows + noise * rng.normal(size=a_rows.shape)], axis=2)
    blk = np.swapaxes(d, 1, 2) @ d  # (pairs, 2 kb, 2 kb)
    g = np.concatenate([ia[:, None] * kb + np.arange(kb), ib[:, None] * kb + np.arange(kb)], 1)
    k = idx.size * kb
    r = np.broadcast_to(g[:, :, None], blk.shape).ravel()
    c = np.broadcast_to(g[:, None, :], blk.shape).ravel()
    s = scipy.sparse.coo_matrix((blk.ravel(), (r, c)), shape=(k, k)).tocsc()
    s = (s + scipy.sparse.diags(prior * s.diagonal())).tocsc()
    return s, rng.normal(size=k)


def run_case(images: int, method: str) -> dict:
    from geoblock.adjust import _solvers

    strips, scenes = LAYOUT[images]
    s, rhs = strip_system(strips, scenes)
    k = s.shape[0]
    groups = np.arange(k, dtype=np.intp).reshape(-1, 6)
    out: dict = {"images": images, "K": k, "nnz_S": int(s.nnz), "method": method}
    if method == "estimate":
        t0 = time.perf_counter()
        out["estimate_MiB"] = _solvers.estimate_factor_bytes(s, groups) / 2**20
        out["seconds"] = time.perf_counter() - t0
        return out
    base = rss_kib("VmRSS") or 0
    reset_peak()
    t0 = time.perf_counter()
    matrix = s.toarray() if method == "dense" else s
    f = _solvers.factorize(method, matrix, groups=groups, use_numba=True, serial_limit=400)
    x = f.solve(rhs)
    out["seconds"] = time.perf_counter() - t0
    out["peak_rss_MiB"] = ((rss_kib("VmHWM") or 0) - base) / 1024
    out["statement"] = f.report.statement
    if method == "direct":
        out["factor_MiB"] = 16 * int(f.lu.nnz) / 2**20
    if method == "iterative":
        out["iterations"] = f.report.iterations
        out["error_estimate"] = f.report.error_estimate
        ref_f = _solvers.factorize("direct", s, groups=groups, use_numba=True, serial_limit=400)
        d = x - ref_f.solve(rhs)
        out["true_error_sigma"] = math.sqrt(max(float(d @ (s @ d)), 0.0))
        # the largest error of one of the first 10 images' parameters in its own sigma
        cols = np.arange(60)
        unit = np.zeros((k, cols.size))
        unit[cols, np.arange(cols.size)] = 1.0
        sigma = np.sqrt(np.diag(ref_f.solve(unit)[cols]))
        out["first60_max_err_sigma"] = float(np.max(np.abs(d[cols]) / sigma))
    if method in ("direct", "iterative"):
        # 10 images' columns (direct), 1 image's (iterative: a full run per column)
        cols = np.arange(60 if method == "direct" else 6)
        unit = np.zeros((k, cols.size))
        unit[cols, np.arange(cols.size)] = 1.0
        t0 = time.perf_counter()
        f.solve(unit)
        out[f"cofactor_{cols.size}_columns_s"] = time.perf_counter() - t0
    return out


def strip_normal_system(strips: int, scenes: int, points_per_image: int, kb: int = 6,
                        seed: int = 0, solver: str = "auto") -> object:
    """A :class:`NormalSystem` of a strip block (as tests/adjust/test_solvers.strip_problem)."""
    from geoblock.adjust.normal import NormalSystem, measurement_pairs

    rng = np.random.default_rng(seed)
    n_images = strips * scenes
    k = n_images * kb
    n_points = points_per_image * n_images
    s0 = rng.integers(0, strips - 1, n_points)
    c0 = rng.integers(0, scenes - 1, n_points)
    corner = np.stack([(s0 + ds) * scenes + c0 + dc for ds in (0, 1) for dc in (0, 1)], 1)
    seen = rng.random((n_points, 4)) < 0.7
    first = rng.integers(0, 4, n_points)
    seen[np.arange(n_points), first] = True
    seen[np.arange(n_points), (first + rng.integers(1, 4, n_points)) % 4] = True
    point_of = np.repeat(np.arange(n_points), 4)[seen.ravel()]
    image_of = corner.ravel()[seen.ravel()]
    m = image_of.size
    blocks = rng.normal(size=(n_images, kb, kb))
    blocks = 1e-2 * (blocks @ np.swapaxes(blocks, 1, 2) / kb + np.eye(kb))
    return NormalSystem(
        n_params=k, gidx=np.arange(k, dtype=np.intp).reshape(n_images, kb), image_of=image_of,
        point_of=point_of, a=rng.normal(size=(m, 2, kb)),
        b=rng.normal(size=(m, 2, 3)) + np.array([[1.0, 0, 0.3], [0, 1.0, 0.2]]),
        v=rng.normal(size=(m, 2)),
        n_pp_prior=scipy.sparse.block_diag(list(blocks), format="csr"),
        b_p_prior=rng.normal(size=k), n_xx_extra=np.zeros((n_points, 3, 3)),
        b_x_extra=np.zeros((n_points, 3)), pairs=measurement_pairs(point_of, n_points),
        solver=solver)


def run_system(images: int, solver: str, points_per_image: int) -> dict:
    strips, scenes = LAYOUT[images]
    base = rss_kib("VmRSS") or 0
    reset_peak()
    t0 = time.perf_counter()
    system = strip_normal_system(strips, scenes, points_per_image, solver=solver)
    t1 = time.perf_counter()
    system.solve(0.1)  # type: ignore[attr-defined]
    t2 = time.perf_counter()
    system.solve(0.0)  # type: ignore[attr-defined]
    t3 = time.perf_counter()
    sel = system.parameter_cofactor(  # type: ignore[attr-defined]
        system.cofactor_columns(images=np.arange(10)))  # type: ignore[attr-defined]
    q_xx, q_px = system.point_cofactors(sel)  # type: ignore[attr-defined]
    system.hat_blocks(sel, q_xx, q_px)  # type: ignore[attr-defined]
    t4 = time.perf_counter()
    return {"images": images, "K": system.n_params,  # type: ignore[attr-defined]
            "measurements": int(system.a.shape[0]),  # type: ignore[attr-defined]
            "points": int(q_xx.shape[0]), "points_with_cofactor": int(np.sum(
                np.isfinite(q_xx[:, 0, 0]))), "solver": solver,
            "used": system.solver_used,  # type: ignore[attr-defined]
            "statement": system.solver_statement,  # type: ignore[attr-defined]
            "build_s": t1 - t0, "solve_damped_s": t2 - t1, "solve_s": t3 - t2,
            "cofactors_10_images_s": t4 - t3,
            "peak_rss_MiB": ((rss_kib("VmHWM") or 0) - base) / 1024}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", type=int, nargs="*", default=[1000, 3000, 10000],
                    choices=sorted(LAYOUT))
    ap.add_argument("--quick", action="store_true", help="300 and 1000 images only")
    ap.add_argument("--system", action="store_true",
                    help="whole NormalSystems (accumulate, reduce, solve, cofactors)")
    ap.add_argument("--points-per-image", type=int, default=100)
    ap.add_argument("--case", nargs=2, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.case:
        if args.system:
            print(json.dumps(run_system(int(args.case[0]), args.case[1],
                                        args.points_per_image)))
        else:
            print(json.dumps(run_case(int(args.case[0]), args.case[1])))
        return
    sizes = [300, 1000] if args.quick else args.sizes
    if args.system:
        for images in sizes:
            solvers_ = ["auto", "direct", "iterative"] + (["dense"] if images * 6 <= 4000
                                                            else [])
            for solver in solvers_:
                proc = subprocess.run(
                    [sys.executable, __file__, "--system", "--points-per-image",
                     str(args.points_per_image), "--case", str(images), solver],
                    capture_output=True, text=True, check=False)
                if proc.returncode:
                    print(f"{images} {solver}: failed\n{proc.stderr[-2000:]}")
                    continue
                r = json.loads(proc.stdout.strip().splitlines()[-1])
                print(f"{images:6d} images K={r['K']:6d} M={r['measurements']:8d} "
                      f"{solver:9s} ({r['used']:9s}) build {r['build_s']:6.2f} s  solve "
                      f"damped {r['solve_damped_s']:6.2f} s, undamped {r['solve_s']:6.2f} s  "
                      f"10 images' cofactors {r['cofactors_10_images_s']:6.2f} s "
                      f"({r['points_with_cofactor']} points)  peak RSS "
                      f"+{r['peak_rss_MiB']:6.0f} MiB\n        {r['statement']}", flush=True)
        return
    for images in sizes:
        methods = ["estimate", "direct", "iterative"] + (["dense"] if images * 6 <= 6000 else [])
        for method in methods:
            proc = subprocess.run([sys.executable, __file__, "--case", str(images), method],
                                  capture_output=True, text=True, check=False)
            if proc.returncode:
                print(f"{images} {method}: failed\n{proc.stderr[-2000:]}")
                continue
            r = json.loads(proc.stdout.strip().splitlines()[-1])
            extra = {key: r[key] for key in ("factor_MiB", "estimate_MiB", "iterations",
                                             "error_estimate", "true_error_sigma",
                                             "first60_max_err_sigma", "cofactor_60_columns_s",
                                             "cofactor_6_columns_s")
                     if key in r}
            print(f"{images:6d} images K={r['K']:6d} nnz(S)={r['nnz_S']:9d} {method:9s} "
                  f"{r['seconds']:8.2f} s  peak RSS +{r.get('peak_rss_MiB', 0):7.0f} MiB  "
                  + "  ".join(f"{key}={val:.3g}" for key, val in extra.items()), flush=True)


if __name__ == "__main__":
    main()
