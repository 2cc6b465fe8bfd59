"""Make the walk-through's figures from its outputs (docs/user-guide/walkthrough-ventoux.md).

Run the page's commands in a directory (tests/docs/test_walkthrough_ventoux.py does), then::

    python docs/user-guide/img/make_ventoux_images.py WORKDIR

It writes ``ventoux-before-after.png`` (the two mosaics side by side, at full resolution
around the overlap) and ``ventoux-residuals-right.png`` (the adjustment's residual plot of
the right image) beside this script.
"""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import rasterio  # noqa: E402

HERE = Path(__file__).resolve().parent


def _window(path: Path, x0: float, y0: float, width: int, height: int) -> np.ndarray:
    """``height x width`` pixels from map point ``(x0, y0)`` (top left) down and right."""
    with rasterio.open(path) as ds:
        row, col = ds.index(x0, y0)
        band = ds.read(1, window=((row, row + height), (col, col + width))).astype(float)
        band[band == ds.nodata] = np.nan
    return band


def main(workdir: Path) -> None:
    # the same 150 x 100 m of ground in both mosaics, in the two orthos' overlap
    with rasterio.open(workdir / "after_mosaic.tif") as ds:
        x0 = ds.bounds.left + 0.25 * (ds.bounds.right - ds.bounds.left)
        y0 = ds.bounds.top - 0.42 * (ds.bounds.top - ds.bounds.bottom)
        res = ds.res[0]
    size = (int(150 / res), int(100 / res))
    before = _window(workdir / "before_mosaic.tif", x0, y0, *size)
    after = _window(workdir / "after_mosaic.tif", x0, y0, *size)
    lo, hi = np.nanpercentile(after, [1, 99])
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.6), layout="constrained")
    for ax, data, title in ((axes[0], before, "before: vendor RPCs"),
                            (axes[1], after, "after: RPCV-1 from geoblock match + adjust")):
        ax.imshow(data, cmap="gray", vmin=lo, vmax=hi, interpolation="nearest")
        ax.set_title(title, fontsize=10)
        ax.set_axis_off()
    fig.savefig(HERE / "ventoux-before-after.png", dpi=90)
    shutil.copyfile(workdir / "adjusted" / "residuals_right.png",
                    HERE / "ventoux-residuals-right.png")


if __name__ == "__main__":
    main(Path(sys.argv[1]))
