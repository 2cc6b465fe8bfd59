"""The simulation behind ``geoblock experiment reference``: blocks, reference orthos, reference
control, the adjustment and what is measured on it against the truth.

Blocks (:data:`BLOCKS`), each simulated once per process (:func:`make_scene`: sensors, true
terrain, measured DEM, texture, the raw images rendered through the TRUE models):

``teo``
    The three SPOT-5 strips of Teo et al. (``teo2010-spot5``'s sensor presets: orbits,
    incidences 5.2, 5.7 and -14.8 deg, on-board errors of 34, 12 and 42 m with the
    simulator's realistic components) at their full 2.5 m GSD, cut to 640 x 640 px (1.6 km)
    and moved together so that neighbours overlap by 13 % as Teo's do; ridged terrain of
    200-1400 m (slopes to 45 deg), Teo's 40 m DEM of RMSEz 5 m; linescan ``dg`` parameters.
``aguilar``
    Aguilar et al.'s QuickBird basic scene (``aguilar2007-quickbird``'s sensor: 0.62 m GSD,
    8 deg off nadir, 15 m on-board error with the along-track drift), cut to 1600 x 1600 px
    (1 km), fractal terrain of 50-350 m, Aguilar's 5 m DEM of RMSEz 1.75 m; the vendor RPC
    fitted to the on-board model and refined with an affine image correction (RPCV-1: the
    paper's best); a single image, so no tie point.
``rpc4``
    Four SPOT-5-like 2.5 m views (600 x 600 px) on a 2 x 2 layout with half-image overlaps,
    incidences +8, -8, +20 and -20 deg, from four dates, on-board errors of 25 m; ridged
    terrain of 100-900 m, a 30 m DEM of RMSEz 4 m; each image's vendor RPC fitted to its
    on-board model, with RPCV-1 corrections.

A **case** (:class:`Case`) is a reference: its GSD and its error. The reference is rendered
from the scene's texture (:func:`geoblock.simulate.reference.render_reference`, shaded by the
true terrain as the images are) over the block plus a margin, misregistered by ``error_m``
in a random direction (``random=False``) or by a shift drawn from the Gaussian its stated
CE90 describes (``random=True``). Its stated accuracy is ``CE90 = 1.5175 error_m`` (the
CE90 of a circular normal error whose RMS radial error is ``error_m``), at least 0.5 m.

A **repetition** (:func:`run_case`) with one seed: new image noise (1 DN), a new shift
direction (or draw), new tie points (40 per overlapping pair, 0.3 px) and ICPs (60 per image,
given at their TRUE ground positions with exact image positions, so that their error is the
adjusted models' alone), then:

1. control from the reference, :func:`geoblock.match.match_reference`, against the measured
   DEM; each control point compared with the truth: the raw image position's true ground
   point (the TRUE model on the TRUE terrain) against the control's ground position, with the
   reference's shift removed (the matching error) and included (what the block is told);
2. adjustments with the control weighted three ways (:data:`WEIGHTINGS`):

   * ``independent``: the reference's error counted in every point's own sigma, as if the
     points' errors were independent, ``sqrt((CE90 / 2.146)^2 + (sigma_match gsd)^2)`` per
     axis (what :func:`~geoblock.match.match_reference` gave before it stated the common
     error);
   * ``shift``: as :func:`~geoblock.match.match_reference` gives it: each point with its
     matching error, the reference's error as one shift common to all its points
     (``sigma_shift = CE90 / 2.146`` per axis) that the block engine **estimates**, when
     the engine has it (:func:`engine_has_shift`);
   * ``own``: each point with its matching error and no shift: the adjustment of the
     ``consider`` route below;

3. for the ``own`` weighting, the **consider** correction: the reference's error kept as a
   common error that is not estimated but propagated, ``J Sigma_s J^T`` with ``J`` the
   response of the adjusted ground positions to a 1 m shift of every control point (east,
   then north: two more adjustments), added to the posterior's prediction;
4. at the ICPs: RMSE (2D) against the prediction (:attr:`~geoblock.adjust.BlockResult.
   predicted_sigma`), CE90 against the predicted CE90 (:mod:`geoblock.adjust.accuracy`); the
   **ortho error** (each ICP's true image position located on the measured DEM through the
   adjusted model, minus the truth) against the per-pixel predicted error of the accuracy
   layer (:func:`geoblock.models.uncertainty.ground_error`: the posterior propagated to the
   ground plus ``sigma_DEM tan(incidence)``).
"""

from __future__ import annotations

import inspect
import math
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from geoblock import coords
from geoblock.adjust import Block, BlockResult, GroundPoints, ImagePoints, adjust
from geoblock.adjust.accuracy import CE90_FACTOR, empirical_ce, predicted_ce
from geoblock.dem.intersect import localize
from geoblock.errors import MatchError
from geoblock.simulate.points import simulate_points
from geoblock.simulate.reference import RenderedReference, render_reference, shift_lonlat
from geoblock.simulate.render import render_image
from geoblock.simulate.scenario import Scenario, derived_seed, scenario_from_dict
from geoblock.simulate.scene import (
    scene_dem,
    scene_grid,
    scene_sensors,
    scene_texture,
    true_terrain,
)
from geoblock.simulate.sensors import SimulatedSensor

__all__ = ["BLOCKS", "WEIGHTINGS", "BlockDesign", "Case", "CaseOutcome", "OracleControl",
           "Scene", "engine_has_shift", "make_scene", "oracle_control", "run_case",
           "stated_ce90", "stratified_radius"]

#: CE90 over the RMS radial error of a circular normal error: ``CE90_FACTOR / sqrt(2)``.
CE90_PER_RMS = CE90_FACTOR / math.sqrt(2.0)
#: The smallest stated CE90, metres (a perfect reference still states something).
MIN_CE90_M = 0.5
#: Tie points per overlapping pair, their pointing noise (px), ICPs per image.
TP_PER_PAIR = 40
TP_SIGMA_PX = 0.3
ICP_PER_IMAGE = 60
#: ICPs' sigmas: given at their true positions (px, m): they do not enter the solution.
EXACT_PX = 1e-3
EXACT_M = 1e-3
#: Margin of the reference beyond the images' footprints, metres.
REFERENCE_MARGIN_M = 250.0
#: Image noise, DN (per repetition).
NOISE_DN = 1.0
#: The control weightings compared (module docstring).
WEIGHTINGS = ("independent", "shift", "own")


def stated_ce90(error_m: float) -> float:
    """The CE90 a reference of RMS radial error ``error_m`` states (module docstring)."""
    return max(CE90_PER_RMS * float(error_m), MIN_CE90_M)


def engine_has_shift() -> bool:
    """Whether the block engine estimates an error common to a source's control points
    (``GroundPoints(..., sigma_shift_e=...)``)."""
    return "sigma_shift_e" in inspect.signature(GroundPoints).parameters


# ================================================================================ blocks
def _deg_e(m: float, lat: float) -> float:
    return m / (math.radians(1.0) * coords.WGS84_A * math.cos(math.radians(lat)))


def _deg_n(m: float) -> float:
    return m / (math.radians(1.0) * coords.WGS84_A)


def _common(points_seed: int) -> dict[str, Any]:
    return {"points": {"gcp": 0, "icp": 0, "tp": 0, "ictp": 0, "sigma_px": TP_SIGMA_PX},
            "render": {"enabled": True, "dtype": "uint8", "noise_dn": 0.0,
                       "texture_scale_px": 1.0},
            "report": {"distance_plot": False, "gcp_study": False}, "seed": points_seed}


def _teo() -> dict[str, Any]:
    lat, lon0, width = 23.85, 120.96, 2.5 * 640
    images = [{"id": f"strip{k + 1}", "preset": f"spot5-strip{k + 1}", "shape": [640, 640],
               "centre_lon": lon0 + _deg_e((k - 1) * 0.87 * width, lat)} for k in range(3)]
    return {"name": "reference-teo", "method": "dg", "images": images,
            "terrain": {"kind": "ridged", "relief": [200.0, 1400.0], "resolution_m": 10.0,
                        "max_slope_deg": 45.0, "vertical": "ellipsoid", "margin_m": 800.0},
            "dems": [{"name": "dem40", "spacing_m": 40.0, "rmse_z": 5.0}], **_common(2010)}


def _aguilar() -> dict[str, Any]:
    out = {"name": "reference-aguilar", "method": "rpcv1",
           "images": [{"id": "quickbird", "preset": "quickbird", "shape": [1600, 1600]}],
           "terrain": {"kind": "fractal", "relief": [50.0, 350.0], "hurst": 0.8,
                       "resolution_m": 5.0, "vertical": "ellipsoid", "margin_m": 600.0},
           "dems": [{"name": "dem5", "spacing_m": 5.0, "rmse_z": 1.75}], **_common(2007)}
    # the texture's features at the Teo scale (150 m fields): 0.62 m x 4 = 2.5 m
    out["render"]["texture_scale_px"] = 2.5 / 0.62
    return out


def _rpc4() -> dict[str, Any]:
    lat, lon0, width = 23.85, 120.96, 2.5 * 600
    layout = [(8.0, -1, 1, "2003-06-21T02:40:00Z"), (-8.0, 1, 1, "2003-06-24T02:40:00Z"),
              (20.0, -1, -1, "2003-07-02T02:40:00Z"), (-20.0, 1, -1, "2003-07-09T02:40:00Z")]
    images = [{"id": f"view{k + 1}", "preset": "spot5-strip2", "shape": [600, 600],
               "incidence_deg": inc, "epoch": epoch, "onboard_rmse_m": 25.0,
               "centre_lon": lon0 + _deg_e(0.25 * sx * width, lat),
               "centre_lat": lat + _deg_n(0.25 * sy * width)}
              for k, (inc, sx, sy, epoch) in enumerate(layout)]
    return {"name": "reference-rpc4", "method": "rpcv1", "images": images,
            "terrain": {"kind": "ridged", "relief": [100.0, 900.0], "resolution_m": 10.0,
                        "max_slope_deg": 40.0, "vertical": "ellipsoid", "margin_m": 800.0},
            "dems": [{"name": "dem30", "spacing_m": 30.0, "rmse_z": 4.0}], **_common(4)}


@dataclass(frozen=True)
class BlockDesign:
    """A block of the study: its label, scenario and the models adjusted (``dg``: the
    linescan on-board model's ``dg`` set; ``rpcv1``: the vendor RPC fitted to the on-board
    model with an affine image correction)."""

    label: str
    scenario: Callable[[], dict[str, Any]]
    method: str


#: The study's blocks (module docstring).
BLOCKS: dict[str, BlockDesign] = {
    "teo": BlockDesign("Teo: 3 SPOT-5 strips, 2.5 m, dg", _teo, "dg"),
    "aguilar": BlockDesign("Aguilar: QuickBird, 0.62 m, RPCV-1", _aguilar, "rpcv1"),
    "rpc4": BlockDesign("4 RPC views, 2.5 m, RPCV-1", _rpc4, "rpcv1"),
}


@dataclass(eq=False)
class Scene:
    """One block, simulated once: what every case and repetition shares.

    ``pixels``: the raw images rendered noise-free through the TRUE models (uint8);
    ``models``: the models the adjustment starts from (on-board: ``dg`` set, or vendor RPC
    with RPCV-1); ``truth``: the true terrain as a DEM source, ``dem``: the measured DEM;
    ``bounds``: the reference's area (the images' footprints plus a margin) in ``crs``.
    """

    block: str
    design: BlockDesign
    scenario: Scenario
    sensors: dict[str, SimulatedSensor]
    terrain: Any
    truth: Any
    dem: Any
    dem_sigma_m: float
    texture: Any
    pixels: dict[str, np.ndarray]
    models: dict[str, Any]
    crs: Any
    bounds: tuple[float, float, float, float]
    gsd_m: dict[str, float]
    seconds: float


_SCENES: dict[str, Scene] = {}


def _initial_models(design: BlockDesign, sensors: Mapping[str, SimulatedSensor],
                    height_range: tuple[float, float]) -> dict[str, Any]:
    import geoblock

    if design.method == "dg":
        return {i: s.onboard_model.with_parameter_set("dg") for i, s in sensors.items()}
    from geoblock_rpc.fit import fit_rpc
    from geoblock_rpc.model import RpcModel

    out = {}
    for i, s in sensors.items():  # one fit per image
        rpc, _ = fit_rpc(s.onboard_model, height_range=height_range, grid=(13, 13, 7),
                         regularization=1e-6)
        out[i] = geoblock.ImageCorrection(RpcModel(rpc, s.onboard_model.shape), order=1)
    return out


def make_scene(block: str, design: BlockDesign | None = None) -> Scene:
    """The block ``block`` of :data:`BLOCKS` (or of ``design``), simulated once per process
    under that name (module docstring).

    Raises
    ------
    KeyError
        Unknown block and no design.
    """
    if block in _SCENES:
        return _SCENES[block]
    design = design or BLOCKS[block]
    start = time.perf_counter()
    scenario = scenario_from_dict(design.scenario(), source=f"reference study ({block})")
    sensors = scene_sensors(scenario)
    terrain = true_terrain(scenario, scene_grid(scenario, sensors))
    truth = terrain.to_dem()
    dem = scene_dem(scenario, terrain, 0).to_dem()
    texture = scene_texture(scenario, sensors)
    pixels = {}
    for k, (image, sim) in enumerate(sensors.items()):  # one rendering per image
        # lattice 8 px, 0.2 px: QuickBird's 0.62 m pixels over a 5 m fractal terrain refine
        # half the cells at 0.05 px (4x the time) for nothing a 2.5 m reference can see
        pixels[image] = render_image(sim.true_model, truth, texture=texture, dtype="uint8",
                                     noise_dn=0.0, seed=derived_seed(scenario.seed, 6, k),
                                     lattice_step=8, tolerance_px=0.2).pixels
    lo, hi = terrain.relief
    models = _initial_models(design, sensors, (float(lo) - 200.0, float(hi) + 200.0))
    lon = np.concatenate([np.asarray(s.true_model.footprint(h=h, n=8).lon)
                          for s in sensors.values() for h in (lo, hi)])
    lat = np.concatenate([np.asarray(s.true_model.footprint(h=h, n=8).lat)
                          for s in sensors.values() for h in (lo, hi)])
    crs = coords.utm_crs(float(lon.mean()), float(lat.mean()))
    x, y = coords.transformer("EPSG:4326", crs).transform(lon, lat)
    m = REFERENCE_MARGIN_M
    bounds = (float(np.min(x)) - m, float(np.min(y)) - m, float(np.max(x)) + m,
              float(np.max(y)) + m)
    scene = Scene(block, design, scenario, sensors, terrain, truth, dem,
                  float(scenario.dems[0].rmse_z), texture, pixels, models, crs, bounds,
                  {i: float(s.spec.gsd_m) for i, s in sensors.items()},
                  time.perf_counter() - start)
    _SCENES[block] = scene
    return scene


# ================================================================================ a case
@dataclass(frozen=True)
class Case:
    """A reference: its GSD (m), its RMS radial error (m) and whether the error is a fixed
    magnitude in a random direction (``random=False``) or drawn from the Gaussian of its
    stated CE90."""

    gsd_m: float = 10.0
    error_m: float = 4.0
    random: bool = False

    @property
    def ce90_m(self) -> float:
        """The stated CE90 (:func:`stated_ce90`)."""
        return stated_ce90(self.error_m)

    @property
    def label(self) -> str:
        return (f"{self.gsd_m:g} m GSD, {'drawn, RMS ' if self.random else ''}"
                f"{self.error_m:g} m error")


@dataclass(eq=False)
class CaseOutcome:
    """One repetition of one case on one block: flat statistics ``values`` (keys in
    :func:`run_case`), per-ICP arrays for the accuracy layer (``layer``), wall times, and
    ``failure``: why the reference gave no control (empty when it did)."""

    block: str
    case: Case
    seed: int
    values: dict[str, float] = field(default_factory=dict)
    layer: dict[str, np.ndarray] = field(default_factory=dict)
    seconds: dict[str, float] = field(default_factory=dict)
    failure: str = ""


@dataclass(frozen=True, eq=False)
class OracleControl:
    """Control as a perfect matcher would give it (:func:`oracle_control`): the
    ``ground``/``measurements`` columns of :class:`geoblock.match.ReferenceControl`."""

    ground: dict[str, np.ndarray]
    measurements: dict[str, np.ndarray]

    def __len__(self) -> int:
        return int(self.ground["id"].size)


def oracle_control(scene: Scene, ref: RenderedReference, ce90_m: float,
                   rng: np.random.Generator, *, step_px: int = 6,
                   sigma_match_px: float = 0.1) -> OracleControl:
    """Control points an ideal matcher would find: nodes of the reference every ``step_px``
    pixels inside each image; the node's ground position as the reference states it (the
    shift included) plus a matching error of ``sigma_match_px`` reference pixels per axis,
    height from the measured DEM; the image position where the TRUE model sees the true
    feature (the shift removed) on the TRUE terrain. Sigmas as
    :func:`geoblock.match.match_reference` gives them. The floor a matcher can reach."""
    rows, cols = ref.pixels.shape
    rr, cc = np.meshgrid(np.arange(step_px // 2, rows, step_px, dtype=float),
                         np.arange(step_px // 2, cols, step_px, dtype=float), indexing="ij")
    lon_s, lat_s = ref.pixel_lonlat(rr.ravel(), cc.ravel())
    lon_t, lat_t = ref.true_lonlat(lon_s, lat_s)
    h_t = scene.truth.height(lon_t, lat_t)
    parts = []
    for image, sim in scene.sensors.items():  # a loop over the images
        p = sim.true_model.project(lon_t, lat_t, h_t)
        r0, c0 = sim.true_model.shape
        inside = (np.isfinite(p.row) & (p.row > 10) & (p.row < r0 - 11) & (p.col > 10)
                  & (p.col < c0 - 11))
        parts.append((image, np.flatnonzero(inside), p.row[inside], p.col[inside]))
    total = sum(part[1].size for part in parts)
    gsd = ref.gsd_m
    noise = rng.normal(0.0, sigma_match_px * gsd, (total, 2))
    idx = np.concatenate([part[1] for part in parts])
    lon, lat = shift_lonlat(lon_s[idx], lat_s[idx], noise[:, 0], noise[:, 1])
    h = scene.dem.height(lon, lat)
    s = math.hypot(ce90_m / CE90_FACTOR, sigma_match_px * gsd)
    ids = np.array([f"orc{k:05d}" for k in range(total)])
    ground = {"id": ids, "kind": np.full(total, "gcp"),
              "source": np.full(total, "reference:oracle"),
              "lon": lon, "lat": lat, "h": h, "sigma_e": np.full(total, s),
              "sigma_n": np.full(total, s),
              "sigma_h": np.full(total, math.hypot(scene.dem_sigma_m, s))}
    meas = {"id": ids, "image": np.concatenate([np.full(part[1].size, part[0])
                                                for part in parts]),
            "row": np.concatenate([part[2] for part in parts]),
            "col": np.concatenate([part[3] for part in parts]),
            "sigma": np.full(total, 0.05), "kind": np.full(total, "gcp")}
    return OracleControl(ground, meas)


def stratified_radius(sigma: float, k: int, count: int) -> float:
    """The size of the ``k``-th of ``count`` stratified draws of a circular normal error of
    ``sigma`` per axis: the root of the mean of ``r**2`` (Rayleigh) over its ``k``-th
    ``1/count`` quantile cell, so that the ``count`` sizes have exactly the population's RMS
    ``sqrt(2) sigma`` and its quantiles to ``1/count``.

    Over the cell ``[a, b]`` of the probability ``u``, ``r**2 = -2 sigma**2 ln(1 - u)`` has
    the mean ``2 sigma**2 (1 + ((1-b) ln(1-b) - (1-a) ln(1-a)) / (b - a))``.
    """
    a, b = k / count, (k + 1) / count

    def g(u: float) -> float:  # (1 - u) ln(1 - u), 0 at u = 1
        return 0.0 if u >= 1.0 else (1.0 - u) * math.log(1.0 - u)

    mean = 1.0 + (g(b) - g(a)) / (b - a)
    return sigma * math.sqrt(2.0 * mean)


def _shift(case: Case, rng: np.random.Generator, stratum: tuple[int, int] | None
           ) -> tuple[float, float]:
    angle = rng.uniform(0.0, 2.0 * math.pi)
    if not case.random:
        size = case.error_m
    elif stratum is None:
        s = case.ce90_m / CE90_FACTOR
        de, dn = rng.normal(0.0, s, 2)
        return float(de), float(dn)
    else:
        size = stratified_radius(case.ce90_m / CE90_FACTOR, *stratum)
    return float(size * math.sin(angle)), float(size * math.cos(angle))


def _en(lon0: Any, lat0: Any, h0: Any, lon: Any, lat: Any) -> tuple[np.ndarray, np.ndarray]:
    """East/north metres of ``(lon, lat)`` (at the height ``h0``) from ``(lon0, lat0, h0)``."""
    de, dn, _ = coords.enu_offsets(lon0, lat0, h0, lon, lat, h0)
    return np.asarray(de, float), np.asarray(dn, float)


def _ground(ids: Any, kind: Any, lon: Any, lat: Any, h: Any, se: Any, sn: Any, sh: Any,
            **extra: Any) -> GroundPoints:
    """GroundPoints with the optional columns the engine knows (``source``, shift sigmas)."""
    known = inspect.signature(GroundPoints).parameters
    return GroundPoints(ids, kind, lon, lat, h, se, sn, sh,
                        **{k: v for k, v in extra.items() if k in known})


def _concat_ground(parts: list[GroundPoints]) -> GroundPoints:
    names = [n for n in ("id", "kind", "lon", "lat", "h", "sigma_e", "sigma_n", "sigma_h",
                         "source", "sigma_shift_e", "sigma_shift_n", "sigma_shift_h")
             if all(hasattr(p, n) for p in parts)]
    cols = {n: np.concatenate([getattr(p, n) for p in parts]) for n in names}
    first = [cols.pop(n) for n in ("id", "kind", "lon", "lat", "h", "sigma_e", "sigma_n",
                                   "sigma_h")]
    return _ground(*first, **cols)


def _measure_control(scene: Scene, ref: RenderedReference, control: Any,
                     values: dict[str, float]) -> dict[str, np.ndarray]:
    """Compare each control point with the truth (module docstring, step 1); returns the
    per-point ground errors (shift removed), metres."""
    g, m = control.ground, control.measurements
    order = {p: k for k, p in enumerate(np.asarray(g["id"]).tolist())}
    k = np.array([order[p] for p in np.asarray(m["id"]).tolist()], dtype=np.intp)
    lon, lat = np.asarray(g["lon"], float)[k], np.asarray(g["lat"], float)[k]
    e_rem = np.full(k.size, np.nan)
    n_rem = np.full(k.size, np.nan)
    e_inc = np.full(k.size, np.nan)
    n_inc = np.full(k.size, np.nan)
    images = np.asarray(m["image"]).astype(str)
    for image, sim in scene.sensors.items():  # a loop over the images
        sel = images == image
        if not sel.any():
            continue
        truth, status = localize(sim.true_model, np.asarray(m["row"], float)[sel],
                                 np.asarray(m["col"], float)[sel], scene.truth, warn=False)
        tl, tt = ref.true_lonlat(lon[sel], lat[sel])
        e_rem[sel], n_rem[sel] = _en(truth.lon, truth.lat, truth.h, tl, tt)
        e_inc[sel], n_inc[sel] = _en(truth.lon, truth.lat, truth.h, lon[sel], lat[sel])
    r_rem, r_inc = np.hypot(e_rem, n_rem), np.hypot(e_inc, n_inc)
    gsd = ref.gsd_m
    values["control/n"] = float(k.size)
    values["control/within_1px_removed"] = float(np.nanmean(r_rem < gsd)) if k.size else math.nan
    values["control/within_1px_included"] = float(np.nanmean(r_inc < gsd)) if k.size \
        else math.nan
    values["control/rms_removed_m"] = float(np.sqrt(np.nanmean(r_rem**2))) if k.size \
        else math.nan
    values["control/median_removed_px"] = float(np.nanmedian(r_rem) / gsd) if k.size \
        else math.nan
    values["control/mean_e_removed_m"] = float(np.nanmean(e_rem)) if k.size else math.nan
    values["control/mean_n_removed_m"] = float(np.nanmean(n_rem)) if k.size else math.nan
    for image in scene.sensors:
        values[f"control/n/{image}"] = float(np.count_nonzero(images == image))
    return {"e": e_rem, "n": n_rem}


def _icp_errors(models: Mapping[str, Any], icp: dict[str, np.ndarray], dem: Any = None
                ) -> tuple[np.ndarray, np.ndarray]:
    """(N,) east/north error of each ICP measurement through ``models``: its exact image
    position located at the true height (``dem`` None: the check's error) or on ``dem`` (the
    ortho's error), minus the truth, metres."""
    de = np.full(icp["row"].size, np.nan)
    dn = np.full(icp["row"].size, np.nan)
    for image, model in models.items():  # a loop over the images
        sel = icp["image"] == image
        if not sel.any():
            continue
        if dem is None:
            g = model.backproject(icp["row"][sel], icp["col"][sel], icp["h"][sel])
        else:
            g, _ = localize(model, icp["row"][sel], icp["col"][sel], dem, warn=False)
        de[sel], dn[sel] = _en(icp["lon"][sel], icp["lat"][sel], icp["h"][sel], g.lon, g.lat)
    return de, dn


#: Pixel of the accuracy layers computed for the validation, metres (the layer is smooth).
LAYER_PX_M = 10.0


def _bilinear(values: np.ndarray, row: np.ndarray, col: np.ndarray) -> np.ndarray:
    """``values`` (R, C) at fractional pixel positions (centres at integers), NaN outside."""
    r0 = np.floor(row).astype(np.intp)
    c0 = np.floor(col).astype(np.intp)
    ok = (r0 >= 0) & (c0 >= 0) & (r0 + 1 < values.shape[0]) & (c0 + 1 < values.shape[1])
    r0, c0 = np.where(ok, r0, 0), np.where(ok, c0, 0)
    tr, tc = row - r0, col - c0
    out = (values[r0, c0] * (1 - tr) * (1 - tc) + values[r0 + 1, c0] * tr * (1 - tc)
           + values[r0, c0 + 1] * (1 - tr) * tc + values[r0 + 1, c0 + 1] * tr * tc)
    return np.where(ok, out, np.nan)


def _layer(result: BlockResult, scene: Scene, icp: dict[str, np.ndarray], full: bool
           ) -> dict[str, np.ndarray]:
    """The accuracy layer at the ICPs' ortho positions (each ICP's exact image position
    located on the measured DEM through the adjusted model): ``exact`` (N,) its value there
    (:func:`geoblock.models.uncertainty.ground_error`: the radial RMS of the posterior
    propagated plus the DEM part), ``dem`` (N,) the DEM part, and with ``full`` ``layer``
    (N,) the layer itself, :func:`geoblock.ortho.accuracy_layer` on a :data:`LAYER_PX_M`
    grid over the image sampled bilinearly."""
    from geoblock.models.uncertainty import ModelPosterior, ground_error
    from geoblock.ortho import accuracy_layer
    from geoblock.ortho.grid import OutputGrid

    n = icp["row"].size
    out = {k: np.full(n, np.nan) for k in (("layer", "exact", "dem") if full
                                           else ("exact", "dem"))}
    for image, model in result.models.items():  # a loop over the images
        sel = np.flatnonzero(icp["image"] == image)
        if not sel.size:
            continue
        g, _ = localize(model, icp["row"][sel], icp["col"][sel], scene.dem, warn=False)
        names, cov = result.parameter_covariance(image)
        err = ground_error(model, names, cov, ground=(g.lon, g.lat, g.h),
                           dem_sigma=scene.dem_sigma_m)
        out["exact"][sel] = err.sigma
        out["dem"][sel] = np.sqrt(np.trace(err.dem, axis1=1, axis2=2))
        if not full:
            continue
        grid = OutputGrid.for_model(model, scene.dem, crs=scene.crs, resolution=LAYER_PX_M)
        layer = accuracy_layer(model, scene.dem, grid, dem_sigma=scene.dem_sigma_m,
                               posterior=ModelPosterior(names, cov))
        values = np.asarray(layer.values, dtype=np.float64)[0]
        x, y = coords.transformer("EPSG:4326", scene.crs).transform(g.lon, g.lat)
        t = grid.transform
        out["layer"][sel] = _bilinear(values, (np.asarray(y) - t.f) / t.e - 0.5,
                                      (np.asarray(x) - t.c) / t.a - 0.5)
    return out


def _rms(x: np.ndarray) -> float:
    x = np.asarray(x, float)
    return float(np.sqrt(np.nanmean(x**2))) if np.isfinite(x).any() else math.nan


def run_case(scene: Scene, case: Case, seed: int, workdir: Path, *,
             weightings: tuple[str, ...] = WEIGHTINGS, layer: bool = False,
             consider: bool = True, matcher: str = "match",
             stratum: tuple[int, int] | None = None, full_layer: bool = False) -> CaseOutcome:
    """One repetition of ``case`` on ``scene`` (module docstring).

    ``values`` keys: ``shift/e``, ``shift/n`` (m); ``control/*`` (:func:`_measure_control`:
    ``n``, ``within_1px_removed``, ``within_1px_included``, ``rms_removed_m``,
    ``median_removed_px``); per weighting ``w``: ``{w}/icp_rmse_m``, ``{w}/icp_pred_m``
    (RMS of the predicted sigmas, 2D), ``{w}/icp_mse_m2``, ``{w}/icp_pred_m2``,
    ``{w}/ce90_emp_m``, ``{w}/ce90_pred_m``, ``{w}/sigma0``, ``{w}/converged``,
    ``{w}/ortho_rmse_m``; for ``own`` with ``consider``: ``own/icp_pred_consider_m``,
    ``.../icp_pred_consider_m2``, ``.../ce90_pred_consider_m`` and the mean response
    ``own/response`` (ICP shift per metre of control shift); with
    ``shift`` when the engine estimates it: ``shift/est_e``, ``shift/est_n`` (m),
    ``shift/est_sigma_e`` (m).

    ``stratum``: ``(k, count)`` for a ``random`` case: the shift's size is the ``k``-th of
    ``count`` stratified draws (:func:`stratified_radius`) in a random direction; None: a
    plain Gaussian draw. ``full_layer``: with ``layer``, also compute the accuracy layer
    itself over each image (:func:`geoblock.ortho.accuracy_layer`, ~1 s per image) and
    sample it at the ICPs (``{w}/layer``); otherwise only its exact value there
    (``{w}/exact``, what the layer interpolates to 0.1 %).

    ``matcher``: ``"match"`` (:func:`geoblock.match.match_reference`) or ``"oracle"``
    (:func:`oracle_control`: an ideal matcher, the floor).

    ``layer`` (per weighting, when asked, arrays over the ICP measurements): ``{w}/exact``,
    ``{w}/dem`` and with ``full_layer`` ``{w}/layer`` (:func:`_layer`), ``{w}/ortho_e``,
    ``{w}/ortho_n`` the ortho errors, ``{w}/check_e``, ``{w}/check_n``, ``{w}/check_cov``
    (N, 2, 2) the check errors and their predicted covariance (in
    :attr:`~geoblock.adjust.BlockResult.check`'s order),
    ``{w}/vertical_u``, ``{w}/vertical_sigma`` the vertical check; for ``own``
    ``own/pred_consider`` (N, 2, 2) the consider covariance at the ortho positions and
    ``own/check_consider`` at the check rows.
    """
    out = CaseOutcome(scene.block, case, int(seed))
    v = out.values
    rng = np.random.default_rng([int(seed), int(case.gsd_m * 100), int(case.error_m * 100),
                                 int(case.random), sum(map(ord, scene.block))])
    t0 = time.perf_counter()
    de, dn = _shift(case, rng, stratum)
    v["shift/e"], v["shift/n"] = de, dn
    path = workdir / f"reference-{scene.block}-{case.gsd_m:g}m-{seed}.tif"
    ref = render_reference(scene.texture, scene.bounds, case.gsd_m, scene.crs,
                           shift_en_m=(de, dn), path=path, terrain=scene.terrain,
                           noise_dn=NOISE_DN, seed=int(rng.integers(1 << 31)))
    out.seconds["reference"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    try:
        control = (oracle_control(scene, ref, case.ce90_m, rng) if matcher == "oracle"
                   else _match(scene, path, case, rng))
    except MatchError as exc:  # e.g. a 1 km image is 50 x 50 px of a 20 m reference
        out.failure = str(exc)
        out.seconds["match"] = time.perf_counter() - t0
        return out
    out.seconds["match"] = time.perf_counter() - t0
    _measure_control(scene, ref, control, v)
    # ---- tie points and ICPs from the truth
    pts = simulate_points({i: s.true_model for i, s in scene.sensors.items()}, scene.truth,
                          gcp=0, icp=ICP_PER_IMAGE, tp=TP_PER_PAIR if len(scene.sensors) > 1
                          else 0, sigma_px=TP_SIGMA_PX, sigma_e=0.0, sigma_n=0.0, sigma_h=0.0,
                          seed=int(rng.integers(1 << 31)))
    gp, mp = pts.ground, pts.image
    icp_ground = gp.kind == "icp"
    icp_ids = gp.id[icp_ground]
    exact = _ground(icp_ids, np.full(icp_ids.size, "icp"), gp.lon_true[icp_ground],
                    gp.lat_true[icp_ground], gp.h_true[icp_ground], EXACT_M, EXACT_M, EXACT_M)
    is_icp = mp.kind == "icp"
    is_tp = mp.kind == "tp"
    where = {p: k for k, p in enumerate(gp.id.tolist())}
    kk = np.array([where[p] for p in mp.id[is_icp].tolist()], dtype=np.intp)
    icp = {"id": mp.id[is_icp], "image": mp.image[is_icp].astype(str),
           "row": mp.row_true[is_icp], "col": mp.col_true[is_icp], "lon": gp.lon_true[kk],
           "lat": gp.lat_true[kk], "h": gp.h_true[kk]}
    meas_parts = [
        ImagePoints(mp.id[is_tp], mp.image[is_tp], mp.row[is_tp], mp.col[is_tp],
                    TP_SIGMA_PX, TP_SIGMA_PX, "tp"),
        ImagePoints(icp["id"], icp["image"], icp["row"], icp["col"], EXACT_PX, EXACT_PX,
                    "icp"),
        ImagePoints(control.measurements["id"], control.measurements["image"],
                    control.measurements["row"], control.measurements["col"],
                    control.measurements["sigma"], control.measurements["sigma"], "gcp"),
    ]
    meas = ImagePoints(*(np.concatenate([getattr(p, f) for p in meas_parts]) for f in (
        "id", "image", "row", "col", "sigma_row", "sigma_col", "kind")))
    g = control.ground
    s_shift = case.ce90_m / CE90_FACTOR
    if "sigma_shift_e" in g:  # match_reference gives each point its own (matching) sigma
        own = np.asarray(g["sigma_e"], float)
    else:  # an older match_reference: the reference's CE90 in each point's sigma
        own = np.sqrt(np.maximum(np.asarray(g["sigma_e"], float) ** 2 - s_shift**2, 1e-6))
    source = np.asarray(g.get("source", np.full(len(control), "reference")))
    for w in weightings:
        if w == "shift" and not engine_has_shift():
            continue
        if w == "independent":
            both = np.hypot(own, s_shift)
            ctrl = _ground(g["id"], g["kind"], g["lon"], g["lat"], g["h"], both, both,
                           g["sigma_h"], source=source)
        elif w == "own":
            ctrl = _ground(g["id"], g["kind"], g["lon"], g["lat"], g["h"], own, own,
                           g["sigma_h"], source=source)
        else:
            ctrl = _ground(g["id"], g["kind"], g["lon"], g["lat"], g["h"], own, own,
                           g["sigma_h"], source=source, sigma_shift_e=s_shift,
                           sigma_shift_n=s_shift, sigma_shift_h=0.0)
        block = Block(scene.models, meas, _concat_ground([ctrl, exact]), scene.dem,
                      scene.dem_sigma_m)
        t0 = time.perf_counter()
        # "shift": the engine estimates the common error (control_shifts="estimate"); its
        # default, "consider", is what the "consider" route computes here by hand
        result = adjust(block, control_shifts="estimate") if w == "shift" else adjust(block)
        out.seconds[f"adjust/{w}"] = time.perf_counter() - t0
        _measure_result(result, w, v)
        oe, on = _icp_errors(result.models, icp, scene.dem)
        v[f"{w}/ortho_rmse_m"] = _rms(np.hypot(oe, on))
        if w == "shift":
            shifts = getattr(result, "shifts", {}) or {}
            if shifts:
                s = next(iter(shifts.values()))
                v["shift/est_e"], v["shift/est_n"] = float(s.values[0]), float(s.values[1])
                v["shift/est_sigma_e"] = float(s.sigmas[0])
                v["shift/est_sigma_n"] = float(s.sigmas[1])
        if layer:
            t1 = time.perf_counter()
            for key, arr in _layer(result, scene, icp, full_layer).items():
                out.layer[f"{w}/{key}"] = arr
            out.layer[f"{w}/ortho_e"], out.layer[f"{w}/ortho_n"] = oe, on
            st = result.accuracy_statement()
            out.layer[f"{w}/check_e"] = result.check.e[_icp_rows(result)]
            out.layer[f"{w}/check_n"] = result.check.n[_icp_rows(result)]
            out.layer[f"{w}/check_cov"] = _icp_pred_cov(result)
            vert = getattr(result, "vertical", None)
            if vert is not None and len(vert):
                out.layer[f"{w}/vertical_u"] = np.asarray(vert.u, float)
                out.layer[f"{w}/vertical_sigma"] = np.asarray(vert.sigma_up, float)
            v[f"{w}/le90_pred_m"] = st.le90_predicted
            v[f"{w}/le90_emp_m"] = st.le90_empirical
            out.seconds[f"layer/{w}"] = time.perf_counter() - t1
        if w == "own" and consider:
            t0 = time.perf_counter()
            cons = _consider(scene, block, result, icp, s_shift, layer)
            out.seconds["consider"] = time.perf_counter() - t0
            pred = _icp_pred_cov(result)
            total = pred + cons["check"]
            v["own/icp_pred_consider_m2"] = float(np.nanmean(np.trace(
                total, axis1=1, axis2=2)))
            v["own/icp_pred_consider_m"] = math.sqrt(v["own/icp_pred_consider_m2"])
            v["own/ce90_pred_consider_m"] = predicted_ce(total, 0.90)
            v["own/response"] = cons["response"]
            if layer:
                out.layer["own/pred_consider"] = cons["ortho"]
                out.layer["own/check_consider"] = cons["check"]
    out.seconds["total"] = sum(out.seconds.values())
    return out


def _match(scene: Scene, path: Path, case: Case, rng: np.random.Generator) -> Any:
    """The images of this repetition (new noise) matched against the reference."""
    from geoblock.io.images import ArrayImage
    from geoblock.match import MatchImage, match_reference

    images = []
    for image, clean in scene.pixels.items():  # a loop over the images
        noisy = clean.astype(np.float64) + rng.normal(0.0, NOISE_DN, clean.shape)
        noisy = np.where(clean == 0, 0.0, np.clip(np.round(noisy), 1.0, 255.0))
        images.append(MatchImage(image, ArrayImage(noisy.astype(np.uint8), nodata=0,
                                                   name=image), scene.models[image]))
    return match_reference(images, str(path), scene.dem,
                           reference_accuracy_ce90_m=case.ce90_m,
                           dem_sigma_m=scene.dem_sigma_m)


def _icp_rows(result: BlockResult) -> np.ndarray:
    return np.char.lower(result.check.kind.astype(str)) == "icp"


def _icp_pred_cov(result: BlockResult) -> np.ndarray:
    """(N, 2, 2) predicted east/north covariance at the ICP rows of ``result.check``."""
    icp = _icp_rows(result)
    full = getattr(result, "predicted_covariance", None)
    if full is not None:
        return np.asarray(full, float)[icp]
    s = np.asarray(result.predicted_sigma, float)[icp]
    return s[:, :, None] ** 2 * np.eye(2)


def _measure_result(result: BlockResult, w: str, v: dict[str, float]) -> None:
    icp = _icp_rows(result)
    e, n = result.check.e[icp], result.check.n[icp]
    cov = _icp_pred_cov(result)
    v[f"{w}/icp_mse_m2"] = float(np.nanmean(e**2 + n**2))
    v[f"{w}/icp_rmse_m"] = math.sqrt(v[f"{w}/icp_mse_m2"])
    v[f"{w}/icp_pred_m2"] = float(np.nanmean(np.trace(cov, axis1=1, axis2=2)))
    v[f"{w}/icp_pred_m"] = math.sqrt(v[f"{w}/icp_pred_m2"])
    v[f"{w}/icp_mean_e_m"] = float(np.nanmean(e))
    v[f"{w}/icp_mean_n_m"] = float(np.nanmean(n))
    v[f"{w}/ce90_emp_m"] = empirical_ce(e, n, 0.90)
    v[f"{w}/ce90_pred_m"] = predicted_ce(cov, 0.90)
    v[f"{w}/sigma0"] = float(result.sigma0)
    # the engine scales its posterior by sigma0**2: the prediction of the a-priori weights
    v[f"{w}/icp_pred_unscaled_m"] = v[f"{w}/icp_pred_m"] / float(result.sigma0) \
        if result.sigma0 > 0 else math.nan
    v[f"{w}/converged"] = float(result.converged)


def _consider(scene: Scene, block: Block, result: BlockResult, icp: dict[str, np.ndarray],
              s_shift: float, ortho: bool) -> dict[str, Any]:
    """The consider covariance of a shift common to all control points (module docstring,
    step 3): two adjustments with every control point moved 1 m east, then 1 m north."""
    assert block.ground is not None
    gr = block.ground
    ctrl = np.char.lower(gr.kind.astype(str)) == "gcp"
    base_check = _icp_errors(result.models, icp)
    base_ortho = _icp_errors(result.models, icp, scene.dem) if ortho else None
    cols_check, cols_ortho = [], []
    for de, dn in ((1.0, 0.0), (0.0, 1.0)):
        lon, lat = shift_lonlat(gr.lon, gr.lat, np.where(ctrl, de, 0.0),
                                np.where(ctrl, dn, 0.0))
        moved = _ground(gr.id, gr.kind, lon, lat, gr.h, gr.sigma_e, gr.sigma_n, gr.sigma_h,
                        **{k: getattr(gr, k) for k in ("source",) if hasattr(gr, k)})
        res = adjust(Block(block.models, block.measurements, moved, block.dem,
                           block.dem_sigma_m))
        e, n = _icp_errors(res.models, icp)
        cols_check.append(np.stack([e - base_check[0], n - base_check[1]], axis=-1))
        if ortho and base_ortho is not None:
            e, n = _icp_errors(res.models, icp, scene.dem)
            cols_ortho.append(np.stack([e - base_ortho[0], n - base_ortho[1]], axis=-1))
    # the check rows of result.check are in the block's ICP measurement order: match them
    icp_rows = _icp_rows(result)
    key = np.char.add(np.char.add(result.check.id[icp_rows].astype(str), "\x00"),
                      result.check.image[icp_rows].astype(str))
    mine = np.char.add(np.char.add(icp["id"].astype(str), "\x00"), icp["image"])
    pos = {k: i for i, k in enumerate(mine.tolist())}
    take = np.array([pos[k] for k in key.tolist()], dtype=np.intp)
    jac = np.stack(cols_check, axis=-1)  # (N, 2, 2): d(e, n) / d(shift e, shift n)
    cov_check = s_shift**2 * (jac @ np.swapaxes(jac, 1, 2))
    out: dict[str, Any] = {"check": cov_check[take],
                           "response": float(np.nanmean(0.5 * (jac[:, 0, 0] + jac[:, 1, 1])))}
    if ortho:
        jo = np.stack(cols_ortho, axis=-1)
        out["ortho"] = s_shift**2 * (jo @ np.swapaxes(jo, 1, 2))
    return out
