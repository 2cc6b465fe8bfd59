"""DIMAP: Pleiades/SPOT 6-7 v2 ``RPC_*.XML``/``DIM_*.XML``, Pleiades Neo v3, PHR DIMAP."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import numpy as np

from geoblock.errors import ModelFormatError
from geoblock.io.metadata import XmlFields, read_xml
from geoblock_rpc._formats.common import (
    AnyPath, _POLY_KEYS, _SCALAR_KEYS, Result, Shape, _field_error, _image_size, _src,
    _xml_error,
)
from geoblock_rpc.rpc00b import Rpc00b


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


def _dimap_shape(path: AnyPath, root: ET.Element) -> Shape | None:
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


def _parse_dimap(path: AnyPath, doc: XmlFields, _depth: int = 0) -> Result | None:
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
                    from geoblock_rpc.readers import _read_xml_file

                    result = _read_xml_file(target, _depth=1)
                    if result is None:
                        raise ModelFormatError(f"{_src(path)}: the RPC file its "
                                               f"Rational_Function_Model refers to ({target}) "
                                               "is not a DIMAP RPC document")
                    rpc, shape, sub_extra = result
                    shape = _dimap_shape(path, root) or shape
                    return rpc, shape, {**sub_extra, "rpc_file": str(target)}
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
    # the image's size is the product document's (Raster_Dimensions), never the RFM's
    # validity domain (Direct_Model_Validity_Domain is where the RFM was fitted: -27..42248
    # rows for the 41801-row Ventoux scene)
    shape = _dimap_shape(path, root)
    if shape is None and _depth == 0:
        found = _product_shape(path)
        if found is not None:
            shape, extra["shape_from"] = found
    return rpc, shape, extra


def _product_shape(path: AnyPath) -> tuple[Shape, str] | None:
    """The image size of the DIMAP product document (``DIM_*.XML``) beside an ``RPC_*.XML``
    that names it as its RFM component (``COMPONENT_PATH href``), and that document's path.

    ``None`` when no such document is there (the RPC file was copied alone): the model's
    size is then not stated (:attr:`RpcModel.shape_stated
    <geoblock_rpc.model.RpcModel.shape_stated>`).
    """
    if not isinstance(path, Path):
        return None  # a GDAL virtual path: no directory to look in
    try:
        candidates = sorted(p for p in path.parent.iterdir()
                            if p.name.upper().startswith("DIM_") and p.suffix.upper() == ".XML")
    except OSError:
        return None
    me = path.resolve()
    for candidate in candidates:
        try:
            doc = read_xml(candidate, _xml_error, strip_namespaces=True)
        except ModelFormatError:
            continue  # not well-formed: not the product document we look for
        for ref in doc.root.iter("COMPONENT_PATH"):
            href = ref.get("href")
            if href and (candidate.parent / href).resolve() == me:
                shape = _dimap_shape(candidate, doc.root)
                if shape is not None:
                    return shape, str(candidate)
    return None


def _check_box(rpc: Rpc00b, extra: dict[str, Any]) -> Rpc00b:
    """Keep a DIMAP validity box only if it lies on the model; repair swapped lon/lat."""
    if not rpc.has_validity_box:
        return rpc

    def fits(lon0: float, lon1: float, lat0: float, lat1: float) -> bool:
        return (abs((lon0 + lon1) / 2 - rpc.long_off) <= 1.5 * abs(rpc.long_scale)
                and abs((lat0 + lat1) / 2 - rpc.lat_off) <= 1.5 * abs(rpc.lat_scale))

    box = (float(rpc.min_long), float(rpc.max_long),  # type: ignore[arg-type]
           float(rpc.min_lat), float(rpc.max_lat))  # type: ignore[arg-type]
    if fits(*box):
        extra["validity_box"] = "as in the file"
        return rpc
    if fits(box[2], box[3], box[0], box[1]):
        extra["validity_box"] = "swapped lon/lat in the file, repaired"
        return rpc.replace(min_long=box[2], max_long=box[3], min_lat=box[0], max_lat=box[1])
    extra["validity_box"] = "dropped: it does not lie on the model's ground domain"
    return rpc.replace(min_long=None, max_long=None, min_lat=None, max_lat=None)


def _parse_phr_dimap(path: AnyPath, doc: XmlFields) -> Result:
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
