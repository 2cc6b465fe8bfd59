"""Arguments, options and helpers shared by several ``geoblock`` commands (rasterio's
``rio/options.py``).

Paths stay strings: only :mod:`geoblock.io` opens files, so a missing file is reported by the
reader as one ``Error:`` line (exit code 1), not by click.
"""

from __future__ import annotations

import math
import sys
from typing import TYPE_CHECKING, Any

import click

if TYPE_CHECKING:
    import pyproj

    from geoblock.models.protocol import SensorModel

__all__ = [
    "bounds_value",
    "crop_offset_opt",
    "crs_value",
    "finite_values",
    "json_opt",
    "model_arg",
    "model_for_image_arg",
    "model_name_opt",
    "no_crop_opt",
    "nonnegative_float",
    "open_model_arg",
    "output_opt",
    "points_arg",
    "points_source",
    "positive_float",
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

#: ``--model NAME``: force a registered model instead of the first reader that recognises MODEL.
model_name_opt = click.option(
    "--model",
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
                        crop_offset: tuple[float, float] | None, no_crop: bool) -> SensorModel:
    """``model`` reconciled with ``image`` (:func:`geoblock.models.crop.model_for_image`).

    Applies the crop offset of ``--crop-offset`` or of the image's pixel-unit geotransform (and
    says so on standard error), refuses an image whose shape differs from the model's with no
    crop offset (one ``Error:`` line naming both shapes, ``--crop-offset`` and ``--no-crop``).
    """
    from geoblock.models.crop import CLI_NAMES, CroppedModel, model_for_image

    if no_crop and crop_offset:
        raise click.UsageError("give --crop-offset or --no-crop, not both")
    out = model_for_image(model, image, crop_offset=crop_offset or None, crop=not no_crop,
                          names=CLI_NAMES)
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
