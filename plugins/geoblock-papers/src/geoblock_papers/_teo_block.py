"""The block of Teo et al. (2010) and Chen, Teo & Lo (2008), shared by both experiments.

Both papers adjust the same three SPOT-5 strips (case I of Teo et al.: one scene per strip)
with the same three methods; :mod:`geoblock_papers.teo2010` and
:mod:`geoblock_papers.chen2008` format the statistics computed here against each paper's
tables.

One repetition (:func:`seed_outcome`, kept per seed and variant so that both experiments
run in one process share it):

1. simulates the ``teo2010-spot5`` preset in memory (:mod:`geoblock.simulate.scene`, the
   block :func:`geoblock.workflows.run_scenario` would write) with the repetition's seed:
   new terrain, DEM, on-board errors and points. As in the papers, whose GCPs came from
   1:5000 maps while the TPs were measured where the strips overlap, the GCPs lie away from
   the overlaps: 27 are drawn per strip (3 per cell of a 3 x 3 grid) and the 9 nearest the
   strip's centre column are kept (:func:`central_gcps`); TPs and ICTPs are drawn in the
   ranges of Teo et al.'s Table III (13-19 and 13-18 per overlap);
2. builds the three methods' models from the on-board models: **MBA** Chen & Lee's
   polynomial model fitted to the on-board model (:func:`geoblock_spot.fit.fit_chenlee` with
   the strip's own interior geometry, its ``mba`` parameter set), **DG** the on-board
   line-of-sight model with its ``dg`` set, **RFM** a sensor-oriented RPC fitted to the
   on-board model (:func:`geoblock_rpc.fit.fit_rpc`) refined by an affine image correction
   (Teo et al. eq. 7);
3. adjusts each method in the runs of :data:`RUNS` (:func:`geoblock.adjust.adjust`);
4. measures, per run: GCP and ICP RMSE per strip (Tables V-VI), TP and ICTP discrepancy
   RMSE per overlap through the adjusted models and the DEM (Table III), the TPs' adjusted
   heights against the truth; and, once, the on-board models' accuracy (Table II) and the
   ICTP discrepancy of the TRUE models (the floor that pointing noise and DEM error leave).

Statistics are flat ``{key: value}`` dictionaries per seed (:data:`SeedOutcome.values`);
:class:`Outcomes` turns a key into an :class:`~geoblock_papers.report.Estimate` over the
seeds. Keys: ``"{method}/{run}/{kind}/{where}/{stat}"`` with ``kind`` one of ``gcp, icp``
(``where`` a strip or ``all``) or ``tp, ictp`` (``where`` a pair label of :data:`PAIRS`; TPs
for the runs ``single`` and ``block`` only),
``stat`` one of ``e, n, 2d`` (RMSE, metres); ``"{method}/{run}/tp_height"`` (RMSE of the TPs'
adjusted heights, metres), ``"{method}/{run}/sigma0"``, ``"{method}/{run}/converged"`` (1 or
0); ``"onboard/{strip}/{mean_e|mean_n|rmse_e|rmse_n|rmse_2d}"``,
``"onboard/ictp/{pair}/{stat}"``, ``"truth/ictp/{pair}/{stat}"``;
``"count/{kind}/{strip or pair}"``; ``"incidence/{strip}"``, ``"gsd/{strip}"`` (degrees,
metres); ``"terrain/min"``, ``"terrain/max"``, ``"terrain/max_slope"`` (metres, degrees);
``"dem/tp_rmse"`` (the DEM's height error at the TPs, metres).
"""

from __future__ import annotations

import math
import time
from collections import OrderedDict
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from matplotlib.ticker import FuncFormatter

import geoblock
from geoblock.adjust import Block, BlockResult, GroundPoints, ImagePoints, adjust, ictp_accuracy
from geoblock.adjust.statistics import AccuracyStats, IctpDiscrepancies, PointErrors
from geoblock.report import error_vector_plot, to_local_en
from geoblock.report.figures import nice_number
from geoblock.simulate.points import PointSet
from geoblock.simulate.scenario import Scenario, derived_seed, preset_dict, scenario_from_dict
from geoblock.simulate.scene import (
    scene_dem,
    scene_grid,
    scene_points,
    scene_sensors,
    true_terrain,
)
from geoblock.simulate.sensors import SimulatedSensor, incidence_angle
from geoblock.simulate.study import onboard_errors
from geoblock.simulate.terrain import measured_dem
from geoblock_papers.registry import ExperimentError
from geoblock_papers.report import Estimate, GridRow, estimate

__all__ = [
    "CACHE_SIZE",
    "CONSISTENCY_ROWS",
    "GCPS_PER_STRIP",
    "GCP_CANDIDATES",
    "ICTP_RANGE",
    "METHODS",
    "PAIRS",
    "PAIR_COLUMNS",
    "POOR_DEM_RMSE_M",
    "RUNS",
    "STRIPS",
    "STRIP_COLUMNS",
    "TP_RANGE",
    "Outcomes",
    "PaperTables",
    "Run",
    "SeedOutcome",
    "TeoBlock",
    "Vectors",
    "absolute_grid",
    "add_dem_section",
    "add_figures",
    "add_findings",
    "central_gcps",
    "consistency_grid",
    "describe_setup",
    "icp_vector_figure",
    "ictp_bar_figure",
    "ictp_vector_figure",
    "is_cached",
    "method_models",
    "onboard_grid",
    "outcomes",
    "record_results",
    "scenario_dict",
    "seed_outcome",
    "setup_grid",
    "simulate_block",
    "ties_grid",
]

STRIPS = ("strip1", "strip2", "strip3")
#: overlapping pairs of strips, by label (Teo et al.'s "strips 1 & 2", "strips 2 & 3")
PAIRS: dict[str, tuple[str, str]] = {"1-2": ("strip1", "strip2"), "2-3": ("strip2", "strip3")}
METHODS = ("MBA", "DG", "RFM")


@dataclass(frozen=True)
class Run:
    """One adjustment of each method.

    Attributes
    ----------
    options : dict
        Options of :func:`geoblock.adjust.adjust`.
    dem : {"measured", "poor"}
        The DEM of the block: the preset's (RMSEz 5 m) or :data:`POOR_DEM_RMSE_M`.
    description : str
    """

    options: dict[str, Any]
    dem: str
    description: str


#: the adjustments of each method, by name
RUNS: dict[str, Run] = {
    "single": Run({"mode": "single"}, "measured",
                  "strip by strip with its GCPs (the papers' single adjustment)"),
    "block": Run({}, "measured", "all strips with GCPs, TPs and DEM control (a weighted "
                 "observation h - DEM = 0)"),
    "iterate": Run({"dem_control": "iterate"}, "measured",
                   "block, with the papers' literal DEM control (Z1 -> Z1' -> Z2 ...)"),
    "no-dem": Run({"dem_control": "none"}, "measured", "block without DEM control"),
    "collocation": Run({"collocation": True}, "measured",
                       "block, then least-squares collocation of the residual vectors "
                       "(Teo et al. eqs. 4-5)"),
    "poor-dem": Run({}, "poor", "block with a DEM of RMSEz 25 m (given to the adjustment "
                    "as 5 m)"),
}
#: RMSEz of the poor DEM, metres: what a 40 m DEM may reach over steep mountains (Teo et
#: al.: "the vertical accuracy in the hilly area could be larger than the estimated value")
POOR_DEM_RMSE_M = 25.0
#: GCPs per strip (Teo et al. Table I), kept from :data:`GCP_CANDIDATES` drawn per strip
GCPS_PER_STRIP = 9
#: GCPs drawn per strip: three per cell of the 3 x 3 grid, so that the 9 nearest the centre
#: column cover the strip's length
GCP_CANDIDATES = 27
#: TPs and ICTPs per overlap, drawn in these ranges (Teo et al. Table III: 19 and 13 TPs, 18
#: and 13 ICTPs)
TP_RANGE = (13, 19)
ICTP_RANGE = (13, 18)
#: sigma of the DEM heights given to the adjustment, metres (the preset's DEM RMSEz)
DEM_SIGMA_M = 5.0
#: the runs whose error vectors the figures show
_VECTOR_RUNS = ("single", "block")


# ================================================================================ block
def scenario_dict(seed: int, full: bool) -> dict[str, Any]:
    """The ``teo2010-spot5`` preset (``full`` or ``small``) with ``seed`` and the point
    counts above (:data:`GCP_CANDIDATES`, :data:`TP_RANGE`, :data:`ICTP_RANGE`)."""
    data = preset_dict("teo2010-spot5", "full" if full else "small")
    data["seed"] = int(seed)
    data["points"].update(gcp=GCP_CANDIDATES, tp=list(TP_RANGE), ictp=list(ICTP_RANGE))
    data["description"] += (f"; {GCP_CANDIDATES} GCP candidates per strip of which the "
                            f"{GCPS_PER_STRIP} nearest the centre column are kept")
    return data


@dataclass(frozen=True, eq=False)
class TeoBlock:
    """One simulated block, in memory.

    Attributes
    ----------
    scenario : Scenario
    sensors : dict of str to SimulatedSensor
        True and on-board models per strip.
    dem : DemSource
        The measured 40 m DEM (heights above the ellipsoid).
    poor_dem : DemSource
        The same with an RMSEz of :data:`POOR_DEM_RMSE_M`.
    points : PointSet
        Every simulated point with its truth (all GCP candidates included).
    ground : GroundPoints
        The kept GCPs and the ICPs, as surveyed.
    measurements : ImagePoints
        Their image measurements and the TPs' and ICTPs', kinds resolved.
    terrain : tuple of float
        Lowest and highest true height, and the steepest true slope (metres, degrees).
    """

    scenario: Scenario
    sensors: dict[str, SimulatedSensor]
    dem: Any
    poor_dem: Any
    points: PointSet
    ground: GroundPoints
    measurements: ImagePoints
    terrain: tuple[float, float, float]


def central_gcps(measurements: ImagePoints, shapes: Mapping[str, tuple[int, int]],
                 count: int) -> np.ndarray:
    """The ids of the ``count`` GCPs of each image nearest its centre column.

    Parameters
    ----------
    measurements : ImagePoints
        Kinds resolved.
    shapes : mapping of str to (int, int)
        ``(rows, cols)`` per image.
    count : int

    Returns
    -------
    ndarray of str
        The kept ids, image after image.

    Raises
    ------
    ExperimentError
        An image has fewer than ``count`` GCPs.
    """
    kept = []
    for image, (_, cols) in shapes.items():  # a loop over the three strips
        sel = (measurements.kind == "gcp") & (measurements.image == image)
        if int(sel.sum()) < count:
            raise ExperimentError(f"teo block: image {image} has {int(sel.sum())} GCPs, "
                                  f"fewer than the {count} wanted")
        offset = np.abs(measurements.col[sel] - (cols - 1) / 2.0)
        kept.append(measurements.id[sel][np.argsort(offset, kind="stable")[:count]])
    return np.concatenate(kept)


def simulate_block(seed: int, full: bool = False) -> TeoBlock:
    """Simulate the block of one repetition in memory (module docstring, step 1)."""
    scenario = scenario_from_dict(scenario_dict(seed, full))
    sensors = scene_sensors(scenario)
    truth = true_terrain(scenario, scene_grid(scenario, sensors))
    dem = scene_dem(scenario, truth, 0).to_dem()
    spacing = scenario.dems[0].spacing_m
    # seeded as a second DEM of the scenario would be (the preset has one)
    poor_dem = measured_dem(truth, spacing, POOR_DEM_RMSE_M,
                            seed=derived_seed(scenario.seed, 3, len(scenario.dems))).to_dem()
    points = scene_points(scenario, sensors, truth.to_dem())
    ground, meas = points.observations()
    meas = meas.resolve_kinds(ground)
    keep = central_gcps(meas, {i: s.true_model.shape for i, s in sensors.items()},
                        GCPS_PER_STRIP)
    gcp_ids = ground.id[ground.kind == "gcp"]
    drop = gcp_ids[~np.isin(gcp_ids, keep)]
    lo, hi = truth.relief
    return TeoBlock(scenario, sensors, dem, poor_dem, points,
                    ground.subset(~np.isin(ground.id, drop)), meas.subset(~np.isin(meas.id, drop)),
                    (float(lo), float(hi), float(np.nanmax(truth.slope_deg()))))


def method_models(sensors: Mapping[str, SimulatedSensor],
                  height_range: tuple[float, float]) -> dict[str, dict[str, Any]]:
    """The three methods' models of each strip, from its on-board model (module docstring,
    step 2).

    Parameters
    ----------
    sensors : mapping of str to SimulatedSensor
    height_range : (float, float)
        Heights the sensor-oriented RPCs are fitted over, metres above the ellipsoid.

    Returns
    -------
    dict
        ``{"MBA": {strip: model}, "DG": ..., "RFM": ...}``.
    """
    from geoblock_rpc.fit import fit_rpc
    from geoblock_rpc.model import RpcModel
    from geoblock_spot.fit import fit_chenlee

    out: dict[str, dict[str, Any]] = {"MBA": {}, "DG": {}, "RFM": {}}
    for i, sim in sensors.items():  # a loop over the three strips
        m = sim.onboard_model
        # the strip's own interior comes from the on-board model (geoblock_spot's
        # source_interior): the mba set's a-priori sigmas scale with the scene's duration
        out["MBA"][i] = fit_chenlee(m, location_accuracy_m=m.location_accuracy_m).model
        out["DG"][i] = m.with_parameter_set("dg")
        rpc, _ = fit_rpc(m, height_range=height_range, grid=(13, 13, 7), regularization=1e-6)
        out["RFM"][i] = geoblock.ImageCorrection(RpcModel(rpc, m.shape), order=1)
    return out


# ================================================================================ one seed
@dataclass(frozen=True)
class Vectors:
    """Error or discrepancy vectors for a figure, arrays (N,).

    ``lon, lat`` the point (degrees), ``de, dn`` the vector (metres east, north), ``kind``
    (``GCP``, ``ICP``, ``TP``, ``ICTP``), ``image`` (a strip, or ``"strip1 & strip2"``).
    """

    lon: np.ndarray
    lat: np.ndarray
    de: np.ndarray
    dn: np.ndarray
    kind: np.ndarray
    image: np.ndarray

    @staticmethod
    def concat(parts: Sequence[Vectors]) -> Vectors:
        return Vectors(*(np.concatenate([getattr(p, f) for p in parts])
                         for f in ("lon", "lat", "de", "dn", "kind", "image")))


@dataclass(frozen=True, eq=False)
class SeedOutcome:
    """The statistics of one repetition.

    Attributes
    ----------
    seed : int
    full : bool
    values : dict of str to float
        Flat statistics (the module docstring lists the keys); NaN where undefined.
    ties : dict of str to Vectors
        ``"{method}/{run}"`` -> TP and ICTP discrepancy vectors (runs single and block).
    checks : dict of str to Vectors
        ``"{method}/{run}"`` -> GCP and ICP error vectors (runs single and block).
    seconds : dict of str to float
        ``simulate``, ``models``, ``adjust``.
    """

    seed: int
    full: bool
    values: dict[str, float]
    ties: dict[str, Vectors]
    checks: dict[str, Vectors]
    seconds: dict[str, float]


def _put(values: dict[str, float], prefix: str, stats: AccuracyStats) -> None:
    values[f"{prefix}/e"] = stats.rmse_e
    values[f"{prefix}/n"] = stats.rmse_n
    values[f"{prefix}/2d"] = stats.rmse_2d


def _pair_label(a: str, b: str) -> str | None:
    return next((label for label, pair in PAIRS.items() if pair == (a, b)), None)


def _put_pairs(values: dict[str, float], prefix: str, disc: IctpDiscrepancies) -> None:
    by_pair = disc.by_pair()
    for label, pair in PAIRS.items():
        _put(values, f"{prefix}/{label}", by_pair.get(pair, AccuracyStats.from_errors([], [])))


def _tie_vectors(disc: IctpDiscrepancies, kind: str) -> Vectors:
    image = np.char.add(np.char.add(disc.image_a.astype(str), " & "), disc.image_b.astype(str))
    return Vectors(disc.lon_a, disc.lat_a, disc.e, disc.n, np.full(len(disc), kind), image)


def _check_vectors(check: PointErrors, ground: GroundPoints) -> Vectors:
    order = np.argsort(ground.id)
    k = order[np.searchsorted(ground.id, check.id, sorter=order)]
    return Vectors(ground.lon[k], ground.lat[k], check.e, check.n, check.kind, check.image)


def _measure_run(values: dict[str, float], prefix: str, result: BlockResult, tb: TeoBlock,
                 dem: Any, tp_truth: tuple[np.ndarray, np.ndarray],
                 with_ties: bool) -> tuple[Vectors, Vectors]:
    """The statistics of one adjustment into ``values``: with ``with_ties`` the TP
    discrepancies too (TPs ray-traced onto ``dem``, the block's); its tie (ICTP, and TP with
    ``with_ties``) and check vectors."""
    for kind in ("gcp", "icp"):
        for strip in STRIPS:
            _put(values, f"{prefix}/{kind}/{strip}", result.check.select(kind=kind,
                                                                         image=strip).stats())
        _put(values, f"{prefix}/{kind}/all", result.check.select(kind=kind).stats())
    meas = tb.measurements
    tp = meas.kind == "tp"
    tps = None
    if with_ties:
        tps = ictp_accuracy(result.models, meas.id[tp], meas.image[tp], meas.row[tp],
                            meas.col[tp], dem, warn=False)
        _put_pairs(values, f"{prefix}/tp", tps)
    assert result.ictp is not None  # the block has ICTPs
    _put_pairs(values, f"{prefix}/ictp", result.ictp)
    points = result.points
    sel = points.kind == "tp"
    ids, h_true = tp_truth
    if sel.any():
        order = np.argsort(ids)
        k = order[np.searchsorted(ids, points.id[sel], sorter=order)]
        values[f"{prefix}/tp_height"] = float(np.sqrt(np.mean((points.h[sel] - h_true[k]) ** 2)))
    else:
        values[f"{prefix}/tp_height"] = math.nan
    values[f"{prefix}/sigma0"] = float(result.sigma0)
    values[f"{prefix}/converged"] = float(result.converged)
    ictps = _tie_vectors(result.ictp, "ICTP")
    ties = ictps if tps is None else Vectors.concat([_tie_vectors(tps, "TP"), ictps])
    return ties, _check_vectors(result.check, tb.ground)


#: outcomes computed in this process, by ``(seed, full)``, oldest first
_CACHE: OrderedDict[tuple[int, bool], SeedOutcome] = OrderedDict()
#: outcomes kept in :data:`_CACHE` (a few hundred kB each)
CACHE_SIZE = 64


def is_cached(seed: int, full: bool = False) -> bool:
    """Whether :func:`seed_outcome` of ``(seed, full)`` is already computed in this
    process."""
    return (int(seed), bool(full)) in _CACHE


def seed_outcome(seed: int, full: bool = False) -> SeedOutcome:
    """Simulate, adjust and measure one repetition (module docstring); kept per
    ``(seed, full)`` in this process (the last :data:`CACHE_SIZE`), so that teo2010 and
    chen2008 share it.

    Raises
    ------
    GeoblockError
        The simulation or an adjustment failed (the message says which).
    """
    key = (int(seed), bool(full))
    if key not in _CACHE:
        _CACHE[key] = _compute_outcome(*key)
        while len(_CACHE) > CACHE_SIZE:
            _CACHE.popitem(last=False)
    return _CACHE[key]


def _compute_outcome(seed: int, full: bool) -> SeedOutcome:
    clock = time.perf_counter()
    tb = simulate_block(seed, full)
    seconds = {"simulate": time.perf_counter() - clock}
    values: dict[str, float] = {}
    meas, pts = tb.measurements, tb.points

    # the set-up: geometry, counts, terrain and DEM
    for strip, sim in tb.sensors.items():
        rows, cols = sim.true_model.shape
        values[f"incidence/{strip}"] = incidence_angle(sim.true_model, (rows - 1) / 2,
                                                       (cols - 1) / 2, sim.spec.centre_h)
        values[f"gsd/{strip}"] = sim.spec.gsd_m
        for kind in ("gcp", "icp"):
            values[f"count/{kind}/{strip}"] = float(np.count_nonzero(
                (meas.kind == kind) & (meas.image == strip)))
    values["terrain/min"], values["terrain/max"], values["terrain/max_slope"] = tb.terrain
    tp_rows = pts.ground.kind == "tp"
    tp_truth = (pts.ground.id[tp_rows], pts.ground.h_true[tp_rows])
    dem_h = tb.dem.height(pts.ground.lon_true[tp_rows], pts.ground.lat_true[tp_rows])
    values["dem/tp_rmse"] = float(np.sqrt(np.nanmean((dem_h - tp_truth[1]) ** 2)))
    dem_h = tb.poor_dem.height(pts.ground.lon_true[tp_rows], pts.ground.lat_true[tp_rows])
    values["poor_dem/tp_rmse"] = float(np.sqrt(np.nanmean((dem_h - tp_truth[1]) ** 2)))

    # the on-board models (Table II: at all the ground points) and the floor
    ob = onboard_errors(tb.sensors, pts)
    for strip in STRIPS:
        st = ob.select(image=strip).stats()
        values.update({f"onboard/{strip}/mean_e": st.mean_e, f"onboard/{strip}/mean_n": st.mean_n,
                       f"onboard/{strip}/rmse_e": st.rmse_e, f"onboard/{strip}/rmse_n": st.rmse_n,
                       f"onboard/{strip}/rmse_2d": st.rmse_2d})
    ictp = meas.kind == "ictp"
    for who, given in (("onboard", {i: s.onboard_model for i, s in tb.sensors.items()}),
                       ("truth", {i: s.true_model for i, s in tb.sensors.items()})):
        disc = ictp_accuracy(given, meas.id[ictp], meas.image[ictp], meas.row[ictp],
                             meas.col[ictp], tb.dem, warn=False)
        _put_pairs(values, f"{who}/ictp", disc)
    for kind in ("tp", "ictp"):
        sel = meas.kind == kind
        for label, (a, b) in PAIRS.items():
            both = np.intersect1d(meas.id[sel & (meas.image == a)],
                                  meas.id[sel & (meas.image == b)])
            values[f"count/{kind}/{label}"] = float(both.size)

    # the three methods, each in every run
    clock = time.perf_counter()
    lo, hi = tb.scenario.terrain.relief
    models = method_models(tb.sensors, (lo - 500.0, hi + 700.0))
    seconds["models"] = time.perf_counter() - clock
    clock = time.perf_counter()
    ties: dict[str, Vectors] = {}
    checks: dict[str, Vectors] = {}
    for method, strip_models in models.items():
        blocks = {"measured": Block(strip_models, meas, tb.ground, tb.dem, DEM_SIGMA_M),
                  "poor": Block(strip_models, meas, tb.ground, tb.poor_dem, DEM_SIGMA_M)}
        for run, spec in RUNS.items():
            block = blocks[spec.dem]
            try:
                result = adjust(block, **spec.options)
            except geoblock.GeoblockError as exc:
                raise ExperimentError(f"teo block, seed {seed}: the {method} {run} "
                                      f"adjustment failed: {exc}") from exc
            tie, check = _measure_run(values, f"{method}/{run}", result, tb, block.dem,
                                      tp_truth, with_ties=run in _VECTOR_RUNS)
            if run in _VECTOR_RUNS:
                ties[f"{method}/{run}"], checks[f"{method}/{run}"] = tie, check
    seconds["adjust"] = time.perf_counter() - clock
    return SeedOutcome(int(seed), bool(full), values, ties, checks, seconds)


# ================================================================================ seeds
@dataclass(frozen=True, eq=False)
class Outcomes:
    """The repetitions of an experiment: statistics as estimates over the seeds.

    Attributes
    ----------
    items : tuple of SeedOutcome
    """

    items: tuple[SeedOutcome, ...]

    @property
    def seeds(self) -> tuple[int, ...]:
        return tuple(o.seed for o in self.items)

    def est(self, key: str, unit: str = "m") -> Estimate:
        """The per-seed values of statistic ``key`` (NaN where a seed lacks it)."""
        return estimate((o.values.get(key, math.nan) for o in self.items), unit)

    def derived(self, fn: Callable[[Mapping[str, float]], float], unit: str = "m") -> Estimate:
        """``fn`` of each seed's values."""
        return estimate((fn(o.values) for o in self.items), unit)

    def array(self, key: str) -> np.ndarray:
        """(S,) the values of statistic ``key`` over the seeds (NaN where a seed lacks it)."""
        return np.array([o.values.get(key, math.nan) for o in self.items], dtype=float)

    def ratio(self, *pairs: tuple[str, str]) -> Estimate:
        """Per seed, the mean over ``pairs`` of ``value(a) / value(b)`` (no unit)."""
        return estimate(np.mean([self.array(a) / self.array(b) for a, b in pairs], axis=0), "")

    def difference(self, *pairs: tuple[str, str], unit: str = "m") -> Estimate:
        """Per seed, the mean over ``pairs`` of ``value(a) - value(b)``."""
        return estimate(np.mean([self.array(a) - self.array(b) for a, b in pairs], axis=0),
                        unit)

    def per_seed(self) -> dict[str, list[float]]:
        """Every statistic, its values over the seeds (for ``results.json``)."""
        keys = list(dict.fromkeys(k for o in self.items for k in o.values))
        return {k: [o.values.get(k, math.nan) for o in self.items] for k in keys}


def outcomes(seeds: Sequence[int], full: bool,
             progress: Callable[[str], None] | None = None) -> Outcomes:
    """:func:`seed_outcome` of each seed, with a progress line per seed."""
    say = progress or (lambda message: None)
    items = []
    for k, seed in enumerate(seeds):
        cached = is_cached(seed, full)
        outcome = seed_outcome(int(seed), bool(full))
        if not cached:
            s = outcome.seconds
            say(f"  seed {seed} ({k + 1}/{len(seeds)}): simulated in {s['simulate']:.1f} s, "
                f"3 methods x {len(RUNS)} adjustments in {s['models'] + s['adjust']:.1f} s")
        else:
            say(f"  seed {seed} ({k + 1}/{len(seeds)}): already computed in this process")
        items.append(outcome)
    return Outcomes(tuple(items))


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


def ictp_bar_figure(data: Outcomes, paper: Mapping[tuple[str, str, str], float],
                    paper_name: str) -> Any:
    """ICTP RMSE 2D per overlap, bars per method and run (single, block) with 95 %
    intervals over the seeds, the paper's figures as markers.

    Parameters
    ----------
    data : Outcomes
    paper : mapping of (method, run, pair label) to float
        The paper's ICTP RMSE 2D (``hypot`` of its E and N), metres.
    paper_name : str
        For the legend, e.g. ``"Teo et al. Table III"``.
    """
    fig, axes = _figure(1, 1, (9.0, 5.4))
    ax = axes[0, 0]
    colours = {"MBA": "#1f5fa8", "DG": "#c0392b", "RFM": "#16a085"}
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
                name = f"{method} {run}"
                ax.bar(x, est.mean, width * 0.92, color=colours[method],
                       alpha=1.0 if run == "block" else 0.45, yerr=err, capsize=3,
                       label=None if name in labelled else name, edgecolor="white")
                labelled.add(name)
                value = paper.get((method, run, label))
                if value is not None:
                    ax.plot([x], [value], marker="D", color="black", markersize=5,
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

PaperCells = Mapping[tuple[str, str], Sequence[str]]
"""A paper's table as printed: ``(method, row label) -> cells``."""


def _improvement(method: str, label: str, axis: str) -> Callable[[Mapping[str, float]], float]:
    def fn(v: Mapping[str, float]) -> float:
        return (v[f"{method}/single/ictp/{label}/{axis}"]
                - v[f"{method}/block/ictp/{label}/{axis}"])
    return fn


def consistency_grid(data: Outcomes, paper: PaperCells, rows: Sequence[str], *,
                     reference: bool = True) -> list[GridRow]:
    """Rows of a consistency table (``rows`` from :data:`CONSISTENCY_ROWS`) per method, in
    :data:`PAIR_COLUMNS`; with ``reference`` two more rows without the paper's figures: the
    on-board models before adjustment and the true models (the floor)."""
    out = []
    for method in METHODS:
        for row in rows:
            spec = CONSISTENCY_ROWS[row]
            ours: list[Estimate | str | float] = []
            for label in PAIRS:
                for axis in ("e", "n"):
                    if spec is None:
                        ours.append(data.derived(_improvement(method, label, axis)))
                    else:
                        run, kind = spec
                        ours.append(data.est(f"{method}/{run}/{kind}/{label}/{axis}"))
            out.append(GridRow(f"{method} {row}", list(paper.get((method, row), ["-"] * 4)),
                               ours))
    if reference:
        for who, name in (("onboard", "on-board models ICTP (before adjustment)"),
                          ("truth", "true models ICTP (the floor: noise and DEM)")):
            out.append(GridRow(name, ["-"] * 4, [data.est(f"{who}/ictp/{label}/{axis}")
                                                for label in PAIRS for axis in ("e", "n")]))
    return out


def absolute_grid(data: Outcomes, run: str, paper: PaperCells) -> list[GridRow]:
    """GCP and ICP RMSE E, N per strip of each method in ``run`` (:data:`STRIP_COLUMNS`)."""
    return [GridRow(f"{method} {kind}", list(paper.get((method, kind), ["-"] * 6)),
                    [data.est(f"{method}/{run}/{kind.lower()}/{strip}/{axis}")
                     for strip in STRIPS for axis in ("e", "n")])
            for method in METHODS for kind in ("GCP", "ICP")]


def onboard_grid(data: Outcomes, paper: PaperCells) -> list[GridRow]:
    """Mean and RMSE E, N of the on-board models per strip (Teo et al. Table II)."""
    return [GridRow(label, list(paper.get(("on-board", label), ["-"] * 6)),
                    [data.est(f"onboard/{strip}/{stat}_{axis}")
                     for strip in STRIPS for axis in ("e", "n")])
            for label, stat in (("Mean", "mean"), ("RMSE", "rmse"))]


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


# ================================================================================ findings
@dataclass(frozen=True)
class PaperTables:
    """A paper's figures behind the findings both papers state, as printed.

    Attributes
    ----------
    name : str
        E.g. ``"Teo et al."``.
    single_ictp, block_ictp : mapping of method to 4 str
        ICTP RMSE in :data:`PAIR_COLUMNS`, single and block.
    single_abs, block_abs : PaperCells
        ``(method, "GCP"|"ICP") ->`` 6 cells in :data:`STRIP_COLUMNS`.
    tables : mapping of str to str
        The tables' names: ``consistency``, ``single``, ``block``.
    icp_agreement_m : float
        The paper's bound on the single ICP differences between methods (metres).
    """

    name: str
    single_ictp: Mapping[str, Sequence[str]]
    block_ictp: Mapping[str, Sequence[str]]
    single_abs: PaperCells
    block_abs: PaperCells
    tables: Mapping[str, str]
    icp_agreement_m: float


def _f(cells: Sequence[str]) -> list[float]:
    return [float(c) for c in cells]


def _paper_2d(cells: Sequence[str], k: int) -> float:
    v = _f(cells)
    return math.hypot(v[2 * k], v[2 * k + 1])


def _span(values: Sequence[float]) -> float:
    return max(values) - min(values)


def _fmt(x: float, decimals: int = 1) -> str:
    return f"{x:.{decimals}f}"


def add_findings(report: Any, data: Outcomes, paper: PaperTables) -> None:
    """The findings both papers state (Teo et al. section III-D, Chen et al. section 3.3,
    and their abstracts), each with our figures and, where it does not reproduce, why; and
    a section of side-by-side tables of the figures behind them."""
    from geoblock_papers.report import Row

    t = paper.tables
    report.section("Findings in numbers",
                   "The figures behind each finding above, the paper's derived from its tables "
                   "as printed (2D RMSE = hypot(E, N)).")

    # 1. block vs single: the factor
    rows, means, evidence = [], {}, []
    for method in METHODS:
        parts = []
        for k, label in enumerate(PAIRS):
            mine = data.ratio((f"{method}/single/ictp/{label}/2d",
                               f"{method}/block/ictp/{label}/2d"))
            theirs = (_paper_2d(paper.single_ictp[method], k)
                      / _paper_2d(paper.block_ictp[method], k))
            means[(method, label)] = mine.mean
            rows.append(Row(f"{method} ICTP RMSE single / block, strips "
                            f"{label.replace('-', ' & ')}", _fmt(theirs), mine,
                            "clear (>= 2.5x)" if mine.mean >= 2.5 else "small (< 2.5x)"))
            parts.append(f"{mine.mean:.1f}x")
        evidence.append(f"{method} {' and '.join(parts)}")
    clear = [m >= 2.5 for m in means.values()]
    dg_note = ""
    if not all(clear):
        weak = sorted({m for (m, _), v in means.items() if v < 2.5})
        dg_note = (f" Not for {', '.join(weak)}: "
                   + ("our DG single adjustment is already consistent, because the simulated "
                      "on-board errors (position and attitude biases, an along-track drift) "
                      "have exactly the form of the DG correction (position biases and drifts, "
                      "attitude biases, with a-priori sigmas), which 9 central GCPs fix and "
                      "which extrapolates correctly to the overlaps; the papers' real on-board "
                      "errors evidently had parts a single strip's GCPs could not extrapolate."
                      if "DG" in weak else "its single adjustment extrapolates well here."))
    report.finding(
        "block_vs_single",
        f"Block adjustment improves the geometric consistency between overlapping strips "
        f"about 5 times over single adjustment ({t['consistency']}, summary 2)",
        True if all(clear) else (None if any(clear) else False),
        "ICTP RMSE single/block: " + "; ".join(evidence) + " (strips 1 & 2 and 2 & 3)."
        + dg_note)
    report.compare("finding_block_vs_single", rows, title="Improvement factor of the ICTP "
                   f"consistency (2D RMSE single / block; paper: {t['consistency']})")

    # 2. the methods agree
    def spread(v: Mapping[str, float]) -> float:
        return max(_span([v[f"{m}/block/ictp/{p}/{a}"] for m in METHODS])
                   for p in PAIRS for a in ("e", "n"))

    mine = data.derived(spread)
    columns = list(zip(*(_f(paper.block_ictp[m]) for m in METHODS), strict=True))
    theirs = max(_span(c) for c in columns)
    theirs_no_rfm = max(_span(c[:2]) for c in columns)

    def icp_spread(v: Mapping[str, float]) -> float:
        return max(_span([v[f"{m}/single/icp/{s}/{a}"] for m in METHODS])
                   for s in STRIPS for a in ("e", "n"))

    mine_icp = data.derived(icp_spread)
    icp_cols = list(zip(*(_f(paper.single_abs[(m, "ICP")]) for m in METHODS), strict=True))
    theirs_icp = max(_span(c) for c in icp_cols)
    single_icp = {m: data.est(f"{m}/single/icp/all/2d").mean for m in METHODS}
    worst = max(single_icp, key=lambda m: single_icp[m])
    why = {
        "MBA": " MBA's single adjustment is the outlier: Chen & Lee's 19-parameter polynomial "
               "model, fixed by 9 GCPs in the central third of the strip (away from the "
               "overlaps, as in the papers), extrapolates poorly to the ICPs near the strip "
               "edges, where the 9-parameter DG set and the 6-parameter affine RFM correction "
               "hold better.",
        "RFM": " RFM's single adjustment is the outlier: its affine correction's across-track "
               "terms, fixed by 9 GCPs in the central third of the strip, extrapolate the GCPs' "
               "noise to the strip edges.",
        "DG": " DG's single adjustment is the outlier.",
    }[worst]
    report.finding(
        "methods_agree",
        "The three methods' geometric performance is similar: after block adjustment their "
        f"ICTP RMSE differ by less than 1 m ({t['consistency']}; summary 1)",
        mine.mean < 1.0,
        f"largest difference between MBA, DG and RFM in a block ICTP RMSE (E or N, either "
        f"overlap): {mine.format()} (paper {theirs:.2f} m, {theirs_no_rfm:.2f} m without "
        "RFM, which the paper excepts for strips 2 & 3).")
    report.finding(
        "methods_agree_single_icp",
        f"In single adjustment the three methods' ICP RMSE differ by less than "
        f"{paper.icp_agreement_m:g} m ({t['single']})",
        mine_icp.mean < paper.icp_agreement_m,
        f"largest difference in a single ICP RMSE (E or N, any strip): {mine_icp.format()} "
        f"(paper {theirs_icp:.2f} m)."
        + ("" if mine_icp.mean < paper.icp_agreement_m else why))
    report.compare("finding_methods_agree", [
        Row("largest block ICTP RMSE difference between methods", f"{theirs:.2f}", mine),
        Row("largest single ICP RMSE difference between methods", f"{theirs_icp:.2f}",
            mine_icp)], title="Agreement of the three methods (metres)")

    # 3. ICP RMSE in block vs single mode, and 4. the DEM as its cause
    rows = []
    rises, poor_rises = {}, {}
    for method in METHODS:
        mine = data.difference(*((f"{method}/block/icp/{s}/2d", f"{method}/single/icp/{s}/2d")
                                 for s in STRIPS))
        theirs = float(np.mean([_paper_2d(paper.block_abs[(method, "ICP")], k)
                                - _paper_2d(paper.single_abs[(method, "ICP")], k)
                                for k in range(3)]))
        poor = data.difference((f"{method}/poor-dem/icp/all/2d", f"{method}/block/icp/all/2d"))
        rises[method], poor_rises[method] = mine.mean, poor.mean
        rows += [Row(f"{method} ICP RMSE 2D, block minus single (mean of the strips)",
                     f"{theirs:+.2f}", mine,
                     "rises" if mine.mean > 0 else "falls (not reproduced)"),
                 Row(f"{method} ICP RMSE 2D, block with a {POOR_DEM_RMSE_M:g} m DEM minus "
                     "block with the 5 m DEM", "-", poor,
                     "rises" if poor.mean > 0 else "falls")]
    slope = data.est("terrain/max_slope", "deg")
    report.finding(
        "icp_rises_in_block",
        f"The ICP RMSE increases slightly when block adjustment is employed ({t['single']} vs "
        f"{t['block']}; summary 3)",
        all(r > 0 for r in rises.values()),
        "block minus single ICP RMSE 2D: " + ", ".join(f"{m} {r:+.2f} m"
                                                         for m, r in rises.items())
        + ". Our block improves or keeps the absolute accuracy: the simulated on-board errors "
        "are entirely of the form the adjusted parameters model, and the simulated DEM is "
        f"accurate (RMSEz {data.est('dem/tp_rmse').mean:.1f} m at the TPs; true slopes up to "
        f"{slope.mean:.0f} deg in this variant), so the TPs' DEM control agrees with the "
        "GCPs instead of trading absolute for relative accuracy.")
    report.finding(
        "dem_degrades_icp",
        "A DEM less accurate than the GCPs in steep mountains explains why the consistency "
        "improves while the ICP RMSE deteriorates (summary 4)",
        True if all(r > 0 for r in poor_rises.values()) else (
            None if any(r > 0 for r in poor_rises.values()) else False),
        f"with a DEM of RMSEz {POOR_DEM_RMSE_M:g} m (given to the adjustment as 5 m) the "
        "block ICP RMSE 2D rises by " + ", ".join(f"{m} {r:+.2f} m"
                                                  for m, r in poor_rises.items())
        + " against the block with the 5 m DEM, and the TP heights follow the DEM's errors "
        f"({data.est('MBA/poor-dem/tp_height').format(1)} RMSE for MBA).")
    report.compare("finding_icp", rows, title="ICP RMSE in block mode (metres; paper: "
                   f"{t['block']} minus {t['single']})")

    # 5. strips 2 & 3
    def ratio(run: str) -> Estimate:
        return data.ratio(*((f"{m}/{run}/ictp/2-3/2d", f"{m}/{run}/ictp/1-2/2d")
                            for m in METHODS))

    theirs = float(np.mean([_paper_2d(paper.block_ictp[m], 1) / _paper_2d(paper.block_ictp[m], 0)
                            for m in METHODS]))
    good, poor = ratio("block"), ratio("poor-dem")
    report.finding(
        "pair23_worse",
        "After block adjustment strips 2 & 3 (steep terrain, incidence 5.7 and -14.8 deg) stay "
        f"less consistent than strips 1 & 2 ({t['consistency']})",
        None if good.mean < 1.5 <= poor.mean else good.mean >= 1.5,
        f"block ICTP RMSE 2D, strips 2 & 3 over strips 1 & 2 (mean of the methods): "
        f"{good.format()} with the 5 m DEM, {poor.format()} with the {POOR_DEM_RMSE_M:g} m "
        f"DEM (paper {theirs:.1f}). A DEM height error dh moves the two rays of an ICTP apart "
        "by dh (tan 5.7 + tan 14.8 deg) = 0.36 dh for strips 2 & 3 against 0.01 dh for strips "
        "1 & 2 (5.2 and 5.7 deg, same side): the contrast appears with a DEM as poor as the "
        "papers' probably was in the mountains.")
    report.compare("finding_pair23", [
        Row("block ICTP 2D RMSE ratio 2&3 / 1&2, 5 m DEM", f"{theirs:.2f}", good),
        Row(f"block ICTP 2D RMSE ratio 2&3 / 1&2, {POOR_DEM_RMSE_M:g} m DEM", "-", poor)],
        title="Strips 2 & 3 against strips 1 & 2 (mean of the three methods)")

    # 6. DEM control and 7. collocation (the abstracts; no table)
    heights = {m: data.ratio((f"{m}/no-dem/tp_height", f"{m}/block/tp_height"))
               for m in METHODS}
    ictp = {m: data.ratio(*((f"{m}/no-dem/ictp/{p}/2d", f"{m}/block/ictp/{p}/2d")
                            for p in PAIRS)) for m in METHODS}
    report.finding(
        "dem_control",
        "Using the DEM as elevation control significantly improves the geometric accuracy "
        "and the discrepancies between images, for all three methods (abstract)",
        all(h.mean >= 2.0 for h in heights.values()),
        "TP height RMSE without / with DEM control: "
        + ", ".join(f"{m} {h.mean:.0f}x" for m, h in heights.items())
        + "; ICTP RMSE without / with: " + ", ".join(f"{m} {r.mean:.1f}x"
                                                      for m, r in ictp.items())
        + " (see the DEM control table).")
    colloc = {m: data.difference((f"{m}/collocation/icp/all/2d", f"{m}/block/icp/all/2d"))
              for m in METHODS}
    report.finding(
        "collocation",
        "Least-squares collocation, integrated into the three methods, improves the "
        "positioning accuracy (abstract; the paper gives no figures)",
        all(c.mean < -0.1 for c in colloc.values()),
        "ICP RMSE 2D with minus without collocation: "
        + ", ".join(f"{m} {c.mean:+.2f} m" for m, c in colloc.items())
        + ". No effect here: the simulated on-board errors are smooth (biases and drifts the "
        "adjusted parameters absorb) and the SPOT-5 jitter is below 0.5 m, so the residual "
        "vectors hold only the measurement noise, which collocation filters out; it needs "
        "local systematic errors, which real images have and our simulation does not.")



# ================================================================================ sections
def describe_setup(data: Outcomes, full: bool) -> str:
    """A paragraph saying what was simulated and how it was adjusted."""
    size = "24000 x 24000 px at 2.5 m (the papers' size)" if full else \
        "600 x 600 px at 100 m (40 times fewer rows and columns, the same footprints)"
    lo, hi = data.est("terrain/min").mean, data.est("terrain/max").mean
    return (
        f"Each repetition simulates the `teo2010-spot5` preset ({'full' if full else 'small'} "
        f"variant: three strips of {size}) with its own seed: a new ridged terrain "
        f"({lo:.0f}-{hi:.0f} m, true slopes up to "
        f"{data.est('terrain/max_slope', 'deg').mean:.0f} deg on average over the seeds), a "
        "40 m DEM of RMSEz 5 m, on-board errors (position and attitude biases and an "
        "along-track drift, 2D RMSE 33.6, 12.0 and 42.3 m as in Teo et al.'s Table II, in "
        "random directions), GCPs and ICPs (survey sigma 3 m), TPs and ICTPs (pointing sigma "
        "0.5 px at the papers' pixel size). As in the papers, whose GCPs came from maps while "
        f"the TPs were measured in the overlaps, the {GCPS_PER_STRIP} GCPs of each strip lie "
        f"away from the overlaps (the {GCPS_PER_STRIP} nearest the centre column of "
        f"{GCP_CANDIDATES} drawn, 3 per cell of a 3 x 3 grid). "
        "MBA is Chen & Lee's model fitted to the on-board model (19 parameters with a-priori "
        "sigmas), DG the on-board line-of-sight model with its position biases and drifts and "
        "attitude biases, RFM a sensor-oriented RPC fitted to the on-board model with an "
        "affine image correction. Single adjustment: each strip with its GCPs only; block "
        "adjustment: the three strips with GCPs, TPs (weak ground pseudo-observations, 10 "
        "times the GCPs' sigma) and DEM control. GCP and ICP errors are measured against the "
        "surveyed coordinates, as the papers do; ICTP (and TP) discrepancies are the distance "
        "between the two rays of a point traced onto the DEM through the adjusted models.")


def add_dem_section(report: Any, data: Outcomes) -> None:
    """The DEM control and collocation tables (no paper table: the abstracts' claims)."""
    report.section(
        "DEM elevation control (the paper gives no table)",
        "The block adjustment of each method with the DEM as a weighted observation "
        "(`block`, geoblock's default), with the papers' literal iteration Z1 -> Z1' -> Z2 ... "
        "(`iterate`), without DEM control (`no-dem`), and with a DEM of RMSEz "
        f"{POOR_DEM_RMSE_M:g} m (`poor-dem`, the adjustment told 5 m). TP height RMSE against "
        "the truth; ICTPs traced onto the block's DEM.")
    rows = []
    for method in METHODS:
        for run in ("block", "iterate", "no-dem", "poor-dem"):
            rows.append([method, run, data.est(f"{method}/{run}/tp_height")]
                        + [data.est(f"{method}/{run}/ictp/{p}/2d") for p in PAIRS]
                        + [data.est(f"{method}/{run}/icp/all/2d")])
    report.table(["method", "run", "TP height RMSE", "ICTP 2D strips 1 & 2",
                  "ICTP 2D strips 2 & 3", "ICP 2D (all strips)"], rows, key="dem_control",
                 align="llrrrr")
    report.text(
        "Without DEM control the weakly convergent rays (incidences 5.2, 5.7 and -14.8 deg) "
        "leave the TP heights free to drift by tens of metres; the papers' iteration and the "
        "weighted observation give the same solution. The DEM's own RMSE at the TPs is "
        f"{data.est('dem/tp_rmse').format(1)} (5 m DEM) and "
        f"{data.est('poor_dem/tp_rmse').format(1)} ({POOR_DEM_RMSE_M:g} m DEM).")
    report.section(
        "Least-squares collocation (the paper gives no table)",
        "The block adjustment followed by least-squares collocation of each image's residual "
        "vectors (Teo et al. eqs. 4-5, filtering ratio 0.2).")
    rows = []
    for method in METHODS:
        for run in ("block", "collocation"):
            rows.append([method, run] + [data.est(f"{method}/{run}/icp/{s}/2d") for s in STRIPS]
                        + [data.est(f"{method}/{run}/ictp/{p}/2d") for p in PAIRS])
    report.table(["method", "run", "ICP 2D strip 1", "ICP 2D strip 2", "ICP 2D strip 3",
                  "ICTP 2D strips 1 & 2", "ICTP 2D strips 2 & 3"], rows, key="collocation",
                 align="llrrrrr")


def add_figures(report: Any, data: Outcomes, paper: PaperTables) -> None:
    """The ICTP bar figure (with the paper's figures) and the error-vector figures."""
    bars = {}
    for method in METHODS:
        for k, label in enumerate(PAIRS):
            bars[(method, "single", label)] = _paper_2d(paper.single_ictp[method], k)
            bars[(method, "block", label)] = _paper_2d(paper.block_ictp[method], k)
    report.figure(ictp_bar_figure(data, bars, f"{paper.name} {paper.tables['consistency']}"),
                  "ictp_per_overlap.png",
                  "ICTP RMSE 2D per overlap, single (light) and block (dark) adjustment of each "
                  "method, mean and 95 % interval over the seeds; diamonds: the paper; dotted: "
                  "the true models (the floor)")
    first = data.items[0]
    report.figure(ictp_vector_figure(first), "ictp_vectors.png",
                  "TP and ICTP discrepancy vectors between strips in the overlaps 1 & 2 "
                  f"(west) and 2 & 3 (east), single vs block adjustment, seed {first.seed} "
                  "(the same exaggeration in every panel; Teo et al. Fig. 9)")
    report.figure(icp_vector_figure(first), "icp_vectors.png",
                  "MBA: error vectors at the GCPs and ICPs of the three strips, single vs "
                  f"block adjustment, seed {first.seed} (Teo et al. Figs. 10-12)")


def record_results(report: Any, data: Outcomes) -> None:
    """Every statistic of every seed (``per_seed``, keys in the module docstring) and each
    seed's timings (``seconds``: simulate, models, adjust) into ``results.json``."""
    report.record("per_seed", data.per_seed())
    report.record("seconds_per_seed", {str(o.seed): o.seconds for o in data.items})
