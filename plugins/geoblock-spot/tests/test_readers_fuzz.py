"""Fuzz the SPOT / Pleiades physical-metadata readers with mutants of the real files (issue 12,
items 3 and 6).

Each mutant of a DIMAP v1 ``METADATA.DIM`` (SPOT 1-5), DIMAP v2 ``DIM_*.XML`` (SPOT 6) or
Pleiades internal ``PHRDIMAP_*.XML`` of ``../shared/data`` (elements or lines deleted, values
emptied, numbers replaced with garbage, negated or scaled, file truncated) is read through the
plugin's read hook and must either

* give a model whose physical fields are plausible (:func:`_implausible`),
* give None (not recognised as a SPOT / Pleiades physical document), or
* raise a :class:`~geoblock.errors.GeoblockError` naming the file,

never an ``IndexError``, ``ValueError``, ``KeyError``... The counts per file are printed
(``pytest -s``); ``GEOBLOCK_FUZZ_EXAMPLES`` sets the number of mutants per file (default 50,
fewer for the slow SPOT 5 file: the whole module takes about 20 s).
"""

from __future__ import annotations

import os
import re
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
from geoblock_spot import plugin
from geoblock_spot.dimap import DimapFormatError
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from geoblock.errors import GeoblockError
from geoblock.models.linescan import LinescanModel
from geoblock.testing.fuzz import read_mutant

#: the physical-metadata files of the shared data read by this plugin
FILES = [
    "cosicorr3d/test_dataset/SPOT1.DIM",
    "cosicorr3d/test_dataset/SPOT2.DIM",
    "cosicorr3d/test_dataset/SPOT3.DIM",
    "cosicorr3d/test_dataset/SPOT4.DIM",
    "cosicorr3d/test_dataset/SPOT5.DIM",
    "stereopipeline/tests/spot_example1.xml",  # cropped: refused, but every mutant cleanly
    "cosicorr3d/test_dataset/SPOT6.XML",
    "shareloc/rpc/PHRDIMAP_P1BP--2017030824934340CP.XML",
    "shareloc/rpc/PHRDIMAP_P1BP--2018122638935449CP.XML",
]

EXAMPLES = int(os.environ.get("GEOBLOCK_FUZZ_EXAMPLES", "50"))
#: fraction of EXAMPLES for the slow files (SPOT 5: 2.5 MB and a 12000-detector table, about
#: 0.1 s a mutant; the others take 0.01-0.04 s)
SLOW = {"SPOT5.DIM": 0.4}
GARBAGE = ["", " ", "abc", "nan", "NaN", "inf", "-inf", "1e999", "1e308", "-1e308", "-9.9e231",
           "0", "-0", "-1", "-12000", "1e-300", "2", "99999999999", "-", "+", "1,5", "0x10",
           "++1", "1e", "--3", "\u00e9"]
_NUMBER = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?")
#: the text of a leaf element (what "emptying" removes)
_VALUE = re.compile(r"(?<=>)[^<>]+(?=</)")
_OPEN = re.compile(r"<([A-Za-z_][\w.-]*)(\s[^<>]*)?(?<!/)>")
#: lines holding the fields the model is built from (mutated more often than the rest)
_KEY = re.compile(
    r"<(NROWS|NCOLS|LINE_PERIOD|SENSOR_LINE_PERIOD|SCENE_CENTER_\w+|TIME|UTC_TIME|Q_TIME|START|"
    r"END|X|Y|Z|LOCATION_\w+|VELOCITY_\w+|YAW|PITCH|ROLL|Q[0-3]|PSI_[XY]|DETECTOR_ID|[XY]LOS_\d+|"
    r"COEFFICIENTS|DEGREE|OFFSET|SCALE|FIRST_COL|MISSION_INDEX|PIXEL_ORIGIN|ROW|COL|LON|LAT|"
    r"FRAME_\w+|GEODETIC_CRS_CODE)[ >]")


def _targets(text: str) -> dict[str, list[tuple[int, int]]]:
    """The spans of ``text`` a mutation can hit, by kind (computed once per file: the real
    files are up to 2.5 MB)."""
    lines = [m.span() for m in re.finditer(r"[^\n]*\n", text)]
    elements = []
    for m in _OPEN.finditer(text):
        close = text.find(f"</{m.group(1)}>", m.end())
        if close >= 0:
            elements.append((m.start(), close + len(m.group(1)) + 3))
    key_numbers = []
    for a, b in lines:
        if _KEY.search(text, a, b):
            key_numbers += [m.span() for m in _NUMBER.finditer(text, a, b)]
    return {"line": lines, "element": elements,
            "value": [m.span() for m in _VALUE.finditer(text)],
            "number": [m.span() for m in _NUMBER.finditer(text)], "key": key_numbers}


def _mutate(text: str, targets: dict[str, list[tuple[int, int]]],
            data: st.DataObject) -> tuple[str, list[str]]:
    """Apply 1-3 random mutations to ``text`` (non-overlapping edits of the original, then
    maybe a truncation); returns it and what was done."""
    edits: list[tuple[int, int, str]] = []
    done = []
    truncate = None
    for _ in range(data.draw(st.integers(1, 3), label="n_mutations")):
        op = data.draw(st.sampled_from(
            ["delete_line", "delete_element", "empty_value", "garbage_number", "garbage_key",
             "negate_key", "scale_key", "truncate"]), label="op")
        done.append(op)
        if op == "truncate":
            truncate = data.draw(st.integers(0, len(text)), label="length")
            continue
        kind = {"delete_line": "line", "delete_element": "element", "empty_value": "value",
                "garbage_number": "number"}.get(op, "key")
        spans = targets[kind]
        if not spans:
            continue
        a, b = spans[data.draw(st.integers(0, len(spans) - 1), label=kind)]
        old = text[a:b]
        if op in ("delete_line", "delete_element", "empty_value"):
            new = ""
        elif op == "negate_key":
            new = old[1:] if old.startswith("-") else "-" + old.lstrip("+")
        elif op == "scale_key":
            factor = data.draw(st.sampled_from([1e-3, 0.5, 2.0, 10.0, 1e3, 1e6]), label="factor")
            new = repr(float(old) * factor)
        else:
            new = data.draw(st.sampled_from(GARBAGE), label="garbage")
        edits.append((a, b, new))
    end = len(text)
    for a, b, new in sorted(edits, reverse=True):  # from the end: earlier spans stay valid
        if b <= end:
            text = text[:a] + new + text[b:]
            end = a
    if truncate is not None:
        text = text[:truncate]
    return text, done


def _implausible(model: LinescanModel) -> str | None:
    """What is physically impossible in an accepted model (None when nothing is)."""
    rows, cols = model.shape
    if not (isinstance(rows, int) and isinstance(cols, int) and rows >= 1 and cols >= 2):
        return f"shape {model.shape}"
    period = model.line_times.line_period_s
    if not (np.isfinite(period) and period > 0):
        return f"line period {period!r}"
    eph = model.ephemeris
    if not (np.all(np.isfinite(eph.time_s)) and np.all(np.diff(eph.time_s) > 0)):
        return "ephemeris times"
    radius = np.linalg.norm(eph.position_m, axis=1)
    if not np.all((radius >= 6.5e6) & (radius <= 8.5e6)):
        return f"orbit radius {radius.min():.6g}..{radius.max():.6g} m"
    speed = np.linalg.norm(eph.velocity_m_s, axis=1)
    if not np.all(speed < 1e4):
        return f"speed {speed.max():.6g} m/s"
    v = model.look.vectors
    tangents = v[:, :2] / v[:, 2:]
    if not (np.all(np.isfinite(tangents)) and np.all(np.abs(tangents) < 1.0)):
        return f"look tangents up to {np.nanmax(np.abs(tangents)):.6g}"
    norm = np.linalg.norm(model.attitude.quaternion, axis=1)
    if not np.all(np.abs(norm - 1.0) < 1e-3):
        return "non-unit quaternions"
    acc = model.location_accuracy_m
    if acc is not None and not (np.isfinite(acc) and acc > 0):
        return f"location accuracy {acc!r}"
    return None


@pytest.mark.parametrize("rel", FILES, ids=[Path(f).name for f in FILES])
def test_mutated_dimap_files_read_or_raise_a_geoblock_error(rel, data_dir, tmp_path_factory):
    source = data_dir / rel
    if not source.is_file():
        pytest.skip(f"{rel} not in {data_dir}")
    original = source.read_bytes().decode("utf-8", errors="replace")
    targets = _targets(original)
    work = tmp_path_factory.mktemp("fuzz-dimap")
    mutant = work / source.name
    counts: Counter[str] = Counter()

    @settings(max_examples=max(1, round(EXAMPLES * SLOW.get(source.name, 1.0))), deadline=None,
              database=None,
              suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
    @given(data=st.data())
    def check(data: st.DataObject) -> None:
        text, ops = _mutate(original, targets, data)
        mutant.write_text(text, encoding="utf-8")
        model = read_mutant(lambda: plugin.geoblock_read_sensor_model(mutant, None, {}),
                            mutant, f"{source.name} mutated by {ops}", counts)
        if model is None:
            return
        assert isinstance(model, LinescanModel)
        problem = _implausible(model)
        assert problem is None, f"{source.name} mutated by {ops}: accepted with {problem}"

    check()
    print(f"\n{source.name}: " + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())))
    assert counts["tried"] > 0
    assert counts["tried"] == sum(v for k, v in counts.items() if k != "tried")


def _replace_nth(text: str, pattern: str, repl: str, n: int = 0) -> str:
    matches = list(re.finditer(pattern, text))
    assert len(matches) > n, pattern
    m = matches[n]
    return text[:m.start()] + m.expand(repl) + text[m.end():]


SPOT5 = "cosicorr3d/test_dataset/SPOT5.DIM"
SPOT1 = "cosicorr3d/test_dataset/SPOT1.DIM"
SPOT6 = "cosicorr3d/test_dataset/SPOT6.XML"
PHR = "shareloc/rpc/PHRDIMAP_P1BP--2018122638935449CP.XML"

#: (file, [(regex, replacement, occurrence)], fragments of the message besides the file name):
#: physically impossible values each refused naming the file and the field
KNOWN = {
    "v1 negative NCOLS": (SPOT5, [(r"<NCOLS>\d+", "<NCOLS>-12000", 0)], ["NCOLS"]),
    "v1 zero LINE_PERIOD": (SPOT5, [(r"<LINE_PERIOD>[^<]+", "<LINE_PERIOD>0", 0)],
                            ["LINE_PERIOD", "> 0"]),
    "v1 orbit at 1e3 x": (SPOT5, [(r"(<Location>\s*<X>)([^<]+)", r"\g<1>7e9", 0)],
                          ["Location", "radius"]),
    "v1 fast satellite": (SPOT5, [(r"(<Velocity>\s*<X>)([^<]+)", r"\g<1>-2e4", 3)],
                          ["Velocity"]),
    "v1 wide look angle": (SPOT5, [(r"<PSI_Y>[^<]+", "<PSI_Y>1.2", 5)], ["PSI_Y"]),
    "v1 huge yaw": (SPOT5, [(r"<YAW>[^<]+", "<YAW>1e300", 4)], ["YAW"]),
    "v1 non-unit quaternion": (SPOT5, [(r"<Q0>[^<]+", "<Q0>5.0", 2)], ["Q0", "unit"]),
    "v1 garbage angular speed": (SPOT1, [(r"(?s)(<Angular_Speeds>(?:(?!</Angular_Speeds>).)*?<YAW>)"
                                          r"[^<]+", r"\g<1>1e200", 1)], ["Angular_Speeds"]),
    "v2 garbage LINE_PERIOD": (SPOT6, [(r"(<LINE_PERIOD[^>]*>)[^<]+", r"\g<1>1e308", 0)],
                               ["LINE_PERIOD"]),
    "v2 non-unit quaternion": (SPOT6, [(r"<Q1>[^<]+", "<Q1>3", 10)],
                               ["Quaternion_List/Quaternion[10]/Q0..Q3", "unit"]),
    "v2 wide look": (SPOT6, [(r"<XLOS_0>[^<]+", "<XLOS_0>2.5", 0)], ["XLOS"]),
    "phr orbit radius": (PHR, [(r"(<LOCATION_VALUES[^>]*>)\S+", r"\g<1>1e9", 13)],
                         ["LOCATION_VALUES"]),
    "phr quaternion polynomial": (PHR, [(r"(<Q2>\s*<DEGREE>[^<]*</DEGREE>\s*<COEFFICIENTS>)\S+",
                                         r"\g<1>40", 0)], ["Polynomial_Models", "unit"]),
}


@pytest.mark.parametrize("case", sorted(KNOWN))
def test_implausible_values_are_refused_naming_file_and_field(case, data_dir, tmp_path):
    rel, edits, fragments = KNOWN[case]
    source = data_dir / rel
    if not source.is_file():
        pytest.skip(f"{rel} not in {data_dir}")
    text = source.read_text(encoding="utf-8")
    for pattern, repl, n in edits:
        text = _replace_nth(text, pattern, repl, n)
    mutant = tmp_path / source.name
    mutant.write_text(text, encoding="utf-8")
    with pytest.raises(DimapFormatError) as info:
        plugin.geoblock_read_sensor_model(mutant, None, {})
    for fragment in [str(mutant), *fragments]:
        assert fragment in str(info.value)


@pytest.mark.parametrize("accuracy", [0.0, -3.0, float("nan"), float("inf")])
def test_implausible_accuracy_option_is_refused_naming_the_file(accuracy, data_dir):
    source = data_dir / SPOT6
    if not source.is_file():
        pytest.skip(f"{SPOT6} not in {data_dir}")
    with pytest.raises(GeoblockError, match=re.escape(str(source)) + ".*accuracy"):
        plugin.geoblock_read_sensor_model(source, None, {"accuracy_m": accuracy})


@pytest.mark.parametrize(("rel", "options"), [
    (SPOT5, {"height_range": "abc"}), (SPOT5, {"height_range": (1.0, float("nan"))}),
    (SPOT5, {"use_attitude": "yes"}), (SPOT5, {"parameters": "bogus"}),
    (SPOT5, {"parameters": 3}), (SPOT6, {"attitude_step_s": 0}),
    (PHR, {"attitude_step_s": "fast"}), (PHR, {"parameters": "bogus"}),
    (PHR, {"parameters": "dg"}), (PHR, {"height_range": (5.0, 1.0)}),
])
def test_bad_options_are_refused_naming_the_file(rel, options, data_dir):
    source = data_dir / rel
    if not source.is_file():
        pytest.skip(f"{rel} not in {data_dir}")
    with pytest.raises(GeoblockError) as info:
        plugin.geoblock_read_sensor_model(source, None, options)
    assert str(source) in str(info.value)
