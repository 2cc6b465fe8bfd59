"""Block files: the TOML description of a block of images to adjust together.

A block file names the images (sensor-model file, optional raster, the parameter set or
image-space correction to adjust), the point files, the DEM with its accuracy, the
adjustment method with the engine's options and the outputs wanted. Relative paths are
relative to the block file's directory. Example::

    # geoblock block file
    version = 1
    name = "taiwan-3-strips"
    method = "dg"             # mba, dg, rfm, rpcv0, rpcv1, default (geoblock.adjust.methods)
    mode = "block"            # or "single": each image alone with its GCPs

    [points]
    ground = "ground.csv"     # id, lon, lat, h, sigma_e, sigma_n, sigma_h, kind (gcp|icp)
    image = "image.csv"       # id, image, row, col, sigma[, kind gcp|icp|tp|ictp]
    truth = "truth.csv"       # optional: simulated truth

    [dem]
    path = "dem.tif"          # or "const:250"
    vertical = "geoid"        # optional: as the file states by default
    geoid = "egm96_15.gtx"    # optional
    sigma = 5.0               # optional: the DEM's accuracy, metres (default 5)

    [reference]               # optional: control from a reference orthoimage (geoblock match)
    path = "gri.tif"          # a georeferenced ortho (any CRS)
    accuracy_ce90_m = 8.0     # its absolute accuracy, CE90 metres (or --reference-accuracy)
    local_accuracy_ce90_m = 2.0   # optional: its point-to-point accuracy, CE90 metres
    band = 1                  # optional: the band matched (1-based)

    [options]                 # the engine's options (ADJUST_OPTIONS), all optional
    dem_control = "observation"   # observation | iterate | none
    robust = "cauchy"             # none | huber | cauchy | snooping
    max_iterations = 30
    sigma_px = 0.5                # measurements without a sigma column
    collocation = { filtering_ratio = 0.2 }
    control_shifts = "consider"   # consider | estimate: a control source's common error
    components = "refuse"         # refuse | separate | joint: disconnected groups of images
    solver = "auto"               # auto | dense | direct | iterative: the reduced system
    covariance = "auto"           # auto | full | none | ["img1", ...]: cofactors computed
    start = "adjusted"            # optional: warm start from a previous geoblock adjust output

    [match]                   # optional: which pairs geoblock match matches (MATCH_OPTIONS)
    min_overlap = 0.1             # share of the smaller footprint
    max_pairs_per_image = 10      # the largest overlaps; a spanning forest is always kept
    min_convergence_deg = 0.0     # lines of sight at the overlap's centre (stereo only)
    max_convergence_deg = 45.0

    [outputs]                 # free-form: name = path
    directory = "out"

    [[images]]
    id = "strip1"
    model = "strip1.json"
    raster = "strip1.tif"     # optional
    parameters = "dg"         # optional: a parameter set of the model (default: the method's)
    accuracy_m = 30.0         # optional: the product's accuracy, for the preset's sigmas
    parameter_options = { knot_lines = 100 }   # optional: options of the parameter set
    sigmas = { dp_along = 10.0, roll_bias = 1e-5 }   # optional a-priori sigmas (0: fixed)

    [[images]]
    id = "scene2"
    model = "scene2_RPC.TXT"
    correction = 1            # optional: an image-space correction of order 0, 1 or 2

:func:`read_block` validates the file (unknown keys, types, duplicate image ids, missing
required fields are errors naming the field) and returns a frozen :class:`Block`;
:func:`write_block` writes one back (paths relative to the new file); :func:`open_block`
also opens the models, point files and DEM for :func:`geoblock.adjust.adjust`.
"""

from __future__ import annotations

import math
import os
import re
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import TYPE_CHECKING, Any

import tomli_w

from geoblock.errors import BlockFileError, GeoblockIOError
from geoblock.io.files import write_text

if TYPE_CHECKING:
    from geoblock.dem.protocol import DemSource

__all__ = ["ADJUST_OPTIONS", "MATCH_OPTIONS", "Block", "BlockDem", "BlockFileError", "BlockImage",
           "BlockReference", "OpenedBlock", "dumps_toml", "open_block", "read_block",
           "write_block"]

BLOCK_FORMAT_VERSION = 1
#: Keys of a block file's ``[match]`` table and the types they take (``geoblock match``'s
#: pair selection, :class:`geoblock.match.MatchOptions`).
MATCH_OPTIONS: Mapping[str, tuple[type, ...]] = MappingProxyType({
    "min_overlap": (int, float), "max_pairs_per_image": (int,),
    "min_convergence_deg": (int, float), "max_convergence_deg": (int, float)})
_METHOD = re.compile(r"^[a-z][a-z0-9_-]*$")
_BARE_KEY = re.compile(r"[A-Za-z0-9_-]+")


def _readonly(mapping: Mapping[str, Any]) -> Mapping[str, Any]:
    return MappingProxyType({k: _freeze(v) for k, v in mapping.items()})


def _freeze(value: Any) -> Any:
    if isinstance(value, Mapping):
        return _readonly(value)
    if isinstance(value, list | tuple):
        return tuple(_freeze(v) for v in value)
    return value


def _thaw(value: Any) -> Any:
    if isinstance(value, Mapping):
        return {k: _thaw(v) for k, v in value.items()}
    if isinstance(value, tuple | list):
        return [_thaw(v) for v in value]
    return value


# ---------------------------------------------------------------------------- values
@dataclass(frozen=True)
class BlockImage:
    """One image of a block.

    Attributes
    ----------
    id : str
        The image's name, as used in the ``image`` column of the measurement file.
    model : pathlib.Path
        Sensor-model file (vendor metadata or model JSON), absolute.
    raster : pathlib.Path or None
        The image's pixels, absolute, if given.
    parameters : str or None
        Name of the parameter set to adjust (a preset of the model such as ``mba`` or ``dg``,
        or ``"default"``); None: the method's.
    sigmas : mapping of str to float
        A-priori sigmas of named parameters, overriding the model's.
    correction : int or None
        Order (0, 1, 2) of an image-space correction wrapped around the model (RPCV-0,
        RPCV-1, order 2); None: the method's.
    accuracy_m : float or None
        The product's location accuracy (1 sigma, metres), for presets whose a-priori sigmas
        derive from it (``dg``, ``mba``).
    parameter_options : mapping of str to value
        Further options of the parameter set, passed to the model's ``with_parameter_set``
        (e.g. ``knot_lines``, ``sigma_rad`` of a linescan model's ``jitter`` set); the model
        names the ones it does not know.
    """

    id: str
    model: Path
    raster: Path | None = None
    parameters: str | None = None
    sigmas: Mapping[str, float] = field(default_factory=dict)
    correction: int | None = None
    accuracy_m: float | None = None
    parameter_options: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        object.__setattr__(self, "sigmas", _readonly(dict(self.sigmas)))
        object.__setattr__(self, "parameter_options", _readonly(dict(self.parameter_options)))


@dataclass(frozen=True)
class BlockDem:
    """The DEM of a block.

    Attributes
    ----------
    source : str
        Absolute path of the DEM file, or ``"const:H"``.
    vertical : {"ellipsoid", "geoid"} or None
        Datum of the heights; ``None``: as the file states.
    geoid : pathlib.Path or None
        Geoid grid, absolute.
    sigma : float or None
        Standard deviation of the DEM's heights, metres (its accuracy, used as the weight of
        the DEM elevation control); None: the adjustment's default (5 m).
    """

    source: str
    vertical: str | None = None
    geoid: Path | None = None
    sigma: float | None = None

    def to_source(self, block_name: str = "the block file") -> DemSource:
        """The DEM, opened with :func:`geoblock.open_dem`.

        Raises
        ------
        DemDatumError
            The file does not state its vertical datum and the block file does not either;
            the message says to set ``vertical`` in ``block_name``'s ``[dem]`` table.
        GeoidNotFoundError
            The geoid grid is not found; the message says to set ``geoid`` there.
        """
        from geoblock.errors import DemDatumError, GeoidNotFoundError
        from geoblock.io.dem import open_dem

        try:
            return open_dem(self.source, vertical=self.vertical, geoid=self.geoid)
        except DemDatumError as exc:
            raise exc.with_hint(
                f"set vertical = \"geoid\" (heights above EGM96, e.g. SRTM; with geoid = "
                f"\"GRID.gtx\" for another geoid) or vertical = \"ellipsoid\" in the [dem] "
                f"table of {block_name}") from None
        except GeoidNotFoundError as exc:
            raise exc.with_hint(f"set geoid = \"path/to/egm96_15.gtx\" in the [dem] table of "
                                f"{block_name}, or GEOBLOCK_GEOID") from None


@dataclass(frozen=True)
class BlockReference:
    """The reference orthoimage of a block: ground control for ``geoblock match``
    (:func:`geoblock.match.match_reference`).

    Attributes
    ----------
    path : pathlib.Path
        The reference orthoimage, absolute.
    accuracy_ce90_m : float or None
        Its absolute accuracy, circular error at 90 %, metres: the weight of every control
        point matched on it. None: ``geoblock match --reference-accuracy`` must give it.
    band : int or None
        The band matched (1-based); None: the first.
    local_accuracy_ce90_m : float or None
        Its local (point-to-point) accuracy, CE90 metres, added to each control point's own
        sigma (:attr:`geoblock.match.ReferenceOptions.local_accuracy_ce90_m`); None: 0.
    """

    path: Path
    accuracy_ce90_m: float | None = None
    band: int | None = None
    local_accuracy_ce90_m: float | None = None


@dataclass(frozen=True)
class Block:
    """A block of images to adjust together, as a block file describes it.

    Attributes
    ----------
    images : tuple of BlockImage
    method : str
        Adjustment method (lower-case name: ``mba``, ``dg``, ``rfm``, ``rpcv0``, ``rpcv1``...;
        the adjustment engine checks it is one it knows).
    ground_points : pathlib.Path or None
        Ground-point CSV (GCPs and ICPs).
    image_points : pathlib.Path or None
        Image-measurement CSV.
    truth : pathlib.Path or None
        Truth CSV of a simulated block.
    dem : BlockDem or None
    options : mapping
        The method's options (read-only; nested tables are read-only mappings, arrays tuples).
    outputs : mapping of str to pathlib.Path
        Output name to absolute path.
    name : str
        Free label.
    mode : {"block", "single"}
        Adjust all images together (with TPs and the DEM) or each alone with its GCPs.
    reference : BlockReference or None
        A reference orthoimage ``geoblock match`` takes ground control from.
    match : mapping
        ``geoblock match``'s pair-selection options (:data:`MATCH_OPTIONS`; read-only).
    """

    images: tuple[BlockImage, ...]
    method: str
    ground_points: Path | None = None
    image_points: Path | None = None
    truth: Path | None = None
    dem: BlockDem | None = None
    options: Mapping[str, Any] = field(default_factory=dict)
    outputs: Mapping[str, Path] = field(default_factory=dict)
    name: str = ""
    mode: str = "block"
    reference: BlockReference | None = None
    match: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        object.__setattr__(self, "images", tuple(self.images))
        object.__setattr__(self, "match", _readonly(dict(self.match)))
        object.__setattr__(self, "options", _readonly(dict(self.options)))
        outputs = {k: Path(v) for k, v in self.outputs.items()}
        object.__setattr__(self, "outputs", _readonly(outputs))
        _check(self, "<Block>")

    def image(self, image_id: str) -> BlockImage:
        """The image of that id (``KeyError`` naming the ids otherwise)."""
        for im in self.images:
            if im.id == image_id:
                return im
        raise KeyError(f"no image {image_id!r} in the block; images: {[i.id for i in self.images]}")


def _check(block: Block, where: str) -> None:
    if not block.images:
        raise BlockFileError(f"{where}: 'images': a block needs at least one image")
    seen: set[str] = set()
    for k, im in enumerate(block.images):
        if not im.id:
            raise BlockFileError(f"{where}: 'images[{k}].id' is empty")
        if im.id in seen:
            raise BlockFileError(f"{where}: 'images[{k}].id': duplicate image id {im.id!r}")
        seen.add(im.id)
        for name, sigma in im.sigmas.items():
            if not (isinstance(sigma, int | float) and not isinstance(sigma, bool) and sigma >= 0):
                raise BlockFileError(f"{where}: 'images[{k}].sigmas.{name}' must be a number >= 0 "
                                     f"(inf for free), got {sigma!r}")
        if im.correction is not None and im.correction not in (0, 1, 2):
            raise BlockFileError(f"{where}: 'images[{k}].correction' must be 0, 1 or 2, got "
                                 f"{im.correction!r}")
        if im.accuracy_m is not None and not (math.isfinite(im.accuracy_m)
                                              and im.accuracy_m > 0):
            raise BlockFileError(f"{where}: 'images[{k}].accuracy_m' must be a number > 0, got "
                                 f"{im.accuracy_m!r}")
    if not _METHOD.fullmatch(block.method):
        raise BlockFileError(f"{where}: 'method' must be a lower-case name such as 'mba', 'dg', "
                             f"'rfm', got {block.method!r}")
    if block.mode not in ("block", "single"):
        raise BlockFileError(f"{where}: 'mode' must be 'block' or 'single', got {block.mode!r}")
    if block.dem is not None and block.dem.sigma is not None and not (
            math.isfinite(block.dem.sigma) and block.dem.sigma > 0):
        raise BlockFileError(f"{where}: 'dem.sigma' must be a number > 0 (metres), got "
                             f"{block.dem.sigma!r}")
    ref = block.reference
    if ref is not None and ref.accuracy_ce90_m is not None and not (
            isinstance(ref.accuracy_ce90_m, int | float)
            and not isinstance(ref.accuracy_ce90_m, bool)
            and math.isfinite(ref.accuracy_ce90_m) and ref.accuracy_ce90_m > 0):
        raise BlockFileError(f"{where}: 'reference.accuracy_ce90_m' must be a number > 0 "
                             f"(metres), got {ref.accuracy_ce90_m!r}")
    if ref is not None and ref.local_accuracy_ce90_m is not None and not (
            isinstance(ref.local_accuracy_ce90_m, int | float)
            and not isinstance(ref.local_accuracy_ce90_m, bool)
            and math.isfinite(ref.local_accuracy_ce90_m) and ref.local_accuracy_ce90_m >= 0):
        raise BlockFileError(f"{where}: 'reference.local_accuracy_ce90_m' must be a number >= 0 "
                             f"(metres), got {ref.local_accuracy_ce90_m!r}")
    if ref is not None and ref.band is not None and not (
            isinstance(ref.band, int) and not isinstance(ref.band, bool) and ref.band >= 1):
        raise BlockFileError(f"{where}: 'reference.band' must be an integer >= 1, got "
                             f"{ref.band!r}")
    if block.dem is not None and block.dem.vertical not in (None, "ellipsoid", "geoid"):
        raise BlockFileError(f"{where}: 'dem.vertical' must be 'ellipsoid' or 'geoid', got "
                             f"{block.dem.vertical!r}")


# ---------------------------------------------------------------------------- reading
_TOML_TYPE = {str: "string", int: "integer", float: "float", bool: "boolean", list: "array",
              dict: "table"}


def _take(table: dict[str, Any], key: str, kind: type | tuple[type, ...], where: str,
          required: bool = False, default: Any = None) -> Any:
    if key not in table:
        if required:
            raise BlockFileError(f"{where}: the required field '{key}' is missing")
        return default
    value = table.pop(key)
    kinds = kind if isinstance(kind, tuple) else (kind,)
    if not isinstance(value, kinds) or (isinstance(value, bool) and bool not in kinds):
        name = " or ".join(_TOML_TYPE.get(k, k.__name__) for k in kinds)
        raise BlockFileError(f"{where}: '{key}' must be a {name}, got {value!r}")
    return value


def _no_more(table: dict[str, Any], where: str, allowed: str) -> None:
    if table:
        raise BlockFileError(f"{where}: unknown field(s) {sorted(table)}; allowed: {allowed}")


def _resolve(base: Path, text: str, where: str) -> Path:
    if not text:
        raise BlockFileError(f"{where}: empty path")
    p = Path(os.path.expanduser(text))
    return p if p.is_absolute() else (base / p).resolve()


def read_block(path: str | os.PathLike[str]) -> Block:
    """Read and validate a block file.

    Parameters
    ----------
    path : str or os.PathLike
        The TOML block file.

    Returns
    -------
    Block
        With every path absolute (relative paths are taken from the file's directory). The
        files named are not opened (nor required to exist yet: outputs may not).

    Raises
    ------
    GeoblockIOError
        The file cannot be read.
    BlockFileError
        Invalid TOML, an unknown or missing field, a value of the wrong type, an unsupported
        ``version``, duplicate image ids (the message names the file and the field).
    """
    path = Path(path)
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise GeoblockIOError(f"cannot read block file {str(path)!r}: {exc.strerror}") from exc
    name = str(path)
    try:
        data = tomllib.loads(raw.decode("utf-8-sig"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise BlockFileError(f"{name}: not a valid TOML file: {exc}") from None
    base = path.resolve().parent

    version = _take(data, "version", int, name, default=BLOCK_FORMAT_VERSION)
    if version != BLOCK_FORMAT_VERSION:
        raise BlockFileError(f"{name}: 'version' {version} is not supported (this geoblock reads "
                             f"version {BLOCK_FORMAT_VERSION})")
    label = _take(data, "name", str, name, default="")
    method = _take(data, "method", str, name, required=True)
    mode = _take(data, "mode", str, name, default="block")

    images_raw = _take(data, "images", list, name, required=True)
    images = []
    for k, item in enumerate(images_raw):
        where = f"{name}: images[{k}]"
        if not isinstance(item, dict):
            raise BlockFileError(f"{where} must be a table ([[images]])")
        item = dict(item)
        image_id = _take(item, "id", str, where, required=True)
        model = _resolve(base, _take(item, "model", str, where, required=True), f"{where}.model")
        raster_text = _take(item, "raster", str, where)
        raster = None if raster_text is None else _resolve(base, raster_text, f"{where}.raster")
        parameters = _take(item, "parameters", str, where)
        sigmas = _take(item, "sigmas", dict, where, default={})
        for key, value in sigmas.items():
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise BlockFileError(f"{where}: 'sigmas.{key}' must be a number, got {value!r}")
        correction = _take(item, "correction", int, where)
        accuracy = _take(item, "accuracy_m", (int, float), where)
        options = _take(item, "parameter_options", dict, where, default={})
        for key, value in options.items():
            if not isinstance(value, bool | int | float | str):
                raise BlockFileError(f"{where}: 'parameter_options.{key}' must be a number, a "
                                     f"string or a boolean, got {value!r}")
        _no_more(item, where, "id, model, raster, parameters, sigmas, correction, accuracy_m, "
                 "parameter_options")
        images.append(BlockImage(image_id, model, raster, parameters,
                                 {k: float(v) for k, v in sigmas.items()}, correction,
                                 None if accuracy is None else float(accuracy), options))

    points = dict(_take(data, "points", dict, name, default={}))
    where = f"{name}: points"
    paths = {}
    for key in ("ground", "image", "truth"):
        text = _take(points, key, str, where)
        paths[key] = None if text is None else _resolve(base, text, f"{where}.{key}")
    _no_more(points, where, "ground, image, truth")

    dem = None
    dem_raw = _take(data, "dem", dict, name)
    if dem_raw is not None:
        dem_raw = dict(dem_raw)
        where = f"{name}: dem"
        source = _take(dem_raw, "path", str, where, required=True)
        if not source.startswith("const:"):
            source = str(_resolve(base, source, f"{where}.path"))
        vertical = _take(dem_raw, "vertical", str, where)
        geoid_text = _take(dem_raw, "geoid", str, where)
        sigma = _take(dem_raw, "sigma", (int, float), where)
        _no_more(dem_raw, where, "path, vertical, geoid, sigma")
        dem = BlockDem(source, vertical,
                       None if geoid_text is None else _resolve(base, geoid_text, f"{where}.geoid"),
                       None if sigma is None else float(sigma))

    reference = None
    ref_raw = _take(data, "reference", dict, name)
    if ref_raw is not None:
        ref_raw = dict(ref_raw)
        where = f"{name}: reference"
        ref_path = _resolve(base, _take(ref_raw, "path", str, where, required=True),
                            f"{where}.path")
        accuracy = _take(ref_raw, "accuracy_ce90_m", (int, float), where)
        band = _take(ref_raw, "band", int, where)
        local = _take(ref_raw, "local_accuracy_ce90_m", (int, float), where)
        _no_more(ref_raw, where, "path, accuracy_ce90_m, local_accuracy_ce90_m, band")
        reference = BlockReference(ref_path, None if accuracy is None else float(accuracy),
                                   band, None if local is None else float(local))

    match = dict(_take(data, "match", dict, name, default={}))
    for key, value in match.items():
        kinds = MATCH_OPTIONS.get(key)
        if kinds is None:
            raise BlockFileError(f"{name}: unknown key 'match.{key}'; allowed: "
                                 f"{', '.join(MATCH_OPTIONS)}")
        if isinstance(value, bool) or not isinstance(value, kinds):
            raise BlockFileError(f"{name}: 'match.{key}' must be "
                                 f"{'an integer' if kinds == (int,) else 'a number'}, got "
                                 f"{value!r}")
    options = _take(data, "options", dict, name, default={})
    outputs_raw = dict(_take(data, "outputs", dict, name, default={}))
    outputs = {}
    for key, value in outputs_raw.items():
        if not isinstance(value, str):
            raise BlockFileError(f"{name}: 'outputs.{key}' must be a path (string), got {value!r}")
        outputs[key] = _resolve(base, value, f"{name}: outputs.{key}")
    _no_more(data, name, "version, name, method, mode, images, points, dem, reference, "
             "match, options, outputs")
    try:
        return Block(tuple(images), method, paths["ground"], paths["image"], paths["truth"], dem,
                     options, outputs, label, mode, reference, match)
    except BlockFileError as exc:
        raise BlockFileError(str(exc).replace("<Block>", name)) from None


# ---------------------------------------------------------------------------- writing
def _relative(path: Path | str, base: Path) -> str:
    text = str(path)
    if text.startswith("const:"):
        return text
    p = Path(path).absolute()  # a relative path is relative to the working directory
    try:
        return Path(os.path.relpath(p, base)).as_posix()
    except ValueError:  # another drive (Windows)
        return str(p)


def block_to_dict(block: Block, base: str | os.PathLike[str] | None = None) -> dict[str, Any]:
    """The block as the TOML document's dictionary; paths relative to ``base`` if given."""
    b = Path(base).absolute() if base is not None else None

    def rel(p: Path | str) -> str:
        return _relative(p, b) if b is not None else str(p)

    out: dict[str, Any] = {"version": BLOCK_FORMAT_VERSION}
    if block.name:
        out["name"] = block.name
    out["method"] = block.method
    if block.mode != "block":
        out["mode"] = block.mode
    points = {k: rel(v) for k, v in (("ground", block.ground_points), ("image", block.image_points),
                                     ("truth", block.truth)) if v is not None}
    if points:
        out["points"] = points
    if block.dem is not None:
        dem: dict[str, Any] = {"path": rel(block.dem.source)}
        if block.dem.vertical is not None:
            dem["vertical"] = block.dem.vertical
        if block.dem.geoid is not None:
            dem["geoid"] = rel(block.dem.geoid)
        if block.dem.sigma is not None:
            dem["sigma"] = block.dem.sigma
        out["dem"] = dem
    if block.reference is not None:
        ref: dict[str, Any] = {"path": rel(block.reference.path)}
        if block.reference.accuracy_ce90_m is not None:
            ref["accuracy_ce90_m"] = block.reference.accuracy_ce90_m
        if block.reference.local_accuracy_ce90_m is not None:
            ref["local_accuracy_ce90_m"] = block.reference.local_accuracy_ce90_m
        if block.reference.band is not None:
            ref["band"] = block.reference.band
        out["reference"] = ref
    if block.match:
        out["match"] = dict(block.match)
    if block.options:
        out["options"] = _thaw(block.options)
    if block.outputs:
        out["outputs"] = {k: rel(v) for k, v in block.outputs.items()}
    images = []
    for im in block.images:
        item: dict[str, Any] = {"id": im.id, "model": rel(im.model)}
        if im.raster is not None:
            item["raster"] = rel(im.raster)
        if im.parameters is not None:
            item["parameters"] = im.parameters
        if im.sigmas:
            item["sigmas"] = dict(im.sigmas)
        if im.correction is not None:
            item["correction"] = im.correction
        if im.accuracy_m is not None:
            item["accuracy_m"] = im.accuracy_m
        if im.parameter_options:
            item["parameter_options"] = dict(im.parameter_options)
        images.append(item)
    out["images"] = images
    return out


def write_block(path: str | os.PathLike[str], block: Block) -> Path:
    """Write a block file (atomically: a temporary name in the same directory, then renamed).

    Paths are written relative to the file's directory (absolute when on another drive), so
    that a block directory can be moved as a whole; :func:`read_block` gives back an equal
    :class:`Block`.

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    path = Path(path)
    text = "# geoblock block file (docs: user-guide/simulation.md)\n" + dumps_toml(
        block_to_dict(block, path.parent))
    write_text(path, text, "block file ")
    return path


# ---------------------------------------------------------------------------- TOML text
def dumps_toml(data: Mapping[str, Any]) -> str:
    """A TOML document of ``data``; ``tomllib.loads`` gives it back.

    Values may be str, int, float (``nan`` and ``inf`` included), bool, lists or tuples, and
    mappings (nested tables); a :class:`pathlib.Path` is written as its text. ``tomli-w``
    writes the scalar values and quoted keys, arrays of values stay on one line, and the layout
    is fixed so that the file reads, and can be edited, top-down: each table's own keys
    first, then its sub-tables (``[a.b]``) and arrays of tables (``[[images]]``, one section
    per item), each section after a blank line.

    Raises
    ------
    BlockFileError
        A value TOML cannot hold (names its key, e.g. ``images.0.raster``).
    """
    return _table_text(_plain(data, ""), ())


def _table_text(table: dict[str, Any], name: tuple[str, ...]) -> str:
    values = {k: v for k, v in table.items() if not _is_section(v)}
    parts = ["".join(f"{_key(k)} = {_inline(v)}\n" for k, v in values.items())] if values else []
    for key, value in table.items():
        if not _is_section(value):
            continue
        header = ".".join(_key(part) for part in (*name, key))
        if isinstance(value, dict):
            parts.append(f"[{header}]\n" + _table_text(value, (*name, key)))
        else:
            parts.extend(f"[[{header}]]\n" + _table_text(item, (*name, key)) for item in value)
    return "\n".join(parts)


def _is_section(value: Any) -> bool:
    """A table, or a non-empty array of tables: written as ``[...]`` / ``[[...]]`` sections."""
    return isinstance(value, dict) or (
        isinstance(value, list) and bool(value) and all(isinstance(v, dict) for v in value))


def _inline(value: Any) -> str:
    """A value on one line: arrays as ``[a, b]`` (tomli-w alone spreads every array over
    several lines), scalars as tomli-w writes them."""
    if isinstance(value, list):
        return "[" + ", ".join(_inline(v) for v in value) + "]"
    if isinstance(value, dict):  # a table inside an array of values: an inline table
        return "{" + ", ".join(f"{_key(k)} = {_inline(v)}" for k, v in value.items()) + "}"
    return tomli_w.dumps({"k": value}).removeprefix("k = ").removesuffix("\n")


def _key(key: str) -> str:
    """A key of a section header: bare if it can be, else quoted as tomli-w quotes strings."""
    if _BARE_KEY.fullmatch(key):
        return key
    return tomli_w.dumps({"k": key}).removeprefix("k = ").removesuffix("\n")


def _plain(value: Any, where: str) -> Any:
    """``value`` with mappings as dicts, tuples as lists and paths as text, checked for TOML."""
    if isinstance(value, Mapping):
        return {str(k): _plain(v, f"{where}.{k}" if where else str(k)) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v, f"{where}.{i}") for i, v in enumerate(value)]
    if isinstance(value, Path):
        return str(value)
    if isinstance(value, bool | str):
        return value
    if isinstance(value, int):
        return int(value)
    if isinstance(value, float):  # numpy's float64 too, written as a plain float
        return float(value)
    raise BlockFileError(f"TOML writer: {where}: cannot write a {type(value).__name__} "
                         f"({value!r})")


# ---------------------------------------------------------------------------- opening
#: engine options a block file's ``[options]`` table may set, with their types
ADJUST_OPTIONS: Mapping[str, tuple[type, ...]] = MappingProxyType({
    "dem_control": (str,), "tp_sigma_factor": (int, float), "tp_sigma_m": (int, float),
    "tp_prior": (str,), "robust": (str,), "robust_k": (int, float), "alpha": (float,),
    "max_iterations": (int,), "tolerance": (int, float), "collocation": (bool, Mapping),
    "sigma_px": (int, float), "control_shifts": (str,), "components": (str,),
    "solver": (str,), "covariance": (str, list, tuple), "start": (str,),
})
_COLLOCATION_KEYS = ("filtering_ratio", "d_max")


def _is_option_kind(value: Any, kinds: tuple[type, ...]) -> bool:
    """``value`` is one of ``kinds`` (a bool only where ``bool`` is one of them)."""
    return isinstance(value, kinds) and (bool in kinds or not isinstance(value, bool))


@dataclass(frozen=True, eq=False)
class OpenedBlock:
    """A block file opened for :func:`geoblock.adjust.adjust`.

    Attributes
    ----------
    spec : Block
        The file's description.
    block : geoblock.adjust.Block
        Models (with their parameter sets), points and DEM.
    options : dict
        Keyword arguments of :func:`geoblock.adjust.adjust` (``mode`` included).
    """

    spec: Block
    block: Any
    options: dict[str, Any]


def open_block(path: str | os.PathLike[str] | Block, *, name: str | None = None
               ) -> OpenedBlock:
    """Open a block file: read it, open every model, point file and the DEM.

    The method (``mba``, ``dg``, ``rfm``, ``rpcv0``, ``rpcv1``, ``default``: see
    :mod:`geoblock.adjust.methods`) gives each image its parameter set or correction unless
    the image states its own; ``[options]`` may set the engine's options
    (:data:`ADJUST_OPTIONS`) and nothing else.

    Parameters
    ----------
    path : str, path-like or Block
        The block file, or one already read (:func:`read_block`).
    name : str, optional
        How messages name the block (default: its path, or ``"<block>"`` for a Block).

    Raises
    ------
    BlockFileError
        An unknown method or option, a value of the wrong type, a model or point file that
        cannot be used (the message names the file and the field).
    GeoblockError
        Whatever opening a model, a point file or the DEM raises (names the file).
    """
    from geoblock.adjust.block import Block as AdjustBlock
    from geoblock.adjust.methods import METHODS, prepare_model
    from geoblock.errors import AdjustmentError
    from geoblock.io.models import open_model
    from geoblock.io.points import PointFileError, read_observations

    spec = path if isinstance(path, Block) else read_block(path)
    if name is None:
        name = "<block>" if isinstance(path, Block) else str(path)
    if spec.method not in METHODS:
        raise BlockFileError(f"{name}: 'method' {spec.method!r} is not known; methods: "
                             f"{', '.join(METHODS)}")
    method = METHODS[spec.method]
    options: dict[str, Any] = {"mode": spec.mode}
    if method["collocation"]:
        options["collocation"] = True
    reading: dict[str, float] = {}  # sigma_px: read_observations' default unless given
    for key, value in spec.options.items():
        where = f"{name}: options.{key}"
        if key not in ADJUST_OPTIONS:
            raise BlockFileError(f"{where}: unknown option; options: {', '.join(ADJUST_OPTIONS)}")
        kinds = ADJUST_OPTIONS[key]
        if not _is_option_kind(value, kinds):
            raise BlockFileError(f"{where} must be a {' or '.join(k.__name__ for k in kinds)}, "
                                 f"got {value!r}")
        if key == "sigma_px":
            reading["sigma_px"] = float(value)
            continue
        if key == "start" and not isinstance(path, Block):  # relative to the block file
            value = str(Path(path).resolve().parent / value)
        if key == "covariance" and not isinstance(value, str):
            if not all(isinstance(v, str) for v in value):
                raise BlockFileError(f"{where} must be auto, full, none or an array of image "
                                     f"ids, got {value!r}")
            value = list(value)
        if key == "collocation" and isinstance(value, Mapping):
            unknown = sorted(set(value) - set(_COLLOCATION_KEYS))
            if unknown:
                raise BlockFileError(f"{where}: unknown key(s) {unknown}; allowed: "
                                     f"{', '.join(_COLLOCATION_KEYS)}")
            value = dict(value)
        options[key] = value
    if spec.image_points is None:
        raise BlockFileError(f"{name}: 'points.image' (the image measurements) is required")
    try:
        ground, measurements = read_observations(spec.ground_points, spec.image_points,
                                                 **reading)
    except PointFileError as exc:
        raise BlockFileError(str(exc)) from None
    models = {}
    for k, im in enumerate(spec.images):
        where = f"{name}: images[{k}] ({im.id})"
        model = open_model(im.model)
        try:
            models[im.id] = prepare_model(
                model, parameters=im.parameters if im.parameters is not None
                else method["parameters"],
                correction=im.correction if im.correction is not None else method["correction"],
                accuracy_m=im.accuracy_m, options=im.parameter_options, where=where)
        except AdjustmentError as exc:
            raise BlockFileError(str(exc)) from None
    dem = None
    extra: dict[str, Any] = {}  # the Block's default DEM sigma unless the file gives one
    if spec.dem is not None:
        dem = spec.dem.to_source(name)
        if spec.dem.sigma is not None:
            extra["dem_sigma_m"] = spec.dem.sigma
    try:
        block = AdjustBlock(models, measurements, ground, dem,
                            sigmas={im.id: dict(im.sigmas) for im in spec.images if im.sigmas},
                            **extra)
    except AdjustmentError as exc:
        raise BlockFileError(f"{name}: {exc}") from None
    return OpenedBlock(spec, block, options)
