"""Large simulated blocks: strips x scenes of a SPOT-like sensor over a continental area.

:class:`LargeBlockSpec` describes a block of ``strips x scenes`` images laid out as a
satellite acquires them: each strip one pass of a near-polar, sun-synchronous orbit, its
scenes consecutive along the track with an along-track overlap, neighbouring strips
overlapping by ``side_overlap`` of a swath. :func:`large_block` builds it with points only
(no rendering): the true and on-board model of every image
(:func:`~geoblock.simulate.sensors.simulate_sensor`, realistic on-board errors), a true
terrain and a coarse measured DEM on a longitude/latitude grid, and ``tps`` tie points,
``gcps`` GCPs, ``icps`` ICPs and ``ictps`` ICTPs for the whole block, measured in every image
that sees them (:class:`~geoblock.simulate.points.PointSet`). :meth:`LargeBlock.block` gives
the :class:`geoblock.adjust.Block` to adjust.

It scales to 10^4 images and 10^6-10^7 points: points are drawn on the ground, not in
images (no ray tracing), each one tested only against the images of the 3 x 3 neighbourhood
of its strip and scene (a point-in-footprint test, then a projection through the true
model), so that the cost is linear in the number of points; the one loop over images builds
the sensors (~20 ms each) and projects each image's candidates at once.

**Curvature.** The layout is computed on the ellipsoid, in an oblique Mercator projection
whose central line follows the ground track of the block's central strip (``+proj=omerc``,
scale error under 1 % within 1000 km of the line, 6 % at 2250 km): strips are lines of
constant distance across that track, scenes steps of constant distance along it. Every image
gets its own orbit, through its scene centre with the scene's incidence (so scenes are
rotated by the convergence of ground tracks, a few degrees at 1000 km; the overlaps stay
as asked within a few per cent). The terrain and the DEM are longitude/latitude grids
(EPSG:4326), valid at any extent; the block engine works in a Cartesian local frame (ECEF
rotated to the block's centre) with exact conversions, so a 5000 km block is no
approximation, only its "up" axis tilts from the local vertical far from the centre.

**Not simulated** (for speed; say so when it matters): hidden points (the terrain is a
smooth 1-2 km grid, the incidences small); per-pair TP counts (TPs are uniform over the
area seen by two images or more: a pair's share is its overlap's area).
"""

from __future__ import annotations

import dataclasses
import math
import os
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pyproj

from geoblock import coords
from geoblock.errors import GeoblockError
from geoblock.pixels import image_domain
from geoblock.simulate.points import (
    PointSet,
    SimulatedGround,
    SimulatedMeasurements,
    point_ids,
    pointing_noise,
    survey_noise,
)
from geoblock.simulate.sensors import SPOT_HRG20, OrbitSensorSpec, SimulatedSensor, simulate_sensor
from geoblock.simulate.terrain import Grid, Terrain, fractal_terrain, measured_dem
from geoblock.typing import GroundCoords, Status

__all__ = [
    "LARGE_PRESETS",
    "LargeBlock",
    "LargeBlockSpec",
    "Layout",
    "large_block",
    "large_preset",
    "layout",
]

_DEG_M = math.radians(1.0) * coords.WGS84_A


@dataclass(frozen=True)
class LargeBlockSpec:
    """A block of ``strips x scenes`` images of one sensor (module docstring).

    Parameters
    ----------
    name : str
    strips, scenes : int
        Strips across track, scenes per strip along track.
    tps : int
        Tie points in the whole block, each seen by two images or more.
    gcps, icps, ictps : int
        GCPs, ICPs and ICTPs in the whole block, uniform over the area the images see (GCPs
        and ICPs seen by one image or more, ICTPs by two or more).
    sensor : OrbitSensorSpec
        The sensor of every image (orbit, GSD, image shape, on-board error budget); its
        centre, incidence, epoch, name and seed are set per image.
    centre_lon, centre_lat : float
        Centre of the block, degrees.
    side_overlap : float
        Fraction of the swath shared by neighbouring strips, in [0, 0.9].
    along_overlap : float
        Fraction of a scene's length shared by consecutive scenes of a strip, in [0, 0.9].
    incidence_deg : float
        Each strip's incidence is drawn uniformly in ``[-incidence_deg, incidence_deg]``.
    relief : (float, float)
        Lowest and highest true terrain height, metres above the ellipsoid.
    terrain_spacing_m : float
        Post spacing of the true terrain (fractal, Hurst 0.8), metres.
    dem_spacing_m, dem_rmse_z : float
        The measured DEM given to the adjustment: spacing and RMSEz against the truth, metres.
    sigma_px : float
        Pointing noise of every measurement, pixels.
    sigma_ground_m : float
        Survey noise of the GCPs and ICPs, metres, east, north and up.
    margin_px : float
        Measurements at least this far inside the image edges, pixels.
    method : str
        Adjustment method of :meth:`LargeBlock.block` (:data:`geoblock.adjust.methods.METHODS`).
    seed : int
        Every draw derives from it.
    description : str
    """

    name: str
    strips: int
    scenes: int
    tps: int
    gcps: int = 100
    icps: int = 200
    ictps: int = 0
    sensor: OrbitSensorSpec = SPOT_HRG20
    centre_lon: float = 2.5
    centre_lat: float = 46.5
    side_overlap: float = 0.25
    along_overlap: float = 0.10
    incidence_deg: float = 5.0
    relief: tuple[float, float] = (0.0, 2500.0)
    terrain_spacing_m: float = 1000.0
    dem_spacing_m: float = 2000.0
    dem_rmse_z: float = 10.0
    sigma_px: float = 0.3
    sigma_ground_m: float = 1.0
    margin_px: float = 10.0
    method: str = "dg"
    seed: int = 0
    description: str = ""

    def __post_init__(self) -> None:
        def need(ok: bool, name: str, rule: str) -> None:
            if not ok:
                raise GeoblockError(f"LargeBlockSpec.{name}: {rule} (got "
                                    f"{getattr(self, name)!r})")

        need(self.strips >= 1 and self.scenes >= 1, "strips", "strips and scenes must be >= 1")
        need(self.strips * self.scenes >= 2, "scenes", "a block needs two images or more")
        for name in ("tps", "gcps", "icps", "ictps"):
            need(isinstance(getattr(self, name), int) and getattr(self, name) >= 0, name,
                 "must be an integer >= 0")
        need(0.0 <= self.side_overlap <= 0.9, "side_overlap", "must be in [0, 0.9]")
        need(0.0 <= self.along_overlap <= 0.9, "along_overlap", "must be in [0, 0.9]")
        need(self.strips == 1 or self.side_overlap > 0 or self.scenes > 1, "side_overlap",
             "the images must overlap")
        need(0.0 <= self.incidence_deg < 30.0, "incidence_deg", "must be in [0, 30)")
        need(self.relief[1] > self.relief[0], "relief", "high must be > low")
        for name in ("terrain_spacing_m", "dem_spacing_m", "sigma_px", "sigma_ground_m"):
            need(math.isfinite(getattr(self, name)) and getattr(self, name) > 0, name,
                 "must be a finite number > 0")
        need(self.dem_rmse_z >= 0, "dem_rmse_z", "must be >= 0")
        from geoblock.adjust.methods import METHODS

        need(self.method in METHODS, "method", f"must be one of {', '.join(METHODS)}")

    @property
    def images(self) -> int:
        """Number of images, ``strips * scenes``."""
        return self.strips * self.scenes

    def replace(self, **changes: Any) -> LargeBlockSpec:
        """A copy with some fields changed (``dataclasses.replace``)."""
        return dataclasses.replace(self, **changes)


# ================================================================================ presets
def _presets() -> dict[str, LargeBlockSpec]:
    return {
        "continental-spot-1000": LargeBlockSpec(
            name="continental-spot-1000", strips=20, scenes=50, tps=1_000_000, gcps=250,
            icps=500, ictps=2000, seed=29,
            description="20 strips x 50 scenes of a SPOT-like 20 m sensor (60 x 60 km scenes, "
                        "25 % side and 10 % along-track overlap) over 900 x 2700 km of France "
                        "and beyond, 10^6 TPs, 250 GCPs, 500 ICPs, 2000 ICTPs, a 2 km DEM"),
        "continental-spot-10000": LargeBlockSpec(
            name="continental-spot-10000", strips=100, scenes=100, tps=2_000_000, gcps=500,
            icps=1000, ictps=5000, centre_lat=45.0, centre_lon=15.0, seed=2929,
            dem_spacing_m=5000.0, terrain_spacing_m=2500.0,
            description="100 strips x 100 scenes of a SPOT-like 20 m sensor (60 x 60 km "
                        "scenes, 25 % side and 10 % along-track overlap) over 4500 x 5400 km "
                        "of Europe, 2 x 10^6 TPs, 500 GCPs (as IGN for 20000 SPOT-5 images), "
                        "1000 ICPs, 5000 ICTPs, a 5 km DEM"),
    }


#: Points-only large presets (:func:`large_preset`): name -> spec.
LARGE_PRESETS: Mapping[str, LargeBlockSpec] = _presets()


def large_preset(name: str, *, tps: int | None = None, images: int | None = None,
                 seed: int | None = None) -> LargeBlockSpec:
    """A spec of :data:`LARGE_PRESETS`, optionally with another TP count, size or seed.

    Parameters
    ----------
    name : str
    tps : int, optional
        Tie points in the whole block (default the preset's).
    images : int, optional
        About this many images instead (strips and scenes scaled by the same factor, at least
        2 x 2), e.g. 100, 300, 3000 for a scaling study; the relief is scaled by the block's
        side to the power 0.8 (the terrain's Hurst exponent), so that the terrain is as rough
        per kilometre and the DEM's RMSEz holds.
    seed : int, optional

    Raises
    ------
    GeoblockError
        Unknown preset (the message lists the known ones).
    """
    if name not in LARGE_PRESETS:
        raise GeoblockError(f"unknown large-block preset {name!r}; known: "
                            f"{', '.join(LARGE_PRESETS)}")
    spec = LARGE_PRESETS[name]
    changes: dict[str, Any] = {}
    if images is not None:
        if images < 4:
            raise GeoblockError(f"large_preset: images must be >= 4, got {images}")
        f = math.sqrt(images / spec.images)
        strips = max(2, round(spec.strips * f))
        scenes = max(2, round(images / strips))
        # the fractal terrain spans its relief over the whole block: scaled with the block's
        # side to the power of its Hurst exponent (0.8), it keeps the same roughness per
        # kilometre whatever the block's size
        k = math.sqrt(strips * scenes / spec.images) ** 0.8
        lo, hi = spec.relief
        changes.update(strips=strips, scenes=scenes, name=f"{spec.name}-{images}",
                       relief=(lo * k, hi * k))
    if tps is not None:
        changes["tps"] = int(tps)
    if images is not None or tps is not None:
        changes["description"] = (
            f"{spec.description}; scaled to {changes.get('strips', spec.strips)} strips x "
            f"{changes.get('scenes', spec.scenes)} scenes, {changes.get('tps', spec.tps)} TPs")
    if seed is not None:
        changes["seed"] = int(seed)
    return spec.replace(**changes) if changes else spec


# ================================================================================ layout
@dataclass(frozen=True, eq=False)
class Layout:
    """Where each image of a :class:`LargeBlockSpec` looks.

    Attributes
    ----------
    ids : ndarray of str, (N,)
        ``s{strip:03d}k{scene:03d}``, strip-major.
    strip, scene : ndarray of int, (N,)
    lon, lat : ndarray, (N,)
        Scene centres, degrees.
    incidence_deg : ndarray, (N,)
        Signed incidence of each scene (one per strip).
    epoch : list of str
        ISO-8601 UTC time of each scene centre (a strip's scenes follow each other on its
        pass; strips are a day apart).
    projection : str
        The oblique Mercator (PROJ string) whose ``x`` is across and ``y`` along the track.
    step_across_m, step_along_m : float
        Distance between neighbouring strips and scenes, metres.
    """

    ids: np.ndarray
    strip: np.ndarray
    scene: np.ndarray
    lon: np.ndarray
    lat: np.ndarray
    incidence_deg: np.ndarray
    epoch: list[str]
    projection: str
    step_across_m: float
    step_along_m: float

    def specs(self, spec: LargeBlockSpec) -> list[OrbitSensorSpec]:
        """The sensor spec of every image (seeded from ``spec.seed`` and the image index)."""
        ss = np.random.SeedSequence([spec.seed & 0xFFFFFFFF, 1]).spawn(len(self.ids))
        return [spec.sensor.replace(
            name=str(self.ids[i]), centre_lon=float(self.lon[i]), centre_lat=float(self.lat[i]),
            incidence_deg=float(self.incidence_deg[i]), epoch=self.epoch[i],
            seed=int(ss[i].generate_state(1)[0]))
            for i in range(len(self.ids))]


def _track_azimuth(sensor: OrbitSensorSpec, lon: float, lat: float) -> float:
    """Azimuth of the flight direction (degrees from north) of ``sensor`` over (lon, lat)."""
    model = simulate_sensor(sensor.replace(centre_lon=lon, centre_lat=lat, incidence_deg=0.0,
                                           onboard_errors="bias-drift",
                                           onboard_rmse_m=0.0)).true_model
    rows, cols = model.shape
    rc, cc = (rows - 1) / 2.0, (cols - 1) / 2.0
    dt = model.line_times.line_period_s  # seconds per row, signed
    step = 0.25 * rows * (1.0 if dt > 0 else -1.0)  # later in time
    g = model.backproject(np.array([rc - step, rc + step]), np.array([cc, cc]),
                          np.array([0.0, 0.0]))
    az, _, _ = pyproj.Geod(ellps="WGS84").inv(g.lon[0], g.lat[0], g.lon[1], g.lat[1])
    return float(az)


def _epoch_plus(epoch: str, seconds: float) -> str:
    t = np.datetime64(epoch.rstrip("Z"), "ns") + np.timedelta64(int(round(seconds * 1e9)), "ns")
    return str(np.datetime_as_string(t, unit="ms")) + "Z"


def layout(spec: LargeBlockSpec) -> Layout:
    """The scene centres, incidences and epochs of a block (module docstring: curvature).

    Raises
    ------
    GeoblockError
        The block reaches latitudes the orbit does not fly over.
    """
    sensor = spec.sensor
    az = _track_azimuth(sensor, spec.centre_lon, spec.centre_lat)
    alpha = (az + 90.0) % 180.0 - 90.0  # the track's line, in [-90, 90)
    forward = 1.0 if math.cos(math.radians(az - alpha)) > 0 else -1.0  # flight along +y?
    proj = (f"+proj=omerc +lonc={spec.centre_lon!r} +lat_0={spec.centre_lat!r} "
            f"+alpha={alpha!r} +gamma=0 +k_0=1 +x_0=0 +y_0=0 +ellps=WGS84 +units=m +no_defs")
    rows, cols = sensor.shape
    length, swath = rows * sensor.gsd_m, cols * sensor.gsd_m
    step_x = swath * (1.0 - spec.side_overlap)
    step_y = length * (1.0 - spec.along_overlap)
    s_grid, k_grid = np.meshgrid(np.arange(spec.strips), np.arange(spec.scenes), indexing="ij")
    s, k = s_grid.ravel(), k_grid.ravel()
    x = (s - (spec.strips - 1) / 2.0) * step_x
    y = forward * (k - (spec.scenes - 1) / 2.0) * step_y  # scene k after scene k - 1
    lon, lat = pyproj.Proj(proj)(x, y, inverse=True)
    lon, lat = np.asarray(lon, float), np.asarray(lat, float)
    lim = min(sensor.inclination_deg, 180.0 - sensor.inclination_deg) - 1.0
    if not np.all(np.abs(lat) < lim):
        raise GeoblockError(f"large block {spec.name}: its scenes reach latitude "
                            f"{float(np.max(np.abs(lat))):.1f}, beyond the {lim:.1f} deg the "
                            f"{sensor.inclination_deg} deg orbit flies over; move centre_lat "
                            "toward the equator or use fewer scenes")
    rng = np.random.default_rng(np.random.SeedSequence([spec.seed & 0xFFFFFFFF, 7]))
    inc = rng.uniform(-spec.incidence_deg, spec.incidence_deg, spec.strips)[s]
    speed = sensor.ground_speed_m_s
    epoch = [_epoch_plus(sensor.epoch, 86400.0 * float(si) + (float(ki) - (spec.scenes - 1) / 2.0)
                         * step_y / speed) for si, ki in zip(s.tolist(), k.tolist(), strict=True)]
    ids = np.array([f"s{a:03d}k{b:03d}" for a, b in zip(s.tolist(), k.tolist(), strict=True)])
    return Layout(ids, s, k, lon, lat, inc, epoch, proj, step_x, step_y)


# ================================================================================ block
@dataclass(frozen=True, eq=False)
class LargeBlock:
    """A large simulated block (:func:`large_block`).

    Attributes
    ----------
    spec : LargeBlockSpec
    layout : Layout
    sensors : dict of str to SimulatedSensor
        True and on-board model by image id, strip-major.
    truth : Terrain
        The true terrain (heights above the ellipsoid), EPSG:4326.
    dem : Terrain
        The measured DEM (``spec.dem_spacing_m``, RMSEz ``spec.dem_rmse_z``).
    points : PointSet
        GCPs, ICPs, TPs and ICTPs with their truth and their measurements.
    timings : dict of str to float
        Seconds per stage (sensors, terrain, points).
    """

    spec: LargeBlockSpec
    layout: Layout
    sensors: dict[str, SimulatedSensor]
    truth: Terrain
    dem: Terrain
    points: PointSet
    timings: dict[str, float] = field(default_factory=dict)

    def onboard_models(self, method: str | None = None) -> dict[str, Any]:
        """The on-board models prepared for ``method`` (default ``spec.method``): each with
        the method's parameter set or image-space correction
        (:func:`geoblock.adjust.methods.prepare_model`)."""
        from geoblock.adjust.methods import METHODS, prepare_model

        m = METHODS[method or self.spec.method]
        return {i: prepare_model(s.onboard_model, parameters=m["parameters"],
                                 correction=m["correction"], where=f"image {i}")
                for i, s in self.sensors.items()}

    def block(self, method: str | None = None) -> Any:
        """The :class:`geoblock.adjust.Block` to adjust: on-board models (``method``), every
        measurement, the surveyed GCPs and ICPs, the measured DEM with its RMSEz as sigma."""
        from geoblock.adjust.problem import Block

        ground, image = self.points.observations()
        return Block(self.onboard_models(method), image, ground, self.dem.to_dem(),
                     max(self.spec.dem_rmse_z, 0.1))

    def write(self, directory: str | os.PathLike[str], *, true_models: bool = False,
              progress: Any = None) -> dict[str, Path]:
        """Write the block as ``geoblock simulate`` writes a scenario, without images or
        report: ``block.toml`` (on-board models, the spec's method, the DEM with its RMSEz
        as sigma), ``images/<id>_onboard.json`` (and ``<id>_true.json`` with
        ``true_models``: ~0.45 MB each for 3000 columns), ``terrain/truth.tif``,
        ``terrain/dem.tif``, ``points/ground.csv``, ``points/image.csv``,
        ``points/truth.csv``.

        Returns
        -------
        dict of str to pathlib.Path
            ``block``, ``truth``, ``dem``, ``points:ground``... and
            ``onboard_model:<id>`` per image.

        Raises
        ------
        GeoblockIOError
            A file cannot be written (names it).
        """
        from geoblock.io import BlockDem, BlockImage, write_block, write_model
        from geoblock.io.blocks import Block as BlockFile
        from geoblock.io.files import make_directory

        say = progress or (lambda message: None)
        out = Path(directory)
        for sub in ("terrain", "images", "points"):
            make_directory(out / sub)
        files: dict[str, Path] = {
            "truth": self.truth.write(out / "terrain" / "truth.tif"),
            "dem": self.dem.write(out / "terrain" / "dem.tif")}
        say(f"writing {len(self.sensors)} on-board models")
        for image_id, sim in self.sensors.items():
            files[f"onboard_model:{image_id}"] = write_model(
                sim.onboard_model, out / "images" / f"{image_id}_onboard.json")
            if true_models:
                files[f"true_model:{image_id}"] = write_model(
                    sim.true_model, out / "images" / f"{image_id}_true.json")
        say(f"writing {len(self.points.image)} measurements")
        for key, path in self.points.write(out / "points").items():
            files[f"points:{key}"] = path
        block = BlockFile(
            images=tuple(BlockImage(i, files[f"onboard_model:{i}"], None)
                         for i in self.sensors),
            method=self.spec.method, ground_points=files["points:ground"],
            image_points=files["points:image"], truth=files["points:truth"],
            dem=BlockDem(str(files["dem"]), sigma=self.spec.dem_rmse_z or None),
            name=self.spec.name,
            outputs={"directory": out / "adjusted", "report": out / "adjusted" / "report.md"})
        files["block"] = write_block(out / "block.toml", block)
        return files


def _footprints(models: list[Any], proj: pyproj.Proj, h: float) -> np.ndarray:
    """(N, 4, 2) image corners (outer pixel edges) at height ``h`` in the layout's x, y,
    counter-clockwise or clockwise consistently per image."""
    out = np.empty((len(models), 4, 2))
    for i, m in enumerate(models):
        r0, c0, r1, c1 = image_domain(m.shape)
        g = m.backproject(np.array([r0, r0, r1, r1]), np.array([c0, c1, c1, c0]), np.full(4, h))
        x, y = proj(np.asarray(g.lon), np.asarray(g.lat))
        out[i, :, 0], out[i, :, 1] = x, y
    return out


def _inside_quads(x: np.ndarray, y: np.ndarray, quads: np.ndarray, pad: float) -> np.ndarray:
    """Whether each point (P,) is inside its quad (P, 4, 2), grown by ``pad`` metres."""
    inside = np.ones(x.shape, bool)
    # orientation of each quad (signed area), so that "inside" is the same side of each edge
    qx, qy = quads[..., 0], quads[..., 1]
    area = 0.5 * np.sum(qx * np.roll(qy, -1, -1) - np.roll(qx, -1, -1) * qy, axis=-1)
    sign = np.sign(area)
    for e in range(4):
        ax, ay = qx[..., e], qy[..., e]
        bx, by = qx[..., (e + 1) % 4], qy[..., (e + 1) % 4]
        ex, ey = bx - ax, by - ay
        norm = np.hypot(ex, ey)
        cross = (ex * (y - ay) - ey * (x - ax)) * sign / norm  # distance inside the edge
        inside &= cross > -pad
    return inside


class _Measured:
    """The candidate measurements of a batch of ground points in the images near them."""

    def __init__(self, point: np.ndarray, image: np.ndarray, row: np.ndarray,
                 col: np.ndarray) -> None:
        self.point, self.image, self.row, self.col = point, image, row, col


def _measure(x: np.ndarray, y: np.ndarray, lon: np.ndarray, lat: np.ndarray, h: np.ndarray,
             lay: Layout, spec: LargeBlockSpec, quads: np.ndarray, models: list[Any],
             pad: float) -> _Measured:
    """Every image of the 3 x 3 neighbourhood of each point that sees it: its index, the
    image index, the true row and col (inside the image by ``spec.margin_px``)."""
    s0 = np.rint(x / lay.step_across_m + (spec.strips - 1) / 2.0).astype(np.int64)
    k_sign = _scene_sign(lay, spec)
    k0 = np.rint(k_sign * y / lay.step_along_m + (spec.scenes - 1) / 2.0).astype(np.int64)
    pts, imgs = [], []
    for ds in (-1, 0, 1):
        for dk in (-1, 0, 1):
            s, k = s0 + ds, k0 + dk
            ok = (s >= 0) & (s < spec.strips) & (k >= 0) & (k < spec.scenes)
            idx = np.flatnonzero(ok)
            img = s[idx] * spec.scenes + k[idx]
            near = _inside_quads(x[idx], y[idx], quads[img], pad)
            pts.append(idx[near])
            imgs.append(img[near])
    point = np.concatenate(pts) if pts else np.zeros(0, np.int64)
    image = np.concatenate(imgs) if imgs else np.zeros(0, np.int64)
    order = np.lexsort((point, image))  # by image, then point
    point, image = point[order], image[order]
    row = np.full(point.size, np.nan)
    col = np.full(point.size, np.nan)
    bounds = np.searchsorted(image, np.arange(len(models) + 1))
    for i in np.flatnonzero(np.diff(bounds)):
        a, b = bounds[i], bounds[i + 1]
        j = point[a:b]
        (r, c), status = models[i].project_with_status(lon[j], lat[j], h[j])
        r0, c0, r1, c1 = image_domain(models[i].shape)
        m = spec.margin_px
        good = ((status == Status.CONVERGED) & (r >= r0 + m) & (r < r1 - m) & (c >= c0 + m)
                & (c < c1 - m))
        row[a:b] = np.where(good, r, np.nan)
        col[a:b] = np.where(good, c, np.nan)
    keep = np.isfinite(row)
    return _Measured(point[keep], image[keep], row[keep], col[keep])


def _scene_sign(lay: Layout, spec: LargeBlockSpec) -> float:
    """+1 when scene k lies at +y of scene k - 1 in the layout's projection, else -1."""
    if spec.scenes < 2:
        return 1.0
    x, y = pyproj.Proj(lay.projection)(lay.lon[:2], lay.lat[:2])
    return 1.0 if y[1] > y[0] else -1.0


def _draw(rng: np.random.Generator, count: int, min_images: int, lay: Layout,
          spec: LargeBlockSpec, quads: np.ndarray, models: list[Any], proj: pyproj.Proj,
          height: Any, pad: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, _Measured]:
    """``count`` ground points uniform over the area seen by ``min_images`` images or more,
    drawn in batches over the layout's rectangle: lon, lat, h and their measurements."""
    x_half = 0.5 * (spec.strips - 1) * lay.step_across_m + 0.6 * spec.sensor.shape[1] \
        * spec.sensor.gsd_m
    y_half = 0.5 * (spec.scenes - 1) * lay.step_along_m + 0.6 * spec.sensor.shape[0] \
        * spec.sensor.gsd_m
    got: list[tuple[np.ndarray, ...]] = []
    total = 0
    rate = 0.3  # first guess of the share of the rectangle seen by min_images images
    tries = 0
    while total < count:
        tries += 1
        if tries > 50:
            raise GeoblockError(f"large block {spec.name}: cannot place {count} points seen "
                                f"by {min_images} images or more (the images barely overlap?)")
        want = count - total
        n = int(min(max(1.3 * want / rate, 1000), 1_000_000))  # bounded memory per batch
        x = rng.uniform(-x_half, x_half, n)
        y = rng.uniform(-y_half, y_half, n)
        lon, lat = proj(x, y, inverse=True)
        lon, lat = np.asarray(lon, float), np.asarray(lat, float)
        h = np.asarray(height(lon, lat), float)
        ok = np.isfinite(h)
        meas = _measure(x, y, lon, lat, h, lay, spec, quads, models, pad)
        seen = np.bincount(meas.point, minlength=n)
        keep = np.flatnonzero(ok & (seen >= min_images))
        rate = max(keep.size / n, 1e-3)
        keep = keep[:want]
        new = np.full(n, -1)
        new[keep] = np.arange(keep.size) + total
        sel = new[meas.point] >= 0
        got.append((lon[keep], lat[keep], h[keep], new[meas.point[sel]], meas.image[sel],
                    meas.row[sel], meas.col[sel]))
        total += keep.size
    parts = [np.concatenate([g[k] for g in got]) for k in range(7)]
    return parts[0], parts[1], parts[2], _Measured(parts[3], parts[4], parts[5], parts[6])


def large_block(spec: LargeBlockSpec | str, *, progress: Any = None) -> LargeBlock:
    """Build a large block with points only (module docstring).

    Parameters
    ----------
    spec : LargeBlockSpec or str
        A spec, or the name of one of :data:`LARGE_PRESETS`.
    progress : callable, optional
        Called with a one-line message at each stage.

    Returns
    -------
    LargeBlock

    Raises
    ------
    GeoblockError
        Invalid spec, a layout beyond the orbit's latitudes, or points that cannot be placed.
    """
    if isinstance(spec, str):
        spec = large_preset(spec)
    say = progress or (lambda message: None)
    timings: dict[str, float] = {}
    t0 = time.perf_counter()
    lay = layout(spec)
    say(f"{spec.name}: {spec.images} images ({spec.strips} strips x {spec.scenes} scenes)")
    sensors = {str(sp.name): simulate_sensor(sp) for sp in lay.specs(spec)}
    timings["sensors"] = time.perf_counter() - t0
    say(f"  sensors: {timings['sensors']:.1f} s")

    t1 = time.perf_counter()
    true_models = [s.true_model for s in sensors.values()]
    proj = pyproj.Proj(lay.projection)
    lo, hi = spec.relief
    quads = _footprints(true_models, proj, 0.5 * (lo + hi))
    # the terrain: a lon/lat grid over every footprint at the lowest and highest heights
    corners = np.concatenate([_footprints(true_models, proj, v).reshape(-1, 2)
                              for v in (lo, hi)])
    clon, clat = proj(corners[:, 0], corners[:, 1], inverse=True)
    margin = 5.0 * spec.dem_spacing_m / _DEG_M
    lat_max = float(np.max(np.abs(clat)))
    mlon = margin / max(math.cos(math.radians(min(lat_max + margin, 89.0))), 0.05)
    res = spec.terrain_spacing_m / _DEG_M
    grid = Grid.from_bounds((float(np.min(clon)) - mlon, float(np.min(clat)) - margin,
                             float(np.max(clon)) + mlon, float(np.max(clat)) + margin), res,
                            "EPSG:4326")
    ss = np.random.SeedSequence([spec.seed & 0xFFFFFFFF, 2])
    s_terrain, s_dem, s_points = (int(v) for v in ss.generate_state(3))
    truth = fractal_terrain(grid, spec.relief, hurst=0.8, seed=s_terrain)
    dem = measured_dem(truth, spec.dem_spacing_m, spec.dem_rmse_z, seed=s_dem)
    timings["terrain"] = time.perf_counter() - t1
    say(f"  terrain {truth.shape[0]} x {truth.shape[1]} posts, DEM {dem.shape[0]} x "
        f"{dem.shape[1]}: {timings['terrain']:.1f} s")

    t2 = time.perf_counter()
    true_dem = truth.to_dem()

    def height(lon: np.ndarray, lat: np.ndarray) -> np.ndarray:
        return np.asarray(true_dem.height(lon, lat), float)

    rng = np.random.default_rng(s_points)
    # footprints at the mean height, grown by the relief's parallax and a margin
    tan_max = math.tan(math.radians(spec.incidence_deg + 5.0))
    pad = (hi - lo) * tan_max + 2.0 * spec.sensor.gsd_m * spec.margin_px
    kind_names: list[str] = []
    parts: list[tuple[np.ndarray, np.ndarray, np.ndarray, _Measured]] = []
    for kind_name, count, min_images in (("gcp", spec.gcps, 1), ("icp", spec.icps, 1),
                                    ("tp", spec.tps, 2), ("ictp", spec.ictps, 2)):
        if count:
            parts.append(_draw(rng, count, min_images, lay, spec, quads, true_models, proj,
                               height, pad))
            kind_names.append(kind_name)
    if not parts:
        raise GeoblockError(f"large block {spec.name}: no point requested")
    offsets = np.cumsum([0] + [p[0].size for p in parts])
    kind = np.concatenate([np.full(p[0].size, k) for k, p in zip(kind_names, parts, strict=True)])
    lon = np.concatenate([p[0] for p in parts])
    lat = np.concatenate([p[1] for p in parts])
    h = np.concatenate([p[2] for p in parts])
    m_point = np.concatenate([p[3].point + o for p, o in zip(parts, offsets, strict=False)])
    m_image = np.concatenate([p[3].image for p in parts])
    m_row = np.concatenate([p[3].row for p in parts])
    m_col = np.concatenate([p[3].col for p in parts])
    order = np.lexsort((m_image, m_point))
    m_point, m_image, m_row, m_col = (a[order] for a in (m_point, m_image, m_row, m_col))
    ids = point_ids(kind)
    row_m, col_m, blunder = pointing_noise(m_row, m_col, sigma_px=spec.sigma_px, rng=rng)
    surveyed = np.isin(kind, ("gcp", "icp"))
    sv = np.flatnonzero(surveyed)
    sg = spec.sigma_ground_m
    survey, g_blunder_sv = survey_noise(GroundCoords(lon[sv], lat[sv], h[sv]),
                                        sigma_e=sg, sigma_n=sg, sigma_h=sg, rng=rng)
    glon, glat, gh = (np.full(lon.size, np.nan) for _ in range(3))
    glon[sv], glat[sv], gh[sv] = survey.lon, survey.lat, survey.h
    sig = np.where(surveyed, sg, np.nan)
    ground = SimulatedGround(id=ids, kind=kind, lon_true=lon, lat_true=lat, h_true=h,
                             lon=glon, lat=glat, h=gh, sigma_e=sig, sigma_n=sig, sigma_h=sig,
                             blunder=np.zeros(lon.size, bool))
    names = lay.ids
    image = SimulatedMeasurements(
        id=ids[m_point], image=names[m_image], kind=kind[m_point], row_true=m_row,
        col_true=m_col, row=row_m, col=col_m, sigma=np.full(m_point.size, spec.sigma_px),
        blunder=blunder)
    points = PointSet(ground, image, tuple(names.tolist()))
    timings["points"] = time.perf_counter() - t2
    timings["total"] = time.perf_counter() - t0
    say(f"  points: {', '.join(f'{points.count(k)} {k.upper()}s' for k in kind_names)}, "
        f"{len(image)} measurements: {timings['points']:.1f} s")
    return LargeBlock(spec, lay, sensors, truth, dem, points, timings)
