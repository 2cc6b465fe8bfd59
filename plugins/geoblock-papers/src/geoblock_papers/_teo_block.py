"""The block of Teo et al. (2010) and Chen, Teo & Lo (2008), shared by both experiments.

Both papers adjust the same three SPOT-5 strips (case I of Teo et al.: one scene per strip)
with the same three methods; :mod:`geoblock_papers.teo2010` and
:mod:`geoblock_papers.chen2008` format the statistics computed here against each paper's
tables. Teo et al.'s case II (two scenes per strip) is the variant ``case2`` (:data:`CASES`).

Each repetition is run under both on-board error models of the simulator
(:data:`ERROR_MODELS`: ``"realistic"``, attitude wander, interior orientation and
orbital-period ephemeris errors besides the biases and drifts, and ``"bias-drift"``, the
biases and linear drifts alone), on the same terrain, DEMs and point draws: the two columns
of every table differ by the error model only.

One repetition under one error model (:func:`seed_outcome`, kept per seed, variant and error
model so that both experiments run in one process share it):

1. simulates the ``teo2010-spot5`` preset in memory (:mod:`geoblock.simulate.scene`, the
   block :func:`geoblock.workflows.run_scenario` would write) with the repetition's seed and
   the error model: new terrain, DEM, on-board errors and points (the terrain and DEMs are
   computed once per seed and variant when both error models' footprints give the same
   grid). As in the papers, whose GCPs came from
   1:5000 maps while the TPs were measured where the strips overlap, the GCPs lie away from
   the overlaps: 27 are drawn per strip (3 per cell of a 3 x 3 grid) and the 9 nearest the
   strip's centre column are kept (:func:`central_gcps`); TPs and ICTPs are drawn in the
   ranges of Teo et al.'s Table III (13-19 and 13-18 per overlap; case II: :data:`CASES`);
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
``"dem/tp_rmse"`` (the DEM's height error at the TPs, metres);
``"onboard/{strip}/nonaffine_2d"`` (the part of the on-board ground error that no affine
function of row and column removes, over a 15 x 15 grid at the scene centre's height: what
the realistic error model adds that a single strip's GCPs cannot extrapolate, metres).
"""

from __future__ import annotations

import math
import time
from collections import OrderedDict
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

import geoblock
from geoblock.adjust import Block, BlockResult, GroundPoints, ImagePoints, adjust, ictp_accuracy
from geoblock.adjust.statistics import AccuracyStats, IctpDiscrepancies, PointErrors
from geoblock.simulate.points import PointSet
from geoblock.simulate.scenario import Scenario, derived_seed, scenario_from_dict
from geoblock.simulate.scene import (
    scene_dem,
    scene_grid,
    scene_points,
    scene_sensors,
    true_terrain,
)
from geoblock.simulate.sensors import SimulatedSensor, incidence_angle
from geoblock.simulate.study import onboard_errors
from geoblock.simulate.terrain import Grid, measured_dem
from geoblock_papers._teo_cases import (
    CASES,
    ERROR_MODELS,
    SENSITIVITY_MODELS,
    VARIANTS,
    Case,
    available_error_models,
    case_of,
    scenario_dict,
)
from geoblock_papers.registry import ExperimentError, is_full
from geoblock_papers.report import Estimate, estimate

__all__ = [
    "CACHE_SIZE",
    "CASES",
    "ERROR_MODELS",
    "SENSITIVITY_MODELS",
    "METHODS",
    "PAIRS",
    "POOR_DEM_RMSE_M",
    "RUNS",
    "STRIPS",
    "VARIANTS",
    "Case",
    "Outcomes",
    "Run",
    "SeedOutcome",
    "Study",
    "TeoBlock",
    "Vectors",
    "available_error_models",
    "case_of",
    "central_gcps",
    "is_cached",
    "method_models",
    "outcomes",
    "scenario_dict",
    "seed_outcome",
    "simulate_block",
    "study",
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
#: sigma of the DEM heights given to the adjustment, metres (the preset's DEM RMSEz)
DEM_SIGMA_M = 5.0
#: the runs whose error vectors the figures show
_VECTOR_RUNS = ("single", "block")

# ================================================================================ block
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
    variant, errors : str
        The variant (:data:`VARIANTS`) and the on-board error model.
    """

    scenario: Scenario
    sensors: dict[str, SimulatedSensor]
    dem: Any
    poor_dem: Any
    points: PointSet
    ground: GroundPoints
    measurements: ImagePoints
    terrain: tuple[float, float, float]
    variant: str = "small"
    errors: str = "bias-drift"


def central_gcps(measurements: ImagePoints, shapes: Mapping[str, tuple[int, int]],
                 count: int | Mapping[str, int]) -> np.ndarray:
    """The ids of the ``count`` GCPs of each image nearest its centre column.

    Parameters
    ----------
    measurements : ImagePoints
        Kinds resolved.
    shapes : mapping of str to (int, int)
        ``(rows, cols)`` per image.
    count : int or mapping of str to int
        GCPs kept per image (the same for all, or by image).

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
        want = int(count) if isinstance(count, int) else int(count[image])
        sel = (measurements.kind == "gcp") & (measurements.image == image)
        if int(sel.sum()) < want:
            raise ExperimentError(f"teo block: image {image} has {int(sel.sum())} GCPs, "
                                  f"fewer than the {want} wanted")
        offset = np.abs(measurements.col[sel] - (cols - 1) / 2.0)
        kept.append(measurements.id[sel][np.argsort(offset, kind="stable")[:want]])
    return np.concatenate(kept)


@dataclass(frozen=True, eq=False)
class _Ground:
    """The true terrain and the measured DEMs of a seed and variant, on ``grid``."""

    grid: Grid
    truth: Any
    dem: Any
    poor_dem: Any


#: the last seed's terrain and DEMs, by ``(seed, variant)``: both error models use them
_GROUND: OrderedDict[tuple[int, str], _Ground] = OrderedDict()


def _same_grid(a: Grid, b: Grid) -> bool:
    return a.shape == b.shape and a.transform == b.transform and a.crs == b.crs


def _ground(scenario: Scenario, sensors: Mapping[str, SimulatedSensor],
            key: tuple[int, str]) -> _Ground:
    """The terrain and DEMs of ``scenario`` on the grid its sensors' footprints give; those
    of the same seed and variant under another error model when the grid is the same (the
    terrain and DEMs depend on the grid and the seed only)."""
    grid = scene_grid(scenario, sensors)
    known = _GROUND.get(key)
    if known is not None and _same_grid(known.grid, grid):
        return known
    truth = true_terrain(scenario, grid)
    dem = scene_dem(scenario, truth, 0).to_dem()
    # seeded as a second DEM of the scenario would be (the preset has one)
    poor_dem = measured_dem(truth, scenario.dems[0].spacing_m, POOR_DEM_RMSE_M,
                            seed=derived_seed(scenario.seed, 3, len(scenario.dems))).to_dem()
    _GROUND.clear()
    _GROUND[key] = _Ground(grid, truth, dem, poor_dem)
    return _GROUND[key]


def simulate_block(seed: int, variant: str = "small", errors: str | None = None) -> TeoBlock:
    """Simulate the block of one repetition in memory (module docstring, step 1).

    Parameters
    ----------
    seed : int
    variant : str
        A key of :data:`VARIANTS`.
    errors : str, optional
        The on-board error model (:data:`ERROR_MODELS`; default the simulator's).
    """
    case = case_of(variant)
    scenario = scenario_from_dict(scenario_dict(seed, variant, errors))
    sensors = scene_sensors(scenario)
    ground = _ground(scenario, sensors, (int(seed), variant))
    truth = ground.truth
    points = scene_points(scenario, sensors, truth.to_dem())
    observed, meas = points.observations()
    meas = meas.resolve_kinds(observed)
    keep = central_gcps(meas, {i: s.true_model.shape for i, s in sensors.items()},
                        dict(zip(sensors, case.gcps, strict=True)))
    gcp_ids = observed.id[observed.kind == "gcp"]
    drop = gcp_ids[~np.isin(gcp_ids, keep)]
    lo, hi = truth.relief
    used = errors or str(getattr(next(iter(sensors.values())).spec, "onboard_errors",
                                 "bias-drift"))
    return TeoBlock(scenario, sensors, ground.dem, ground.poor_dem, points,
                    observed.subset(~np.isin(observed.id, drop)),
                    meas.subset(~np.isin(meas.id, drop)),
                    (float(lo), float(hi), float(np.nanmax(truth.slope_deg()))), variant, used)


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
    variant : str
        A key of :data:`VARIANTS`.
    errors : str
        The on-board error model (:data:`ERROR_MODELS`).
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
    variant: str
    errors: str
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


#: outcomes computed in this process, by ``(seed, variant, error model)``, oldest first
_CACHE: OrderedDict[tuple[int, str, str], SeedOutcome] = OrderedDict()
#: outcomes kept in :data:`_CACHE` (a few hundred kB each)
CACHE_SIZE = 64


def is_cached(seed: int, variant: str = "small", errors: str = ERROR_MODELS[0]) -> bool:
    """Whether :func:`seed_outcome` of ``(seed, variant, errors)`` is already computed in
    this process."""
    return (int(seed), str(variant), str(errors)) in _CACHE


def seed_outcome(seed: int, variant: str = "small",
                 errors: str = ERROR_MODELS[0]) -> SeedOutcome:
    """Simulate, adjust and measure one repetition under one on-board error model (module
    docstring); kept per ``(seed, variant, errors)`` in this process (the last
    :data:`CACHE_SIZE`), so that teo2010 and chen2008 share it.

    Parameters
    ----------
    seed : int
    variant : str
        A key of :data:`VARIANTS`.
    errors : str
        One of :func:`available_error_models` (``sensitivity=True``: also
        :data:`~geoblock_papers._teo_cases.SENSITIVITY_MODELS`).

    Raises
    ------
    ExperimentError
        An unknown variant or error model.
    GeoblockError
        The simulation or an adjustment failed (the message says which).
    """
    case_of(variant)
    if errors not in available_error_models(sensitivity=True):
        raise ExperimentError(f"teo block: on-board error model {errors!r} is not one of the "
                              f"simulator's: {', '.join(available_error_models(True))}")
    key = (int(seed), str(variant), str(errors))
    if key not in _CACHE:
        _CACHE[key] = _compute_outcome(*key)
        while len(_CACHE) > CACHE_SIZE:
            _CACHE.popitem(last=False)
    return _CACHE[key]


def _nonaffine_2d(sim: SimulatedSensor) -> float:
    """RMS of the on-board ground error left by an affine function of row and column (15 x
    15 grid at the scene centre's height), metres."""
    err = sim.onboard_error(n=15)
    basis = np.stack([np.ones(err.row.size), err.row.ravel(), err.col.ravel()], axis=-1)
    values = np.stack([err.de.ravel(), err.dn.ravel()], axis=-1)
    coef = np.linalg.lstsq(basis, values, rcond=None)[0]
    return float(np.sqrt(np.mean(np.sum((values - basis @ coef) ** 2, axis=-1))))


def _compute_outcome(seed: int, variant: str, errors: str) -> SeedOutcome:
    clock = time.perf_counter()
    tb = simulate_block(seed, variant, errors)
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
                       f"onboard/{strip}/rmse_2d": st.rmse_2d,
                       f"onboard/{strip}/nonaffine_2d": _nonaffine_2d(tb.sensors[strip])})
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
    return SeedOutcome(int(seed), variant, errors, values, ties, checks, seconds)


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


@dataclass(frozen=True, eq=False)
class Study:
    """The repetitions of a variant under each on-board error model.

    Attributes
    ----------
    variant : str
        A key of :data:`VARIANTS`.
    by_model : dict of str to Outcomes
        Error model -> its repetitions, in :data:`ERROR_MODELS` order (the simulator's
        default first).
    """

    variant: str
    by_model: dict[str, Outcomes]

    @property
    def models(self) -> tuple[str, ...]:
        """The error models, the default first."""
        return tuple(self.by_model)

    @property
    def primary(self) -> Outcomes:
        """The default error model's repetitions."""
        return self.by_model[self.models[0]]

    @property
    def case(self) -> Case:
        return case_of(self.variant)

    @property
    def full(self) -> bool:
        return is_full(self.variant)


def outcomes(seeds: Sequence[int], variant: str = "small", errors: str = ERROR_MODELS[0],
             progress: Callable[[str], None] | None = None) -> Outcomes:
    """:func:`seed_outcome` of each seed under one error model, with a progress line per
    seed."""
    return study(seeds, variant, (errors,), progress).by_model[errors]


def study(seeds: Sequence[int], variant: str = "small",
          models: Sequence[str] | None = None,
          progress: Callable[[str], None] | None = None) -> Study:
    """:func:`seed_outcome` of each seed under each error model (default
    :func:`available_error_models`), seed after seed (both models of a seed share its
    terrain), with a progress line per seed and model."""
    say = progress or (lambda message: None)
    models = tuple(models or available_error_models())
    items: dict[str, list[SeedOutcome]] = {m: [] for m in models}
    for k, seed in enumerate(seeds):
        for model in models:
            cached = is_cached(seed, variant, model)
            outcome = seed_outcome(int(seed), variant, model)
            where = f"  seed {seed} ({k + 1}/{len(seeds)}), {model} errors:"
            if not cached:
                s = outcome.seconds
                say(f"{where} simulated in {s['simulate']:.1f} s, 3 methods x {len(RUNS)} "
                    f"adjustments in {s['models'] + s['adjust']:.1f} s")
            else:
                say(f"{where} already computed in this process")
            items[model].append(outcome)
    return Study(variant, {m: Outcomes(tuple(v)) for m, v in items.items()})
