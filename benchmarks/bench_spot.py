"""Speed of the SPOT Chen & Lee model (geoblock-spot): project and backproject of 10^6 points.

Run: ``python benchmarks/bench_spot.py [--quick]``. The model is Chen & Lee's (1993) Table 1
orientation on a SPOT 1A 6000 x 6000 scene (``ChenLeeModel.table1()``). Image points are
uniform over the image (pixel edges included) with heights uniform in -500..9000 m; they are
backprojected, and the ground points so obtained are projected back. Prints one line per case:
best-of-N wall time, throughput, the peak of memory allocated by numpy during one call
(tracemalloc), and for the directions the round-trip error. Nothing here is asserted; the
figures go into the closing notes of the issues that change them. Then the same for the
DIMAP line-of-sight models of ``SPOT5.DIM`` (DIMAP v1) and ``SPOT6.XML`` (DIMAP v2) from the
shared test data (``GEOBLOCK_TEST_DATA`` or ``../shared/data``), skipped when absent.
"""

from __future__ import annotations

import argparse
import os
import warnings
from pathlib import Path

import numpy as np
from _measure import measure  # benchmarks/_measure.py (run as a script)
from geoblock_spot.chenlee import ChenLeeModel, Interior
from geoblock_spot.fit import fit_chenlee

import geoblock
from geoblock.adjust import ControlPoints, resect
from geoblock.testing.synthetic import ConstantVelocityPushbroom

HERE = Path(__file__).resolve()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="10x fewer points")
    args = parser.parse_args()
    scale = 10 if args.quick else 1
    warnings.simplefilter("error")
    rng = np.random.default_rng(0)
    model = ChenLeeModel.table1()
    print(f"geoblock {geoblock.__version__}, numpy {np.__version__}; {model!r}")

    n = 1_000_000 // scale
    row, col = rng.uniform(-0.5, 5999.5, n), rng.uniform(-0.5, 5999.5, n)
    h = rng.uniform(-500.0, 9000.0, n)
    g = model.backproject(row, col, h)
    r2, c2 = model.project(g.lon, g.lat, g.h)
    err = np.hypot(r2 - row, c2 - col)
    measure(f"chen-lee backproject, ray/height surface ({n} pts)",
            lambda: model.backproject(row, col, h), n)
    measure(f"chen-lee project, Newton on t ({n} pts)", lambda: model.project(g.lon, g.lat, g.h), n)
    print(f"  round trip project(backproject): max {err.max():.2e} px, "
          f"median {np.median(err):.2e} px")
    m = 100_000 // scale
    measure(f"chen-lee partials_ground, analytic ({m} pts)",
            lambda: model.partials_ground(g.lon[:m], g.lat[:m], g.h[:m]), m)
    measure(f"chen-lee partials_parameters, analytic ({m} pts)",
            lambda: model.partials_parameters(g.lon[:m], g.lat[:m], g.h[:m]), m)

    k = 21
    mba = model.mba(350.0)
    gcps = ControlPoints([str(i) for i in range(k)], g.lon[:k], g.lat[:k], g.h[:k],
                         row[:k] + 3.0, col[:k] - 2.0, sigma_row=0.2, sigma_col=0.2)
    measure(f"resect mba set (19 parameters, {k} GCPs)", lambda: resect(mba, gcps), k, repeat=3)
    push = ConstantVelocityPushbroom.example(shape=(6000, 6000), roll=0.1)
    # the synthetic pushbroom publishes no interior: its example's 2.5 m pixels from 700 km
    interior = Interior(pixel_size_m=1.082 * 2.5 / 700e3, focal_length_m=1.082,
                        line_period_s=2.5 / 7000.0)
    fit = fit_chenlee(push, interior=interior)
    print(f"  fit_chenlee to a 6000 x 6000 pushbroom: {fit.n_points} grid points, "
          f"max {fit.max_px:.2e} px, check max {fit.check_max_px:.2e} px")
    measure("fit_chenlee (15 x 15 x 5 grid)", lambda: fit_chenlee(push, interior=interior),
            fit.n_points, repeat=1)

    # the DIMAP line-of-sight models (geoblock's linescan model) of the shared test data
    data = Path(os.environ.get("GEOBLOCK_TEST_DATA", HERE.parents[2] / "shared" / "data"))
    for name in ("cosicorr3d/test_dataset/SPOT5.DIM", "cosicorr3d/test_dataset/SPOT6.XML"):
        path = data / name
        if not path.exists():
            print(f"  {name}: not in {data}, skipped")
            continue
        los = geoblock.open_model(path)
        rows, cols = los.shape
        lr = rng.uniform(-0.5, rows - 0.5, n)
        lc = rng.uniform(-0.5, cols - 0.5, n)
        lh = rng.uniform(-500.0, 9000.0, n)
        lg = los.backproject(lr, lc, lh)
        measure(f"{path.name} line of sight: backproject ({n} pts)",
                lambda los=los, lr=lr, lc=lc, lh=lh: los.backproject(lr, lc, lh), n)
        measure(f"{path.name} line of sight: project ({n} pts)",
                lambda los=los, lg=lg: los.project(lg.lon, lg.lat, lg.h), n)


if __name__ == "__main__":
    main()
