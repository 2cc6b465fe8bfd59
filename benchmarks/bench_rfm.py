"""Rational functions from points (geoblock-rpc): ``fit_rpc`` on full scenes and ``fit_rfm``
against the number of GCPs.

Run: ``python benchmarks/bench_rfm.py [--quick]``. Part 1 fits a sensor-oriented RPC to each
physical model in the shared data with the defaults (a 21 x 21 x 9 grid of virtual points
backprojected through the model, regularisation chosen by GCV, an independent 40 x 40 x 16
check grid), and prints best-of-3 wall time (grid generation included: what a user waits for),
peak numpy memory and the check-grid error. Part 2 fits RFM-1/2/3 to n GCPs (the simulated
QuickBird of Aguilar et al., 0.31 m pointing noise; n from 9 to 4000) and prints the time per
fit with and without ``order="auto"`` (leave-one-out cross-validation up to 100 GCPs,
10-fold above). Data from ``GEOBLOCK_TEST_DATA`` or ``../shared/data``; absent files are
skipped. Nothing is asserted; the figures go into closing notes.
"""

from __future__ import annotations

import argparse
import os
import warnings
from pathlib import Path

import numpy as np
from _measure import measure  # benchmarks/_measure.py (run as a script)
from geoblock_rpc.fit import fit_rpc
from geoblock_rpc.rfm import fit_rfm, minimum_gcps

import geoblock
from geoblock.adjust import ControlPoints
from geoblock.simulate.sensors import QUICKBIRD_SMALL, simulate_sensor

HERE = Path(__file__).resolve()
SCENES = ("cosicorr3d/test_dataset/SPOT5.DIM", "cosicorr3d/test_dataset/SPOT6.XML",
          "shareloc/rpc/PHRDIMAP_P1BP--2017030824934340CP.XML",
          "stereopipeline/tests/wv_test1.xml")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer scenes and GCP counts")
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    data = Path(os.environ.get("GEOBLOCK_TEST_DATA", HERE.parents[2] / "shared" / "data"))
    print(f"geoblock {geoblock.__version__}, numpy {np.__version__}")
    print("-- fit_rpc with the defaults (grid 21x21x9 = 3969 fit points, 25600 check points)")
    for name in SCENES[:2] if args.quick else SCENES:
        if not (data / name).exists():
            print(f"{name}: absent, skipped")
            continue
        model = geoblock.open_model(data / name)
        _, stats = fit_rpc(model)
        measure(f"fit_rpc {Path(name).name} ({model.shape[0]}x{model.shape[1]})",
                lambda m=model: fit_rpc(m), 3969)
        print(f"    {stats}")

    print("-- fit_rfm against the GCP count (simulated QuickBird, UTM frame)")
    truth = simulate_sensor(QUICKBIRD_SMALL).true_model
    rng = np.random.default_rng(0)
    rows, cols = truth.shape
    noise = 0.5 / 40
    for n in (9, 18, 45, 100) if args.quick else (9, 18, 45, 100, 400, 1000, 4000):
        r, c, h = rng.uniform(0, rows - 1, n), rng.uniform(0, cols - 1, n), rng.uniform(50, 850, n)
        g = truth.backproject(r, c, h)
        gcps = ControlPoints(np.arange(n).astype(str), g.lon, g.lat, h,
                             r + rng.normal(0, noise, n), c + rng.normal(0, noise, n),
                             sigma_row=noise, sigma_col=noise)
        for order in (1, 2, 3):
            if n >= minimum_gcps(order):
                measure(f"fit_rfm RFM-{order}, {n} GCPs",
                        lambda p=gcps, k=order: fit_rfm(p, order=k), n)
        if n > minimum_gcps(1):
            measure(f"fit_rfm order='auto', {n} GCPs", lambda p=gcps: fit_rfm(p, order="auto"),
                    n, repeat=1)


if __name__ == "__main__":
    main()
