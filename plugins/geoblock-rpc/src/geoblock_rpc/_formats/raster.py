"""GDAL rasters (GeoTIFF tags, NITF TREs, sidecars) and GDAL VRTs with an RPC domain."""

from __future__ import annotations

import struct
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import numpy as np

from geoblock.errors import GeoblockIOError, ModelFormatError
from geoblock.io import open_image, open_quietly
from geoblock.io.metadata import Fields, read_bytes
from geoblock_rpc._formats.common import (
    AnyPath, _OPTIONAL_KEYS, _POLY_KEYS, _SCALAR_KEYS, Result, _field_error, _image_size, _require,
    _rpc_from_fields, _src,
)
from geoblock_rpc._formats.fixed import parse_fixed
from geoblock_rpc.rpc00b import Rpc00b

# ---------------------------------------------------------------------------------- parsers
_RPC_TAG = 50844  # GeoTIFF RPCCoefficientTag: 92 doubles
_TAG_ORDER = ("ERR_BIAS", "ERR_RAND", *_SCALAR_KEYS)


def _tiff_rpc_tag(path: AnyPath) -> dict[str, str] | None:
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


def _exact_tag_values(path: AnyPath, gdal_items: dict[str, str]) -> dict[str, str]:
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


def _parse_gdal(path: AnyPath) -> Result | None:
    from rasterio.errors import RasterioIOError

    try:
        with open_quietly(path) as ds:
            tags = {str(k).upper(): v for k, v in (ds.tags(ns="RPC") or {}).items()}
            shape = (int(ds.height), int(ds.width))
            driver = ds.driver
            imd = ds.tags(ns="IMD") or {}
            tre = (ds.tags(ns="TRE") or {}) if driver == "NITF" else {}
            files = [Path(f).name for f in ds.files]
    except RasterioIOError:
        return None
    if not tags:
        kind = {"GTiff": "a GeoTIFF", "NITF": "a NITF"}.get(driver, f"a {driver} raster")
        raise ModelFormatError(
            f"{_src(path)}: is {kind} without RPC metadata (no RPC tags or RPC00B TRE, no "
            "RPB/_RPC.TXT sidecar next to it); pass the sensor metadata file instead"
        )
    # where GDAL found the RPC: a sidecar (.RPB, _RPC.TXT, ALOS RPC-*.txt) or the raster itself
    sidecars = [f for f in files[1:] if f.upper().endswith((".RPB", "_RPC.TXT", ".TXT"))]
    what = "GDAL RPC metadata" + (f" (from {', '.join(sidecars)})" if sidecars else "")
    extra: dict[str, Any] = {"format": "gdal", "driver": driver, "files": files,
                             "source_ids": dict(getattr(open_image(path), "source_ids", {}))}
    if "RPC00A" in tre and "RPC00B" not in tre:
        # GDAL reorders RPC00A's terms the other way round (RPC00A_TO_B): read the TRE itself
        rpc = parse_fixed(_src(path), tre["RPC00A"], "NITF RPC00A TRE", tre=True, rpc00a=True)
        extra["tre"] = "RPC00A"
    else:
        _require(tags, _SCALAR_KEYS + _POLY_KEYS, path, what)
        keys = {k: k for k in _SCALAR_KEYS + _POLY_KEYS + _OPTIONAL_KEYS if k in tags}
        rpc = _rpc_from_fields(Fields(_src(path), tags, error=_field_error(what)), keys)
        if driver == "GTiff":
            exact = _exact_tag_values(path, tags)
            if exact is not tags:
                rpc = Rpc00b.from_gdal(exact, source=_src(path))
    satid = imd.get("SATID") or imd.get("IMAGE_1.SATID")
    if satid:
        extra["satellite_id"] = satid.strip('"')
    return rpc, shape, extra


def _parse_vrt(path: AnyPath, root: ET.Element) -> Result:
    md_nodes = [m for m in root.findall("Metadata") if m.get("domain", "").upper() == "RPC"]
    if not md_nodes:
        gdal = _parse_gdal(path)  # the RPC may come from the VRT's source raster
        if gdal is None:
            raise ModelFormatError(f"{_src(path)}: GDAL VRT without a <Metadata domain=\"RPC\">")
        rpc, shape, gdal_extra = gdal
        return rpc, shape, {**gdal_extra, "format": "gdal-vrt"}
    md = {m.get("key", "").upper(): (m.text or "") for m in md_nodes[0].findall("MDI")}
    _require(md, _SCALAR_KEYS + _POLY_KEYS, path, "VRT RPC metadata domain")
    keys = {k: k for k in _SCALAR_KEYS + _POLY_KEYS + _OPTIONAL_KEYS if k in md}
    rpc = _rpc_from_fields(Fields(_src(path), md, error=_field_error("VRT RPC metadata")), keys)
    shape = None
    if root.get("rasterYSize") is not None or root.get("rasterXSize") is not None:
        shape = _image_size(path, root.get("rasterYSize"), root.get("rasterXSize"),
                            "VRT rasterYSize/rasterXSize")
    extra = {"format": "gdal-vrt"}
    for m in root.findall("Metadata"):
        if m.get("domain", "").upper() == "IMD":
            for mdi in m.findall("MDI"):
                if mdi.get("key", "").upper() in ("SATID", "IMAGE_1.SATID") and mdi.text:
                    extra["satellite_id"] = mdi.text.strip().strip('"')
    return rpc, shape, extra
