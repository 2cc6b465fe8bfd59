"""``geoblock experiment aguilar2007``: Aguilar et al. (2007) on a simulated QuickBird scene.

Aguilar, Aguilar, Agüera & Sánchez orient one QuickBird basic scene with four models (the
vendor RPCs refined by a shift, RPCV-0, or an affinity, RPCV-1; a first-order
terrain-dependent RFM, RFM-1; Toutin's CCRS physical model) and 9 to 45 GCPs, check them at
79 ICPs, study random against stratified GCP sampling, and make orthoimages with DEMs of
RMSEz 0.31, 1.75 and 5.82 m. This experiment repeats each test on simulated scenes
(:mod:`geoblock_papers._aguilar_sim`) and puts our figures beside the paper's Tables 1-7 and
Figs. 3-7 (:mod:`geoblock_papers._aguilar_figures`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

from geoblock_papers import _aguilar_figures as figures
from geoblock_papers import _aguilar_paper as paper
from geoblock_papers import _aguilar_sim as sim
from geoblock_papers.report import Estimate, GridRow, Report, Row, estimate

TITLE = ("Aguilar et al. (2007): QuickBird basic imagery with RPCV-0, RPCV-1, RFM-1 and a "
         "physical model, GCP number and sampling, orthoimage error budget")
CITATION = ("Aguilar, Aguilar, Agüera & Sánchez 2007, *Geometric accuracy assessment of "
            "QuickBird basic imagery using different operational approaches*, PE&RS 73(12)")
SEEDS = {"small": 3, "full": 10}

#: GCP counts at and beyond which the paper finds no further improvement
MANY = (18, 27, 36, 45)
#: a figure "reproduces" a paper's figure within this relative difference
CLOSE = 0.25


class _Data:
    """The repetitions' statistics as :class:`~geoblock_papers.report.Estimate` values."""

    def __init__(self, outcomes: Sequence[sim.SeedOutcome]) -> None:
        self.outcomes = list(outcomes)
        self.dems = [d for d in ("dem2", "dem5", "dem20")
                     if f"dem/{d}/rmse_z" in self.outcomes[0].values]

    def values(self, key: str) -> np.ndarray:
        """(S,) the per-seed values of ``key`` (NaN where absent)."""
        return np.array([o.values.get(key, math.nan) for o in self.outcomes])

    def est(self, key: str, unit: str = "m") -> Estimate:
        return estimate(self.values(key), unit)

    def mean(self, key: str) -> float:
        """The mean over the seeds of ``key`` (NaN-ignoring)."""
        v = self.values(key)
        return float(sim.finite_mean(v))

    def many(self, model: str, stat: str = "2d") -> np.ndarray:
        """(S,) per seed: the mean over :data:`MANY` GCP counts of ``t3/{model}/{n}/{stat}``."""
        return sim.finite_mean(np.stack([self.values(f"t3/{model}/{n}/{stat}") for n in MANY]),
                          axis=0)

    def per_seed(self) -> dict[str, list[float]]:
        keys = sorted({k for o in self.outcomes for k in o.values})
        return {k: self.values(k).tolist() for k in keys}


def _row_label(model: str, n: int | str) -> str:
    name = "CCRS / physical" if model == "physical" else model
    return f"{name}, {n} GCPs" if isinstance(n, int) else f"{name}, {n}"


# ================================================================================ findings
def _findings(report: Report, data: _Data) -> None:
    many = {m: float(sim.finite_mean(data.many(m))) for m in sim.MODELS}
    others = max(many[m] for m in sim.MODELS if m != "RPCV-0")
    gsd = data.mean("gsd")
    report.finding(
        "rpcv0_worst",
        "RPCV-0 gives the worst orientation: RMSE 2D 1.23-1.29 m, about twice the GSD "
        "(Table 3)",
        many["RPCV-0"] > 1.5 * others,
        f"ours {many['RPCV-0']:.2f} m with 18-45 GCPs against at most {others:.2f} m for the "
        "other models. The level is calibrated on the paper (the along-track drift of the "
        f"simulated on-board data, {sim.ONBOARD_DRIFT_SHARE} of its error budget, is set "
        "from the paper's RPCV-0 minus RFM-1 in quadrature); that a shift leaves it and the "
        "three other models remove it is the result.")
    best = min(many.values())
    physical_like = (many["RFM-1"] + many["physical"]) / 2
    rpcv1_between = many["RPCV-1"] > 1.15 * physical_like and many["RPCV-1"] < many["RPCV-0"]
    report.finding(
        "rpcv1_between",
        "RPCV-1 (RMSE 2D 0.82-1.02 m) is better than RPCV-0 but worse than RFM-1 and CCRS "
        "(~0.63 m) (Table 3)",
        rpcv1_between,
        f"ours RPCV-1 {many['RPCV-1']:.2f} m, RFM-1 {many['RFM-1']:.2f} m, physical "
        f"{many['physical']:.2f} m (18-45 GCPs). "
        + ("" if rpcv1_between else
           "Not reproduced: the simulated vendor RPC's error is an on-board bias plus a drift "
           "linear in time (ephemeris and attitude), which an affine image correction absorbs "
           "entirely, so RPCV-1 is as good as the physical model here. The paper's RPCV-1 "
           "excess (~0.3 m in quadrature) points to a distortion of the real RPCs that an "
           "affinity cannot follow (e.g. attitude variations within the 2.4 s scene), which "
           "the simulator does not model."))
    level_ok = all(abs(many[m] / 0.63 - 1.0) <= CLOSE for m in ("RFM-1", "physical"))
    tied = all(many[m] <= 1.15 * best for m in ("RFM-1", "physical"))
    truth_floor = float(sim.finite_mean(data.many("physical", "truth2d")))
    report.finding(
        "best_models",
        "RFM-1 and CCRS give the best orientation, RMSE 2D ~0.63 m (about the GSD) with 18 "
        "or more GCPs (Table 3)",
        True if tied and level_ok else (None if tied or level_ok else False),
        f"ours RFM-1 {many['RFM-1']:.2f} m and physical {many['physical']:.2f} m (best: "
        f"{best:.2f} m), of which the models' own error is {truth_floor:.2f} m: the rest is "
        "the pointing noise of the ICPs (the preset's 0.5 px of 0.62 m per axis, 0.44 m 2D). "
        "The paper's 0.63 m floor implies a pointing error of about 0.7 px. Our GSD: "
        f"{gsd:.2f} m (the small variant's pixels are 40 times the paper's, with the same "
        "pointing error in metres).")
    gain = {m: float(sim.finite_mean((data.values(f"t3/{m}/18/2d") - data.values(f"t3/{m}/45/2d"))
                                / data.values(f"t3/{m}/45/2d"))) for m in sim.MODELS}
    flat = [m for m in sim.MODELS if gain[m] < 0.10]
    report.finding(
        "eighteen_enough",
        "More than 18 well-distributed (stratified) GCPs do not improve the results "
        "(Table 3)",
        True if len(flat) == len(gain) else (None if flat else False),
        "ours, RMSE 2D with 18 GCPs relative to 45 (mean over the seeds): "
        + ", ".join(f"{m} {100 * g:+.0f} %" for m, g in gain.items()) + "."
        + ("" if "RFM-1" in flat else
           " RFM-1 still gains from 18 to 45 GCPs here: its 14 unknowns, fitted to 36 "
           "observations with 0.31 m of pointing noise each, carry that noise to the ICPs "
           "(about sqrt(7/18) of it per axis), which more GCPs average out; the paper's "
           "RFM-1 was flat from 18 GCPs (0.63, 0.64, 0.60, 0.62 m)."))
    r9, r18 = data.mean("sampling/RFM-1/9/SR/mean"), data.mean("sampling/RFM-1/18/SR/mean")
    report.finding(
        "rfm1_nine",
        "RFM-1 with only 9 GCPs (one per cell, 14 unknowns) is clearly worse than with 18 "
        "(0.97 m against 0.63 m, Table 3)",
        r9 > 1.2 * r18,
        f"ours {r9:.2f} m against {r18:.2f} m (mean RMSE 2D of the nine stratified samples of "
        "the sampling test: one combination per seed, as in Table 3, varies too much; "
        f"Table 3's: {data.mean('t3/RFM-1/9/2d'):.2f} against "
        f"{data.mean('t3/RFM-1/18/2d'):.2f} m).")
    r2 = {m: data.est(f"fig4/{m}/r2", "") for m in sim.MODELS}
    slope = data.est("fig4/RPCV-0/slope", "m/km")
    grows = (r2["RPCV-0"].mean > 0.1 and bool(np.all(slope.finite > 0))
             and r2["RPCV-0"].mean > 3 * max(r2[m].mean for m in sim.MODELS if m != "RPCV-0"))
    report.finding(
        "distance_growth",
        "After RPCV-0 the 2D residuals grow linearly with the distance from the image centre "
        "(R² = 0.37); no other model shows it (Fig. 4)",
        grows,
        f"ours R² RPCV-0 {r2['RPCV-0'].format(2)}, slope {slope.format(3)}; RPCV-1 "
        f"{r2['RPCV-1'].mean:.2f}, RFM-1 {r2['RFM-1'].mean:.2f}, physical "
        f"{r2['physical'].mean:.2f}. The along-track drift grows with the along-track "
        "distance from the centre; the planimetric distance mixes in the across-track one, "
        "hence a moderate R² (|along-track| residual: R² "
        f"{data.est('fig4/RPCV-0/along/r2', '').mean:.2f}).")
    x0, y0 = float(sim.finite_mean(data.many("RPCV-0", "x"))), float(sim.finite_mean(data.many(
        "RPCV-0", "y")))
    report.finding(
        "along_track",
        "RPCV-0 leaves systematic errors mainly along track (Fig. 5a; Table 3: RMSE Y "
        "1.08-1.11 m against X 0.58-0.65 m for a near-polar orbit)",
        y0 > 1.5 * x0,
        f"ours RPCV-0 RMSE X {x0:.2f} m, Y {y0:.2f} m (18-45 GCPs; the simulated orbit is "
        "descending at 97 deg, so Y is nearly along track).")
    orders = {k: {n: data.mean(f"order/{k}/{n}/2d") for n in sim.COUNTS} for k in sim.RFM_ORDERS}
    compared = [(n, k) for k in (2, 3) for n in sim.COUNTS if math.isfinite(orders[k][n])]
    first_best = bool(compared) and all(orders[1][n] < orders[k][n] for n, k in compared)
    report.finding(
        "rfm_order",
        "A first-order RFM (4 coefficients per polynomial) gives the lowest ICP RMSE for any "
        "number of GCPs (Fig. 3)",
        first_best,
        "ours RMSE 2D (m), order 1 / 2 / 3: " + "; ".join(
            f"{n} GCPs {orders[1][n]:.2f}"
            + "".join(f" / {orders[k][n]:.2f}" for k in (2, 3) if math.isfinite(orders[k][n]))
            for n in sim.COUNTS) + " (an order needs 7, 19 or 39 GCPs).")
    _sampling_finding(report, data)
    _few_finding(report, data)
    _ortho_findings(report, data)


def _sampling_finding(report: Report, data: _Data) -> None:
    parts, ratio = [], {}
    for m in ("RFM-1", "physical"):
        for n in sim.SAMPLING_COUNTS:
            mr = data.mean(f"sampling/{m}/{n}/R/mean") / data.mean(f"sampling/{m}/{n}/SR/mean")
            hr = data.mean(f"sampling/{m}/{n}/R/half") / data.mean(f"sampling/{m}/{n}/SR/half")
            ratio[(m, n)] = (mr, hr)
        parts.append(f"{m}: R / SR mean {ratio[(m, 9)][0]:.2f} and interval "
                     f"{ratio[(m, 9)][1]:.1f}x with 9 GCPs, {ratio[(m, 18)][0]:.2f} and "
                     f"{ratio[(m, 18)][1]:.1f}x with 18")
    rfm = (ratio[("RFM-1", 9)][0] > 1.1 and ratio[("RFM-1", 9)][1] > 1.5
           and ratio[("RFM-1", 18)][0] < ratio[("RFM-1", 9)][0])
    physical = ratio[("physical", 9)][1] > 2.0
    fails = sum(data.mean(f"sampling/{m}/9/R/fail") for m in sim.MODELS)
    report.finding(
        "sampling",
        "Random sampling of 9 GCPs gives worse and much less reliable results than "
        "stratified random sampling, especially with RFM-1 and CCRS (CCRS's interval ~3x "
        "wider); with 18 GCPs the sampling matters much less (Fig. 6)",
        True if rfm and physical else (None if rfm else False),
        "ours " + "; ".join(parts) + f" ({fails:.1f} failed fits per seed among the random "
        "samples of 9)."
        + ("" if physical else
           " The physical model hardly feels the sampling here: its nine parameters have "
           "a-priori sigmas from the stated 15 m accuracy and its attitude drifts "
           "extrapolate linearly in time, so nine GCPs anywhere in the scene determine it; "
           "the paper's CCRS model was three times less reliable with random samples."))


def _few_finding(report: Report, data: _Data) -> None:
    k_better = next((k for k in sim.FEW_COUNTS if k >= 3 and data.mean(f"few/RPCV-1/{k}/2d")
                     < 0.85 * data.mean(f"few/RPCV-0/{k}/2d")), None)
    below = [k for k in sim.FEW_COUNTS
             if max(data.mean(f"few/RPCV-0/{k}/2d"), data.mean(f"few/RPCV-1/{k}/2d")) < 2.2]
    first = f"{below[0]} GCP{'s' if below[0] > 1 else ''}" if below else "no count"
    report.finding(
        "few_gcps",
        "With 3-7 GCPs RPCV-1 is not numerically stable; only from 8 GCPs is it clearly "
        "better than RPCV-0 (Fig. 7)",
        k_better is not None and k_better >= 7,
        f"ours: RPCV-1 is clearly better (>15 %) on average from {k_better} GCPs; both stay "
        f"under 2.2 m from {first} (the paper: from 4); with "
        f"three GCPs (an exact affinity) RPCV-1 averages "
        f"{data.mean('few/RPCV-1/3/2d'):.2f} m and is unstable in some seeds. "
        + ("" if k_better is not None and k_better >= 7 else
           "Not reproduced beyond three GCPs: with one GCP per cell of the 3 x 3 grid and "
           "0.3 m of pointing error, four or more GCPs determine the affinity well; the "
           "paper's instability up to seven suggests poorer GCP measurements or geometry "
           "in its draws."))


def _ortho_findings(report: Report, data: _Data) -> None:
    tan = data.mean("view/tan_rms")
    worst, spreads = 0.0, []
    for d in data.dems:
        shifts = []
        for m in sim.MODELS:
            shifts.append(data.mean(f"shift/{d}/{m}/18/2d"))
            for n in MANY:
                pred = np.hypot(data.values(f"t3/{m}/{n}/2d"), data.values(f"dem/{d}/sigma_pred"))
                ratio = float(sim.finite_mean(data.values(f"ortho/{d}/{m}/{n}/2d") / pred))
                worst = max(worst, abs(ratio - 1.0))
        spreads.append(max(shifts) / min(shifts) - 1.0)
    report.finding(
        "ortho_budget",
        "The orthoimage error adds the orientation and the DEM errors in quadrature, "
        "sigma_ortho² = sigma_o² + sigma_DEM² (Eq. 3), sigma_DEM not depending on the sensor "
        "model (Table 7)",
        worst < 0.10 and max(spreads) < 0.25,
        f"ours: with sigma_DEM = RMSEz x tan(theta) (tan theta = {tan:.3f} at the ICPs; "
        "RMSEz the DEM's height error at the ICPs) the measured orthoimage RMSE 2D is within "
        f"{100 * worst:.0f} % of the prediction for every model, DEM and 18-45 GCPs (mean "
        "over the seeds); the DEM's share differs by at most "
        f"{100 * max(spreads):.0f} % between models. Read literally with sigma_DEM = RMSEz "
        "the equation would predict 5.9 m for the 20 m DEM; the paper's sigma_DEM is "
        "planimetric, which the viewing geometry sets.")
    rising = all(
        all(data.mean(f"ortho/{a}/{m}/18/2d") < data.mean(f"ortho/{b}/{m}/18/2d")
            for a, b in zip(data.dems, data.dems[1:], strict=False))
        for m in sim.MODELS)
    best = {d: (data.mean(f"ortho/{d}/RFM-1/18/2d") + data.mean(f"ortho/{d}/physical/18/2d")) / 2
            for d in data.dems}
    report.finding(
        "dem_accuracy",
        "The orthoimage's accuracy follows the DEM's: best with the dense DEM (RMSE 2D "
        "~0.74 m with CCRS or RFM-1 and 18 GCPs), 0.82 m with the medium one, worst with "
        "the coarse one (Tables 4-6)",
        rising if "dem2" in data.dems else (None if rising else False),
        "ours, RFM-1 and physical with 18 GCPs: " + ", ".join(
            f"{d} (RMSEz {data.mean(f'dem/{d}/rmse_z'):g} m) {v:.2f} m" for d, v in best.items())
        + ("" if "dem2" in data.dems else "; the small variant has no dense 2 m DEM (a 2 m "
           "grid over the 17 km scene is a full-variant cost)") + ".")
    paper_t7 = {"dem2": 0.43, "dem5": 0.57, "dem20": 1.05}
    ours = {d: data.mean(f"shift/{d}/physical/18/2d") for d in data.dems}
    floor = 0.43
    report.finding(
        "dem_share_levels",
        "The DEM's share of the orthoimage error is 0.43, 0.57 and 1.05 m (RMSE 2D) for "
        "RMSEz 0.31, 1.75 and 5.82 m (Table 7)",
        None,
        "ours (physical, 18 GCPs): " + ", ".join(f"{d} {v:.2f} m" for d, v in ours.items())
        + f" = RMSEz x tan(theta). The paper's values include re-identifying the ICPs on "
        f"the orthoimage, a floor of ~{floor} m (its dense DEM's share, where RMSEz x "
        "tan(theta) is 0.05 m); without it in quadrature they are "
        + ", ".join(f"{math.sqrt(max(paper_t7[d] ** 2 - floor**2, 0.0)):.2f} m"
                    for d in ("dem5", "dem20"))
        + " for the 5 and 20 m DEMs, against our "
        + ", ".join(f"{data.mean(f'dem/{d}/rmse_z') * data.mean('view/tan_rms'):.2f} m"
                    for d in ("dem5", "dem20")) + " predicted: the geometry explains the rest "
        "(the 20 m DEM's -1.71 m bias, Table 2, adds to the paper's).")


# ================================================================================ tables
def _setup(report: Report, data: _Data, full: bool) -> None:
    n = len(data.outcomes)
    report.section("Set-up (Tables 1 and 2)", (
        f"Each of the {n} repetitions simulates the `aguilar2007-quickbird` preset "
        f"({'full: 27552 x 27424 px of 0.62 m' if full else 'small: 689 x 686 px of 24.8 m'}"
        ", the same 17 x 17 km footprint and pointing noise in metres) with a new seed: new "
        "fractal terrain of 50-850 m, new on-board errors (15 m RMSE 2D, the along-track "
        f"drift share set to {sim.ONBOARD_DRIFT_SHARE}: see the findings), 45 GCPs "
        "stratified over the 3 x 3 grid (five per cell) and 79 ICPs, measured with 0.5 px "
        "of 0.62 m (0.31 m per axis) and surveyed with 5 cm (DGPS), and the measured DEMs "
        f"({', '.join(data.dems)}).\n\n"
        "**Models.** The *vendor RPC* is an RPC00B fitted to the simulated on-board "
        "physical model (`geoblock_rpc.fit.fit_rpc`, fit error "
        f"{data.est('vendor/fit_px', 'px').mean:.1e} px), as DigitalGlobe fits its RPCs to "
        "its camera model; **RPCV-0** and **RPCV-1** refine it by a shift or an affinity in "
        "image space (`geoblock.models.ImageCorrection` fitted by `geoblock.adjust.resect`); "
        "**RFM-1** is a first-order rational function fitted to the GCPs alone in UTM "
        "(`geoblock_rpc.rfm.fit_rfm`, separate denominators: 7 unknowns per image "
        "coordinate); the **physical** model stands for Toutin's CCRS model in OrthoEngine: "
        "the on-board linescan model (ephemeris, attitude, detector look directions) with "
        "its `physical` parameter set (attitude biases and drifts, along- and across-track "
        "position biases, focal scale, with a-priori sigmas from the 15 m on-board "
        "accuracy) adjusted to the GCPs.\n\n"
        "**Accuracy.** As in the paper, an ICP's error is its measured image position "
        "located through the oriented model at its surveyed height, minus its surveyed "
        "position (X = east, Y = north). The orthoimage's error at an ICP is measured "
        "without rendering: the orthoimage shows the ICP where the oriented model puts its "
        "image position on the DEM, so the measured image position is located on the DEM "
        "(`geoblock.localize`) and compared with the surveyed position; Table 7's DEM "
        "share is that location minus the orientation's. Each repetition draws one "
        "stratified combination per GCP count (1-5 per cell, nested), as the paper's fixed "
        "combinations."))
    rows = [
        GridRow("off-nadir / incidence at the centre (deg)", ["8 (off-nadir)"],
                [data.est("view/incidence", "deg")]),
        GridRow("GSD (m)", ["0.62 x 0.62"], [data.est("gsd")]),
        GridRow("ICP height range (m)", ["68-247"],
                [f"{data.mean('icp/h_min'):.0f}-{data.mean('icp/h_max'):.0f}"]),
        GridRow("vendor RPC before refinement, ICP RMSE 2D (m)",
                ["RMSE 1D 2.4-13.8 (literature)"], [data.est("vendor/2d")]),
    ]
    for d in ("dem2", "dem5", "dem20"):
        spacing, _, rmse, _ = paper.TABLE_2[d]
        ours: Estimate | str = (data.est(f"dem/{d}/icp_rmse_z") if d in data.dems
                                else "not in the small variant")
        rows.append(GridRow(f"DEM of {spacing} m: RMSEz (m)", [rmse], [ours]))
    report.grid("tables_1_2", ["value"], rows, title="Tables 1 and 2: the scene and the DEMs",
                note="Our DEMs' RMSEz is measured at the ICPs (the preset sets it over the "
                "whole grid); the paper's at 50 DGPS points. The paper's 20 m DEM also has a "
                "mean error of -1.71 m, ours none.")


def _table_3(report: Report, data: _Data) -> None:
    report.section("Orientation accuracy vs GCPs and model (Table 3)")
    rows = [GridRow(_row_label(m, n), list(paper.TABLE_3[(paper.PAPER_MODEL[m], n)]),
                    [data.est(f"t3/{m}/{n}/{s}") for s in ("x", "y", "2d")])
            for m in sim.MODELS for n in sim.COUNTS]
    report.grid("table_3", ["RMSE X (m)", "RMSE Y (m)", "RMSE 2D (m)"], rows,
                title="Table 3: RMSE at the 79 ICPs after sensor orientation",
                note="The paper's maximum and mean errors are not repeated: the signs of our "
                "errors are random per seed (results.json has every statistic per seed).")
    report.table(["model", "RMSE 2D as measured, 18-45 GCPs", "model's own error",
                  "pointing share (quadrature)"],
                 [[m, estimate(data.many(m)).format(2),
                   estimate(data.many(m, "truth2d")).format(2),
                   estimate(np.sqrt(np.maximum(data.many(m) ** 2
                                               - data.many(m, "truth2d") ** 2, 0.0))).format(2)]
                  for m in sim.MODELS], key="orientation_floor")
    report.text("The model's own error is the ICP's *true* image position located at its "
                "true height, against the truth: what is left once pointing and survey "
                "noise are taken out. The rest is the ICPs' pointing noise (0.44 m 2D).")
    report.figure(figures.rmse_figure(data.outcomes), "aguilar2007_rmse_vs_gcps.png",
                  "RMSE 2D at the ICPs against the number of GCPs for the four models "
                  "(Table 3 as a figure; the paper's Fig. 3 is the RFM order test below)")
    report.section("The RFM order (Fig. 3)")
    header = ["RFM order (coefficients per polynomial)"] + [f"{n} GCPs" for n in sim.COUNTS]
    rows_o: list[list[str]] = []
    for k, coefficients in zip(sim.RFM_ORDERS, (4, 10, 20), strict=True):
        cells = []
        for n in sim.COUNTS:
            e = data.est(f"order/{k}/{n}/2d")
            cells.append(e.format(2) if e.finite.size else "too few GCPs")
        rows_o.append([f"{k} ({coefficients})"] + cells)
    report.table(header, rows_o, key="fig_3")
    report.text("RMSE 2D at the ICPs (m) of terrain-dependent RFMs of each order fitted to "
                "the same GCPs (the paper's Fig. 3 plots them against the number of "
                "coefficients; it prints no values: the lowest RMSE with 4 coefficients for "
                "any number of GCPs).")


def _distance(report: Report, data: _Data) -> None:
    report.section("Systematic errors of RPCV-0 (Figs. 4 and 5)")
    report.compare("fig_4", [
        Row("RPCV-0: R² of the 2D residual vs distance", "0.37",
            data.est("fig4/RPCV-0/r2", "")),
        Row("RPCV-0: slope of the 2D residual vs distance (m per km)", "-",
            data.est("fig4/RPCV-0/slope", "m/km"), "", ),
        Row("RPCV-0: R² of the along-track residual vs distance", "-",
            data.est("fig4/RPCV-0/along/r2", "")),
        *(Row(f"{m}: R² of the 2D residual vs distance", "no growth",
              data.est(f"fig4/{m}/r2", "")) for m in sim.MODELS if m != "RPCV-0"),
    ], title="Fig. 4: residuals against the distance from the image centre (the "
       "combinations of 18-45 GCPs of Table 3 pooled, per seed)", decimals=3)
    report.figure(figures.distance_figure(data.outcomes), "aguilar2007_fig4_distance.png",
                  "2D residuals at the ICPs against the distance from the image centre after "
                  "each model, and RPCV-0's along-track residual (the paper's Fig. 4)")
    report.figure(figures.vector_figure(data.outcomes[0]), "aguilar2007_fig5_vectors.png",
                  "ICP error vectors after orientation with 18 GCPs (the paper's Fig. 5): "
                  "RPCV-0's along-track pattern, none after the other models")


def _sampling(report: Report, data: _Data) -> None:
    report.section("Random against stratified GCP sampling (Fig. 6)")
    rows = []
    for n in sim.SAMPLING_COUNTS:
        for m in sim.MODELS:
            cells = [_row_label(m, n)]
            for design in ("SR", "R"):
                cells += [data.est(f"sampling/{m}/{n}/{design}/mean").format(2),
                          data.est(f"sampling/{m}/{n}/{design}/half").format(2)]
            cells.append(f"{data.mean(f'sampling/{m}/{n}/R/fail'):.1f}")
            rows.append(cells)
    report.table(["model, GCPs", "SR: mean RMSE 2D", "SR: 95 % half-width",
                  "R: mean RMSE 2D", "R: 95 % half-width", "R: failed fits per seed"], rows,
                 key="fig_6")
    report.text(f"Per seed, {sim.SAMPLING_REPEATS} random (R) and {sim.SAMPLING_REPEATS} "
                "stratified random (SR, equal numbers per cell) samples of the 45 GCPs; the "
                "mean RMSE 2D at the ICPs over the samples and the half-width of its 95 % "
                "Student-t interval (the paper's error bars), then the mean and interval of "
                "those over the seeds.")

    def ratio(m: str, n: int, stat: str) -> Estimate:
        return estimate(data.values(f"sampling/{m}/{n}/R/{stat}")
                        / data.values(f"sampling/{m}/{n}/SR/{stat}"), "")

    report.compare("fig_6_text", [
        Row("CCRS / physical, 9 GCPs: interval width R / SR", "~3",
            ratio("physical", 9, "half")),
        Row("RFM-1, 9 GCPs: interval width R / SR", "larger (figure)",
            ratio("RFM-1", 9, "half")),
        Row("CCRS / physical and RFM-1, 9 GCPs SR: mean RMSE 2D (m)", "~0.65-1 (interval)",
            f"{data.est('sampling/physical/9/SR/mean').format(2)}; "
            f"{data.est('sampling/RFM-1/9/SR/mean').format(2)}"),
        Row("CCRS / physical and RFM-1, 18 GCPs SR: mean RMSE 2D (m)", "~0.62-0.76 (interval)",
            f"{data.est('sampling/physical/18/SR/mean').format(2)}; "
            f"{data.est('sampling/RFM-1/18/SR/mean').format(2)}"),
    ], title="Fig. 6 as the paper's text gives it")
    report.figure(figures.sampling_figure(data.outcomes), "aguilar2007_fig6_sampling.png",
                  "Mean RMSE 2D of nine samples of 9 and 18 GCPs, random (R) and stratified "
                  "random (SR), with the 95 % interval of that mean (the paper's Fig. 6)")


def _few(report: Report, data: _Data) -> None:
    report.section("RPCV-0 and RPCV-1 with few GCPs (Fig. 7)")
    rows = [[str(k), data.est(f"few/RPCV-0/{k}/2d").format(2),
             data.est(f"few/RPCV-1/{k}/2d").format(2)] for k in sim.FEW_COUNTS]
    report.table(["GCPs", "RPCV-0: RMSE 2D", "RPCV-1: RMSE 2D"], rows, key="fig_7")
    report.text(f"Per seed, the mean of {sim.FEW_REPEATS} samples: the first GCP in the "
                "central cell, then one per cell in a random order of cells (the paper's "
                "design); RPCV-1 is the shift below three GCPs, as in PCI. The paper prints "
                "no values: both under 2.2 m from four GCPs, RPCV-1 unstable with 3-7 and "
                "clearly better from 8.")
    report.figure(figures.few_gcps_figure(data.outcomes), "aguilar2007_fig7_few_gcps.png",
                  "RMSE 2D at the ICPs of RPCV-0 and RPCV-1 with 1 to 9 GCPs (the paper's "
                  "Fig. 7)")


def _ortho(report: Report, data: _Data) -> None:
    report.section("Orthoimage accuracy with each DEM (Tables 4, 5 and 6)")
    for d in ("dem20", "dem5", "dem2"):
        number, table = paper.DEM_TABLES[d]
        spacing, _, rmse, _ = paper.TABLE_2[d]
        title = (f"{number}: RMSE at the 79 ICPs on the orthoimage, DEM of {spacing} m grid "
                 f"spacing (RMSEz = {rmse} m)")
        if d not in data.dems:
            report.text(f"**{title}**: not in the small variant (no {spacing} m DEM; run "
                        "with `--full`).")
            continue
        rows = [GridRow(_row_label(m, n), list(table[(paper.PAPER_MODEL[m], n)]),
                        [data.est(f"ortho/{d}/{m}/{n}/{s}") for s in ("x", "y", "2d")])
                for m in sim.MODELS for n in sim.COUNTS]
        report.grid(f"table_{number.split()[1]}", ["RMSE X (m)", "RMSE Y (m)", "RMSE 2D (m)"],
                    rows, title=title)
    report.section("The DEM's share and the error budget (Table 7, Eq. 3)")
    columns = ["DEM 2 x 2: RMSE 2D (m)", "DEM 5 x 5: RMSE 2D (m)", "DEM 20 x 20: RMSE 2D (m)"]
    rows7 = []
    for m in sim.MODELS:
        for n in (*sim.COUNTS, "Mean"):
            ours: list[Estimate | str] = []
            for d in ("dem2", "dem5", "dem20"):
                if d not in data.dems:
                    ours.append("not in the small variant")
                elif n == "Mean":
                    ours.append(estimate(sim.finite_mean(np.stack(
                        [data.values(f"shift/{d}/{m}/{c}/2d") for c in sim.COUNTS]), axis=0)))
                else:
                    ours.append(data.est(f"shift/{d}/{m}/{n}/2d"))
            rows7.append(GridRow(_row_label(m, n), list(paper.TABLE_7[(paper.PAPER_MODEL[m], n)]),
                                 ours))
    report.grid("table_7", columns, rows7,
                title="Table 7: RMSE 2D at the ICPs related to the quality of the DEM "
                "(orthoimage position minus orientation position)")
    report.text(
        "**The propagation of a DEM error into the orthoimage.** A line of sight reaches the "
        "ground at a viewing zenith angle theta; a DEM height error dh moves the point where "
        "it meets the DEM horizontally, towards the sensor for dh > 0, by "
        "dh tan(theta) / (1 + s tan(theta)), s the terrain slope along the view's azimuth. "
        "With QuickBird's 8 deg off-nadir view (about 8.5 deg of incidence, tan theta ~0.15) "
        "and slopes below ~30 %, the slope term changes it by under 5 %, so the DEM's "
        "planimetric contribution is sigma_DEM = RMSEz x tan(theta): the sigma_DEM of the "
        "paper's Eq. 3 is this planimetric error, not RMSEz itself. The budget below "
        "compares the measured orthoimage error with sqrt(sigma_o² + sigma_DEM²), sigma_o "
        "the orientation RMSE of the same fit (Table 3) and sigma_DEM the RMS of dh "
        "tan(theta) over the ICPs (dh the DEM's height error there; the nominal RMSEz gives "
        "the column before it).")
    tan = data.values("view/tan_rms")
    rows_b = []
    for d in data.dems:
        z = data.mean(f"dem/{d}/rmse_z")
        for m in sim.MODELS:
            o = data.values(f"t3/{m}/18/2d")
            meas = data.values(f"ortho/{d}/{m}/18/2d")
            pred = np.hypot(o, data.values(f"dem/{d}/sigma_pred"))
            rows_b.append([
                f"{d} (RMSEz {z:g} m), {m}",
                data.est(f"dem/{d}/icp_rmse_z").format(2),
                estimate(o).format(2),
                estimate(z * tan).format(2),
                data.est(f"dem/{d}/sigma_pred").format(2),
                data.est(f"shift/{d}/{m}/18/2d").format(2),
                estimate(pred).format(2),
                estimate(meas).format(2),
                estimate(meas / pred, "").format(3),
                estimate(np.hypot(o, z)).format(2),
            ])
    report.table(["DEM, model (18 GCPs)", "RMSEz at the ICPs", "sigma_o (orientation)",
                  "RMSEz tan(theta), nominal RMSEz", "sigma_DEM predicted: RMS of dh tan(theta)",
                  "sigma_DEM measured (Table 7)",
                  "sigma_ortho predicted", "sigma_ortho measured", "measured / predicted",
                  "Eq. 3 with sigma_DEM = RMSEz"], rows_b, key="ortho_budget")
    report.figure(figures.budget_figure(data.outcomes, data.dems), "aguilar2007_ortho_budget.png",
                  "Orthoimage RMSE 2D against the DEM's RMSEz with 18 GCPs: ours (points, "
                  "95 % intervals), the budget with sigma_DEM = RMSEz tan(theta) (solid), "
                  "Eq. 3 read with sigma_DEM = RMSEz (dotted), the paper's Tables 4-6 "
                  "(dashed)")


def run(report: Report, *, full: bool, seeds: Sequence[int],
        progress: Callable[[str], None]) -> None:
    """Simulate and measure every test once per seed and fill ``report``."""
    data = _Data(sim.outcomes(seeds, full, progress))
    progress("  tables and figures")
    _findings(report, data)
    _setup(report, data, full)
    _table_3(report, data)
    _distance(report, data)
    _sampling(report, data)
    _few(report, data)
    _ortho(report, data)
    report.section(
        "Not simulated",
        "The paper's ICPs lie in a 68-247 m sub-area with the dense DEM; ours cover the "
        "scene. OrthoEngine's CCRS model is replaced by our physical linescan model (see "
        "the set-up); the sin(x)/x resampling of the paper's 60 orthoimages does not enter "
        "our rendering-free measure. The paper's maximum and mean errors (Tables 3-6) and "
        "the 20 m DEM's bias are not reproduced.")
    report.record("seconds_per_seed", [o.seconds for o in data.outcomes])
    report.record("per_seed", data.per_seed())
