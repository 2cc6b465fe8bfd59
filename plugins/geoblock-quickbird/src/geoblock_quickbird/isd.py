"""DigitalGlobe/Maxar image support data (ISD): readers for the combined XML and the text files.

A DigitalGlobe basic (1B) product describes its image geometry in six sections:

=======  ==========================================================================
``IMD``  image metadata: size, satellite, band, line-time table (TLC), scan direction
``EPH``  ephemeris: ECEF positions and velocities every ``TIMEINTERVAL`` s, covariances
``ATT``  attitude: body -> ECEF quaternions ``(q1, q2, q3, q4)``, ``q4`` scalar, covariances
``GEO``  camera: principal distance, detector array mounting, camera -> body attitude
``RPB``  the vendor's RPC (read by geoblock-rpc)
``TIL``  tiling: each tile file's rows and columns in the full image
=======  ==========================================================================

either as one XML document (root ``<isd>``, the form Maxar delivers with newer products and
that ASP, rpcm and s2p read) or as separate ``.IMD``, ``.EPH``, ``.ATT``, ``.GEO``, ``.RPB`` and
``.TIL`` keyword files (``key = value;``, ``BEGIN_GROUP = NAME`` ... ``END_GROUP = NAME``,
lists in parentheses). :func:`read_isd` reads either into one :class:`Isd`; :func:`find_isd`
finds the support data of a product directory or of any one of its files (an image tile
too).

Conventions (from the Ames Stereo Pipeline's ``LinescanDGModel.cc``, checked against the
vendor RPB: see :mod:`geoblock_quickbird.model`):

* rows and columns are 0-based pixel centres, as geoblock's; the TLC table gives the
  exposure time of rows (``TLCLIST`` = ``row, seconds after TLCTIME``);
* all times here are seconds after :attr:`Isd.epoch` (``TLCTIME``), UTC;
* sample ``i`` (0-based) of the ephemeris and the attitude is at ``STARTTIME + i *
  TIMEINTERVAL``; the first list item of each sample is its 1-based index;
* lengths of ``GEO`` are millimetres (principal distance, detector origin and pitch) and
  metres (perspective-centre offset), angles degrees.
"""

from __future__ import annotations

import os
import re
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from geoblock.errors import GeoblockIOError, ModelFormatError
from geoblock.io.metadata import Fields, decode_text, parse_utc, read_bytes, read_xml
from geoblock.io.vsi import as_path

__all__ = [
    "SECTIONS",
    "Isd",
    "IsdFormatError",
    "Tile",
    "find_isd",
    "read_isd",
]

#: the ISD sections, in the order of a combined XML document
SECTIONS: tuple[str, ...] = ("IMD", "EPH", "ATT", "GEO", "RPB", "TIL")
#: the sections the rigorous model needs
PHYSICAL_SECTIONS: tuple[str, ...] = ("IMD", "EPH", "ATT", "GEO")
#: years accepted in ISD times: wide, since ASP's anonymised test products are dated 1959
#: and 1432 (the times are used relative to each other; garbage is caught by the ranges)
YEAR_RANGE = (1000, 2999)
#: largest image side accepted, pixels
MAX_IMAGE_SIZE = 10_000_000


class IsdFormatError(ModelFormatError):
    """DigitalGlobe support data are missing, malformed or inconsistent; the message names
    the file and the field.

    Attributes
    ----------
    path : str
        The file at fault.
    field : str
        The section and field (``EPH.EPHEMLIST[3]``).
    """

    def __init__(self, path: str | os.PathLike[str], field: str, problem: str,
                 missing: tuple[str, ...] = ()) -> None:
        super().__init__(f"{str(path)!r}: ISD field {field}: {problem}")
        self.path = str(path)
        self.field = field
        #: the physical sections absent (an RPC-only product), else ()
        self.missing = missing


def _error(source: str, field: str, problem: str) -> IsdFormatError:
    return IsdFormatError(source, field, problem)


@dataclass(frozen=True)
class Tile:
    """One tile file of a tiled product: its place in the full image.

    Attributes
    ----------
    filename : str
        The tile's file name as the ``TIL`` section gives it.
    offset : (int, int)
        ``(row0, col0)``: the full-image pixel of the tile's first pixel.
    shape : (int, int)
        ``(rows, cols)`` of the tile.
    """

    filename: str
    offset: tuple[int, int]
    shape: tuple[int, int]


@dataclass(frozen=True, eq=False)
class Isd:
    """Parsed DigitalGlobe image support data (the physical sections and the tiling).

    All times are seconds after :attr:`epoch`; positions metres and velocities metres per
    second in ECEF (EPSG:4978); rows/columns 0-based pixel centres.

    Attributes
    ----------
    path : pathlib.Path
        What was opened (a file or a product directory).
    sources : dict of str to pathlib.Path
        The file each section was read from.
    satellite : str
        ``SATID`` (``QB02``, ``WV01``, ``WV02``, ``WV03``, ``GE01`` ...).
    band : str
        ``BANDID`` (``P`` for panchromatic).
    product : str
        ``IMAGEDESCRIPTOR`` (``Basic1B``, ``Stereo1B`` ...) or ``""``.
    shape : (int, int)
        ``(NUMROWS, NUMCOLUMNS)``.
    epoch : str
        ISO-8601 UTC ``TLCTIME``.
    reference_row, reference_time_s, line_period_s : float
        The row exposed at ``reference_time_s`` and the line period (from the TLC table, or
        from ``AVGLINERATE`` and ``SCANDIRECTION`` when it holds one entry, as ASP does).
    ephemeris_time_s : ndarray, (n,)
    position_m, velocity_m_s : ndarray, (n, 3)
    position_covariance_m2 : ndarray, (n, 6)
        ``xx, xy, xz, yy, yz, zz`` of each sample.
    attitude_time_s : ndarray, (m,)
    quaternion : ndarray, (m, 4)
        ``(q1, q2, q3, q4)`` as in the file: ``q4`` is the scalar part; body -> ECEF.
    attitude_covariance : ndarray, (m, 10)
        The upper triangle of each quaternion's covariance (``q11, q12, q13, q14, q22 ...``).
    principal_distance_mm : float
    detector_origin_mm : (float, float)
        ``(DETORIGINX, DETORIGINY)`` of the band's detector array in the camera frame.
    detector_rotation_deg : float
    detector_pitch_mm : float
    camera_attitude : (float, float, float, float)
        ``(QCS1, QCS2, QCS3, QCS4)``, camera -> body, ``QCS4`` scalar.
    perspective_centre_m : (float, float, float)
        The camera's perspective centre in the body frame, metres.
    tiles : tuple of Tile
        The ``TIL`` section's tiles (empty without one).
    has_rpb : bool
        Whether the support data hold an ``RPB`` section (``model="rpc"`` reads it).
    rpb_height_range : (float, float) or None
        ``HEIGHTOFFSET -/+ HEIGHTSCALE`` of the RPB, metres, when it states them.
    """

    path: Path
    sources: dict[str, Path]
    satellite: str
    band: str
    product: str
    shape: tuple[int, int]
    epoch: str
    reference_row: float
    reference_time_s: float
    line_period_s: float
    ephemeris_time_s: np.ndarray
    position_m: np.ndarray
    velocity_m_s: np.ndarray
    position_covariance_m2: np.ndarray
    attitude_time_s: np.ndarray
    quaternion: np.ndarray
    attitude_covariance: np.ndarray
    principal_distance_mm: float
    detector_origin_mm: tuple[float, float]
    detector_rotation_deg: float
    detector_pitch_mm: float
    camera_attitude: tuple[float, float, float, float]
    perspective_centre_m: tuple[float, float, float]
    tiles: tuple[Tile, ...] = field(default=())
    has_rpb: bool = False
    rpb_height_range: tuple[float, float] | None = None

    def tile(self, name: str) -> Tile | None:
        """The tile whose file name (or stem) is ``name``'s, case-insensitively, or None."""
        key = Path(name).name.lower()
        stem = Path(name).stem.lower()
        for t in self.tiles:
            tname = Path(t.filename).name.lower()
            if tname == key or Path(tname).stem == stem:
                return t
        return None

    def __repr__(self) -> str:
        return (f"Isd({self.satellite} {self.product or 'product'} band {self.band}, "
                f"shape={self.shape}, epoch={self.epoch}, path={str(self.path)!r})")


# ============================================================================ finding the data
_TEXT_SUFFIXES = {f".{s.lower()}" for s in SECTIONS}


def _is_isd_xml(path: Path) -> bool:
    try:
        head = read_bytes(path, 4096)
    except GeoblockIOError:
        return False
    return re.search(rb"<\s*isd[\s>]", head, re.IGNORECASE) is not None


def _siblings(path: Path) -> dict[str, Path]:
    """The section text files beside ``path`` sharing its stem: ``{"IMD": Path, ...}``."""
    out: dict[str, Path] = {}
    stem = path.stem.lower()
    try:
        entries = list(path.parent.iterdir())
    except OSError:
        return out
    for entry in entries:
        suffix = entry.suffix.lower()
        if suffix in _TEXT_SUFFIXES and entry.stem.lower() == stem and entry.is_file():
            out[suffix[1:].upper()] = entry
    return out


def find_isd(path: str | os.PathLike[str]) -> Path | dict[str, Path] | None:
    """The support data of a DigitalGlobe product, or None if ``path`` is not one.

    Parameters
    ----------
    path : path
        A combined ISD ``.XML``; any of a product's ``.IMD``, ``.EPH``, ``.ATT``, ``.GEO``,
        ``.RPB``, ``.TIL`` files; an image (``.TIF``, ``.NTF``) with its ISD beside it (same
        stem, or the product whose ``TIL`` lists it); or a product directory holding
        exactly one product.

    Returns
    -------
    pathlib.Path or dict or None
        The combined XML, or the section files by section name; None if no support data is
        found (other readers are then asked).
    """
    p = as_path(path)  # a GDAL virtual path (/vsizip/...) stays one
    if p.is_dir():
        found = [q for q in sorted(p.iterdir()) if q.suffix.lower() == ".xml"
                 and q.is_file() and _is_isd_xml(q)]
        stems = sorted({q.stem for q in p.iterdir() if q.suffix.lower() == ".imd"})
        if len(found) == 1 and not stems:
            return found[0]
        if len(stems) == 1 and not found:
            return _siblings(p / f"{stems[0]}.IMD")
        if found or stems:
            names = [q.name for q in found] + [f"{s}.IMD" for s in stems]
            raise IsdFormatError(p, "(product directory)",
                                 f"holds {len(names)} products ({', '.join(names[:6])}); "
                                 "open one of their files")
        return None
    if not p.is_file():
        return None
    suffix = p.suffix.lower()
    if suffix == ".xml":
        return p if _is_isd_xml(p) else None
    if suffix in _TEXT_SUFFIXES:
        siblings = _siblings(p)
        return siblings if "IMD" in siblings else None
    # an image: its ISD beside it, same stem, or a product whose TIL lists it
    xml = [q for q in p.parent.glob("*") if q.suffix.lower() == ".xml"
           and q.stem.lower() == p.stem.lower() and _is_isd_xml(q)]
    if xml:
        return xml[0]
    siblings = _siblings(p)
    if "IMD" in siblings:
        return siblings
    for til in sorted(q for q in p.parent.iterdir() if q.suffix.lower() == ".til"):
        try:
            text = decode_text(read_bytes(til))
        except GeoblockIOError:
            continue
        if p.name.lower() in text.lower():
            siblings = _siblings(til)
            if "IMD" in siblings:
                return siblings
    return None


# ================================================================================= parsing
def _xml_tree(element: ET.Element) -> Any:
    """An XML element as nested dicts of strings; ``<XLISTList>`` -> ``"XLIST": [rows]``,
    repeated children -> lists, keys upper-case."""
    children = list(element)
    if not children:
        return (element.text or "").strip()
    out: dict[str, Any] = {}
    tag = element.tag
    if tag.endswith("List") and len({c.tag for c in children}) == 1:
        return [(c.text or "").strip() for c in children]
    for child in children:
        key = child.tag.upper()
        if child.tag.endswith("List") and len(child) and len({c.tag for c in child}) == 1:
            key = child.tag[:-4].upper()
        value = _xml_tree(child)
        if key in out:
            if not isinstance(out[key], list):
                out[key] = [out[key]]
            out[key].append(value)
        else:
            out[key] = [value] if key == "TILE" else value
    return out


_TOKEN = re.compile(r'"[^"]*"|[()=;,]|[^\s()=;,"]+')


def _keyword_tree(text: str, source: Path, section: str) -> dict[str, Any]:
    """A keyword file (``key = value;``, groups, parenthesised lists) as nested dicts."""
    tokens = _TOKEN.findall(text)
    pos = 0

    def fail(problem: str) -> IsdFormatError:
        return IsdFormatError(source, section, problem)

    def value() -> Any:
        nonlocal pos
        if pos >= len(tokens):
            raise fail("the file ends inside a value (truncated?)")
        tok = tokens[pos]
        if tok != "(":
            pos += 1
            return tok.strip('"')
        pos += 1
        items: list[Any] = []
        while True:
            if pos >= len(tokens):
                raise fail("the file ends inside a parenthesised list (truncated?)")
            if tokens[pos] == ")":
                pos += 1
                break
            if tokens[pos] == ",":
                pos += 1
                continue
            items.append(value())
        if items and all(isinstance(i, list) for i in items):
            return [" ".join(i) for i in items]  # rows of a table
        if any(isinstance(i, list) for i in items):
            raise fail("a list mixes numbers and sub-lists")
        return items

    def group(end: str | None) -> dict[str, Any]:
        nonlocal pos
        out: dict[str, Any] = {}
        while pos < len(tokens):
            key = tokens[pos]
            if key.upper() == "END" and (pos + 1 >= len(tokens) or tokens[pos + 1] == ";"):
                pos += 2
                if end is not None:
                    raise fail(f"END before END_GROUP = {end}")
                return out
            if pos + 1 >= len(tokens) or tokens[pos + 1] != "=":
                raise fail(f"expected 'key = value;' at {key!r}")
            pos += 2
            if key.upper() == "BEGIN_GROUP":
                name = str(value()).upper()
                body = group(name)
                base = re.sub(r"_\d+$", "", name)
                if base in ("TILE", "IMAGE") and name != base:
                    if base == "TILE":
                        out.setdefault("TILE", []).append(body)
                    else:
                        out[base] = body
                else:
                    out[name] = body
                continue
            if key.upper() == "END_GROUP":
                name = str(value()).upper()
                if pos < len(tokens) and tokens[pos] == ";":
                    pos += 1
                if name != end:
                    raise fail(f"END_GROUP = {name} closes group {end}")
                return out
            val = value()
            if isinstance(val, list) and val and not any(" " in str(v) for v in val):
                val = " ".join(str(v) for v in val)
            out[key.upper()] = val
            if pos < len(tokens) and tokens[pos] == ";":
                pos += 1
        if end is not None:
            raise fail(f"the file ends before END_GROUP = {end} (truncated?)")
        return out

    return group(None)


def _load(found: Path | dict[str, Path]) -> tuple[dict[str, Any], dict[str, Path]]:
    """``({section: tree}, {section: file})`` of a combined XML or of section files."""
    if not isinstance(found, dict):  # one ISD XML (a Path or a VsiPath)
        root = read_xml(found, _error).root
        if root.tag.lower() != "isd":
            raise IsdFormatError(found, "(root)", f"root element <{root.tag}> is not <isd>")
        tree = _xml_tree(root)
        if not isinstance(tree, dict):
            raise IsdFormatError(found, "(root)", "the <isd> element is empty")
        return tree, {name: found for name in tree}
    trees: dict[str, Any] = {}
    for name, file in found.items():
        text = decode_text(read_bytes(file))
        trees[name] = _keyword_tree(text, file, name)
    return trees, dict(found)


def _fields(trees: dict[str, Any], sources: dict[str, Path], section: str) -> Fields:
    """A present section (read_isd checks the physical sections first) as Fields."""
    return Fields(str(sources[section]), trees[section], f"{section}.", _error)


def _time(f: Fields, key: str) -> np.datetime64:
    text = f.text(key)
    return parse_utc(text, lambda fld, problem: f.error(fld, problem), key,
                     years=YEAR_RANGE, unit="us")


def _seconds(t: np.datetime64, epoch: np.datetime64) -> float:
    return float((t - epoch) / np.timedelta64(1, "us")) * 1e-6


def _rows(f: Fields, key: str, width: int, count_key: str) -> np.ndarray:
    """A table of ``count_key`` rows of at least ``width`` numbers each, (n, width)."""
    raw = f.get(key)
    if isinstance(raw, str):
        raw = [raw]
    if not isinstance(raw, list) or not raw:
        raise f.error(key, "must be a list of samples")
    rows = []
    for i, row in enumerate(raw):
        values = Fields(f.source, {f"{key}[{i}]": row}, f.where, _error).numbers(f"{key}[{i}]")
        if values.size < width:
            raise f.error(f"{key}[{i}]", f"has {values.size} numbers, expected {width}")
        rows.append(values[:width])
    table = np.array(rows)
    n = f.number(count_key, from_text=True, integer=True, low=1)
    if n != table.shape[0]:
        raise f.error(count_key, f"says {n} samples, {key} has {table.shape[0]}")
    index = table[:, 0]
    if not np.array_equal(index, np.arange(1, n + 1)):
        i = int(np.flatnonzero(index != np.arange(1, n + 1))[0])
        raise f.error(f"{key}[{i}]", f"sample index {index[i]:g}, expected {i + 1} (samples "
                                     "numbered from 1, one per TIMEINTERVAL)")
    return table


def read_isd(path: str | os.PathLike[str]) -> Isd:
    """Read the support data of a DigitalGlobe/Maxar basic product.

    Parameters
    ----------
    path : path
        Anything :func:`find_isd` accepts.

    Returns
    -------
    Isd

    Raises
    ------
    IsdFormatError
        No support data found, a physical section missing (``IMD``, ``EPH``, ``ATT``,
        ``GEO``), or a field missing, malformed or inconsistent (named with its file).
    GeoblockIOError
        A file cannot be read.
    """
    p = as_path(path)  # a GDAL virtual path (/vsizip/...) stays one
    found = find_isd(p)
    if found is None:
        raise IsdFormatError(p, "(file)", "no DigitalGlobe support data (an <isd> XML or "
                                          ".IMD/.EPH/.ATT/.GEO files) found here")
    trees, sources = _load(found)
    missing = [s for s in PHYSICAL_SECTIONS if not isinstance(trees.get(s), Mapping)]
    if missing:
        raise IsdFormatError(next(iter(sources.values()), p), "/".join(missing),
                             "section missing (the rigorous model needs IMD, EPH, ATT and GEO; "
                             "an RPC-only product opens with model='rpc')",
                             missing=tuple(missing))
    imd = _fields(trees, sources, "IMD")
    image = imd.table("IMAGE", required=True)
    rows = imd.number("NUMROWS", from_text=True, integer=True, low=1, high=MAX_IMAGE_SIZE)
    cols = imd.number("NUMCOLUMNS", from_text=True, integer=True, low=2, high=MAX_IMAGE_SIZE)
    band = imd.text("BANDID", "P") or "P"
    satellite = image.text("SATID", "")
    product = imd.text("IMAGEDESCRIPTOR", "") or image.text("IMAGEDESCRIPTOR", "")
    epoch = _time(image, "TLCTIME")
    tlc = _tlc(image)
    if tlc.shape[0] == 1:
        rate = image.number("AVGLINERATE", from_text=True, low=0.0, strict_low=True)
        direction = image.text("SCANDIRECTION", "Forward").lower()
        period = (1.0 if direction == "forward" else -1.0) / rate
    else:
        period = _tlc_period(image, tlc)
    ref_row, ref_time = float(tlc[0, 0]), float(tlc[0, 1])
    if "FIRSTLINETIME" in image:
        first = _seconds(_time(image, "FIRSTLINETIME"), epoch)
        expected = ref_time + (0.0 - ref_row) * period
        if abs(first - expected) > 0.1 * abs(period):
            raise image.error("FIRSTLINETIME", f"is {first:.6f} s after TLCTIME, the TLC table "
                                               f"puts row 0 at {expected:.6f} s")

    eph = _fields(trees, sources, "EPH")
    e_start = _seconds(_time(eph, "STARTTIME"), epoch)
    e_step = eph.number("TIMEINTERVAL", from_text=True, low=0.0, strict_low=True)
    etab = _rows(eph, "EPHEMLIST", 7, "NUMPOINTS")
    ecov = _covariance(eph, "EPHEMLIST", 7, 6, etab.shape[0])
    att = _fields(trees, sources, "ATT")
    a_start = _seconds(_time(att, "STARTTIME"), epoch)
    a_step = att.number("TIMEINTERVAL", from_text=True, low=0.0, strict_low=True)
    atab = _rows(att, "ATTLIST", 5, "NUMPOINTS")
    acov = _covariance(att, "ATTLIST", 5, 10, atab.shape[0])
    q = atab[:, 1:5]
    norm = np.linalg.norm(q, axis=1)
    if np.any(~(np.abs(norm - 1.0) < 1e-3)):
        i = int(np.flatnonzero(~(np.abs(norm - 1.0) < 1e-3))[0])
        raise att.error(f"ATTLIST[{i}]", f"is not a unit quaternion (norm {norm[i]:.6g})")

    geo = _fields(trees, sources, "GEO")
    pd = geo.table("PRINCIPAL_DISTANCE", required=True).number("PD", from_text=True, low=1.0)
    detector = _detector(geo, band)
    cam = geo.table("CAMERA_ATTITUDE", required=True)
    qcs = tuple(cam.number(f"QCS{i}", from_text=True) for i in (1, 2, 3, 4))
    if abs(float(np.linalg.norm(qcs)) - 1.0) > 1e-3:
        raise cam.error("QCS1..QCS4", f"is not a unit quaternion (norm "
                                      f"{float(np.linalg.norm(qcs)):.6g})")
    centre = geo.table("PERSPECTIVE_CENTER")
    pc = tuple(centre.number(k, 0.0, from_text=True) for k in ("CX", "CY", "CZ"))
    distortion = geo.table("OPTICAL_DISTORTION")
    order = distortion.number("POLYORDER", 0, from_text=True, integer=True)
    if order > 0:
        coefficients = np.concatenate([distortion.numbers(k, []) for k in ("ALIST", "BLIST")])
        if np.any(coefficients != 0):
            raise distortion.error("POLYORDER", f"optical distortion polynomials of order "
                                                f"{order} are not supported")
    tiles = _tiles(trees, sources, (rows, cols))
    return Isd(
        path=p, sources=sources, satellite=satellite, band=band, product=product,
        shape=(rows, cols), epoch=str(epoch) + "Z", reference_row=ref_row,
        reference_time_s=ref_time, line_period_s=period,
        ephemeris_time_s=e_start + e_step * np.arange(etab.shape[0]),
        position_m=etab[:, 1:4], velocity_m_s=etab[:, 4:7], position_covariance_m2=ecov,
        attitude_time_s=a_start + a_step * np.arange(atab.shape[0]), quaternion=q,
        attitude_covariance=acov, principal_distance_mm=pd,
        detector_origin_mm=(detector["DETORIGINX"], detector["DETORIGINY"]),
        detector_rotation_deg=detector["DETROTANGLE"], detector_pitch_mm=detector["DETPITCH"],
        camera_attitude=qcs,  # type: ignore[arg-type]
        perspective_centre_m=pc,  # type: ignore[arg-type]
        tiles=tiles, has_rpb="RPB" in trees, rpb_height_range=_rpb_heights(trees, sources))


def _rpb_heights(trees: dict[str, Any], sources: dict[str, Path]) -> tuple[float, float] | None:
    """``HEIGHTOFFSET -/+ HEIGHTSCALE`` of the RPB section (its ``IMAGE`` group), if stated;
    a malformed RPB is left to geoblock-rpc to report (``model="rpc"``)."""
    rpb = trees.get("RPB")
    image = rpb.get("IMAGE") if isinstance(rpb, Mapping) else None
    if not isinstance(image, Mapping):
        return None
    f = Fields(str(sources["RPB"]), image, "RPB.IMAGE.", _error)
    try:
        offset = f.number("HEIGHTOFFSET", from_text=True)
        scale = f.number("HEIGHTSCALE", from_text=True, low=0.0, strict_low=True)
    except IsdFormatError:
        return None
    return offset - scale, offset + scale


def _tlc(image: Fields) -> np.ndarray:
    raw = image.get("TLCLIST")
    if isinstance(raw, str):
        raw = [raw]
    if not isinstance(raw, list) or not raw:
        raise image.error("TLCLIST", "must list (row, time) pairs")
    pairs = []
    for i, row in enumerate(raw):
        key = f"TLCLIST[{i}]"
        pairs.append(Fields(image.source, {key: row}, image.where, _error).numbers(key, count=2))
    tlc = np.array(pairs)
    if "NUMTLC" in image:
        n = image.number("NUMTLC", from_text=True, integer=True, low=1)
        if n != tlc.shape[0]:
            raise image.error("NUMTLC", f"says {n} entries, TLCLIST has {tlc.shape[0]}")
    return tlc


def _tlc_period(image: Fields, tlc: np.ndarray) -> float:
    """The line period of a TLC table of >= 2 entries; refuses a table that is not linear."""
    drow, dt = np.diff(tlc[:, 0]), np.diff(tlc[:, 1])
    if np.any(~(drow > 0)):
        raise image.error("TLCLIST", "rows must increase")
    slopes = dt / drow
    period = float((tlc[-1, 1] - tlc[0, 1]) / (tlc[-1, 0] - tlc[0, 0]))
    if not (np.isfinite(period) and period != 0 and abs(period) < 1.0):
        raise image.error("TLCLIST", f"gives a line period of {period!r} s")
    if np.any(np.abs(slopes - period) * (tlc[-1, 0] - tlc[0, 0]) > 0.01 * abs(period)):
        raise image.error("TLCLIST", "the line rate changes within the image (a piecewise "
                                     "TLC table is not supported yet)")
    return period


def _covariance(f: Fields, key: str, first: int, width: int, n: int) -> np.ndarray:
    """The covariance columns after the first ``first`` numbers of each sample (zeros when a
    file omits them)."""
    raw = f.get(key)
    if isinstance(raw, str):
        raw = [raw]
    out = np.zeros((n, width))
    for i, row in enumerate(raw):
        values = Fields(f.source, {f"{key}[{i}]": row}, f.where, _error).numbers(f"{key}[{i}]")
        if values.size >= first + width:
            out[i] = values[first:first + width]
    return out


def _detector(geo: Fields, band: str) -> dict[str, float]:
    mounting = geo.table("DETECTOR_MOUNTING", required=True)
    groups = {k: v for k, v in mounting.data.items() if k.startswith("BAND_")}
    if not groups:
        raise mounting.error("BAND_*", "no detector band group")
    key = f"BAND_{band.upper()}"
    if key not in groups:
        if len(groups) != 1:
            raise mounting.error(key, f"band {band!r} of IMD has no detector mounting; the "
                                      f"GEO section has {sorted(groups)}")
        key = next(iter(groups))
    array = mounting.table(key, required=True).table("DETECTOR_ARRAY", required=True)
    out = {k: array.number(k, from_text=True)
           for k in ("DETORIGINX", "DETORIGINY", "DETROTANGLE", "DETPITCH")}
    if not out["DETPITCH"] > 0:
        raise array.error("DETPITCH", f"must be > 0 mm, got {out['DETPITCH']!r}")
    return out


def _tiles(trees: dict[str, Any], sources: dict[str, Path],
           shape: tuple[int, int]) -> tuple[Tile, ...]:
    tree = trees.get("TIL")
    if not isinstance(tree, Mapping):  # absent, or a placeholder (ASP's samples: "monkey")
        return ()
    til = Fields(str(sources["TIL"]), tree, "TIL.", _error)
    items = til.get("TILE", [])
    if isinstance(items, Mapping):
        items = [items]
    tiles = []
    for i, item in enumerate(items):
        t = Fields(til.source, item, f"TIL.TILE[{i}].", _error)
        name = t.text("FILENAME")
        r0 = t.number("ULROWOFFSET", from_text=True, integer=True, low=0)
        c0 = t.number("ULCOLOFFSET", from_text=True, integer=True, low=0)
        r1 = t.number("LRROWOFFSET", from_text=True, integer=True, low=r0)
        c1 = t.number("LRCOLOFFSET", from_text=True, integer=True, low=c0)
        if r1 >= shape[0] or c1 >= shape[1]:
            raise t.error("LRROWOFFSET/LRCOLOFFSET",
                          f"tile {name} ends at row {r1}, col {c1}: outside the "
                          f"{shape[0]} x {shape[1]} image (IMD NUMROWS/NUMCOLUMNS)")
        tiles.append(Tile(name, (r0, c0), (r1 - r0 + 1, c1 - c0 + 1)))
    if "NUMTILES" in til:
        n = til.number("NUMTILES", from_text=True, integer=True, low=0)
        if n != len(tiles):
            raise til.error("NUMTILES", f"says {n} tiles, the section lists {len(tiles)}")
    return tuple(tiles)
