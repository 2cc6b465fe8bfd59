"""Tables, figures and sections of the Teo et al. (2010) block, shared by ``teo2010`` and
``chen2008``: the statistics of :mod:`geoblock_papers._teo_block` set against a paper's
tables, one column per on-board error model (:class:`~geoblock_papers._teo_block.Study`);
the findings are :mod:`geoblock_papers._teo_findings`'."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from functools import partial
from typing import Any

import numpy as np
from matplotlib.ticker import FuncFormatter

from geoblock.report import error_vector_plot, to_local_en
from geoblock.report.figures import nice_number
from geoblock_papers._teo_block import (
    _VECTOR_RUNS,
    METHODS,
    PAIRS,
    POOR_DEM_RMSE_M,
    STRIPS,
    Outcomes,
    SeedOutcome,
    Study,
    Vectors,
)
from geoblock_papers._teo_findings import PaperCells, PaperTables, add_findings, paper_2d
from geoblock_papers.report import Estimate, GridRow

__all__ = [
    "CONSISTENCY_ROWS",
    "PAIR_COLUMNS",
    "STRIP_COLUMNS",
    "PaperCells",
    "PaperTables",
    "absolute_grid",
    "add_dem_section",
    "add_figures",
    "add_findings",
    "add_onboard_section",
    "consistency_grid",
    "describe_setup",
    "grid_series",
    "icp_vector_figure",
    "ictp_bar_figure",
    "ictp_vector_figure",
    "nonaffine_rows",
    "onboard_grid",
    "record_results",
    "setup_grid",
    "ties_grid",
]

# ================================================================================ figures
def _figure(rows: int, cols: int, size: tuple[float, float]) -> Any:
    """A new Agg figure and its ``(rows, cols)`` array of axes."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=size, layout="constrained")
    FigureCanvasAgg(fig)
    return fig, fig.subplots(rows, cols, squeeze=False)


def _vector_panels(vectors: Mapping[str, Vectors], rows: Sequence[str], what: str) -> Any:
    """Rows of (single, block) error-vector panels on a common frame and scale."""
    every = Vectors.concat(list(vectors.values()))
    origin = (float(np.mean(every.lon)), float(np.mean(every.lat)), 0.0)
    err = np.hypot(every.de, every.dn)
    err = err[np.isfinite(err)]
    e_all, n_all = to_local_en(every.lon, every.lat, 0.0, origin=origin)
    extent = max(float(np.ptp(e_all)), float(np.ptp(n_all)), 1.0)
    typical = float(np.percentile(err, 95)) if err.size else 1.0
    scale = nice_number(0.12 * extent / typical) if typical > 0 else 1.0
    bar = nice_number(float(np.sqrt(np.mean(err**2))), round_down=False) if err.size else 1.0
    fig, axes = _figure(len(rows), 2, (12.0, 6.4 * len(rows)))
    km = FuncFormatter(lambda x, _: f"{x / 1e3:g}")
    for i, method in enumerate(rows):
        for j, run in enumerate(_VECTOR_RUNS):
            v = vectors[f"{method}/{run}"]
            e, n = to_local_en(v.lon, v.lat, 0.0, origin=origin)
            ax = axes[i, j]
            error_vector_plot(e, n, v.de, v.dn, v.kind, scale=scale, scale_bar=bar, ax=ax,
                              title=f"{method}, {run} adjustment: {what}",
                              xlabel="E (km)", ylabel="N (km)")
            ax.xaxis.set_major_formatter(km)
            ax.yaxis.set_major_formatter(km)
    return fig


def ictp_vector_figure(outcome: SeedOutcome, methods: Sequence[str] = METHODS) -> Any:
    """TP and ICTP discrepancy vectors of each method, single vs block (Teo et al. Fig. 9),
    on one scale, for one seed."""
    return _vector_panels(
        {k: v for k, v in outcome.ties.items() if k.split("/")[0] in methods}, methods,
        f"TP/ICTP discrepancies, seed {outcome.seed}")


def icp_vector_figure(outcome: SeedOutcome, methods: Sequence[str] = ("MBA",)) -> Any:
    """GCP and ICP error vectors of the strips, single vs block (Teo et al. Figs. 10-12), on
    one scale, for one seed."""
    return _vector_panels(
        {k: v for k, v in outcome.checks.items() if k.split("/")[0] in methods}, methods,
        f"GCP/ICP errors, seed {outcome.seed}")


def ictp_bar_figure(study: Study, paper: Mapping[tuple[str, str, str], float],
                    paper_name: str) -> Any:
    """ICTP RMSE 2D per overlap, bars per method and run (single, block) with 95 %
    intervals over the seeds under the first error model, the other models' means as hollow
    markers, the paper's figures as diamonds.

    Parameters
    ----------
    study : Study
    paper : mapping of (method, run, pair label) to float
        The paper's ICTP RMSE 2D (``hypot`` of its E and N), metres.
    paper_name : str
        For the legend, e.g. ``"Teo et al. Table III"``.
    """
    data = study.primary
    fig, axes = _figure(1, 1, (9.0, 5.4))
    ax = axes[0, 0]
    colours = {"MBA": "#1f5fa8", "DG": "#c0392b", "RFM": "#16a085"}
    markers = ("o", "s", "^")
    runs = ("single", "block")
    width = 0.8 / (len(METHODS) * len(runs))
    labelled = set()
    for p, label in enumerate(PAIRS):
        for m, method in enumerate(METHODS):
            for r, run in enumerate(runs):
                x = p + (m * len(runs) + r - (len(METHODS) * len(runs) - 1) / 2) * width
                est = data.est(f"{method}/{run}/ictp/{label}/2d")
                low, high = est.interval
                err = None if not math.isfinite(low) else [[est.mean - low], [high - est.mean]]
                name = f"{method} {run}" + (f" ({study.models[0]})" if len(study.models) > 1
                                            else "")
                ax.bar(x, est.mean, width * 0.92, color=colours[method],
                       alpha=1.0 if run == "block" else 0.45, yerr=err, capsize=3,
                       label=None if name in labelled else name, edgecolor="white")
                labelled.add(name)
                for k, (model, other) in enumerate(list(study.by_model.items())[1:]):
                    value = other.est(f"{method}/{run}/ictp/{label}/2d").mean
                    ax.plot([x], [value], marker=markers[k % len(markers)], markersize=6,
                            markerfacecolor="none", markeredgecolor="#333333",
                            linestyle="none",
                            label=None if model in labelled else f"mean, {model} errors")
                    labelled.add(model)
                theirs = paper.get((method, run, label))
                if theirs is not None:
                    ax.plot([x], [theirs], marker="D", color="black", markersize=5,
                            linestyle="none",
                            label=None if "paper" in labelled else paper_name)
                    labelled.add("paper")
        floor = data.est(f"truth/ictp/{label}/2d")
        ax.hlines(floor.mean, p - 0.42, p + 0.42, colors="#555555", linestyles=":",
                  label=None if "floor" in labelled else "true models (floor)")
        labelled.add("floor")
    ax.set_xticks(range(len(PAIRS)), [f"strips {k.replace('-', ' & ')}" for k in PAIRS])
    ax.set_ylabel("ICTP RMSE 2D (m)")
    ax.set_ylim(bottom=0.0)
    ax.set_title("Geometric consistency between strips: ICTP RMSE per overlap "
                 f"(mean and 95 % CI over {len(data.items)} seeds)", fontsize=10)
    ax.grid(True, axis="y", color="#dddddd", linewidth=0.6)
    ax.set_axisbelow(True)
    ax.legend(fontsize=8, ncol=4, loc="upper center", bbox_to_anchor=(0.5, -0.08),
              frameon=False)
    return fig


# ================================================================================ tables
#: columns of the absolute-accuracy tables (Teo et al. Tables II, V, VI; Chen et al. 4, 5)
STRIP_COLUMNS = [f"strip {k} {axis}" for k in (1, 2, 3) for axis in ("E", "N")]
#: columns of the consistency tables (Teo et al. Table III; Chen et al. Tables 2, 3)
PAIR_COLUMNS = [f"strips {label.replace('-', ' & ')} {axis}" for label in PAIRS
                for axis in ("E", "N")]
#: the consistency tables' rows: label -> (run, kind) of the RMSE, or None for the
#: improvement (single minus block ICTP RMSE, Teo et al. Table III)
CONSISTENCY_ROWS: dict[str, tuple[str, str] | None] = {
    "block TP": ("block", "tp"), "block ICTP": ("block", "ictp"),
    "single ICTP": ("single", "ictp"), "improvement ICTP": None,
}

def _improvement(method: str, label: str, axis: str) -> Callable[[Mapping[str, float]], float]:
    def fn(v: Mapping[str, float]) -> float:
        return (v[f"{method}/single/ictp/{label}/{axis}"]
                - v[f"{method}/block/ictp/{label}/{axis}"])
    return fn


def _grid_row(study: Study, label: str, paper: Sequence[str],
              cells: Callable[[Outcomes], list[Estimate | str | float]]) -> GridRow:
    """A grid row: ``cells`` of each error model's outcomes, the first as ``ours``."""
    ours = [cells(data) for data in study.by_model.values()]
    return GridRow(label, list(paper), ours[0], ours[1:])


def _ictp_cells(data: Outcomes, who: str) -> list[Estimate | str | float]:
    return [data.est(f"{who}/ictp/{label}/{axis}") for label in PAIRS for axis in ("e", "n")]


def _strip_cells(data: Outcomes, prefix: str, suffix: str) -> list[Estimate | str | float]:
    """``prefix{strip}{suffix}{axis}`` per strip and axis; the separator between strip and
    axis is ``/`` unless ``suffix`` ends in ``_``."""
    sep = "" if suffix.endswith("_") else "/"
    return [data.est(f"{prefix}{strip}{suffix}{sep}{axis}") for strip in STRIPS
            for axis in ("e", "n")]


def grid_series(study: Study) -> tuple[str, ...]:
    """The ``series`` of a grid or compare table: the error models, when there are two or
    more."""
    return study.models if len(study.models) > 1 else ()


def consistency_grid(study: Study, paper: PaperCells, rows: Sequence[str], *,
                     reference: bool = True) -> list[GridRow]:
    """Rows of a consistency table (``rows`` from :data:`CONSISTENCY_ROWS`) per method, in
    :data:`PAIR_COLUMNS`, one series per error model; with ``reference`` two more rows
    without the paper's figures: the on-board models before adjustment and the true models
    (the floor)."""
    out = []
    for method in METHODS:
        for row in rows:
            spec = CONSISTENCY_ROWS[row]

            def cells(data: Outcomes, method: str = method,
                      spec: tuple[str, str] | None = spec) -> list[Estimate | str | float]:
                got: list[Estimate | str | float] = []
                for label in PAIRS:
                    for axis in ("e", "n"):
                        if spec is None:
                            got.append(data.derived(_improvement(method, label, axis)))
                        else:
                            got.append(data.est(f"{method}/{spec[0]}/{spec[1]}/{label}/{axis}"))
                return got

            out.append(_grid_row(study, f"{method} {row}", paper.get((method, row), ["-"] * 4),
                                 cells))
    if reference:
        for who, name in (("onboard", "on-board models ICTP (before adjustment)"),
                          ("truth", "true models ICTP (the floor: noise and DEM)")):
            out.append(_grid_row(study, name, ["-"] * 4, partial(_ictp_cells, who=who)))
    return out


def absolute_grid(study: Study, run: str, paper: PaperCells) -> list[GridRow]:
    """GCP and ICP RMSE E, N per strip of each method in ``run`` (:data:`STRIP_COLUMNS`),
    one series per error model."""
    return [_grid_row(study, f"{method} {kind}", paper.get((method, kind), ["-"] * 6),
                      partial(_strip_cells, prefix=f"{method}/{run}/{kind.lower()}/",
                              suffix=""))
            for method in METHODS for kind in ("GCP", "ICP")]


def onboard_grid(study: Study, paper: PaperCells) -> list[GridRow]:
    """Mean and RMSE E, N of the on-board models per strip (Teo et al. Table II), one series
    per error model."""
    return [_grid_row(study, label, paper.get(("on-board", label), ["-"] * 6),
                      partial(_strip_cells, prefix="onboard/", suffix=f"/{stat}_"))
            for label, stat in (("Mean", "mean"), ("RMSE", "rmse"))]


def nonaffine_rows(study: Study) -> list[list[Any]]:
    """Per error model, the on-board error's 2D RMSE and its non-affine part per strip."""
    return [[model] + [v for strip in STRIPS
                       for v in (data.est(f"onboard/{strip}/rmse_2d"),
                                 data.est(f"onboard/{strip}/nonaffine_2d"))]
            for model, data in study.by_model.items()]


def setup_grid(data: Outcomes, paper: Mapping[str, Sequence[str]]) -> list[GridRow]:
    """Incidence, GSD and point counts per strip (Teo et al. Table I), :data:`STRIPS`
    columns; ``paper`` by row label (``incidence``, ``GSD``, ``GCPs``, ``ICPs``)."""
    rows = [("incidence (deg)", "incidence", "deg"), ("GSD (m)", "gsd", "m"),
            ("GCPs", "count/gcp", ""), ("ICPs", "count/icp", "")]
    return [GridRow(label, list(paper.get(label, ["-"] * 3)),
                    [data.est(f"{key}/{strip}", unit) for strip in STRIPS])
            for label, key, unit in rows]


def ties_grid(data: Outcomes, paper: Mapping[str, Sequence[str]]) -> list[GridRow]:
    """TPs and ICTPs per overlap (:data:`PAIRS` columns); ``paper`` by ``TPs``/``ICTPs``."""
    return [GridRow(label, list(paper.get(label, ["-"] * 2)),
                    [data.est(f"count/{kind}/{pair}", "") for pair in PAIRS])
            for label, kind in (("TPs", "tp"), ("ICTPs", "ictp"))]


# ================================================================================ sections
def describe_setup(study: Study) -> str:
    """A paragraph saying what was simulated and how it was adjusted."""
    data, case = study.primary, study.case
    rows = 24000 * case.scenes
    if study.full:
        size = f"{rows} x 24000 px at 2.5 m (the paper's size)"
    else:
        size = (f"{rows // 40} x 600 px at 100 m (40 times fewer rows and columns, the same "
                "footprints)")
    lo, hi = data.est("terrain/min").mean, data.est("terrain/max").mean
    gcps = "/".join(str(g) for g in case.gcps)
    models = " and ".join(f"`{m}`" for m in study.models)
    return (
        f"Each repetition simulates the `teo2010-spot5` preset (variant `{study.variant}`, "
        f"Teo et al.'s case {case.name}: three strips of {case.scenes} scene"
        f"{'s' if case.scenes > 1 else ''}, {size}) with its own seed: a new ridged terrain "
        f"({lo:.0f}-{hi:.0f} m, true slopes up to "
        f"{data.est('terrain/max_slope', 'deg').mean:.0f} deg on average over the seeds), a "
        "40 m DEM of RMSEz 5 m, on-board errors of 2D RMSE "
        f"{', '.join(f'{r:g}' for r in case.onboard_rmse_m)} m as in Teo et al.'s Table II "
        "(in random directions), GCPs and ICPs (survey sigma 3 m), TPs and ICTPs (pointing "
        "sigma 0.5 px at the papers' pixel size). "
        f"The on-board errors follow each of the simulator's error models in turn ({models}) "
        "on the same terrain, DEMs and point draws: `bias-drift` is position and attitude "
        "biases and an along-track drift (plus a 1 Hz sinusoidal attitude jitter of 0.5 urad "
        "the on-board data do not know); `realistic` adds an attitude wander (a band-limited "
        "power-law process whose size and spectrum were measured on SPOT5.DIM), a smooth "
        "across- and along-track look-angle error (the size of SPOT5.DIM's look-angle table's "
        "departure from a cubic) and an orbital-period ephemeris error (SPOT-5's DIODE), the "
        "biases and drifts scaled so that the on-board RMSE is the same. "
        "As in the papers, whose GCPs came from maps while "
        f"the TPs were measured in the overlaps, the GCPs of each strip ({gcps}) lie "
        f"away from the overlaps (those nearest the centre column of {case.gcp_candidates} "
        "drawn, stratified over a 3 x 3 grid). "
        "MBA is Chen & Lee's model fitted to the on-board model (19 parameters with a-priori "
        "sigmas), DG the on-board line-of-sight model with its position biases and drifts and "
        "attitude biases, RFM a sensor-oriented RPC fitted to the on-board model with an "
        "affine image correction. Single adjustment: each strip with its GCPs only; block "
        "adjustment: the three strips with GCPs, TPs (weak ground pseudo-observations, 10 "
        "times the GCPs' sigma) and DEM control. GCP and ICP errors are measured against the "
        "surveyed coordinates, as the papers do; ICTP (and TP) discrepancies are the distance "
        "between the two rays of a point traced onto the DEM through the adjusted models.")


def add_dem_section(report: Any, study: Study) -> None:
    """The DEM control and collocation tables (no paper table: the abstracts' claims), a
    line per method, run and error model."""
    data = study.primary
    report.section(
        "DEM elevation control (the paper gives no table)",
        "The block adjustment of each method with the DEM as a weighted observation "
        "(`block`, geoblock's default), with the papers' literal iteration Z1 -> Z1' -> Z2 ... "
        "(`iterate`), without DEM control (`no-dem`), and with a DEM of RMSEz "
        f"{POOR_DEM_RMSE_M:g} m (`poor-dem`, the adjustment told 5 m), under each on-board "
        "error model. TP height RMSE against the truth; ICTPs traced onto the block's DEM.")
    rows = []
    for method in METHODS:
        for run in ("block", "iterate", "no-dem", "poor-dem"):
            for model, d in study.by_model.items():
                rows.append([method, run, model, d.est(f"{method}/{run}/tp_height")]
                            + [d.est(f"{method}/{run}/ictp/{p}/2d") for p in PAIRS]
                            + [d.est(f"{method}/{run}/icp/all/2d")])
    report.table(["method", "run", "on-board errors", "TP height RMSE", "ICTP 2D strips 1 & 2",
                  "ICTP 2D strips 2 & 3", "ICP 2D (all strips)"], rows, key="dem_control",
                 align="lllrrrr")
    report.text(
        "Without DEM control the weakly convergent rays (incidences 5.2, 5.7 and -14.8 deg) "
        "leave the TP heights free to drift by tens of metres; the papers' iteration and the "
        "weighted observation give the same solution. The DEM's own RMSE at the TPs is "
        f"{data.est('dem/tp_rmse').format(1)} (5 m DEM) and "
        f"{data.est('poor_dem/tp_rmse').format(1)} ({POOR_DEM_RMSE_M:g} m DEM).")
    report.section(
        "Least-squares collocation (the paper gives no table)",
        "The block adjustment followed by least-squares collocation of each image's residual "
        "vectors (Teo et al. eqs. 4-5, filtering ratio 0.2), under each on-board error model "
        "(the differences: the findings' collocation table).")
    rows = []
    for method in METHODS:
        for model, d in study.by_model.items():
            for run in ("block", "collocation"):
                rows.append([method, model, run]
                            + [d.est(f"{method}/{run}/icp/{s}/2d") for s in STRIPS]
                            + [d.est(f"{method}/{run}/ictp/{p}/2d") for p in PAIRS])
    report.table(["method", "on-board errors", "run", "ICP 2D strip 1", "ICP 2D strip 2",
                  "ICP 2D strip 3", "ICTP 2D strips 1 & 2", "ICTP 2D strips 2 & 3"], rows,
                 key="collocation", align="lllrrrrr")


def add_onboard_section(report: Any, study: Study, paper: PaperCells, table: str,
                        case: str) -> None:
    """The on-board accuracy before adjustment (Teo et al. Table II) per error model, and
    the part of it no affine correction removes."""
    report.section(f"On-board accuracy before adjustment ({table})")
    report.grid(f"table_{table.split()[-1]}", STRIP_COLUMNS, onboard_grid(study, paper),
                series=grid_series(study),
                title=f"{table}: absolute accuracy before adjustment, case {case} (metres)",
                note="The simulated on-board errors are set to the paper's 2D RMSE per strip; "
                "their direction, hence the split between E and N and the signs of the "
                "means, is random per seed, so only the 2D size compares. As in the paper "
                "the error is mostly a bias (mean close to RMSE).")
    report.table(["on-board errors"] + [f"strip {k} {what}" for k in (1, 2, 3)
                                        for what in ("RMSE 2D", "non-affine")],
                 nonaffine_rows(study), key="onboard_nonaffine", align="l" + "r" * 6)
    report.text("The non-affine part: the RMS of the on-board ground error (15 x 15 grid at "
                "the scene centre's height) left by the best affine function of row and "
                "column, i.e. what a correction of the DG form fitted to GCPs cannot remove "
                "anywhere in the strip.")


def add_figures(report: Any, study: Study, paper: PaperTables) -> None:
    """The ICTP bar figure (with the paper's figures) and the error-vector figures (the
    first error model's first seed)."""
    bars = {}
    for method in METHODS:
        for k, label in enumerate(PAIRS):
            bars[(method, "single", label)] = paper_2d(paper.single_ictp[method], k)
            bars[(method, "block", label)] = paper_2d(paper.block_ictp[method], k)
    first_model = study.models[0]
    report.figure(ictp_bar_figure(study, bars,
                                  f"{paper.name} {paper.tables['consistency']}"),
                  "ictp_per_overlap.png",
                  "ICTP RMSE 2D per overlap, single (light) and block (dark) adjustment of each "
                  f"method, mean and 95 % interval over the seeds ({first_model} on-board "
                  "errors; hollow markers: the other error model's means); diamonds: the "
                  "paper; dotted: the true models (the floor)")
    first = study.primary.items[0]
    report.figure(ictp_vector_figure(first), "ictp_vectors.png",
                  "TP and ICTP discrepancy vectors between strips in the overlaps 1 & 2 "
                  f"(west) and 2 & 3 (east), single vs block adjustment, seed {first.seed}, "
                  f"{first_model} on-board errors (the same exaggeration in every panel; Teo "
                  "et al. Fig. 9)")
    report.figure(icp_vector_figure(first), "icp_vectors.png",
                  "MBA: error vectors at the GCPs and ICPs of the three strips, single vs "
                  f"block adjustment, seed {first.seed}, {first_model} on-board errors (Teo "
                  "et al. Figs. 10-12)")


def record_results(report: Any, study: Study) -> None:
    """Every statistic of every seed per error model (``per_seed``: ``{model: {key:
    values}}``, keys in :mod:`geoblock_papers._teo_block`) and each seed's timings
    (``seconds_per_seed``: ``{model: {seed: {simulate, models, adjust}}}``) into
    ``results.json``."""
    report.record("error_models", list(study.models))
    report.record("per_seed", {m: d.per_seed() for m, d in study.by_model.items()})
    report.record("seconds_per_seed", {m: {str(o.seed): o.seconds for o in d.items}
                                       for m, d in study.by_model.items()})
