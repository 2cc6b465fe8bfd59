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
import xml.etree.ElementTree as ET
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from geoblock.errors import ModelFormatError, UnsupportedFormatError
from geoblock.io import open_image, open_quietly
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


def _require(md: Mapping[str, Any], keys: tuple[str, ...], path: Path, what: str) -> None:
    missing = [k for k in keys if k not in md]
    if missing:
        raise ModelFormatError(f"{_src(path)}: {what} lacks {', '.join(missing)}")


def _image_size(path: Path, rows: Any, cols: Any, fields: str) -> Shape:
    """``(rows, cols)`` as whole numbers of pixels in 1 .. MAX_PIXELS (whole-number text such
    as ``"2920.0"`` too), by :func:`geoblock.models.image_shape`.

    Raises :class:`ModelFormatError` naming the file and the ``fields`` otherwise.
    """
    return image_shape((rows, cols), f"{_src(path)}: {fields}", maximum=int(MAX_PIXELS))


def _xml_text(elem: ET.Element | None, tag: str, path: Path, where: str) -> str:
    node = None if elem is None else elem.find(tag)
    if node is None or node.text is None or not node.text.strip():
        raise ModelFormatError(f"{_src(path)}: {where} has no <{tag.split('/')[-1]}> value")
    return node.text.strip()


def _local(tag: str) -> str:
    return tag.rsplit("}", 1)[-1]


def _strip_namespaces(root: ET.Element) -> ET.Element:
    for elem in root.iter():
        if isinstance(elem.tag, str):
            elem.tag = _local(elem.tag)
    return root


# ---------------------------------------------------------------------------------- sniffing
def _read_head(path: Path) -> bytes:
    with open(path, "rb") as fh:
        return fh.read(_HEAD_BYTES)


def _decode(data: bytes) -> str:
    for enc in ("utf-8-sig", "latin-1"):
        try:
            return data.decode(enc)
        except UnicodeDecodeError:
            continue
    return ""  # pragma: no cover - latin-1 decodes anything


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
    path = Path(path)
    head = _read_head(path)
    if not head:
        return None
    if _looks_binary(head):
        return "gdal"
    text = _decode(head).lstrip()
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
    import struct

    try:
        with open(path, "rb") as fh:
            head = fh.read(16)
            bo = {b"II": "<", b"MM": ">"}.get(head[:2])
            if bo is None:
                return None
            (magic,) = struct.unpack(bo + "H", head[2:4])
            if magic == 42:
                (ifd,) = struct.unpack(bo + "I", head[4:8])
                fh.seek(ifd)
                (n,) = struct.unpack(bo + "H", fh.read(2))
                entry, fmt = 12, bo + "HHII"
            elif magic == 43:
                (ifd,) = struct.unpack(bo + "Q", head[8:16])
                fh.seek(ifd)
                (n,) = struct.unpack(bo + "Q", fh.read(8))
                entry, fmt = 20, bo + "HHQQ"
            else:
                return None
            table = fh.read(entry * n)
            for i in range(n):
                tag, typ, count, offset = struct.unpack(fmt, table[i * entry:(i + 1) * entry])
                if tag == _RPC_TAG and typ == 12 and count == 92:
                    fh.seek(offset)
                    values = struct.unpack(bo + "92d", fh.read(8 * 92))
                    break
            else:
                return None
    except (OSError, struct.error):
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
    extra: dict[str, Any] = {"format": "gdal", "driver": driver, "files": files}
    satid = imd.get("SATID") or imd.get("IMAGE_1.SATID")
    if satid:
        extra["satellite_id"] = satid.strip('"')
    return rpc, shape, extra


def _parse_rpc_txt(path: Path, text: str) -> Result:
    md: dict[str, Any] = {}
    coeffs: dict[str, dict[int, str]] = {k: {} for k in _POLY_KEYS}
    for line_no, line in enumerate(text.splitlines(), start=1):
        if ":" not in line:
            continue
        key, _, value = line.partition(":")
        key = key.strip().upper()
        value = value.strip()
        m = re.fullmatch(r"(LINE|SAMP)_(NUM|DEN)_COEFF_(\d+)", key)
        if not (m or key in _POLY_KEYS or key in _SCALAR_KEYS or key in _OPTIONAL_KEYS):
            continue
        if not value:
            if key in _OPTIONAL_KEYS:
                continue  # an optional field without a value is an absent one
            raise ModelFormatError(f"{_src(path)}, line {line_no}: _RPC.TXT field {key} has no "
                                   "value")
        if m:
            index = int(m[3])
            if not 1 <= index <= 20:
                raise ModelFormatError(f"{_src(path)}, line {line_no}: _RPC.TXT field {key}: "
                                       "coefficient numbers run from 1 to 20")
            coeffs[f"{m[1]}_{m[2]}_COEFF"][index] = value
        else:
            md[key] = value
    for key, items in coeffs.items():
        if key in md:
            continue
        missing = [i for i in range(1, 21) if i not in items]
        if missing:
            raise ModelFormatError(
                f"{_src(path)}: _RPC.TXT lacks {key}_{missing[0]}"
                + (f" (and {len(missing) - 1} more)" if len(missing) > 1 else "")
            )
        md[key] = " ".join(items[i].split()[0] for i in range(1, 21))
    _require(md, _SCALAR_KEYS, path, "_RPC.TXT")
    return Rpc00b.from_gdal(md, source=_src(path)), None, {"format": "rpc-txt"}


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
    md: dict[str, Any] = {}
    for key, value in _RPB_ITEM.findall(m[1]):
        gkey = _RPB_MAP.get(key.upper())
        if gkey is None:
            continue
        value = value.strip()
        if value.startswith("("):
            value = " ".join(v.strip() for v in value[1:-1].split(",") if v.strip())
        if not value:
            if gkey in _OPTIONAL_KEYS:
                continue  # an optional field without a value is an absent one
            raise ModelFormatError(f"{_src(path)}: RPB field {key} has no value")
        md[gkey] = value
    _require(md, _SCALAR_KEYS + _POLY_KEYS,
             path, "RPB (DigitalGlobe keys lineOffset ... sampDenCoef)")
    extra: dict[str, Any] = {"format": "rpb"}
    for key, value in _RPB_ITEM.findall(text[: m.start()]):
        extra[{"satid": "satellite_id", "bandid": "band_id", "specid": "spec_id"}.get(
            key.lower(), key)] = value.strip().strip('"')
    return Rpc00b.from_gdal(md, source=_src(path)), None, extra


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
    fmt = get.get("polynomial_format", "B").strip().upper() or "B"
    if fmt not in ("A", "B"):
        raise ModelFormatError(f"{_src(path)}: OSSIM polynomial_format {fmt!r} is not A or B")
    md: dict[str, Any] = {}
    for key in _SCALAR_KEYS:
        if key.lower() not in get:
            raise ModelFormatError(f"{_src(path)}: OSSIM keyword list lacks {prefix}{key.lower()}")
        md[key] = get[key.lower()]
    for key in _POLY_KEYS:
        values = []
        for i in range(20):
            name = f"{key.lower()}_{i:02d}"
            if name not in get:
                raise ModelFormatError(f"{_src(path)}: OSSIM keyword list lacks {prefix}{name}")
            values.append(get[name])
        if fmt == "A":
            reordered = [""] * 20
            for a_index, b_index in enumerate(RPC00A_TO_B):
                reordered[b_index] = values[a_index]
            values = reordered
        md[key] = " ".join(values)
    extra: dict[str, Any] = {"format": "ossim-kwl", "ossim_type": get.get("type"),
                             "polynomial_format": fmt}
    sensor = get.get("sensor") or get.get("support_data.sensorID")
    if sensor:
        extra["satellite_id"] = sensor
    shape = None
    if "number_lines" in get and "number_samples" in get:
        shape = _image_size(path, get["number_lines"], get["number_samples"],
                            f"OSSIM {prefix}number_lines/{prefix}number_samples")
    return Rpc00b.from_gdal(md, source=_src(path)), shape, extra


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
        data = json.loads(path.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError):
        return None
    if not isinstance(data, dict):
        return None
    if isinstance(data.get("model"), str) and "schema_version" in data:
        return None  # geoblock's own model JSON: the core reader's
    block = data.get("rpc") if isinstance(data.get("rpc"), dict) else data
    upper = {str(k).upper(): v for k, v in block.items()}
    if "row_offset" in block or "row_num" in block:
        md = {g: block[k] for k, g in _RPCM_KEYS.items() if k in block}
        _require(md, _SCALAR_KEYS + _POLY_KEYS, path, "rpcm RPC dictionary")
        fmt = "rpcm-json"
    elif "LINE_OFF" in upper and "LINE_NUM_COEFF" in upper:
        md = upper
        fmt = "gdal-json"
    else:
        return None
    _check_json_values(path, md, {g: k for k, g in _RPCM_KEYS.items()} if fmt == "rpcm-json"
                       else {})
    extra: dict[str, Any] = {"format": fmt}
    for key in ("img", "acquisition_date", "sun_elevation", "sun_azimuth", "min_alt",
                "max_alt"):
        if key in data:
            extra[key] = data[key]
    shape = None
    if isinstance(data.get("height"), int) and isinstance(data.get("width"), int):
        shape = _image_size(path, data["height"], data["width"], "JSON height/width")
    return Rpc00b.from_gdal(md, source=_src(path)), shape, extra


def _check_json_values(path: Path, md: Mapping[str, Any], names: Mapping[str, str]) -> None:
    """JSON values of the right type: a number (or numeric text) for a scalar, a list of
    numbers (or whitespace-separated text) for a coefficient list; ``names`` maps the GDAL key
    to the file's own key, for the message."""

    def scalar(v: Any) -> bool:
        if isinstance(v, bool):
            return False
        if isinstance(v, int):
            return abs(v) <= 1e308  # float(v) would overflow
        return isinstance(v, float | str)

    for key, value in md.items():
        if key in _POLY_KEYS:
            ok = isinstance(value, str) or (isinstance(value, list)
                                            and all(scalar(v) for v in value))
            want = "a list of 20 numbers"
        elif key in _SCALAR_KEYS or key in _OPTIONAL_KEYS:
            ok = scalar(value)
            want = "a number"
        else:
            continue
        if not ok:
            raise ModelFormatError(
                f"{_src(path)}: JSON field {names.get(key, key)!r} must be {want}, got "
                f"{json.dumps(value)[:80]}"
            )


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
    return Rpc00b.from_gdal(md, source=_src(path)), shape, extra


def _parse_isd(path: Path, root: ET.Element) -> Result:
    image = root.find("RPB/IMAGE")
    if image is None:
        raise ModelFormatError(
            f"{_src(path)}: DigitalGlobe ISD XML without an <RPB><IMAGE> section: no RPC "
            "coefficients in this file (use its physical model or the product's .RPB)"
        )
    md: dict[str, Any] = {}
    for child in image:
        gkey = _RPB_MAP.get(child.tag.upper().removesuffix("LIST"))
        if gkey is None:
            continue
        if len(child):
            md[gkey] = " ".join((c.text or "").strip() for c in child)
        else:
            md[gkey] = (child.text or "").strip()
    _require(md, _SCALAR_KEYS + _POLY_KEYS, path, "ISD <RPB><IMAGE>")
    extra: dict[str, Any] = {"format": "dg-isd"}
    satid = root.findtext("RPB/SATID") or root.findtext("IMD/IMAGE/SATID")
    if satid:
        extra["satellite_id"] = satid.strip()
    shape = None
    rows, cols = root.findtext("IMD/NUMROWS"), root.findtext("IMD/NUMCOLUMNS")
    if rows is not None or cols is not None:
        shape = _image_size(path, rows, cols, "ISD <IMD><NUMROWS>/<NUMCOLUMNS>")
    return Rpc00b.from_gdal(md, source=_src(path)), shape, extra


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


def _parse_dimap(path: Path, root: ET.Element, _depth: int = 0) -> Result | None:
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
    md: dict[str, Any] = {k: _xml_text(valid, k, path, f"{where}/RFM_Validity")
                          for k in _SCALAR_KEYS}
    inv_tag = "GroundtoImage_Values" if pneo else "Inverse_Model"
    inv = gl.find(inv_tag)
    if inv is None:
        raise ModelFormatError(f"{_src(path)}: {where} has no {inv_tag} (ground -> image)")
    for key in _POLY_KEYS:
        md[key] = " ".join(
            _xml_text(inv, f"{key}_{i}", path, f"{where}/{inv_tag}") for i in range(1, 21))
    domain = valid.find("Inverse_Model_Validity_Domain")
    if domain is not None:
        for tag, key in (("FIRST_LON", "MIN_LONG"), ("LAST_LON", "MAX_LONG"),
                         ("FIRST_LAT", "MIN_LAT"), ("LAST_LAT", "MAX_LAT")):
            text = domain.findtext(tag)
            if text:
                md[key] = text.strip()
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
        text = inv.findtext(tag)
        if text and text.strip():
            try:
                extra[tag.lower()] = float(text)
            except ValueError:
                raise ModelFormatError(f"{_src(path)}: {where}/{inv_tag}/{tag} is not a number: "
                                       f"{text.strip()!r}") from None
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


def _parse_phr_dimap(path: Path, root: ET.Element) -> Result:
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
    md: dict[str, Any] = {}
    for axis, off_key, scale_key in (("Lon", "LONG_OFF", "LONG_SCALE"),
                                     ("Lat", "LAT_OFF", "LAT_SCALE"),
                                     ("Alt", "HEIGHT_OFF", "HEIGHT_SCALE"),
                                     ("Col", "SAMP_OFF", "SAMP_SCALE"),
                                     ("Row", "LINE_OFF", "LINE_SCALE")):
        node = valid.find(axis)
        md[scale_key] = _xml_text(node, "A", path, f"{where}/RFM_Validity/{axis}")
        md[off_key] = _xml_text(node, "B", path, f"{where}/RFM_Validity/{axis}")
    inv = gl.find("Inverse_Model")
    for tag, prefix in (("F_ROW", "LINE"), ("F_COL", "SAMP")):
        values = _xml_text(inv, tag, path, f"{where}/Inverse_Model").split()
        if len(values) != 40:
            raise ModelFormatError(f"{_src(path)}: {where}/Inverse_Model/{tag} must hold 40 "
                                   f"numbers (20 numerator + 20 denominator), got {len(values)}")
        md[f"{prefix}_NUM_COEFF"] = " ".join(values[:20])
        md[f"{prefix}_DEN_COEFF"] = " ".join(values[20:])
    domain = valid.find("Inverse_Model_Validity_Domain")
    if domain is not None:
        for tag, key in (("FIRST_LON", "MIN_LONG"), ("LAST_LON", "MAX_LONG"),
                         ("FIRST_LAT", "MIN_LAT"), ("LAST_LAT", "MAX_LAT")):
            text = domain.findtext(tag)
            if text:
                md[key] = text.strip()
    rpc = Rpc00b.from_gdal(md, source=_src(path))
    rpc = rpc.replace(line_off=rpc.line_off - 1.0, samp_off=rpc.samp_off - 1.0)
    extra = {"format": "dimap-phr", "offset_shift": -1.0, "profile": _dimap_profile(root)}
    rpc = _check_box(rpc, extra)
    return rpc, _dimap_shape(path, root), extra


def _read_xml_file(path: Path, _depth: int = 0) -> Result | None:
    try:
        root = _strip_namespaces(ET.parse(path).getroot())
    except (ET.ParseError, LookupError, UnicodeError, ValueError) as exc:
        # LookupError: an unknown encoding in the XML declaration
        if _name_says_rpc(path):
            raise ModelFormatError(f"{_src(path)}: is not well-formed XML ({exc})") from None
        return None
    tag = root.tag
    if tag == "VRTDataset":
        return _parse_vrt(path, root)
    if tag.lower() == "isd":
        return _parse_isd(path, root)
    if tag == "PHR_Dimap_Document":
        return _parse_phr_dimap(path, root)
    if tag == "Dimap_Document" or root.find("Metadata_Identification") is not None:
        return _parse_dimap(path, root, _depth)
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
    return _decode(path.read_bytes())


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
    image = None if image is None else Path(image)
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
    path = Path(path)
    result = _read(path, options)
    if result is None:
        raise UnsupportedFormatError(
            f"{_src(path)}: not an RPC file geoblock-rpc reads (GDAL raster with RPC, VRT, "
            "_RPC.TXT, RPB, DigitalGlobe ISD XML, DIMAP, OSSIM .geom, rpcm JSON)"
        )
    return result
