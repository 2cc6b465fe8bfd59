"""DigitalGlobe / Maxar: the ``.RPB`` keyword file and the ISD XML's ``<RPB>`` section."""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from collections.abc import Callable
from typing import Any

from geoblock.errors import ModelFormatError
from geoblock.io.metadata import Fields
from geoblock_rpc._formats.common import (
    AnyPath, _POLY_KEYS, _SCALAR_KEYS, Result, _field_error, _image_size, _require, _rpc_from_fields,
    _src,
)


_RPB_MAP = {
    "ERRBIAS": "ERR_BIAS", "ERRRAND": "ERR_RAND",
    "LINEOFFSET": "LINE_OFF", "SAMPOFFSET": "SAMP_OFF", "LATOFFSET": "LAT_OFF",
    "LONGOFFSET": "LONG_OFF", "HEIGHTOFFSET": "HEIGHT_OFF",
    "LINESCALE": "LINE_SCALE", "SAMPSCALE": "SAMP_SCALE", "LATSCALE": "LAT_SCALE",
    "LONGSCALE": "LONG_SCALE", "HEIGHTSCALE": "HEIGHT_SCALE",
    "LINENUMCOEF": "LINE_NUM_COEFF", "LINEDENCOEF": "LINE_DEN_COEFF",
    "SAMPNUMCOEF": "SAMP_NUM_COEFF", "SAMPDENCOEF": "SAMP_DEN_COEFF",
}
_RPB_ITEM = re.compile(r"(\w+)\s*=\s*(\([^)]*\)|[^;]*?)\s*;", re.DOTALL)


def _parse_rpb(path: AnyPath, text: str) -> Result:
    m = re.search(r"BEGIN_GROUP\s*=\s*IMAGE(.*?)END_GROUP\s*=\s*IMAGE", text, re.S | re.I)
    if m is None:
        raise ModelFormatError(f"{_src(path)}: RPB has no complete BEGIN_GROUP = IMAGE ... "
                               "END_GROUP = IMAGE block")
    kv: dict[str, str] = {}  # the file's keys (lineOffset ...) -> value text
    keys: dict[str, str] = {}  # GDAL key -> the file's key
    for key, value in _RPB_ITEM.findall(m[1]):
        gkey = _RPB_MAP.get(key.upper())
        if gkey is None:
            continue
        value = value.strip()
        if value.startswith("("):  # a list: ( a, b, ... )
            value = " ".join(v.strip() for v in value[1:-1].split(",") if v.strip())
        kv[key], keys[gkey] = value, key
    _require(keys, _SCALAR_KEYS + _POLY_KEYS,
             path, "RPB (DigitalGlobe keys lineOffset ... sampDenCoef)")
    rpc = _rpc_from_fields(Fields(_src(path), kv, error=_field_error("RPB")), keys)
    extra: dict[str, Any] = {"format": "rpb"}
    for key, value in _RPB_ITEM.findall(text[: m.start()]):
        extra[{"satid": "satellite_id", "bandid": "band_id", "specid": "spec_id"}.get(
            key.lower(), key)] = value.strip().strip('"')
    return rpc, None, extra

def _parse_isd(path: AnyPath, root: ET.Element) -> Result:
    image = root.find("RPB/IMAGE")
    if image is None:
        raise ModelFormatError(
            f"{_src(path)}: DigitalGlobe ISD XML without an <RPB><IMAGE> section: no RPC "
            "coefficients in this file (use its physical model or the product's .RPB)"
        )
    kv: dict[str, str] = {}  # the ISD's tags -> value text (a list's items joined)
    keys: dict[str, str] = {}  # GDAL key -> ISD tag
    for child in image:
        gkey = _RPB_MAP.get(child.tag.upper().removesuffix("LIST"))
        if gkey is None:
            continue
        if len(child):
            kv[child.tag] = " ".join((c.text or "").strip() for c in child)
        else:
            kv[child.tag] = (child.text or "").strip()
        keys[gkey] = child.tag
    _require(keys, _SCALAR_KEYS + _POLY_KEYS, path, "ISD <RPB><IMAGE>")
    rpc = _rpc_from_fields(Fields(_src(path), kv, error=_field_error("ISD <RPB><IMAGE>")), keys)
    extra: dict[str, Any] = {"format": "dg-isd"}
    catid = (root.findtext("IMD/IMAGE/CATID") or "").strip()
    if catid:
        extra["source_ids"] = {"catalog_id": catid}
    satid = root.findtext("RPB/SATID") or root.findtext("IMD/IMAGE/SATID")
    if satid:
        extra["satellite_id"] = satid.strip()
    shape = None
    rows, cols = root.findtext("IMD/NUMROWS"), root.findtext("IMD/NUMCOLUMNS")
    if rows is not None or cols is not None:
        shape = _image_size(path, rows, cols, "ISD <IMD><NUMROWS>/<NUMCOLUMNS>")
    return rpc, shape, extra


_IMD_ITEM = re.compile(r"^\s*(\w+)\s*=\s*([^;]*?)\s*;", re.MULTILINE)


def looks_imd(text: str) -> bool:
    """A DigitalGlobe ``.IMD`` keyword file: an ``IMAGE_n`` group and ``numRows``, no RPC."""
    return (re.search(r"BEGIN_GROUP\s*=\s*IMAGE_\d", text, re.IGNORECASE) is not None
            and re.search(r"^\s*numRows\s*=", text, re.MULTILINE | re.IGNORECASE) is not None
            and re.search(r"\blineOffset\s*=", text, re.IGNORECASE) is None)


def _sibling(path: AnyPath, suffix: str) -> AnyPath | None:
    for name in (path.stem + suffix, path.stem + suffix.lower()):
        candidate = path.parent / name
        if candidate.is_file():
            return candidate
    return None


def parse_imd(path: AnyPath, text: str, rpb_text: Callable[[AnyPath], str]) -> Result:
    """A DigitalGlobe ``.IMD`` given alone: the RPC of an RPC-only product is its ``.RPB``
    (same name, DigitalGlobe Imagery Support Data documentation), read beside it; the image's
    size and the satellite from the ``.IMD``.

    Raises :class:`ModelFormatError` naming the ``.RPB`` looked for when it is not there.
    """
    rpb = _sibling(path, ".RPB")
    if rpb is None:
        raise ModelFormatError(
            f"{_src(path)}: a DigitalGlobe .IMD holds no RPC; the product's RPC is its .RPB "
            f"({path.stem}.RPB), which is not beside it: pass the .RPB or the ISD .XML (or the "
            ".IMD with its .EPH/.ATT/.GEO files for the physical model)"
        )
    rpc, _, extra = _parse_rpb(rpb, rpb_text(rpb))
    items = {k.lower(): v.strip().strip('"') for k, v in _IMD_ITEM.findall(text)}
    shape = None
    if "numrows" in items or "numcolumns" in items:
        shape = _image_size(path, items.get("numrows"), items.get("numcolumns"),
                            "IMD numRows/numColumns")
    extra = {**extra, "format": "dg-imd", "rpb_file": str(rpb)}
    if items.get("satid"):
        extra["satellite_id"] = items["satid"]
    if items.get("catid"):
        extra["source_ids"] = {"catalog_id": items["catid"]}
    return rpc, shape, extra
