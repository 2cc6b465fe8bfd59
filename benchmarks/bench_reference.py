"""Control from a reference orthoimage (``geoblock match --reference``): throughput.

Run: ``python benchmarks/bench_reference.py [--quick] [--repeat N] [--keep DIR]``.

Cases:

* ``sim2.5``: two 600 x 600 px views at 2.5 m (tests/match/test_reference.py's scene: ridged
  100-400 m terrain, incidences +-12 degrees, on-board models), a reference rendered from the
  simulator's ground texture at 10 m and misregistered by (3, -4) m; images averaged 4 x 4;
* ``sim0.5``: one 2000 x 2000 px view at 0.5 m against the same kind of 10 m reference
  (images averaged 20 x 20); ``--quick`` skips it;
* ``ventoux``: the right Pleiades crop (495 x 498 px) against the left crop's ortho through its
  vendor RPC and the SRTM at 0.5 m (``../shared/data``; skipped when absent).

Per case:

* **library**: :func:`geoblock.match.match_reference`, best of ``--repeat`` after a warm-up
  call (images, models, DEM opened outside the timing);
* **command**: ``geoblock match IMAGE --model ... --reference REF --reference-accuracy 5 -o ...
  --ground-output ...`` in its own process per image (no tie points), start-up included, the
  images' sum, best of ``--repeat`` after an untimed run;
* control points, control points per second and megapixels of raw image per second (the raw
  images' pixels over the wall time) both ways; on the simulated cases the median of the
  control points' ground minus the truth of their image measurements against the shift the
  reference was given.

Nothing is asserted; the figures go into benchmarks/README.md.
"""

from __future__ import annotations

import argparse
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve()
DATA = Path(os.environ.get("GEOBLOCK_TEST_DATA", HERE.parents[2] / "shared" / "data"))
SHARELOC = DATA / "shareloc"
sys.path.insert(0, str(HERE.parents[1] / "tests" / "match"))


def _geoblock_exe() -> str:
    exe = Path(sys.executable).with_name("geoblock")
    return str(exe) if exe.exists() else "geoblock"


def _simulated(root: Path, name: str, gsd: float, n: int, images: int, scale: float) -> dict:
    from test_reference import render_reference, scenario  # tests/match/test_reference.py

    from geoblock.simulate.scenario import scenario_from_dict
    from geoblock.workflows import run_scenario

    out = root / name
    if not (out / "ref_10.tif").exists():
        run_scenario(scenario_from_dict(scenario(gsd, n, images, 5 if images == 2 else 7,
                                                 scale)), out)
        render_reference(out, out / "ref_10.tif")
    ids = ("a", "b")[:images]
    return {"images": {i: (out / "images" / f"{i}_onboard.json", out / "images" / f"{i}.tif")
                       for i in ids},
            "reference": out / "ref_10.tif", "dem": ["--dem", out / "terrain" / "dem.tif"],
            "dem_sigma": 5.0, "out": out}


def _ventoux(root: Path) -> dict | None:
    srtm = SHARELOC / "dtm/srtm_ventoux/srtm90_non_void_filled/N44E005.hgt"
    geoid = SHARELOC / "dtm/geoid/egm96_15.gtx"
    left = SHARELOC / "image/phr_ventoux/left_image.tif"
    right = SHARELOC / "image/phr_ventoux/right_image.tif"
    rpc = SHARELOC / "rpc/phr_ventoux"
    if not all(p.exists() for p in (srtm, geoid, left, right)):
        return None
    dem = ["--dem", srtm, "--dem-vertical", "geoid", "--geoid", geoid]
    ortho = root / "left_ortho.tif"
    if not ortho.exists():
        subprocess.run([_geoblock_exe(), "ortho", str(left), str(ortho), "--model",
                        str(rpc / "left_image.geom"), *map(str, dem), "--res", "0.5",
                        "--resampling", "bicubic"], check=True, capture_output=True)
    return {"images": {"right": (rpc / "right_image.geom", right)}, "reference": ortho,
            "dem": dem, "dem_sigma": 10.0, "out": None}


def _dem(case: dict):  # type: ignore[no-untyped-def]
    import geoblock

    args = [str(a) for a in case["dem"]]
    kw = {}
    if "--dem-vertical" in args:
        kw = {"vertical": args[args.index("--dem-vertical") + 1],
              "geoid": args[args.index("--geoid") + 1]}
    return geoblock.open_dem(args[1], **kw)


def _truth_error(case: dict, control) -> str:  # type: ignore[no-untyped-def]
    import numpy as np

    import geoblock
    from geoblock import coords

    out = case["out"]
    if out is None:
        return "-"
    truth = geoblock.open_dem(out / "terrain" / "truth.tif")
    g, m = control.ground, control.measurements
    errs = []
    for image_id in case["images"]:
        model = geoblock.open_model(out / "images" / f"{image_id}_true.json")
        sel = m["image"] == image_id
        gr, _ = geoblock.localize(model, m["row"][sel], m["col"][sel], truth, warn=False)
        de, dn, _ = coords.enu_offsets(gr.lon, gr.lat, gr.h, g["lon"][sel], g["lat"][sel],
                                       g["h"][sel])
        errs.append(np.hypot(de - 3.0, dn + 4.0))
    e = np.concatenate(errs)
    return f"{np.median(e):.2f} m, {100 * np.mean(e < 10):.1f} % < 1 ref px"


def _run(name: str, case: dict, repeat: int, root: Path) -> None:
    from geoblock.match import MatchImage, match_reference

    dem = _dem(case)
    images = [MatchImage.from_files(i, r, m) for i, (m, r) in case["images"].items()]
    mpix = sum(im.image.shape[0] * im.image.shape[1] for im in images) / 1e6
    kw = {"reference_accuracy_ce90_m": 5.0, "dem_sigma_m": case["dem_sigma"]}
    control = match_reference(images, case["reference"], dem, **kw)  # warm-up
    best = math.inf
    for _ in range(repeat):
        t = time.perf_counter()
        control = match_reference(images, case["reference"], dem, **kw)
        best = min(best, time.perf_counter() - t)
    n = len(control)
    cmds = []  # one command per image: the reference control alone, no tie points
    for image_id, (model, raster) in case["images"].items():
        cmds.append([_geoblock_exe(), "match", str(raster), "--model", str(model),
                     "--image-id", image_id, *[str(a) for a in case["dem"]],
                     "--dem-sigma", str(case["dem_sigma"]), "--reference",
                     str(case["reference"]), "--reference-accuracy", "5", "-o",
                     str(root / f"{name}_{image_id}_image.csv"), "--ground-output",
                     str(root / f"{name}_{image_id}_ground.csv"), "--overwrite"])
    for cmd in cmds:
        subprocess.run(cmd, check=True, capture_output=True)
    best_cmd = math.inf
    for _ in range(repeat):
        t = time.perf_counter()
        for cmd in cmds:
            subprocess.run(cmd, check=True, capture_output=True)
        best_cmd = min(best_cmd, time.perf_counter() - t)
    print(f"| {name} | {mpix:.2f} | {control.counts()['candidates']} | {n} | {best:.2f} | "
          f"{n / best:.0f} | {mpix / best:.2f} | {best_cmd:.2f} | {n / best_cmd:.0f} | "
          f"{mpix / best_cmd:.2f} | {_truth_error(case, control)} |", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--keep", type=Path, default=None)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        root = args.keep or Path(tmp)
        root.mkdir(parents=True, exist_ok=True)
        print("| case | raw MPix | candidates | control points | library s | library pts/s | "
              "library MPix/s | command s | command pts/s | command MPix/s | ground error |")
        print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|")
        cases = {"sim2.5": lambda: _simulated(root, "sim25", 2.5, 600, 2, 1.0)}
        if not args.quick:
            cases["sim0.5"] = lambda: _simulated(root, "sim05", 0.5, 2000, 1, 5.0)
        cases["ventoux"] = lambda: _ventoux(root)
        for name, make in cases.items():
            case = make()
            if case is None:
                print(f"| {name} | skipped: data not found |")
                continue
            _run(name, case, args.repeat, root)


if __name__ == "__main__":
    main()
