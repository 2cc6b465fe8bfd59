"""Regenerate accuracy-vectors.png and the tables of docs/user-guide/accuracy.md.

Run from the repository root: ``python docs/user-guide/img/make_accuracy_example.py``.
A synthetic pushbroom image whose true geometry has an affine image error (an RPCV-1 kind of
error); RPCV-0 (a shift) is fitted to 9 GCPs on a 3 x 3 grid and checked on 40 ICPs, so the
vectors keep the systematic part a shift cannot model.
"""

from pathlib import Path

import numpy as np

from geoblock import ImageCorrection
from geoblock.adjust import ControlPoints, PointErrors, resect
from geoblock.report import error_vector_plot, stats_table, to_local_en
from geoblock.testing.synthetic import ConstantVelocityPushbroom

rng = np.random.default_rng(42)
base = ConstantVelocityPushbroom.example(roll=0.01)          # 800 x 1000 px, 2.5 m GSD
truth = ImageCorrection(base, 1, [2.0, 0.8, -0.3, -1.5, 0.2, 0.6])  # pixels


def points(rows, cols, prefix, noise_px=0.3):
    h = rng.uniform(0.0, 1500.0, rows.size)
    g = truth.backproject(rows, cols, h)
    ids = [f"{prefix}{i}" for i in range(rows.size)]
    return ControlPoints(ids, g.lon, g.lat, g.h,
                         rows + rng.normal(0, noise_px, rows.size),
                         cols + rng.normal(0, noise_px, cols.size))


grid_r, grid_c = np.meshgrid([100.0, 400.0, 700.0], [120.0, 500.0, 880.0], indexing="ij")
gcps = points(grid_r.ravel(), grid_c.ravel(), "g")
icps = points(rng.uniform(0, 799, 40), rng.uniform(0, 999, 40), "i")
result = resect(ImageCorrection(base, 0), gcps, icps)       # RPCV-0

errors = PointErrors(
    id=np.r_[result.gcp.id, result.icp.id],
    kind=["GCP"] * len(gcps) + ["ICP"] * len(icps),
    e=np.r_[result.gcp.e, result.icp.e], n=np.r_[result.gcp.n, result.icp.n],
    row=np.r_[result.gcp.row, result.icp.row], col=np.r_[result.gcp.col, result.icp.col],
)
print(stats_table(errors.by_kind(), labels=("kind",)))
print(stats_table(errors.by_kind(image_space=True), labels=("kind",)))

e, n = to_local_en(np.r_[gcps.lon, icps.lon], np.r_[gcps.lat, icps.lat])
fig = error_vector_plot(e, n, errors.e, errors.n, errors.kind, figsize=(5.6, 5.8),
                        title="RPCV-0 fitted to 9 GCPs (synthetic pushbroom)")
out = Path(__file__).with_name("accuracy-vectors.png")
fig.savefig(out, dpi=90)
print(out, out.stat().st_size, "bytes")
