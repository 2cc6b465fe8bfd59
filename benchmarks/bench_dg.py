"""Speed of the DigitalGlobe rigorous model (geoblock-quickbird) beside the SPOT models.

Run: ``python benchmarks/bench_dg.py [--quick]``. For each model, 10^6 image points uniform
over the image (pixel edges included) with heights uniform over the model's height range are
backprojected, and the ground points so obtained projected back. Prints, per case, best-of-3
wall time, throughput and the peak of memory numpy allocated during one call (tracemalloc),
and the round-trip error. The models: the WorldView-2 ``wv_test1.xml`` of the shared test
data, with all light-path corrections (the default) and without them (the cost of the
corrections), and the SPOT 5 and SPOT 6 DIMAP models (the same linescan engine without
corrections) for comparison. Data from ``GEOBLOCK_TEST_DATA`` or ``../shared/data``; a model
whose file is absent is skipped. Nothing is asserted; the figures go into closing notes.
"""

from __future__ import annotations

import argparse
import os
import warnings
from pathlib import Path

import numpy as np
from _measure import measure  # benchmarks/_measure.py (run as a script)
from geoblock_quickbird.model import dg_model

import geoblock

HERE = Path(__file__).resolve()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="10x fewer points")
    args = parser.parse_args()
    n = 1_000_000 // (10 if args.quick else 1)
    warnings.simplefilter("error")
    rng = np.random.default_rng(0)
    data = Path(os.environ.get("GEOBLOCK_TEST_DATA", HERE.parents[2] / "shared" / "data"))
    print(f"geoblock {geoblock.__version__}, numpy {np.__version__}; {n} points per call")
    wv = data / "stereopipeline/tests/wv_test1.xml"
    cases = []
    if wv.exists():
        cases += [("WV02 dg-rigorous, corrections on", geoblock.open_model(wv)),
                  ("WV02 dg-rigorous, no corrections", dg_model(wv, corrections=()))]
    for name in ("cosicorr3d/test_dataset/SPOT5.DIM", "cosicorr3d/test_dataset/SPOT6.XML"):
        if (data / name).exists():
            cases.append((f"{Path(name).name} linescan (DIMAP)", geoblock.open_model(data / name)))
    if not cases:
        print(f"no model files in {data}: nothing to measure")
        return
    for label, model in cases:
        rows, cols = model.shape
        h0, h1 = model.height_range
        row, col = rng.uniform(-0.5, rows - 0.5, n), rng.uniform(-0.5, cols - 0.5, n)
        h = rng.uniform(h0, h1, n)
        g = model.backproject(row, col, h)
        p = model.project(g.lon, g.lat, g.h)
        err = np.hypot(p.row - row, p.col - col)
        measure(f"{label}: backproject", lambda m=model, r=row, c=col, hh=h: m.backproject(
            r, c, hh), n)
        measure(f"{label}: project", lambda m=model, g=g: m.project(g.lon, g.lat, g.h), n)
        print(f"  round trip: max {err.max():.2e} px, median {np.median(err):.2e} px")


if __name__ == "__main__":
    main()
