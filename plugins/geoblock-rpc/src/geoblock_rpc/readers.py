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
``dg-imd``             DigitalGlobe ``.IMD`` (``BEGIN_GROUP =      as stored (its ``.RPB``)
                       IMAGE_1``, ``numRows``): its ``.RPB``
``alos``               one fixed-width line of 1026 characters     as stored (as GDAL)
                       (JAXA ALOS ``RPC-*.txt``)
=====================  ==========================================  ===========================

The parsers live in the private package ``geoblock_rpc._formats``, one module per family
(rasters and VRTs, text and JSON, DigitalGlobe, OSSIM, DIMAP, fixed-width NITF TRE and ALOS).
RPC00A coefficients (OSSIM ``polynomial_format A``, a NITF ``RPC00A`` TRE) are put in RPC00B
order by :data:`RPC00A_TO_B` (OSSIM's RPC00A).

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

import math
import os
import re
from collections.abc import Callable, Mapping
from typing import Any

from geoblock.errors import ModelFormatError, UnsupportedFormatError
from geoblock.io import open_image, open_quietly
from geoblock.io.metadata import decode_text, read_bytes, read_xml
from geoblock.io.vsi import as_path
from geoblock_rpc._formats.common import RPC00A_TO_B, AnyPath, Result, _src, _xml_error
from geoblock_rpc._formats.dg import _parse_isd, _parse_rpb, looks_imd, parse_imd
from geoblock_rpc._formats.dimap import _parse_dimap, _parse_phr_dimap
from geoblock_rpc._formats.fixed import looks_alos, parse_alos
from geoblock_rpc._formats.ossim import _parse_ossim
from geoblock_rpc._formats.raster import _parse_gdal, _parse_vrt
from geoblock_rpc._formats.text import _parse_json, _parse_rpc_txt

__all__ = ["RPC00A_TO_B", "ReaderOptionError", "read_rpc", "sniff_rpc_format"]

#: re-exported for the tests and the writers' round trips
_REEXPORTS = (_parse_rpb, _parse_rpc_txt)

_HEAD_BYTES = 65536
_RASTER_MAGIC = (b"II*\x00", b"MM\x00*", b"II+\x00", b"MM\x00+", b"NITF", b"NSIF")


# ---------------------------------------------------------------------------------- sniffing
def _looks_binary(head: bytes) -> bool:
    return head.startswith(_RASTER_MAGIC) or b"\x00" in head[:4096]


_RPCTXT_RE = re.compile(r"^\s*LINE_NUM_COEFF(_1)?\s*:", re.MULTILINE)
_OSSIM_RE = re.compile(r"^\s*(\S+\.)?line_num_coeff_0*0\s*:", re.MULTILINE)
_RPB_RE = re.compile(r"BEGIN_GROUP\s*=\s*IMAGE", re.IGNORECASE)


def _name_says_rpc(path: AnyPath) -> bool:
    name = path.name.lower()
    return path.suffix.lower() in {".rpb", ".geom"} or (
        "rpc" in name and path.suffix.lower() in {".txt", ".xml", ".json"}
    )


def sniff_rpc_format(path: str | os.PathLike[str]) -> str | None:
    """The RPC container format of ``path`` judged from its content, or ``None``.

    Returns one of ``"gdal"`` (a binary raster for GDAL), ``"xml"`` (decided when parsing:
    VRT, DigitalGlobe ISD, DIMAP), ``"rpc-txt"``, ``"rpb"``, ``"ossim-kwl"``, ``"json"``, ``"dg-imd"``
    (a DigitalGlobe ``.IMD``: its ``.RPB`` is read), ``"alos"`` (JAXA fixed-width).
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
    if looks_imd(text):
        return "dg-imd"
    if looks_alos(text):
        return "alos"
    return None



# ---------------------------------------------------------------------------------- XML
def _read_xml_file(path: AnyPath, _depth: int = 0) -> Result | None:
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
def _pixel_crop_origin(image: AnyPath) -> tuple[float, float]:
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
def _dispatch(path: AnyPath) -> Result | None:
    kind = sniff_rpc_format(path)
    parsers: dict[str, Callable[[], Result | None]] = {
        "gdal": lambda: _parse_gdal(path),
        "xml": lambda: _read_xml_file(path),
        "json": lambda: _parse_json(path),
        "rpb": lambda: _parse_rpb(path, _text(path)),
        "ossim-kwl": lambda: _parse_ossim(path, _text(path)),
        "rpc-txt": lambda: _parse_rpc_txt(path, _text(path)),
        "dg-imd": lambda: parse_imd(path, _text(path), _text),
        "alos": lambda: parse_alos(path, _text(path)),
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


def _text(path: AnyPath) -> str:
    return decode_text(read_bytes(path))


def _read(path: AnyPath, options: Mapping[str, Any]) -> Result | None:
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

