"""Arguments, options and helpers shared by several ``geoblock`` commands (rasterio's
``rio/options.py``).

Paths stay strings: only :mod:`geoblock.io` opens files, so a missing file is reported by the
reader as one ``Error:`` line (exit code 1), not by click.
"""

from __future__ import annotations

import math
import sys
from typing import Any

import click

__all__ = [
    "bounds_value",
    "crs_value",
    "json_opt",
    "model_arg",
    "model_name_opt",
    "nonnegative_float",
    "open_model_arg",
    "output_opt",
    "points_arg",
    "points_source",
    "positive_float",
]

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


def open_model_arg(model_path: str, model_name: str | None, **options: Any):
    """Open ``MODEL`` with :func:`geoblock.open_model` (errors become one ``Error:`` line)."""
    from geoblock.io import open_model

    return open_model(model_path, model=model_name, **options)


# ---------------------------------------------------------------------- option checks
# click callbacks: a bad value becomes click's one-line usage error naming the option (exit 2)
def positive_float(ctx: click.Context, param: click.Parameter, value: float | None):
    """A float option that must be positive and finite (None passes)."""
    if value is not None and not (math.isfinite(value) and value > 0):
        raise click.BadParameter(f"{value!r} is not a positive finite number.", ctx, param)
    return value


def nonnegative_float(ctx: click.Context, param: click.Parameter, value: float | None):
    """A float option that must be finite and >= 0 (None passes)."""
    if value is not None and not (math.isfinite(value) and value >= 0):
        raise click.BadParameter(f"{value!r} is not a finite number >= 0.", ctx, param)
    return value


def crs_value(ctx: click.Context, param: click.Parameter, value: str | None):
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


def bounds_value(ctx: click.Context, param: click.Parameter, value: tuple | None):
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
