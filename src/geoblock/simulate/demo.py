"""``geoblock demo``: the project's main job on built-in data (first form).

:func:`run_demo` simulates a small three-strip SPOT-5 block (the ``teo2010-spot5`` preset,
small variant: 600 x 600 px strips at 100 m with their true and on-board models, a 0-3800 m
true terrain and a 40 m measured DEM, GCPs, ICPs, TPs and ICTPs), orthorectifies each raw
image with its ON-BOARD model (what a user is given) on the measured DEM, mosaics the orthos
and writes a short report: footprints, the on-board models' accuracy at the check points,
the ICTP discrepancies between strips and a PNG quicklook of the mosaic with the strips'
outlines. The misregistration of the on-board models shows in the mosaic at the seams; the
block adjustment, when it comes, will remove it.
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

from geoblock.errors import GeoblockError

__all__ = ["DEMO_SIZES", "DemoResult", "demo_scenario", "run_demo"]

#: Sizes of the demo: ``small`` (the default: the teo2010-spot5 small preset) and ``tiny``
#: (200 x 200 px strips at 300 m, a 200 m DEM: a few seconds, for tests).
DEMO_SIZES = ("small", "tiny")


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
    scenario: Any
    seconds: float


def demo_scenario(size: str = "small", seed: int | None = None) -> Any:
    """The demo's :class:`~geoblock.simulate.scenario.Scenario`."""
    from geoblock.simulate.scenario import preset_dict, scenario_from_dict

    if size not in DEMO_SIZES:
        raise GeoblockError(f"demo: unknown size {size!r}; known: {', '.join(DEMO_SIZES)}")
    data = preset_dict("teo2010-spot5", "small")
    if size == "tiny":
        for image in data["images"]:
            image["scale"] = 120
        data["terrain"]["resolution_m"] = 300.0
        data["dems"] = [{"name": "dem200", "spacing_m": 200.0, "rmse_z": 10.0}]
        data["points"].update(icp=9, tp=[8, 12], ictp=[4, 6])
        data["name"] = "teo2010-spot5-tiny"
    data["description"] += "; the geoblock demo"
    if seed is not None:
        data["seed"] = int(seed)
    return scenario_from_dict(data, f"demo:{size}")


def run_demo(
    outdir: str | os.PathLike[str] = "geoblock-demo",
    *,
    size: str = "small",
    seed: int | None = None,
    progress: Callable[[str], None] | None = None,
    quicklook_width: int = 1024,
) -> DemoResult:
    """Simulate, orthorectify with the on-board models, mosaic and report (module docstring).

    Files in ``outdir``: ``report.md``, ``quicklook.png``, ``mosaic.tif`` (feathered mosaic,
    UTM), ``contribution.tif`` (which strip each mosaic pixel came from), ``orthos/<id>.tif``
    and the simulated block in ``block/`` (see
    :func:`~geoblock.simulate.scenario.run_scenario`).

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

    Returns
    -------
    DemoResult
    """
    from geoblock import coords
    from geoblock.io import open_dem, write_ortho
    from geoblock.ortho import OutputGrid, mosaic, orthorectify
    from geoblock.ortho.mosaic import open_ortho
    from geoblock.simulate.scenario import run_scenario

    say = progress or (lambda message: None)
    start = time.perf_counter()
    out = Path(outdir)
    scenario = demo_scenario(size, seed)
    say(f"[1/4] simulating {scenario.name}: {scenario.description}")
    sim = run_scenario(scenario, out / "block", progress=lambda m: say(f"      {m}"),
                       render=True)

    say("[2/4] orthorectifying each image with its ON-BOARD model on the measured DEM")
    (out / "orthos").mkdir(parents=True, exist_ok=True)
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
    report = _report(out, sim, orthos, mosaic_path, quicklook, seconds)
    say(f"done in {seconds:.0f} s: {report}")
    return DemoResult(out, report, quicklook, mosaic_path, orthos, sim, seconds)


def _outline(model: Any, dem: Any, crs: Any, n: int = 24) -> tuple[np.ndarray, np.ndarray]:
    """The image outline on the DEM (pixel edges), in ``crs`` coordinates, closed."""
    from geoblock import coords
    from geoblock.dem import localize

    rows, cols = model.shape
    t = np.linspace(0.0, 1.0, n, endpoint=False)
    r0, r1, c0, c1 = -0.5, rows - 0.5, -0.5, cols - 0.5
    row = np.concatenate([np.full(n, r0), r0 + (r1 - r0) * t, np.full(n, r1),
                          r1 - (r1 - r0) * t])
    col = np.concatenate([c0 + (c1 - c0) * t, np.full(n, c1), c1 - (c1 - c0) * t,
                          np.full(n, c0)])
    ground, _ = localize(model, row, col, dem, warn=False)
    x, y = coords.transformer("EPSG:4326", crs).transform(ground.lon, ground.lat)
    x, y = np.asarray(x, float), np.asarray(y, float)
    return np.append(x, x[:1]), np.append(y, y[:1])


def _quicklook(mosaic_path: Path, sim: Any, dem: Any, path: Path, width: int) -> Path:
    """A PNG of the mosaic (downsampled by block averages) with each strip's outline."""
    import pyproj
    import rasterio
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from geoblock.report import save_figure

    with rasterio.open(mosaic_path) as ds:
        band = ds.read(1, masked=True)
        transform = ds.transform
        crs = pyproj.CRS.from_wkt(ds.crs.to_wkt())
    rows, cols = band.shape
    step = max(1, math.ceil(cols / max(int(width), 1)))
    r, c = rows // step * step, cols // step * step
    values = band.astype(np.float64).filled(np.nan)[:r, :c]
    with np.errstate(invalid="ignore"):
        blocks = values.reshape(r // step, step, c // step, step)
        ok = np.isfinite(blocks).sum(axis=(1, 3))
        small = np.where(ok > 0, np.nansum(blocks, axis=(1, 3)) / np.maximum(ok, 1), np.nan)
    x0, y0 = transform.c, transform.f
    extent = [x0 / 1e3, (x0 + c * transform.a) / 1e3, (y0 + r * transform.e) / 1e3, y0 / 1e3]
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


def _report(out: Path, sim: Any, orthos: dict[str, Path], mosaic_path: Path, quicklook: Path,
            seconds: float) -> Path:
    from geoblock.report import stats_table
    from geoblock.simulate.scenario import _write_text, footprint_rows

    scenario = sim.scenario
    fp = footprint_rows(sim.sensors, sim.truth)
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
    return _write_text(out / "report.md", "\n".join(lines))
