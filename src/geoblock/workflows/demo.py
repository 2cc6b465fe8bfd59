"""``geoblock demo``: the project's main job on built-in data.

:func:`run_demo` simulates a small three-strip SPOT-5 block (the ``teo2010-spot5`` preset,
small variant: 600 x 600 px strips at 100 m with their true and on-board models, a 0-3800 m
true terrain and a 40 m measured DEM, GCPs, ICPs, TPs and ICTPs;
:func:`~geoblock.simulate.scenario.demo_scenario`), orthorectifies each raw image with its
ON-BOARD model (what a user is given) on the measured DEM, mosaics the orthos and writes a
short report: footprints, the on-board models' accuracy at the check points, the ICTP
discrepancies between strips and a PNG quicklook of the mosaic with the strips' outlines.
The misregistration of the on-board models shows in the mosaic at the seams; the block
adjustment removes it.

Re-running into the same OUTDIR replaces the previous demo's outputs. A demo output is
recognised by the marker file :data:`DEMO_MARKER` (``OUTDIR/.geoblock-demo``), which
:func:`run_demo` writes first when OUTDIR is absent or empty (or already a demo output); only
the demo's own entries (:data:`DEMO_OUTPUTS`) are removed before the new run, anything else in
OUTDIR is left alone. A non-empty OUTDIR without the marker is refused
(:class:`~geoblock.errors.DemoOutdirError`) unless ``force=True``, which writes into it
(files of the same name are replaced) without marking it.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from geoblock.errors import DemoOutdirError, GeoblockIOError
from geoblock.io import open_dem, open_image, write_ortho
from geoblock.io.files import make_directory, read_text, remove, save_figure, write_text
from geoblock.pixels import image_domain
from geoblock.simulate.scenario import demo_scenario
from geoblock.workflows.scenario import ScenarioResult, footprint_rows, run_scenario

__all__ = [
    "DEMO_MARKER",
    "DEMO_OUTPUTS",
    "DemoResult",
    "is_demo_outdir",
    "prepare_demo_outdir",
    "run_demo",
]

#: The marker file :func:`run_demo` writes first in an OUTDIR it may replace on the next run.
DEMO_MARKER = ".geoblock-demo"

#: The entries :func:`run_demo` writes in OUTDIR (besides :data:`DEMO_MARKER`): what a re-run
#: into a demo output removes before writing anew.
DEMO_OUTPUTS = ("block", "orthos", "mosaic.tif", "contribution.tif", "report.md",
                "quicklook.png")

_MARKER_TEXT = """\
This directory was written by `geoblock demo`.
The next `geoblock demo` into it replaces the demo's outputs: block/, orthos/, mosaic.tif,
contribution.tif, report.md and quicklook.png (anything else is left alone).
Delete this file to protect the directory from being replaced.
"""


def is_demo_outdir(outdir: str | os.PathLike[str]) -> bool:
    """Whether ``outdir`` is a directory written by a previous :func:`run_demo`.

    True when it holds :data:`DEMO_MARKER`, or (demos made before the marker existed) when
    all its entries are demo outputs and its ``report.md`` starts with ``# geoblock demo``.
    """
    path = Path(outdir)
    if not path.is_dir() or path.is_symlink():
        return False
    if (path / DEMO_MARKER).is_file():
        return True
    names = {p.name for p in path.iterdir()}
    if not names or not names <= set(DEMO_OUTPUTS) or "report.md" not in names:
        return False
    try:
        text = read_text(path / "report.md")
    except GeoblockIOError:  # unreadable, or not UTF-8: not a demo's report
        return False
    return text.split("\n", 1)[0].strip() == "# geoblock demo"


def prepare_demo_outdir(outdir: str | os.PathLike[str], *, force: bool = False) -> bool:
    """Make ``outdir`` ready for :func:`run_demo`; return whether to mark it as a demo output.

    * absent or empty: ready (marked);
    * a previous demo output (:func:`is_demo_outdir`): its :data:`DEMO_OUTPUTS` are removed
      (anything else is kept), ready (marked);
    * any other non-empty directory: :class:`~geoblock.errors.DemoOutdirError` naming it,
      unless ``force`` (written into, files of the same name replaced, not marked);
    * not a directory: :class:`~geoblock.errors.DemoOutdirError`.
    """
    path = Path(outdir)
    if (path.exists() or path.is_symlink()) and not path.is_dir():
        raise DemoOutdirError(f"demo OUTDIR {str(path)!r} exists and is not a directory", path)
    if not path.exists() or not any(path.iterdir()):
        return True
    if is_demo_outdir(path):
        for name in DEMO_OUTPUTS:
            remove(path / name, "previous demo output ")
        return True
    if force:
        return False
    raise DemoOutdirError(
        f"demo OUTDIR {str(path)!r} exists, is not empty and is not the output of a previous "
        f"geoblock demo (it has no {DEMO_MARKER} marker file); choose another OUTDIR or empty "
        "this one", path)


@dataclass(frozen=True, eq=False)
class DemoResult:
    """What :func:`run_demo` made.

    Attributes
    ----------
    outdir : pathlib.Path
    report : pathlib.Path
        ``report.md``.
    quicklook : pathlib.Path
        ``quicklook.png``.
    mosaic : pathlib.Path
        ``mosaic.tif``.
    orthos : dict of str to pathlib.Path
    scenario : ScenarioResult
    seconds : float
        Wall time.
    """

    outdir: Path
    report: Path
    quicklook: Path
    mosaic: Path
    orthos: dict[str, Path]
    scenario: ScenarioResult
    seconds: float


def run_demo(
    outdir: str | os.PathLike[str] = "geoblock-demo",
    *,
    size: str = "small",
    seed: int | None = None,
    progress: Callable[[str], None] | None = None,
    quicklook_width: int = 1024,
    force: bool = False,
) -> DemoResult:
    """Simulate, orthorectify with the on-board models, mosaic and report (module docstring).

    Files in ``outdir``: ``report.md``, ``quicklook.png``, ``mosaic.tif`` (feathered mosaic,
    UTM), ``contribution.tif`` (which strip each mosaic pixel came from), ``orthos/<id>.tif``
    and the simulated block in ``block/`` (see
    :func:`~geoblock.workflows.scenario.run_scenario`), and the marker :data:`DEMO_MARKER`.
    A previous demo's outputs in ``outdir`` are replaced; any other non-empty ``outdir`` is
    refused unless ``force`` (:func:`prepare_demo_outdir`).

    Parameters
    ----------
    outdir : str or os.PathLike
    size : {"small", "tiny"}
    seed : int, optional
        Default: the preset's.
    progress : callable, optional
        Called with one-line messages.
    quicklook_width : int
        Largest width of the quicklook's image, pixels.
    force : bool
        Write into a non-empty ``outdir`` that is not a demo output (files of the same name
        are replaced; the directory is not marked as a demo output).

    Returns
    -------
    DemoResult

    Raises
    ------
    DemoOutdirError
        ``outdir`` is not a directory, or is a non-empty one that is not a demo output
        (without ``force``); nothing is written.
    ScenarioError
        Unknown ``size``.
    """
    from geoblock import coords
    from geoblock.ortho import OutputGrid, mosaic, orthorectify
    from geoblock.ortho.mosaic import open_ortho

    say = progress or (lambda message: None)
    start = time.perf_counter()
    out = Path(outdir)
    scenario = demo_scenario(size, seed)
    if prepare_demo_outdir(out, force=force):
        make_directory(out)
        write_text(out / DEMO_MARKER, _MARKER_TEXT)
    say(f"[1/4] simulating {scenario.name}: {scenario.description}")
    sim = run_scenario(scenario, out / "block", progress=lambda m: say(f"      {m}"),
                       render=True)

    say("[2/4] orthorectifying each image with its ON-BOARD model on the measured DEM")
    make_directory(out / "orthos")
    dem = open_dem(str(sim.dem_path))
    specs = {im.id: im.spec for im in scenario.images}
    lon0 = float(np.mean([s.centre_lon for s in specs.values()]))
    lat0 = float(np.mean([s.centre_lat for s in specs.values()]))
    crs = coords.utm_crs(lon0, lat0)
    resolution = float(min(s.gsd_m for s in specs.values()))
    orthos: dict[str, Path] = {}
    for image_id, sensor in sim.sensors.items():
        raster = sim.files[f"image:{image_id}"]
        grid = OutputGrid.for_model(sensor.onboard_model, dem, crs=crs, resolution=resolution)
        data = orthorectify(str(raster), sensor.onboard_model, dem, grid)
        orthos[image_id] = write_ortho(data, out / "orthos" / f"{image_id}.tif")
        say(f"      orthos/{image_id}.tif: {grid.shape[0]} x {grid.shape[1]} px of "
            f"{resolution:g} m ({crs.name})")

    say("[3/4] mosaicking (feathered seams)")
    ds = mosaic([open_ortho(p) for p in orthos.values()], method="feather", feather_px=16.0)
    mosaic_path = write_ortho(ds["mosaic"], out / "mosaic.tif")
    write_ortho(ds["contribution"].expand_dims(band=[1]), out / "contribution.tif")
    say(f"      mosaic.tif: {ds.sizes['y']} x {ds.sizes['x']} px")

    say("[4/4] report and quicklook")
    quicklook = _quicklook(mosaic_path, sim, dem, out / "quicklook.png", quicklook_width)
    seconds = time.perf_counter() - start
    report = write_text(out / "report.md", _report(sim, orthos, mosaic_path, quicklook, seconds))
    say(f"done in {seconds:.0f} s: {report}")
    return DemoResult(out, report, quicklook, mosaic_path, orthos, sim, seconds)


def _outline(model: Any, dem: Any, crs: Any, n: int = 24) -> tuple[np.ndarray, np.ndarray]:
    """The image outline on the DEM (pixel edges), in ``crs`` coordinates, closed."""
    from geoblock import coords
    from geoblock.dem import localize

    r0, c0, r1, c1 = image_domain(model.shape)
    t = np.linspace(0.0, 1.0, n, endpoint=False)
    row = np.concatenate([np.full(n, r0), r0 + (r1 - r0) * t, np.full(n, r1),
                          r1 - (r1 - r0) * t])
    col = np.concatenate([c0 + (c1 - c0) * t, np.full(n, c1), c1 - (c1 - c0) * t,
                          np.full(n, c0)])
    ground, _ = localize(model, row, col, dem, warn=False)
    x, y = coords.transformer("EPSG:4326", crs).transform(ground.lon, ground.lat)
    x, y = np.asarray(x, float), np.asarray(y, float)
    return np.append(x, x[:1]), np.append(y, y[:1])


def _quicklook(mosaic_path: Path, sim: ScenarioResult, dem: Any, path: Path,
               width: int) -> Path:
    """A PNG of the mosaic (downsampled by block averages) with each strip's outline."""
    import pyproj
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    source = open_image(mosaic_path)
    band = source.read()[0]
    values = band.astype(np.float64)
    if source.nodata is not None:  # as a masked read: nodata pixels are no data
        nodata = np.isnan(band) if np.isnan(source.nodata) else band == source.nodata
        values[nodata] = np.nan
    transform = source.transform
    crs = pyproj.CRS.from_wkt(source.crs.to_wkt())
    rows, cols = band.shape
    step = max(1, math.ceil(cols / max(int(width), 1)))
    r, c = rows // step * step, cols // step * step
    values = values[:r, :c]
    with np.errstate(invalid="ignore"):
        blocks = values.reshape(r // step, step, c // step, step)
        ok = np.isfinite(blocks).sum(axis=(1, 3))
        small = np.where(ok > 0, np.nansum(blocks, axis=(1, 3)) / np.maximum(ok, 1), np.nan)
    x0, y0 = transform.c, transform.f
    extent = (x0 / 1e3, (x0 + c * transform.a) / 1e3, (y0 + r * transform.e) / 1e3, y0 / 1e3)
    aspect = small.shape[0] / max(small.shape[1], 1)
    fig = Figure(figsize=(10.24, max(2.5, 10.24 * aspect + 1.2)), layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    ax.set_facecolor("#1b2631")
    ax.imshow(np.ma.masked_invalid(small), cmap="gray", extent=extent, interpolation="nearest",
              vmin=np.nanpercentile(small, 1), vmax=np.nanpercentile(small, 99))
    colours = ("#f39c12", "#2ecc71", "#3498db", "#e74c3c", "#9b59b6")
    for k, (image_id, sensor) in enumerate(sim.sensors.items()):
        x, y = _outline(sensor.onboard_model, dem, crs)
        ax.plot(x / 1e3, y / 1e3, color=colours[k % len(colours)], linewidth=1.2,
                label=image_id)
    ax.set_xlim(extent[0], extent[1])
    ax.set_ylim(extent[2], extent[3])
    ax.set_aspect("equal")
    ax.set_xlabel(f"E (km, {crs.name})")
    ax.set_ylabel("N (km)")
    ax.legend(loc="upper right", fontsize=8, framealpha=0.8)
    ax.set_title("geoblock demo: mosaic of the strips orthorectified with their ON-BOARD "
                 "models (outlines: on-board footprints)", fontsize=10)
    return save_figure(fig, path, dpi=100)


def _report(sim: ScenarioResult, orthos: dict[str, Path], mosaic_path: Path, quicklook: Path,
            seconds: float) -> str:
    """The demo's ``report.md``."""
    from geoblock.report import stats_table

    scenario = sim.scenario
    fp = footprint_rows(sim.sensors)
    lines = [
        "# geoblock demo", "",
        f"{scenario.description}.", "",
        "Three simulated SPOT-5 strips were rendered through their TRUE models, then "
        "orthorectified with their ON-BOARD models (the erroneous ephemeris and attitude a "
        "user is given) on the measured DEM and mosaicked. The on-board errors show as "
        "misregistration at the seams of the mosaic; the block adjustment removes them.", "",
        f"![quicklook]({quicklook.name})", "",
        "## Files", "",
        f"- `{mosaic_path.name}`: the mosaic (feathered), `contribution.tif`: which strip each "
        "pixel came from",
        *(f"- `orthos/{p.name}`: {i} orthorectified with its on-board model"
          for i, p in orthos.items()),
        "- `block/`: the simulated block (terrain, DEM, images with true and on-board models, "
        "points, `block.toml`, `report/report.md` with the error-vector figures)", "",
        "## Footprints", "",
        "| image | size (px) | GSD (m) | incidence (deg) | centre lon, lat | footprint (km) |",
        "|---|---|---|---|---|---|",
        *(f"| {r['image']} | {r['rows']} x {r['cols']} | {r['gsd_m']:.3g} | "
          f"{r['incidence_deg']:.2f} | {r['centre_lon']:.4f}, {r['centre_lat']:.4f} | "
          f"{r['width_km']:.1f} x {r['length_km']:.1f} |" for r in fp), "",
        "## Accuracy of the on-board models at the check points", "",
        "Ground error (m, local east/north) of each on-board model at the ICPs (and at the "
        "GCPs, which the adjustment will use), from the simulated truth:", "",
        stats_table(sim.onboard.by_image_and_kind(), labels=("image", "kind"),
                    columns=("n", "rmse_e", "rmse_n", "rmse_2d", "mean_e", "mean_n",
                             "max_2d")).rstrip(), "",
    ]
    if sim.ictp is not None and len(sim.ictp):
        pairs = {f"{a} & {b}": s for (a, b), s in sim.ictp.by_pair().items()}
        lines += ["## ICTP discrepancies between strips", "",
                  "The same independent check tie points ray-traced from each strip onto the "
                  "DEM with the on-board models: the misregistration between strips.", "",
                  stats_table(pairs, labels=("pair",),
                              columns=("n", "rmse_e", "rmse_n", "rmse_2d", "max_2d")).rstrip(),
                  ""]
    if sim.notes:
        lines += ["## Notes", "", *(f"- {n}" for n in sim.notes), ""]
    lines += [f"Made by `geoblock demo` in {seconds:.0f} s (seed {scenario.seed}).", ""]
    return "\n".join(lines)
