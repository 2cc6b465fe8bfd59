"""The figures of ``geoblock experiment aguilar2007``, each beside the paper's.

Every function takes the repetitions (:class:`~geoblock_papers._aguilar_sim.SeedOutcome`)
and returns a matplotlib figure (no pyplot state): ICP RMSE against the number of GCPs with
the paper's Table 3 (:func:`rmse_figure`), the residuals against the distance from the image
centre (Fig. 4, :func:`distance_figure`), the error vectors (Fig. 5, :func:`vector_figure`),
random against stratified sampling (Fig. 6, :func:`sampling_figure`), RPCV-0 and RPCV-1
with few GCPs (Fig. 7, :func:`few_gcps_figure`) and the orthoimage error budget
(:func:`budget_figure`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from geoblock.report import error_vector_plot, residual_vs_distance, rmse_vs_gcp_count
from geoblock_papers import _aguilar_paper as paper
from geoblock_papers import _aguilar_sim as sim

__all__ = ["budget_figure", "distance_figure", "few_gcps_figure", "rmse_figure",
           "sampling_figure", "vector_figure"]

_PAPER_STYLE: dict[str, Any] = {"linestyle": "--", "marker": "o", "markerfacecolor": "none",
                                "linewidth": 1.0}


def _new(size: tuple[float, float]) -> Figure:
    fig = Figure(figsize=size, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _table(outcomes: Sequence[sim.SeedOutcome], key: str) -> np.ndarray:
    """(S,) per-seed values of ``key`` (NaN where absent)."""
    return np.array([o.values.get(key, math.nan) for o in outcomes])


def _with_paper(ax: Axes, series: Mapping[str, tuple[Any, Sequence[float]]],
                seeds: int) -> None:
    """Add the paper's lines (dashed, hollow markers, the colour of our line of the same
    model) to an axes drawn by :func:`geoblock.report.rmse_vs_gcp_count`, and redo the
    legend."""
    ours = ax.get_lines()
    for line, (label, (x, y)) in zip(ours, series.items(), strict=False):
        ax.plot(x, y, color=line.get_color(), label=label, **_PAPER_STYLE)
    handles, labels = ax.get_legend_handles_labels()
    if seeds > 1:
        handles.append(Line2D([], [], color="grey", alpha=0.4, linewidth=6))
        labels.append("95 % confidence interval of our mean")
    ax.legend(handles, labels, fontsize=8, frameon=False, ncol=2)


def rmse_figure(outcomes: Sequence[sim.SeedOutcome]) -> Figure:
    """ICP RMSE 2D after orientation against the number of GCPs, the four models, with the
    95 % interval over the seeds, and the paper's Table 3 dashed."""
    fig = _new((7.6, 5.0))
    ax = fig.subplots()
    counts = np.array(sim.COUNTS, dtype=float)
    series = {m: (counts, np.stack([_table(outcomes, f"t3/{m}/{n}/2d") for n in sim.COUNTS],
                                   axis=1))
              for m in sim.MODELS}
    rmse_vs_gcp_count(series, ax=ax, title="ICP RMSE 2D after orientation vs GCPs "
                      "(geoblock: solid; paper's Table 3: dashed)")
    theirs = {f"paper {paper.PAPER_MODEL[m]}":
              (counts, [float(paper.TABLE_3[(paper.PAPER_MODEL[m], n)][2]) for n in sim.COUNTS])
              for m in sim.MODELS}
    _with_paper(ax, theirs, len(outcomes))
    top = max(1.6, 1.15 * max(float(np.max(np.nan_to_num(sim.finite_mean(y, axis=0))))
                              for _, y in series.values()))
    ax.set_ylim(0.0, top)  # a wild fit's interval (RFM-1, 9 GCPs) would flatten the rest
    return fig


def distance_figure(outcomes: Sequence[sim.SeedOutcome]) -> Figure:
    """Fig. 4: 2D residuals at the ICPs against the distance from the image centre, after
    each model (the combinations of 18 to 45 GCPs of Table 3, every seed), and RPCV-0's
    along-track residual; least-squares lines with slope and R²."""
    series: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for name in sim.MODELS:
        parts = [o.residuals[name] for o in outcomes if name in o.residuals]
        if not parts:
            continue
        d = np.concatenate([p[0] for p in parts])
        series[f"{name}: 2D"] = (d, np.concatenate([p[1] for p in parts]))
        if name == "RPCV-0":
            series["RPCV-0: |along track|"] = (d, np.abs(np.concatenate([p[2] for p in parts])))
    return residual_vs_distance(
        series, panels=True, figsize=(9.0, 9.6),
        title="Residuals at the ICPs vs distance from the image centre (paper's Fig. 4: "
              "RPCV-0 R² = 0.37)")


def vector_figure(outcome: sim.SeedOutcome) -> Figure:
    """Fig. 5: ICP error vectors of the four models with 18 GCPs (one seed)."""
    fig = _new((10.0, 10.0))
    axes = fig.subplots(2, 2).ravel()
    for ax, name in zip(axes, sim.MODELS, strict=True):
        if name not in outcome.vectors:
            ax.set_visible(False)
            continue
        e, n, de, dn = outcome.vectors[name]
        error_vector_plot(e, n, de, dn, "ICP", ax=ax, title=f"{name}, 18 GCPs")
    fig.suptitle(f"ICP errors after orientation, seed {outcome.seed} (paper's Fig. 5)")
    return fig


def sampling_figure(outcomes: Sequence[sim.SeedOutcome]) -> Figure:
    """Fig. 6: mean ICP RMSE 2D of nine samples of 9 and 18 GCPs, random (R) and stratified
    random (SR), with the 95 % interval of that mean (averaged over the seeds)."""
    fig = _new((10.0, 4.4))
    axes = fig.subplots(1, len(sim.SAMPLING_COUNTS), sharey=True)
    x = np.arange(len(sim.MODELS), dtype=float)
    for ax, n in zip(np.atleast_1d(axes), sim.SAMPLING_COUNTS, strict=True):
        for shift, design, colour, marker in ((-0.12, "R", "#c0392b", "s"),
                                              (0.12, "SR", "#1f5fa8", "o")):
            mean = [sim.finite_mean(_table(outcomes, f"sampling/{m}/{n}/{design}/mean"))
                    for m in sim.MODELS]
            half = [sim.finite_mean(_table(outcomes, f"sampling/{m}/{n}/{design}/half"))
                    for m in sim.MODELS]
            ax.errorbar(x + shift, mean, yerr=half, fmt=marker, color=colour, capsize=4,
                        label=f"{design} ({'random' if design == 'R' else 'stratified random'})")
        ax.set_xticks(x)
        ax.set_xticklabels([paper.PAPER_MODEL[m] if m == "physical" else m
                            for m in sim.MODELS])
        ax.set_title(f"{sim.SAMPLING_REPEATS} samples of {n} GCPs")
        ax.grid(True, axis="y", color="#dddddd", linewidth=0.6)
        ax.set_ylim(bottom=0)
    np.atleast_1d(axes)[0].set_ylabel("RMSE 2D at ICPs (m)")
    np.atleast_1d(axes)[0].legend(fontsize=8, frameon=False)
    fig.suptitle("Random (R) vs stratified random (SR) GCP sampling (paper's Fig. 6): mean "
                 "and 95 % interval\nof nine samples, averaged over the seeds (CCRS: our "
                 "physical model)", fontsize=10)
    return fig


def few_gcps_figure(outcomes: Sequence[sim.SeedOutcome]) -> Figure:
    """Fig. 7: RPCV-0 and RPCV-1 with 1 to 9 GCPs (mean of four samples per seed; interval
    over the seeds)."""
    fig = _new((7.0, 4.6))
    ax = fig.subplots()
    counts = np.array(sim.FEW_COUNTS, dtype=float)
    series = {m: (counts, np.stack([_table(outcomes, f"few/{m}/{k}/2d")
                                    for k in sim.FEW_COUNTS], axis=1))
              for m in ("RPCV-0", "RPCV-1")}
    rmse_vs_gcp_count(series, ax=ax, title="RPCV-0 and RPCV-1 with few GCPs (paper's Fig. 7; "
                      "RPCV-1 is the shift below 3 GCPs)")
    return fig


def budget_figure(outcomes: Sequence[sim.SeedOutcome], dems: Sequence[str]) -> Figure:
    """Orthoimage RMSE 2D against the DEM's RMSEz (18 GCPs): ours per model (mean and 95 %
    interval over the seeds), the budget ``sqrt(sigma_o^2 + (RMSEz tan(theta))^2)`` (solid),
    the paper's Eq. 3 read with ``sigma_DEM = RMSEz`` (dotted) and the paper's Tables 4-6
    (dashed)."""
    from geoblock_papers.report import estimate

    fig = _new((8.0, 6.2))
    ax = fig.subplots()
    z = np.array([sim.finite_mean(_table(outcomes, f"dem/{d}/rmse_z")) for d in dems])
    grid = np.linspace(0.0, max(6.0, float(z.max()) * 1.05), 60)
    tan = float(sim.finite_mean(_table(outcomes, "view/tan_rms")))
    colours = ("#1f5fa8", "#c0392b", "#16a085", "#8e44ad")
    for i, (name, colour) in enumerate(zip(sim.MODELS, colours, strict=True)):
        means, lows, highs = [], [], []
        for d in dems:
            e = estimate(_table(outcomes, f"ortho/{d}/{name}/18/2d"))
            lo, hi = e.interval
            means.append(e.mean)
            lows.append(e.mean - lo if math.isfinite(lo) else 0.0)
            highs.append(hi - e.mean if math.isfinite(hi) else 0.0)
        offset = (i - 1.5) * 0.06
        ax.errorbar(z + offset, means, yerr=[lows, highs], fmt="o", color=colour, capsize=3,
                    label=f"{name} (geoblock)")
        sigma_o = float(sim.finite_mean(_table(outcomes, f"t3/{name}/18/2d")))
        ax.plot(grid, np.hypot(sigma_o, grid * tan), color=colour, linewidth=1.0)
        ax.plot(grid, np.hypot(sigma_o, grid), color=colour, linewidth=0.8, linestyle=":")
        pz = [float(paper.TABLE_2[d][2]) for d in ("dem2", "dem5", "dem20")]
        pv = [float(paper.DEM_TABLES[d][1][(paper.PAPER_MODEL[name], 18)][2])
              for d in ("dem2", "dem5", "dem20")]
        ax.plot(pz, pv, color=colour, label=f"paper {paper.PAPER_MODEL[name]}", **_PAPER_STYLE)
    handles, labels = ax.get_legend_handles_labels()
    handles += [Line2D([], [], color="grey", linewidth=1.0),
                Line2D([], [], color="grey", linewidth=0.8, linestyle=":")]
    labels += [f"sqrt(sigma_o² + (RMSEz tan theta)²), tan theta = {tan:.3f}",
               "sqrt(sigma_o² + RMSEz²) (Eq. 3 with sigma_DEM = RMSEz)"]
    fig.legend(handles, labels, loc="outside lower center", fontsize=7.5, frameon=False,
               ncol=3)
    ax.set_xlabel("DEM RMSEz (m)")
    ax.set_ylabel("orthoimage RMSE 2D at ICPs (m)")
    ax.set_ylim(0.0, 2.5)
    ax.grid(True, color="#dddddd", linewidth=0.6)
    ax.set_title("Orthoimage error budget, 18 GCPs (paper's Tables 4-6 dashed)", fontsize=10)
    return fig
