"""Shared pieces of the RPC readers: result types, GDAL key names and field helpers."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from geoblock.errors import ModelFormatError
from geoblock.io.metadata import ErrorFactory, Fields
from geoblock.io.vsi import VsiPath
from geoblock.models import image_shape
from geoblock_rpc.rpc00b import MAX_PIXELS, Rpc00b


#: a file: a local path or a GDAL virtual path (``/vsizip/...``)
AnyPath = Path | VsiPath
Shape = tuple[int, int]
Result = tuple[Rpc00b, Shape | None, dict[str, Any]]


#: Index in RPC00B order of each RPC00A term: the B-order coefficient ``RPC00A_TO_B[a]`` is the
#: A-order coefficient ``a``. With ``L`` the normalised longitude, ``P`` the latitude and ``H``
#: the height, RPC00A is ``1 L P H LP LH PH LPH L2 P2 H2 L3 L2P L2H LP2 P3 P2H LH2 PH2 H3``
#: (OSSIM ``ossimRpcModel::polynomial``, ``src/projection/ossimRpcModel.cpp`` l. 645-652 at
#: ossimlabs/ossim ``bcf2f33``, type ``A``) and RPC00B
#: ``1 L P H LP LH PH L2 P2 H2 PLH L3 LP2 LH2 L2P P3 PH2 L2H P2H H3`` (the same file's type
#: ``B``, GDAL's ``gdal_rpc.cpp``). The quadratic terms form a 4-cycle (7 -> 10 -> 9 -> 8 -> 7)
#: and the cubic ones three swaps (12 <-> 14, 13 <-> 17, 16 <-> 18). GDAL's NITF reader
#: (``NITFReadRPC00B``, ``anRPC00AMap``) holds the same numbers but reads them the other way
#: round (B term ``i`` from A term ``map[i]``), which inverts the 4-cycle: its quadratic terms
#: are not OSSIM's.
RPC00A_TO_B: tuple[int, ...] = (
    0, 1, 2, 3, 4, 5, 6, 10, 7, 8, 9, 11, 14, 17, 12, 15, 18, 13, 16, 19,
)


def rpc00a_to_b(coefficients: Any) -> np.ndarray:
    """20 RPC00A-order coefficients (last axis) in RPC00B order."""
    a = np.asarray(coefficients, dtype=np.float64)
    b = np.empty_like(a)
    b[..., list(RPC00A_TO_B)] = a
    return b


def gdal_rpc00a_to_b(coefficients: Any) -> np.ndarray:
    """GDAL's reading of an RPC00A TRE (B term ``i`` = A term ``RPC00A_TO_B[i]``) -> the
    RPC00B-order coefficients of :data:`RPC00A_TO_B`'s (OSSIM's) RPC00A order."""
    g = np.asarray(coefficients, dtype=np.float64)
    a = np.empty_like(g)
    a[..., list(RPC00A_TO_B)] = g  # undo GDAL's gather: A term map[i] = g[i]
    return rpc00a_to_b(a)


_SCALAR_KEYS = (
    "LINE_OFF", "SAMP_OFF", "LAT_OFF", "LONG_OFF", "HEIGHT_OFF",
    "LINE_SCALE", "SAMP_SCALE", "LAT_SCALE", "LONG_SCALE", "HEIGHT_SCALE",
)
_POLY_KEYS = ("LINE_NUM_COEFF", "LINE_DEN_COEFF", "SAMP_NUM_COEFF", "SAMP_DEN_COEFF")
_OPTIONAL_KEYS = ("ERR_BIAS", "ERR_RAND", "MIN_LONG", "MIN_LAT", "MAX_LONG", "MAX_LAT")


# ---------------------------------------------------------------------------------- helpers
def _src(path: AnyPath) -> str:
    return str(path)


def _require(md: Mapping[str, Any], keys: Sequence[str], path: AnyPath, what: str) -> None:
    missing = [k for k in keys if k not in md]
    if missing:
        raise ModelFormatError(f"{_src(path)}: {what} lacks {', '.join(missing)}")


def _field_error(what: str, lines: Mapping[str, int] | None = None,
                 quote: bool = False) -> ErrorFactory:
    """The :mod:`geoblock.io.metadata` error factory of one format:
    ``ModelFormatError("<file>[, line n]: <what> field <field> <problem>")`` (the line of a
    text format's key from ``lines``; ``quote`` the field as JSON keys are)."""

    def error(source: str, field: str, problem: str) -> ModelFormatError:
        line = f", line {lines[field]}" if lines and field in lines else ""
        name = repr(field) if quote else field
        return ModelFormatError(f"{source}{line}: {what} field {name} {problem}")

    return error


def _xml_error(source: str, field: str, problem: str) -> ModelFormatError:
    """``read_xml``'s error for a document that is not well-formed: ``<file>: XML: ...``."""
    return ModelFormatError(f"{source}: {field}: {problem}")


#: a GDAL key's source in a format: the file's own key, or one key per coefficient (20)
FieldKeys = Mapping[str, str | Sequence[str]]


def _rpc_from_fields(fields: Fields, keys: FieldKeys) -> Rpc00b:
    """The RPC whose GDAL keys ``keys`` maps to ``fields``' own keys (read through
    :class:`~geoblock.io.metadata.Fields`: numbers, or text starting with one as in
    ``"+015834.00 pixels"``; a coefficient list as 20 numbers or whitespace-separated text,
    or 20 keys). An optional field (``ERR_BIAS``, ``MIN_LONG`` ...) that is absent or has no
    value is absent; the callers have checked that the required keys are present."""
    values: dict[str, Any] = {}
    for gdal_key, key in keys.items():
        if not isinstance(key, str):  # one key per coefficient
            values[gdal_key] = np.array([fields.number(k, from_text=True) for k in key])
        elif gdal_key in _POLY_KEYS:
            values[gdal_key] = fields.numbers(key, count=20)
        elif gdal_key in _OPTIONAL_KEYS:
            value = fields.get(key, None)
            if value is not None and not (isinstance(value, str) and not value.strip()):
                values[gdal_key] = fields.number(key, from_text=True)
        else:
            values[gdal_key] = fields.number(key, from_text=True)
    return Rpc00b.from_gdal(values, source=fields.source)


def _image_size(path: AnyPath, rows: Any, cols: Any, fields: str) -> Shape:
    """``(rows, cols)`` as whole numbers of pixels in 1 .. MAX_PIXELS (whole-number text such
    as ``"2920.0"`` too), by :func:`geoblock.models.image_shape`.

    Raises :class:`ModelFormatError` naming the file and the ``fields`` otherwise.
    """
    return image_shape((rows, cols), f"{_src(path)}: {fields}", maximum=int(MAX_PIXELS))
