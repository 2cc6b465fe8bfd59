"""Point files: CSV with a header line, one point per row.

Column names follow the conventions: ground ``lon, lat, h`` (degrees, metres above the
ellipsoid), image ``row, col`` (pixels, pixel-centre convention), accuracies ``sigma_row,
sigma_col`` (pixels) and ``sigma_e, sigma_n, sigma_h`` (metres), and the text columns ``id``,
``kind`` (``gcp`` | ``icp``) and ``image``. Other columns are kept as text.
"""

from __future__ import annotations

import csv
import io
import os
import sys
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import IO

import numpy as np

from geoblock.errors import GeoblockIOError, ModelFormatError

__all__ = ["PointFileError", "read_points", "write_points"]

TEXT_COLUMNS = frozenset({"id", "kind", "image", "name"})


class PointFileError(ModelFormatError):
    """A point file is malformed (names the file, line and column)."""


def read_points(
    source: str | os.PathLike[str] | IO[str],
    required: Sequence[str] = (),
    optional: Mapping[str, float | str] | None = None,
) -> dict[str, np.ndarray]:
    """Read a CSV point file into column arrays.

    Parameters
    ----------
    source : path, ``"-"`` or text stream
        The file; ``"-"`` reads standard input.
    required : sequence of str
        Columns that must be present.
    optional : mapping, optional
        Columns filled with a default when absent (``{"sigma_row": 0.5}``).

    Returns
    -------
    dict of str to ndarray
        Numeric columns as float64 (N,), text columns (``id``, ``kind``, ``image``, unknown
        ones) as str (N,). An ``id`` column is made up (``"1"``, ``"2"``...) when absent.

    Raises
    ------
    PointFileError
        A required column is missing or a value is not a number (file, line and column named).
    GeoblockIOError
        The file cannot be read.
    """
    name, text = _read_text(source)
    rows = list(csv.reader(io.StringIO(text)))
    rows = [r for r in rows if r and not (len(r) == 1 and not r[0].strip())]
    if not rows:
        raise PointFileError(f"{name}: empty point file (a header line is required)")
    header = [h.strip() for h in rows[0]]
    missing = [c for c in required if c not in header]
    if missing:
        raise PointFileError(
            f"{name}: missing column(s) {missing}; the header has {header}"
        )
    out: dict[str, np.ndarray] = {}
    body = rows[1:]
    for line_no, r in enumerate(body, start=2):
        if len(r) != len(header):
            raise PointFileError(
                f"{name}, line {line_no}: {len(r)} fields but the header has {len(header)}"
            )
    for j, col in enumerate(header):
        values = [r[j].strip() for r in body]
        if col in TEXT_COLUMNS or (col not in required and col not in (optional or {})
                                   and not _all_numeric(values)):
            out[col] = np.array(values, dtype=str)
            continue
        arr = np.empty(len(values))
        for i, v in enumerate(values):
            try:
                arr[i] = float(v) if v not in ("", "nan", "NaN") else np.nan
            except ValueError:
                raise PointFileError(
                    f"{name}, line {i + 2}, column {col!r}: {v!r} is not a number"
                ) from None
        out[col] = arr
    n = len(body)
    for col, default in (optional or {}).items():
        if col not in out:
            out[col] = np.full(n, default, dtype=float if isinstance(default, float | int) else str)
    if "id" not in out:
        out["id"] = np.array([str(i + 1) for i in range(n)], dtype=str)
    return out


def _all_numeric(values: Iterable[str]) -> bool:
    try:
        for v in values:
            if v:
                float(v)
    except ValueError:
        return False
    return True


def _read_text(source: str | os.PathLike[str] | IO[str]) -> tuple[str, str]:
    if hasattr(source, "read"):
        return getattr(source, "name", "<stream>"), source.read()  # type: ignore[union-attr]
    if str(source) == "-":
        return "<stdin>", sys.stdin.read()
    path = Path(source)
    try:
        return str(path), path.read_text(encoding="utf-8-sig")
    except OSError as exc:
        raise GeoblockIOError(f"cannot read point file {str(path)!r}: {exc.strerror}") from exc


def write_points(target: str | os.PathLike[str] | IO[str], columns: Mapping[str, np.ndarray]) -> None:
    """Write column arrays as CSV; floats use the shortest text that round-trips exactly."""
    names = list(columns)
    arrays = [np.asarray(columns[c]).ravel() for c in names]
    n = arrays[0].size if arrays else 0

    def fmt(v: object) -> str:
        if isinstance(v, float | np.floating):
            return "nan" if np.isnan(v) else repr(float(v))
        if isinstance(v, np.integer):
            return str(int(v))
        return str(v)

    def emit(stream: IO[str]) -> None:
        w = csv.writer(stream, lineterminator="\n")
        w.writerow(names)
        for i in range(n):
            w.writerow([fmt(a[i]) for a in arrays])

    if hasattr(target, "write"):
        emit(target)  # type: ignore[arg-type]
    elif str(target) == "-":
        emit(sys.stdout)
    else:
        with open(target, "w", encoding="utf-8", newline="") as f:
            emit(f)
