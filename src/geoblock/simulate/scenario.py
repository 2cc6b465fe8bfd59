"""Scenarios: a whole simulated block (sensors, terrain, DEMs, points, images) in one value.

A :class:`Scenario` is a frozen description of a synthetic block, read from a TOML file
(:func:`read_scenario`) or taken from a named preset (:func:`preset`) that mimics one of the
papers' set-ups:

``teo2010-spot5``
    Teo et al. (2010): three SPOT-5 strips (2.5 m GSD, incidence 5.2, 5.7 and -14.8 deg,
    10-15 % overlaps) over 0-3800 m ridged terrain, a 40 m DEM, 9 GCPs per strip, 13-32 TPs
    per overlap, ICPs and ICTPs.
``aguilar2007-quickbird``
    Aguilar et al. (2007): one QuickBird basic scene (0.62 m GSD, 8 deg off nadir) over
    50-850 m rolling terrain, 45 GCPs stratified over a 3 x 3 grid, 79 ICPs, DEMs of 2 / 5 /
    20 m spacing with RMSEz 0.31 / 1.75 / 5.82 m.
``chen1993-spot1a``
    Chen & Lee (1993): one SPOT 1A scene (10 m, 6000 x 6000 px) over 950 m of relief, 21 GCPs
    and check points, a 40 m DTM.

Each comes in a ``small`` variant (images 10-40 times smaller with the same footprint, a
coarser true terrain: seconds) and a ``full`` variant (the papers' image sizes: a minute or
two; images larger than ``render.max_pixels`` are not rendered, which the output says).

:func:`run_scenario` simulates a scenario into a directory: true terrain and measured DEMs
(GeoTIFF), per image the true and the on-board model (JSON) and the raw image, the point
files with their truth, a block file for the adjustment engine, and a report of the
on-board models' accuracy (Markdown and CSV tables, PNG figures). Everything is
deterministic for the scenario's seed.
"""

from __future__ import annotations

import copy
import dataclasses
import json
import math
import os
import time
import tomllib
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from geoblock.errors import GeoblockError
from geoblock.simulate import sensors as _sensors
from geoblock.simulate.sensors import OrbitSensorSpec

__all__ = [
    "PRESETS",
    "SENSOR_PRESETS",
    "VARIANTS",
    "DemConfig",
    "ImageConfig",
    "PointsConfig",
    "RenderConfig",
    "ReportConfig",
    "Scenario",
    "ScenarioError",
    "ScenarioResult",
    "TerrainConfig",
    "load_scenario",
    "preset",
    "preset_dict",
    "read_scenario",
    "run_scenario",
    "scenario_from_dict",
    "scenario_to_dict",
]

VARIANTS = ("small", "full")
"""Variants of the named presets."""

#: Sensor presets an image can start from (``preset = "spot5-strip1"``), by name.
SENSOR_PRESETS: dict[str, OrbitSensorSpec] = {
    "spot5-strip1": _sensors.SPOT5_STRIPS[0],
    "spot5-strip2": _sensors.SPOT5_STRIPS[1],
    "spot5-strip3": _sensors.SPOT5_STRIPS[2],
    "quickbird": _sensors.QUICKBIRD,
    "spot1a": _sensors.SPOT1A,
}


class ScenarioError(GeoblockError, ValueError):
    """A scenario file or preset is invalid (the message names the file and the key)."""


# ================================================================================ values
@dataclass(frozen=True)
class ImageConfig:
    """One simulated image.

    Attributes
    ----------
    id : str
        Image name (file names, the ``image`` column of the point files).
    spec : OrbitSensorSpec
        The sensor, orbit and on-board error budget (its ``seed`` is derived from the
        scenario's seed unless the file gives one).
    preset : str
        The sensor preset it started from (``""``: none).
    scale : float
        The factor applied with :meth:`OrbitSensorSpec.scaled` (1: none).
    overrides : mapping
        The fields the file set on top of the preset (kept to write the scenario back).
    """

    id: str
    spec: OrbitSensorSpec
    preset: str = ""
    scale: float = 1.0
    overrides: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class TerrainConfig:
    """The true terrain.

    Attributes
    ----------
    kind : {"ridged", "fractal"}
        :func:`~geoblock.simulate.terrain.ridged_terrain` or
        :func:`~geoblock.simulate.terrain.fractal_terrain`.
    relief : (float, float)
        Lowest and highest height, metres above ``vertical``.
    resolution_m : float
        Post spacing of the true terrain, metres.
    max_slope_deg : float or None
        Steepest slope wanted (None: as generated).
    hurst : float or None
        Hurst exponent (None: the generator's default).
    vertical : {"ellipsoid", "geoid"}
        Datum of the heights (geoid: EGM96, needs the geoid grid).
    crs : str or None
        Horizontal CRS of the grids (None: the UTM zone of the scene).
    margin_m : float
        Terrain beyond the images' footprints, metres.
    """

    kind: str = "ridged"
    relief: tuple[float, float] = (0.0, 1000.0)
    resolution_m: float = 100.0
    max_slope_deg: float | None = None
    hurst: float | None = None
    vertical: str = "ellipsoid"
    crs: str | None = None
    margin_m: float = 3000.0


@dataclass(frozen=True)
class DemConfig:
    """A "measured" DEM derived from the truth (:func:`~geoblock.simulate.terrain.measured_dem`).

    Attributes
    ----------
    name : str
        File stem (``dem40`` -> ``terrain/dem40.tif``).
    spacing_m : float
        Post spacing, metres.
    rmse_z : float
        RMSE of the heights against the truth, metres.
    """

    name: str
    spacing_m: float
    rmse_z: float


@dataclass(frozen=True)
class PointsConfig:
    """Point counts, design and noise (the arguments of
    :func:`~geoblock.simulate.points.simulate_points`)."""

    gcp: int = 9
    icp: int = 0
    design: str = "stratified"
    cells: int = 3
    tp: tuple[int, int] = (0, 0)
    ictp: tuple[int, int] = (0, 0)
    sigma_px: float = 0.5
    sigma_e: float = 1.0
    sigma_n: float = 1.0
    sigma_h: float = 1.0
    blunder_fraction: float = 0.0
    blunder_px: float = 10.0
    ground_blunder_fraction: float = 0.0
    ground_blunder_m: float = 20.0
    margin_px: float = 10.0


@dataclass(frozen=True)
class RenderConfig:
    """Rendering of the raw images (:func:`~geoblock.simulate.render.render_image`).

    Attributes
    ----------
    enabled : bool
    dtype : {"uint8", "uint16"}
    noise_dn : float
        Gaussian sensor noise, digital numbers.
    max_pixels : int
        Images with more pixels are not rendered (a full-size render would take more than a
        few minutes); the run says so.
    texture_scale_px : float
        Scale of the procedural texture's features relative to the image GSD (1: fields of
        about 60 pixels, roads 320 pixels apart, whatever the GSD), so that small and full
        variants look alike.
    texture_contrast : float
        Contrast of the texture around mid-grey (1: the texture as is; 0.5 lets the relief's
        shading show).
    """

    enabled: bool = True
    dtype: str = "uint8"
    noise_dn: float = 0.0
    max_pixels: int = 20_000_000
    texture_scale_px: float = 1.0
    texture_contrast: float = 0.5


@dataclass(frozen=True)
class ReportConfig:
    """What the report shows besides the tables and the error-vector plots.

    Attributes
    ----------
    distance_plot : bool
        Residuals at the ICPs against the distance from the image centre (Aguilar et al.
        Fig. 4): of the on-board model, and after RPCV-0 and RPCV-1-style image-space
        corrections fitted to all the image's GCPs.
    gcp_study : bool
        ICP RMSE after RPCV-0 and RPCV-1-style corrections against the number of GCPs, ten
        random subsets per count (Aguilar et al. Figs. 3, 6, 7;
        :func:`geoblock.simulate.study.gcp_count_study`).
    """

    distance_plot: bool = False
    gcp_study: bool = False


@dataclass(frozen=True)
class Scenario:
    """A simulated block: what :func:`run_scenario` makes.

    Attributes
    ----------
    name : str
    description : str
    seed : int
        Every random draw (sensors, terrain, DEMs, points, textures) derives from it.
    images : tuple of ImageConfig
    terrain : TerrainConfig
    dems : tuple of DemConfig
        The first one is the block's DEM (orthos, ICTP ray tracing).
    points : PointsConfig
    render : RenderConfig
    report : ReportConfig
    method : str
        The adjustment method written to the block file (``dg``: the on-board linescan
        models' direct-georeferencing set; ``rpcv0``, ``rpcv1``: image-space corrections;
        see :mod:`geoblock.adjust.methods`).
    source : str
        Where the scenario came from (a file path or ``preset:NAME/VARIANT``).
    """

    name: str
    description: str
    seed: int
    images: tuple[ImageConfig, ...]
    terrain: TerrainConfig
    dems: tuple[DemConfig, ...]
    points: PointsConfig = PointsConfig()
    render: RenderConfig = RenderConfig()
    report: ReportConfig = ReportConfig()
    method: str = "dg"
    source: str = ""

    def replace(self, **changes: Any) -> Scenario:
        """A copy with some fields changed (``dataclasses.replace``)."""
        return dataclasses.replace(self, **changes)

    def with_seed(self, seed: int) -> Scenario:
        """The same scenario with another seed (every derived seed changes with it, except an
        image ``seed`` the file sets explicitly)."""
        data = scenario_to_dict(self)
        data["seed"] = int(seed)
        return scenario_from_dict(data, self.source)


# ================================================================================ parsing
_TOP_KEYS = ("name", "description", "seed", "method", "preset", "variant", "images", "terrain",
             "dems", "points", "render", "report")
_IMAGE_KEYS = ("id", "preset", "scale")
_SPEC_FIELDS = {f.name: f for f in dataclasses.fields(OrbitSensorSpec)}


class _Reader:
    """Typed access to a parsed TOML table, with errors naming the source and the key."""

    def __init__(self, source: str) -> None:
        self.source = source

    def error(self, key: str, message: str) -> ScenarioError:
        return ScenarioError(f"{self.source}: {key}: {message}")

    def table(self, data: Mapping[str, Any], key: str, where: str) -> dict[str, Any]:
        value = data.get(key, {})
        if not isinstance(value, Mapping):
            raise self.error(f"{where}{key}", f"must be a table, got {_tname(value)}")
        return dict(value)

    def known(self, data: Mapping[str, Any], allowed: Sequence[str], where: str) -> None:
        for key in data:
            if key not in allowed:
                raise self.error(f"{where}{key}", f"unknown key; allowed: {', '.join(allowed)}")

    def number(self, data: Mapping[str, Any], key: str, where: str, default: Any = None, *,
               integer: bool = False, low: float | None = None, high: float | None = None,
               strict_low: bool = False, optional: bool = False) -> Any:
        if key not in data:
            if default is None and not optional:
                raise self.error(f"{where}{key}", "required key missing")
            return default
        value = data[key]
        ok_types = (int,) if integer else (int, float)
        if isinstance(value, bool) or not isinstance(value, ok_types):
            want = "an integer" if integer else "a number"
            raise self.error(f"{where}{key}", f"must be {want}, got {_tname(value)} {value!r}")
        if not math.isfinite(value):
            raise self.error(f"{where}{key}", f"must be finite, got {value!r}")
        if low is not None and (value < low or (strict_low and value == low)):
            raise self.error(f"{where}{key}", f"must be {'>' if strict_low else '>='} {low}, "
                                              f"got {value!r}")
        if high is not None and value > high:
            raise self.error(f"{where}{key}", f"must be <= {high}, got {value!r}")
        return int(value) if integer else float(value)

    def string(self, data: Mapping[str, Any], key: str, where: str, default: str | None = None,
               choices: Sequence[str] | None = None) -> str:
        if key not in data:
            if default is None:
                raise self.error(f"{where}{key}", "required key missing")
            return default
        value = data[key]
        if not isinstance(value, str):
            raise self.error(f"{where}{key}", f"must be a string, got {_tname(value)} {value!r}")
        if choices is not None and value not in choices:
            raise self.error(f"{where}{key}", f"must be one of {', '.join(choices)}; got "
                                              f"{value!r}")
        return value

    def boolean(self, data: Mapping[str, Any], key: str, where: str, default: bool) -> bool:
        value = data.get(key, default)
        if not isinstance(value, bool):
            raise self.error(f"{where}{key}", f"must be true or false, got {value!r}")
        return value

    def pair(self, data: Mapping[str, Any], key: str, where: str, default: Any, *,
             integer: bool = False) -> tuple[Any, Any]:
        """A ``[low, high]`` pair; a single number ``n`` means ``[n, n]`` when integer."""
        if key not in data:
            return default
        value = data[key]
        if integer and isinstance(value, int) and not isinstance(value, bool):
            value = [value, value]
        if not (isinstance(value, list) and len(value) == 2):
            what = "a count or [low, high]" if integer else "[low, high]"
            raise self.error(f"{where}{key}", f"must be {what}, got {value!r}")
        lo = self.number({key: value[0]}, key, where, integer=integer, low=0 if integer else None)
        hi = self.number({key: value[1]}, key, where, integer=integer, low=0 if integer else None)
        if hi < lo:
            raise self.error(f"{where}{key}", f"high must be >= low, got {value!r}")
        return lo, hi


def _tname(value: Any) -> str:
    return {dict: "a table", list: "an array", str: "a string", bool: "a boolean",
            int: "an integer", float: "a number"}.get(type(value), type(value).__name__)


def _merge(base: dict[str, Any], extra: Mapping[str, Any]) -> dict[str, Any]:
    """``base`` updated by ``extra``: tables merge key by key, anything else is replaced."""
    out = copy.deepcopy(base)
    for key, value in extra.items():
        if isinstance(value, Mapping) and isinstance(out.get(key), Mapping):
            out[key] = _merge(dict(out[key]), value)
        else:
            out[key] = copy.deepcopy(value)
    return out


def _derived_seed(seed: int, *salt: int) -> int:
    """A seed for one component, derived from the scenario's (stable across versions)."""
    return int(np.random.SeedSequence([int(seed) & 0xFFFFFFFF, *salt]).generate_state(1)[0])


def _parse_image(r: _Reader, data: Any, index: int, seed: int) -> ImageConfig:
    where = f"images[{index}]."
    if not isinstance(data, Mapping):
        raise r.error(f"images[{index}]", f"must be a table, got {_tname(data)}")
    data = dict(data)
    allowed = (*_IMAGE_KEYS, *_SPEC_FIELDS)
    r.known(data, allowed, where)
    image_id = r.string(data, "id", where)
    if not image_id or any(c in image_id for c in "/\\:*?\"<>| ") or image_id.startswith("."):
        raise r.error(f"{where}id", f"must be a plain file-name-safe name, got {image_id!r}")
    name = r.string(data, "preset", where, default="")
    if name and name not in SENSOR_PRESETS:
        raise r.error(f"{where}preset", f"unknown sensor preset {name!r}; known: "
                                        f"{', '.join(SENSOR_PRESETS)}")
    scale = r.number(data, "scale", where, 1.0, low=0.0, strict_low=True)
    overrides = {k: v for k, v in data.items() if k not in _IMAGE_KEYS}
    values: dict[str, Any] = {}
    for key, value in overrides.items():
        f = _SPEC_FIELDS[key]
        if key == "shape":
            if not (isinstance(value, list) and len(value) == 2
                    and all(isinstance(v, int) and not isinstance(v, bool) for v in value)):
                raise r.error(f"{where}shape", f"must be [rows, cols] integers, got {value!r}")
            values[key] = (int(value[0]), int(value[1]))
        elif f.type in ("str",):
            values[key] = r.string(overrides, key, where)
        elif f.type in ("bool",):
            values[key] = r.boolean(overrides, key, where, False)
        elif f.type in ("int",):
            values[key] = r.number(overrides, key, where, integer=True)
        else:  # float or float | None
            values[key] = r.number(overrides, key, where)
    values.setdefault("name", image_id)
    values.setdefault("seed", _derived_seed(seed, 1, index))
    try:
        if name:
            spec = SENSOR_PRESETS[name].replace(**values)
        else:
            missing = [f.name for f in _SPEC_FIELDS.values()
                       if f.default is dataclasses.MISSING and f.name not in values]
            if missing:
                raise r.error(f"images[{index}]", "without a sensor preset these keys are "
                                                  f"required: {', '.join(missing)}")
            spec = OrbitSensorSpec(**values)
        if scale != 1.0:
            spec = spec.scaled(scale).replace(name=values["name"])
    except ScenarioError:
        raise
    except GeoblockError as exc:
        raise r.error(f"images[{index}]", str(exc)) from exc
    return ImageConfig(image_id, spec, name, scale, overrides)


def scenario_from_dict(data: Mapping[str, Any], source: str = "<scenario>") -> Scenario:
    """A :class:`Scenario` from the parsed TOML form (see :func:`read_scenario`).

    Raises
    ------
    ScenarioError
        Unknown or invalid keys, naming ``source`` and the key.
    """
    r = _Reader(source)
    data = dict(data)
    r.known(data, _TOP_KEYS, "")
    if "preset" in data:
        name = r.string(data, "preset", "")
        variant = r.string(data, "variant", "", default="small", choices=VARIANTS)
        if name not in PRESETS:
            raise r.error("preset", f"unknown preset {name!r}; known: {', '.join(PRESETS)}")
        extra = {k: v for k, v in data.items() if k not in ("preset", "variant")}
        data = _merge(preset_dict(name, variant), extra)
    elif "variant" in data:
        raise r.error("variant", "only meaningful with preset = NAME")
    seed = r.number(data, "seed", "", 0, integer=True, low=0)
    name = r.string(data, "name", "", default="scenario")
    description = r.string(data, "description", "", default="")
    method = r.string(data, "method", "", default="dg")
    from geoblock.adjust.methods import METHODS

    if method not in METHODS:
        raise r.error("method", f"unknown adjustment method {method!r}; methods: "
                                f"{', '.join(METHODS)} (the simulated on-board models are "
                                "linescan models: dg, rpcv0, rpcv1 or default apply)")

    images_raw = data.get("images")
    if not isinstance(images_raw, list) or not images_raw:
        raise r.error("images", "at least one [[images]] table is required")
    images = tuple(_parse_image(r, im, i, seed) for i, im in enumerate(images_raw))
    ids = [im.id for im in images]
    if len(set(ids)) != len(ids):
        raise r.error("images", f"duplicate image ids in {ids}")

    t = r.table(data, "terrain", "")
    w = "terrain."
    r.known(t, [f.name for f in dataclasses.fields(TerrainConfig)], w)
    terrain = TerrainConfig(
        kind=r.string(t, "kind", w, "ridged", ("ridged", "fractal")),
        relief=r.pair(t, "relief", w, (0.0, 1000.0)),
        resolution_m=r.number(t, "resolution_m", w, 100.0, low=0.0, strict_low=True),
        max_slope_deg=r.number(t, "max_slope_deg", w, optional=True, low=0.0, high=89.0,
                               strict_low=True),
        hurst=r.number(t, "hurst", w, optional=True, low=0.0, strict_low=True),
        vertical=r.string(t, "vertical", w, "ellipsoid", ("ellipsoid", "geoid")),
        crs=(r.string(t, "crs", w) if "crs" in t else None),
        margin_m=r.number(t, "margin_m", w, 3000.0, low=0.0),
    )
    if terrain.relief[1] <= terrain.relief[0]:
        raise r.error("terrain.relief", f"high must be > low, got {list(terrain.relief)}")
    if terrain.crs is not None:
        import pyproj

        try:
            pyproj.CRS.from_user_input(terrain.crs)
        except pyproj.exceptions.CRSError as exc:
            raise r.error("terrain.crs", f"not a CRS: {exc}") from exc

    dems_raw = data.get("dems", [])
    if not isinstance(dems_raw, list) or not dems_raw:
        raise r.error("dems", "at least one [[dems]] table (name, spacing_m, rmse_z) is required")
    dems = []
    for i, d in enumerate(dems_raw):
        w = f"dems[{i}]."
        if not isinstance(d, Mapping):
            raise r.error(f"dems[{i}]", f"must be a table, got {_tname(d)}")
        r.known(d, ("name", "spacing_m", "rmse_z"), w)
        dem_name = r.string(d, "name", w)
        if not dem_name or any(c in dem_name for c in "/\\:*?\"<>| ") or dem_name == "truth":
            raise r.error(f"{w}name", f"must be a file-name-safe name other than 'truth', "
                                      f"got {dem_name!r}")
        dems.append(DemConfig(dem_name, r.number(d, "spacing_m", w, low=0.0, strict_low=True),
                              r.number(d, "rmse_z", w, low=0.0)))
    if len({d.name for d in dems}) != len(dems):
        raise r.error("dems", f"duplicate DEM names in {[d.name for d in dems]}")

    p = r.table(data, "points", "")
    w = "points."
    r.known(p, [f.name for f in dataclasses.fields(PointsConfig)], w)
    points = PointsConfig(
        gcp=r.number(p, "gcp", w, 9, integer=True, low=0),
        icp=r.number(p, "icp", w, 0, integer=True, low=0),
        design=r.string(p, "design", w, "stratified", ("stratified", "random")),
        cells=r.number(p, "cells", w, 3, integer=True, low=1),
        tp=r.pair(p, "tp", w, (0, 0), integer=True),
        ictp=r.pair(p, "ictp", w, (0, 0), integer=True),
        **{k: r.number(p, k, w, default, low=0.0) for k, default in (
            ("sigma_px", 0.5), ("sigma_e", 1.0), ("sigma_n", 1.0), ("sigma_h", 1.0),
            ("blunder_px", 10.0), ("ground_blunder_m", 20.0), ("margin_px", 10.0))},
        blunder_fraction=r.number(p, "blunder_fraction", w, 0.0, low=0.0, high=1.0),
        ground_blunder_fraction=r.number(p, "ground_blunder_fraction", w, 0.0, low=0.0,
                                         high=1.0),
    )

    rd = r.table(data, "render", "")
    w = "render."
    r.known(rd, [f.name for f in dataclasses.fields(RenderConfig)], w)
    render = RenderConfig(
        enabled=r.boolean(rd, "enabled", w, True),
        dtype=r.string(rd, "dtype", w, "uint8", ("uint8", "uint16")),
        noise_dn=r.number(rd, "noise_dn", w, 0.0, low=0.0),
        max_pixels=r.number(rd, "max_pixels", w, 20_000_000, integer=True, low=0),
        texture_scale_px=r.number(rd, "texture_scale_px", w, 1.0, low=0.0, strict_low=True),
        texture_contrast=r.number(rd, "texture_contrast", w, 0.5, low=0.0, high=1.0),
    )
    rp = r.table(data, "report", "")
    r.known(rp, ("distance_plot", "gcp_study"), "report.")
    report = ReportConfig(distance_plot=r.boolean(rp, "distance_plot", "report.", False),
                          gcp_study=r.boolean(rp, "gcp_study", "report.", False))
    return Scenario(name, description, seed, images, terrain, tuple(dems), points, render,
                    report, method, source)


def read_scenario(path: str | os.PathLike[str]) -> Scenario:
    """Read a scenario TOML file.

    The file either describes everything (``[[images]]``, ``[terrain]``, ``[[dems]]``,
    ``[points]``, ``[render]``, ``[report]``, ``seed``...) or starts from a named preset
    (``preset = "teo2010-spot5"``, ``variant = "small"``) and overrides some of it: tables
    merge key by key, arrays of tables (``[[images]]``, ``[[dems]]``) replace the preset's.
    See docs/user-guide/simulation.md for every key.

    Raises
    ------
    ScenarioError
        The file is missing, is not TOML, or has an unknown or invalid key (named).
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise ScenarioError(f"{path}: cannot read the scenario file: {exc.strerror}") from exc
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{path}: not a valid TOML file: {exc}") from exc
    return scenario_from_dict(data, str(path))


def load_scenario(name_or_path: str | os.PathLike[str], variant: str | None = None,
                  seed: int | None = None) -> Scenario:
    """A preset by name or a scenario file by path, optionally with another variant or seed.

    Parameters
    ----------
    name_or_path : str or os.PathLike
        A name of :data:`PRESETS` or a TOML file.
    variant : {"small", "full"}, optional
        For a preset (default ``small``), or a file that starts from a preset.
    seed : int, optional
        Replaces the scenario's seed.

    Raises
    ------
    ScenarioError
        Unknown preset (the message lists the known ones), a missing or invalid file, or a
        variant for a file that does not start from a preset.
    """
    text = str(name_or_path)
    if variant is not None and variant not in VARIANTS:
        raise ScenarioError(f"unknown variant {variant!r}; known: {', '.join(VARIANTS)}")
    if text in PRESETS:
        data = preset_dict(text, variant or "small")
        source = f"preset:{text}/{variant or 'small'}"
    elif Path(text).suffix.lower() == ".toml" or Path(text).exists():
        path = Path(text)
        if not path.is_file():
            raise ScenarioError(f"{path}: no such scenario file")
        try:
            data = tomllib.loads(path.read_text(encoding="utf-8"))
        except OSError as exc:
            raise ScenarioError(f"{path}: cannot read the scenario file: {exc.strerror}") from exc
        except tomllib.TOMLDecodeError as exc:
            raise ScenarioError(f"{path}: not a valid TOML file: {exc}") from exc
        if variant is not None:
            if "preset" not in data:
                raise ScenarioError(f"{path}: --variant applies to presets; this file does not "
                                    "start from one (preset = NAME)")
            data["variant"] = variant
        source = str(path)
    else:
        raise ScenarioError(f"unknown scenario {text!r}: not a preset ({', '.join(PRESETS)}) "
                            "and not a .toml file")
    if seed is not None:
        if seed < 0:
            raise ScenarioError(f"seed must be >= 0, got {seed}")
        data["seed"] = int(seed)
    return scenario_from_dict(data, source)


def scenario_to_dict(scenario: Scenario) -> dict[str, Any]:
    """The TOML form of a scenario, fully resolved (no ``preset =``): reading it back with
    :func:`scenario_from_dict` gives an equal scenario."""
    images = []
    for im in scenario.images:
        entry: dict[str, Any] = {"id": im.id}
        if im.preset:
            entry["preset"] = im.preset
        if im.scale != 1.0:
            entry["scale"] = im.scale
        for k, v in im.overrides.items():
            entry[k] = list(v) if isinstance(v, tuple) else v
        images.append(entry)
    terrain = {k: (list(v) if isinstance(v, tuple) else v)
               for k, v in dataclasses.asdict(scenario.terrain).items() if v is not None}
    points = {k: (list(v) if isinstance(v, tuple) else v)
              for k, v in dataclasses.asdict(scenario.points).items()}
    return {
        "name": scenario.name,
        "description": scenario.description,
        "seed": scenario.seed,
        "method": scenario.method,
        "terrain": terrain,
        "points": points,
        "render": dataclasses.asdict(scenario.render),
        "report": dataclasses.asdict(scenario.report),
        "dems": [dataclasses.asdict(d) for d in scenario.dems],
        "images": images,
    }


# ================================================================================ presets
def _teo(variant: str) -> dict[str, Any]:
    small = variant == "small"
    return {
        "name": f"teo2010-spot5-{variant}",
        "description": (
            "Teo et al. (2010): three SPOT-5 supermode strips over Taiwan (2.5 m GSD, "
            "incidence 5.2, 5.7 and -14.8 deg, 10-15 % overlaps), 0-3800 m ridged terrain, "
            "a 40 m DEM, 9 GCPs per strip, 13-32 TPs per overlap, ICPs and ICTPs"
            + (" (small: 600 x 600 px strips at 100 m, same footprints)" if small else "")
        ),
        "seed": 2010,
        "method": "dg",
        "images": [{"id": f"strip{k}", "preset": f"spot5-strip{k}",
                    **({"scale": 40} if small else {})} for k in (1, 2, 3)],
        "terrain": {"kind": "ridged", "relief": [0.0, 3800.0],
                    "resolution_m": 100.0 if small else 40.0,
                    **({} if small else {"max_slope_deg": 70.0}),
                    "vertical": "ellipsoid", "margin_m": 3000.0},
        # Teo et al. give no RMSEz for their 40 m DEM: 5 m is assumed
        "dems": [{"name": "dem40", "spacing_m": 40.0, "rmse_z": 5.0}],
        "points": {"gcp": 9, "icp": 20, "design": "stratified", "cells": 3, "tp": [13, 32],
                   "ictp": [5, 10], "sigma_px": 0.5 / 40 if small else 0.5,
                   "sigma_e": 3.0, "sigma_n": 3.0, "sigma_h": 3.0},
        "render": {"enabled": True, "dtype": "uint8", "noise_dn": 1.0,
                   "texture_scale_px": 1.0},
        "report": {"distance_plot": False, "gcp_study": False},
    }


def _aguilar(variant: str) -> dict[str, Any]:
    small = variant == "small"
    dems = ([{"name": "dem5", "spacing_m": 5.0, "rmse_z": 1.75},
             {"name": "dem20", "spacing_m": 20.0, "rmse_z": 5.82}] if small else
            [{"name": "dem2", "spacing_m": 2.0, "rmse_z": 0.31},
             {"name": "dem5", "spacing_m": 5.0, "rmse_z": 1.75},
             {"name": "dem20", "spacing_m": 20.0, "rmse_z": 5.82}])
    return {
        "name": f"aguilar2007-quickbird-{variant}",
        "description": (
            "Aguilar et al. (2007): a QuickBird basic scene over Almeria (0.62 m GSD, 8 deg "
            "off nadir), 50-850 m rolling terrain, 45 GCPs stratified over a 3 x 3 grid, "
            "79 ICPs, DEMs of 2 / 5 / 20 m spacing with RMSEz 0.31 / 1.75 / 5.82 m"
            + (" (small: ~690 x 690 px at 24.8 m, same footprint; the 5 and 20 m DEMs)"
               if small else "")
        ),
        "seed": 2007,
        "method": "rpcv1",
        "images": [{"id": "quickbird", "preset": "quickbird", **({"scale": 40} if small else {})}],
        "terrain": {"kind": "fractal", "relief": [50.0, 850.0], "hurst": 0.8,
                    "resolution_m": 20.0 if small else 4.0, "vertical": "ellipsoid",
                    "margin_m": 500.0},
        "dems": dems,
        "points": {"gcp": 45, "icp": 79, "design": "stratified", "cells": 3, "tp": 0, "ictp": 0,
                   "sigma_px": 0.5 / 40 if small else 0.5, "sigma_e": 0.05, "sigma_n": 0.05,
                   "sigma_h": 0.1},
        "render": {"enabled": True, "dtype": "uint8", "noise_dn": 1.0,
                   "texture_scale_px": 1.0},
        "report": {"distance_plot": True, "gcp_study": True},
    }


def _chen(variant: str) -> dict[str, Any]:
    small = variant == "small"
    return {
        "name": f"chen1993-spot1a-{variant}",
        "description": (
            "Chen & Lee (1993): a SPOT 1A scene (10 m, 6000 x 6000 px, 1.5 ms line period) "
            "over 950 m of relief, 21 GCPs, check points, a 40 m DTM"
            + (" (small: 600 x 600 px at 100 m, same footprint)" if small else "")
        ),
        "seed": 1993,
        "method": "dg",
        "images": [{"id": "spot1a", "preset": "spot1a", **({"scale": 10} if small else {})}],
        "terrain": {"kind": "ridged", "relief": [150.0, 1100.0],
                    "resolution_m": 100.0 if small else 20.0, "vertical": "ellipsoid",
                    "margin_m": 3000.0},
        "dems": [{"name": "dem40", "spacing_m": 40.0, "rmse_z": 5.0}],
        "points": {"gcp": 21, "icp": 20, "design": "stratified", "cells": 3, "tp": 0,
                   "ictp": 0, "sigma_px": 0.3 / 10 if small else 0.3, "sigma_e": 1.0,
                   "sigma_n": 1.0, "sigma_h": 1.0},
        "render": {"enabled": True, "dtype": "uint8", "noise_dn": 1.0,
                   "texture_scale_px": 1.0},
        "report": {"distance_plot": False, "gcp_study": False},
    }


#: Named scenario presets: name -> one-line description.
PRESETS: dict[str, str] = {
    "teo2010-spot5": "Teo et al. 2010: three SPOT-5 strips, 0-3800 m, 40 m DEM, GCP/ICP/TP/ICTP",
    "aguilar2007-quickbird": "Aguilar et al. 2007: QuickBird basic, 45 GCPs 3x3, 79 ICPs, "
                             "2/5/20 m DEMs",
    "chen1993-spot1a": "Chen & Lee 1993: SPOT 1A, 21 GCPs, check points, 950 m relief",
}
_PRESET_BUILDERS: dict[str, Callable[[str], dict[str, Any]]] = {
    "teo2010-spot5": _teo, "aguilar2007-quickbird": _aguilar, "chen1993-spot1a": _chen,
}


def preset_dict(name: str, variant: str = "small") -> dict[str, Any]:
    """The TOML form of a named preset (a fresh dictionary: change it and pass it to
    :func:`scenario_from_dict`).

    Raises
    ------
    ScenarioError
        Unknown preset (the message lists the known ones) or variant.
    """
    if name not in _PRESET_BUILDERS:
        raise ScenarioError(f"unknown scenario preset {name!r}; known: {', '.join(PRESETS)}")
    if variant not in VARIANTS:
        raise ScenarioError(f"unknown variant {variant!r} of {name}; known: "
                            f"{', '.join(VARIANTS)}")
    return _PRESET_BUILDERS[name](variant)


def preset(name: str, variant: str = "small", *, seed: int | None = None) -> Scenario:
    """A named preset as a :class:`Scenario` (see the module docstring)."""
    data = preset_dict(name, variant)
    if seed is not None:
        data["seed"] = int(seed)
    return scenario_from_dict(data, f"preset:{name}/{variant}")


# ================================================================================ running
@dataclass(frozen=True, eq=False)
class ScenarioResult:
    """What :func:`run_scenario` made.

    Attributes
    ----------
    scenario : Scenario
    outdir : pathlib.Path
    files : mapping of str to pathlib.Path
        Every file written, by a short key (``truth``, ``dem:dem40``, ``image:strip1``,
        ``true_model:strip1``, ``onboard_model:strip1``, ``points:ground``, ``block``,
        ``report``...).
    sensors : mapping of str to SimulatedSensor
        By image id: true and on-board models.
    truth : Terrain
    dems : mapping of str to Terrain
    points : PointSet
    onboard : PointErrors
        The on-board models' ground errors at the GCPs and ICPs (per measurement).
    ictp : IctpDiscrepancies or None
        The on-board models' discrepancies at the ICTPs (None without ICTPs).
    notes : tuple of str
        What was skipped or reduced, and why (also in the report).
    timings : mapping of str to float
        Seconds per stage.
    """

    scenario: Scenario
    outdir: Path
    files: Mapping[str, Path]
    sensors: Mapping[str, Any]
    truth: Any
    dems: Mapping[str, Any]
    points: Any
    onboard: Any
    ictp: Any
    notes: tuple[str, ...]
    timings: Mapping[str, float]

    @property
    def dem_path(self) -> Path:
        """The block's DEM file (the first measured DEM)."""
        return self.files[f"dem:{self.scenario.dems[0].name}"]


def _no_progress(message: str) -> None:
    return None


def _scene_grid(scenario: Scenario, sims: Sequence[Any]) -> Any:
    """The true terrain's grid: every image's footprint at the relief's extremes, plus margin."""
    from geoblock import coords
    from geoblock.simulate.terrain import Grid

    lo, hi = scenario.terrain.relief
    lon, lat = [], []
    for sim in sims:
        for h in (lo, hi):
            fp = sim.true_model.footprint(h=h, n=8)
            lon.append(np.asarray(fp.lon))
            lat.append(np.asarray(fp.lat))
    lon_a, lat_a = np.concatenate(lon), np.concatenate(lat)
    lon0, lat0 = float(np.mean(lon_a)), float(np.mean(lat_a))
    crs = scenario.terrain.crs or coords.utm_crs(lon0, lat0)
    import pyproj

    crs = pyproj.CRS.from_user_input(crs)
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
    # whole multiples of the resolution: the same scene gives the same grid
    w = math.floor((x.min() - m) / res) * res
    s = math.floor((y.min() - m) / res) * res
    e = math.ceil((x.max() + m) / res) * res
    n = math.ceil((y.max() + m) / res) * res
    return Grid.from_bounds((w, s, e, n), res, horizontal)


@dataclass(frozen=True)
class _Contrasted:
    """A texture with its contrast around mid-grey reduced, so that the relief's shading
    shows through the fields."""

    texture: Any
    contrast: float

    def __call__(self, lon: np.ndarray, lat: np.ndarray) -> np.ndarray:
        return 0.5 + self.contrast * (np.asarray(self.texture(lon, lat), float) - 0.5)


def _texture(scenario: Scenario, sims: Sequence[Any]) -> Any:
    """One procedural texture for every image (so that orthos of the block agree), its
    features scaled to the images' GSD."""
    from geoblock.simulate.render import ProceduralTexture

    lon = float(np.mean([s.spec.centre_lon for s in sims]))
    lat = float(np.mean([s.spec.centre_lat for s in sims]))
    gsd = float(np.mean([s.spec.gsd_m for s in sims])) * scenario.render.texture_scale_px
    # the defaults (150 m fields, 8 m roads 800 m apart, rivers 3 km apart) suit a 2.5 m GSD
    k = gsd / 2.5
    base = ProceduralTexture((lon, lat), _derived_seed(scenario.seed, 5) % (1 << 31),
                             field_size_m=150.0 * k, road_spacing_m=800.0 * k,
                             road_width_m=8.0 * k, river_spacing_m=3000.0 * k,
                             river_width_m=25.0 * k)
    return _Contrasted(base, scenario.render.texture_contrast)


def run_scenario(
    scenario: Scenario,
    outdir: str | os.PathLike[str],
    *,
    progress: Callable[[str], None] | None = None,
    render: bool | None = None,
) -> ScenarioResult:
    """Simulate a scenario into ``outdir`` (created if needed; existing files are replaced).

    Files (paths relative to ``outdir``)::

        scenario.toml                 the scenario, fully resolved (runs again as is)
        block.toml                    block file for the adjustment engine (on-board models)
        terrain/truth.tif             the true terrain (GeoTIFF stating its vertical datum)
        terrain/<dem>.tif             each measured DEM
        images/<id>.tif               raw image rendered through the true model (if rendered)
        images/<id>_true.json         the true model
        images/<id>_onboard.json      the on-board model (what a user would be given)
        points/ground.csv             GCPs and ICPs (surveyed, with noise)
        points/image.csv              image measurements of every kind (with noise)
        points/truth.csv              the truth of every measurement
        report/report.md              footprints and on-board accuracy, the tables below
        report/footprints.csv
        report/onboard_accuracy.csv   per image and kind (GCP, ICP): RMSE, mean, max
        report/ictp_accuracy.csv      per strip pair, when there are ICTPs
        report/errors_<id>.png        error vectors of the on-board model (GCPs, ICPs)
        report/residual_vs_distance.png   with report.distance_plot
        report/rmse_vs_gcps_<image>.png   with report.gcp_study
        timings.json                  seconds per stage (the only file that changes run to run)

    Parameters
    ----------
    scenario : Scenario
    outdir : str or os.PathLike
    progress : callable, optional
        Called with a one-line message at each stage.
    render : bool, optional
        Override ``scenario.render.enabled``.

    Returns
    -------
    ScenarioResult
    """
    from geoblock.adjust.statistics import PointErrors, ictp_accuracy
    from geoblock.io import BlockDem, BlockImage, write_block, write_model
    from geoblock.io.blocks import Block
    from geoblock.simulate import terrain as _terrain
    from geoblock.simulate.points import simulate_points
    from geoblock.simulate.render import render_image

    say = progress or _no_progress
    out = Path(outdir)
    for sub in ("terrain", "images", "points", "report"):
        (out / sub).mkdir(parents=True, exist_ok=True)
    files: dict[str, Path] = {}
    timings: dict[str, float] = {}
    notes: list[str] = []
    start = time.perf_counter()
    clock = [start]

    def lap(stage: str) -> None:
        now = time.perf_counter()
        timings[stage] = round(now - clock[0], 3)
        clock[0] = now

    files["scenario"] = _write_text(out / "scenario.toml", _scenario_toml(scenario))

    # --- sensors
    say(f"sensors: {len(scenario.images)} image(s)")
    sims = {}
    for im in scenario.images:
        sims[im.id] = _sensors.simulate_sensor(im.spec)
        rows, cols = im.spec.shape
        say(f"  {im.id}: {rows} x {cols} px, GSD {im.spec.gsd_m:g} m, on-board RMSE "
            f"{im.spec.onboard_rmse_m:g} m")
    lap("sensors")

    # --- terrain
    t = scenario.terrain
    grid = _scene_grid(scenario, list(sims.values()))
    say(f"terrain: {t.kind} {t.relief[0]:g}-{t.relief[1]:g} m on {grid.shape[0]} x "
        f"{grid.shape[1]} posts of {t.resolution_m:g} m ({grid.crs.name})")
    options: dict[str, Any] = {"max_slope_deg": t.max_slope_deg, "seed":
                               _derived_seed(scenario.seed, 2), "vertical": t.vertical}
    if t.hurst is not None:
        options["hurst"] = t.hurst
    make = _terrain.ridged_terrain if t.kind == "ridged" else _terrain.fractal_terrain
    truth = make(grid, t.relief, **options)
    files["truth"] = truth.write(out / "terrain" / "truth.tif")
    true_dem = truth.to_dem()
    lap("terrain")
    dems = {}
    for k, d in enumerate(scenario.dems):
        say(f"DEM {d.name}: {d.spacing_m:g} m posts, RMSEz {d.rmse_z:g} m")
        dems[d.name] = _terrain.measured_dem(truth, d.spacing_m, d.rmse_z,
                                             seed=_derived_seed(scenario.seed, 3, k))
        files[f"dem:{d.name}"] = dems[d.name].write(out / "terrain" / f"{d.name}.tif")
    lap("dems")

    # --- models
    for image_id, sim in sims.items():
        files[f"true_model:{image_id}"] = write_model(
            sim.true_model, out / "images" / f"{image_id}_true.json")
        files[f"onboard_model:{image_id}"] = write_model(
            sim.onboard_model, out / "images" / f"{image_id}_onboard.json")

    # --- points
    p = scenario.points
    say("points: GCPs and ICPs per image, TPs and ICTPs per overlap")
    pts = simulate_points(
        {i: s.true_model for i, s in sims.items()}, true_dem,
        gcp=p.gcp, icp=p.icp, design=p.design, cells=p.cells, tp=p.tp, ictp=p.ictp,
        sigma_px=p.sigma_px, sigma_e=p.sigma_e, sigma_n=p.sigma_n, sigma_h=p.sigma_h,
        blunder_fraction=p.blunder_fraction, blunder_px=p.blunder_px,
        ground_blunder_fraction=p.ground_blunder_fraction, ground_blunder_m=p.ground_blunder_m,
        margin_px=p.margin_px, seed=_derived_seed(scenario.seed, 4),
    )
    for key, path in pts.write(out / "points").items():
        files[f"points:{key}"] = path
    say("  " + ", ".join(f"{pts.count(k)} {k.upper()}s" for k in ("gcp", "icp", "tp", "ictp")))
    lap("points")

    # --- images
    do_render = scenario.render.enabled if render is None else bool(render)
    rasters: dict[str, Path] = {}
    if do_render:
        texture = _texture(scenario, list(sims.values()))
        from geoblock.io import write_image

        for k, (image_id, sim) in enumerate(sims.items()):
            rows, cols = sim.spec.shape
            if rows * cols > scenario.render.max_pixels:
                note = (f"image {image_id} not rendered: {rows} x {cols} px is more than "
                        f"render.max_pixels = {scenario.render.max_pixels} (a full-size render "
                        "would take more than a few minutes; the models and points are "
                        "complete, use the small variant to look at images)")
                notes.append(note)
                say(f"  {note}")
                continue
            say(f"rendering {image_id}: {rows} x {cols} px")
            rendered = render_image(sim.true_model, true_dem, texture=texture,
                                    dtype=scenario.render.dtype,
                                    noise_dn=scenario.render.noise_dn,
                                    seed=_derived_seed(scenario.seed, 6, k))
            path = out / "images" / f"{image_id}.tif"
            write_image(path, rendered.pixels, nodata=0,
                        tags={"GEOBLOCK_SIMULATED": "rendered by geoblock.simulate.render",
                              "GEOBLOCK_MODEL": f"{image_id}_true.json",
                              "GEOBLOCK_ONBOARD_MODEL": f"{image_id}_onboard.json"})
            files[f"image:{image_id}"] = rasters[image_id] = path
    else:
        notes.append("images not rendered (render disabled)")
        say("images: not rendered (render disabled)")
    lap("render")

    # --- block file
    first = scenario.dems[0].name
    block = Block(
        images=tuple(BlockImage(i, files[f"onboard_model:{i}"], rasters.get(i))
                     for i in sims),
        method=scenario.method, ground_points=files["points:ground"],
        image_points=files["points:image"], truth=files["points:truth"],
        dem=BlockDem(str(files[f"dem:{first}"]), sigma=scenario.dems[0].rmse_z or None),
        name=scenario.name,
        outputs={"directory": out / "adjusted", "report": out / "adjusted" / "report.md"},
    )
    files["block"] = write_block(out / "block.toml", block)

    # --- accuracy of the on-board models
    say("report: on-board accuracy at GCPs and ICPs, ICTP discrepancies")
    onboard = _onboard_errors(sims, pts, PointErrors)
    ictp = None
    sel = pts.image.kind == "ictp"
    if sel.any():
        ictp = ictp_accuracy({i: s.onboard_model for i, s in sims.items()}, pts.image.id[sel],
                             pts.image.image[sel], pts.image.row[sel], pts.image.col[sel],
                             dems[first].to_dem(), warn=False)
    files.update(_write_report(scenario, out / "report", sims, truth, dems, pts, onboard, ictp,
                               notes))
    lap("report")
    timings["total"] = round(time.perf_counter() - start, 3)
    files["timings"] = _write_text(out / "timings.json", json.dumps(timings, indent=2) + "\n")
    say(f"done in {timings['total']:.1f} s: {out}")
    return ScenarioResult(scenario, out, files, sims, truth, dems, pts, onboard, ictp,
                          tuple(notes), timings)


def _onboard_errors(sims: Mapping[str, Any], pts: Any, point_errors: Any) -> Any:
    """Ground errors of the on-board models at the GCP and ICP measurements.

    The true image position of each measurement is backprojected through the image's
    on-board model at the point's true height and compared with the true ground position:
    the error of the model alone (no pointing, survey or DEM error).
    """
    m, g = pts.image, pts.ground
    index = {pid: i for i, pid in enumerate(g.id.tolist())}
    keep = np.flatnonzero(np.isin(m.kind, ("gcp", "icp")))
    k = np.array([index[i] for i in m.id[keep].tolist()], dtype=np.intp)
    lon = np.full(keep.size, np.nan)
    lat = np.full(keep.size, np.nan)
    h_true = g.h_true[k]
    for image_id, sim in sims.items():
        sel = np.flatnonzero(m.image[keep] == image_id)
        if sel.size:
            est = sim.onboard_model.backproject(m.row_true[keep][sel], m.col_true[keep][sel],
                                                h_true[sel])
            lon[sel], lat[sel] = est.lon, est.lat
    return point_errors.from_ground(m.id[keep], np.char.upper(m.kind[keep].astype(str)), lon,
                                    lat, g.lon_true[k], g.lat_true[k], h=h_true, h_ref=h_true,
                                    image=m.image[keep])


def _refinement_points(pts: Any, image_id: str) -> tuple[Any, Any]:
    """``(ControlPoints of the image's GCPs as measured, CheckPoints of its ICPs with their
    truth)``; None for a kind the image does not have."""
    from geoblock.adjust import ControlPoints
    from geoblock.simulate.study import CheckPoints

    m, g = pts.image, pts.ground
    index = {pid: i for i, pid in enumerate(g.id.tolist())}
    out: list[Any] = []
    for kind in ("gcp", "icp"):
        sel = np.flatnonzero((m.image == image_id) & (m.kind == kind))
        if sel.size == 0:
            out.append(None)
            continue
        k = np.array([index[i] for i in m.id[sel].tolist()], dtype=np.intp)
        if kind == "gcp":
            out.append(ControlPoints(id=m.id[sel], lon=g.lon[k], lat=g.lat[k], h=g.h[k],
                                     row=m.row[sel], col=m.col[sel], sigma_row=m.sigma[sel],
                                     sigma_col=m.sigma[sel], sigma_e=g.sigma_e[k],
                                     sigma_n=g.sigma_n[k], sigma_h=g.sigma_h[k]))
        else:
            out.append(CheckPoints(g.lon_true[k], g.lat_true[k], g.h_true[k],
                                   m.row_true[sel], m.col_true[sel]))
    return out[0], out[1]


def _write_text(path: Path, text: str) -> Path:
    from geoblock.report._files import write_atomic

    return write_atomic(path, lambda f: f.write(text.encode("utf-8")))


def _scenario_toml(scenario: Scenario) -> str:
    from geoblock.io.blocks import dumps_toml

    head = (f"# geoblock scenario (docs: user-guide/simulation.md), from {scenario.source}\n"
            "# run it again with: geoblock simulate scenario.toml OUTDIR\n")
    return head + dumps_toml(scenario_to_dict(scenario))


def footprint_rows(sims: Mapping[str, Any], truth: Any) -> list[dict[str, Any]]:
    """Per image: size, GSD, incidence, centre and corners of the true footprint (at the
    scene centre's height), and the on-board model's shift at the centre."""
    from geoblock import coords
    from geoblock.simulate.sensors import incidence_angle

    rows_out = []
    for image_id, sim in sims.items():
        spec = sim.spec
        rows, cols = spec.shape
        h = spec.centre_h
        rc, cc = (rows - 1) / 2.0, (cols - 1) / 2.0
        corners_r = np.array([-0.5, -0.5, rows - 0.5, rows - 0.5])
        corners_c = np.array([-0.5, cols - 0.5, cols - 0.5, -0.5])
        g = sim.true_model.backproject(corners_r, corners_c, np.full(4, h))
        c_true = sim.true_model.backproject(rc, cc, h)
        c_ob = sim.onboard_model.backproject(rc, cc, h)
        de, dn, _ = coords.enu_offsets(*c_true, *c_ob)
        width = float(np.hypot(*coords.enu_offsets(g.lon[0], g.lat[0], h, g.lon[1], g.lat[1],
                                                   h)[:2]))
        length = float(np.hypot(*coords.enu_offsets(g.lon[0], g.lat[0], h, g.lon[3], g.lat[3],
                                                    h)[:2]))
        err = sim.onboard_error()
        rows_out.append({
            "image": image_id, "rows": rows, "cols": cols, "gsd_m": spec.gsd_m,
            "incidence_deg": round(incidence_angle(sim.true_model, rc, cc, h), 3),
            "centre_lon": float(c_true.lon), "centre_lat": float(c_true.lat),
            "width_km": width / 1e3, "length_km": length / 1e3,
            **{f"corner{k + 1}_lon": float(g.lon[k]) for k in range(4)},
            **{f"corner{k + 1}_lat": float(g.lat[k]) for k in range(4)},
            "onboard_rmse_asked_m": spec.onboard_rmse_m,
            "onboard_rmse_grid_m": err.rmse,
            "onboard_centre_de_m": float(de), "onboard_centre_dn_m": float(dn),
        })
    return rows_out


def _csv(rows: Sequence[Mapping[str, Any]]) -> str:
    import csv
    import io

    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=list(rows[0]), lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow({k: (repr(v) if isinstance(v, float) else v) for k, v in row.items()})
    return buf.getvalue()


def _write_report(scenario: Scenario, folder: Path, sims: Mapping[str, Any], truth: Any,
                  dems: Mapping[str, Any], pts: Any, onboard: Any, ictp: Any,
                  notes: Sequence[str]) -> dict[str, Path]:
    from geoblock.adjust.statistics import distance_from_image_centre
    from geoblock.report import error_vector_plot, residual_vs_distance, stats_table, to_local_en

    files: dict[str, Path] = {}
    fp = footprint_rows(sims, truth)
    files["report:footprints"] = _write_text(folder / "footprints.csv", _csv(fp))
    by = onboard.by_image_and_kind()
    files["report:onboard_accuracy"] = _write_text(
        folder / "onboard_accuracy.csv", stats_table(by, labels=("image", "kind"), fmt="csv"))
    ictp_md = ""
    if ictp is not None and len(ictp):
        pairs = {f"{a} & {b}": s for (a, b), s in ictp.by_pair().items()}
        files["report:ictp_accuracy"] = _write_text(
            folder / "ictp_accuracy.csv", stats_table(pairs, labels=("pair",), fmt="csv"))
        ictp_md = stats_table(pairs, labels=("pair",))

    # figures: error vectors of the on-board model per image, GCPs triangles, ICPs circles
    for image_id in sims:
        sel = onboard.select(image=image_id)
        if not len(sel):
            continue
        k = np.array([np.flatnonzero(pts.ground.id == i)[0] for i in sel.id.tolist()])
        e, n = to_local_en(pts.ground.lon_true[k], pts.ground.lat_true[k],
                           pts.ground.h_true[k])
        path = folder / f"errors_{image_id}.png"
        error_vector_plot(e, n, sel.e, sel.n, sel.kind, path=path,
                          title=f"{image_id}: on-board model at GCPs and ICPs")
        files[f"report:errors_{image_id}"] = path
    study_md = []
    if scenario.report.distance_plot or scenario.report.gcp_study:
        from geoblock.errors import GeoblockError
        from geoblock.report import rmse_vs_gcp_count
        from geoblock.simulate.study import gcp_count_study, refined_errors

        series = {}
        for image_id, sim in sims.items():
            gcps, icps = _refinement_points(pts, image_id)
            sel = onboard.select(image=image_id, kind="ICP")
            if not len(sel) or icps is None:
                continue
            k = np.array([np.flatnonzero(pts.ground.id == i)[0] for i in sel.id.tolist()])
            d = distance_from_image_centre(sim.true_model, pts.ground.lon_true[k],
                                           pts.ground.lat_true[k], pts.ground.h_true[k])
            series[f"{image_id} on-board"] = (d, np.hypot(sel.e, sel.n))
            if gcps is None:
                continue
            d_icp = distance_from_image_centre(sim.true_model, icps.lon, icps.lat, icps.h)
            for order, label in ((0, "RPCV-0"), (1, "RPCV-1")):
                try:
                    err = refined_errors(sim.onboard_model, gcps, icps, order)
                except GeoblockError:  # too few GCPs in this image for the order
                    continue
                series[f"{image_id} {label}, {len(gcps)} GCPs"] = (d_icp, err)
            if scenario.report.gcp_study:
                counts = [n for n in (3, 6, 9, 18, 27, 45) if n <= len(gcps)]
                if len(gcps) not in counts:
                    counts.append(len(gcps))
                study = gcp_count_study(sim.onboard_model, gcps, icps, counts=counts,
                                        repeats=10, seed=scenario.seed)
                path = folder / f"rmse_vs_gcps_{image_id}.png"
                rmse_vs_gcp_count(study.series(), path=path,
                                  title=f"{image_id}: ICP RMSE after refinement vs GCPs")
                files[f"report:rmse_vs_gcps_{image_id}"] = path
                study_md += [f"### {image_id}", "",
                             "RMSE 2D at the ICPs (m), mean (min-max) over 10 random GCP "
                             "subsets:", "", study.table().rstrip(), "",
                             f"![{image_id}](rmse_vs_gcps_{image_id}.png)", ""]
        if scenario.report.distance_plot and series:
            path = folder / "residual_vs_distance.png"
            residual_vs_distance(series, path=path,
                                 title="2D error at ICPs vs distance from the image centre")
            files["report:residual_vs_distance"] = path

    # Markdown
    lines = [f"# {scenario.name}", "", scenario.description, "",
             f"Seed {scenario.seed}; source `{scenario.source}`.", ""]
    if notes:
        lines += ["Notes:", ""] + [f"- {n}" for n in notes] + [""]
    lines += ["## Images and footprints", "",
              "| image | size (px) | GSD (m) | incidence (deg) | centre lon, lat | footprint (km) "
              "| on-board RMSE asked / over the image (m) |",
              "|---|---|---|---|---|---|---|"]
    for r in fp:
        lines.append(
            f"| {r['image']} | {r['rows']} x {r['cols']} | {r['gsd_m']:.3g} | "
            f"{r['incidence_deg']:.2f} | {r['centre_lon']:.4f}, {r['centre_lat']:.4f} | "
            f"{r['width_km']:.1f} x {r['length_km']:.1f} | {r['onboard_rmse_asked_m']:.1f} / "
            f"{r['onboard_rmse_grid_m']:.1f} |")
    lo, hi = truth.relief
    lines += ["", "## Terrain and DEMs", "",
              f"True terrain: {scenario.terrain.kind}, {lo:.0f}-{hi:.0f} m above the "
              f"{truth.vertical}, {truth.shape[0]} x {truth.shape[1]} posts of "
              f"{scenario.terrain.resolution_m:g} m, steepest slope "
              f"{float(np.nanmax(truth.slope_deg())):.1f} deg (`terrain/truth.tif`).", ""]
    for d in scenario.dems:
        dem = dems[d.name]
        lines.append(f"- `terrain/{d.name}.tif`: {dem.shape[0]} x {dem.shape[1]} posts of "
                     f"{d.spacing_m:g} m, RMSEz {d.rmse_z:g} m against the truth")
    counts = ", ".join(f"{pts.count(k)} {k.upper()}s" for k in ("gcp", "icp", "tp", "ictp"))
    lines += ["", "## Points", "", f"{counts}; {len(pts.image)} image measurements "
              f"(pointing noise {scenario.points.sigma_px:g} px, survey noise "
              f"{scenario.points.sigma_e:g} / {scenario.points.sigma_n:g} / "
              f"{scenario.points.sigma_h:g} m E/N/U). Files: `points/ground.csv`, "
              "`points/image.csv`, `points/truth.csv`; block file `block.toml`.", ""]
    lines += ["## Accuracy of the on-board models", "",
              "Ground error of each image's on-board model at the GCPs and ICPs: the true image "
              "position backprojected at the true height, minus the true ground position "
              "(metres, local east/north): the error a user starts from before any "
              "adjustment.", "",
              stats_table(by, labels=("image", "kind")).rstrip(), ""]
    for image_id in sims:
        if f"report:errors_{image_id}" in files:
            lines.append(f"![{image_id}](errors_{image_id}.png)")
    lines.append("")
    if ictp_md:
        lines += ["## ICTP discrepancies between images", "",
                  "Each ICTP measurement (with its pointing noise) ray-traced onto the DEM "
                  f"`{scenario.dems[0].name}` through its image's on-board model; discrepancy = "
                  "second image's ground point minus the first's (Teo et al.'s relative "
                  "accuracy).", "", ictp_md.rstrip(), ""]
    if "report:residual_vs_distance" in files:
        lines += ["## Error against the distance from the image centre", "",
                  "2D error at the ICPs of the on-board model, and after RPCV-0 (shift) and "
                  "RPCV-1 (affine) image-space corrections fitted to all the image's GCPs "
                  "(Aguilar et al. Fig. 4): what a shift cannot absorb (an along-track drift) "
                  "grows with the distance from the image centre.", "",
                  "![residual vs distance](residual_vs_distance.png)", ""]
    if study_md:
        lines += ["## ICP accuracy against the number of GCPs", "",
                  "RPCV-0 and RPCV-1-style corrections of the on-board model fitted to random "
                  "subsets of the GCPs (Aguilar et al. Figs. 3, 6, 7).", ""] + study_md
    files["report"] = _write_text(folder / "report.md", "\n".join(lines) + "\n")
    return files
