"""Simulate a scenario into a directory: files, block file and report (``geoblock simulate``).

:func:`run_scenario` builds the scene of a :class:`~geoblock.simulate.scenario.Scenario`
step by step (:mod:`geoblock.simulate.scene`: sensors, true terrain, measured DEMs, points,
rendered images), writes each component through :mod:`geoblock.io` as soon as it is made,
writes a block file for the adjustment engine and reports the on-board models' accuracy
(Markdown and CSV tables, PNG figures through :mod:`geoblock.report`). Everything is
deterministic for the scenario's seed: the same scenario gives the same files, byte for byte
(except ``timings.json``).
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from geoblock import coords
from geoblock.adjust import PointErrors
from geoblock.adjust.statistics import IctpDiscrepancies, ictp_accuracy
from geoblock.errors import GeoblockError
from geoblock.io import BlockDem, BlockImage, write_block, write_image, write_model
from geoblock.io.blocks import Block
from geoblock.io.files import make_directory, save_figure, write_csv, write_json, write_text
from geoblock.pixels import image_domain
from geoblock.simulate.points import PointSet
from geoblock.simulate.scenario import Scenario, write_scenario
from geoblock.simulate.scene import (
    scene_dem,
    scene_grid,
    scene_image,
    scene_points,
    scene_sensors,
    scene_texture,
    true_terrain,
)
from geoblock.simulate.sensors import SimulatedSensor, incidence_angle
from geoblock.simulate.study import onboard_errors, refinement_points
from geoblock.simulate.terrain import Terrain

__all__ = ["ScenarioResult", "footprint_rows", "run_scenario"]

Progress = Callable[[str], None]
"""Called with a one-line message at each stage."""


@dataclass(frozen=True, eq=False)
class ScenarioResult:
    """What :func:`run_scenario` made.

    Attributes
    ----------
    scenario : Scenario
    outdir : pathlib.Path
    files : mapping of str to pathlib.Path
        Every file written, by a short key (``truth``, ``dem:dem40``, ``image:strip1``,
        ``true_model:strip1``, ``onboard_model:strip1``, ``points:ground``, ``block``,
        ``report``...).
    sensors : mapping of str to SimulatedSensor
        By image id: true and on-board models.
    truth : Terrain
    dems : mapping of str to Terrain
    points : PointSet
    onboard : PointErrors
        The on-board models' ground errors at the GCPs and ICPs (per measurement).
    ictp : IctpDiscrepancies or None
        The on-board models' discrepancies at the ICTPs (None without ICTPs).
    notes : tuple of str
        What was skipped or reduced, and why (also in the report).
    timings : mapping of str to float
        Seconds per stage.
    """

    scenario: Scenario
    outdir: Path
    files: Mapping[str, Path]
    sensors: Mapping[str, SimulatedSensor]
    truth: Terrain
    dems: Mapping[str, Terrain]
    points: PointSet
    onboard: PointErrors
    ictp: IctpDiscrepancies | None
    notes: tuple[str, ...]
    timings: Mapping[str, float]

    @property
    def dem_path(self) -> Path:
        """The block's DEM file (the first measured DEM)."""
        return self.files[f"dem:{self.scenario.dems[0].name}"]


def _no_progress(message: str) -> None:
    return None


def run_scenario(
    scenario: Scenario,
    outdir: str | os.PathLike[str],
    *,
    progress: Progress | None = None,
    render: bool | None = None,
) -> ScenarioResult:
    """Simulate a scenario into ``outdir`` (created if needed; existing files are replaced).

    Files (paths relative to ``outdir``)::

        scenario.toml                 the scenario, fully resolved (runs again as is)
        block.toml                    block file for the adjustment engine (on-board models)
        terrain/truth.tif             the true terrain (GeoTIFF stating its vertical datum)
        terrain/<dem>.tif             each measured DEM
        images/<id>.tif               raw image rendered through the true model (if rendered)
        images/<id>_true.json         the true model
        images/<id>_onboard.json      the on-board model (what a user would be given)
        points/ground.csv             GCPs and ICPs (surveyed, with noise)
        points/image.csv              image measurements of every kind (with noise)
        points/truth.csv              the truth of every measurement
        report/report.md              footprints and on-board accuracy, the tables below
        report/footprints.csv
        report/onboard_accuracy.csv   per image and kind (GCP, ICP): RMSE, mean, max
        report/ictp_accuracy.csv      per strip pair, when there are ICTPs
        report/errors_<id>.png        error vectors of the on-board model (GCPs, ICPs)
        report/residual_vs_distance.png   with report.distance_plot
        report/rmse_vs_gcps_<image>.png   with report.gcp_study
        timings.json                  seconds per stage (the only file that changes run to run)

    Images larger than ``scenario.render.max_pixels`` are not rendered (a note says so).

    Parameters
    ----------
    scenario : Scenario
    outdir : str or os.PathLike
    progress : callable, optional
        Called with a one-line message at each stage.
    render : bool, optional
        Override ``scenario.render.enabled``.

    Returns
    -------
    ScenarioResult

    Raises
    ------
    GeoblockIOError
        A file or directory cannot be written (names it).
    GeoblockError
        The scene cannot be simulated (e.g. too few points can be placed).
    """
    say = progress or _no_progress
    out = Path(outdir)
    for sub in ("terrain", "images", "points", "report"):
        make_directory(out / sub)
    files: dict[str, Path] = {}
    timings: dict[str, float] = {}
    notes: list[str] = []
    start = time.perf_counter()
    clock = [start]

    def lap(stage: str) -> None:
        now = time.perf_counter()
        timings[stage] = round(now - clock[0], 3)
        clock[0] = now

    files["scenario"] = write_scenario(out / "scenario.toml", scenario)

    # --- sensors
    say(f"sensors: {len(scenario.images)} image(s)")
    sims = scene_sensors(scenario)
    for im in scenario.images:
        rows, cols = im.spec.shape
        say(f"  {im.id}: {rows} x {cols} px, GSD {im.spec.gsd_m:g} m, on-board RMSE "
            f"{im.spec.onboard_rmse_m:g} m")
    lap("sensors")

    # --- terrain
    t = scenario.terrain
    grid = scene_grid(scenario, sims)
    say(f"terrain: {t.kind} {t.relief[0]:g}-{t.relief[1]:g} m on {grid.shape[0]} x "
        f"{grid.shape[1]} posts of {t.resolution_m:g} m ({grid.crs.name})")
    truth = true_terrain(scenario, grid)
    files["truth"] = truth.write(out / "terrain" / "truth.tif")
    true_dem = truth.to_dem()
    lap("terrain")
    dems = {}
    for k, d in enumerate(scenario.dems):
        say(f"DEM {d.name}: {d.spacing_m:g} m posts, RMSEz {d.rmse_z:g} m")
        dems[d.name] = scene_dem(scenario, truth, k)
        files[f"dem:{d.name}"] = dems[d.name].write(out / "terrain" / f"{d.name}.tif")
    lap("dems")

    # --- models
    for image_id, sim in sims.items():
        files[f"true_model:{image_id}"] = write_model(
            sim.true_model, out / "images" / f"{image_id}_true.json")
        files[f"onboard_model:{image_id}"] = write_model(
            sim.onboard_model, out / "images" / f"{image_id}_onboard.json")

    # --- points
    say("points: GCPs and ICPs per image, TPs and ICTPs per overlap")
    pts = scene_points(scenario, sims, true_dem)
    for key, path in pts.write(out / "points").items():
        files[f"points:{key}"] = path
    say("  " + ", ".join(f"{pts.count(k)} {k.upper()}s" for k in ("gcp", "icp", "tp", "ictp")))
    lap("points")

    # --- images
    do_render = scenario.render.enabled if render is None else bool(render)
    rasters: dict[str, Path] = {}
    if do_render:
        texture = scene_texture(scenario, sims)
        for image_id, sim in sims.items():
            rows, cols = sim.spec.shape
            if rows * cols > scenario.render.max_pixels:
                note = (f"image {image_id} not rendered: {rows} x {cols} px is more than "
                        f"render.max_pixels = {scenario.render.max_pixels} (a full-size render "
                        "would take more than a few minutes; the models and points are "
                        "complete, use the small variant to look at images)")
                notes.append(note)
                say(f"  {note}")
                continue
            say(f"rendering {image_id}: {rows} x {cols} px")
            rendered = scene_image(scenario, sims, image_id, true_dem, texture)
            path = out / "images" / f"{image_id}.tif"
            write_image(path, rendered.pixels, nodata=0,
                        tags={"GEOBLOCK_SIMULATED": "rendered by geoblock.simulate.render",
                              "GEOBLOCK_MODEL": f"{image_id}_true.json",
                              "GEOBLOCK_ONBOARD_MODEL": f"{image_id}_onboard.json"})
            files[f"image:{image_id}"] = rasters[image_id] = path
    else:
        notes.append("images not rendered (render disabled)")
        say("images: not rendered (render disabled)")
    lap("render")

    # --- block file
    first = scenario.dems[0].name
    block = Block(
        images=tuple(BlockImage(i, files[f"onboard_model:{i}"], rasters.get(i))
                     for i in sims),
        method=scenario.method, ground_points=files["points:ground"],
        image_points=files["points:image"], truth=files["points:truth"],
        dem=BlockDem(str(files[f"dem:{first}"]), sigma=scenario.dems[0].rmse_z or None),
        name=scenario.name,
        outputs={"directory": out / "adjusted", "report": out / "adjusted" / "report.md"},
    )
    files["block"] = write_block(out / "block.toml", block)

    # --- accuracy of the on-board models
    say("report: on-board accuracy at GCPs and ICPs, ICTP discrepancies")
    onboard = onboard_errors(sims, pts)
    ictp = None
    sel = pts.image.kind == "ictp"
    if sel.any():
        ictp = ictp_accuracy({i: s.onboard_model for i, s in sims.items()}, pts.image.id[sel],
                             pts.image.image[sel], pts.image.row[sel], pts.image.col[sel],
                             dems[first].to_dem(), warn=False)
    files.update(_write_report(scenario, out / "report", sims, truth, dems, pts, onboard, ictp,
                               notes))
    lap("report")
    timings["total"] = round(time.perf_counter() - start, 3)
    files["timings"] = write_json(out / "timings.json", timings, indent=2)
    say(f"done in {timings['total']:.1f} s: {out}")
    return ScenarioResult(scenario, out, files, sims, truth, dems, pts, onboard, ictp,
                          tuple(notes), timings)


# ================================================================================ report
def footprint_rows(sensors: Mapping[str, SimulatedSensor]) -> list[dict[str, Any]]:
    """Per image: size, GSD, incidence, centre and corners of the true footprint (at the
    scene centre's height), and the on-board model's shift at the centre.

    Parameters
    ----------
    sensors : mapping of str to SimulatedSensor
        By image id.

    Returns
    -------
    list of dict
        One row per image: ``image, rows, cols, gsd_m, incidence_deg, centre_lon,
        centre_lat, width_km, length_km, corner1_lon ... corner4_lat`` (image corners,
        clockwise from the first pixel's outer corner), ``onboard_rmse_asked_m``,
        ``onboard_rmse_grid_m``, ``onboard_centre_de_m, onboard_centre_dn_m`` (metres).
    """
    rows_out = []
    for image_id, sim in sensors.items():
        spec = sim.spec
        rows, cols = spec.shape
        h = spec.centre_h
        rc, cc = (rows - 1) / 2.0, (cols - 1) / 2.0
        r0, c0, r1, c1 = image_domain(spec.shape)
        corners_r = np.array([r0, r0, r1, r1])
        corners_c = np.array([c0, c1, c1, c0])
        g = sim.true_model.backproject(corners_r, corners_c, np.full(4, h))
        c_true = sim.true_model.backproject(rc, cc, h)
        c_ob = sim.onboard_model.backproject(rc, cc, h)
        de, dn, _ = coords.enu_offsets(*c_true, *c_ob)
        width = float(np.hypot(*coords.enu_offsets(g.lon[0], g.lat[0], h, g.lon[1], g.lat[1],
                                                   h)[:2]))
        length = float(np.hypot(*coords.enu_offsets(g.lon[0], g.lat[0], h, g.lon[3], g.lat[3],
                                                    h)[:2]))
        err = sim.onboard_error()
        rows_out.append({
            "image": image_id, "rows": rows, "cols": cols, "gsd_m": spec.gsd_m,
            "incidence_deg": round(incidence_angle(sim.true_model, rc, cc, h), 3),
            "centre_lon": float(c_true.lon), "centre_lat": float(c_true.lat),
            "width_km": width / 1e3, "length_km": length / 1e3,
            **{f"corner{k + 1}_lon": float(g.lon[k]) for k in range(4)},
            **{f"corner{k + 1}_lat": float(g.lat[k]) for k in range(4)},
            "onboard_rmse_asked_m": spec.onboard_rmse_m,
            "onboard_rmse_grid_m": err.rmse,
            "onboard_centre_de_m": float(de), "onboard_centre_dn_m": float(dn),
        })
    return rows_out


def _ground_rows(points: PointSet, ids: np.ndarray) -> np.ndarray:
    """Row of each of ``ids`` in ``points.ground``."""
    index = {pid: i for i, pid in enumerate(points.ground.id.tolist())}
    return np.array([index[i] for i in ids.tolist()], dtype=np.intp)


def _figures(scenario: Scenario, folder: Path, sims: Mapping[str, SimulatedSensor],
             pts: PointSet, onboard: PointErrors) -> tuple[dict[str, Path], list[str]]:
    """The report's PNG figures (error vectors per image; with ``report.distance_plot`` the
    error against the distance from the image centre; with ``report.gcp_study`` the ICP RMSE
    against the number of GCPs) and the Markdown of the GCP study."""
    from geoblock.adjust.statistics import distance_from_image_centre
    from geoblock.report import (
        error_vector_plot,
        residual_vs_distance,
        rmse_vs_gcp_count,
        to_local_en,
    )
    from geoblock.simulate.study import gcp_count_study, refined_errors

    files: dict[str, Path] = {}
    # error vectors of the on-board model per image, GCPs triangles, ICPs circles
    for image_id in sims:
        sel = onboard.select(image=image_id)
        if not len(sel):
            continue
        k = _ground_rows(pts, sel.id)
        e, n = to_local_en(pts.ground.lon_true[k], pts.ground.lat_true[k],
                           pts.ground.h_true[k])
        fig = error_vector_plot(e, n, sel.e, sel.n, sel.kind,
                                title=f"{image_id}: on-board model at GCPs and ICPs")
        files[f"report:errors_{image_id}"] = save_figure(
            fig, folder / f"errors_{image_id}.png", dpi=150)
    study_md: list[str] = []
    if not (scenario.report.distance_plot or scenario.report.gcp_study):
        return files, study_md
    series = {}
    for image_id, sim in sims.items():
        gcps, icps = refinement_points(pts, image_id)
        sel = onboard.select(image=image_id, kind="ICP")
        if not len(sel) or icps is None:
            continue
        k = _ground_rows(pts, sel.id)
        d = distance_from_image_centre(sim.true_model, pts.ground.lon_true[k],
                                       pts.ground.lat_true[k], pts.ground.h_true[k])
        series[f"{image_id} on-board"] = (d, np.hypot(sel.e, sel.n))
        if gcps is None:
            continue
        d_icp = distance_from_image_centre(sim.true_model, icps.lon, icps.lat, icps.h)
        for order, label in ((0, "RPCV-0"), (1, "RPCV-1")):
            try:
                err = refined_errors(sim.onboard_model, gcps, icps, order)
            except GeoblockError:  # too few GCPs in this image for the order
                continue
            series[f"{image_id} {label}, {len(gcps)} GCPs"] = (d_icp, err)
        if scenario.report.gcp_study:
            counts = [n for n in (3, 6, 9, 18, 27, 45) if n <= len(gcps)]
            if len(gcps) not in counts:
                counts.append(len(gcps))
            study = gcp_count_study(sim.onboard_model, gcps, icps, counts=counts,
                                    repeats=10, seed=scenario.seed)
            fig = rmse_vs_gcp_count(study.series(),
                                    title=f"{image_id}: ICP RMSE after refinement vs GCPs")
            files[f"report:rmse_vs_gcps_{image_id}"] = save_figure(
                fig, folder / f"rmse_vs_gcps_{image_id}.png", dpi=150)
            study_md += [f"### {image_id}", "",
                         "RMSE 2D at the ICPs (m), mean (min-max) over 10 random GCP "
                         "subsets:", "", study.table().rstrip(), "",
                         f"![{image_id}](rmse_vs_gcps_{image_id}.png)", ""]
    if scenario.report.distance_plot and series:
        fig = residual_vs_distance(series,
                                   title="2D error at ICPs vs distance from the image centre")
        files["report:residual_vs_distance"] = save_figure(
            fig, folder / "residual_vs_distance.png", dpi=150)
    return files, study_md


def _write_report(scenario: Scenario, folder: Path, sims: Mapping[str, SimulatedSensor],
                  truth: Terrain, dems: Mapping[str, Terrain], pts: PointSet,
                  onboard: PointErrors, ictp: IctpDiscrepancies | None,
                  notes: Sequence[str]) -> dict[str, Path]:
    """The report's tables (CSV), figures (PNG) and ``report.md`` in ``folder``."""
    from geoblock.report import stats_table

    files: dict[str, Path] = {}
    fp = footprint_rows(sims)
    files["report:footprints"] = write_csv(folder / "footprints.csv", fp)
    by = onboard.by_image_and_kind()
    files["report:onboard_accuracy"] = write_text(
        folder / "onboard_accuracy.csv", stats_table(by, labels=("image", "kind"), fmt="csv"))
    ictp_md = ""
    if ictp is not None and len(ictp):
        pairs = {f"{a} & {b}": s for (a, b), s in ictp.by_pair().items()}
        files["report:ictp_accuracy"] = write_text(
            folder / "ictp_accuracy.csv", stats_table(pairs, labels=("pair",), fmt="csv"))
        ictp_md = stats_table(pairs, labels=("pair",))
    figures, study_md = _figures(scenario, folder, sims, pts, onboard)
    files.update(figures)

    lines = [f"# {scenario.name}", "", scenario.description, "",
             f"Seed {scenario.seed}; source `{scenario.source}`.", ""]
    if notes:
        lines += ["Notes:", ""] + [f"- {n}" for n in notes] + [""]
    lines += ["## Images and footprints", "",
              "| image | size (px) | GSD (m) | incidence (deg) | centre lon, lat | footprint (km) "
              "| on-board RMSE asked / over the image (m) |",
              "|---|---|---|---|---|---|---|"]
    for r in fp:
        lines.append(
            f"| {r['image']} | {r['rows']} x {r['cols']} | {r['gsd_m']:.3g} | "
            f"{r['incidence_deg']:.2f} | {r['centre_lon']:.4f}, {r['centre_lat']:.4f} | "
            f"{r['width_km']:.1f} x {r['length_km']:.1f} | {r['onboard_rmse_asked_m']:.1f} / "
            f"{r['onboard_rmse_grid_m']:.1f} |")
    lo, hi = truth.relief
    lines += ["", "## Terrain and DEMs", "",
              f"True terrain: {scenario.terrain.kind}, {lo:.0f}-{hi:.0f} m above the "
              f"{truth.vertical}, {truth.shape[0]} x {truth.shape[1]} posts of "
              f"{scenario.terrain.resolution_m:g} m, steepest slope "
              f"{float(np.nanmax(truth.slope_deg())):.1f} deg (`terrain/truth.tif`).", ""]
    for d in scenario.dems:
        dem = dems[d.name]
        lines.append(f"- `terrain/{d.name}.tif`: {dem.shape[0]} x {dem.shape[1]} posts of "
                     f"{d.spacing_m:g} m, RMSEz {d.rmse_z:g} m against the truth")
    counts = ", ".join(f"{pts.count(k)} {k.upper()}s" for k in ("gcp", "icp", "tp", "ictp"))
    lines += ["", "## Points", "", f"{counts}; {len(pts.image)} image measurements "
              f"(pointing noise {scenario.points.sigma_px:g} px, survey noise "
              f"{scenario.points.sigma_e:g} / {scenario.points.sigma_n:g} / "
              f"{scenario.points.sigma_h:g} m E/N/U). Files: `points/ground.csv`, "
              "`points/image.csv`, `points/truth.csv`; block file `block.toml`.", ""]
    lines += ["## Accuracy of the on-board models", "",
              "Ground error of each image's on-board model at the GCPs and ICPs: the true image "
              "position backprojected at the true height, minus the true ground position "
              "(metres, local east/north): the error a user starts from before any "
              "adjustment.", "",
              stats_table(by, labels=("image", "kind")).rstrip(), ""]
    for image_id in sims:
        if f"report:errors_{image_id}" in files:
            lines.append(f"![{image_id}](errors_{image_id}.png)")
    lines.append("")
    if ictp_md:
        lines += ["## ICTP discrepancies between images", "",
                  "Each ICTP measurement (with its pointing noise) ray-traced onto the DEM "
                  f"`{scenario.dems[0].name}` through its image's on-board model; discrepancy = "
                  "second image's ground point minus the first's (Teo et al.'s relative "
                  "accuracy).", "", ictp_md.rstrip(), ""]
    if "report:residual_vs_distance" in files:
        lines += ["## Error against the distance from the image centre", "",
                  "2D error at the ICPs of the on-board model, and after RPCV-0 (shift) and "
                  "RPCV-1 (affine) image-space corrections fitted to all the image's GCPs "
                  "(Aguilar et al. Fig. 4): what a shift cannot absorb (an along-track drift) "
                  "grows with the distance from the image centre.", "",
                  "![residual vs distance](residual_vs_distance.png)", ""]
    if study_md:
        lines += ["## ICP accuracy against the number of GCPs", "",
                  "RPCV-0 and RPCV-1-style corrections of the on-board model fitted to random "
                  "subsets of the GCPs (Aguilar et al. Figs. 3, 6, 7).", ""] + study_md
    files["report"] = write_text(folder / "report.md", "\n".join(lines) + "\n")
    return files
