"""OSSIM keyword lists (``.geom``): ``ossimRpcModel``-style RPCs, types A and B."""

from __future__ import annotations

import re
from typing import Any

from geoblock.errors import ModelFormatError
from geoblock.io.metadata import Fields
from geoblock_rpc._formats.common import (
    AnyPath, _POLY_KEYS, _SCALAR_KEYS, RPC00A_TO_B, Result, _field_error, _image_size,
    _rpc_from_fields, _src,
)

def _parse_ossim(path: AnyPath, text: str) -> Result:
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
        names: tuple[str, ...] = tuple(f"{key.lower()}_{i:02d}" for i in range(20))
        if fmt == "A":  # the B-order term j is the A-order term a with RPC00A_TO_B[a] == j
            names = tuple(names[RPC00A_TO_B.index(j)] for j in range(20))
        keys[key] = names
    for source in keys.values():
        for name in (source,) if isinstance(source, str) else source:
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
