"""Fixtures of the geoblock-quickbird tests (self-contained: run with --import-mode=importlib).

Real data lives in ``<repo>/../shared/data``; ``GEOBLOCK_TEST_DATA`` overrides it. Tests that
need it skip with the reason when it is absent.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[3]
DATA_DIR = Path(os.environ.get("GEOBLOCK_TEST_DATA", REPO.parent / "shared" / "data"))


@pytest.fixture(scope="session")
def data_dir() -> Path:
    """The shared real-data folder (skips the test when it is absent)."""
    if not DATA_DIR.is_dir():
        pytest.skip(f"real test data not found at {DATA_DIR} (set GEOBLOCK_TEST_DATA)")
    return DATA_DIR


# ============================================================ DigitalGlobe keyword-file products
#: DigitalGlobe's spelling of the keys in the .IMD/.EPH/.ATT/.GEO/.RPB/.TIL text files (the
#: XML tags are their upper-case forms; the reader is case-insensitive)
_KEYS = {
    "NUMROWS": "numRows", "NUMCOLUMNS": "numColumns", "BANDID": "bandId", "SATID": "satId",
    "TLCTIME": "TLCTime", "NUMTLC": "numTLC", "TLCLIST": "TLCList",
    "FIRSTLINETIME": "firstLineTime", "AVGLINERATE": "avgLineRate",
    "SCANDIRECTION": "scanDirection", "STARTTIME": "startTime", "NUMPOINTS": "numPoints",
    "TIMEINTERVAL": "timeInterval", "EPHEMLIST": "ephemList", "ATTLIST": "attList",
    "DETORIGINX": "detOriginX", "DETORIGINY": "detOriginY", "DETROTANGLE": "detRotAngle",
    "DETPITCH": "detPitch", "DETARRID": "detArrId", "POLYORDER": "polyOrder",
    "ALIST": "aList", "BLIST": "bList", "CX": "cX", "CY": "cY", "CZ": "cZ",
    "QCS1": "qcs1", "QCS2": "qcs2", "QCS3": "qcs3", "QCS4": "qcs4", "NUMTILES": "numTiles",
    "FILENAME": "filename", "ULCOLOFFSET": "ULColOffset", "ULROWOFFSET": "ULRowOffset",
    "LRCOLOFFSET": "LRColOffset", "LRROWOFFSET": "LRRowOffset",
    "LINEOFFSET": "lineOffset", "SAMPOFFSET": "sampOffset", "LATOFFSET": "latOffset",
    "LONGOFFSET": "longOffset", "HEIGHTOFFSET": "heightOffset", "LINESCALE": "lineScale",
    "SAMPSCALE": "sampScale", "LATSCALE": "latScale", "LONGSCALE": "longScale",
    "HEIGHTSCALE": "heightScale", "LINENUMCOEF": "lineNumCoef", "LINEDENCOEF": "lineDenCoef",
    "SAMPNUMCOEF": "sampNumCoef", "SAMPDENCOEF": "sampDenCoef", "SPECID": "SpecId",
}


def _number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _value(text: str) -> str:
    words = text.split()
    if len(words) > 1 and all(_number(w) for w in words):
        return "(" + ", ".join(words) + ")"
    if _number(text) or (len(text) > 10 and text[4:5] == "-" and "T" in text):
        return text  # numbers and times are written bare
    return f'"{text}"'


def _lines(element, depth: int = 0) -> list[str]:
    import re as _re

    out = []
    tab = "\t" * depth
    tiles = 0
    for child in element:
        tag = child.tag
        key = _KEYS.get(tag, tag)
        if tag.endswith("List") and len(child):
            rows = [(c.text or "").split() for c in child]
            key = _KEYS.get(tag[:-4], tag[:-4])
            if len(rows) == 1:  # one row: a flat list (the RPB's coefficients)
                body = ",\n".join(f"{tab}\t{v}" for v in rows[0])
            else:
                body = ",\n".join(f"{tab}\t({', '.join(r)})" for r in rows)
            out.append(f"{tab}{key} = (\n{body});")
        elif len(child):
            name = tag
            if tag == "TILE":
                tiles += 1
                name = f"TILE_{tiles}"
            elif tag == "IMAGE" and element.tag == "IMD":
                name = "IMAGE_1"
            out.append(f"{tab}BEGIN_GROUP = {name}")
            out.extend(_lines(child, depth + 1))
            out.append(f"{tab}END_GROUP = {name}")
        else:
            text = (child.text or "").strip()
            if _re.fullmatch(r"[A-Z]+", text) is None or tag != "BANDID":
                out.append(f"{tab}{key} = {_value(text)};")
            else:
                out.append(f'{tab}{key} = "{text}";')
    return out


def write_keyword_product(xml_path: Path, folder: Path, stem: str,
                          sections: tuple[str, ...] = ("IMD", "EPH", "ATT", "GEO", "RPB", "TIL"),
                          ) -> dict[str, Path]:
    """The separate DigitalGlobe text files of a combined ISD XML, written to ``folder``.

    DigitalGlobe's keyword syntax (``key = value;``, ``BEGIN_GROUP``/``END_GROUP``, lists in
    parentheses, ``END;``), its key spellings (camelCase), ``IMAGE_1`` and ``TILE_n`` groups;
    the RPB in the layout GDAL reads (``BEGIN_GROUP = IMAGE``).
    """
    import xml.etree.ElementTree as ET

    root = ET.parse(xml_path).getroot()
    folder.mkdir(parents=True, exist_ok=True)
    written = {}
    for section in sections:
        element = root.find(section)
        if element is None or not len(element):
            continue
        lines = _lines(element)
        if section == "RPB":  # GDAL's RPB: the IMAGE group holds the coefficients
            lines = [line.replace("IMAGE_1", "IMAGE") for line in lines]
        path = folder / f"{stem}.{section}"
        path.write_text("\n".join(lines) + "\nEND;\n", encoding="utf-8")
        written[section] = path
    return written


@pytest.fixture(scope="session")
def keyword_product():
    """:func:`write_keyword_product` (the tests run with --import-mode=importlib)."""
    return write_keyword_product

