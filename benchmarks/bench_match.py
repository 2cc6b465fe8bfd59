"""Tie points from images (``geoblock match``): speed, yield, correctness and memory.

Run: ``python benchmarks/bench_match.py [--quick] [--repeat N] [--keep DIR]``.

Cases:

* ``sim300``: the pair ``a`` & ``b`` of tests/match's simulated block (300 x 300 px, 2.5 m GSD,
  incidences +12 / -12 degrees, ridged 100-400 m terrain, on-board models off by 20-30 m, a
  measured DEM of 20 m posts and RMSEz 5 m);
* ``sim1200``: the same scene and geometry at 1200 x 1200 px (the texture's fields as many
  pixels wide, so four times the images' area and about 16 times their keypoints);
  skipped by ``--quick``;
* ``ventoux``: the real Pleiades pair of Mont Ventoux (shareloc's 500 x 500 px crops), their
  RPCs and the SRTM tile with EGM96 heights (``../shared/data``; skipped when absent or
  without the ``geoblock-rpc`` plugin).

Per case:

* **command**: ``geoblock match A B --model ... --dem ... -o OUT`` in its own process, start-up
  included, best wall time of ``--repeat`` runs after an untimed one; its peak RSS from
  ``os.wait4``'s rusage;
* **library**: :func:`geoblock.match.match_images` in a worker process (images and models
  opened outside the timing, as a program matching many pairs would), best of ``--repeat``
  after a warm-up call; peak RSS during the calls (reset through ``/proc/self/clear_refs``);
* keypoints, candidates, kept matches, matches per second (kept / wall time) both ways;
* on the simulated pairs, the share of kept matches within 1 px of the truth (the TRUE model
  of A on the TRUE terrain, projected by B's TRUE model) and its median error.

Nothing is asserted; the figures go into benchmarks/README.md.
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

HERE = Path(__file__).resolve()
DATA = Path(os.environ.get("GEOBLOCK_TEST_DATA", HERE.parents[2] / "shared" / "data"))
SHARELOC = DATA / "shareloc"


def _geoblock_exe() -> str:
    exe = Path(sys.executable).with_name("geoblock")
    return str(exe) if exe.exists() else "geoblock"


# ------------------------------------------------------------------------------ data
def _scenario(size: int) -> dict:
    """tests/match/conftest.py's scenario, images ``a`` and ``b`` at ``size`` px."""
    image = {"preset": "spot5-strip1", "centre_lon": 120.95, "shape": [size, size],
             "gsd_m": 2.5 * 300 / size}
    return {
        "name": f"match-pair-{size}", "description": "a stereo pair for geoblock match",
        "seed": 17, "method": "dg",
        "images": [{"id": "a", **image, "incidence_deg": 12.0},
                   {"id": "b", **image, "incidence_deg": -12.0,
                    "epoch": "2003-06-23T02:40:00Z"}],
        "terrain": {"kind": "ridged", "relief": [100.0, 400.0],
                    "resolution_m": 10.0 * 300 / size, "vertical": "ellipsoid",
                    "margin_m": 300.0},
        "dems": [{"name": "dem", "spacing_m": 20.0, "rmse_z": 5.0}],
        "points": {"gcp": 4, "icp": 0, "tp": [0, 0], "ictp": [0, 0], "sigma_px": 0.3},
        # fields as many pixels wide at every size (the texture scales with the GSD)
        "render": {"enabled": True, "dtype": "uint8", "noise_dn": 1.0,
                   "texture_scale_px": 0.5},
        "report": {"distance_plot": False, "gcp_study": False},
    }


def simulated_case(directory: Path, size: int) -> dict:
    """Simulate the pair once into ``directory`` (kept between runs)."""
    from geoblock.simulate.scenario import scenario_from_dict
    from geoblock.workflows import run_scenario

    if not (directory / "block.toml").exists():
        t0 = time.perf_counter()
        run_scenario(scenario_from_dict(_scenario(size)), directory)
        print(f"  simulated {size} x {size} px pair in {time.perf_counter() - t0:.1f} s",
              flush=True)
    images = directory / "images"
    return {"name": f"sim{size}", "images": [str(images / "a.tif"), str(images / "b.tif")],
            "models": [str(images / "a_onboard.json"), str(images / "b_onboard.json")],
            "ids": ["a", "b"], "dem": [str(directory / "terrain" / "dem.tif")],
            "truth": str(directory)}


def ventoux_case() -> dict | None:
    files = [SHARELOC / f"image/phr_ventoux/{s}_image.tif" for s in ("left", "right")]
    rpcs = [SHARELOC / f"rpc/phr_ventoux/{s}_image.geom" for s in ("left", "right")]
    srtm = SHARELOC / "dtm/srtm_ventoux/srtm90_non_void_filled/N44E005.hgt"
    geoid = SHARELOC / "dtm/geoid/egm96_15.gtx"
    if not all(p.exists() for p in (*files, *rpcs, srtm, geoid)):
        return None
    try:
        import geoblock_rpc  # noqa: F401
    except ImportError:
        return None
    return {"name": "ventoux", "images": [str(p) for p in files],
            "models": [str(p) for p in rpcs], "ids": ["left", "right"],
            "dem": [str(srtm), "--dem-vertical", "geoid", "--geoid", str(geoid)],
            "truth": None}


# ------------------------------------------------------------------------------ worker
def _worker(case: dict, repeat: int) -> dict:
    """In its own process: the library call, timed, and its outcome."""
    import numpy as np

    import geoblock
    from geoblock.match import MatchImage, match_images

    images = [MatchImage.from_files(i, p, m) for i, p, m in
              zip(case["ids"], case["images"], case["models"], strict=True)]
    dem_args = case["dem"]
    options = dict(zip(dem_args[1::2], dem_args[2::2], strict=True))
    dem = geoblock.open_dem(dem_args[0], vertical=options.get("--dem-vertical"),
                            geoid=options.get("--geoid"))
    match_images(images, dem)  # warm-up: numba's kernels, the DEM's and geoid's caches
    before = rss_kib("VmRSS")
    reset = reset_peak()
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        tps = match_images(images, dem)
        times.append(time.perf_counter() - t0)
    peak = rss_kib("VmHWM")
    counts = tps.counts()
    out = {"seconds": min(times), "keypoints": sum(tps.keypoints.values()),
           "candidates": counts["candidates"], "kept": counts["kept"],
           "rss_before_mib": (before or 0) / 1024,
           "peak_mib": (peak or 0) / 1024 if reset else None}
    if case["truth"]:
        outdir = Path(case["truth"])
        true = {i: geoblock.open_model(outdir / "images" / f"{i}_true.json") for i in "ab"}
        terrain = geoblock.open_dem(outdir / "terrain" / "truth.tif")
        cols = tps.to_columns()
        a, b = cols["image"] == "a", cols["image"] == "b"
        assert np.array_equal(cols["id"][a], cols["id"][b])
        ground, _ = geoblock.localize(true["a"], cols["row"][a], cols["col"][a], terrain,
                                      warn=False)
        r, c = true["b"].project(ground.lon, ground.lat, ground.h)
        err = np.hypot(cols["row"][b] - r, cols["col"][b] - c)
        out["within_1px"] = float(np.mean(err < 1.0))
        out["median_error_px"] = float(np.median(err))
    return out


def library(case: dict, repeat: int) -> dict:
    code = (f"import sys, json; sys.path.insert(0, {str(HERE.parent)!r}); "
            f"from bench_match import _worker; "
            f"print(json.dumps(_worker({case!r}, {repeat})))")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=True)
    return json.loads(proc.stdout.strip().splitlines()[-1])


def command(case: dict, repeat: int, outdir: Path) -> dict:
    args = [_geoblock_exe(), "match", *case["images"]]
    for model in case["models"]:
        args += ["--model", model]
    for image_id in case["ids"]:
        args += ["--image-id", image_id]
    # every repeat writes the same file
    args += ["--dem", *case["dem"], "-o", str(outdir / f"{case['name']}.csv"), "--overwrite"]
    times, peaks = [], []
    for k in range(repeat + 1):
        t0 = time.perf_counter()
        proc = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                                text=True)
        stderr = proc.stderr.read() if proc.stderr else ""
        _, status, usage = os.wait4(proc.pid, 0)
        elapsed = time.perf_counter() - t0
        proc.returncode = os.waitstatus_to_exitcode(status)
        if proc.returncode != 0:
            raise RuntimeError(f"geoblock match failed: {stderr}")
        if k:  # the first run warms the page and numba caches
            times.append(elapsed)
            peaks.append(usage.ru_maxrss / 1024)
    return {"seconds": min(times), "peak_mib": max(peaks), "summary": stderr.splitlines()[-1]}


# ------------------------------------------------------------------------------ main
def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="skip the 1200 px pair")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--keep", type=Path, default=None,
                        help="directory for the simulated pairs (kept between runs)")
    args = parser.parse_args()
    import geoblock

    print(f"geoblock {geoblock.__version__}, python {sys.version.split()[0]}, "
          f"{os.cpu_count()} CPUs")
    with tempfile.TemporaryDirectory() as tmp:
        root = args.keep or Path(tmp)
        root.mkdir(parents=True, exist_ok=True)
        cases = [simulated_case(root / "sim300", 300)]
        if not args.quick:
            cases.append(simulated_case(root / "sim1200", 1200))
        vtx = ventoux_case()
        if vtx is None:
            print("ventoux: skipped (data or the geoblock-rpc plugin missing)")
        else:
            cases.append(vtx)
        header = (f"{'case':9s} {'keypoints':>9s} {'candidates':>10s} {'kept':>6s} "
                  f"{'lib s':>7s} {'lib m/s':>8s} {'lib MiB':>8s} {'cmd s':>7s} "
                  f"{'cmd m/s':>8s} {'cmd MiB':>8s} {'<1 px':>6s} {'median px':>9s}")
        print(header)
        for case in cases:
            lib = library(case, args.repeat)
            cmd = command(case, args.repeat, root)
            within = f"{100 * lib['within_1px']:5.1f}%" if "within_1px" in lib else "     -"
            median = f"{lib['median_error_px']:9.3f}" if "median_error_px" in lib else \
                "        -"
            lib_peak = f"{lib['peak_mib']:8.0f}" if lib["peak_mib"] else "       -"
            print(f"{case['name']:9s} {lib['keypoints']:9d} {lib['candidates']:10d} "
                  f"{lib['kept']:6d} {lib['seconds']:7.2f} {lib['kept'] / lib['seconds']:8.0f} "
                  f"{lib_peak} {cmd['seconds']:7.2f} {lib['kept'] / cmd['seconds']:8.0f} "
                  f"{cmd['peak_mib']:8.0f} {within} {median}", flush=True)
            print(f"          command: {cmd['summary']}")


if __name__ == "__main__":
    main()
