"""One repetition of Chen & Lee (1993): a simulated SPOT 1A scene oriented with 21 GCPs
through Chen & Lee's model, its check points over the scene (Case III) and the orthoimage
accuracy over a rolling (Case I) and a rugged (Case II) test area.

:func:`seed_outcome` does, for one seed:

1. simulates the ``chen1993-spot1a`` preset in memory (:mod:`geoblock.simulate.scene`) with
   the seed and Case III's 24 check points (CKPs): a SPOT 1A scene (10.4 deg incidence) over
   ridged terrain of 950 m relief, 21 GCPs stratified over a 3 x 3 grid, pointing noise of
   the preset (0.3 SPOT pixel) and map noise of 1 m;
2. fits Chen & Lee's polynomial model (second-order orbit and attitude in time, scale
   affinity; :func:`geoblock_spot.fit.fit_chenlee`) to the on-board model and adjusts its
   ``mba`` parameter set (corrections with a-priori sigmas from the on-board accuracy) to
   the 21 GCPs (:func:`geoblock.adjust.resect`): the GCP image residuals (Table 2) and the
   CKPs' (measured minus projected, Table 5);
3. orthoimage accuracy without rendering (Cases I and II, Tables 3-4): each test area is a
   5.5 x 5 km patch (the paper's 550 x 500 orthoimage pixels of 10 m) of its own true
   terrain, rolling (fractal, 10-170 m) or rugged (ridged, 50-590 m, as the paper's sites),
   seen by the same oriented scene, with a 40 m DTM of the preset's RMSEz read by cubic
   convolution (the paper's 40 m DTM resampled to 10 m). Where the orthoimage shows a check
   point is where the adjusted model puts its image position on the DTM: the point's true
   image position, plus the pointing noise of identifying it, is located on the DTM
   (:func:`geoblock.localize`) and compared with its map (surveyed) position. The same on
   the true terrain separates the DTM's share.

Statistics are a flat ``{key: value}`` dictionary (:attr:`SeedOutcome.values`); keys are
listed in :func:`seed_outcome`.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from geoblock_spot.fit import fit_chenlee

import geoblock
from geoblock import coords
from geoblock.adjust import ControlPoints, ResectionResult, ground_errors, resect
from geoblock.errors import GeoblockError
from geoblock.simulate.points import PointSet
from geoblock.simulate.scenario import derived_seed, preset_dict, scenario_from_dict
from geoblock.simulate.scene import scene_grid, scene_points, scene_sensors, true_terrain
from geoblock.simulate.sensors import SimulatedSensor, incidence_angle
from geoblock.simulate.terrain import Grid, Terrain, fractal_terrain, measured_dem, ridged_terrain

__all__ = [
    "AREA_SIZE_M",
    "CASES",
    "CKP_COUNT",
    "SPOT_PIXEL_M",
    "Case",
    "SeedOutcome",
    "area_terrain",
    "locate_on_dtm",
    "outcomes",
    "scenario_dict",
    "seed_outcome",
]

#: SPOT 1A pixel, metres: image residuals are given in these pixels whatever the variant
SPOT_PIXEL_M = 10.0
#: check points of Case III (the preset has 20 ICPs)
CKP_COUNT = 24
#: extent of each test area (east, north), metres: 550 x 500 orthoimage pixels of 10 m
AREA_SIZE_M = (5500.0, 5000.0)
#: post spacing of the test areas' true terrain, metres (the orthoimage's pixel)
AREA_RESOLUTION_M = 10.0
#: check points are kept this far inside the test area, metres
AREA_INSET_M = 250.0


@dataclass(frozen=True)
class Case:
    """A test area of Cases I and II.

    Attributes
    ----------
    name : str
        ``"rolling"`` or ``"rugged"``.
    label : str
        The paper's name (``"Case I"``).
    centre : (float, float)
        Its centre as fractions of the image rows and columns.
    relief : (float, float)
        Lowest and highest true height, metres (the paper's elevation range).
    kind : {"fractal", "ridged"}
        Terrain generator (:func:`~geoblock.simulate.terrain.fractal_terrain`: rolling
        hills; :func:`~geoblock.simulate.terrain.ridged_terrain`: crests and valleys).
    max_slope_deg : float or None
        Steepest slope (None: as generated).
    checkpoints : int
        The paper's number of check points.
    """

    name: str
    label: str
    centre: tuple[float, float]
    relief: tuple[float, float]
    kind: str
    max_slope_deg: float | None
    checkpoints: int


#: Cases I (Houlong, rolling, 10-170 m, 25 check points) and II (Hsitang, rugged, 50-590 m,
#: 22 check points); the paper does not locate them in the scene, we put them in two
#: quadrants
CASES = (
    Case("rolling", "Case I", (0.3, 0.3), (10.0, 170.0), "fractal", None, 25),
    Case("rugged", "Case II", (0.65, 0.65), (50.0, 590.0), "ridged", 40.0, 22),
)


def scenario_dict(seed: int, full: bool) -> dict[str, Any]:
    """The ``chen1993-spot1a`` preset (``full`` or ``small``) with ``seed`` and
    :data:`CKP_COUNT` ICPs; nothing is rendered."""
    data = preset_dict("chen1993-spot1a", "full" if full else "small")
    data["seed"] = int(seed)
    data["points"]["icp"] = CKP_COUNT
    data["render"]["enabled"] = False
    return data


def _control_points(points: PointSet, kind: str) -> ControlPoints:
    """The measurements of ``kind`` (one image) with their surveyed ground points."""
    m, g = points.image, points.ground
    sel = np.flatnonzero(m.kind == kind)
    index = {pid: i for i, pid in enumerate(g.id.tolist())}
    k = np.array([index[p] for p in m.id[sel].tolist()], dtype=np.intp)
    return ControlPoints(m.id[sel], g.lon[k], g.lat[k], g.h[k], m.row[sel], m.col[sel],
                         m.sigma[sel], m.sigma[sel], g.sigma_e[k], g.sigma_n[k], g.sigma_h[k])


def area_terrain(case: Case, sensor: SimulatedSensor, seed: int) -> Terrain:
    """The true terrain of a test area: :data:`AREA_SIZE_M` at :data:`AREA_RESOLUTION_M`
    around the ground point the true model sees at ``case.centre`` (mid-relief height)."""
    rows, cols = sensor.spec.shape
    g = sensor.true_model.backproject(case.centre[0] * rows, case.centre[1] * cols,
                                      0.5 * sum(case.relief))
    grid = Grid.around(float(g.lon), float(g.lat), AREA_SIZE_M, AREA_RESOLUTION_M)
    make = fractal_terrain if case.kind == "fractal" else ridged_terrain
    return make(grid, case.relief, max_slope_deg=case.max_slope_deg, seed=seed)


def locate_on_dtm(model: Any, row: np.ndarray, col: np.ndarray, dem: Any,
                  lon_ref: np.ndarray, lat_ref: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """East and north errors (metres) of image points located on ``dem`` through ``model``
    (:func:`geoblock.localize`) against reference positions: the error of an orthoimage
    made with ``model`` and ``dem`` at those points. NaN where the location fails."""
    g, _ = geoblock.localize(model, row, col, dem, warn=False)
    de, dn, _ = ground_errors(g.lon, g.lat, lon_ref, lat_ref)
    return de, dn


@dataclass
class SeedOutcome:
    """The statistics of one repetition.

    Attributes
    ----------
    seed : int
    values : dict of str to float
        Keys in :func:`seed_outcome`.
    vectors : dict of str to (e, n, de, dn)
        Positions (local metres) and errors (metres) for the error vector plots: ``gcp``
        (ground equivalent of the image residuals, Fig. 5), ``ckp`` (Fig. 11), ``rolling``
        (Fig. 8), ``rugged`` (Fig. 10).
    seconds : float
    """

    seed: int
    values: dict[str, float] = field(default_factory=dict)
    vectors: dict[str, tuple[np.ndarray, ...]] = field(default_factory=dict)
    seconds: float = math.nan


def _put_axis(values: dict[str, float], prefix: str, x: np.ndarray) -> None:
    """``max``, ``min`` and ``rms`` of residuals (NaN ignored)."""
    x = x[np.isfinite(x)]
    values[f"{prefix}/max"] = float(x.max()) if x.size else math.nan
    values[f"{prefix}/min"] = float(x.min()) if x.size else math.nan
    values[f"{prefix}/rms"] = float(np.sqrt(np.mean(x**2))) if x.size else math.nan


def _local_en(lon: np.ndarray, lat: np.ndarray, h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    frame = coords.LocalFrame.centred_on(lon, lat, h)
    e, n, _ = frame.from_geodetic(lon, lat, h)
    return np.asarray(e), np.asarray(n)


def _orientation(sensor: SimulatedSensor, gcps: ControlPoints,
                 ckps: ControlPoints) -> tuple[ResectionResult, float]:
    """Chen & Lee's model fitted to the on-board model, its ``mba`` set adjusted to the GCPs
    (CKPs evaluated); and the fit's RMS error (pixels of the simulated image)."""
    onboard = sensor.onboard_model
    fit = fit_chenlee(onboard, location_accuracy_m=onboard.location_accuracy_m)
    return resect(fit.model, gcps, ckps), float(fit.rms_px)


def seed_outcome(seed: int, full: bool = False,
                 progress: Callable[[str], None] | None = None) -> SeedOutcome:
    """Simulate one scene and measure the three cases (module docstring).

    Keys of :attr:`SeedOutcome.values` (``{axis}`` ``x`` along track = rows, ``y`` across =
    columns, in SPOT pixels of :data:`SPOT_PIXEL_M`; ``{X|Y}`` map east and north, metres):

    * ``gcp/{axis}/{max|min|rms}``: GCP image residuals after the adjustment (Table 2);
    * ``ckp/{axis}/{max|min|rms}``: CKP image residuals (Table 5); ``ckp/relief``: the CKPs'
      height range, metres;
    * ``{case}/{X|Y}/{max|min|rms}``: orthoimage errors at the check points of case
      ``rolling`` or ``rugged`` (Tables 3-4); ``{case}/truth/{X|Y}/{max|min|rms}``: the same
      located on the true terrain; ``{case}/dtm_rmse_z``: the DTM's height error at the
      check points;
      ``{case}/relief``, ``{case}/slope_p95``: the area's relief (m) and 95th percentile
      slope (degrees);
    * ``sigma0``, ``fit_px`` (Chen & Lee's fit to the on-board model, SPOT pixels),
      ``incidence`` (degrees), ``onboard_2d`` (the on-board model's RMSE 2D at the CKPs, m),
      ``ortho_seconds``: ground to image through the adjusted model for the 550 x 500 posts
      of the rugged area (Chen & Lee's indirect method).

    Raises
    ------
    GeoblockError
        The scene cannot be simulated or the model cannot be fitted or adjusted.
    """
    say = progress or (lambda message: None)
    start = time.perf_counter()
    out = SeedOutcome(int(seed))
    v = out.values
    scenario = scenario_from_dict(scenario_dict(seed, full),
                                  f"preset:chen1993-spot1a/{'full' if full else 'small'}")
    sensors = scene_sensors(scenario)
    (sensor,) = sensors.values()
    truth = true_terrain(scenario, scene_grid(scenario, sensors))
    points = scene_points(scenario, sensors, truth.to_dem())
    gcps, ckps = _control_points(points, "gcp"), _control_points(points, "icp")
    px = sensor.spec.gsd_m / SPOT_PIXEL_M  # simulated pixels -> SPOT pixels
    rows, cols = sensor.spec.shape
    v["incidence"] = abs(incidence_angle(sensor.true_model, (rows - 1) / 2, (cols - 1) / 2,
                                         float(np.mean(gcps.h))))
    (lon, lat, _), _ = sensor.onboard_model.backproject_with_status(ckps.row, ckps.col, ckps.h)
    de, dn, _ = ground_errors(lon, lat, ckps.lon, ckps.lat, h=ckps.h)
    v["onboard_2d"] = float(np.sqrt(np.mean(de**2 + dn**2)))

    say(f"  seed {seed}: Chen & Lee's model fitted to the on-board model, adjusted to "
        f"{len(gcps)} GCPs")
    result, fit_px = _orientation(sensor, gcps, ckps)
    adjusted = result.model
    v["sigma0"] = float(result.sigma0)
    v["fit_px"] = fit_px * px
    for prefix, res, pts in (("gcp", result.gcp, gcps), ("ckp", result.icp, ckps)):
        if res is None:  # resect evaluates the CKPs it is given
            raise GeoblockError(f"chen1993: seed {seed}: the resection gave no {prefix} "
                                "residuals")
        _put_axis(v, f"{prefix}/x", res.row * px)
        _put_axis(v, f"{prefix}/y", res.col * px)
        out.vectors[prefix] = (*_local_en(pts.lon, pts.lat, pts.h), res.e, res.n)
    v["ckp/relief"] = float(np.ptp(points.ground.h_true[points.ground.kind == "icp"]))

    sigma_px = scenario.points.sigma_px
    sigma_e, sigma_n = scenario.points.sigma_e, scenario.points.sigma_n
    spec = scenario.dems[0]
    for k, case in enumerate(CASES):
        say(f"  seed {seed}: {case.label} ({case.name}, {case.relief[0]:g}-{case.relief[1]:g} "
            f"m): {case.checkpoints} check points on a {spec.spacing_m:g} m DTM")
        area = area_terrain(case, sensor, derived_seed(seed, 1993, k, 1))
        area_dem = area.to_dem()
        dtm = measured_dem(area, spec.spacing_m, spec.rmse_z,
                           seed=derived_seed(seed, 1993, k, 2)).to_dem(interpolation="bicubic")
        rng = np.random.default_rng(derived_seed(seed, 1993, k, 3))
        w, s, e, n = area.grid.bounds
        x = rng.uniform(w + AREA_INSET_M, e - AREA_INSET_M, case.checkpoints)
        y = rng.uniform(s + AREA_INSET_M, n - AREA_INSET_M, case.checkpoints)
        to_geo = coords.transformer(area.crs, "EPSG:4326")
        lon_t, lat_t = (np.asarray(a) for a in to_geo.transform(x, y))
        h_t = area_dem.height(lon_t, lat_t)
        row_t, col_t = sensor.true_model.project(lon_t, lat_t, h_t)
        # identified on the orthoimage: the true image position plus pointing noise; map
        # coordinates: the truth plus survey noise (UTM metres ~ east/north here)
        row_m = row_t + rng.normal(0.0, sigma_px, row_t.shape)
        col_m = col_t + rng.normal(0.0, sigma_px, col_t.shape)
        lon_s, lat_s = (np.asarray(a) for a in to_geo.transform(
            x + rng.normal(0.0, sigma_e, x.shape), y + rng.normal(0.0, sigma_n, y.shape)))
        ex, ey = locate_on_dtm(adjusted, row_m, col_m, dtm, lon_s, lat_s)
        _put_axis(v, f"{case.name}/X", ex)
        _put_axis(v, f"{case.name}/Y", ey)
        tx, ty = locate_on_dtm(adjusted, row_m, col_m, area_dem, lon_s, lat_s)
        _put_axis(v, f"{case.name}/truth/X", tx)
        _put_axis(v, f"{case.name}/truth/Y", ty)
        v[f"{case.name}/dtm_rmse_z"] = float(np.sqrt(np.mean(
            (dtm.height(lon_t, lat_t) - h_t) ** 2)))
        lo, hi = area.relief
        v[f"{case.name}/relief"] = hi - lo
        v[f"{case.name}/slope_p95"] = float(np.percentile(area.slope_deg(), 95))
        out.vectors[case.name] = (*_local_en(lon_t, lat_t, h_t), ex, ey)
        if case.name == "rugged":  # Chen & Lee's indirect method over a 550 x 500 orthoimage
            gx, gy = area.grid.xy()
            xx, yy = np.meshgrid(gx[:550], gy[:500])
            lon_o, lat_o = (np.asarray(a) for a in to_geo.transform(xx, yy))
            h_o = dtm.height(lon_o, lat_o)
            tick = time.perf_counter()
            adjusted.project(lon_o, lat_o, h_o)
            v["ortho_seconds"] = time.perf_counter() - tick
    out.seconds = time.perf_counter() - start
    return out


def outcomes(seeds: Sequence[int], full: bool,
             progress: Callable[[str], None] | None = None) -> list[SeedOutcome]:
    """:func:`seed_outcome` of each seed, in order, with a progress line per seed."""
    from geoblock_papers.registry import per_seed

    return per_seed(seeds, lambda seed: seed_outcome(seed, full, progress), "the SPOT 1A scene",
                    progress)
