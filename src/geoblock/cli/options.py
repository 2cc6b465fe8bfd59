"""Arguments, options and helpers shared by several ``geoblock`` commands (rasterio's
``rio/options.py``).

Paths stay strings: only :mod:`geoblock.io` opens files, so a missing file is reported by the
reader as one ``Error:`` line (exit code 1), not by click.
"""

from __future__ import annotations

import contextlib
import math
import os
import sys
import warnings
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import click

if TYPE_CHECKING:
    import pyproj

    from geoblock.dem.protocol import DemSource
    from geoblock.models.protocol import SensorModel

__all__ = [
    "bounds_value",
    "check_outputs",
    "crop_offset_opt",
    "crs_value",
    "deprecated_aliases",
    "dem_options",
    "force_opt",
    "finite_values",
    "json_opt",
    "model_arg",
    "model_for_image_arg",
    "model_type_opt",
    "no_crop_opt",
    "nonnegative_float",
    "open_dem_arg",
    "open_model_arg",
    "output_opt",
    "overwrite_opt",
    "points_arg",
    "points_source",
    "positive_float",
    "scheduler_opt",
    "using_scheduler",
    "write_options",
]

def _creation_options(ctx: click.Context, param: click.Parameter,
                      values: tuple[str, ...]) -> dict[str, str]:
    """``--co KEY=VALUE`` (repeatable) -> ``{KEY: VALUE}``, later ones winning."""
    options: dict[str, str] = {}
    for item in values:
        key, sep, value = item.partition("=")
        if not sep or not key.strip() or not key.strip().replace("_", "").isalnum():
            raise click.BadParameter(f"{item!r} is not KEY=VALUE (e.g. --co PREDICTOR=2)",
                                     ctx=ctx, param=param)
        options[key.strip().upper()] = value.strip()
    return options


def _compress_choice() -> click.Choice[str]:
    from geoblock.io.geotiff import COMPRESSIONS

    return click.Choice(COMPRESSIONS, case_sensitive=False)


def write_options(func: Any) -> Any:
    """``--compress NAME``, ``--level N`` and ``--co KEY=VALUE``: how OUT is written."""
    from geoblock.io.geotiff import DEFAULT_COMPRESS

    func = click.option(
        "--co", "creation_options", metavar="KEY=VALUE", multiple=True,
        callback=_creation_options,
        help="GDAL creation option of OUT, repeatable, as gdalwarp -co (PREDICTOR=2, "
        "NUM_THREADS=ALL_CPUS, BIGTIFF=YES, BLOCKXSIZE=256...; with --cog, the COG driver's "
        "options). Wins over --compress and --level.")(func)
    func = click.option(
        "--level", type=click.IntRange(min=1), default=None, metavar="N",
        help="Compression level (ZSTD 1-22, DEFLATE 1-9); default 1, the fastest: GDAL's "
        "defaults (ZSTD 9, DEFLATE 6) cost 2 to 3 times the warp.")(func)
    return click.option(
        "--compress", type=_compress_choice(), default=DEFAULT_COMPRESS, show_default=True,
        help="Compression of OUT. zstd at level 1 costs no time over none while the warp "
        "runs (a 6000 x 6000 uint16 ortho: 51 MB instead of 75 MB); deflate for readers built "
        "without ZSTD; none is what gdalwarp writes by default.")(func)


#: ``MODEL``: sensor-model metadata or geoblock model JSON, read by :func:`geoblock.open_model`.
model_arg = click.argument("model_path", metavar="MODEL")

#: ``--model-type NAME``: read MODEL as this registered model instead of the first reader that
#: recognises it (``--model`` is a sensor-model *file* in every command that takes one).
model_type_opt = click.option(
    "--model-type",
    "model_name",
    metavar="NAME",
    default=None,
    help="Registered model to read MODEL as (see 'geoblock plugins'); "
    "default: the first plugin that recognises the file.",
)

#: ``--crop-offset ROW COL``: the image is a crop of the model's scene starting at that pixel.
crop_offset_opt = click.option(
    "--crop-offset",
    "crop_offset",
    type=float,
    nargs=2,
    metavar="ROW COL",
    default=None,
    callback=lambda ctx, param, value: finite_values(ctx, param, value),
    help="The image is a crop of the model's scene whose first pixel is scene pixel (ROW, "
    "COL); default: as the image's pixel-unit geotransform states it, if it does.",
)

#: ``--no-crop``: use the model's pixels as they are, whatever the image's shape.
no_crop_opt = click.option(
    "--no-crop",
    is_flag=True,
    default=False,
    help="Take image pixel (r, c) as model pixel (r, c): ignore the image's pixel-unit "
    "geotransform and a shape that differs from the model's.",
)

#: ``--force``: accept a model whose image ids differ from the raster's.
force_opt = click.option(
    "--force", is_flag=True, default=False,
    help="Use the model even when its image id (catalog id, datastrip, DIMAP dataset name, "
    "NITF IID2...) differs from the image's: by default such a model, of another image of "
    "the same area, is refused.")

#: ``--json``: machine-readable output.
json_opt = click.option(
    "--json", "as_json", is_flag=True, default=False, help="Write JSON instead of a table."
)

#: ``[POINTS]``: a CSV point file, ``-`` or omitted for standard input.
points_arg = click.argument("points", metavar="[POINTS]", required=False, default="-")

#: ``-o/--output``: a CSV file, ``-`` (the default) for standard output.
output_opt = click.option(
    "-o",
    "--output",
    metavar="OUTPUT",
    default="-",
    show_default=True,
    help="CSV file to write; '-' writes standard output.",
)


def points_source(points: str) -> str:
    """``points`` checked for the one mistake worth catching early: reading a terminal.

    Raises
    ------
    click.UsageError
        ``points`` is standard input and standard input is an interactive terminal (the command
        would otherwise wait silently for typed input).
    """
    if points == "-":
        isatty = getattr(sys.stdin, "isatty", None)
        if isatty is not None and isatty():
            raise click.UsageError(
                "no POINTS file given and standard input is a terminal; "
                "pass a CSV file or pipe one in (for example: cat points.csv | geoblock ...)"
            )
    return points


def open_model_arg(model_path: str, model_name: str | None, **options: Any) -> SensorModel:
    """Open ``MODEL`` with :func:`geoblock.open_model` (errors become one ``Error:`` line)."""
    from geoblock.io import open_model

    return open_model(model_path, model=model_name, **options)


def model_for_image_arg(model: SensorModel, image: Any,
                        crop_offset: tuple[float, float] | None, no_crop: bool,
                        force: bool = False) -> SensorModel:
    """``model`` reconciled with ``image`` (:func:`geoblock.models.crop.model_for_image`).

    Applies the crop offset of ``--crop-offset`` or of the image's pixel-unit geotransform (and
    says so on standard error), refuses an image whose shape differs from the model's with no
    crop offset (one ``Error:`` line naming both shapes, ``--crop-offset`` and ``--no-crop``),
    and a model whose image ids differ from the image's unless ``force`` (``--force``).
    """
    from geoblock.models.crop import CLI_NAMES, CroppedModel, model_for_image

    if no_crop and crop_offset:
        raise click.UsageError("give --crop-offset or --no-crop, not both")
    out = model_for_image(model, image, crop_offset=crop_offset or None, crop=not no_crop,
                          names=CLI_NAMES, force=force)
    if out is not model and not isinstance(out, CroppedModel):  # a size the file did not state
        rows, cols = out.shape
        scene_rows, scene_cols = model.shape
        name = getattr(image, "path", image)
        click.echo(f"{name}: {rows} x {cols} px, taken as the whole scene (the model's file "
                   f"states no image size; its fitted extent is {scene_rows} x {scene_cols} px)",
                   err=True)
    if isinstance(out, CroppedModel) and out is not model:
        rows, cols = out.shape
        scene_rows, scene_cols = model.shape
        source = "--crop-offset" if crop_offset else "its pixel-unit geotransform"
        name = getattr(image, "path", image)
        click.echo(f"{name}: a {rows} x {cols} px crop at row/col {out.offset[0]:g}, "
                   f"{out.offset[1]:g} of the model's {scene_rows} x {scene_cols} px scene "
                   f"({source})", err=True)
    return out


# ---------------------------------------------------------------------- option checks
# click callbacks: a bad value becomes click's one-line usage error naming the option (exit 2)
def positive_float(ctx: click.Context, param: click.Parameter, value: float | None
                   ) -> float | None:
    """A float option that must be positive and finite (None passes)."""
    if value is not None and not (math.isfinite(value) and value > 0):
        raise click.BadParameter(f"{value!r} is not a positive finite number.", ctx, param)
    return value


def nonnegative_float(ctx: click.Context, param: click.Parameter, value: float | None
                      ) -> float | None:
    """A float option that must be finite and >= 0 (None passes)."""
    if value is not None and not (math.isfinite(value) and value >= 0):
        raise click.BadParameter(f"{value!r} is not a finite number >= 0.", ctx, param)
    return value


def crs_value(ctx: click.Context, param: click.Parameter, value: str | None,
              ) -> pyproj.CRS | None:
    """A CRS option (EPSG code, WKT, PROJ string) read by pyproj; a ``pyproj.CRS`` or None."""
    if value is None:
        return None
    import pyproj

    try:
        return pyproj.CRS.from_user_input(value)
    except pyproj.exceptions.CRSError as exc:
        detail = " ".join(str(exc).split())
        raise click.BadParameter(f"{value!r} is not a CRS pyproj knows ({detail}).", ctx,
                                 param) from exc


def finite_values(ctx: click.Context, param: click.Parameter,
                  value: tuple[float, ...] | None) -> tuple[float, ...] | None:
    """A multi-value float option whose values must be finite (None/() gives None)."""
    if not value:
        return None
    if not all(math.isfinite(v) for v in value):
        raise click.BadParameter(f"{' '.join(f'{v:g}' for v in value)}: not finite.", ctx, param)
    return tuple(float(v) for v in value)


def bounds_value(ctx: click.Context, param: click.Parameter,
                 value: tuple[float, float, float, float] | None,
                 ) -> tuple[float, ...] | None:
    """``XMIN YMIN XMAX YMAX``: finite, ``xmin < xmax`` and ``ymin < ymax`` (None/() passes)."""
    if not value:
        return None
    xmin, ymin, xmax, ymax = value
    if not all(math.isfinite(v) for v in value):
        raise click.BadParameter(f"{' '.join(f'{v:g}' for v in value)}: not finite.", ctx, param)
    if not (xmin < xmax and ymin < ymax):
        raise click.BadParameter(
            f"{' '.join(f'{v:g}' for v in value)}: need XMIN < XMAX and YMIN < YMAX "
            "(the order is XMIN YMIN XMAX YMAX).", ctx, param)
    return tuple(float(v) for v in value)


# ---------------------------------------------------------------------- outputs
#: ``--overwrite``: an existing output may be replaced (every command that writes has it).
overwrite_opt = click.option(
    "--overwrite", is_flag=True, default=False,
    help="Replace outputs that exist already. Without it an existing output is refused "
    "before any work (geoblock cannot tell a file of an earlier run from one of yours); an "
    "output that is also an input is refused always.")


def check_outputs(outputs: Mapping[str, Any], inputs: Mapping[str, Any] | None = None, *,
                  overwrite: bool,
                  directories: Iterable[str] = ()) -> None:
    """:func:`geoblock.io.outputs.check_outputs` with the command line's ``--overwrite`` hint:
    call it before any work."""
    from geoblock.io.outputs import check_outputs as check

    check(outputs, inputs, overwrite=overwrite, directories=directories,
          overwrite_hint="pass --overwrite to replace it")


# ---------------------------------------------------------------------- deprecated spellings
def _rewrite(args: Sequence[str], aliases: Mapping[str, str | tuple[str, ...]],
             command: str) -> list[str]:
    out: list[str] = []
    for k, arg in enumerate(args):
        if arg == "--":  # what follows is positional
            out.extend(args[k:])
            break
        name, eq, value = arg.partition("=")
        new = aliases.get(name) if name.startswith("--") else None
        if new is None:
            out.append(arg)
            continue
        tokens = (new,) if isinstance(new, str) else tuple(new)
        warnings.warn(
            f"'geoblock {command} {name}' is deprecated and will be removed in the next "
            f"release: use {' '.join(tokens)}", _deprecation(), stacklevel=2)
        out.extend(tokens[:-1])
        out.append(f"{tokens[-1]}={value}" if eq else tokens[-1])
    return out


def _deprecation() -> type[Warning]:
    from geoblock.errors import GeoblockDeprecationWarning

    return GeoblockDeprecationWarning


def deprecated_aliases(**aliases: str | tuple[str, ...]) -> Callable[[click.Command],
                                                                    click.Command]:
    """Keep old option spellings of a command for one release, hidden from its help.

    ``@deprecated_aliases(vertical="--dem-vertical")`` above ``@click.command`` makes
    ``--vertical X`` (and ``--vertical=X``) mean ``--dem-vertical X``, with a
    :class:`~geoblock.errors.GeoblockDeprecationWarning` naming the new spelling. A value may
    be several tokens (``full=("--variant", "full")`` for a retired flag). The aliases are
    kept in ``command.deprecated_aliases`` (``{"--vertical": "--dem-vertical"}``), which
    the command-line grammar test and the reference read.
    """
    table = {f"--{k.replace('_', '-')}": v for k, v in aliases.items()}

    def decorate(command: click.Command) -> click.Command:
        parse = command.parse_args

        def parse_args(ctx: click.Context, args: list[str]) -> list[str]:
            return parse(ctx, _rewrite(args, table, command.name or ""))

        command.parse_args = parse_args  # type: ignore[method-assign]
        command.deprecated_aliases = table  # type: ignore[attr-defined]
        return command

    return decorate


# ---------------------------------------------------------------------- the DEM
_VOIDS = ("nan", "fill", "nearest")


def _dem_voids(ctx: click.Context, param: click.Parameter, value: str | None
               ) -> str | float | None:
    if value is None or value.lower() in _VOIDS:
        return None if value is None else value.lower()
    try:
        height = float(value)
    except ValueError:
        raise click.BadParameter(f"{value!r} is none of nan, fill, nearest or a height in "
                                 "metres.", ctx, param) from None
    if not math.isfinite(height):
        raise click.BadParameter(f"{value!r} is not a finite height.", ctx, param)
    return height


def dem_options(*, required: bool = True, voids: bool = False,
                required_help: str = "") -> Callable[[Any], Any]:
    """``--dem``, ``--dem-vertical``, ``--geoid`` and, with ``voids``, ``--dem-voids``,
    ``--fill-height`` and ``--dem-interpolation``: one spelling of the DEM in every command.

    Open the DEM with :func:`open_dem_arg` (its errors name these options).
    """
    def decorate(func: Any) -> Any:
        if voids:
            func = click.option(
                "--dem-interpolation", type=click.Choice(["bilinear", "nearest", "bicubic"]),
                default="bilinear", show_default=True,
                help="How heights are sampled between DEM posts.")(func)
            func = click.option(
                "--fill-height", type=float, default=None, metavar="H",
                callback=finite_height,
                help="Ellipsoidal height (metres) wherever the DEM still has none after "
                "--dem-voids, inside it or outside it (GDAL's RPC_DEM_MISSING_VALUE); "
                "default: none, so such points are NaN (status no_dem) or nodata pixels.")(func)
            func = click.option(
                "--dem-voids", default="nan", show_default=True, metavar="nan|fill|nearest|H",
                callback=_dem_voids,
                help="DEM voids (nodata posts inside the DEM): nan leaves them void, fill (or "
                "nearest) fills them from the surrounding posts (GDAL's fillnodata), a number "
                "is a height in the DEM's own datum, metres.")(func)
        func = click.option(
            "--geoid", metavar="GTX", default=None,
            help="Geoid grid (.gtx) for geoid heights; default GEOBLOCK_GEOID or PROJ's "
            "egm96_15.gtx.")(func)
        func = click.option(
            "--dem-vertical", type=click.Choice(["geoid", "ellipsoid"]), default=None,
            help="Vertical datum of the DEM heights when the file does not state it (or to "
            "override it); default: as the file states it.")(func)
        given: dict[str, Any] = {"required": True} if required else {"default": None}
        return click.option(
            "--dem", "dem_source", metavar="DEM", **given,
            help="DEM file (GeoTIFF, SRTM .hgt, VRT, a GDAL virtual path...) or 'const:H' "
            f"(metres above the ellipsoid).{required_help}")(func)

    return decorate


def finite_height(ctx: click.Context, param: click.Parameter, value: float | None
                  ) -> float | None:
    """A float option that must be finite (None passes)."""
    if value is not None and not math.isfinite(value):
        raise click.BadParameter(f"{value!r} is not a finite number.", ctx, param)
    return value


#: What a DEM of geoid heights needs when the geoid grid is not found, on the command line.
GEOID_HINT = "pass --geoid GTX or set GEOBLOCK_GEOID"

#: What a DEM whose datum is not stated needs, on the command line.
DEM_DATUM_HINT = ("pass --dem-vertical geoid (heights above EGM96, e.g. SRTM; with --geoid "
                  "GTX for another geoid, e.g. EGM2008 for the Copernicus DEM) or "
                  "--dem-vertical ellipsoid (heights above WGS84)")


def open_dem_arg(source: str | Sequence[str], vertical: str | None, geoid: str | None,
                 voids: str | float | None = None, fill_height: float | None = None,
                 interpolation: str | None = None) -> DemSource:
    """The DEM of :func:`dem_options`, opened with :func:`geoblock.open_dem`.

    A DEM whose vertical datum is not stated fails with the command line's own hint
    (``--dem-vertical``); ``fill_height`` makes it a :class:`~geoblock.dem.FilledDem`.
    """
    from geoblock.errors import DemDatumError, GeoidNotFoundError
    from geoblock.io.dem import open_dem

    options: dict[str, Any] = {}
    if voids is not None:
        options["nodata"] = voids
    if interpolation is not None:
        options["interpolation"] = interpolation
    if fill_height is not None:
        options["missing"] = fill_height
    try:
        dem = open_dem(source, vertical=vertical, geoid=geoid, **options)
    except DemDatumError as exc:
        raise exc.with_hint(DEM_DATUM_HINT) from None
    except GeoidNotFoundError as exc:
        raise exc.with_hint(GEOID_HINT) from None
    return dem


# ---------------------------------------------------------------------- dask
#: ``--scheduler``: where the chunks are computed, one meaning in every command.
scheduler_opt = click.option(
    "--scheduler", default="threads", show_default=True,
    metavar="threads|processes|synchronous|ADDRESS",
    help="dask scheduler: local threads, local processes, synchronous (one chunk at a time, "
    "for debugging), or the address of a dask.distributed scheduler (tcp://host:8786).")


@contextlib.contextmanager
def using_scheduler(scheduler: str) -> Iterator[Any]:
    """What ``write_ortho(..., scheduler=)`` takes for ``--scheduler``: the name of a local
    scheduler, or a ``distributed.Client`` connected to ADDRESS for the block's duration."""
    if scheduler in ("threads", "processes", "synchronous"):
        yield scheduler
        return
    if "://" not in scheduler and ":" not in scheduler:
        raise click.BadParameter(
            f"{scheduler!r} is none of threads, processes, synchronous or a scheduler "
            "address (tcp://host:8786).", param_hint="--scheduler")
    from distributed import Client

    with Client(scheduler) as client:
        yield client
