"""Readers: every common RPC00B container -> :class:`~geoblock_rpc.rpc00b.Rpc00b`.

:func:`read_rpc` sniffs the file's *content* (the suffix only breaks ties) and hands it to one
parser per format. Every parser returns coefficients in geoblock's convention: ``(0, 0)`` is
the centre of the first pixel (RPC00B-native, GDAL ``RPC`` metadata as stored).

=====================  ==========================================  ===========================
format (``extra["format"]``)  recognised by                        offsets
=====================  ==========================================  ===========================
``gdal``               TIFF / NITF / other raster GDAL opens,      as stored (GDAL RPC domain)
                       incl. ``.RPB``/``_RPC.TXT`` sidecars
``gdal-vrt``           XML root ``VRTDataset`` with an RPC domain  as stored
``rpc-txt``            ``LINE_OFF:`` + ``LINE_NUM_COEFF_1..20``    as stored
``rpb``                ``BEGIN_GROUP = IMAGE`` + ``lineOffset``    as stored
``dg-isd``             XML root ``isd`` with ``RPB/IMAGE``         as stored
``dimap-v2``           XML ``Dimap_Document`` v2 ``Global_RFM``    ``-1`` (1-based, "first
                                                                   pixel is (1, 1)")
``dimap-v3``           ``Dimap_Document`` v3 (PNEO)                as stored (0-based, see
                       ``GroundtoImage_Values``                    below)
``dimap-phr``          ``PHR_Dimap_Document`` ``F_COL``/``F_ROW``  ``-1`` (1-based)
``ossim-kwl``          ``line_num_coeff_00:`` (OSSIM ``.geom``)    as stored (0-based centre)
``rpcm-json``          JSON with rpcm/IARPA keys (``row_offset``)  as stored
=====================  ==========================================  ===========================

Evidence for the conventions (checked on the shared test data):

* OSSIM ``.geom``: ``PHR1B_..._178609-001.geom`` has ``line_off 11469.5, samp_off 19999.5``
  where its DIMAP ``RPC_..._178609-001.XML`` has ``11470.5, 20000.5`` and the GDAL tag of the
  matching GeoTIFF has ``11469.5, 19999.5``: OSSIM offsets are already 0-based pixel-centre.
  shareloc adds 0.5 to every source (its "top-left" convention), so its expected
  ``(col 100.5, row 200.5)`` is geoblock's ``(col 100.0, row 200.0)`` for all three files.
* DIMAP v2 / PHR DIMAP: 1-based, as GDAL's DIMAP driver and shareloc (``offset -= 1``).
* DIMAP v3 (Pleiades Neo): 0-based per GDAL (OSGeo/gdal#5716), so kept as stored. NB
  shareloc subtracts 0.5 for v3; no PNEO sample is available here to settle it.

A file this plugin does not recognise makes the hook return ``None``; a recognised file
without usable coefficients raises :class:`~geoblock.errors.ModelFormatError` naming the file
and what is missing.

Reading. The readers never open a file themselves: they get its bytes from
:func:`geoblock.io.metadata.read_bytes` (sniffing, TIFF tags) or parse it with
:func:`~geoblock.io.metadata.read_xml`; each text format is tokenised into a mapping of its own
keys (``KEY: value`` lines, ``key = value;`` groups, OSSIM keywords, JSON, a VRT's or an
ISD's key/value block), whose fields are read through :class:`geoblock.io.metadata.Fields`,
and the DIMAP documents' through :class:`~geoblock.io.metadata.XmlFields`: a missing, empty
or non-numeric field is refused naming the file and the field as the file spells it.

Crops. RPC tags describe the full image. :func:`read_rpc` shifts the offsets when asked:
``crop_offset=(row0, col0)`` explicitly, or ``crop_from_geotransform=True`` to take
``(row0, col0)`` from a pixel-unit geotransform (origin ``(col0, row0)``, pixel size 1, no
CRS; shareloc's Ventoux crops ``image/phr_ventoux/*.tif`` are such images without RPC tags)
of ``image=`` (or of ``path`` itself when it is a raster). ``image=`` also sets the shape.
"""

from __future__ import annotations

import json
import math
import os
import re
import struct
import xml.etree.ElementTree as ET
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from geoblock.errors import GeoblockIOError, ModelFormatError, UnsupportedFormatError
from geoblock.io import open_image, open_quietly
from geoblock.io.metadata import ErrorFactory, Fields, XmlFields, decode_text, read_bytes, read_xml
from geoblock.io.vsi import VsiPath, as_path
from geoblock.models import image_shape
from geoblock_rpc.rpc00b import MAX_PIXELS, Rpc00b

__all__ = ["RPC00A_TO_B", "ReaderOptionError", "read_rpc", "sniff_rpc_format"]

Shape = tuple[int, int]
Result = tuple[Rpc00b, Shape | None, dict[str, Any]]

#: index in RPC00B order of each RPC00A term (A: 1 L P H LP LH PH LPH L2 P2 H2 L3 ...)
RPC00A_TO_B: tuple[int, ...] = (
    0, 1, 2, 3, 4, 5, 6, 10, 7, 8, 9, 11, 12, 13, 14, 15, 16, 17, 18, 19,
)

_HEAD_BYTES = 65536
_RASTER_MAGIC = (b"II*\x00", b"MM\x00*", b"II+\x00", b"MM\x00+", b"NITF", b"NSIF")
_SCALAR_KEYS = (
    "LINE_OFF", "SAMP_OFF", "LAT_OFF", "LONG_OFF", "HEIGHT_OFF",
    "LINE_SCALE", "SAMP_SCALE", "LAT_SCALE", "LONG_SCALE", "HEIGHT_SCALE",
)
_POLY_KEYS = ("LINE_NUM_COEFF", "LINE_DEN_COEFF", "SAMP_NUM_COEFF", "SAMP_DEN_COEFF")
_OPTIONAL_KEYS = ("ERR_BIAS", "ERR_RAND", "MIN_LONG", "MIN_LAT", "MAX_LONG", "MAX_LAT")


# ---------------------------------------------------------------------------------- helpers
def _src(path: Path) -> str:
    return str(path)


def _require(md: Mapping[str, Any], keys: Sequence[str], path: Path, what: str) -> None:
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


def _image_size(path: Path, rows: Any, cols: Any, fields: str) -> Shape:
    """``(rows, cols)`` as whole numbers of pixels in 1 .. MAX_PIXELS (whole-number text such
    as ``"2920.0"`` too), by :func:`geoblock.models.image_shape`.

    Raises :class:`ModelFormatError` naming the file and the ``fields`` otherwise.
    """
    return image_shape((rows, cols), f"{_src(path)}: {fields}", maximum=int(MAX_PIXELS))


# ---------------------------------------------------------------------------------- sniffing
def _looks_binary(head: bytes) -> bool:
    return head.startswith(_RASTER_MAGIC) or b"\x00" in head[:4096]


_RPCTXT_RE = re.compile(r"^\s*LINE_NUM_COEFF(_1)?\s*:", re.MULTILINE)
_OSSIM_RE = re.compile(r"^\s*(\S+\.)?line_num_coeff_0*0\s*:", re.MULTILINE)
_RPB_RE = re.compile(r"BEGIN_GROUP\s*=\s*IMAGE", re.IGNORECASE)


def _name_says_rpc(path: Path) -> bool:
    name = path.name.lower()
    return path.suffix.lower() in {".rpb", ".geom"} or (
        "rpc" in name and path.suffix.lower() in {".txt", ".xml", ".json"}
    )


def sniff_rpc_format(path: str | os.PathLike[str]) -> str | None:
    """The RPC container format of ``path`` judged from its content, or ``None``.

    Returns one of ``"gdal"`` (a binary raster for GDAL), ``"xml"`` (decided when parsing:
    VRT, DigitalGlobe ISD, DIMAP), ``"rpc-txt"``, ``"rpb"``, ``"ossim-kwl"``, ``"json"``.
    """
    path = as_path(path)
    head = read_bytes(path, _HEAD_BYTES)
    if not head:
        return None
    if _looks_binary(head):
        return "gdal"
    text = decode_text(head).lstrip()
    if text.startswith("<"):
        return "xml"
    if text.startswith("{"):
        return "json"
    if _RPB_RE.search(text) and re.search(r"\blineOffset\s*=", text, re.IGNORECASE):
        return "rpb"
    if _OSSIM_RE.search(text):
        return "ossim-kwl"
    if _RPCTXT_RE.search(text) and re.search(r"^\s*LINE_OFF\s*:", text, re.MULTILINE):
        return "rpc-txt"
    return None


# ---------------------------------------------------------------------------------- parsers
_RPC_TAG = 50844  # GeoTIFF RPCCoefficientTag: 92 doubles
_TAG_ORDER = ("ERR_BIAS", "ERR_RAND", *_SCALAR_KEYS)


def _tiff_rpc_tag(path: Path) -> dict[str, str] | None:
    """The exact doubles of the first IFD's RPCCoefficientTag, as GDAL-style items.

    GDAL reports that tag as ``%.15g`` text (up to ~1e-8 px off for a 40 000 px image); this
    reads the 92 doubles themselves. ``None`` when absent or unreadable.
    """
    try:
        head = read_bytes(path, 16)
        bo = {b"II": "<", b"MM": ">"}.get(head[:2])
        if bo is None:
            return None
        (magic,) = struct.unpack(bo + "H", head[2:4])
        if magic == 42:
            (ifd,) = struct.unpack(bo + "I", head[4:8])
            (n,) = struct.unpack(bo + "H", read_bytes(path, 2, ifd))
            entry, fmt, first = 12, bo + "HHII", ifd + 2
        elif magic == 43:
            (ifd,) = struct.unpack(bo + "Q", head[8:16])
            (n,) = struct.unpack(bo + "Q", read_bytes(path, 8, ifd))
            entry, fmt, first = 20, bo + "HHQQ", ifd + 8
        else:
            return None
        table = read_bytes(path, entry * n, first)
        for i in range(n):
            tag, typ, count, offset = struct.unpack(fmt, table[i * entry:(i + 1) * entry])
            if tag == _RPC_TAG and typ == 12 and count == 92:
                values = struct.unpack(bo + "92d", read_bytes(path, 8 * 92, offset))
                break
        else:
            return None
    except (GeoblockIOError, struct.error):
        return None
    items = {k: repr(v) for k, v in zip(_TAG_ORDER, values[:12], strict=True)}
    for j, key in enumerate(_POLY_KEYS):
        items[key] = " ".join(repr(v) for v in values[12 + 20 * j: 32 + 20 * j])
    return items


def _exact_tag_values(path: Path, gdal_items: dict[str, str]) -> dict[str, str]:
    """GDAL's items with the full-precision tag values when they are the same RPC."""
    tag = _tiff_rpc_tag(path)
    if tag is None:
        return gdal_items
    try:
        a = Rpc00b.from_gdal(gdal_items).to_dict()
        b = Rpc00b.from_gdal(tag).to_dict()
    except ModelFormatError:
        return gdal_items
    for key in ("line_off", "samp_off", "lat_off", "long_off", "height_off", "line_scale",
                "samp_scale", "lat_scale", "long_scale", "height_scale", "line_num",
                "line_den", "samp_num", "samp_den"):
        if not np.allclose(a[key], b[key], rtol=1e-13, atol=0):
            return gdal_items  # the RPC came from elsewhere (e.g. a sidecar)
    out = dict(gdal_items)
    out.update({k: v for k, v in tag.items() if k not in ("ERR_BIAS", "ERR_RAND")})
    return out


def _parse_gdal(path: Path) -> Result | None:
    from rasterio.errors import RasterioIOError

    try:
        with open_quietly(path) as ds:
            rpcs = ds.rpcs
            shape = (int(ds.height), int(ds.width))
            driver = ds.driver
            imd = ds.tags(ns="IMD") or {}
            files = [Path(f).name for f in ds.files]
    except RasterioIOError:
        return None
    if rpcs is None:
        kind = {"GTiff": "a GeoTIFF", "NITF": "a NITF"}.get(driver, f"a {driver} raster")
        raise ModelFormatError(
            f"{_src(path)}: is {kind} without RPC metadata (no RPC tags or RPC00B TRE, no "
            "RPB/_RPC.TXT sidecar next to it); pass the sensor metadata file instead"
        )
    items = rpcs.to_gdal()
    if driver == "GTiff":
        items = _exact_tag_values(path, items)
    rpc = Rpc00b.from_gdal(items, source=_src(path))
    extra: dict[str, Any] = {"format": "gdal", "driver": driver, "files": files,
                             "source_ids": dict(open_image(path).source_ids)}
    satid = imd.get("SATID") or imd.get("IMAGE_1.SATID")
    if satid:
        extra["satellite_id"] = satid.strip('"')
    return rpc, shape, extra


def _parse_rpc_txt(path: Path, text: str) -> Result:
    kv: dict[str, str] = {}
    lines: dict[str, int] = {}
    for line_no, line in enumerate(text.splitlines(), start=1):
        if ":" not in line:
            continue
        key, _, value = line.partition(":")
        key = key.strip().upper()
        m = re.fullmatch(r"(LINE|SAMP)_(NUM|DEN)_COEFF_(\d+)", key)
        if not (m or key in _POLY_KEYS or key in _SCALAR_KEYS or key in _OPTIONAL_KEYS):
            continue
        if m and not 1 <= int(m[3]) <= 20:
            raise ModelFormatError(f"{_src(path)}, line {line_no}: _RPC.TXT field {key}: "
                                   "coefficient numbers run from 1 to 20")
        kv[key], lines[key] = value, line_no
    # a coefficient list is one key (LINE_NUM_COEFF: 20 numbers) or twenty (LINE_NUM_COEFF_1..20)
    keys: dict[str, str | tuple[str, ...]] = {k: k for k in _SCALAR_KEYS + _OPTIONAL_KEYS}
    for key in _POLY_KEYS:
        keys[key] = key if key in kv else tuple(f"{key}_{i}" for i in range(1, 21))
    for key in _POLY_KEYS:
        missing = [k for k in keys[key] if k not in kv] if key not in kv else []
        if missing:
            raise ModelFormatError(
                f"{_src(path)}: _RPC.TXT lacks {missing[0]}"
                + (f" (and {len(missing) - 1} more)" if len(missing) > 1 else "")
            )
    _require(kv, _SCALAR_KEYS, path, "_RPC.TXT")
    fields = Fields(_src(path), kv, error=_field_error("_RPC.TXT", lines))
    return _rpc_from_fields(fields, keys), None, {"format": "rpc-txt"}


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


def _parse_rpb(path: Path, text: str) -> Result:
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


def _parse_ossim(path: Path, text: str) -> Result:
    kw: dict[str, str] = {}
    for line in text.splitlines():
        key, sep, value = line.partition(":")
        if sep:
            kw[key.strip()] = value.strip()
    # keys may carry a prefix (e.g. "image0."): take the one of line_num_coeff_00
    prefix = ""
    for key in kw:
        if re.fullmatch(r"(.*\.)?line_num_coeff_0*0", key):
            prefix = key[: key.rfind("line_num_coeff")]
            break
    get = {k[len(prefix):]: v for k, v in kw.items() if k.startswith(prefix)}
    fields = Fields(_src(path), get, where=prefix, error=_field_error("OSSIM keyword list"))
    fmt = (fields.string("polynomial_format", "B").strip().upper() or "B")
    if fmt not in ("A", "B"):
        raise ModelFormatError(f"{_src(path)}: OSSIM polynomial_format {fmt!r} is not A or B")
    keys: dict[str, str | tuple[str, ...]] = {k: k.lower() for k in _SCALAR_KEYS}
    for key in _POLY_KEYS:
        names = tuple(f"{key.lower()}_{i:02d}" for i in range(20))
        if fmt == "A":  # the B-order term j is the A-order term a with RPC00A_TO_B[a] == j
            names = tuple(names[RPC00A_TO_B.index(j)] for j in range(20))
        keys[key] = names
    for key in keys.values():
        for name in (key,) if isinstance(key, str) else key:
            if name not in get:
                raise ModelFormatError(f"{_src(path)}: OSSIM keyword list lacks {prefix}{name}")
    rpc = _rpc_from_fields(fields, keys)
    extra: dict[str, Any] = {"format": "ossim-kwl", "ossim_type": get.get("type"),
                             "polynomial_format": fmt}
    sensor = get.get("sensor") or get.get("support_data.sensorID")
    if sensor:
        extra["satellite_id"] = sensor
    image_id = (get.get("image_id") or get.get("support_data.image_id") or "").strip()
    if image_id:
        extra["source_ids"] = {"ossim_image_id": image_id}
    shape = None
    if "number_lines" in get and "number_samples" in get:
        shape = _image_size(path, get["number_lines"], get["number_samples"],
                            f"OSSIM {prefix}number_lines/{prefix}number_samples")
    return rpc, shape, extra


_RPCM_KEYS = {
    "row_offset": "LINE_OFF", "col_offset": "SAMP_OFF", "lat_offset": "LAT_OFF",
    "lon_offset": "LONG_OFF", "alt_offset": "HEIGHT_OFF",
    "row_scale": "LINE_SCALE", "col_scale": "SAMP_SCALE", "lat_scale": "LAT_SCALE",
    "lon_scale": "LONG_SCALE", "alt_scale": "HEIGHT_SCALE",
    "row_num": "LINE_NUM_COEFF", "row_den": "LINE_DEN_COEFF",
    "col_num": "SAMP_NUM_COEFF", "col_den": "SAMP_DEN_COEFF",
}


def _parse_json(path: Path) -> Result | None:
    try:
        data = json.loads(read_bytes(path).decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError):
        return None
    if not isinstance(data, dict):
        return None
    if isinstance(data.get("model"), str) and "schema_version" in data:
        return None  # geoblock's own model JSON: the core reader's
    block = data.get("rpc") if isinstance(data.get("rpc"), dict) else data
    upper = {str(k).upper(): v for k, v in block.items()}
    keys: dict[str, str]
    if "row_offset" in block or "row_num" in block:
        keys = {g: k for k, g in _RPCM_KEYS.items() if k in block}
        _require(keys, _SCALAR_KEYS + _POLY_KEYS, path, "rpcm RPC dictionary")
        fields = Fields(_src(path), block, error=_field_error("JSON", quote=True))
        fmt = "rpcm-json"
    elif "LINE_OFF" in upper and "LINE_NUM_COEFF" in upper:
        keys = {k: k for k in _SCALAR_KEYS + _POLY_KEYS + _OPTIONAL_KEYS if k in upper}
        _require(keys, _SCALAR_KEYS + _POLY_KEYS, path, "GDAL RPC dictionary")
        fields = Fields(_src(path), upper, error=_field_error("JSON", quote=True))
        fmt = "gdal-json"
    else:
        return None
    rpc = _rpc_from_fields(fields, keys)
    extra: dict[str, Any] = {"format": fmt}
    for key in ("img", "acquisition_date", "sun_elevation", "sun_azimuth", "min_alt",
                "max_alt"):
        if key in data:
            extra[key] = data[key]
    shape = None
    if isinstance(data.get("height"), int) and isinstance(data.get("width"), int):
        shape = _image_size(path, data["height"], data["width"], "JSON height/width")
    return rpc, shape, extra


# ---------------------------------------------------------------------------------- XML
def _parse_vrt(path: Path, root: ET.Element) -> Result:
    md_nodes = [m for m in root.findall("Metadata") if m.get("domain", "").upper() == "RPC"]
    if not md_nodes:
        gdal = _parse_gdal(path)  # the RPC may come from the VRT's source raster
        if gdal is None:
            raise ModelFormatError(f"{_src(path)}: GDAL VRT without a <Metadata domain=\"RPC\">")
        rpc, shape, extra = gdal
        return rpc, shape, {**extra, "format": "gdal-vrt"}
    md = {m.get("key", "").upper(): (m.text or "") for m in md_nodes[0].findall("MDI")}
    _require(md, _SCALAR_KEYS + _POLY_KEYS, path, "VRT RPC metadata domain")
    keys = {k: k for k in _SCALAR_KEYS + _POLY_KEYS + _OPTIONAL_KEYS if k in md}
    rpc = _rpc_from_fields(Fields(_src(path), md, error=_field_error("VRT RPC metadata")), keys)
    shape = None
    if root.get("rasterYSize") is not None or root.get("rasterXSize") is not None:
        shape = _image_size(path, root.get("rasterYSize"), root.get("rasterXSize"),
                            "VRT rasterYSize/rasterXSize")
    extra: dict[str, Any] = {"format": "gdal-vrt"}
    for m in root.findall("Metadata"):
        if m.get("domain", "").upper() == "IMD":
            for mdi in m.findall("MDI"):
                if mdi.get("key", "").upper() in ("SATID", "IMAGE_1.SATID") and mdi.text:
                    extra["satellite_id"] = mdi.text.strip().strip('"')
    return rpc, shape, extra


def _parse_isd(path: Path, root: ET.Element) -> Result:
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


def _dimap_version(root: ET.Element) -> float | None:
    node = root.find("Metadata_Identification/METADATA_FORMAT")
    if node is None:
        node = root.find(".//METADATA_FORMAT")
    if node is None:
        return None
    try:
        return float(node.get("version", "nan"))
    except ValueError:
        return None


def _dimap_profile(root: ET.Element) -> str:
    return (root.findtext("Metadata_Identification/METADATA_PROFILE") or "").strip()


def _dimap_shape(path: Path, root: ET.Element) -> Shape | None:
    rows, cols = root.findtext(".//Raster_Dimensions/NROWS"), root.findtext(
        ".//Raster_Dimensions/NCOLS")
    if rows is None and cols is None:
        return None
    return _image_size(path, rows, cols, "DIMAP Raster_Dimensions NROWS/NCOLS")


def _is_pneo(root: ET.Element, version: float | None) -> bool:
    if root.find(".//GroundtoImage_Values") is not None:
        return True
    profile = _dimap_profile(root).upper()
    return (version is not None and version >= 3.0) or profile.startswith("PNEO")


def _validity_box(doc: XmlFields, valid: ET.Element, label: str) -> dict[str, float]:
    """MIN/MAX_LONG/LAT from ``RFM_Validity/Inverse_Model_Validity_Domain`` (those given)."""
    domain = doc.find("Inverse_Model_Validity_Domain", valid)
    if domain is None:
        return {}
    label += "Inverse_Model_Validity_Domain/"
    return {key: doc.number(tag, domain, label)
            for tag, key in (("FIRST_LON", "MIN_LONG"), ("LAST_LON", "MAX_LONG"),
                             ("FIRST_LAT", "MIN_LAT"), ("LAST_LAT", "MAX_LAT"))
            if doc.optional_text(tag, domain) is not None}


def _parse_dimap(path: Path, doc: XmlFields, _depth: int = 0) -> Result | None:
    root = doc.root
    doc = XmlFields(doc.source, root, _field_error("DIMAP"))
    version = _dimap_version(root)
    rfm = root.find(".//Rational_Function_Model")
    gl = root.find(".//Rational_Function_Model/Global_RFM")
    if gl is None:
        gl = root.find(".//Global_RFM")
    if gl is None:
        if rfm is not None:
            ref = rfm.find(".//COMPONENT_PATH")
            href = None if ref is None else ref.get("href")
            if href and _depth == 0:
                target = (path.parent / href).resolve()
                if target.is_file():
                    rpc, shape, extra = _read_xml_file(target, _depth=1)
                    shape = _dimap_shape(path, root) or shape
                    return rpc, shape, {**extra, "rpc_file": str(target)}
                raise ModelFormatError(
                    f"{_src(path)}: DIMAP document has no RPC coefficients; its "
                    f"Rational_Function_Model refers to {href!r}, which is not next to it "
                    f"({target} does not exist)"
                )
        if version is not None and version < 2.0:
            return None  # DIMAP v1 (SPOT 1-5): physical model only, not ours
        raise ModelFormatError(
            f"{_src(path)}: DIMAP document without RPC coefficients (no Global_RFM in "
            "Rational_Function_Model)"
        )
    where = "DIMAP Global_RFM"
    pneo = _is_pneo(root, version)
    valid = gl.find("RFM_Validity")
    if valid is None:
        raise ModelFormatError(f"{_src(path)}: {where} has no RFM_Validity (offsets, scales)")
    label = "Global_RFM/RFM_Validity/"
    md: dict[str, Any] = {k: doc.number(k, valid, label) for k in _SCALAR_KEYS}
    inv_tag = "GroundtoImage_Values" if pneo else "Inverse_Model"
    inv = gl.find(inv_tag)
    if inv is None:
        raise ModelFormatError(f"{_src(path)}: {where} has no {inv_tag} (ground -> image)")
    for key in _POLY_KEYS:
        md[key] = np.array([doc.number(f"{key}_{i}", inv, f"Global_RFM/{inv_tag}/")
                            for i in range(1, 21)])
    md.update(_validity_box(doc, valid, label))
    shift = 0.0 if pneo else 1.0
    rpc = Rpc00b.from_gdal(md, source=_src(path))
    if shift:
        rpc = rpc.replace(line_off=rpc.line_off - shift, samp_off=rpc.samp_off - shift)
    extra: dict[str, Any] = {
        "format": "dimap-v3" if pneo else "dimap-v2",
        "dimap_version": version,
        "offset_shift": -shift,
        "profile": _dimap_profile(root),
    }
    rpc = _check_box(rpc, extra)
    for tag in ("ERR_BIAS_ROW", "ERR_BIAS_COL"):
        if doc.optional_text(tag, inv) is not None:
            extra[tag.lower()] = doc.number(tag, inv, f"Global_RFM/{inv_tag}/")
    mission = root.findtext(".//Source_Identification//MISSION")
    if mission:
        idx = root.findtext(".//Source_Identification//MISSION_INDEX") or ""
        extra["satellite_id"] = f"{mission.strip()} {idx.strip()}".strip()
    shape = _dimap_shape(path, root)
    if shape is None:
        d = valid.find("Direct_Model_Validity_Domain")
        if d is not None and d.findtext("LAST_ROW") and d.findtext("LAST_COL"):
            shape = _image_size(
                path, d.findtext("LAST_ROW"), d.findtext("LAST_COL"),
                f"{where}/RFM_Validity/Direct_Model_Validity_Domain/LAST_ROW/LAST_COL")
    return rpc, shape, extra


def _check_box(rpc: Rpc00b, extra: dict[str, Any]) -> Rpc00b:
    """Keep a DIMAP validity box only if it lies on the model; repair swapped lon/lat."""
    if not rpc.has_validity_box:
        return rpc

    def fits(lon0: float, lon1: float, lat0: float, lat1: float) -> bool:
        return (abs((lon0 + lon1) / 2 - rpc.long_off) <= 1.5 * abs(rpc.long_scale)
                and abs((lat0 + lat1) / 2 - rpc.lat_off) <= 1.5 * abs(rpc.lat_scale))

    box = (rpc.min_long, rpc.max_long, rpc.min_lat, rpc.max_lat)
    if fits(*box):
        extra["validity_box"] = "as in the file"
        return rpc
    if fits(box[2], box[3], box[0], box[1]):
        extra["validity_box"] = "swapped lon/lat in the file, repaired"
        return rpc.replace(min_long=box[2], max_long=box[3], min_lat=box[0], max_lat=box[1])
    extra["validity_box"] = "dropped: it does not lie on the model's ground domain"
    return rpc.replace(min_long=None, max_long=None, min_lat=None, max_lat=None)


def _parse_phr_dimap(path: Path, doc: XmlFields) -> Result:
    root = doc.root
    doc = XmlFields(doc.source, root, _field_error("PHR_Dimap_Document"))
    gl = root.find(".//Rational_Sensor_Model/Global_RFM")
    if gl is None:
        gl = root.find(".//Global_RFM")
    where = "PHR_Dimap_Document Global_RFM"
    if gl is None:
        raise ModelFormatError(f"{_src(path)}: PHR_Dimap_Document without RPC coefficients "
                               "(no Rational_Sensor_Model/Global_RFM)")
    valid = gl.find("RFM_Validity")
    if valid is None:
        raise ModelFormatError(f"{_src(path)}: {where} has no RFM_Validity (offsets, scales)")
    label = "Global_RFM/RFM_Validity/"
    md: dict[str, Any] = {}
    for axis, off_key, scale_key in (("Lon", "LONG_OFF", "LONG_SCALE"),
                                     ("Lat", "LAT_OFF", "LAT_SCALE"),
                                     ("Alt", "HEIGHT_OFF", "HEIGHT_SCALE"),
                                     ("Col", "SAMP_OFF", "SAMP_SCALE"),
                                     ("Row", "LINE_OFF", "LINE_SCALE")):
        node = doc.node(axis, valid, label)
        md[scale_key] = doc.number("A", node, f"{label}{axis}/")
        md[off_key] = doc.number("B", node, f"{label}{axis}/")
    inv = doc.node("Inverse_Model", gl, "Global_RFM/")
    for tag, prefix in (("F_ROW", "LINE"), ("F_COL", "SAMP")):
        # 20 numerator then 20 denominator coefficients
        values = doc.numbers(tag, inv, "Global_RFM/Inverse_Model/", count=40)
        md[f"{prefix}_NUM_COEFF"] = values[:20]
        md[f"{prefix}_DEN_COEFF"] = values[20:]
    md.update(_validity_box(doc, valid, label))
    rpc = Rpc00b.from_gdal(md, source=_src(path))
    rpc = rpc.replace(line_off=rpc.line_off - 1.0, samp_off=rpc.samp_off - 1.0)
    extra = {"format": "dimap-phr", "offset_shift": -1.0, "profile": _dimap_profile(root)}
    rpc = _check_box(rpc, extra)
    return rpc, _dimap_shape(path, root), extra


def _read_xml_file(path: Path, _depth: int = 0) -> Result | None:
    try:
        doc = read_xml(path, _xml_error, strip_namespaces=True)
    except ModelFormatError:  # not well-formed (or an unknown declared encoding)
        if _name_says_rpc(path):
            raise
        return None
    root = doc.root
    tag = root.tag
    if tag == "VRTDataset":
        return _parse_vrt(path, root)
    if tag.lower() == "isd":
        return _parse_isd(path, root)
    if tag == "PHR_Dimap_Document":
        return _parse_phr_dimap(path, doc)
    if tag == "Dimap_Document" or root.find("Metadata_Identification") is not None:
        return _parse_dimap(path, doc, _depth)
    if _name_says_rpc(path):
        raise ModelFormatError(
            f"{_src(path)}: XML root <{tag}> is none of the RPC containers geoblock reads "
            "(GDAL VRT, DigitalGlobe ISD, DIMAP v2/v3, PHR DIMAP)"
        )
    return None


# ---------------------------------------------------------------------------------- crops
def _pixel_crop_origin(image: Path) -> tuple[float, float]:
    """``(row0, col0)`` of ``image``'s pixel-unit geotransform (core's
    :attr:`ImageSource.crop_offset <geoblock.io.images.ImageSource.crop_offset>`).

    Where the core states no crop (None), the plugin's outcome is kept: GDAL's default
    identity geotransform is the crop at ``(0, 0)``; a CRS or a map geotransform is refused.
    """
    offset = open_image(image).crop_offset
    if offset is not None:
        return float(offset[0]), float(offset[1])
    with open_quietly(image) as ds:
        t, crs = ds.transform, ds.crs
    if crs is not None and crs.is_valid and (crs.is_geographic or crs.is_projected):
        raise ModelFormatError(
            f"{image}: crop_from_geotransform needs a pixel-unit geotransform, but the raster "
            f"has the CRS {crs.to_string()!r}"
        )
    if (t.a, t.b, t.d, t.e) != (1.0, 0.0, 0.0, 1.0):
        raise ModelFormatError(
            f"{image}: crop_from_geotransform needs a pixel-unit geotransform "
            f"(1, 0, col0, 0, 1, row0), got {tuple(t)[:6]}"
        )
    return float(t.f), float(t.c)  # the identity: (0, 0)


# ---------------------------------------------------------------------------------- entry
def _dispatch(path: Path) -> Result | None:
    kind = sniff_rpc_format(path)
    parsers: dict[str, Callable[[], Result | None]] = {
        "gdal": lambda: _parse_gdal(path),
        "xml": lambda: _read_xml_file(path),
        "json": lambda: _parse_json(path),
        "rpb": lambda: _parse_rpb(path, _text(path)),
        "ossim-kwl": lambda: _parse_ossim(path, _text(path)),
        "rpc-txt": lambda: _parse_rpc_txt(path, _text(path)),
    }
    result = parsers[kind]() if kind is not None else None
    if result is None and _name_says_rpc(path) and kind not in ("json", "xml"):
        raise ModelFormatError(
            f"{_src(path)}: named like an RPC file but holds no RPC coefficients (no "
            "LINE_OFF / LINE_NUM_COEFF_1..20 keys, no RPB IMAGE group, no OSSIM "
            "line_num_coeff_00 keyword)"
        )
    return result


class ReaderOptionError(ModelFormatError, TypeError):
    """An option given to the RPC reader is unknown or invalid (names the file and option)."""


def _text(path: Path) -> str:
    return decode_text(read_bytes(path))


def _read(path: Path, options: Mapping[str, Any]) -> Result | None:
    unknown = set(options) - {"crop_offset", "crop_from_geotransform", "image"}
    if unknown:
        raise ReaderOptionError(f"{_src(path)}: unknown RPC reader option(s): "
                                f"{', '.join(sorted(unknown))}; options: crop_offset, "
                                "crop_from_geotransform, image")
    result = _dispatch(path)
    if result is None:
        return None
    rpc, shape, extra = result
    for off, scale in (("line_off", "line_scale"), ("samp_off", "samp_scale")):
        # the image extent a model without a stated shape is given (RpcModel) must exist
        if not math.isfinite(getattr(rpc, off) + abs(getattr(rpc, scale)) + 0.5):
            raise ModelFormatError(
                f"{_src(path)}: {off.upper()} {getattr(rpc, off):g} and {scale.upper()} "
                f"{getattr(rpc, scale):g} give no finite image extent"
            )
    image = options.get("image")
    image = None if image is None else as_path(image)
    crop = options.get("crop_offset")
    if options.get("crop_from_geotransform"):
        source = image if image is not None else path
        if image is None and extra.get("format") != "gdal":
            raise ModelFormatError(
                f"{_src(path)}: crop_from_geotransform needs a raster: pass image=<crop.tif> "
                "with this metadata file"
            )
        if crop is not None:
            raise ReaderOptionError(f"{_src(path)}: give crop_offset or crop_from_geotransform, "
                                    "not both")
        crop = _pixel_crop_origin(source)
        extra["crop_source"] = str(source)
    if image is not None:
        rows, cols = open_image(image).shape
        shape = (int(rows), int(cols))
        extra["image"] = str(image)
    if crop is not None:
        row0, col0 = (float(v) for v in crop)
        if not (math.isfinite(row0) and math.isfinite(col0)):
            raise ReaderOptionError(f"{_src(path)}: crop_offset must be finite, got {crop!r}")
        rpc = rpc.replace(line_off=rpc.line_off - row0, samp_off=rpc.samp_off - col0)
        extra["crop_offset"] = (row0, col0)
        if image is None and extra.get("crop_source") is None:
            shape = None  # the full image's shape no longer applies
    rpc.check_plausible()  # physically possible values (names the file and the field)
    return rpc, shape, extra


def read_rpc(path: str | os.PathLike[str], **options: Any) -> Result:
    """Read RPC00B coefficients from any supported container.

    Parameters
    ----------
    path : str or path-like
        GeoTIFF/NITF (or any GDAL raster) with RPC metadata or sidecar, GDAL VRT, ``_RPC.TXT``,
        DigitalGlobe ``.RPB`` or ISD ``.XML``, DIMAP v2/v3 ``RPC_*.XML`` / ``DIM_*.XML``,
        Pleiades ``PHRDIMAP_*.XML``, OSSIM ``.geom`` or rpcm/IARPA JSON.
    **options
        ``crop_offset=(row0, col0)``: shift the offsets so that the model addresses a crop
        whose first pixel is full-image pixel ``(row0, col0)``.
        ``crop_from_geotransform=True``: take ``(row0, col0)`` from the pixel-unit
        geotransform of ``image`` (or of ``path`` when it is a raster).
        ``image=path``: the raster the model is for; its shape becomes the model's.

    Returns
    -------
    rpc : Rpc00b
        Coefficients, geoblock pixel-centre convention.
    shape : (int, int) or None
        ``(rows, cols)`` when the file (or ``image``) states it.
    extra : dict
        ``format`` and whatever else the file tells (``satellite_id``, ``offset_shift``...).

    Raises
    ------
    UnsupportedFormatError
        The file is none of the formats above.
    ModelFormatError
        The file is one of them but has no (or invalid) RPC coefficients; the message names
        the file and the missing field.
    ReaderOptionError
        An option is unknown or invalid (``crop_offset`` not finite, ``crop_offset`` with
        ``crop_from_geotransform``); a :class:`~geoblock.errors.ModelFormatError` and a
        ``TypeError``, naming the file and the option.
    """
    path = as_path(path)
    result = _read(path, options)
    if result is None:
        raise UnsupportedFormatError(
            f"{_src(path)}: not an RPC file geoblock-rpc reads (GDAL raster with RPC, VRT, "
            "_RPC.TXT, RPB, DigitalGlobe ISD XML, DIMAP, OSSIM .geom, rpcm JSON)"
        )
    return result
