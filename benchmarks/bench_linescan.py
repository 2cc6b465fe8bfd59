"""Speed and memory of the state-vector pushbroom model (geoblock.models.linescan).

Run: ``python benchmarks/bench_linescan.py [--quick] [--points N]``. The model is
``LinescanModel.example`` at 6000 x 6000 pixels (2.5 m GSD, 700 km, attitude in the orbital
frame sampled every 0.05 s) with all twelve correction parameters non-zero. Image points are
uniform over the image, heights uniform in -500..9000 m; their ground points are the inputs of
the projection. Prints best-of-N wall time, throughput, the peak of memory allocated during
one call (tracemalloc) and the round-trip error. Nothing is asserted.
"""

from __future__ import annotations

import argparse
import warnings

import numpy as np
from _measure import measure  # benchmarks/_measure.py (run as a script)

import geoblock
from geoblock.models import SensorModelBase
from geoblock.models.linescan import LinescanModel


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="10x fewer points")
    parser.add_argument("--points", type=int, default=1_000_000, help="points (default 10^6)")
    args = parser.parse_args()
    n = args.points // (10 if args.quick else 1)
    warnings.simplefilter("error")
    rng = np.random.default_rng(0)
    values = np.linspace(1.0, 2.0, 12) * np.repeat([1.0, 0.1, 1e-5, 1e-6], 3)
    model = LinescanModel.example(shape=(6000, 6000)).with_parameters(values)
    rows, cols = model.shape
    r = rng.uniform(-0.5, rows - 0.5, n)
    c = rng.uniform(-0.5, cols - 0.5, n)
    h = rng.uniform(-500.0, 9000.0, n)
    print(f"geoblock {geoblock.__version__}, numpy {np.__version__}; {model!r}")
    measure(f"linescan backproject, ray/height surface ({n} pts)",
            lambda: model.backproject(r, c, h), n)
    g = model.backproject(r, c, h)
    measure(f"linescan project, secant time search ({n} pts)",
            lambda: model.project(g.lon, g.lat, g.h), n)
    rr, cc = model.project(g.lon, g.lat, g.h)
    print(f"  round trip: max |d row| {np.max(np.abs(rr - r)):.2e} px, "
          f"max |d col| {np.max(np.abs(cc - c)):.2e} px")
    m = n // 10
    measure(f"linescan partials_ground, implicit ({m} pts)",
            lambda: model.partials_ground(g.lon[:m], g.lat[:m], g.h[:m]), m, repeat=2)
    measure(f"linescan partials_ground, numeric base class ({m} pts)",
            lambda: SensorModelBase.partials_ground(model, g.lon[:m], g.lat[:m], g.h[:m]), m,
            repeat=2)
    measure(f"linescan partials_parameters, implicit ({m} pts)",
            lambda: model.partials_parameters(g.lon[:m], g.lat[:m], g.h[:m]), m, repeat=2)
    m = n // 100
    measure(f"linescan partials_parameters, numeric base class ({m} pts)",
            lambda: SensorModelBase.partials_parameters(model, g.lon[:m], g.lat[:m], g.h[:m]),
            m, repeat=2)


if __name__ == "__main__":
    main()
