"""The report of the reference-control study (:mod:`geoblock_papers.reference`): tables,
findings and figures from its repetitions."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from geoblock_papers import reference as ref
from geoblock_papers._reference_sim import BLOCKS, Case, CaseOutcome, Scene, engine_has_shift
from geoblock_papers.report import Report, estimate

__all__ = ["write"]


def _f(x: float, d: int = 2) -> str:
    return f"{x:.{d}f}" if isinstance(x, float | int) and math.isfinite(x) else "-"


def _why(failure: str) -> str:
    """A failure's reason without the temporary reference's path."""
    return failure.split(" from the reference")[0][:80]


def _routes() -> tuple[str, ...]:
    return ("independent", "shift", "consider") if engine_has_shift() else (
        "independent", "consider")


def _setup(report: Report, design: ref.Design, scenes: Mapping[str, Scene],
           seeds: Sequence[int], layer_count: int) -> None:
    lines = []
    for block, scene in scenes.items():
        sizes = ", ".join(f"{i} {s.spec.shape[0]}x{s.spec.shape[1]} px at {s.spec.gsd_m:g} m"
                          for i, s in scene.sensors.items())
        lo, hi = scene.terrain.relief
        lines.append(f"- **{block}** ({BLOCKS[block].label}): {sizes}; terrain "
                     f"{lo:.0f}-{hi:.0f} m; measured DEM RMSEz {scene.dem_sigma_m:g} m; "
                     f"simulated and rendered in {scene.seconds:.1f} s")
    report.section("Set-up", (
        "No surveyed GCP: control only from a reference ortho rendered from the truth (the "
        "texture the images show, area-averaged, shaded by the true terrain, 1 DN of noise) "
        "and misregistered by a known shift, matched by `geoblock.match.match_reference` "
        "against the measured DEM; tie points (40 per overlapping pair, 0.3 px) and ICPs "
        "(60 per image, at their true positions with exact image positions: their error is "
        "the adjusted models' alone) from the truth. The reference's error is its RMS radial "
        "error: a fixed shift of that size in a random direction (a), (b), (d), or a shift "
        "drawn from the Gaussian of its stated CE90 (e); it states `CE90 = 1.5175 x error` "
        "(at least 0.5 m). Blocks:\n\n" + "\n".join(lines) + "\n\n"
        f"Repetitions: {len(seeds)} per case (a)-(d) (new image noise, shift direction, tie "
        f"points and ICPs); {layer_count} for the layer's validation (e). The control is "
        "weighted three ways (routes): **independent**, the reference's error counted in "
        "every point's sigma as if independent (`sigma = sqrt((CE90/2.146)^2 + "
        "(sigma_match gsd)^2)` per axis); **estimated**, as `match_reference` gives it: each "
        "point its matching sigma, the reference's error one shift common to all its points "
        "(`sigma_shift = CE90/2.146` per axis) that the block engine estimates; "
        "**consider**, each point its matching sigma, the common error not estimated but "
        "propagated: the experiment adds `J Sigma_s J^T` to the engine's prediction, `J` "
        "the response of the ICPs to a 1 m shift of every control point (two more "
        "adjustments)."))


def _main_rows(runs: Sequence[CaseOutcome], design: ref.Design) -> list[list[Any]]:
    rows = []
    for block in design.blocks:
        for case in design.cases(block):
            if case not in design.main:
                continue
            sel = ref._select(runs, block, case)
            if not sel:
                fails = [o.failure for o in runs if o.block == block and o.case == case]
                rows.append([block, case.label, "no control: " + (_why(fails[0]) if fails
                                                                   else "not run")]
                            + ["-"] * (4 + 2 * len(_routes())))
                continue
            cells = [block, case.label,
                     ref._est(sel, "control/n", "").format(0),
                     ref._est(sel, "control/within_1px_removed", "").format(3),
                     ref._est(sel, "control/within_1px_included", "").format(3),
                     ref._est(sel, "control/rms_removed_m").format(2)]
            for route in _routes():
                w = ref.SOLUTION[route]
                cells += [ref._est(sel, f"{w}/icp_rmse_m").format(2),
                          ref._error_ratio(sel, w).format(3)]
            rows.append(cells + [ref._est(sel, "own/ortho_rmse_m").format(2)])
    return rows


def _posterior_rows(runs: Sequence[CaseOutcome], design: ref.Design
                    ) -> tuple[list[list[Any]], dict[str, list[float]]]:
    rows: list[list[Any]] = []
    pooled: dict[str, list[float]] = {r: [] for r in _routes()}
    for block in design.blocks:
        for case in design.cases(block):
            if case not in design.main:
                continue
            sel = ref._select(runs, block, case)
            if not sel:
                continue
            cells: list[Any] = [block, case.label]
            for route in _routes():
                w = ref.SOLUTION[route]
                key = "icp_pred_consider_m" if route == "consider" else "icp_pred_m"
                p = ref._pooled(sel, route)
                pooled[route].append(p)
                cells += [ref._est(sel, f"{w}/icp_rmse_m").format(2),
                          ref._est(sel, f"{w}/{key}").format(2), _f(p, 3)]
            rows.append(cells)
    return rows, pooled


def _sweep_rows(runs: Sequence[CaseOutcome], design: ref.Design, block: str,
                cases: Sequence[Case]) -> list[list[Any]]:
    rows = []
    width = 2 * len(_routes())
    for case in cases:
        sel = ref._select(runs, block, case)
        if not sel:
            fail = next((o.failure for o in runs if o.block == block and o.case == case), "")
            rows.append([case.label, "no control" + (f": {_why(fail)}" if fail else "")]
                        + ["-"] * (2 + width))
            continue
        cells = [case.label, ref._est(sel, "control/n", "").format(0),
                 ref._est(sel, "control/within_1px_removed", "").format(3),
                 ref._est(sel, "control/median_removed_px", "px").format(3)]
        for route in _routes():
            w = ref.SOLUTION[route]
            cells += [ref._est(sel, f"{w}/icp_rmse_m").format(2)
                      + (f" ({ref._error_ratio(sel, w).mean:.2f}x)" if case.error_m > 0
                         else ""), _f(ref._pooled(sel, route), 3)]
        rows.append(cells)
    return rows


def write(report: Report, design: ref.Design, scenes: Mapping[str, Scene],
          runs: Sequence[CaseOutcome], layers: Sequence[CaseOutcome], seeds: Sequence[int],
          seconds: float) -> None:
    """Fill ``report`` (module docstring of :mod:`geoblock_papers.reference`)."""
    layer_count = len({o.seed for o in layers})
    _setup(report, design, scenes, seeds, layer_count)
    # ---- (a), (c)
    main = [o for o in runs if o.case in design.main and not o.failure]
    report.section("(a), (c) ICP error against the reference's error; the matches", (
        "Per block and reference (4 m error): control points, their share within one "
        "reference pixel of the truth with the shift removed (the matching error: the "
        "control's ground position minus the reference's shift, against the true ground "
        "point of its raw-image position, the TRUE model on the TRUE terrain) and included "
        "(what the block is told), the matching error's RMS (m, shift removed); per route "
        "the ICP RMSE 2D and its ratio to the reference's error (target: within 1.2x); the "
        "ortho's error at the ICPs (located on the measured DEM, consider route's "
        "solution)."))
    header = ["block", "reference", "control points", "within 1 px (shift removed)",
              "within 1 px (shift included)", "matching RMS"]
    for route in _routes():
        header += [f"ICP RMSE ({_ROUTE_SHORT[route]})", "ICP / reference error"]
    report.table(header + ["ortho RMSE at ICPs"], _main_rows(runs, design), key="main",
                 align="ll" + "r" * (len(header) - 1))
    for route in _routes():
        w = ref.SOLUTION[route]
        ratios = [v for o in main for v in ref._error_ratio([o], w).values
                  if math.isfinite(v)]
        ok = bool(ratios) and all(1 / ref.ICP_FACTOR <= r <= ref.ICP_FACTOR for r in ratios)
        report.finding(f"icp_{route}", f"without surveyed GCPs, ICP RMSE within "
                       f"{ref.ICP_FACTOR}x of the reference's error (4 m; 10 and 2.5 m GSD "
                       f"references; {ref._ROUTES[route]})", ok if ratios else None,
                       f"ICP RMSE / reference error {min(ratios):.3f}-{max(ratios):.3f} "
                       f"over {len(ratios)} runs" if ratios else "no run")
    within = [o.values["control/within_1px_removed"] for o in main]
    report.finding("matches", "reference matches within one reference pixel of the truth "
                   "(shift removed): at least 95 %",
                   (min(within) >= 0.95) if within else None,
                   f"{min(within):.3f}-{max(within):.3f} of the kept matches over "
                   f"{len(within)} runs" if within else "no run")
    # ---- (b)
    rows, pooled = _posterior_rows(runs, design)
    header = ["block", "reference"]
    for route in _routes():
        header += [f"ICP RMSE ({route})", f"predicted ({_ROUTE_SHORT[route]})",
                   "measured / predicted"]
    report.section("(b) The posterior's prediction against the measured ICP RMSE", (
        "Predicted: the RMS of the predicted 2D sigmas at the ICPs (the engine's "
        "`predicted_covariance`, scaled by sigma0^2 as the engine scales its posterior; the "
        "consider term is not scaled: the reference's error is known a priori). Measured over "
        "predicted pooled over the repetitions (sqrt of the sums of mean squares); target "
        "within 10 %. A misregistration is one error common to every control point: N "
        "independent points of sigma s average to s / sqrt(N), a common shift does not "
        "average out."))
    report.table(header, rows, key="posterior", align="ll" + "r" * (len(header) - 2))
    for route in _routes():
        vals = [p for p in pooled[route] if math.isfinite(p)]
        good = bool(vals) and all(abs(p - 1) <= ref.POSTERIOR_TOLERANCE for p in vals)
        report.finding(f"posterior_{route}", "the posterior predicts the ICP RMSE within 10 % "
                       f"({ref._ROUTES[route]})", good if vals else None,
                       f"measured / predicted {min(vals):.3f}-{max(vals):.3f} over "
                       f"{len(vals)} block/reference pairs" if vals else "no run")
    report.record("posterior_pooled", pooled)
    # ---- the engine's shift route, diagnosed
    if engine_has_shift():
        _shift_section(report, runs, design)
    # ---- (d) sweeps
    report.section("(d) Against the reference's GSD and error", (
        "Per block: control points, share within one reference pixel (shift removed), "
        "median matching error (reference pixels); per route the ICP RMSE (in brackets its "
        "ratio to the reference's error) and measured / predicted (pooled)."))
    sweep_header = ["reference", "control points", "within 1 px", "median match error"]
    for route in _routes():
        sweep_header += [f"ICP RMSE ({_ROUTE_SHORT[route]}; x error)",
                         f"measured / predicted ({_ROUTE_SHORT[route]})"]
    for block in design.sweep_blocks:
        report.text(f"**{block}**: reference GSD (4 m error)")
        report.table(sweep_header, _sweep_rows(runs, design, block,
                                               [Case(g, 4.0) for g in design.gsds]),
                     key=f"sweep_gsd_{block}")
        report.text(f"**{block}**: reference error (10 m GSD)")
        report.table(sweep_header, _sweep_rows(runs, design, block,
                                               [Case(10.0, e) for e in design.errors]),
                     key=f"sweep_error_{block}")
    if design.sweep_blocks:
        report.figure(_sweep_figure(runs, design), "reference-error.png",
                      "ICP RMSE against the reference's error (10 m GSD) and GSD (4 m "
                      "error): the common error propagated (solid) and estimated by the "
                      "engine (dotted); the dashed line is the reference's error, grey "
                      "within 1.2x")
        report.figure(_match_figure(runs, design), "reference-gsd.png",
                      "The matches against the reference's GSD: share within one reference "
                      "pixel and median error (reference pixels and metres), shift removed")
    # ---- (e) the layer
    _layer_section(report, design, layers, layer_count)
    # ---- times
    times: dict[str, list[float]] = {}
    for o in [*runs, *layers]:
        for k, v in o.seconds.items():
            times.setdefault(k, []).append(v)
    report.record("seconds", {"total": seconds, **{k: float(np.mean(v))
                                                    for k, v in times.items()},
                              "scenes": {b: s.seconds for b, s in scenes.items()}})
    report.record("per_run", [{"block": o.block, "case": o.case.label, "seed": o.seed,
                               "failure": o.failure, **o.values} for o in runs])
    report.record("per_layer_run", [{"block": o.block, "seed": o.seed, **o.values}
                                    for o in layers])
    report.section("Run times", (
        f"{seconds:.0f} s in all ({len(runs)} runs of (a)-(d), {len(layers)} of (e)); mean "
        "per run: " + ", ".join(f"{k} {np.mean(v):.2f} s" for k, v in times.items())
        + "; the blocks simulated and rendered once: " + ", ".join(
            f"{b} {s.seconds:.1f} s" for b, s in scenes.items()) + "."))


def _shift_section(report: Report, runs: Sequence[CaseOutcome], design: ref.Design) -> None:
    rows = []
    for block in design.blocks:
        for case in design.cases(block):
            sel = [o for o in ref._select(runs, block, case) if "shift/est_e" in o.values]
            if not sel:
                continue
            miss = estimate([math.hypot(o.values["shift/est_e"] - o.values["shift/e"],
                                        o.values["shift/est_n"] - o.values["shift/n"])
                             for o in sel])
            size = estimate([math.hypot(o.values["shift/est_e"], o.values["shift/est_n"])
                             for o in sel])
            unscaled = estimate([o.values["shift/est_sigma_e"] / o.values["shift/sigma0"]
                                 for o in sel])
            rows.append([block, case.label, ref._est(sel, "shift/sigma0", "").format(3),
                         ref._est(sel, "shift/icp_rmse_m").format(2),
                         ref._est(sel, "shift/icp_pred_m").format(2),
                         ref._est(sel, "shift/icp_pred_unscaled_m").format(2),
                         size.format(2), miss.format(2),
                         ref._est(sel, "shift/est_sigma_e").format(2), unscaled.format(2)])
    report.text(
        "The common-shift route diagnosed, per block and reference: the engine's sigma0 (its "
        "posterior is scaled by sigma0^2, the shift's a-priori part too), the ICP RMSE, the "
        "prediction as given and divided by sigma0 (the a-priori weights' own), the "
        "estimated shift's size, its error (estimated minus true: 0 would be a shift "
        "recovered, the true size a shift left to its prior), and its posterior sigma per "
        "axis (east) as given and divided by sigma0 (the prior: CE90/2.146).")
    report.table(["block", "reference", "sigma0", "ICP RMSE", "predicted",
                  "predicted / sigma0", "estimated shift", "estimate's error",
                  "posterior sigma (E)", "posterior sigma / sigma0"], rows,
                 key="shift_route", align="ll" + "r" * 8)


_ROUTE_SHORT = {"independent": "independent", "consider": "consider",
                "shift": "estimated"}


def _layer_section(report: Report, design: ref.Design, layers: Sequence[CaseOutcome],
                   count: int) -> None:
    report.section("(e) The accuracy layer against the ortho's error", (
        f"{count} repetitions per block with the reference's shift drawn from its stated "
        f"CE90 ({design.layer_case.ce90_m:.2f} m: RMS radial error "
        f"{design.layer_case.error_m:g} m), 10 m GSD. At each ICP: the accuracy layer "
        f"(`geoblock.ortho.accuracy_layer` of the adjusted model with its posterior, "
        f"{10:g} m pixels, sampled bilinearly where the ortho shows the ICP) against the "
        "ortho's radial error there (the ICP's exact image position located on the measured "
        "DEM through the adjusted model, minus the truth). Bands: quartiles of the predicted "
        "error, pooled over the repetitions; RMS empirical over RMS predicted per band "
        "(target: within 20 %). The layer is the engine's posterior propagated, for the "
        "consider route with the consider covariance added."))
    rows, verdicts, record = [], {}, {}
    for block in design.layer_blocks:
        for route in _routes():
            pred, emp = ref._layer_arrays(layers, block, route)
            bands = ref._bands(pred, emp)
            record[f"{block}/{route}"] = bands
            if not bands:
                continue
            verdicts[(block, route)] = all(abs(b["ratio"] - 1) <= ref.LAYER_TOLERANCE
                                           for b in bands)
            for k, b in enumerate(bands):
                rows.append([block, ref._ROUTES[route], f"Q{k + 1}: {b['low']:.2f}-"
                             f"{b['high']:.2f} m", b["n"], _f(b["rms_predicted"]),
                             _f(b["rms_empirical"]), _f(b["ratio"], 3)])
    agree = [float(np.nanmax(np.abs(o.layer[k] / o.layer[k.replace("/layer", "/exact")] - 1)))
             for o in layers for k in o.layer if k.endswith("/layer")]
    if agree:
        report.text(f"The layer itself (`accuracy_layer` over each image, first repetition) "
                    f"against its exact value at the ICPs: largest relative difference "
                    f"{max(agree):.2e} (its lattice's tolerance: 1e-3); the bands use the "
                    "exact value at every ICP of every repetition.")
        report.record("layer_vs_exact", max(agree))
    report.table(["block", "route", "band (predicted)", "ICPs", "RMS predicted",
                  "RMS empirical", "empirical / predicted"], rows, key="layer_bands",
                 align="lll" + "r" * 4)
    report.record("layer_bands_detail", record)
    enough = count >= 20
    for route in _routes():
        mine = {b: v for (b, r), v in verdicts.items() if r == route}
        worst = [max(abs(x["ratio"] - 1) for x in record[f"{b}/{route}"]) for b in mine]
        report.finding(f"layer_{route}", f"the accuracy layer within 20 % of the ortho's "
                       f"error in every band ({ref._ROUTES[route]})",
                       (all(mine.values()) if enough else None) if mine else None,
                       (f"largest band departure {max(worst):.1%} over {len(mine)} block(s), "
                        f"{count} repetitions" + ("" if enough else
                                                  "; fewer than 20 repetitions: not tested"))
                       if mine else "no run")
    # statements
    srows = []
    for block in design.layer_blocks:
        for route in _routes():
            st = ref._statements(layers, block, route)
            srows.append([block, ref._ROUTES[route], st["n"], _f(st["ce90_pred"]),
                          _f(st["ce90_emp"]), _f(st["ce90_emp"] / st["ce90_pred"], 3)
                          if st["ce90_pred"] else "-", st["n_le"], _f(st["le90_pred"]),
                          _f(st["le90_emp"])])
    report.text("CE90 of the ICPs' check errors (the adjustment report's statement: predicted "
                "from their covariances, empirical their 90th percentile) and LE90 of the "
                "ICPs seen in two images or more (intersected through the adjusted models), "
                "pooled over the repetitions:")
    report.table(["block", "route", "ICP measurements", "CE90 predicted", "CE90 empirical",
                  "empirical / predicted", "ICPs intersected", "LE90 predicted",
                  "LE90 empirical"], srows, key="statements", align="ll" + "r" * 7)
    if rows:
        report.figure(_layer_figure(record), "reference-layer.png",
                      "The accuracy layer's bands: RMS empirical against RMS predicted "
                      "error at the ICPs, per block and route; the band is +-20 %")


def _sweep_figure(runs: Sequence[CaseOutcome], design: ref.Design) -> Any:
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    for block in design.sweep_blocks:
        for ax, cases, x in ((axes[0], [Case(10.0, e) for e in design.errors], design.errors),
                             (axes[1], [Case(g, 4.0) for g in design.gsds], design.gsds)):
            y = [ref._est(ref._select(runs, block, c), "own/icp_rmse_m").mean
                 for c in cases]
            ys = [ref._est(ref._select(runs, block, c), "shift/icp_rmse_m").mean
                  for c in cases]
            line = ax.plot(x, y, "o-", label=f"{block}, common error propagated")[0]
            if any(math.isfinite(v) for v in ys):
                ax.plot(x, ys, "s:", color=line.get_color(), alpha=0.7,
                        label=f"{block}, common shift estimated")
    e = np.asarray(design.errors)
    axes[0].plot(e, e, "k--", lw=1, label="reference error")
    axes[0].fill_between(e, e / ref.ICP_FACTOR, e * ref.ICP_FACTOR, color="0.85", zorder=0)
    axes[0].set(xlabel="reference error (RMS radial, m)", ylabel="ICP RMSE 2D (m)",
                title="against the reference's error (10 m GSD)")
    axes[1].axhline(4.0, color="k", ls="--", lw=1)
    axes[1].axhspan(4.0 / ref.ICP_FACTOR, 4.0 * ref.ICP_FACTOR, color="0.85", zorder=0)
    axes[1].set(xlabel="reference GSD (m)", ylabel="ICP RMSE 2D (m)", xscale="log",
                title="against the reference's GSD (4 m error)")
    _gsd_ticks(axes[1], design.gsds)
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    return fig


def _gsd_ticks(ax: Any, gsds: Sequence[float]) -> None:
    from matplotlib.ticker import NullFormatter

    ax.set_xticks(gsds, [f"{g:g}" for g in gsds])
    ax.xaxis.set_minor_formatter(NullFormatter())


def _match_figure(runs: Sequence[CaseOutcome], design: ref.Design) -> Any:
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 3.8))
    for block in design.sweep_blocks:
        cases = [Case(g, 4.0) for g in design.gsds]
        share = [ref._est(ref._select(runs, block, c), "control/within_1px_removed",
                          "").mean for c in cases]
        med = [ref._est(ref._select(runs, block, c), "control/median_removed_px",
                        "").mean for c in cases]
        axes[0].plot(design.gsds, share, "o-", label=block)
        axes[1].plot(design.gsds, med, "o-", label=f"{block} (px)")
    axes[0].set(xlabel="reference GSD (m)", ylabel="share within 1 reference px",
                xscale="log", ylim=(0, 1.02))
    axes[1].set(xlabel="reference GSD (m)", ylabel="median matching error (reference px)",
                xscale="log")
    for ax in axes:
        _gsd_ticks(ax, design.gsds)
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    return fig


def _layer_figure(record: Mapping[str, list[dict[str, float]]]) -> Any:
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.8))
    colours = {"independent": "tab:red", "shift": "tab:orange", "consider": "tab:green"}
    markers = {b: m for b, m in zip(BLOCKS, "osD^v", strict=False)}
    hi = 0.0
    for key, bands in record.items():
        if not bands:
            continue
        block, route = key.split("/")
        p = [b["rms_predicted"] for b in bands]
        e = [b["rms_empirical"] for b in bands]
        hi = max(hi, *p, *e)
        style = {"color": colours.get(route, "k"), "marker": markers.get(block, "o"),
                 "label": f"{block}, {_ROUTE_SHORT.get(route, route)}"}
        axes[0].plot(p, e, "-", **style)
        if route == "consider":
            axes[1].plot(p, e, "-", **style)
    x = np.geomspace(0.1, max(hi, 1.0) * 1.5, 50)
    for ax in axes:
        ax.plot(x, x, "k--", lw=1)
        ax.fill_between(x, x * (1 - ref.LAYER_TOLERANCE), x * (1 + ref.LAYER_TOLERANCE),
                        color="0.85", zorder=0)
        ax.set(xlabel="RMS predicted by the layer (m)",
               ylabel="RMS empirical: ortho error at ICPs (m)")
    from matplotlib.ticker import FormatStrFormatter, NullFormatter

    axes[0].set(xscale="log", yscale="log", title="every route, quartile bands")
    for axis in (axes[0].xaxis, axes[0].yaxis):  # plain numbers: no mathtext fonts needed
        axis.set_major_formatter(FormatStrFormatter("%g"))
        axis.set_minor_formatter(NullFormatter())
    axes[0].legend(fontsize=7)
    axes[1].set(xlim=(3.0, 5.0), ylim=(3.0, 5.0),
                title="common error propagated (consider), +-20 %")
    axes[1].legend(fontsize=7)
    fig.tight_layout()
    return fig
