"""Text formats: GDAL/IKONOS ``_RPC.TXT`` and rpcm/IARPA or GDAL JSON."""

from __future__ import annotations

import json
import re
from typing import Any

from geoblock.errors import ModelFormatError
from geoblock.io.metadata import Fields, read_bytes
from geoblock_rpc._formats.common import (
    AnyPath, _OPTIONAL_KEYS, _POLY_KEYS, _SCALAR_KEYS, Result, _field_error, _image_size, _require,
    _rpc_from_fields, _src,
)


def _parse_rpc_txt(path: AnyPath, text: str) -> Result:
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

_RPCM_KEYS = {
    "row_offset": "LINE_OFF", "col_offset": "SAMP_OFF", "lat_offset": "LAT_OFF",
    "lon_offset": "LONG_OFF", "alt_offset": "HEIGHT_OFF",
    "row_scale": "LINE_SCALE", "col_scale": "SAMP_SCALE", "lat_scale": "LAT_SCALE",
    "lon_scale": "LONG_SCALE", "alt_scale": "HEIGHT_SCALE",
    "row_num": "LINE_NUM_COEFF", "row_den": "LINE_DEN_COEFF",
    "col_num": "SAMP_NUM_COEFF", "col_den": "SAMP_DEN_COEFF",
}


def _parse_json(path: AnyPath) -> Result | None:
    try:
        data = json.loads(read_bytes(path).decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError):
        return None
    if not isinstance(data, dict):
        return None
    if isinstance(data.get("model"), str) and "schema_version" in data:
        return None  # geoblock's own model JSON: the core reader's
    block: dict[str, Any] = data["rpc"] if isinstance(data.get("rpc"), dict) else data
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
