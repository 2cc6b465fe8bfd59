"""Metadata-field readers whose errors name the file and the field.

Every reader of vendor metadata (DIMAP XML, DigitalGlobe ISD, RPC text, scenario and block
TOML ...) needs the same few things: a required field, a number that must be finite and in a
range, a whole number, a choice among strings, a table whose unknown keys are refused. The two
readers here give them, so that a truncated or absurd file always fails with
``<file>: <field>: <problem>`` and never with a ``KeyError`` or a ``ValueError`` from deep
inside the parser.

* :class:`XmlFields` reads an ElementTree document (:func:`read_xml` parses a file into one);
* :class:`Fields` reads a parsed mapping (TOML, JSON, ``key: value`` text);
* :func:`read_bytes` and :func:`decode_text` give a reader the raw content of a metadata file
  (to sniff its format from the first bytes, or to tokenise a text format into the mapping
  :class:`Fields` reads), so that a reader never opens a file itself.

Both field readers also check sample arrays read field by field (:meth:`XmlFields.bounded`,
:meth:`XmlFields.increasing`), and :class:`XmlFields` parses ISO-8601 UTC times
(:meth:`XmlFields.time`, :func:`parse_utc`).

Both take an ``error`` factory ``error(source, field, problem) -> GeoblockError`` so that a
plugin raises its own :class:`~geoblock.errors.ModelFormatError` subclass; the default is
:class:`~geoblock.errors.MetadataFieldError`.
"""

from __future__ import annotations

import math
import os
import re
import xml.etree.ElementTree as ET
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from geoblock.errors import GeoblockError, GeoblockIOError, MetadataFieldError
from geoblock.io.vsi import as_path, is_vsi
from geoblock.io.vsi import read_bytes as read_vsi_bytes
from geoblock.typing import ArrayLike

__all__ = [
    "ErrorFactory",
    "Fields",
    "XmlFields",
    "decode_text",
    "parse_utc",
    "read_bytes",
    "read_xml",
]

ErrorFactory = Callable[[str, str, str], GeoblockError]
"""``error(source, field, problem)``: the exception a reader raises for a bad field."""

_REQUIRED: Any = object()


def _type_name(value: Any) -> str:
    return {dict: "a table", list: "an array", str: "a string", bool: "a boolean",
            int: "an integer", float: "a number"}.get(type(value), type(value).__name__)


def read_bytes(
    path: str | os.PathLike[str], size: int | None = None, offset: int = 0
) -> bytes:
    """The content of a metadata file: all of it, or at most ``size`` bytes from ``offset``.

    Readers sniff a format from the first bytes (``read_bytes(path, 8192)``), tokenise a text
    format (with :func:`decode_text`) or read the fields of a binary header (a TIFF tag's
    values at their offset) through this function instead of opening the file.

    Parameters
    ----------
    path : str or path-like
        The file: a local path or a GDAL virtual path (``/vsizip/...``, ``/vsicurl/...``,
        :class:`geoblock.io.vsi.VsiPath`), read through GDAL.
    size : int, optional
        Most bytes to read (fewer at the end of the file); default all from ``offset``.
    offset : int
        Where to start, bytes from the beginning of the file.

    Raises
    ------
    GeoblockIOError
        The file cannot be read (missing, a directory, no permission); names the file.
    """
    if is_vsi(path):
        return read_vsi_bytes(path, size, offset)
    path = Path(path)
    try:
        with open(path, "rb") as fh:
            if offset:
                fh.seek(offset)
            return fh.read() if size is None else fh.read(size)
    except (OSError, ValueError, OverflowError) as exc:  # ValueError: negative offset
        reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else exc
        raise GeoblockIOError(f"{str(path)!r}: cannot read: {reason}") from exc


def decode_text(data: bytes, encodings: Sequence[str] = ("utf-8-sig", "latin-1")) -> str:
    """``data`` decoded with the first of ``encodings`` that can (the default falls back to
    Latin-1, which decodes any byte: vendor text metadata is not always UTF-8); ``""`` when
    none can."""
    for encoding in encodings:
        try:
            return data.decode(encoding)
        except (UnicodeDecodeError, LookupError):
            continue
    return ""


def read_xml(
    path: str | os.PathLike[str],
    error: ErrorFactory = MetadataFieldError,
    *,
    strip_namespaces: bool = False,
) -> XmlFields:
    """Parse an XML metadata file into :class:`XmlFields`.

    Parameters
    ----------
    path : str or path-like
        The XML file.
    error : callable, optional
        ``error(source, field, problem)``: the exception of the reader (also for a document
        that is not well-formed, with the field ``"XML"``).
    strip_namespaces : bool
        Drop the ``{namespace}`` of every tag, so that paths need no prefixes.

    Raises
    ------
    GeoblockIOError
        The file cannot be read.
    GeoblockError
        From ``error(path, "XML", ...)`` when the file is not well-formed XML (truncated?) or
        declares an unknown encoding.
    """
    path = as_path(path)
    data = read_bytes(path)
    try:
        root = ET.fromstring(data)
    except ET.ParseError as exc:
        raise error(str(path), "XML", f"not well-formed ({exc}; truncated file?)") from None
    except (LookupError, ValueError) as exc:  # LookupError: an unknown declared encoding
        raise error(str(path), "XML", f"not well-formed ({exc})") from None
    if strip_namespaces:
        for elem in root.iter():
            if isinstance(elem.tag, str):
                elem.tag = elem.tag.rsplit("}", 1)[-1]
    return XmlFields(str(path), root, error)


#: the digits of a fraction of a second after the sixth (microseconds)
_BELOW_MICROSECOND = re.compile(r"\.\d{6}(\d+)")


def parse_utc(
    text: str,
    error: Callable[[str, str], GeoblockError],
    field: str,
    *,
    years: tuple[int, int] | None = None,
    unit: str = "us",
) -> np.datetime64:
    """An ISO-8601 UTC time (``2005-03-13T05:21:07.332158``, optional trailing ``Z``).

    Parameters
    ----------
    text : str
        The time.
    error : callable
        ``error(field, problem)`` giving the exception (:meth:`XmlFields.error`).
    field : str
        The field named in errors.
    years : (int, int), optional
        Accepted years (inclusive): anything else is refused as implausible.
    unit : {"us", "ns"}
        ``"us"``: a ``datetime64[us]`` (the digits below the microsecond are dropped);
        ``"ns"``: a ``datetime64[ns]`` keeping up to three more digits. The text is parsed in
        microseconds either way, which do not overflow (nanoseconds wrap silently outside
        1678-2262).

    Raises
    ------
    GeoblockError
        From ``error``: not an ISO-8601 time, or a year outside ``years``.
    """
    if unit not in ("us", "ns"):
        raise ValueError(f"parse_utc: unit must be 'us' or 'ns', got {unit!r}")
    try:
        value = np.datetime64(text.strip().rstrip("Z"), "us")
    except (ValueError, OverflowError):
        raise error(field, f"{text!r} is not an ISO-8601 time") from None
    if np.isnat(value):
        raise error(field, f"{text!r} is not an ISO-8601 time")
    if years is not None:
        year = int(value.astype("datetime64[Y]").astype(int)) + 1970
        if not years[0] <= year <= years[1]:
            raise error(field, f"{text!r} is not a plausible acquisition time (years "
                               f"{years[0]}-{years[1]})")
    if unit == "us":
        return value
    out = value.astype("datetime64[ns]")
    below_us = _BELOW_MICROSECOND.search(text)
    if below_us:
        out += np.timedelta64(int(below_us.group(1)[:3].ljust(3, "0")), "ns")
    return out


class _SampleChecks:
    """Checks of sample arrays read field by field (shared by the two field readers)."""

    def error(self, field: str, problem: str) -> GeoblockError:
        raise NotImplementedError

    def bounded(self, values: ArrayLike, limit: float, field: str, what: str) -> None:
        """Refuse ``|values| >= limit`` (or NaN) in the 1-D ``values``, naming the first sample.

        Parameters
        ----------
        values : array_like, (n,)
            Samples of ``field`` (e.g. the yaw angles of an attitude table).
        limit : float
            The bound on ``|value|`` (exclusive).
        field : str
            The field named in the error.
        what : str
            What the values are, with their unit (``"angle (rad)"``).
        """
        v = np.asarray(values, dtype=np.float64).ravel()
        bad = np.flatnonzero(~(np.abs(v) < limit))
        if bad.size:
            i = int(bad[0])
            raise self.error(field, f"{what} {float(v[i])!r} (sample {i + 1}) is not "
                                    f"plausible: |{what}| must be < {limit:g}")

    def increasing(self, values: ArrayLike, field: str, what: str = "values") -> None:
        """Refuse 1-D ``values`` (sample times ...) that are not strictly increasing, naming
        the first sample that is not after its predecessor."""
        v = np.asarray(values, dtype=np.float64).ravel()
        if v.size > 1 and not np.all(np.diff(v) > 0):
            i = int(np.flatnonzero(~(np.diff(v) > 0))[0])
            raise self.error(field, f"{what} are not strictly increasing (sample {i + 2} of "
                                    f"{v.size} is not after sample {i + 1})")


class XmlFields(_SampleChecks):
    """Field access to an XML document, with errors naming the source and the element.

    ``where`` arguments are ElementTree paths below ``base`` (default: the root); ``label`` is
    prefixed to ``where`` in error messages when ``base`` is an inner element, so that the
    message names the element's full path (``where="."``, the element's own text, names
    ``label`` without its trailing ``/``).

    Parameters
    ----------
    source : str
        The file (or a label) errors name.
    root : xml.etree.ElementTree.Element
        The document's root element.
    error : callable, optional
        ``error(source, field, problem)`` giving the exception to raise.
    """

    def __init__(
        self, source: str, root: ET.Element, error: ErrorFactory = MetadataFieldError
    ) -> None:
        self.source = str(source)
        self.root = root
        self._error = error

    def error(self, field: str, problem: str) -> GeoblockError:
        """The exception for ``field`` (an element path) and ``problem``."""
        return self._error(self.source, field, problem)

    @staticmethod
    def field(where: str, label: str = "") -> str:
        """The name errors give the element at ``where`` below ``label``."""
        return label.rstrip("/") if where == "." and label else label + where

    def find(self, where: str, base: ET.Element | None = None) -> ET.Element | None:
        """The element at ``where``, or None."""
        return (self.root if base is None else base).find(where)

    def node(self, where: str, base: ET.Element | None = None, label: str = "") -> ET.Element:
        """The element at ``where``; missing is an error."""
        found = self.find(where, base)
        if found is None:
            raise self.error(self.field(where, label), "missing (truncated metadata?)")
        return found

    def nodes(
        self, where: str, base: ET.Element | None = None, label: str = "", minimum: int = 0
    ) -> list[ET.Element]:
        """All elements at ``where``; fewer than ``minimum`` is an error."""
        found = (self.root if base is None else base).findall(where)
        if len(found) < minimum:
            raise self.error(self.field(where, label), f"{len(found)} element(s), at least "
                                                       f"{minimum} needed (truncated metadata?)")
        return found

    def text(self, where: str, base: ET.Element | None = None, label: str = "") -> str:
        """The stripped text at ``where``; missing or empty is an error."""
        found = self.node(where, base, label)
        if found.text is None or not found.text.strip():
            raise self.error(self.field(where, label), "empty (truncated metadata?)")
        return found.text.strip()

    def optional_text(self, where: str, base: ET.Element | None = None) -> str | None:
        """The stripped text at ``where``, or None when missing or empty."""
        found = self.find(where, base)
        if found is None or found.text is None or not found.text.strip():
            return None
        return found.text.strip()

    def number(
        self,
        where: str,
        base: ET.Element | None = None,
        label: str = "",
        *,
        low: float | None = None,
        high: float | None = None,
    ) -> float:
        """A finite float at ``where``, optionally within ``[low, high]``."""
        return _check_number(self.text(where, base, label), self.error, self.field(where, label),
                             low, high)

    def integer(
        self,
        where: str,
        base: ET.Element | None = None,
        label: str = "",
        *,
        minimum: int | None = None,
        maximum: float | None = None,
    ) -> int:
        """A whole number at ``where`` (``"12"`` or ``"12.0"``), optionally within bounds."""
        value = self.number(where, base, label)
        return _check_integer(value, self.error, self.field(where, label), minimum, maximum)

    def numbers(
        self, where: str, base: ET.Element | None = None, label: str = "", count: int | None = None
    ) -> np.ndarray:
        """The whitespace-separated finite floats at ``where``, ``(n,)``; ``count`` enforced."""
        text = self.text(where, base, label)
        return _check_numbers(text.split(), self.error, self.field(where, label), count, text)

    def time(
        self,
        where: str,
        base: ET.Element | None = None,
        label: str = "",
        *,
        years: tuple[int, int] | None = None,
        unit: str = "us",
    ) -> np.datetime64:
        """The ISO-8601 UTC time at ``where`` (see :func:`parse_utc` for ``years``, ``unit``)."""
        return parse_utc(self.text(where, base, label), self.error, self.field(where, label),
                         years=years, unit=unit)


class Fields(_SampleChecks):
    """Typed access to a parsed mapping (a TOML/JSON table), errors naming source and key.

    Parameters
    ----------
    source : str
        The file (or a label) errors name.
    data : Mapping
        The table.
    where : str, optional
        The table's own path (``"images[2]."``), prefixed to keys in errors.
    error : callable, optional
        ``error(source, field, problem)`` giving the exception to raise.
    """

    def __init__(
        self,
        source: str,
        data: Mapping[str, Any],
        where: str = "",
        error: ErrorFactory = MetadataFieldError,
    ) -> None:
        self.source = str(source)
        self.data = data
        self.where = where
        self._error = error

    def __contains__(self, key: str) -> bool:
        return key in self.data

    def error(self, key: str, problem: str) -> GeoblockError:
        """The exception for ``key`` of this table and ``problem``."""
        return self._error(self.source, f"{self.where}{key}", problem)

    def get(self, key: str, default: Any = _REQUIRED) -> Any:
        """The raw value of ``key``; missing is an error unless a default is given."""
        if key not in self.data:
            if default is _REQUIRED:
                raise self.error(key, "required key missing")
            return default
        return self.data[key]

    def table(self, key: str, *, required: bool = False) -> Fields:
        """The sub-table ``key`` (empty when absent unless ``required``)."""
        value = self.get(key) if required else self.data.get(key, {})
        if not isinstance(value, Mapping):
            raise self.error(key, f"must be a table, got {_type_name(value)}")
        return Fields(self.source, value, f"{self.where}{key}.", self._error)

    def tables(self, key: str, *, minimum: int = 0) -> list[Fields]:
        """The array of tables ``key`` (``[[key]]`` in TOML), each as :class:`Fields`."""
        value = self.data.get(key, [])
        if not isinstance(value, list) or not all(isinstance(v, Mapping) for v in value):
            raise self.error(key, f"must be an array of tables, got {_type_name(value)}")
        if len(value) < minimum:
            raise self.error(key, f"{len(value)} given, at least {minimum} needed")
        return [
            Fields(self.source, v, f"{self.where}{key}[{i}].", self._error)
            for i, v in enumerate(value)
        ]

    def known(self, allowed: Sequence[str]) -> None:
        """Refuse keys not in ``allowed``, naming the first unknown one and the allowed."""
        for key in self.data:
            if key not in allowed:
                raise self.error(key, f"unknown key; allowed: {', '.join(allowed)}")

    def number(
        self,
        key: str,
        default: Any = _REQUIRED,
        *,
        integer: bool = False,
        low: float | None = None,
        high: float | None = None,
        strict_low: bool = False,
        from_text: bool = False,
    ) -> Any:
        """A finite number (an ``int`` when ``integer``), optionally bounded.

        ``default`` is returned when the key is absent (it may be None); without one the key
        is required. Booleans are not numbers. With ``from_text``, the value may also be text
        holding a number and optionally a unit (``"+015834.00 pixels"``, as in the
        ``key: value`` text formats); its first word is read.
        """
        if key not in self.data:
            return self.get(key, default)
        value = self.data[key]
        if from_text and isinstance(value, str):
            words = value.split()
            if not words:
                raise self.error(key, "has no value")
            try:
                value = int(words[0]) if integer else float(words[0])
            except ValueError:
                want = "an integer" if integer else "a number"
                raise self.error(key, f"must be {want}, got {value.strip()!r}") from None
        ok_types = (int,) if integer else (int, float)
        if isinstance(value, bool) or not isinstance(value, ok_types):
            want = "an integer" if integer else "a number"
            raise self.error(key, f"must be {want}, got {_type_name(value)} {value!r}")
        try:
            finite = math.isfinite(value)
        except OverflowError:  # an integer beyond float64
            finite = False
        if not finite:
            raise self.error(key, f"must be finite, got {_shown(value)}")
        if low is not None and (value < low or (strict_low and value == low)):
            raise self.error(key, f"must be {'>' if strict_low else '>='} {low}, got {value!r}")
        if high is not None and value > high:
            raise self.error(key, f"must be <= {high}, got {value!r}")
        return int(value) if integer else float(value)

    def text(self, key: str, default: Any = _REQUIRED) -> Any:
        """A string with something besides white space in it, stripped."""
        value = self.string(key, default)
        if key in self.data and not value.strip():
            raise self.error(key, "has no value")
        return value.strip() if key in self.data else value

    def string(
        self, key: str, default: Any = _REQUIRED, *, choices: Sequence[str] | None = None
    ) -> Any:
        """A string, optionally one of ``choices``."""
        if key not in self.data:
            return self.get(key, default)
        value = self.data[key]
        if not isinstance(value, str):
            raise self.error(key, f"must be a string, got {_type_name(value)} {value!r}")
        if choices is not None and value not in choices:
            raise self.error(key, f"must be one of {', '.join(choices)}; got {value!r}")
        return value

    def boolean(self, key: str, default: Any = _REQUIRED) -> Any:
        """``true`` or ``false``."""
        if key not in self.data:
            return self.get(key, default)
        value = self.data[key]
        if not isinstance(value, bool):
            raise self.error(key, f"must be true or false, got {value!r}")
        return value

    def pair(self, key: str, default: Any = _REQUIRED, *, integer: bool = False) -> Any:
        """A ``[low, high]`` pair with ``high >= low``; a single integer ``n`` means
        ``[n, n]`` when ``integer``."""
        if key not in self.data:
            return self.get(key, default)
        value = self.data[key]
        if integer and isinstance(value, int) and not isinstance(value, bool):
            value = [value, value]
        if not (isinstance(value, list) and len(value) == 2):
            what = "a count or [low, high]" if integer else "[low, high]"
            raise self.error(key, f"must be {what}, got {value!r}")
        low = 0 if integer else None
        lo = Fields(self.source, {key: value[0]}, self.where, self._error).number(
            key, integer=integer, low=low
        )
        hi = Fields(self.source, {key: value[1]}, self.where, self._error).number(
            key, integer=integer, low=low
        )
        if hi < lo:
            raise self.error(key, f"high must be >= low, got {value!r}")
        return lo, hi

    def numbers(self, key: str, default: Any = _REQUIRED, *, count: int | None = None) -> Any:
        """An array of finite numbers (or a whitespace-separated string of them), ``(n,)``."""
        if key not in self.data:
            return self.get(key, default)
        value = self.data[key]
        items = value.split() if isinstance(value, str) else value
        if not isinstance(items, list | tuple) or any(
                isinstance(v, bool) or not isinstance(v, int | float | str) for v in items):
            raise self.error(key, f"must be an array of numbers, got {_type_name(value)} "
                                  f"{_shown(value)}")
        return _check_numbers(items, self.error, key, count, value)


def _shown(value: Any, limit: int = 80) -> str:
    """``repr(value)`` cut to ``limit`` characters for a message."""
    text = repr(value)
    return text if len(text) <= limit else text[:limit - 3] + "..."


def _check_number(
    text: str, error: Callable[[str, str], GeoblockError], field: str,
    low: float | None, high: float | None,
) -> float:
    try:
        value = float(text)
    except ValueError:
        raise error(field, f"{text!r} is not a number") from None
    if not math.isfinite(value):
        raise error(field, f"{text!r} is not finite")
    if (low is not None and value < low) or (high is not None and value > high):
        raise error(field, f"{value!r} is outside [{low}, {high}]")
    return value


def _check_integer(
    value: float, error: Callable[[str, str], GeoblockError], field: str,
    minimum: int | None, maximum: float | None,
) -> int:
    if value != int(value):
        raise error(field, f"{value!r} is not a whole number")
    if (minimum is not None and value < minimum) or (maximum is not None and value > maximum):
        raise error(field, f"{int(value)} is outside [{minimum}, {maximum}]")
    return int(value)


def _check_numbers(
    items: Sequence[Any], error: Callable[[str, str], GeoblockError], field: str,
    count: int | None, shown: Any,
) -> np.ndarray:
    try:
        values = np.array([float(v) for v in items], dtype=np.float64)
    except (TypeError, ValueError, OverflowError):
        raise error(field, f"not numbers: {_shown(shown)}") from None
    if count is not None and values.size != count:
        raise error(field, f"expected {count} numbers, got {values.size}: {_shown(shown)}")
    if not np.all(np.isfinite(values)):
        raise error(field, f"not finite: {_shown(shown)}")
    return values
