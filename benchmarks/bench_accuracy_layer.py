"""The per-pixel accuracy layer: its cost per pixel, and ``geoblock ortho`` with and without
``--accuracy-layer`` as whole commands.

Run: ``python benchmarks/bench_accuracy_layer.py [--size N] [--repeat N] [--keep DIR]
[--quick]``.

In-process, one thread (``AccuracyJob.chunk`` over the chunks, no write), ns per output
pixel of the layer beside the same grid's ``source_coordinates`` (the orthorectifier's
geometry, what the layer's lattice shares), on real products from ``../shared/data``:

* **ventoux-rpcv1**: the Pleiades Ventoux RPC under an RPCV-1 correction with a posterior
  covariance of its 6 parameters, over the real SRTM tile (EGM96 geoid), an N x N grid at
  0.5 m in UTM 31N centred on the crop;
* **dg-apriori**: the DigitalGlobe rigorous model of ``stereopipeline/tests/dg_example1.xml``
  with its a-priori sigmas (13 parameters: 26 perturbed projections per lattice node), a
  constant DEM at 1500 m, N x N at 0.5 m at the scene centre.

Whole commands (best and median of ``--repeat`` after a warm-up run, start-up included):
``bench_ortho_cli.py``'s **coarse** case (a 6000 x 6000 uint16 scene carrying an RPC fitted to
the real SPOT-2 scene ``cosicorr3d/test_dataset/SPOT2.DIM``, 400 x 400 DEM, 6000 x 6000 output
at 9 m), its model given as model JSON (the RPC under an RPCV-1 correction, with a posterior),
``geoblock ortho`` without and with ``--accuracy-layer --dem-sigma 10``.
"""

from __future__ import annotations

import argparse
import os
import platform
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve()
sys.path.insert(0, str(HERE.parent))

DATA = Path(os.environ.get("GEOBLOCK_TEST_DATA", HERE.parents[2] / "shared" / "data"))


def _posterior(model):
    from geoblock.models.uncertainty import ModelPosterior

    cov = np.diag([0.3, 1e-3, 1e-3, 0.4, 1e-3, 1e-3]) ** 2
    cov[0, 3] = cov[3, 0] = 0.5 * 0.3 * 0.4
    return ModelPosterior(model.parameters.names, cov, 1.0, 100, "benchmark")


def _cases(size: int) -> list[tuple[str, object, object, object, object]]:
    import geoblock
    from geoblock import coords
    from geoblock.io import open_model
    from geoblock.models import ImageCorrection
    from geoblock.ortho import OutputGrid

    out = []
    rpc = open_model(DATA / "shareloc/rpc/phr_ventoux/RPC_PHR1B_P_201308051042194_SEN_"
                     "690908101-001.XML")
    model = ImageCorrection(rpc, 1)
    dem = geoblock.open_dem(DATA / "shareloc/dtm/srtm_ventoux/srtm90_non_void_filled/"
                            "N44E005.hgt", geoid=DATA / "shareloc/dtm/geoid/egm96_15.gtx",
                            nodata="fill")
    x, y = 675400.0, 4897200.0
    half = 0.25 * size
    grid = OutputGrid.from_bounds("EPSG:32631", (x - half, y - half, x + half, y + half), 0.5)
    out.append(("ventoux-rpcv1 (6 par., SRTM)", model, dem, grid, _posterior(model)))
    dg = open_model(DATA / "stereopipeline/tests/dg_example1.xml")
    rows, cols = dg.shape
    g = dg.backproject((rows - 1) / 2, (cols - 1) / 2, 1500.0)
    crs = coords.utm_crs(g.lon, g.lat)
    x, y = coords.transformer("EPSG:4326", crs).transform(float(g.lon), float(g.lat))
    x, y = round(x), round(y)
    grid = OutputGrid.from_bounds(crs, (x - half, y - half, x + half, y + half), 0.5)
    out.append(("dg-apriori (13 par., const DEM)", dg, 1500.0, grid, None))
    return out


def per_pixel(size: int, repeat: int) -> None:
    from geoblock.dem.intersect import as_dem_source
    from geoblock.ortho.accuracy import accuracy_job
    from geoblock.ortho.lattice import source_coordinates

    print(f"\n== in-process, one thread, {size} x {size} px grid, 1024-px chunks "
          f"(best of {repeat}) ==")
    print(f"{'case':34s} {'layer ns/px':>12s} {'coords ns/px':>13s} {'ratio':>6s}")
    for label, model, dem, grid, post in _cases(size):
        job = accuracy_job(model, dem, grid, dem_sigma=5.0, posterior=post, chunks=1024)
        dem_src = as_dem_source(dem)
        n = grid.shape[0] * grid.shape[1]

        def layer(job=job):
            for w in job.windows():
                job.chunk(w)

        def geometry(model=model, dem_src=dem_src, grid=grid, job=job):
            for w in job.windows():
                source_coordinates(model, dem_src, grid,
                                   window=(slice(w[0], w[1]), slice(w[2], w[3])))

        layer()  # warm-up: numba kernels, DEM reads
        geometry()
        t_layer = min(_timed(layer) for _ in range(repeat))
        t_geo = min(_timed(geometry) for _ in range(repeat))
        print(f"{label:34s} {t_layer / n * 1e9:12.1f} {t_geo / n * 1e9:13.1f} "
              f"{t_layer / t_geo:6.2f}")


def _timed(func) -> float:
    t0 = time.perf_counter()
    func()
    return time.perf_counter() - t0


def whole_commands(directory: Path, repeat: int) -> None:
    from bench_ortho_cli import geoblock_cmd, make_coarse, run

    from geoblock.io import open_model, write_model
    from geoblock.models import ImageCorrection

    case = make_coarse(directory)
    model = ImageCorrection(open_model(case["source"]), 1)
    model_json = str(directory / "spot2_rpcv1.json")
    write_model(model, model_json, posterior=_posterior(model))
    out = str(directory / "ortho.tif")
    acc = str(directory / "ortho_accuracy.tif")
    runs = {
        "geoblock ortho": geoblock_cmd(case, out, ["--model", model_json]),
        "geoblock ortho --accuracy-layer": geoblock_cmd(
            case, out, ["--model", model_json, "--accuracy-layer", acc, "--dem-sigma", "10"]),
    }
    print(f"\n== whole commands: {case['size']} x {case['size']} px at {case['res']} m "
          f"(SPOT-2 RPC + RPCV-1 posterior), best / median of {repeat} ==")
    best = {}
    for label, cmd in runs.items():
        run(cmd)  # warm-up
        times = [run(cmd) for _ in range(repeat)]
        best[label] = min(times)
        print(f"{label:34s} {min(times):7.2f} s  {statistics.median(times):7.2f} s")
    extra = best["geoblock ortho --accuracy-layer"] - best["geoblock ortho"]
    n = case["size"] ** 2
    print(f"{'accuracy layer, added':34s} {extra:7.2f} s  ({extra / n * 1e9:.0f} ns/px, "
          f"{extra / best['geoblock ortho'] * 100:.0f} % of the ortho)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--size", type=int, default=4096, help="side of the in-process grid")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--keep", type=Path, default=None, help="data directory to reuse/keep")
    ap.add_argument("--quick", action="store_true", help="1024 px, one repeat")
    args = ap.parse_args()
    size, repeat = (1024, 1) if args.quick else (args.size, args.repeat)
    print(f"{platform.processor() or platform.machine()}, {os.cpu_count()} cpus, "
          f"python {platform.python_version()}")
    per_pixel(size, repeat)
    directory = args.keep or Path(tempfile.mkdtemp(prefix="bench-accuracy-"))
    try:
        whole_commands(directory, repeat)
    finally:
        if args.keep is None:
            shutil.rmtree(directory, ignore_errors=True)


if __name__ == "__main__":
    main()
