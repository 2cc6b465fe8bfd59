"""``geoblock demo``: the whole pipeline on built-in data, before and after the adjustment.

:func:`run_demo` runs six stages on a simulated block with known truth:

1. **simulate** the ``teo2010-spot5`` small block
   (:func:`~geoblock.simulate.scenario.demo_scenario`: three 600 x 600 px SPOT-5 strips at
   100 m with their true and on-board models, a 0-3800 m true terrain, a 40 m measured DEM,
   GCPs, ICPs, TPs and ICTPs, raw images rendered through the TRUE models) into ``block/``,
   with its block file ``block/block.toml``;
2. **single adjustment**: each strip alone with its GCPs (no TP, no DEM), and
3. **block adjustment**: all strips with GCPs, TPs and the DEM elevation control of the TPs;
   both by the block engine exactly as ``geoblock adjust block/block.toml`` runs it (the
   block file's method, ``dg``: direct-georeferencing biases and drifts of the linescan
   models, then least-squares collocation, :data:`geoblock.adjust.METHODS`), written as
   ``geoblock adjust`` writes them (:func:`geoblock.report.write_result`) into
   ``adjustment/single/`` and ``adjustment/block/``;
4. **orthorectify** each strip on the measured DEM with its ON-BOARD model (what a user is
   given: ``onboard/orthos/``) and with its BLOCK-ADJUSTED model (``orthos/``), and, in
   memory only, with its TRUE model (the reference of the seam measurement);
5. **mosaic** both sets with feathered seams (``onboard/mosaic.tif``; ``mosaic.tif`` and
   ``contribution.tif``);
6. **measure and report**: every model set's ground errors at the GCPs and ICPs from the
   simulated truth and its ICTP discrepancies, the seamline discrepancies measured ON THE
   IMAGES (:class:`~geoblock.match.seams.SeamShift`: the shift between neighbouring orthos in
   their overlap, by robust least-squares matching, :func:`~geoblock.match.seams.seam_shift`;
   between the true-model orthos it is the measurement's own error), ``report.md`` with the
   before/after tables, ``results.json`` with the same numbers, and the figures
   ``quicklook.png`` (before and after mosaics), ``errors.png`` (error vectors) and
   ``seams.png`` (the overlaps' differences).

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
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace
from typing import TYPE_CHECKING, Any

import numpy as np

from geoblock.errors import DemoOutdirError, GeoblockIOError
from geoblock.io import open_dem, open_image, write_ortho
from geoblock.io.files import (
    make_directory,
    read_text,
    remove,
    save_figure,
    write_json,
    write_text,
)
from geoblock.io.images import read_band
from geoblock.match.seams import (
    SEAM_MARGIN_PX,
    SEAM_SEGMENTS,
    SEAM_SMOOTHING_PX,
    SeamShift,
    on_common_grid,
    overlapping_pairs,
    seam_shift,
    smoothed_overlap,
)
from geoblock.pixels import image_domain
from geoblock.simulate.scenario import demo_scenario
from geoblock.workflows.scenario import ScenarioResult, footprint_rows, run_scenario

if TYPE_CHECKING:
    from affine import Affine
    from matplotlib.axes import Axes

    from geoblock.adjust.block import BlockResult
    from geoblock.adjust.statistics import AccuracyStats, IctpDiscrepancies, PointErrors
    from geoblock.dem.protocol import DemSource
    from geoblock.models.protocol import SensorModel
    from geoblock.typing import Float64Array

__all__ = [
    "DEMO_MARKER",
    "DEMO_OUTPUTS",
    "MODEL_SETS",
    "SEAM_SETS",
    "DemoResult",
    "SeamShift",  # re-exported from geoblock.match.seams, where it is defined
    "is_demo_outdir",
    "prepare_demo_outdir",
    "run_demo",
    "seam_shift",  # re-exported from geoblock.match.seams
]

#: The marker file :func:`run_demo` writes first in an OUTDIR it may replace on the next run.
DEMO_MARKER = ".geoblock-demo"

#: The entries :func:`run_demo` writes in OUTDIR (besides :data:`DEMO_MARKER`): what a re-run
#: into a demo output removes before writing anew.
DEMO_OUTPUTS = ("block", "adjustment", "onboard", "orthos", "mosaic.tif", "contribution.tif",
                "report.md", "results.json", "quicklook.png", "errors.png", "seams.png")

#: The model sets the demo compares, by key: label in the report.
MODEL_SETS = {"onboard": "on-board", "single": "single", "block": "block"}
#: The ortho sets whose seams are measured: the reference (TRUE models, known in simulation
#: only: the measurement's own error), before and after.
SEAM_SETS = {"true": "true", "onboard": "on-board", "block": "block-adjusted"}

_MARKER_TEXT = f"""\
This directory was written by `geoblock demo`.
The next `geoblock demo` into it replaces the demo's outputs: {", ".join(DEMO_OUTPUTS)}
(anything else is left alone).
Delete this file to protect the directory from being replaced.
"""

_STAGES = 6

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


# ================================================================================ results
@dataclass(frozen=True, eq=False)
class DemoResult:
    """What :func:`run_demo` made.

    Attributes
    ----------
    outdir : pathlib.Path
    report : pathlib.Path
        ``report.md``.
    quicklook : pathlib.Path
        ``quicklook.png``: the mosaics before and after the adjustment.
    mosaic : pathlib.Path
        ``mosaic.tif``: the mosaic of the block-adjusted orthos.
    orthos : dict of str to pathlib.Path
        The block-adjusted orthos (``orthos/<id>.tif``), by image id.
    scenario : ScenarioResult
        The simulated block (``block/``).
    seconds : float
        Wall time.
    mosaic_onboard : pathlib.Path
        ``onboard/mosaic.tif``.
    orthos_onboard : dict of str to pathlib.Path
        ``onboard/orthos/<id>.tif``.
    single, block : geoblock.adjust.BlockResult
        The single and block adjustments (written in ``adjustment/single/`` and
        ``adjustment/block/``).
    accuracy : dict of str to PointErrors
        Per model set (:data:`MODEL_SETS`: ``onboard``, ``single``, ``block``): the ground
        error at every GCP and ICP measurement from the simulated truth
        (:func:`~geoblock.simulate.study.onboard_errors`: the true image position located
        through the model at the true height, minus the true ground position).
    ictp : dict of str to IctpDiscrepancies
        Per model set: the ICTP discrepancies (measured image positions ray-traced onto the
        measured DEM).
    seams : dict of str to dict of (str, str) to SeamShift
        Per ortho set (:data:`SEAM_SETS`: ``true``, ``onboard``, ``block``): the seam shift
        of each pair of overlapping orthos, as measured.
    seam_discrepancies : dict of str to dict of (str, str) to SeamShift
        ``onboard`` and ``block``: the seam shift less the true-model orthos' one
        (:meth:`SeamShift.minus`): the misregistration the models cause at each seam.
    timings : dict of str to float
        Seconds per stage.
    """

    outdir: Path
    report: Path
    quicklook: Path
    mosaic: Path
    orthos: dict[str, Path]
    scenario: ScenarioResult
    seconds: float
    mosaic_onboard: Path
    orthos_onboard: dict[str, Path]
    single: BlockResult
    block: BlockResult
    accuracy: dict[str, PointErrors]
    ictp: dict[str, IctpDiscrepancies]
    seams: dict[str, dict[tuple[str, str], SeamShift]]
    seam_discrepancies: dict[str, dict[tuple[str, str], SeamShift]]
    timings: dict[str, float]


class _Stages:
    """Progress lines: ``[k/6] title`` per stage, indented details, each stage's time."""

    def __init__(self, say: Callable[[str], None]) -> None:
        self.say = say
        self.timings: dict[str, float] = {}
        self._key = ""
        self._start = time.perf_counter()

    def begin(self, k: int, key: str, title: str) -> None:
        self._key, self._start = key, time.perf_counter()
        self.say(f"[{k}/{_STAGES}] {title}")

    def detail(self, message: str) -> None:
        self.say(f"      {message}")

    def elapsed(self) -> float:
        """Seconds since the current stage began (also recorded as its time)."""
        seconds = time.perf_counter() - self._start
        self.timings[self._key] = round(seconds, 3)
        return seconds

    def end(self, summary: str) -> None:
        self.detail(f"{summary} ({self.elapsed():.1f} s)")


# ================================================================================ driver
def run_demo(
    outdir: str | os.PathLike[str] = "geoblock-demo",
    *,
    size: str = "small",
    seed: int | None = None,
    progress: Callable[[str], None] | None = None,
    quicklook_width: int = 1024,
    force: bool = False,
) -> DemoResult:
    """Simulate, adjust (single and block), orthorectify and mosaic before and after, measure
    the seams and report (module docstring).

    Files in ``outdir``::

        block/                  the simulated block (run_scenario), block.toml among them
        adjustment/single/      single adjustment: models/<id>.json, report.md, report.json,
                                error-vector PNGs (as geoblock adjust writes them)
        adjustment/block/       block adjustment, the same files (report.md compares it
                                with the single adjustment)
        onboard/orthos/<id>.tif each strip orthorectified with its on-board model
        onboard/mosaic.tif      their feathered mosaic
        orthos/<id>.tif         each strip orthorectified with its block-adjusted model
        mosaic.tif              their feathered mosaic (UTM)
        contribution.tif        which strip each pixel of mosaic.tif came from
        report.md               before/after tables and the figures below
        results.json            the report's numbers
        quicklook.png           the mosaics before and after, outlines, seam shifts
        errors.png              error vectors at GCPs and ICPs, per model set
        seams.png               the orthos' difference in each overlap, before and after
        .geoblock-demo          the marker (DEMO_MARKER)

    A previous demo's outputs in ``outdir`` are replaced; any other non-empty ``outdir`` is
    refused unless ``force`` (:func:`prepare_demo_outdir`).

    Parameters
    ----------
    outdir : str or os.PathLike
    size : {"small", "tiny"}
        ``small``: 600 x 600 px strips at 100 m; ``tiny``: 200 x 200 px at 300 m (for tests).
    seed : int, optional
        Default: the preset's.
    progress : callable, optional
        Called with one-line messages: ``[k/6] stage`` lines, indented details, each stage's
        time.
    quicklook_width : int
        Largest width of each mosaic in the quicklook, pixels.
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
    GeoblockError
        A stage failed (an adjustment that cannot be solved, a file that cannot be written:
        the message names it).
    """
    from geoblock import coords
    from geoblock.adjust.block import adjust
    from geoblock.adjust.statistics import ictp_accuracy
    from geoblock.io.blocks import open_block
    from geoblock.report.adjustment import write_result

    stages = _Stages(progress or (lambda message: None))
    start = time.perf_counter()
    out = Path(outdir)
    scenario = demo_scenario(size, seed)
    if prepare_demo_outdir(out, force=force):
        make_directory(out)
        write_text(out / DEMO_MARKER, _MARKER_TEXT)

    stages.begin(1, "simulate", f"simulating {scenario.name}: {scenario.description}")
    sim = run_scenario(scenario, out / "block", progress=stages.detail, render=True)
    stages.end(f"block/: {len(sim.sensors)} strips, "
               + ", ".join(f"{sim.points.count(k)} {k.upper()}s"
                           for k in ("gcp", "icp", "tp", "ictp")))

    # the adjustments, as `geoblock adjust block/block.toml [--compare-single]` runs them
    opened = open_block(sim.files["block"])
    options = dict(opened.options)
    method = opened.spec.method.upper()
    title = f"{opened.spec.name} (method {opened.spec.method})"
    make_directory(out / "adjustment")
    stages.begin(2, "single", f"single adjustment ({method}, each strip alone with its GCPs, "
                 "no DEM)")
    single = adjust(opened.block, progress=stages.detail, **{**options, "mode": "single"})
    write_result(single, out / "adjustment" / "single", title=f"Single adjustment: {title}")
    stages.end(f"{_outcome(single)}: adjustment/single/")
    stages.begin(3, "block", f"block adjustment ({method}, GCPs + TPs + DEM elevation "
                 "control)")
    block = adjust(opened.block, progress=stages.detail, **{**options, "mode": "block"})
    write_result(block, out / "adjustment" / "block", single=single,
                 title=f"Block adjustment: {title}")
    stages.end(f"{_outcome(block)}: adjustment/block/")

    stages.begin(4, "ortho", "orthorectifying each strip on the measured DEM with its ON-BOARD "
                 "and its BLOCK-ADJUSTED model")
    dem = open_dem(str(sim.dem_path))
    specs = [im.spec for im in scenario.images]
    crs = coords.utm_crs(float(np.mean([s.centre_lon for s in specs])),
                         float(np.mean([s.centre_lat for s in specs])))
    resolution = float(min(s.gsd_m for s in specs))
    models: dict[str, dict[str, SensorModel]] = {
        "onboard": {i: s.onboard_model for i, s in sim.sensors.items()},
        "single": dict(single.models), "block": dict(block.models)}
    rasters = {i: sim.files[f"image:{i}"] for i in sim.sensors}
    orthos_onboard = _orthorectify(rasters, models["onboard"], dem, crs, resolution, out,
                                   "onboard/orthos", stages.detail)
    orthos = _orthorectify(rasters, models["block"], dem, crs, resolution, out, "orthos",
                           stages.detail)
    reference = _reference_orthos(rasters, {i: s.true_model for i, s in sim.sensors.items()},
                                  dem, crs, resolution)
    stages.detail("and each strip with its TRUE model, in memory: the seams' reference")
    stages.end(f"onboard/orthos/ and orthos/: {len(orthos)} + {len(orthos)} orthos of "
               f"{resolution:g} m ({crs.name})")

    stages.begin(5, "mosaic", "mosaicking both sets (feathered seams)")
    mosaic_onboard = _mosaic(orthos_onboard, out / "onboard")
    mosaic_path = _mosaic(orthos, out, contribution=True)
    stages.end(f"onboard/mosaic.tif, mosaic.tif: {_shape_text(mosaic_path)}")

    stages.begin(6, "report", "measuring: errors from the truth, ICTP discrepancies, seam "
                 "shifts on the images; report and figures")
    accuracy = {key: _truth_errors(m, sim) for key, m in models.items()}
    meas = sim.points.image
    sel = meas.kind == "ictp"
    ictp = {key: ictp_accuracy(mm, meas.id[sel], meas.image[sel], meas.row[sel],
                               meas.col[sel], dem, warn=False)
            for key, mm in models.items()}
    frames = {"true": on_common_grid(reference),
              "onboard": on_common_grid({i: _read_band(p) for i, p in orthos_onboard.items()}),
              "block": on_common_grid({i: _read_band(p) for i, p in orthos.items()})}
    pairs = overlapping_pairs(frames["block"][0])
    seams = {key: {p: seam_shift(grids[p[0]], grids[p[1]], transform, p) for p in pairs}
             for key, (grids, transform) in frames.items()}
    discrepancies = {key: {p: seams[key][p].minus(seams["true"][p]) for p in pairs}
                     for key in ("onboard", "block")}
    for p in pairs:
        stages.detail(f"seam {p[0]} & {p[1]}: shift {seams['onboard'][p].shift:.1f} m "
                      f"on-board, {seams['block'][p].shift:.1f} m block-adjusted, "
                      f"{seams['true'][p].shift:.1f} m true; less the true: "
                      f"{discrepancies['onboard'][p].shift:.1f} m before, "
                      f"{discrepancies['block'][p].shift:.1f} m after")
    figures = {
        "quicklook": _quicklook(mosaic_onboard, mosaic_path, models, dem, discrepancies,
                                out / "quicklook.png", quicklook_width),
        "errors": _error_figure(accuracy, sim, out / "errors.png"),
        "seams": _seam_figure(frames, seams, discrepancies, out / "seams.png"),
    }
    stages.elapsed()
    seconds = time.perf_counter() - start
    results = _results(sim, size, single, block, accuracy, ictp, seams, discrepancies,
                       stages.timings, seconds)
    write_json(out / "results.json", results, indent=1)
    report = write_text(out / "report.md",
                        _report(sim, opened.spec.method, single, block, accuracy, ictp,
                                seams, discrepancies, figures, stages.timings, seconds))
    stages.end("report.md, results.json, quicklook.png, errors.png, seams.png")
    seconds = time.perf_counter() - start
    stages.say(f"done in {seconds:.0f} s: {report}")
    return DemoResult(out, report, figures["quicklook"], mosaic_path, orthos, sim, seconds,
                      mosaic_onboard, orthos_onboard, single, block, accuracy, ictp, seams,
                      discrepancies, stages.timings)


def _outcome(result: BlockResult) -> str:
    """``converged in 4 iterations, sigma0 1.007`` for the progress lines."""
    state = "converged" if result.converged else "NOT converged"
    return f"{state} in {result.iterations} iterations, sigma0 {result.sigma0:.4g}"


def _shape_text(path: Path) -> str:
    rows, cols = open_image(path).shape
    return f"{rows} x {cols} px"


def _ortho(raster: Path, model: SensorModel, dem: DemSource, crs: Any,
           resolution: float) -> Any:
    """A raw image's orthorectification with ``model`` on its own grid (UTM ``crs``,
    ``resolution`` metres, snapped to multiples of it: the orthos of a set are
    pixel-aligned), planned (:class:`~geoblock.ortho.OrthoJob`: ``geoblock ortho``'s local
    path, chunks on threads without a dask graph)."""
    from geoblock.ortho import OutputGrid, ortho_job

    grid = OutputGrid.for_model(model, dem, crs=crs, resolution=resolution)
    return ortho_job(str(raster), model, dem, grid)


def _orthorectify(rasters: Mapping[str, Path], models: Mapping[str, SensorModel],
                  dem: DemSource, crs: Any, resolution: float, out: Path, folder: str,
                  say: Callable[[str], None]) -> dict[str, Path]:
    """Each raw image orthorectified with its model (:func:`_ortho`), written to
    ``out/folder/<id>.tif``."""
    make_directory(out / folder)
    paths: dict[str, Path] = {}
    for image_id, model in models.items():
        job = _ortho(rasters[image_id], model, dem, crs, resolution)
        paths[image_id] = write_ortho(job, out / folder / f"{image_id}.tif")
        say(f"{folder}/{image_id}.tif: {job.shape[1]} x {job.shape[2]} px")
    return paths


def _reference_orthos(rasters: Mapping[str, Path], models: Mapping[str, SensorModel],
                      dem: DemSource, crs: Any, resolution: float,
                      ) -> dict[str, tuple[Float64Array, Affine]]:
    """Each raw image orthorectified with its TRUE model (known in simulation only,
    :func:`_ortho`), in memory: the first band as float64 (NaN where no pixel) and its
    grid's transform."""
    out: dict[str, tuple[Float64Array, Affine]] = {}
    for image_id, model in models.items():
        job = _ortho(rasters[image_id], model, dem, crs, resolution)
        band = np.empty(job.shape[1:], np.float64)
        for r0, r1, c0, c1 in job.windows():
            band[r0:r1, c0:c1] = job.chunk((r0, r1, c0, c1))[0]
        if not np.isnan(job.fill):
            band[band == job.fill] = np.nan
        out[image_id] = band, job.grid.transform
    return out


def _mosaic(orthos: Mapping[str, Path], folder: Path, *, contribution: bool = False) -> Path:
    """The feathered mosaic of ``orthos`` in ``folder/mosaic.tif`` (and its contribution)."""
    from geoblock.ortho import mosaic
    from geoblock.ortho.mosaic import open_ortho

    ds = mosaic([open_ortho(p) for p in orthos.values()], method="feather", feather_px=16.0)
    path = write_ortho(ds["mosaic"], folder / "mosaic.tif")
    if contribution:
        write_ortho(ds["contribution"].expand_dims(band=[1]), folder / "contribution.tif")
    return path


def _truth_errors(models: Mapping[str, SensorModel], sim: ScenarioResult) -> PointErrors:
    """Ground errors of ``models`` at the GCP and ICP measurements, from the simulated truth:
    the on-board models' measure (:func:`~geoblock.simulate.study.onboard_errors`) applied to
    any models."""
    from geoblock.simulate.study import onboard_errors

    return onboard_errors({i: SimpleNamespace(onboard_model=m) for i, m in models.items()},
                          sim.points)


# ================================================================================ reading
def _read_band(path: Path) -> tuple[Float64Array, Affine]:
    """The first band of a georeferenced image as float64 (NaN where nodata), its transform."""
    source = open_image(path)
    return read_band(source), source.transform


# ================================================================================ figures
def _outline(model: SensorModel, dem: DemSource, crs: Any,
             n: int = 24) -> tuple[Float64Array, Float64Array]:
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


def _downsampled(path: Path, width: int) -> tuple[Float64Array, tuple[float, float, float,
                                                                     float], Any]:
    """A mosaic reduced by block averages to at most ``width`` columns, its extent in km
    ``(left, right, bottom, top)`` and its CRS (pyproj)."""
    import pyproj

    values, transform = _read_band(path)
    crs = pyproj.CRS.from_wkt(open_image(path).crs.to_wkt())
    rows, cols = values.shape
    step = max(1, math.ceil(cols / max(int(width), 1)))
    r, c = rows // step * step, cols // step * step
    with np.errstate(invalid="ignore"):
        blocks = values[:r, :c].reshape(r // step, step, c // step, step)
        ok = np.isfinite(blocks).sum(axis=(1, 3))
        small = np.where(ok > 0, np.nansum(blocks, axis=(1, 3)) / np.maximum(ok, 1), np.nan)
    x0, y0 = transform.c, transform.f
    extent = (x0 / 1e3, (x0 + c * transform.a) / 1e3, (y0 + r * transform.e) / 1e3, y0 / 1e3)
    return small, extent, crs


_COLOURS = ("#f39c12", "#2ecc71", "#3498db", "#e74c3c", "#9b59b6")


def _seam_scale(seams: Mapping[str, Mapping[tuple[str, str], SeamShift]],
                extent_m: float) -> tuple[float, float]:
    """Exaggeration of the seam-shift vectors (the largest is drawn ~6 % of ``extent_m``)
    and the length of the key's arrow, metres."""
    from geoblock.report.figures import nice_number

    lengths = [np.hypot(s.segment_e, s.segment_n) for per in seams.values()
               for s in per.values()]
    finite = np.concatenate(lengths) if lengths else np.zeros(0)
    finite = finite[np.isfinite(finite)]
    largest = float(finite.max()) if finite.size else 0.0
    if largest <= 0:
        return 1.0, 1.0
    return nice_number(0.06 * extent_m / largest), nice_number(largest)


def _quicklook(before: Path, after: Path, models: Mapping[str, Mapping[str, SensorModel]],
               dem: DemSource, seams: Mapping[str, Mapping[tuple[str, str], SeamShift]],
               path: Path, width: int) -> Path:
    """Before (on-board) and after (block-adjusted) mosaics, one above the other, with each
    strip's outline and the misregistration along each seam (``seams``: the segments' seam
    shifts less the true-model orthos', :meth:`SeamShift.minus`; exaggerated, one scale)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    panels = [("onboard", before, "BEFORE: strips orthorectified with their ON-BOARD models"),
              ("block", after, "AFTER: strips orthorectified with their BLOCK-ADJUSTED models")]
    images = [_downsampled(p, width) for _, p, _ in panels]
    aspect = images[0][0].shape[0] / max(images[0][0].shape[1], 1)
    fig = Figure(figsize=(10.24, 2 * max(2.5, 10.24 * aspect) + 1.0), layout="constrained")
    FigureCanvasAgg(fig)
    extent_m = 1e3 * (images[0][1][1] - images[0][1][0])
    scale, key = _seam_scale({name: seams[name] for name, _, _ in panels}, extent_m)
    for k, ((name, _, title), (small, extent, crs)) in enumerate(zip(panels, images,
                                                                      strict=True)):
        ax = fig.add_subplot(2, 1, k + 1)
        ax.set_facecolor("#1b2631")
        finite = small[np.isfinite(small)]
        lo, hi = np.percentile(finite, [1, 99]) if finite.size else (0.0, 1.0)
        ax.imshow(np.ma.masked_invalid(small), cmap="gray", extent=extent,
                  interpolation="nearest", vmin=lo, vmax=hi)
        for j, (image_id, model) in enumerate(models[name].items()):
            x, y = _outline(model, dem, crs)
            ax.plot(x / 1e3, y / 1e3, color=_COLOURS[j % len(_COLOURS)], linewidth=1.1,
                    label=image_id)
        q = None
        for s in seams[name].values():
            q = ax.quiver(s.segment_x / 1e3, s.segment_y / 1e3, s.segment_e, s.segment_n,
                          angles="xy", scale_units="xy", scale=1e3 / scale, color="#ff2d55",
                          width=0.004, headwidth=3.5, headlength=4.0, zorder=4)
        if q is not None:
            ax.quiverkey(q, 0.84, 0.06, key, f"misregistration {key:g} m (x{scale:g})",
                         labelpos="W", coordinates="axes", color="#ff2d55",
                         labelcolor="white", fontproperties={"size": 8})
        ax.set_xlim(extent[0], extent[1])
        ax.set_ylim(extent[2], extent[3])
        ax.set_aspect("equal")
        ax.set_xlabel(f"E (km, {crs.name})")
        ax.set_ylabel("N (km)")
        ax.legend(loc="upper right", fontsize=8, framealpha=0.8)
        ax.set_title(title, fontsize=10)
    return save_figure(fig, path, dpi=100)


def _error_figure(accuracy: Mapping[str, PointErrors], sim: ScenarioResult,
                  path: Path) -> Path:
    """Error vectors at the GCPs and ICPs from the truth, one panel per model set
    (:func:`geoblock.report.error_vector_plot`, each with its own exaggeration: the
    adjusted models' errors are ten times smaller). Every set has the same measurements, in
    the same order (:func:`_truth_errors`); a point in two strips has a vector per strip."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.ticker import FuncFormatter, MaxNLocator

    from geoblock.adjust.observations import lookup
    from geoblock.report import error_vector_plot, to_local_en

    g = sim.points.ground
    k = lookup(g.id, accuracy["onboard"].id)
    e, n = to_local_en(g.lon_true[k], g.lat_true[k])
    fig = Figure(figsize=(6.0 * len(accuracy), 6.6), layout="constrained")
    FigureCanvasAgg(fig)
    km = FuncFormatter(lambda value, _: f"{value / 1e3:g}")
    for j, (key, errors) in enumerate(accuracy.items()):
        ax: Axes = fig.add_subplot(1, len(accuracy), j + 1)
        rmse = errors.select(kind="ICP").stats().rmse_2d
        error_vector_plot(e, n, errors.e, errors.n, errors.kind, ax=ax, xlabel="E (km)",
                          ylabel="N (km)",
                          title=f"{MODEL_SETS[key]} models: ICP RMSE 2D {rmse:.1f} m")
        for axis in (ax.xaxis, ax.yaxis):
            axis.set_major_locator(MaxNLocator(5))
            axis.set_major_formatter(km)
    return save_figure(fig, path, dpi=90)


def _seam_figure(frames: Mapping[str, tuple[Mapping[str, np.ndarray], Affine]],
                 seams: Mapping[str, Mapping[tuple[str, str], SeamShift]],
                 discrepancies: Mapping[str, Mapping[tuple[str, str], SeamShift]],
                 path: Path) -> Path:
    """Per overlap and ortho set (:data:`SEAM_SETS`): ortho ``a`` minus ortho ``b`` in the
    overlap, both smoothed as the matcher sees them, on one colour scale; the measured shift
    and the misregistration (less the true-model orthos' shift) in the titles."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    pairs = list(seams["block"])
    panels = [(p, key) for p in pairs for key in SEAM_SETS]
    crops: dict[tuple[tuple[str, str], str],
                tuple[Float64Array, tuple[float, float, float, float]]] = {}
    for p, key in panels:
        grids, transform = frames[key]
        found = smoothed_overlap(grids[p[0]], grids[p[1]], 0)
        if found is None:
            continue
        (r0, c0), (rows, cols) = found.origin, found.a.shape
        both = _inside(grids[p[0]], grids[p[1]], r0, c0, (rows, cols))
        x0, y0 = transform.c + transform.a * c0, transform.f + transform.e * r0
        x1, y1 = x0 + transform.a * cols, y0 + transform.e * rows
        crops[p, key] = (np.where(both, found.a - found.b, np.nan),
                         (x0 / 1e3, x1 / 1e3, y1 / 1e3, y0 / 1e3))
    before = [np.abs(d[np.isfinite(d)]) for (_, key), (d, _) in crops.items()
              if key == "onboard"]
    limit = float(np.percentile(np.concatenate(before), 98)) if before else 1.0
    fig = Figure(figsize=(1.9 * max(len(panels), 1) + 1.2, 6.0), layout="constrained")
    FigureCanvasAgg(fig)
    image = None
    for column, (p, key) in enumerate(panels, start=1):
        ax = fig.add_subplot(1, len(panels), column)
        if (p, key) not in crops:
            ax.set_axis_off()
            continue
        diff, extent = crops[p, key]
        image = ax.imshow(diff, cmap="RdBu", vmin=-limit, vmax=limit, extent=extent,
                          interpolation="nearest")
        title = f"{_pair_label(p)}\n{SEAM_SETS[key]} models\nmeasured {seams[key][p].shift:.1f} m"
        if key in discrepancies:
            title += f"\nless true {discrepancies[key][p].shift:.1f} m"
        ax.set_title(title, fontsize=8)
        ax.set_xlabel("E (km)", fontsize=8)
        ax.tick_params(labelsize=7)
        if column == 1:
            ax.set_ylabel("N (km)", fontsize=8)
    if image is not None:
        fig.colorbar(image, ax=fig.axes, shrink=0.6,
                     label=f"ortho a - ortho b (DN, smoothed by {SEAM_SMOOTHING_PX:g} px)")
    fig.suptitle("The overlaps: ortho a minus ortho b; the seam shift measured on them, and "
                 "less the one between the true-model orthos", fontsize=10)
    return save_figure(fig, path, dpi=100)


def _inside(a: np.ndarray, b: np.ndarray, r0: int, c0: int,
            shape: tuple[int, ...]) -> np.ndarray:
    """Whether both orthos have a pixel, on a crop of ``shape`` starting at ``(r0, c0)``."""
    window = (slice(r0, r0 + shape[0]), slice(c0, c0 + shape[1]))
    return np.isfinite(a[window]) & np.isfinite(b[window])


# ================================================================================ report
def _json(value: float) -> float | None:
    """JSON-safe float (None for NaN and infinities)."""
    value = float(value)
    return value if math.isfinite(value) else None


def _stats_dict(stats: AccuracyStats) -> dict[str, Any]:
    return {k: (_json(v) if isinstance(v, float) else v) for k, v in stats.as_dict().items()}


def _by_image_and_kind(errors: PointErrors) -> dict[tuple[str, str], AccuracyStats]:
    from geoblock.adjust.statistics import AccuracyStats

    return {k: v for k, v in errors.by_image_and_kind().items()
            if isinstance(v, AccuracyStats)}


def _pair_label(pair: tuple[str, str]) -> str:
    return f"{pair[0]} & {pair[1]}"


def _results(sim: ScenarioResult, size: str, single: BlockResult, block: BlockResult,
             accuracy: Mapping[str, PointErrors], ictp: Mapping[str, IctpDiscrepancies],
             seams: Mapping[str, Mapping[tuple[str, str], SeamShift]],
             discrepancies: Mapping[str, Mapping[tuple[str, str], SeamShift]],
             timings: Mapping[str, float], seconds: float) -> dict[str, Any]:
    """The numbers of the report (``results.json``)."""
    acc: dict[str, Any] = {}
    for key, errors in accuracy.items():
        acc[key] = {}
        for (image, kind), st in _by_image_and_kind(errors).items():
            acc[key].setdefault(image, {})[kind.lower()] = _stats_dict(st)
    return {
        "scenario": sim.scenario.name, "size": size, "seed": sim.scenario.seed,
        "seconds": round(seconds, 3), "timings": dict(timings),
        "adjustment": {name: {"mode": r.mode, "converged": r.converged,
                              "iterations": r.iterations, "sigma0": _json(r.sigma0),
                              "dof": r.dof}
                       for name, r in (("single", single), ("block", block))},
        "accuracy": acc,
        "ictp": {key: {_pair_label(p): _stats_dict(st) for p, st in d.by_pair().items()}
                 for key, d in ictp.items()},
        "seams": {key: {_pair_label(p): s.as_dict() for p, s in per.items()}
                  for key, per in seams.items()},
        "seam_discrepancies": {key: {_pair_label(p): s.as_dict() for p, s in per.items()}
                               for key, per in discrepancies.items()},
    }


def _fmt(value: float, decimals: int = 1) -> str:
    return f"{value:.{decimals}f}" if math.isfinite(value) else "—"


def _seam_table(seams: Mapping[str, Mapping[tuple[str, str], SeamShift]],
                discrepancies: Mapping[str, Mapping[tuple[str, str], SeamShift]],
                ictp: Mapping[str, IctpDiscrepancies]) -> list[str]:
    """Markdown: per overlap and ortho set, the seam shift as measured and less the
    true-model orthos' one, with the ICTPs' mean discrepancy beside it."""
    lines = ["| overlap | orthos made with | measured shift E, N (m) | measured shift (m) | "
             "less the true models': E, N (m) | misregistration (m) | along the seam, RMS "
             "(m) | ICTP mean E, N (m) | pixels |",
             "| :--- | :--- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for p in seams["block"]:
        for key, label in SEAM_SETS.items():
            s = seams[key][p]
            note = "" if s.status == "converged" else f" ({s.status})"
            cells = [_pair_label(p), f"{label} models", f"{_fmt(s.e)}, {_fmt(s.n)}{note}",
                     _fmt(s.shift)]
            d = discrepancies.get(key, {}).get(p)
            if d is None:
                cells += ["—", "—", "—"]
            else:
                cells += [f"{_fmt(d.e)}, {_fmt(d.n)}", _fmt(d.shift), _fmt(d.segment_rms)]
            st = ictp[key].by_pair().get(p) if key in ictp else None
            cells += [f"{_fmt(st.mean_e)}, {_fmt(st.mean_n)}" if st is not None else "—",
                      str(s.pixels)]
            lines.append("| " + " | ".join(cells) + " |")
    return lines


def _report(sim: ScenarioResult, method: str, single: BlockResult, block: BlockResult,
            accuracy: Mapping[str, PointErrors], ictp: Mapping[str, IctpDiscrepancies],
            seams: Mapping[str, Mapping[tuple[str, str], SeamShift]],
            discrepancies: Mapping[str, Mapping[tuple[str, str], SeamShift]],
            figures: Mapping[str, Path], timings: Mapping[str, float], seconds: float) -> str:
    """The demo's ``report.md``."""
    from geoblock.report import comparison_table

    scenario = sim.scenario
    fp = footprint_rows(sim.sensors)
    groups = {key: _by_image_and_kind(errors) for key, errors in accuracy.items()}
    rows = {(image, kind, str(st.n)): {MODEL_SETS[s]: groups[s][image, kind]
                                        for s in groups if (image, kind) in groups[s]}
            for (image, kind), st in groups["onboard"].items()}
    pairs = {p: {MODEL_SETS[s]: ictp[s].by_pair()[p] for s in ictp if p in ictp[s].by_pair()}
             for p in ictp["onboard"].by_pair()}
    icp = {s: {i: st.rmse_2d for (i, kind), st in groups[s].items() if kind == "ICP"}
           for s in groups}
    ictp_2d = {s: [st.rmse_2d for st in ictp[s].by_pair().values()] for s in ictp}
    shifts = {s: [x.shift for x in per.values()] for s, per in discrepancies.items()}

    def listed(values: Iterable[float]) -> str:
        return ", ".join(_fmt(v) for v in values)

    lines = [
        "# geoblock demo", "",
        f"{scenario.description}.", "",
        "Three simulated SPOT-5 strips were rendered through their TRUE models. The block was "
        f"adjusted twice with the `{method}` method, as `geoblock adjust "
        "block/block.toml` does: in **single** mode (each strip alone with its GCPs) and in "
        "**block** mode (all strips together: GCPs, TPs and the DEM elevation control of the "
        "TPs). Each strip was then orthorectified on the measured DEM with its ON-BOARD model "
        "(the erroneous ephemeris and attitude a user is given: *before*) and with its "
        "BLOCK-ADJUSTED model (*after*), and both sets were mosaicked. Every accuracy below "
        "comes from this run and the truth the simulation knows.", "",
        "**In short**: ICP RMSE 2D per strip "
        f"{listed(icp['onboard'].values())} m with the on-board models, "
        f"{listed(icp['single'].values())} m after the single adjustment, "
        f"{listed(icp['block'].values())} m after the block adjustment; ICTP discrepancies "
        f"between strips {listed(ictp_2d['onboard'])} m on-board, "
        f"{listed(ictp_2d['single'])} m single, {listed(ictp_2d['block'])} m block; "
        "neighbouring orthos, matched on their pixels at each seam, are misregistered by "
        f"{listed(shifts['onboard'])} m before and {listed(shifts['block'])} m after.", "",
        f"![quicklook]({figures['quicklook'].name})", "",
        "## Accuracy at the control and check points", "",
        "Ground error of each model at the GCP and ICP measurements, from the simulated "
        "truth: the true image position located through the model at the true height, minus "
        "the true ground position (m, local east E and north N). The adjustments use the "
        "GCPs (surveyed, with noise) and never the ICPs.", "",
        comparison_table(rows, labels=("image", "kind", "n"), counts=False,
                         quantities=("rmse_e", "rmse_n", "rmse_2d")).rstrip(), "",
        f"![error vectors]({figures['errors'].name})", "",
        "## ICTP discrepancies between strips", "",
        "The same independent check tie points, measured in two strips, ray-traced onto the "
        "measured DEM through each strip's model: the distance between the two ground "
        "points is the misregistration between the strips (Teo et al.'s relative accuracy; "
        "the ICTPs never enter the adjustment).", "",
        comparison_table({f"{_pair_label(p)} ({next(iter(g.values())).n} ICTPs)": g
                          for p, g in pairs.items()},
                         labels=("overlap",), counts=False,
                         quantities=("rmse_e", "rmse_n", "rmse_2d")).rstrip(), "",
        "## Seamline discrepancies measured on the images", "",
        "The shift between neighbouring orthos in their overlap, measured on the pixels: "
        "robust least-squares matching of the overlap (translation, radiometric gain and "
        "offset, Cauchy weights; both orthos smoothed by a Gaussian of "
        f"{SEAM_SMOOTHING_PX:g} px, pixels closer than {SEAM_MARGIN_PX} px to either "
        "ortho's edge left out), as ortho *b* minus ortho *a* (the sign of an ICTP "
        "discrepancy, whose mean is given beside it). The orthos made with the TRUE models "
        "(known in simulation only, not written) line up but for the DEM's errors: what the "
        "matching measures between them comes from the images' content (the simulated "
        "texture is aliased differently by each strip: the moiré in the figure), and it is "
        "in the other sets' shifts too. Less it, the shift is the misregistration the models "
        f"cause; its RMS over {SEAM_SEGMENTS} segments along the seam, each matched on its "
        "own, shows how it varies along the seam.", "",
        *_seam_table(seams, discrepancies, ictp), "",
        f"![seams]({figures['seams'].name})", "",
        "## The adjustments", "",
        f"- single: {_outcome(single)}, {single.dof} degrees of freedom; "
        "`adjustment/single/report.md`, its models in `adjustment/single/models/`",
        f"- block: {_outcome(block)}, {block.dof} degrees of freedom; "
        "`adjustment/block/report.md` (parameters, residuals, the single-versus-block "
        "table), its models in `adjustment/block/models/`", "",
        *(f"- note: {n}" for n in (*single.notes, *block.notes)),
        *([""] if (single.notes or block.notes) else []),
        "## Files", "",
        "- `mosaic.tif`: the mosaic of the block-adjusted orthos (feathered); "
        "`contribution.tif`: which strip each pixel came from; `orthos/<strip>.tif`: each "
        "strip orthorectified with its block-adjusted model",
        "- `onboard/mosaic.tif`, `onboard/orthos/<strip>.tif`: the same with the on-board "
        "models",
        "- `adjustment/single/`, `adjustment/block/`: what `geoblock adjust` writes (adjusted "
        "models, `report.md`, `report.json`, error-vector figures)",
        "- `block/`: the simulated block (terrain, DEM, images with true and on-board models, "
        "points, `block.toml`, `report/report.md`)",
        "- `results.json`: this report's numbers; `quicklook.png`, `errors.png`, `seams.png`",
        "",
        "## Footprints", "",
        "| image | size (px) | GSD (m) | incidence (deg) | centre lon, lat | footprint (km) |",
        "|---|---|---|---|---|---|",
        *(f"| {r['image']} | {r['rows']} x {r['cols']} | {r['gsd_m']:.3g} | "
          f"{r['incidence_deg']:.2f} | {r['centre_lon']:.4f}, {r['centre_lat']:.4f} | "
          f"{r['width_km']:.1f} x {r['length_km']:.1f} |" for r in fp), "",
    ]
    if sim.notes:
        lines += ["## Notes", "", *(f"- {n}" for n in sim.notes), ""]
    stages = ", ".join(f"{name} {t:.1f} s" for name, t in timings.items())
    lines += [f"Made by `geoblock demo` in {seconds:.0f} s ({stages}; seed {scenario.seed}).",
              ""]
    return "\n".join(lines)
