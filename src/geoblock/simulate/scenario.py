"""Scenarios: a whole simulated block (sensors, terrain, DEMs, points, images) in one value.

A :class:`Scenario` is a frozen description of a synthetic block, read from a TOML file
(:func:`read_scenario`, :func:`load_scenario`) or taken from a named preset (:func:`preset`,
the papers' set-ups of :mod:`geoblock.simulate.presets`). :func:`scenario_from_dict` parses
and validates the TOML form, naming the file and the key of any error
(:class:`~geoblock.errors.ScenarioError`); :func:`scenario_to_dict` gives it back, fully
resolved, and :func:`write_scenario` writes it.

The values here describe a block; :mod:`geoblock.simulate.scene` turns them into sensors,
terrain, DEMs, points and images in memory, and :func:`geoblock.workflows.run_scenario`
simulates a scenario into a directory (files and report). Every draw is deterministic for
the scenario's seed (:func:`derived_seed`).
"""

from __future__ import annotations

import copy
import dataclasses
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from geoblock.errors import GeoblockError, GeoblockIOError, MetadataFieldError, ScenarioError
from geoblock.io.files import read_toml, write_text
from geoblock.io.metadata import Fields
from geoblock.simulate.onboard import ONBOARD_ERRORS
from geoblock.simulate.presets import (
    PRESETS,
    SENSOR_PRESETS,
    VARIANTS,
    demo_dict,
    preset_dict,
)
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
    "TerrainConfig",
    "demo_scenario",
    "derived_seed",
    "load_scenario",
    "preset",
    "preset_dict",
    "read_scenario",
    "scenario_from_dict",
    "scenario_to_dict",
    "scenario_toml",
    "write_scenario",
]

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
    """A simulated block: what :func:`geoblock.workflows.run_scenario` makes.

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
    onboard_errors : {"realistic", "bias-drift"} or None
        The on-board error model of every image that does not set its own (``onboard_errors``
        at the top of the file; None: each image's, ``"realistic"`` unless it says;
        :data:`~geoblock.simulate.onboard.ONBOARD_ERRORS`).
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
    onboard_errors: str | None = None

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], source: str = "<scenario>") -> Scenario:
        """The scenario of a parsed scenario file (:func:`scenario_from_dict`)."""
        return scenario_from_dict(data, source)

    def to_dict(self) -> dict[str, Any]:
        """The TOML form, fully resolved (:func:`scenario_to_dict`)."""
        return scenario_to_dict(self)

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
             "dems", "points", "render", "report", "onboard_errors")
_IMAGE_KEYS = ("id", "preset", "scale")
_SPEC_FIELDS = {f.name: f for f in dataclasses.fields(OrbitSensorSpec)}
_UNSAFE = "/\\:*?\"<>| "  # characters refused in names that become file names


def _field_error(source: str, field: str, problem: str) -> ScenarioError:
    """The :class:`~geoblock.io.metadata.Fields` error factory: ``source: field: problem``."""
    return ScenarioError(f"{source}: {field}: {problem}")


def _fields(source: str, data: Mapping[str, Any]) -> Fields:
    return Fields(source, data, error=_field_error)


def _array_of_tables(top: Fields, key: str, problem: str) -> list[Fields]:
    """The tables of the array ``key`` (``[[key]]``), each as :class:`Fields` named
    ``key[i].``; an absent or empty array is an error saying ``problem``."""
    items = top.get(key, None)
    if not isinstance(items, list) or not items:
        raise top.error(key, problem)
    # each element read as the sub-table "key[i]" of a one-entry table: a non-table element
    # is refused naming it ("images[2]: must be a table, got a string")
    return [_fields(top.source, {f"{key}[{i}]": item}).table(f"{key}[{i}]")
            for i, item in enumerate(items)]


def _merge(base: dict[str, Any], extra: Mapping[str, Any]) -> dict[str, Any]:
    """``base`` updated by ``extra``: tables merge key by key, anything else is replaced."""
    out = copy.deepcopy(base)
    for key, value in extra.items():
        if isinstance(value, Mapping) and isinstance(out.get(key), Mapping):
            out[key] = _merge(dict(out[key]), value)
        else:
            out[key] = copy.deepcopy(value)
    return out


def derived_seed(seed: int, *salt: int) -> int:
    """The seed of one component of a scenario, derived from the scenario's ``seed`` and a
    component ``salt`` (stable across versions: the same scenario gives the same files).

    The salts in use: 1 sensors (with the image index), 2 true terrain, 3 measured DEMs
    (with the DEM index), 4 points, 5 texture, 6 rendering (with the image index).
    """
    return int(np.random.SeedSequence([int(seed) & 0xFFFFFFFF, *salt]).generate_state(1)[0])


def _parse_image(f: Fields, index: int, seed: int,
                 onboard_errors: str | None = None) -> ImageConfig:
    """One ``[[images]]`` table (``f``, named ``images[index].``); ``onboard_errors``: the
    scenario's, for an image that does not set its own."""
    here = f.where.rstrip(".")
    f.known((*_IMAGE_KEYS, *_SPEC_FIELDS))
    image_id = f.string("id")
    if not image_id or any(c in image_id for c in _UNSAFE) or image_id.startswith("."):
        raise f.error("id", f"must be a plain file-name-safe name, got {image_id!r}")
    name = f.string("preset", "")
    if name and name not in SENSOR_PRESETS:
        raise f.error("preset", f"unknown sensor preset {name!r}; known: "
                                f"{', '.join(SENSOR_PRESETS)}")
    scale = f.number("scale", 1.0, low=0.0, strict_low=True)
    overrides = {k: v for k, v in f.data.items() if k not in _IMAGE_KEYS}
    values: dict[str, Any] = {}
    for key, value in overrides.items():
        kind = _SPEC_FIELDS[key].type  # the annotation, as a string
        if key == "shape":
            if not (isinstance(value, list) and len(value) == 2
                    and all(isinstance(v, int) and not isinstance(v, bool) for v in value)):
                raise f.error("shape", f"must be [rows, cols] integers, got {value!r}")
            values[key] = (int(value[0]), int(value[1]))
        elif kind == "str":
            values[key] = f.string(key)
        elif kind == "bool":
            values[key] = f.boolean(key)
        elif kind == "int":
            values[key] = f.number(key, integer=True)
        elif kind.startswith("tuple[float"):
            n = kind.count("float")
            if not (isinstance(value, list) and len(value) == n
                    and all(isinstance(v, (int, float)) and not isinstance(v, bool)
                            for v in value)):
                raise f.error(key, f"must be a list of {n} numbers, got {value!r}")
            values[key] = tuple(float(v) for v in value)
        else:  # float or float | None
            values[key] = f.number(key)
    values.setdefault("name", image_id)
    values.setdefault("seed", derived_seed(seed, 1, index))
    if onboard_errors is not None:
        values.setdefault("onboard_errors", onboard_errors)
    try:
        if name:
            spec = SENSOR_PRESETS[name].replace(**values)
        else:
            missing = [s.name for s in _SPEC_FIELDS.values()
                       if s.default is dataclasses.MISSING and s.name not in values]
            if missing:
                raise _field_error(f.source, here, "without a sensor preset these keys are "
                                                   f"required: {', '.join(missing)}")
            spec = OrbitSensorSpec(**values)
        if scale != 1.0:
            spec = spec.scaled(scale).replace(name=values["name"])
    except ScenarioError:
        raise
    except GeoblockError as exc:
        raise _field_error(f.source, here, str(exc)) from exc
    return ImageConfig(image_id, spec, name, scale, overrides)


def _parse_terrain(t: Fields) -> TerrainConfig:
    t.known([f.name for f in dataclasses.fields(TerrainConfig)])
    terrain = TerrainConfig(
        kind=t.string("kind", "ridged", choices=("ridged", "fractal")),
        relief=t.pair("relief", (0.0, 1000.0)),
        resolution_m=t.number("resolution_m", 100.0, low=0.0, strict_low=True),
        max_slope_deg=t.number("max_slope_deg", None, low=0.0, high=89.0, strict_low=True),
        hurst=t.number("hurst", None, low=0.0, strict_low=True),
        vertical=t.string("vertical", "ellipsoid", choices=("ellipsoid", "geoid")),
        crs=t.string("crs", None),
        margin_m=t.number("margin_m", 3000.0, low=0.0),
    )
    if terrain.relief[1] <= terrain.relief[0]:
        raise t.error("relief", f"high must be > low, got {list(terrain.relief)}")
    if terrain.crs is not None:
        import pyproj

        try:
            pyproj.CRS.from_user_input(terrain.crs)
        except pyproj.exceptions.CRSError as exc:
            raise t.error("crs", f"not a CRS: {exc}") from exc
    return terrain


def _parse_dem(d: Fields) -> DemConfig:
    d.known(("name", "spacing_m", "rmse_z"))
    name = d.string("name")
    if not name or any(c in name for c in _UNSAFE) or name == "truth":
        raise d.error("name", f"must be a file-name-safe name other than 'truth', got {name!r}")
    return DemConfig(name, d.number("spacing_m", low=0.0, strict_low=True),
                     d.number("rmse_z", low=0.0))


def _parse_points(p: Fields) -> PointsConfig:
    p.known([f.name for f in dataclasses.fields(PointsConfig)])
    return PointsConfig(
        gcp=p.number("gcp", 9, integer=True, low=0),
        icp=p.number("icp", 0, integer=True, low=0),
        design=p.string("design", "stratified", choices=("stratified", "random")),
        cells=p.number("cells", 3, integer=True, low=1),
        tp=p.pair("tp", (0, 0), integer=True),
        ictp=p.pair("ictp", (0, 0), integer=True),
        **{k: p.number(k, default, low=0.0) for k, default in (
            ("sigma_px", 0.5), ("sigma_e", 1.0), ("sigma_n", 1.0), ("sigma_h", 1.0),
            ("blunder_px", 10.0), ("ground_blunder_m", 20.0), ("margin_px", 10.0))},
        blunder_fraction=p.number("blunder_fraction", 0.0, low=0.0, high=1.0),
        ground_blunder_fraction=p.number("ground_blunder_fraction", 0.0, low=0.0, high=1.0),
    )


def _parse_render(r: Fields) -> RenderConfig:
    r.known([f.name for f in dataclasses.fields(RenderConfig)])
    return RenderConfig(
        enabled=r.boolean("enabled", True),
        dtype=r.string("dtype", "uint8", choices=("uint8", "uint16")),
        noise_dn=r.number("noise_dn", 0.0, low=0.0),
        max_pixels=r.number("max_pixels", 20_000_000, integer=True, low=0),
        texture_scale_px=r.number("texture_scale_px", 1.0, low=0.0, strict_low=True),
        texture_contrast=r.number("texture_contrast", 0.5, low=0.0, high=1.0),
    )


def _parse_report(r: Fields) -> ReportConfig:
    r.known(("distance_plot", "gcp_study"))
    return ReportConfig(distance_plot=r.boolean("distance_plot", False),
                        gcp_study=r.boolean("gcp_study", False))


def scenario_from_dict(data: Mapping[str, Any], source: str = "<scenario>") -> Scenario:
    """A :class:`Scenario` from the parsed TOML form (see :func:`read_scenario`).

    Parameters
    ----------
    data : mapping
        The TOML form: every table of a scenario file, or ``preset = NAME`` (and
        ``variant``) with the keys that override the preset (tables merge key by key,
        ``images`` and ``dems`` replace the preset's).
    source : str
        Where ``data`` came from (a file name, ``preset:NAME/VARIANT``); named by errors and
        kept in :attr:`Scenario.source`.

    Raises
    ------
    ScenarioError
        Unknown or invalid keys, naming ``source`` and the key
        (``my.toml: points.gcp: must be an integer, got a number 2.5``).
    """
    top = _fields(source, data)
    top.known(_TOP_KEYS)
    if "preset" in top:
        name = top.string("preset")
        variant = top.string("variant", "small", choices=VARIANTS)
        if name not in PRESETS:
            raise top.error("preset", f"unknown preset {name!r}; known: {', '.join(PRESETS)}")
        extra = {k: v for k, v in data.items() if k not in ("preset", "variant")}
        top = _fields(source, _merge(preset_dict(name, variant), extra))
    elif "variant" in top:
        raise top.error("variant", "only meaningful with preset = NAME")
    seed = top.number("seed", 0, integer=True, low=0)
    onboard_errors = (top.string("onboard_errors", choices=ONBOARD_ERRORS)
                      if "onboard_errors" in top else None)
    name = top.string("name", "scenario")
    description = top.string("description", "")
    method = top.string("method", "dg")
    from geoblock.adjust.methods import METHODS

    if method not in METHODS:
        raise top.error("method", f"unknown adjustment method {method!r}; methods: "
                                  f"{', '.join(METHODS)} (the simulated on-board models are "
                                  "linescan models: dg, rpcv0, rpcv1 or default apply)")

    images = tuple(_parse_image(im, i, seed, onboard_errors) for i, im in enumerate(
        _array_of_tables(top, "images", "at least one [[images]] table is required")))
    ids = [im.id for im in images]
    if len(set(ids)) != len(ids):
        raise top.error("images", f"duplicate image ids in {ids}")
    terrain = _parse_terrain(top.table("terrain"))
    dems = tuple(_parse_dem(d) for d in _array_of_tables(
        top, "dems", "at least one [[dems]] table (name, spacing_m, rmse_z) is required"))
    if len({d.name for d in dems}) != len(dems):
        raise top.error("dems", f"duplicate DEM names in {[d.name for d in dems]}")
    points = _parse_points(top.table("points"))
    render = _parse_render(top.table("render"))
    report = _parse_report(top.table("report"))
    return Scenario(name, description, seed, images, terrain, dems, points, render, report,
                    method, source, onboard_errors)


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
    out: dict[str, Any] = {
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
    if scenario.onboard_errors is not None:
        out["onboard_errors"] = scenario.onboard_errors
    return out


# ================================================================================ presets
def preset(name: str, variant: str = "small", *, seed: int | None = None) -> Scenario:
    """A named preset (:data:`PRESETS`, :mod:`geoblock.simulate.presets`) as a
    :class:`Scenario`, optionally with another seed.

    Raises
    ------
    ScenarioError
        Unknown preset (the message lists the known ones) or variant.
    """
    data = preset_dict(name, variant)
    if seed is not None:
        data["seed"] = int(seed)
    return scenario_from_dict(data, f"preset:{name}/{variant}")


def demo_scenario(size: str = "small", seed: int | None = None) -> Scenario:
    """The scenario of ``geoblock demo`` (:func:`~geoblock.simulate.presets.demo_dict`).

    Parameters
    ----------
    size : {"small", "tiny"}
    seed : int, optional
        Default: the preset's.

    Raises
    ------
    ScenarioError
        Unknown size (the message lists :data:`~geoblock.simulate.presets.DEMO_SIZES`).
    """
    data = demo_dict(size)
    if seed is not None:
        data["seed"] = int(seed)
    return scenario_from_dict(data, f"demo:{size}")


# ================================================================================ files
def _read_toml(path: Path) -> dict[str, Any]:
    """A scenario file's TOML, its errors as :class:`ScenarioError` naming the file."""
    try:
        return read_toml(path, "the scenario file ")
    except MetadataFieldError as exc:  # not TOML: the parser's line and column
        raise ScenarioError(f"{path}: {exc.problem}") from exc
    except GeoblockIOError as exc:
        raise ScenarioError(str(exc)) from exc


def read_scenario(path: str | os.PathLike[str]) -> Scenario:
    """Read a scenario TOML file (through :func:`geoblock.io.files.read_toml`).

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
    return scenario_from_dict(_read_toml(path), str(path))


def load_scenario(name_or_path: str | os.PathLike[str], variant: str | None = None,
                  seed: int | None = None, onboard_errors: str | None = None) -> Scenario:
    """A preset by name or a scenario file by path, optionally with another variant or seed.

    Parameters
    ----------
    name_or_path : str or os.PathLike
        A name of :data:`PRESETS` or a TOML file.
    variant : {"small", "full"}, optional
        For a preset (default ``small``), or a file that starts from a preset.
    seed : int, optional
        Replaces the scenario's seed.
    onboard_errors : {"realistic", "bias-drift"}, optional
        Replaces the scenario's on-board error model, for every image (the images' own
        ``onboard_errors`` too).

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
        data = _read_toml(path)
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
    if onboard_errors is not None:
        if onboard_errors not in ONBOARD_ERRORS:
            raise ScenarioError(f"unknown on-board error model {onboard_errors!r}; known: "
                                f"{', '.join(ONBOARD_ERRORS)}")
        data["onboard_errors"] = onboard_errors
        if isinstance(data.get("images"), list):
            for image in data["images"]:
                if isinstance(image, dict):
                    image.pop("onboard_errors", None)
    return scenario_from_dict(data, source)


def scenario_toml(scenario: Scenario) -> str:
    """The scenario file of ``scenario``, fully resolved, with a comment naming its source:
    ``geoblock simulate`` on it makes the same block again."""
    from geoblock.io.blocks import dumps_toml

    head = (f"# geoblock scenario (docs: user-guide/simulation.md), from {scenario.source}\n"
            "# run it again with: geoblock simulate scenario.toml OUTDIR\n")
    return head + dumps_toml(scenario_to_dict(scenario))


def write_scenario(path: str | os.PathLike[str], scenario: Scenario) -> Path:
    """Write :func:`scenario_toml` to ``path`` (atomically, through
    :func:`geoblock.io.files.write_text`); :func:`read_scenario` reads it back.

    Raises
    ------
    GeoblockIOError
        The file cannot be written (names it).
    """
    return write_text(path, scenario_toml(scenario), "scenario file ")
