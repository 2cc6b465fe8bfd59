"""Fixed-width RPC layouts: the NITF ``RPC00A``/``RPC00B`` TRE body and JAXA's ALOS
PRISM/AVNIR-2 ``RPC-*.txt`` (the same fields without the TRE's leading SUCCESS, ERR_BIAS and
ERR_RAND).

Field widths (characters): LINE_OFF 6, SAMP_OFF 5, LAT_OFF 8, LONG_OFF 9, HEIGHT_OFF 5,
LINE_SCALE 6, SAMP_SCALE 5, LAT_SCALE 8, LONG_SCALE 9, HEIGHT_SCALE 5, then LINE_NUM, LINE_DEN,
SAMP_NUM and SAMP_DEN, 20 coefficients of 12 characters each: 1026 characters (STDI-0002
RPC00B; GDAL's ``NITFReadRPC00B`` and ``GDALMDReaderALOS::LoadRPCTxtFile`` read these widths).
A field that is not a number is refused naming the file, the field and its characters.
"""

from __future__ import annotations

import re
from typing import Any

from geoblock.errors import ModelFormatError
from geoblock.io.metadata import ErrorFactory, Fields
from geoblock_rpc._formats.common import (
    _POLY_KEYS, AnyPath, Result, _rpc_from_fields, _src, gdal_rpc00a_to_b, rpc00a_to_b,
)
from geoblock_rpc.rpc00b import Rpc00b

_WIDTHS = (("LINE_OFF", 6), ("SAMP_OFF", 5), ("LAT_OFF", 8), ("LONG_OFF", 9),
           ("HEIGHT_OFF", 5), ("LINE_SCALE", 6), ("SAMP_SCALE", 5), ("LAT_SCALE", 8),
           ("LONG_SCALE", 9), ("HEIGHT_SCALE", 5))
_COEFF_WIDTH = 12
#: characters of the offsets, scales and 80 coefficients
FIXED_SIZE = sum(w for _, w in _WIDTHS) + 4 * 20 * _COEFF_WIDTH  # 1026
_TRE_HEAD = (("SUCCESS", 1), ("ERR_BIAS", 7), ("ERR_RAND", 7))

def _error(what: str, spans: dict[str, tuple[int, int]]) -> ErrorFactory:
    def error(source: str, field: str, problem: str) -> ModelFormatError:
        a, b = spans.get(field, (0, 0))
        where = f" (characters {a + 1}-{b})" if b else ""
        return ModelFormatError(f"{source}: {what} field {field}{where} {problem}")

    return error

def parse_fixed(source: str, text: str, what: str, *, tre: bool = False,
                rpc00a: bool = False) -> Rpc00b:
    """The RPC of a fixed-width record ``text`` (a TRE body when ``tre``, with SUCCESS,
    ERR_BIAS and ERR_RAND first; coefficients in RPC00A order when ``rpc00a``).

    Raises :class:`ModelFormatError` naming ``source``, ``what``, the field and its characters
    when the record is short or a field is not a number.
    """
    head = _TRE_HEAD if tre else ()
    need = sum(w for _, w in head) + FIXED_SIZE
    if len(text) < need:
        raise ModelFormatError(f"{source}: {what} has {len(text)} characters where the "
                               f"fixed-width RPC layout needs {need}")
    kv: dict[str, str] = {}
    spans: dict[str, tuple[int, int]] = {}
    pos = 0
    for name, width in (*head, *_WIDTHS):
        kv[name], spans[name] = text[pos:pos + width], (pos, pos + width)
        pos += width
    keys: dict[str, Any] = {name: name for name, _ in _WIDTHS}
    for poly in _POLY_KEYS:
        names = tuple(f"{poly}_{i}" for i in range(1, 21))
        for name in names:
            kv[name], spans[name] = text[pos:pos + _COEFF_WIDTH], (pos, pos + _COEFF_WIDTH)
            pos += _COEFF_WIDTH
        keys[poly] = names
    if tre:
        keys.update(ERR_BIAS="ERR_BIAS", ERR_RAND="ERR_RAND")
    rpc = _rpc_from_fields(Fields(source, kv, error=_error(what, spans)), keys)
    if rpc00a:
        rpc = _reordered(rpc, rpc00a_to_b)
    return rpc

def _reordered(rpc: Rpc00b, order: Any) -> Rpc00b:
    return rpc.replace(line_num=order(rpc.line_num), line_den=order(rpc.line_den),
                       samp_num=order(rpc.samp_num), samp_den=order(rpc.samp_den))

def from_gdal_rpc00a(rpc: Rpc00b) -> Rpc00b:
    """An RPC GDAL read from an RPC00A TRE, in RPC00B order (see
    :data:`~geoblock_rpc._formats.common.RPC00A_TO_B`)."""
    return _reordered(rpc, gdal_rpc00a_to_b)


def looks_alos(text: str) -> bool:
    """Whether ``text`` is one fixed-width ALOS RPC record (digits, signs, points and
    exponents only in its first 1026 characters, 80 exponents)."""
    first = text.lstrip("\ufeff").split("\n", 1)[0].rstrip("\r")
    return (FIXED_SIZE <= len(first) < FIXED_SIZE + 64 and first[:FIXED_SIZE].count("E") >= 80
            and not re.search(r"[:=<{]", first))

def parse_alos(path: AnyPath, text: str) -> Result:
    """JAXA's ALOS PRISM/AVNIR-2 ``RPC-*.txt``: one fixed-width line, offsets as stored (as
    GDAL reads them); no image size."""
    first = text.lstrip("\ufeff").split("\n", 1)[0].rstrip("\r")
    rpc = parse_fixed(_src(path), first, "ALOS RPC")
    return rpc, None, {"format": "alos"}
