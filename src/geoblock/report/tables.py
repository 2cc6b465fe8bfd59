"""Markdown and CSV tables of accuracy statistics, in the papers' layouts.

* :func:`stats_table`: one row per group (point kind, image, model and GCP count ...), one
  column per statistic; with :data:`AGUILAR_COLUMNS` it is Aguilar et al.'s Table 3
  (RMSE X Y 2D, maximum error X Y, mean error X Y).
* :func:`comparison_table`: Teo et al.'s Tables III-VIII: rows labelled by method,
  adjustment and point kind (``MBA | Block | TP``), column groups per strip or strip pair,
  RMSE E and N in each.

Every function returns the text; :func:`write_table` saves it (atomically).
"""

from __future__ import annotations

import csv
import io
import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from geoblock.adjust.statistics import AccuracyStats, ImageResidualStats
from geoblock.errors import ObservationError
from geoblock.io import files

__all__ = [
    "AGUILAR_COLUMNS",
    "DEFAULT_COLUMNS",
    "HEADINGS",
    "IMAGE_COLUMNS",
    "comparison_table",
    "stats_table",
    "write_table",
]

#: column heading of each statistic (units in brackets)
HEADINGS: dict[str, str] = {
    "n": "n",
    "rmse_e": "RMSE E (m)",
    "rmse_n": "RMSE N (m)",
    "rmse_2d": "RMSE 2D (m)",
    "rmse_1d": "RMSE 1D (m)",
    "mean_e": "Mean E (m)",
    "mean_n": "Mean N (m)",
    "max_e": "Max E (m)",
    "max_n": "Max N (m)",
    "max_2d": "Max 2D (m)",
    "rmse_row": "RMSE row (px)",
    "rmse_col": "RMSE col (px)",
    "mean_row": "Mean row (px)",
    "mean_col": "Mean col (px)",
    "max_row": "Max row (px)",
    "max_col": "Max col (px)",
}
_PIXEL_HEADINGS = {"rmse_2d": "RMSE 2D (px)", "max_2d": "Max 2D (px)"}

#: default columns of ground statistics
DEFAULT_COLUMNS = ("n", "rmse_e", "rmse_n", "rmse_2d", "mean_e", "mean_n", "max_e", "max_n",
                   "max_2d")
#: Aguilar et al. (2007) Table 3: RMSE X Y 2D, maximum error X Y, mean error X Y
AGUILAR_COLUMNS = ("n", "rmse_e", "rmse_n", "rmse_2d", "max_e", "max_n", "mean_e", "mean_n")
#: default columns of image residual statistics
IMAGE_COLUMNS = ("n", "rmse_row", "rmse_col", "rmse_2d", "mean_row", "mean_col", "max_row",
                 "max_col", "max_2d")

_FORMATS = ("markdown", "csv")


def stats_table(
    stats: Mapping[Any, AccuracyStats | ImageResidualStats],
    *,
    labels: Sequence[str] = ("group",),
    columns: Sequence[str] | None = None,
    fmt: str = "markdown",
    decimals: int | None = None,
    title: str | None = None,
) -> str:
    """A table with one row per group of points.

    Parameters
    ----------
    stats : mapping
        Row key -> :class:`~geoblock.adjust.AccuracyStats` (or
        :class:`~geoblock.adjust.ImageResidualStats`, not mixed). A key is a string or a tuple
        with one entry per label, e.g. the output of
        :meth:`~geoblock.adjust.PointErrors.by_kind` (``labels=("kind",)``) or of
        :meth:`~geoblock.adjust.PointErrors.by_image_and_kind` (``labels=("image", "kind")``).
    labels : sequence of str
        Names of the label columns.
    columns : sequence of str, optional
        Statistics to show, among the attributes of the stats objects (``rmse_1d``
        included); default :data:`DEFAULT_COLUMNS` or :data:`IMAGE_COLUMNS`.
        :data:`AGUILAR_COLUMNS` gives Aguilar et al.'s Table 3.
    fmt : {"markdown", "csv"}
    decimals : int, optional
        Decimals of the values; default 2 for Markdown (centimetres), full precision for CSV.
    title : str, optional
        Markdown only: a bold line above the table.

    Returns
    -------
    str
        The table, ending with a newline. Missing values (NaN) are ``—`` in Markdown and
        ``nan`` in CSV.

    Raises
    ------
    ObservationError
        No row, mixed statistics types, an unknown column, a key that does not match
        ``labels`` or an unknown ``fmt``.
    """
    where = "stats_table"
    _check_fmt(fmt, where)
    if not stats:
        raise ObservationError(f"{where}: no statistics given (empty group)")
    kinds = {type(s) for s in stats.values()}
    if len(kinds) > 1 or not kinds <= {AccuracyStats, ImageResidualStats}:
        raise ObservationError(
            f"{where}: values must all be AccuracyStats or all ImageResidualStats, got "
            f"{sorted(k.__name__ for k in kinds)}"
        )
    pixel = kinds == {ImageResidualStats}
    if columns is None:
        columns = IMAGE_COLUMNS if pixel else DEFAULT_COLUMNS
    sample = next(iter(stats.values()))
    _check_columns(columns, sample, where)
    labels = tuple(labels)
    header = [*labels, *(_heading(c, pixel) for c in columns)]
    body = []
    for key, s in stats.items():
        body.append([*_key_cells(key, labels, where), *(getattr(s, c) for c in columns)])
    return _render(header, body, len(labels), fmt, decimals, title)


def comparison_table(
    rows: Mapping[Any, Mapping[str, AccuracyStats]],
    *,
    labels: Sequence[str] = ("method", "adjustment", "kind"),
    quantities: Sequence[str] = ("rmse_e", "rmse_n"),
    counts: bool = True,
    fmt: str = "markdown",
    decimals: int | None = None,
    title: str | None = None,
) -> str:
    """Teo et al.'s comparison table: labelled rows, a group of columns per strip or pair.

    Parameters
    ----------
    rows : mapping
        Row key (a string or a tuple with one entry per label, e.g.
        ``("MBA", "Block", "ICTP")``) -> mapping of column group (e.g. ``"Strips 1 & 2"``)
        -> :class:`~geoblock.adjust.AccuracyStats`. Groups appear in the order first met;
        a row without a group has empty cells there.
    labels : sequence of str
        Names of the label columns.
    quantities : sequence of str
        Statistics per group (default RMSE E and N, as Teo et al.).
    counts : bool
        Add each group's point count ``n`` before its statistics (Teo et al. give the counts
        in the header, "No. TP=19").
    fmt, decimals, title
        As :func:`stats_table`.

    Returns
    -------
    str

    Raises
    ------
    ObservationError
        No row or no group, an unknown quantity, a key that does not match ``labels``.

    Examples
    --------
    >>> from geoblock.adjust import AccuracyStats
    >>> s = AccuracyStats.from_errors([1.0, -1.0], [2.0, 2.0])
    >>> print(comparison_table({("MBA", "Block", "TP"): {"Strips 1 & 2": s}}, counts=False))
    | method | adjustment | kind | Strips 1 & 2 RMSE E (m) | Strips 1 & 2 RMSE N (m) |
    | :--- | :--- | :--- | ---: | ---: |
    | MBA | Block | TP | 1.00 | 2.00 |
    <BLANKLINE>
    """
    where = "comparison_table"
    _check_fmt(fmt, where)
    if not rows:
        raise ObservationError(f"{where}: no row given")
    groups: list[str] = []
    for row in rows.values():
        for g in row:
            if g not in groups:
                groups.append(g)
    if not groups:
        raise ObservationError(f"{where}: the rows have no column group")
    sample = next(s for row in rows.values() for s in row.values())
    _check_columns(quantities, sample, where)
    labels = tuple(labels)
    per_group = (("n",) if counts else ()) + tuple(quantities)
    header = [*labels, *(f"{g} {_heading(q, False)}" for g in groups for q in per_group)]
    body = []
    for key, row in rows.items():
        cells: list[Any] = list(_key_cells(key, labels, where))
        for g in groups:
            s = row.get(g)
            cells.extend(getattr(s, q) if s is not None else None for q in per_group)
        body.append(cells)
    return _render(header, body, len(labels), fmt, decimals, title)


def write_table(text: str, path: str | os.PathLike[str]) -> Path:
    """Write a table's text to ``path`` (UTF-8, atomically,
    :func:`geoblock.io.files.write_text`); returns the path.

    Raises
    ------
    GeoblockIOError
        The file cannot be written.
    """
    return files.write_text(path, text)


# --------------------------------------------------------------------------- helpers
def _check_fmt(fmt: str, where: str) -> None:
    if fmt not in _FORMATS:
        raise ObservationError(f"{where}: fmt must be one of {_FORMATS}, got {fmt!r}")


def _check_columns(columns: Sequence[str], sample: Any, where: str) -> None:
    bad = [c for c in columns if not hasattr(sample, c) or c.startswith("_")]
    if bad:
        known = [c for c in HEADINGS if hasattr(sample, c)]
        raise ObservationError(f"{where}: unknown column(s) {bad}; available: {known}")


def _heading(column: str, pixel: bool) -> str:
    if pixel and column in _PIXEL_HEADINGS:
        return _PIXEL_HEADINGS[column]
    return HEADINGS.get(column, column)


def _key_cells(key: Any, labels: tuple[str, ...], where: str) -> tuple[str, ...]:
    cells = tuple(str(k) for k in key) if isinstance(key, tuple) else (str(key),)
    if len(cells) != len(labels):
        raise ObservationError(
            f"{where}: row key {key!r} has {len(cells)} part(s) but labels {labels} "
            f"has {len(labels)}"
        )
    return cells


def _cell(value: Any, fmt: str, decimals: int | None) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "—" if fmt == "markdown" else ("" if value is None else "nan")
    if isinstance(value, int | str):
        return str(value)
    value = float(value)
    if decimals is None:
        decimals = 2 if fmt == "markdown" else None
    if decimals is None:
        return repr(value)
    text = f"{value:.{decimals}f}"
    return text[1:] if text.startswith("-") and float(text) == 0 else text  # no "-0.00"


def _render(header: list[str], body: list[list[Any]], n_labels: int, fmt: str,
            decimals: int | None, title: str | None) -> str:
    text = [[_cell(v, fmt, decimals) if i >= n_labels else str(v) for i, v in enumerate(row)]
            for row in body]
    if fmt == "csv":
        out = io.StringIO()
        writer = csv.writer(out, lineterminator="\n")
        writer.writerow(header)
        writer.writerows(text)
        return out.getvalue()

    def line(cells: Sequence[str]) -> str:
        return "| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |"

    align = [":---"] * n_labels + ["---:"] * (len(header) - n_labels)
    lines = [f"**{title}**", ""] if title else []
    lines += [line(header), line(align), *(line(r) for r in text)]
    return "\n".join(lines) + "\n"
