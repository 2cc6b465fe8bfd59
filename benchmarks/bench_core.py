"""Speed and memory of the core's hot paths, with PROJ (pyproj) as the peer where one exists.

Run: ``python benchmarks/bench_core.py [--quick]``. Prints one line per case: best-of-N wall
time, throughput, and the peak of memory allocated by numpy during one call (tracemalloc).
Nothing here is asserted; the figures go into the closing notes of the issues that change them.
"""

from __future__ import annotations

import argparse
import warnings

import _measure  # benchmarks/_measure.py (run as a script)
import numpy as np
import pyproj

import geoblock
from geoblock import coords
from geoblock.adjust import ControlPoints, resect
from geoblock.testing.synthetic import AffineCamera, ConstantVelocityPushbroom


def measure(label, func, n_points, repeat=5):
    return _measure.measure(label, func, n_points, repeat)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="10x fewer points")
    args = parser.parse_args()
    scale = 10 if args.quick else 1
    warnings.simplefilter("error")
    rng = np.random.default_rng(0)

    n = 1_000_000 // scale
    lon, lat, h = rng.uniform(-180, 180, n), rng.uniform(-85, 85, n), rng.uniform(-100, 9000, n)
    fwd = pyproj.Transformer.from_crs("EPSG:4979", "EPSG:4978", always_xy=True)
    inv = pyproj.Transformer.from_crs("EPSG:4978", "EPSG:4979", always_xy=True)
    x, y, z = coords.geodetic_to_ecef(lon, lat, h)
    print(f"geoblock {geoblock.__version__}, numpy {np.__version__}, pyproj {pyproj.__version__}")
    measure(
        f"geodetic -> ECEF, geoblock ({n} pts)", lambda: coords.geodetic_to_ecef(lon, lat, h), n
    )
    measure(f"geodetic -> ECEF, pyproj ({n} pts)", lambda: fwd.transform(lon, lat, h), n)
    measure(f"ECEF -> geodetic, geoblock ({n} pts)", lambda: coords.ecef_to_geodetic(x, y, z), n)
    measure(f"ECEF -> geodetic, pyproj ({n} pts)", lambda: inv.transform(x, y, z), n)

    affine = AffineCamera.example()
    push = ConstantVelocityPushbroom.example(roll=0.01)
    n = 100_000 // scale
    r, c = rng.uniform(-0.5, 999.5, n), rng.uniform(-0.5, 1199.5, n)
    hh = rng.uniform(0, 2000, n)
    g = affine.backproject(r, c, hh)
    measure(f"affine project, analytic ({n} pts)", lambda: affine.project(g.lon, g.lat, g.h), n)
    measure(f"affine backproject, Newton ({n} pts)", lambda: affine.backproject(r, c, hh), n)
    measure(f"affine partials_ground, analytic ({n} pts)",
            lambda: affine.partials_ground(g.lon, g.lat, g.h), n)
    measure(f"affine partials_ground, numeric ({n} pts)",
            lambda: geoblock.SensorModelBase.partials_ground(affine, g.lon, g.lat, g.h), n)
    n = 10_000 // scale
    r, c, hh = r[:n] * 0.8, c[:n] * 0.8, hh[:n]
    gp = push.backproject(r, c, hh)
    measure(f"pushbroom backproject, ray/surface ({n} pts)", lambda: push.backproject(r, c, hh), n)
    measure(f"pushbroom project, Newton on backproject ({n} pts)",
            lambda: push.project(gp.lon, gp.lat, gp.h), n)
    corr = geoblock.ImageCorrection(push, 2, np.linspace(-1, 1, 12))
    measure(f"order-2 correction backproject ({n} pts)", lambda: corr.backproject(r, c, hh), n)

    m = 100
    gc = ControlPoints([str(i) for i in range(m)], gp.lon[:m], gp.lat[:m], gp.h[:m],
                       r[:m] + 1.0, c[:m] - 2.0)
    measure(f"resect RPCV-1 on the pushbroom ({m} GCPs)",
            lambda: resect(geoblock.ImageCorrection(push, 1), gc), m)


if __name__ == "__main__":
    main()
