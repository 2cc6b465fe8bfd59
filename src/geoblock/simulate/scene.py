"""A scenario's scene in memory: sensors, true terrain, measured DEMs, points, texture, images.

Each function builds one component of a :class:`~geoblock.simulate.scenario.Scenario` from
the scenario and the components it depends on, with the component's seed derived from the
scenario's (:func:`~geoblock.simulate.scenario.derived_seed`), so that building them one by
one, in any program, gives exactly the block :func:`geoblock.workflows.run_scenario` writes::

    sensors = scene_sensors(scenario)                 # true and on-board models per image
    grid = scene_grid(scenario, sensors)              # the footprints plus a margin
    truth = true_terrain(scenario, grid)              # Terrain
    dems = {d.name: scene_dem(scenario, truth, k) for k, d in enumerate(scenario.dems)}
    points = scene_points(scenario, sensors, truth.to_dem())
    texture = scene_texture(scenario, sensors)
    image = scene_image(scenario, sensors, "strip1", truth.to_dem(), texture)

Nothing here reads or writes a file.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import pyproj

from geoblock import coords
from geoblock.simulate.points import PointSet, simulate_points
from geoblock.simulate.render import ProceduralTexture, RenderedImage, Texture, render_image
from geoblock.simulate.scenario import Scenario, derived_seed
from geoblock.simulate.sensors import SimulatedSensor, simulate_sensor
from geoblock.simulate.terrain import Grid, Terrain, fractal_terrain, measured_dem, ridged_terrain

__all__ = [
    "ContrastedTexture",
    "scene_dem",
    "scene_grid",
    "scene_image",
    "scene_points",
    "scene_sensors",
    "scene_texture",
    "true_terrain",
]


def scene_sensors(scenario: Scenario) -> dict[str, SimulatedSensor]:
    """The simulated sensor of each image (its true and on-board models), by image id, in
    the scenario's order (:func:`~geoblock.simulate.sensors.simulate_sensor` of each
    image's spec, whose seed the scenario derived)."""
    return {im.id: simulate_sensor(im.spec) for im in scenario.images}


def scene_grid(scenario: Scenario, sensors: Mapping[str, SimulatedSensor]) -> Grid:
    """The true terrain's grid: every image's true footprint at the relief's lowest and
    highest heights, plus ``terrain.margin_m``, in ``terrain.crs`` (default the UTM zone of
    the scene's centre), with ``terrain.resolution_m`` posts.

    In a projected CRS the bounds are whole multiples of the resolution, so that the same
    scene always gives the same grid.
    """
    lo, hi = scenario.terrain.relief
    lon, lat = [], []
    for sim in sensors.values():
        for h in (lo, hi):
            fp = sim.true_model.footprint(h=h, n=8)
            lon.append(np.asarray(fp.lon))
            lat.append(np.asarray(fp.lat))
    lon_a, lat_a = np.concatenate(lon), np.concatenate(lat)
    lon0, lat0 = float(np.mean(lon_a)), float(np.mean(lat_a))
    crs = pyproj.CRS.from_user_input(scenario.terrain.crs or coords.utm_crs(lon0, lat0))
    horizontal = crs.sub_crs_list[0] if crs.is_compound else crs
    m = scenario.terrain.margin_m
    res = scenario.terrain.resolution_m
    if horizontal.is_geographic:
        deg = math.radians(1.0) * coords.WGS84_A
        mx = m / (deg * math.cos(math.radians(lat0)))
        bounds = (lon_a.min() - mx, lat_a.min() - m / deg, lon_a.max() + mx, lat_a.max() + m / deg)
        return Grid.from_bounds(bounds, res / deg, horizontal)
    x, y = coords.transformer("EPSG:4326", horizontal).transform(lon_a, lat_a)
    x, y = np.asarray(x), np.asarray(y)
    w = math.floor((x.min() - m) / res) * res
    s = math.floor((y.min() - m) / res) * res
    e = math.ceil((x.max() + m) / res) * res
    n = math.ceil((y.max() + m) / res) * res
    return Grid.from_bounds((w, s, e, n), res, horizontal)


def true_terrain(scenario: Scenario, grid: Grid) -> Terrain:
    """The true terrain on ``grid``: :func:`~geoblock.simulate.terrain.ridged_terrain` or
    :func:`~geoblock.simulate.terrain.fractal_terrain` as ``scenario.terrain`` says."""
    t = scenario.terrain
    options: dict[str, Any] = {"max_slope_deg": t.max_slope_deg,
                               "seed": derived_seed(scenario.seed, 2), "vertical": t.vertical}
    if t.hurst is not None:
        options["hurst"] = t.hurst
    make = ridged_terrain if t.kind == "ridged" else fractal_terrain
    return make(grid, t.relief, **options)


def scene_dem(scenario: Scenario, truth: Terrain, index: int) -> Terrain:
    """The measured DEM ``scenario.dems[index]`` derived from the true terrain
    (:func:`~geoblock.simulate.terrain.measured_dem`: its spacing and RMSEz)."""
    d = scenario.dems[index]
    return measured_dem(truth, d.spacing_m, d.rmse_z,
                        seed=derived_seed(scenario.seed, 3, index))


def scene_points(scenario: Scenario, sensors: Mapping[str, SimulatedSensor],
                 dem: Any) -> PointSet:
    """GCPs, ICPs, TPs and ICTPs of the scenario (:func:`simulate_points` with
    ``scenario.points``) through the TRUE models on the true terrain ``dem`` (a
    :class:`~geoblock.dem.DemSource`, e.g. ``truth.to_dem()``)."""
    p = scenario.points
    return simulate_points(
        {i: s.true_model for i, s in sensors.items()}, dem,
        gcp=p.gcp, icp=p.icp, design=p.design, cells=p.cells, tp=p.tp, ictp=p.ictp,
        sigma_px=p.sigma_px, sigma_e=p.sigma_e, sigma_n=p.sigma_n, sigma_h=p.sigma_h,
        blunder_fraction=p.blunder_fraction, blunder_px=p.blunder_px,
        ground_blunder_fraction=p.ground_blunder_fraction, ground_blunder_m=p.ground_blunder_m,
        margin_px=p.margin_px, seed=derived_seed(scenario.seed, 4),
    )


@dataclass(frozen=True)
class ContrastedTexture:
    """A texture with its contrast around mid-grey scaled by ``contrast`` (in [0, 1]), so
    that the relief's shading shows through the fields.

    Attributes
    ----------
    texture : Texture
    contrast : float
    """

    texture: Texture
    contrast: float

    def __call__(self, lon: np.ndarray, lat: np.ndarray) -> np.ndarray:
        return 0.5 + self.contrast * (np.asarray(self.texture(lon, lat), float) - 0.5)


def scene_texture(scenario: Scenario, sensors: Mapping[str, SimulatedSensor]) -> Texture:
    """One procedural texture for every image (so that orthos of the block agree), centred
    on the images, its features scaled to their mean GSD times ``render.texture_scale_px``,
    with ``render.texture_contrast``."""
    sims = list(sensors.values())
    lon = float(np.mean([s.spec.centre_lon for s in sims]))
    lat = float(np.mean([s.spec.centre_lat for s in sims]))
    gsd = float(np.mean([s.spec.gsd_m for s in sims])) * scenario.render.texture_scale_px
    # the defaults (150 m fields, 8 m roads 800 m apart, rivers 3 km apart) suit a 2.5 m GSD
    k = gsd / 2.5
    base = ProceduralTexture((lon, lat), derived_seed(scenario.seed, 5) % (1 << 31),
                             field_size_m=150.0 * k, road_spacing_m=800.0 * k,
                             road_width_m=8.0 * k, river_spacing_m=3000.0 * k,
                             river_width_m=25.0 * k)
    return ContrastedTexture(base, scenario.render.texture_contrast)


def scene_image(scenario: Scenario, sensors: Mapping[str, SimulatedSensor], image_id: str,
                dem: Any, texture: Texture) -> RenderedImage:
    """The raw image ``image_id`` rendered through its TRUE model on the true terrain ``dem``
    (:func:`~geoblock.simulate.render.render_image` with ``scenario.render``'s type and
    noise); ``render.max_pixels`` is the caller's to apply."""
    index = list(sensors).index(image_id)
    return render_image(sensors[image_id].true_model, dem, texture=texture,
                        dtype=scenario.render.dtype, noise_dn=scenario.render.noise_dn,
                        seed=derived_seed(scenario.seed, 6, index))
