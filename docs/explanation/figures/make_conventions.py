"""Draw docs/explanation/figures/conventions.png: geoblock's coordinate conventions in one figure.

Run from the repository root: ``python docs/explanation/figures/make_conventions.py``. Four
panels: (a) image coordinates, geoblock's (row, col) with pixel centres at integers; (b) the
same pixels in GDAL's corner-based pixel/line; (c) heights: the ellipsoidal height h, the
geoid height H and the undulation N (h = H + N); (d) ECEF and a local east-north-up frame.
The conventions themselves are those of ``geoblock.pixels`` and ``geoblock.coords``; the
half-pixel relation drawn in (b) is computed with ``geoblock.pixels`` so that the figure
cannot drift from the code.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.patches import Arc, FancyArrowPatch, Rectangle  # noqa: E402

from geoblock.pixels import PIXEL_CENTRE  # noqa: E402

OUT = Path(__file__).with_name("conventions.png")
ROWS, COLS = 3, 4
INK = "#1a237e"
GDAL = "#c62828"
GREY = "#5f6b7a"
plt.rcParams.update({"font.size": 10, "font.family": "DejaVu Sans", "svg.hashsalt": "geoblock"})


def _pixels(ax: plt.Axes) -> None:
    """The 3 x 4 pixels as squares [r - 0.5, r + 0.5) x [c - 0.5, c + 0.5) in geoblock's frame."""
    for r in range(ROWS):
        for c in range(COLS):
            shade = "#e8eefc" if (r + c) % 2 == 0 else "#f7f9fe"
            ax.add_patch(Rectangle((c - 0.5, r - 0.5), 1, 1, facecolor=shade,
                                   edgecolor="#4a5a8a", lw=1.2))
    ax.set_xlim(-1.25, COLS + 0.35)
    ax.set_ylim(ROWS + 0.95, -1.35)  # rows grow downwards, as in an array
    ax.set_aspect("equal")
    ax.axis("off")


def _arrow(ax: plt.Axes, start: tuple[float, float], end: tuple[float, float], color: str,
           label: str = "", offset: tuple[float, float] = (0, 0), **kw) -> None:
    ax.add_patch(FancyArrowPatch(start, end, arrowstyle="-|>", mutation_scale=12, color=color,
                                 lw=1.4, **kw))
    if label:
        ax.text(end[0] + offset[0], end[1] + offset[1], label, color=color, ha="center",
                va="center")


def panel_geoblock(ax: plt.Axes) -> None:
    _pixels(ax)
    for r in range(ROWS):
        for c in range(COLS):
            ax.plot(c, r, "o", color=INK, ms=4)
            ax.text(c, r + 0.22, f"({r}, {c})", color=INK, ha="center", va="top", fontsize=8.5)
    _arrow(ax, (-0.5, -0.85), (COLS - 0.3, -0.85), GREY, "col", (0.25, 0))
    _arrow(ax, (-0.95, -0.5), (-0.95, ROWS - 0.2), GREY, "row", (0, 0.25))
    for c in (-0.5, 0.5, 1.5, 2.5, 3.5):
        ax.text(c, -0.62, f"{c:g}", ha="center", va="bottom", fontsize=7.5, color=GREY)
    for r in (-0.5, 0.5, 1.5, 2.5):
        ax.text(-0.58, r, f"{r:g}", ha="right", va="center", fontsize=7.5, color=GREY)
    ax.text(COLS / 2 - 0.5, ROWS + 0.3, "(row, col): integers at pixel CENTRES;\n"
            f"a {ROWS} x {COLS} image covers [-0.5, {ROWS - 0.5:g}) x [-0.5, {COLS - 0.5:g})\n"
            "numpy, scikit-image, RPC00B (LINE_OFF, SAMP_OFF)",
            ha="center", va="top", fontsize=8.5)
    ax.set_title("(a) geoblock: array[0, 0] is centred on (row, col) = (0, 0)", fontsize=10)


def panel_gdal(ax: plt.Axes) -> None:
    _pixels(ax)
    for r in range(ROWS):
        for c in range(COLS):
            ax.plot(c, r, "o", color=INK, ms=4, alpha=0.35)
    # GDAL pixel/line = geoblock (col, row) + PIXEL_CENTRE: integers at the pixel corners
    for line in range(ROWS + 1):
        for pixel in range(COLS + 1):
            x, y = pixel - PIXEL_CENTRE, line - PIXEL_CENTRE
            ax.plot(x, y, "s", color=GDAL, ms=3.5)
    ax.plot(-PIXEL_CENTRE, -PIXEL_CENTRE, "o", mfc="none", mec=GDAL, ms=13, mew=1.6)
    ax.text(-0.62, -0.62, "pixel/line (0, 0)", color=GDAL, ha="right", va="bottom", fontsize=8.5)
    ax.text(0, 0.22, "(0.5, 0.5)", color=GDAL, ha="center", va="top", fontsize=8.5)
    ax.text(1 + PIXEL_CENTRE, 1 + PIXEL_CENTRE + 0.05, "(2, 2)", color=GDAL, ha="left",
            va="top", fontsize=8.5)
    _arrow(ax, (-0.5, -0.85), (COLS - 0.3, -0.85), GDAL, "pixel", (0.3, 0))
    _arrow(ax, (-0.95, -0.5), (-0.95, ROWS - 0.2), GDAL, "line", (0, 0.25))
    ax.text(COLS / 2 - 0.5, ROWS + 0.3,
            "GDAL pixel/line, geotransforms, rasterio: integers at pixel CORNERS\n"
            "pixel = col + 0.5,  line = row + 0.5   (geoblock.pixels)\n"
            "X = GT[0] + pixel GT[1],  Y = GT[3] + line GT[5];  DIMAP: 1-based centres",
            ha="center", va="top", fontsize=8.5)
    ax.set_title("(b) the same pixels in GDAL's convention", fontsize=10)


def panel_heights(ax: plt.Axes) -> None:
    x = np.linspace(0.0, 10.0, 400)
    ellipsoid = 0.9 + 0.012 * (x - 5.0) ** 2 * -1 + 0.3  # a gently curved reference
    geoid = ellipsoid + 0.9 + 0.35 * np.sin(0.55 * x + 0.4)
    terrain = geoid + 0.25 + 1.3 * np.exp(-((x - 6.6) / 1.4) ** 2) + 0.15 * np.sin(2.3 * x)
    ax.fill_between(x, -0.4, terrain, color="#efe6d4", zorder=0)
    ax.plot(x, ellipsoid, color=INK, lw=1.8, label="WGS84 ellipsoid (h = 0)")
    ax.plot(x, geoid, color="#2e7d32", lw=1.6, ls="--", label="geoid, EGM96 (H = 0)")
    ax.plot(x, terrain, color="#6d4c41", lw=1.8, label="terrain (the DEM)")
    i = int(np.searchsorted(x, 6.6))
    xp, e, g, t = x[i], ellipsoid[i], geoid[i], terrain[i]
    ax.plot(xp, t, "o", color="black", ms=5, zorder=5)
    ax.text(xp + 0.15, t + 0.12, "P (lon, lat, h)", ha="left", va="bottom")
    # h and H beside P (dotted lines carry P's levels to them); N where it is, further left
    k = int(np.searchsorted(x, xp - 1.35))
    for x0, lo, hi, label, color, level in (
            (xp - 0.55, e, t, "h", INK, True), (xp + 0.55, g, t, "H", "#2e7d32", True),
            (x[k], ellipsoid[k], geoid[k], "N", "#8e24aa", False)):
        ax.add_patch(FancyArrowPatch((x0, lo), (x0, hi), arrowstyle="<|-|>", mutation_scale=10,
                                     color=color, lw=1.3))
        ax.text(x0 - 0.12, 0.5 * (lo + hi), label, color=color, ha="right", va="center",
                fontsize=12, fontweight="bold")
        if level:
            ax.plot([min(x0, xp), max(x0, xp)], [hi, hi], color=color, lw=0.6, ls=":")
            ax.plot([min(x0, xp), max(x0, xp)], [lo, lo], color=color, lw=0.6, ls=":")
    ax.text(0.3, 6.0, "h = H + N", fontsize=13, fontweight="bold", va="top")
    ax.text(0.3, 5.5, "h: metres above the WGS84 ellipsoid, everywhere in geoblock\n"
            "H: above the geoid (SRTM, most DEMs): converted when read\n"
            "N: geoid undulation, egm96_15.gtx (+51 m at Mont Ventoux)",
            fontsize=8.5, va="top")
    ax.legend(loc="lower right", fontsize=8, frameon=False)
    ax.set_xlim(0, 10)
    ax.set_ylim(-0.4, 6.1)
    ax.set_xticks([])
    ax.set_yticks([])
    for side in ("top", "right"):
        ax.spines[side].set_visible(False)
    ax.set_title("(c) heights: ellipsoidal h, geoid H, undulation N", fontsize=10)


def panel_frames(ax: plt.Axes) -> None:
    a, b = 1.0, 0.93  # a flattened meridian section (exaggerated)
    t = np.linspace(0, 2 * np.pi, 400)
    ax.fill(a * np.cos(t), b * np.sin(t), color="#eef3fb", zorder=0)
    ax.plot(a * np.cos(t), b * np.sin(t), color=INK, lw=1.4)
    ax.plot([-1.15, 1.15], [0, 0], color=GREY, lw=0.6, ls=":")
    _arrow(ax, (0, 0), (1.45, 0), GREY, "x", (0.08, -0.08))
    _arrow(ax, (0, 0), (0, 1.4), GREY, "z", (-0.08, 0.06))
    _arrow(ax, (0, 0), (-0.55, -0.5), GREY, "y", (-0.06, -0.06))
    ax.text(1.45, -0.2, "lon 0, lat 0", ha="center", va="top", fontsize=8, color=GREY)
    ax.text(0.06, 1.38, "north pole", ha="left", va="center", fontsize=8, color=GREY)
    # a point at geodetic latitude 40 deg on the section
    lat = np.radians(40.0)
    beta = np.arctan(b / a * np.tan(lat))  # parametric latitude of the point of normal `lat`
    p = np.array([a * np.cos(beta), b * np.sin(beta)])
    up = np.array([np.cos(lat), np.sin(lat)])
    north = np.array([-np.sin(lat), np.cos(lat)])
    ax.plot(*p, "o", color="black", ms=5, zorder=5)
    _arrow(ax, tuple(p), tuple(p + 0.5 * up), "#2e7d32", "up (U)", 0.14 * up)
    _arrow(ax, tuple(p), tuple(p + 0.5 * north), "#2e7d32", "north (N)", 0.16 * north)
    ax.plot(p[0], p[1], marker="$\\odot$", color="#2e7d32", ms=11)
    ax.text(p[0] + 0.13, p[1] - 0.1, "east (E):\nout of the page", color="#2e7d32", fontsize=8,
            ha="left", va="top")
    # the geodetic latitude: the angle of the ellipsoid normal with the equatorial plane
    foot = p - up * (p[1] / up[1])
    ax.plot([foot[0], p[0]], [foot[1], p[1]], color="#8e24aa", lw=0.9, ls="--")
    ax.add_patch(Arc(tuple(foot), 0.5, 0.5, theta1=0, theta2=40, color="#8e24aa", lw=1.2))
    ax.text(foot[0] + 0.3, foot[1] + 0.08, "lat", color="#8e24aa", fontsize=9)
    ax.text(-1.45, -1.08,
            "ECEF x, y, z: metres, EPSG:4978 (partials, lines of sight)\n"
            "lon, lat: degrees, h: metres, EPSG:4979 (public API), lon first\n"
            "local ENU (LocalFrame): east, north, up metres at an origin\n"
            "(Teo et al.'s work frame; the adjustment's point unknowns)",
            fontsize=8.5, va="top")
    ax.set_xlim(-1.5, 1.9)
    ax.set_ylim(-1.75, 1.55)
    ax.set_aspect("equal")
    ax.axis("off")
    ax.set_title("(d) ECEF and a local east-north-up frame (geodetic latitude)", fontsize=10)


def main() -> Path:
    fig, axes = plt.subplots(2, 2, figsize=(11.0, 9.4))
    panel_geoblock(axes[0, 0])
    panel_gdal(axes[0, 1])
    panel_heights(axes[1, 0])
    panel_frames(axes[1, 1])
    fig.suptitle("geoblock's conventions: one per quantity", fontsize=12, fontweight="bold")
    fig.tight_layout(rect=(0, 0, 1, 0.97))
    fig.savefig(OUT, dpi=100, metadata={"Software": None})
    plt.close(fig)
    return OUT


if __name__ == "__main__":
    print(main())
