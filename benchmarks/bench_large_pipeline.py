"""The ~100-image rendered block end to end: simulate, match (threads, processes, a 2-worker
LocalCluster), adjust, ortho, mosaic, and the mosaic's seam misregistration before/after.

Run: ``python benchmarks/bench_large_pipeline.py [--out DIR] [--jobs 2] [--skip-cluster]
[--variant small]``.

1. ``geoblock simulate continental-spot-100 OUT`` (10 strips x 10 scenes of 400 x 400 px at
   150 m, rendered; GCPs, ICPs, ICTPs and simulated TPs with their truth).
2. ``geoblock match OUT/block.toml`` on local threads, on processes and on a 2-worker
   ``dask.distributed.LocalCluster`` (``--scheduler threads|processes|ADDRESS``, when the
   command offers ``--scheduler``; else once, in one process, and the table says so): wall
   time and the sha256 of each CSV (identical CSVs: the tie-point ids do not depend on the
   schedule).
3. ``geoblock adjust`` of a block file whose image measurements are the simulated GCPs,
   ICPs and ICTPs with the MATCHED tie points (not the simulated ones): the ICP RMSE before
   (on-board) and after.
4. ``geoblock ortho`` of every image with its on-board, its adjusted and its true model
   (``--jobs`` at a time) on the 1 km DEM, at the command's default grid (so the orthos
   mosaic together).
5. ``geoblock mosaic`` (feathered) of the on-board and of the adjusted orthos.
6. The seam misregistration as ``geoblock demo`` measures it
   (:func:`geoblock.match.seams.seam_shift` in each overlap of neighbouring orthos, minus the
   true-model orthos' shift there: :meth:`~geoblock.match.seams.SeamShift.minus`), per pair
   on the pair's common grid (a 100-image union grid would not fit in memory): the RMS and
   the largest seam discrepancy before (on-board) and after (adjusted).

Prints one Markdown table per stage and a JSON summary (``OUT/pipeline.json``).
"""

from __future__ import annotations

import argparse
import csv
import hashlib
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

GEOBLOCK = str(Path(sys.executable).with_name("geoblock"))


def _env() -> dict:
    env = dict(os.environ)
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    return env


def _run(args: list[str], timeout: float = 3600.0) -> tuple[float, str]:
    """Run a geoblock command: (wall seconds, standard error's last lines)."""
    t0 = time.perf_counter()
    proc = subprocess.run([GEOBLOCK, *args], capture_output=True, text=True, env=_env(),
                          timeout=timeout)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise RuntimeError(f"geoblock {' '.join(args)} failed ({proc.returncode}):\n"
                           f"{proc.stderr[-3000:]}")
    return wall, proc.stderr.strip().splitlines()[-1] if proc.stderr.strip() else ""


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _uptime() -> str:
    return subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()


# ------------------------------------------------------------------------------ stages
def simulate(out: Path, variant: str) -> float:
    wall, _ = _run(["simulate", "continental-spot-100", str(out), "--variant", variant,
                    "--overwrite"])
    return wall


def match(out: Path, skip_cluster: bool) -> list[dict]:
    help_text = subprocess.run([GEOBLOCK, "match", "--help"], capture_output=True,
                               text=True).stdout
    rows = []
    if "--scheduler" not in help_text:
        csv_path = out / "match_single.csv"
        wall, summary = _run(["match", str(out / "block.toml"), "-o", str(csv_path)])
        rows.append({"scheduler": "one process (no --scheduler in this geoblock)",
                     "seconds": wall, "sha256": _sha256(csv_path), "csv": str(csv_path),
                     "summary": summary})
        return rows
    schedulers = ["threads", "processes"]
    cluster = client = None
    if not skip_cluster:
        from dask.distributed import Client, LocalCluster

        cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                               dashboard_address=None)
        client = Client(cluster)
        schedulers.append(cluster.scheduler_address)
    try:
        for sched in schedulers:
            name = "LocalCluster(2)" if sched.startswith("tcp") else sched
            csv_path = out / f"match_{name.split('(')[0].lower()}.csv"
            try:
                wall, summary = _run(["match", str(out / "block.toml"), "-o", str(csv_path),
                                      "--scheduler", sched])
                rows.append({"scheduler": name, "seconds": wall, "sha256": _sha256(csv_path),
                             "csv": str(csv_path), "summary": summary})
            except RuntimeError as exc:
                rows.append({"scheduler": name, "seconds": float("nan"), "sha256": "failed",
                             "csv": "", "summary": str(exc).splitlines()[-1][:200]})
    finally:
        if client is not None:
            client.close()
        if cluster is not None:
            cluster.close()
    return rows


def matched_block(out: Path, tp_csv: Path) -> Path:
    """A block file whose image points are the simulated GCPs/ICPs/ICTPs and the matched TPs."""
    rows = []
    with open(out / "points" / "image.csv", newline="") as f:
        reader = csv.DictReader(f)
        fields = reader.fieldnames or []
        rows = [r for r in reader if r.get("kind") in ("gcp", "icp", "ictp")]
    with open(tp_csv, newline="") as f:
        matched = list(csv.DictReader(f))
    for r in matched:
        r["id"] = "m" + r["id"]  # never the same id as a simulated point
        r.setdefault("kind", "tp")
    unique = matched  # one tie point per image position since d0661d1 (tracks.py)
    count: dict[str, int] = {}
    for r in unique:
        count[r["id"]] = count.get(r["id"], 0) + 1
    matched = [r for r in unique if count[r["id"]] >= 2]  # a TP needs two images
    path = out / "points" / "image_matched.csv"
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=fields, extrasaction="ignore")
        w.writeheader()
        w.writerows(rows)
        w.writerows(matched)
    text = (out / "block.toml").read_text()
    text = text.replace('image = "points/image.csv"', 'image = "points/image_matched.csv"')
    block = out / "block_matched.toml"
    block.write_text(text)
    return block


def adjust(block: Path, out: Path) -> tuple[float, str]:
    """``geoblock adjust``; a block the matched tie points leave in disconnected groups is
    adjusted group by group (``--components separate``), and the summary says so."""
    args = ["adjust", str(block), "-o", str(out / "adjusted"), "--overwrite"]
    try:
        return _run(args)
    except RuntimeError as exc:
        if "disconnected groups" not in str(exc):
            raise
        first = [line for line in str(exc).splitlines() if "disconnected" in line][0]
        print(f"adjust refused: {first[:300]}\n  -> again with --components separate",
              flush=True)
        wall, summary = _run([*args, "--components", "separate"])
        return wall, f"--components separate: {summary}"


def orthos(out: Path, jobs: int) -> dict[str, dict[str, Path]]:
    images = sorted(p.stem for p in (out / "images").glob("*.tif"))
    dem = out / "terrain" / "dem1000.tif"
    sets = {"onboard": lambda i: out / "images" / f"{i}_onboard.json",
            "block": lambda i: out / "adjusted" / "models" / f"{i}.json",
            "true": lambda i: out / "images" / f"{i}_true.json"}
    result: dict[str, dict[str, Path]] = {k: {} for k in sets}
    # one CRS for the whole block (the DEM's): each scene's default UTM zone differs across
    # a zone boundary, and the mosaic does not reproject
    import rasterio

    with rasterio.open(dem) as src:
        crs = src.crs.to_string()
    tasks = []
    for key, model in sets.items():
        folder = out / f"orthos_{key}"
        folder.mkdir(exist_ok=True)
        for i in images:
            target = folder / f"{i}.tif"
            result[key][i] = target
            tasks.append(["ortho", str(out / "images" / f"{i}.tif"), str(target), "--dem",
                          str(dem), "--model", str(model(i)), "--crs", crs, "--overwrite"])
    with ThreadPoolExecutor(max_workers=jobs) as pool:
        list(pool.map(_run, tasks))
    return result


def mosaic(out: Path, sets: dict[str, dict[str, Path]]) -> dict[str, float]:
    times = {}
    for key in ("onboard", "block"):
        paths = [str(p) for p in sets[key].values()]
        times[key] = _run(["mosaic", str(out / f"mosaic_{key}.tif"), *paths, "--method",
                           "feather", "--overwrite"])[0]
    return times


def seams(sets: dict[str, dict[str, Path]]) -> dict:
    import numpy as np
    import rasterio

    from geoblock.match.seams import on_common_grid, seam_shift

    def band(path: Path):
        with rasterio.open(path) as src:
            a = src.read(1).astype(np.float32)
            if src.nodata is not None:
                a[a == src.nodata] = np.nan
            return a, src.transform, src.bounds

    cache: dict[tuple[str, str], tuple] = {}

    def get(key: str, image: str):
        if (key, image) not in cache:
            cache[(key, image)] = band(sets[key][image])
        return cache[(key, image)]

    images = sorted(sets["block"])
    bounds = {i: get("block", i)[2] for i in images}
    pairs = [(a, b) for k, a in enumerate(images) for b in images[k + 1:]
             if min(bounds[a].right, bounds[b].right) > max(bounds[a].left, bounds[b].left)
             and min(bounds[a].top, bounds[b].top) > max(bounds[a].bottom, bounds[b].bottom)]
    out: dict[str, list[float]] = {"onboard": [], "block": []}
    statuses: dict[str, int] = {}
    for a, b in pairs:
        shifts = {}
        for key in ("true", "onboard", "block"):
            (ga, ta, _), (gb, tb, _) = get(key, a), get(key, b)
            grids, transform = on_common_grid({a: (ga, ta), b: (gb, tb)})
            shifts[key] = seam_shift(grids[a], grids[b], transform, (a, b))
        for key in ("onboard", "block"):
            d = shifts[key].minus(shifts["true"])
            statuses[d.status] = statuses.get(d.status, 0) + 1
            if d.status == "converged":
                out[key].append(float(np.hypot(d.e, d.n)))
    summary = {"pairs": len(pairs), "statuses": statuses}
    for key, values in out.items():
        v = np.array(values)
        summary[key] = {"seams": int(v.size),
                        "rms_m": float(np.sqrt(np.mean(v**2))) if v.size else None,
                        "median_m": float(np.median(v)) if v.size else None,
                        "max_m": float(np.max(v)) if v.size else None}
    return summary


def icp_rmse(out: Path) -> dict:
    report = json.loads((out / "adjusted" / "report.json").read_text())
    stats = report.get("statistics", {})
    return {k: v for k, v in stats.items() if "icp" in k.lower()} or {
        "note": "see adjusted/report.md"}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=os.path.join(tempfile.gettempdir(),
                                                      "geoblock_bench_pipeline"))
    parser.add_argument("--variant", default="small", choices=("small", "full"))
    parser.add_argument("--jobs", type=int, default=2, help="geoblock ortho runs at a time")
    parser.add_argument("--skip-cluster", action="store_true",
                        help="no LocalCluster run of the matching")
    parser.add_argument("--reuse", action="store_true",
                        help="keep an existing simulation (and matching) in --out")
    args = parser.parse_args()
    out = Path(args.out)
    print(f"load: {_uptime()}", flush=True)
    summary: dict = {}
    if not (args.reuse and (out / "block.toml").exists()):
        if out.exists():
            shutil.rmtree(out)
        summary["simulate_s"] = simulate(out, args.variant)
        print(f"simulate: {summary['simulate_s']:.1f} s", flush=True)
    cached = out / "match.json"
    if args.reuse and cached.exists():
        runs = json.loads(cached.read_text())
        print("match: the runs of an earlier call (--reuse)")
    else:
        runs = match(out, args.skip_cluster)
        cached.write_text(json.dumps(runs, indent=1))
    summary["match"] = runs
    print("| scheduler | match s | sha256 |\n|---|---:|---|")
    for r in runs:
        print(f"| {r['scheduler']} | {r['seconds']:.1f} | {r['sha256'][:16]} |  {r['summary']}")
    good = [r for r in runs if r["csv"]]
    if not good:
        print("no matching ran: stop", flush=True)
        return
    print(f"identical CSVs: {len({r['sha256'] for r in good}) == 1}", flush=True)
    block = matched_block(out, Path(good[0]["csv"]))
    summary["adjust_s"], summary["adjust_summary"] = adjust(block, out)
    print(f"adjust: {summary['adjust_s']:.1f} s ({summary['adjust_summary']})", flush=True)
    summary["icp"] = icp_rmse(out)
    t0 = time.perf_counter()
    sets = orthos(out, args.jobs)
    summary["ortho_s"] = time.perf_counter() - t0
    print(f"ortho: {summary['ortho_s']:.1f} s for {sum(len(v) for v in sets.values())} "
          "orthos", flush=True)
    summary["mosaic_s"] = mosaic(out, sets)
    print(f"mosaic: {summary['mosaic_s']}", flush=True)
    summary["seams"] = seams(sets)
    s = summary["seams"]
    print(f"seams ({s['pairs']} overlapping pairs, outcomes {s['statuses']}):")
    for key in ("onboard", "block"):
        v = s[key]
        if v["seams"]:
            print(f"  {key}: {v['seams']} seams, misregistration RMS {v['rms_m']:.1f} m, "
                  f"median {v['median_m']:.1f} m, max {v['max_m']:.1f} m")
    print(f"load: {_uptime()}")
    (out / "pipeline.json").write_text(json.dumps(summary, indent=1, default=str))


if __name__ == "__main__":
    main()
