"""DEM sampling speed: geoblock's RasterDem against rasterio's ``sample()`` and a plain
``scipy.ndimage.map_coordinates`` on the array in memory.

Data: the SRTM3 tile ``shareloc/dtm/srtm_ventoux/srtm90_non_void_filled/N44E005.hgt``
(1201 x 1201 int16, EGM96 heights) of the shared data (``$GEOBLOCK_TEST_DATA``, default
``../shared/data``) and ``egm96_15.gtx`` beside it. Queries: N uniform random (lon, lat) over
the tile. Time: the best of ``--repeat`` calls after a warm-up call (which fills geoblock's block
cache); heights per second = N / best time. rasterio's ``sample()`` is a per-point Python
generator, so it is timed on N / 10 points (``--sample-points``) and reported per height.

Run: ``python benchmarks/bench_dem.py [--points N] [--repeat R]``
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np


def best(fn, repeat):
    fn()
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=10**6)
    parser.add_argument("--sample-points", type=int, default=None)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()

    import rasterio
    from scipy.ndimage import map_coordinates

    import geoblock

    data = Path(os.environ.get("GEOBLOCK_TEST_DATA",
                               Path(__file__).resolve().parents[2] / "shared" / "data"))
    srtm = data / "shareloc/dtm/srtm_ventoux/srtm90_non_void_filled/N44E005.hgt"
    gtx = data / "shareloc/dtm/geoid/egm96_15.gtx"
    n = args.points
    rng = np.random.default_rng(0)
    lon = rng.uniform(5.0, 6.0, n)
    lat = rng.uniform(44.0, 45.0, n)
    rows = []

    for interp in ("nearest", "bilinear", "bicubic"):
        raw = geoblock.open_dem(srtm, vertical="ellipsoid", interpolation=interp)
        t = best(lambda raw=raw: raw.height(lon, lat), args.repeat)
        rows.append((f"geoblock RasterDem {interp}, file heights", n, t))
    dem = geoblock.open_dem(srtm, geoid=gtx, interpolation="bilinear")
    t = best(lambda: dem.height(lon, lat), args.repeat)
    rows.append(("geoblock RasterDem bilinear + EGM96 (ellipsoidal)", n, t))

    with rasterio.open(srtm) as ds:
        arr = ds.read(1).astype(np.float64)
        inv = ~ds.transform
        m = args.sample_points or max(n // 10, 1)
        pts = list(zip(lon[:m], lat[:m], strict=True))
        t = best(lambda: np.fromiter((v[0] for v in ds.sample(pts)), float, m), 1)
        rows.append(("rasterio DatasetReader.sample() (nearest)", m, t))
    arr[arr == -32768] = np.nan

    def scipy_bilinear(order):
        col, row = inv * (lon, lat)
        return map_coordinates(arr, [row - 0.5, col - 0.5], order=order, mode="nearest")

    rows.append(("scipy map_coordinates order=0 (array in memory)", n,
                 best(lambda: scipy_bilinear(0), args.repeat)))
    rows.append(("scipy map_coordinates order=1 (array in memory)", n,
                 best(lambda: scipy_bilinear(1), args.repeat)))

    print(f"{'method':<55} {'points':>9} {'best s':>9} {'Mheights/s':>11}")
    for name, count, t in rows:
        print(f"{name:<55} {count:>9} {t:>9.4f} {count / t / 1e6:>11.3f}")


if __name__ == "__main__":
    main()
