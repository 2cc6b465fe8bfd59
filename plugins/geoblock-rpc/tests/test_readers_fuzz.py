"""Fuzz the RPC readers with mutants of the real files (issue 12, items 3 and 6).

Each mutant of a text RPC container of ``../shared/data`` (lines deleted, values emptied,
numbers replaced with garbage or with another number of the file, file truncated) must either
read as a model or raise a :class:`~geoblock.errors.GeoblockError` naming the file: never an
``IndexError``, ``ValueError``, ``KeyError``...; and every model it gives must be plausible
(its centre projects to a converged pixel near the image, see :func:`implausibility`). The
counts per format are printed (``pytest -s``); ``GEOBLOCK_FUZZ_EXAMPLES`` sets the number of
mutants per format (default 200).
"""

from __future__ import annotations

import os
import re
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
from geoblock_rpc import plugin
from geoblock_rpc.model import RpcModel
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from geoblock.errors import GeoblockError
from geoblock.testing.fuzz import read_mutant
from geoblock.typing import Status

#: format -> the text files of the shared data in that format (binary rasters are not fuzzed)
FORMATS: dict[str, list[str]] = {
    "rpc-txt": [
        "gdal-autotest/gcore/data/test_rpc.txt",
        "rpcm/test_rpc_files/20191015_073816_ssc1d3_0011_basic_l1a_panchromatic_dn_RPC.TXT",
        "rpcm/test_rpc_files/rpc_IKONOS.txt",
        "rpcm/test_rpc_files/rpc_PLANET_L1A.txt",
    ],
    "rpb": ["gdal-autotest/gcore/data/md_dg.RPB", "stereopipeline/tests/sample.RPB"],
    "dg-isd": ["rpcm/test_rpc_files/rpc_WV3.xml", "stereopipeline/tests/dg_example1.xml"],
    "dimap-v2": [
        "rpcm/test_rpc_files/rpc_SPOT6.xml",
        "shareloc/rpc/RPC_PHR1B_P_201709281038393_SEN_PRG_FC_178609-001.XML",
    ],
    "dimap-phr": ["shareloc/rpc/PHRDIMAP_P1BP--2017030824934340CP.XML"],
    "gdal-vrt": ["gdal-autotest/gcore/data/rpc.vrt"],
    "ossim-kwl": ["shareloc/rpc/PHR1B_P_201709281038393_SEN_PRG_FC_178609-001.geom"],
    "rpcm-json": ["rpcm/test_rpc_files/JAX_068_001_RGB.json"],
}

EXAMPLES = int(os.environ.get("GEOBLOCK_FUZZ_EXAMPLES", "200"))
GARBAGE = ["", " ", "abc", "nan", "inf", "-inf", "1e999", "1e308", "-9.9e231", "0", "-", "+",
           "1,5", "0x10", "++1", "()", "( )", ",", ";", ":", "=", "\"\"", "1e", "--3",
           "\u00e9", "\x00"]
_NUMBER = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?")
#: a value after ``KEY:`` / ``key = `` / between ``>`` and ``<`` (what "emptying" removes)
_VALUE = re.compile(r"(?<=[:=>])[^:=<>\n;]+")


def _mutate(text: str, data: st.DataObject) -> tuple[str, list[str]]:
    """Apply 1-4 random mutations to ``text``; returns it and what was done."""
    done = []
    for _ in range(data.draw(st.integers(1, 4), label="n_mutations")):
        op = data.draw(st.sampled_from(["delete_line", "empty_value", "garbage_number",
                                        "other_number", "truncate"]), label="op")
        lines = text.splitlines(keepends=True)
        if op == "delete_line" and lines:
            i = data.draw(st.integers(0, len(lines) - 1), label="line")
            text = "".join(lines[:i] + lines[i + 1:])
        elif op == "empty_value":
            spans = [m.span() for m in _VALUE.finditer(text)]
            if spans:
                a, b = spans[data.draw(st.integers(0, len(spans) - 1), label="value")]
                text = text[:a] + text[b:]
        elif op == "garbage_number":
            spans = [m.span() for m in _NUMBER.finditer(text)]
            if spans:
                a, b = spans[data.draw(st.integers(0, len(spans) - 1), label="number")]
                text = text[:a] + data.draw(st.sampled_from(GARBAGE), label="garbage") + text[b:]
        elif op == "other_number":  # a number of the file in another field (LAT_OFF 501)
            spans = [m.span() for m in _NUMBER.finditer(text)]
            if spans:
                a, b = spans[data.draw(st.integers(0, len(spans) - 1), label="number")]
                c, d = spans[data.draw(st.integers(0, len(spans) - 1), label="other")]
                text = text[:a] + text[c:d] + text[b:]
        elif op == "truncate":
            text = text[: data.draw(st.integers(0, len(text)), label="length")]
        done.append(op)
    return text, done


@pytest.mark.parametrize("fmt", sorted(FORMATS))
def test_mutated_rpc_files_read_or_raise_a_geoblock_error(fmt, data_dir, tmp_path_factory):
    sources = [data_dir / rel for rel in FORMATS[fmt] if (data_dir / rel).is_file()]
    if not sources:
        pytest.skip(f"no {fmt} file in {data_dir}")
    texts = {p: p.read_bytes().decode("utf-8-sig", errors="replace") for p in sources}
    work = tmp_path_factory.mktemp(f"fuzz-{fmt}")
    counts: Counter[str] = Counter()

    @settings(max_examples=EXAMPLES, deadline=None, database=None,
              suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
    @given(source=st.sampled_from(sources), data=st.data())
    def check(source: Path, data: st.DataObject) -> None:
        text, ops = _mutate(texts[source], data)
        mutant = work / source.name  # the same name: the sniffer uses it to break ties
        mutant.write_text(text, encoding="utf-8")
        model = read_mutant(lambda: plugin.geoblock_read_sensor_model(mutant, None, {}),
                            mutant, f"{source.name} mutated by {ops}", counts)
        if model is not None:
            assert isinstance(model, RpcModel)
            problem = implausibility(model)
            if problem is not None:
                counts["implausible accepted"] += 1
                implausible.append(f"{source.name} mutated by {ops}: {problem}")

    implausible: list[str] = []
    check()
    print(f"\n{fmt}: " + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())))
    assert counts["tried"] > 0
    assert counts["tried"] == sum(v for k, v in counts.items()
                                  if k not in ("tried", "implausible accepted"))
    assert not implausible, f"{len(implausible)} implausible models accepted: {implausible[:5]}"


def implausibility(model: RpcModel) -> str | None:
    """Why ``model`` is no RPC of a real image, or None: its own centre (LONG_OFF, LAT_OFF,
    HEIGHT_OFF) must project CONVERGED to finite pixels inside a generous box (the image plus
    its size on every side, or 11 scales around LINE/SAMP_OFF), with finite partials, and
    backproject to itself."""
    rpc = model.rpc
    rows, cols = model.shape
    (row, col), status = model.project_with_status(rpc.long_off, rpc.lat_off, rpc.height_off)
    if status != Status.CONVERGED or not (np.isfinite(row) and np.isfinite(col)):
        return f"its centre projects with status {Status(int(status)).name} to {row}, {col}"
    for value, n, off, scale, what in ((row, rows, rpc.line_off, rpc.line_scale, "row"),
                                       (col, cols, rpc.samp_off, rpc.samp_scale, "col")):
        # the image and its size on every side, or 11 scales around the offset (rpc.vrt: a
        # crop of a larger scene; PlanetScope L1A: the centre 4.2 scales from the offset)
        lo = min(-n - 1.0, off - 11 * abs(scale))
        hi = max(2.0 * n, off + 11 * abs(scale))
        if not lo <= value <= hi:
            return (f"its centre projects to {what} {float(value):g}, outside [{lo:g}, {hi:g}] "
                    f"(image {rows}x{cols})")
    jac = model.partials_geodetic(rpc.long_off, rpc.lat_off, rpc.height_off)
    if not np.all(np.isfinite(jac)):
        return "its partials at its centre are not finite"
    size = footprint_km(model)
    if size > MAX_FOOTPRINT_KM:
        return f"its image spans {size:.0f} km"
    g, status = model.backproject_with_status(row, col, rpc.height_off)
    if status != Status.CONVERGED:
        return f"its centre pixel backprojects with status {Status(int(status)).name}"
    if abs(g.lat - rpc.lat_off) > 1e-6 * max(abs(rpc.lat_scale), 1e-3):
        return f"its centre pixel backprojects to lat {float(g.lat)!r}, not {rpc.lat_off!r}"
    return None


#: (file, [(old, new) text replacements], fragments of the message besides the file name): the
#: mutants that gave IndexError / LookupError / ValueError / TypeError / OverflowError before
KNOWN = {
    "rpc-txt empty LINE_OFF": ("gdal-autotest/gcore/data/test_rpc.txt",
                               [("LINE_OFF: +015834.00 pixels", "LINE_OFF:")],
                               ["line 1", "LINE_OFF has no value"]),
    "rpc-txt empty coefficient": ("gdal-autotest/gcore/data/test_rpc.txt",
                                  [("LINE_NUM_COEFF_5: +5.236585985386163E-03",
                                   "LINE_NUM_COEFF_5:  ")],
                                  ["line 15", "LINE_NUM_COEFF_5 has no value"]),
    "rpc-txt overflowing extent": ("gdal-autotest/gcore/data/test_rpc.txt",
                                   [("LINE_OFF: +015834.00", "LINE_OFF: 1e308"),
                                    ("LINE_SCALE: +015834.00", "LINE_SCALE: 1e308")],
                                   ["LINE_OFF", "LINE_SCALE", "no finite image extent"]),
    "rpb empty lineOffset": ("stereopipeline/tests/sample.RPB",
                             [("lineOffset =   531.0;", "lineOffset = ;")],
                             ["RPB field lineOffset has no value"]),
    "xml unknown encoding": ("rpcm/test_rpc_files/rpc_WV3.xml",
                             [('encoding="UTF-8"', 'encoding="UTFabc"')],
                             ["XML: not well-formed", "UTFabc"]),
    "isd blank NUMROWS": ("stereopipeline/tests/dg_example1.xml",
                          [("<NUMROWS>23708</NUMROWS>", "<NUMROWS> </NUMROWS>")],
                          ["NUMROWS", "positive whole numbers"]),
    "vrt zero width": ("gdal-autotest/gcore/data/rpc.vrt",
                       [('rasterXSize="2220"', 'rasterXSize="0"')],
                       ["rasterXSize", "positive whole numbers"]),
    "dimap garbage ERR_BIAS_ROW": (
        "shareloc/rpc/RPC_PHR1B_P_201709281038393_SEN_PRG_FC_178609-001.XML",
        [("<ERR_BIAS_ROW>0.001754165229986022</ERR_BIAS_ROW>", "<ERR_BIAS_ROW>x</ERR_BIAS_ROW>")],
        ["ERR_BIAS_ROW", "not a number"]),
    "ossim infinite number_lines": (
        "shareloc/rpc/PHR1B_P_201709281038393_SEN_PRG_FC_178609-001.geom",
        [("number_lines:  22940", "number_lines:  1e999")],
        ["number_lines", "positive whole numbers"]),
}


@pytest.mark.parametrize("case", sorted(KNOWN))
def test_known_malformed_values_raise_a_geoblock_error_naming_file_and_field(
    case, data_dir, tmp_path
):
    rel, replacements, fragments = KNOWN[case]
    source = data_dir / rel
    if not source.is_file():
        pytest.skip(f"{rel} not in {data_dir}")
    text = source.read_bytes().decode("utf-8-sig")
    for old, new in replacements:
        assert old in text
        text = text.replace(old, new, 1)
    mutant = tmp_path / source.name
    mutant.write_text(text, encoding="utf-8")
    with pytest.raises(GeoblockError) as info:
        plugin.geoblock_read_sensor_model(mutant, None, {})
    for fragment in [str(mutant), *fragments]:
        assert fragment in str(info.value)


@pytest.mark.parametrize(("key", "value"), [
    ("row_num", 5), ("row_num", None), ("col_den", [[1.0]] * 20), ("col_num", {"a": 1}),
    ("row_offset", None), ("row_offset", True), ("lat_scale", [1.0]), ("alt_offset", 10**400),
])
def test_rpcm_json_values_of_the_wrong_type_are_named(key, value, data_dir, tmp_path):
    import json

    source = data_dir / "rpcm/test_rpc_files/JAX_068_001_RGB.json"
    if not source.is_file():
        pytest.skip(f"{source} not found")
    data = json.loads(source.read_text())
    data["rpc"][key] = value
    mutant = tmp_path / "rpc.json"
    mutant.write_text(json.dumps(data))
    with pytest.raises(GeoblockError, match=rf"rpc\.json: JSON field '{key}' must be"):
        plugin.geoblock_read_sensor_model(mutant, None, {})


#: widest footprint of an image an RPC00B can describe, km (the widest pushbroom swaths are a
#: few hundred km; the scale-swap mutants of issue 26 gave 2 000-9 700 km)
MAX_FOOTPRINT_KM = 1000.0


def footprint_km(model: RpcModel) -> float:
    """Largest great-circle distance between the image's corners and centre localised at
    HEIGHT_OFF (those that localise, with no validity domain), km."""
    rpc = model.rpc
    rows, cols = model.shape
    free = RpcModel(rpc, model.shape, domain_limit=1e3, height_limit=1e3)
    r = np.array([0.0, 0.0, rows - 1.0, rows - 1.0, (rows - 1) / 2.0])
    c = np.array([0.0, cols - 1.0, 0.0, cols - 1.0, (cols - 1) / 2.0])
    g, status = free.backproject_with_status(r, c, rpc.height_off)
    lon, lat = np.radians(g.lon[status == 0]), np.radians(g.lat[status == 0])
    cos = (np.sin(lat[:, None]) * np.sin(lat[None, :])
           + np.cos(lat[:, None]) * np.cos(lat[None, :]) * np.cos(lon[:, None] - lon[None, :]))
    return float(np.max(6371.0 * np.arccos(np.clip(cos, -1.0, 1.0)), initial=0.0))


def test_scale_swaps_are_refused_or_keep_an_earthly_footprint(data_dir):
    """Every scalar field of every shared RPC given another scalar field's value (the fuzz's
    "other_number" mutation, e.g. LAT_SCALE <- LONG_OFF): refused with a GeoblockError, or a
    model whose image spans at most MAX_FOOTPRINT_KM (issue 26: the rules of issue 12 let
    2 000-14 000 km footprints through; the GSD anisotropy limit refuses them)."""
    from geoblock_rpc.readers import read_rpc
    from geoblock_rpc.rpc00b import _SCALARS

    from .conftest import RPC_FILES

    counts: Counter[str] = Counter()
    wide = []
    for rel in sorted(RPC_FILES):
        rpc, shape, _ = read_rpc(data_dir / rel)
        for field in _SCALARS:
            for other in _SCALARS:
                value = getattr(rpc, other)
                if value == getattr(rpc, field):
                    continue
                counts["tried"] += 1
                try:
                    model = RpcModel(rpc.replace(**{field: value}), shape)
                except GeoblockError:
                    counts["refused"] += 1
                    continue
                size = footprint_km(model)
                if size > MAX_FOOTPRINT_KM:
                    wide.append(f"{rel}: {field.upper()} <- {other.upper()}: {size:.0f} km")
    print(f"\nscale swaps: {dict(counts)}, {len(wide)} wider than {MAX_FOOTPRINT_KM:g} km")
    assert counts["tried"] > 3000 and counts["refused"] > 0
    assert not wide, wide[:5]
