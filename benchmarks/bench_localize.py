"""localize throughput: image points -> ground on a DEM, for an RPC model.

Run: ``python benchmarks/bench_localize.py [--points N] [--quick]``.

Two set-ups: the synthetic ``RpcModel.example()`` (10 000 x 12 000 px near Nice) over a
30 m synthetic GridDem with 800 m of relief, and (when the shared data is present) the
Ventoux Pleiades RPC (``shareloc/rectification/left_image.geom``) over SRTM N44E005 + EGM96.
For each: points per second of ``method="robust"`` and ``"ray-tracing"`` (best of 3 after a
warm-up), the statuses, the number of DEM/model evaluation rounds, and the accuracy: the
maximum ``|h - dem(lon, lat)|`` and the re-projection residual in pixels.
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np

import geoblock
from geoblock.dem import GridDem

REPO = Path(__file__).resolve().parents[1]
DATA_DIR = Path(os.environ.get("GEOBLOCK_TEST_DATA", REPO.parent / "shared" / "data"))


def synthetic():
    from geoblock_rpc.model import RpcModel

    model = RpcModel.example()
    res = 30.0 / 111_000
    lon0, lat0, n = 6.98, 43.78, 1000
    lon = lon0 + (np.arange(n) + 0.5) * res
    lat = lat0 - (np.arange(n) + 0.5) * res
    x, y = np.meshgrid(lon, lat)
    z = 600 + 400 * np.sin(x * 300) * np.cos(y * 200)
    return "RpcModel.example() + 30 m synthetic DEM", model, GridDem(
        z, (res, 0, lon0, 0, -res, lat0), "EPSG:4326")


def ventoux():
    shareloc = DATA_DIR / "shareloc"
    model = geoblock.open_model(shareloc / "rectification/left_image.geom")
    dem = geoblock.open_dem(shareloc / "dtm/srtm_ventoux/srtm90_non_void_filled/N44E005.hgt",
                            geoid=shareloc / "dtm/geoid/egm96_15.gtx", nodata="fill")
    return "Ventoux Pleiades RPC + SRTM 90 m + EGM96", model, dem


def run(name, model, dem, n, repeat):
    rng = np.random.default_rng(0)
    rows, cols = model.shape
    row = rng.uniform(0, rows - 1, n)
    col = rng.uniform(0, cols - 1, n)
    print(f"\n{name}: {n} points")
    print(f"{'method':<12} {'pts/s':>10} {'best s':>8} {'converged':>10} "
          f"{'max|h-dem| m':>13} {'max resid px':>13}")
    for method in ("robust", "ray-tracing"):
        geoblock.localize(model, row[:100], col[:100], dem, method=method, warn=False)
        best = np.inf
        for _ in range(repeat):
            t = time.perf_counter()
            g, status = geoblock.localize(model, row, col, dem, method=method, warn=False)
            best = min(best, time.perf_counter() - t)
        ok = status == 0
        dz = np.abs(g.h[ok] - dem.height(g.lon[ok], g.lat[ok])).max() if ok.any() else np.nan
        (r, c), _ = model.project_with_status(g.lon[ok], g.lat[ok], g.h[ok])
        resid = np.hypot(r - row[ok], c - col[ok]).max() if ok.any() else np.nan
        print(f"{method:<12} {n / best:>10.0f} {best:>8.3f} {ok.sum():>10d} {dz:>13.2e} "
              f"{resid:>13.2e}  statuses {np.bincount(status, minlength=7).tolist()}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=100_000)
    parser.add_argument("--quick", action="store_true", help="10^4 points, 1 timed call")
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    n = 10_000 if args.quick else args.points
    repeat = 1 if args.quick else args.repeat
    setups = [synthetic]
    if DATA_DIR.is_dir() and hasattr(geoblock, "open_dem"):
        setups.append(ventoux)
    else:
        print(f"(Ventoux set-up skipped: no data at {DATA_DIR})")
    for setup in setups:
        run(*setup(), n, repeat)


if __name__ == "__main__":
    main()
