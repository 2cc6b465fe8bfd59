"""Arguments, options and helpers shared by several ``geoblock`` commands (rasterio's
``rio/options.py``).

Paths stay strings: only :mod:`geoblock.io` opens files, so a missing file is reported by the
reader as one ``Error:`` line (exit code 1), not by click.
"""

from __future__ import annotations

import sys
from typing import Any

import click

__all__ = [
    "json_opt",
    "model_arg",
    "model_name_opt",
    "open_model_arg",
    "output_opt",
    "points_arg",
    "points_source",
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
