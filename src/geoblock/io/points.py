"""Point files: CSV with a header line, one point per row.

Column names follow the conventions: ground ``lon, lat, h`` (degrees, metres above the
ellipsoid), image ``row, col`` (pixels, pixel-centre convention), accuracies ``sigma_row,
sigma_col`` (pixels) and ``sigma_e, sigma_n, sigma_h``, ``sigma_shift_e, sigma_shift_n,
sigma_shift_h`` (metres), and the text columns ``id``, ``kind`` (``gcp`` | ``icp`` | ``hcp``),
``source`` and ``image``. Other columns are kept as text, exactly as written.
"""

from __future__ import annotations

import csv
import io
import os
import sys
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import IO, TYPE_CHECKING

import numpy as np

from geoblock.errors import GeoblockIOError, PointFileError
from geoblock.io.files import write_with

if TYPE_CHECKING:
    from geoblock.adjust.observations import GroundPoints, ImagePoints

__all__ = ["PointFileError", "read_observations", "read_points", "write_points"]

NUMERIC_COLUMNS = frozenset(
    {"lon", "lat", "h", "row", "col", "x", "y", "z", "sigma", "sigma_row", "sigma_col",
     "sigma_e", "sigma_n", "sigma_h", "sigma_shift_e", "sigma_shift_n", "sigma_shift_h"}
)


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
        The coordinate and sigma columns (``lon, lat, h, row, col, x, y, z, sigma_*``) and the
        ``required`` and ``optional`` ones as float64 (N,); every other column as str (N,),
        exactly as written. An ``id`` column is made up (``"1"``, ``"2"``...) when absent.

    Raises
    ------
    PointFileError
        A required column is missing, a column name appears twice in the header, a value is
        not a number (file, line and column named), or the file is not UTF-8 text.
    GeoblockIOError
        The file cannot be read.
    """
    name, text = _read_text(source)
    reader = csv.reader(io.StringIO(text))
    records = [(reader.line_num, r) for r in reader if any(f.strip() for f in r)]
    if not records:
        raise PointFileError(f"{name}: empty point file (a header line is required)")
    header = [h.strip() for h in records[0][1]]
    duplicated = sorted({h for h in header if header.count(h) > 1})
    if duplicated:
        raise PointFileError(
            f"{name}, line {records[0][0]}: duplicated column(s) {duplicated} in the header "
            f"{header}; each column must appear once"
        )
    missing = [c for c in required if c not in header]
    if missing:
        raise PointFileError(f"{name}: missing column(s) {missing}; the header has {header}")
    body = records[1:]
    for line_no, r in body:
        if len(r) != len(header):
            raise PointFileError(
                f"{name}, line {line_no}: {len(r)} fields but the header has {len(header)}"
            )
    numeric = NUMERIC_COLUMNS | set(required) | set(optional or {})
    out: dict[str, np.ndarray] = {}
    for j, col in enumerate(header):
        values = [r[j].strip() for _, r in body]
        if col not in numeric:
            out[col] = np.array(values, dtype=str)
            continue
        arr = np.empty(len(values))
        for i, ((line_no, _), v) in enumerate(zip(body, values, strict=True)):
            try:
                arr[i] = float(v) if v not in ("", "nan", "NaN") else np.nan
            except ValueError:
                raise PointFileError(
                    f"{name}, line {line_no}, column {col!r}: {v!r} is not a number"
                ) from None
        out[col] = arr
    n = len(body)
    for col, default in (optional or {}).items():
        if col not in out:
            out[col] = np.full(n, default, dtype=float if isinstance(default, float | int) else str)
    if "id" not in out:
        out["id"] = np.array([str(i + 1) for i in range(n)], dtype=str)
    return out


def _read_text(source: str | os.PathLike[str] | IO[str]) -> tuple[str, str]:
    if hasattr(source, "read"):
        name = str(getattr(source, "name", "<stream>"))
        return name, _decoded(name, source.read)
    if str(source) == "-":
        return "<stdin>", _decoded("<stdin>", sys.stdin.read)
    path = Path(source)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise GeoblockIOError(f"cannot read point file {str(path)!r}: {exc.strerror}") from exc
    return str(path), _decoded(str(path), lambda: data.decode("utf-8-sig"))


def _decoded(name: str, read: Callable[[], str | bytes]) -> str:
    """The text ``read()`` gives; a decoding failure becomes a :class:`PointFileError`."""
    try:
        text = read()
        if isinstance(text, bytes):
            text = text.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise PointFileError(
            f"{name}: not UTF-8 text (byte 0x{exc.object[exc.start]:02x} at offset {exc.start}); "
            "save the point file as UTF-8"
        ) from None
    return text.removeprefix("\ufeff")


def write_points(
    target: str | os.PathLike[str] | IO[str], columns: Mapping[str, np.ndarray]
) -> None:
    """Write column arrays as CSV; floats use the shortest text that round-trips exactly.

    Parameters
    ----------
    target : path, ``"-"`` or text stream
        A file is written atomically (:func:`geoblock.io.files.write_with`: under a temporary
        beside it, renamed when complete), so that a failure (a full disk, ``Ctrl-C``)
        leaves a previous file as it was and no temporary; ``"-"`` writes standard output
        and a stream is written as it is.
    columns : mapping of str to array
        The columns, in order, all of one length.

    Raises
    ------
    GeoblockIOError
        The file cannot be written: one line naming ``target`` (a full disk says so).
    """
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
        write_with(target, emit, "point file ", encoding="utf-8")


def read_observations(
    ground: str | os.PathLike[str] | None,
    image: str | os.PathLike[str],
    *,
    sigma_px: float = 0.5,
) -> tuple[GroundPoints | None, ImagePoints]:
    """Read a block's two point files into the adjustment's tables.

    Parameters
    ----------
    ground : path or None
        Ground CSV: ``id, lon, lat, h[, sigma_e, sigma_n, sigma_h][, kind][, source]
        [, sigma_shift_e, sigma_shift_n, sigma_shift_h]`` (kind gcp|icp|hcp; ``lon, lat``
        may be empty in ``hcp`` rows, and absent when every row is one).
    image : path
        Image-measurement CSV: ``id, image, row, col[, sigma | sigma_row, sigma_col][, kind]``.
    sigma_px : float
        Measurement sigma (pixels) of rows without one.

    Returns
    -------
    (GroundPoints or None, ImagePoints)

    Raises
    ------
    PointFileError
        A file is malformed or a table refuses its values (the message names the file).
    """
    from geoblock.adjust.observations import GroundPoints, ImagePoints
    from geoblock.errors import ObservationError

    try:
        measurements = ImagePoints.from_columns(read_points(image, required=("row", "col")),
                                                source=str(image), sigma=sigma_px)
        points = None if ground is None else GroundPoints.from_columns(
            read_points(ground, required=("h",)), source=str(ground))
    except ObservationError as exc:
        raise PointFileError(str(exc)) from None
    return points, measurements

