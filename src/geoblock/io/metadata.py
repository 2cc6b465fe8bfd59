"""Metadata-field readers whose errors name the file and the field.

Every reader of vendor metadata (DIMAP XML, DigitalGlobe ISD, RPC text, scenario and block
TOML ...) needs the same few things: a required field, a number that must be finite and in a
range, a whole number, a choice among strings, a table whose unknown keys are refused. The two
readers here give them, so that a truncated or absurd file always fails with
``<file>: <field>: <problem>`` and never with a ``KeyError`` or a ``ValueError`` from deep
inside the parser.

* :class:`XmlFields` reads an ElementTree document (:func:`read_xml` parses a file into one);
* :class:`Fields` reads a parsed mapping (TOML, JSON, ``key: value`` text).

Both take an ``error`` factory ``error(source, field, problem) -> GeoblockError`` so that a
plugin raises its own :class:`~geoblock.errors.ModelFormatError` subclass; the default is
:class:`~geoblock.errors.MetadataFieldError`.
"""

from __future__ import annotations

import math
import os
import xml.etree.ElementTree as ET
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from geoblock.errors import GeoblockError, GeoblockIOError, MetadataFieldError

__all__ = ["ErrorFactory", "Fields", "XmlFields", "read_xml"]

ErrorFactory = Callable[[str, str, str], GeoblockError]
"""``error(source, field, problem)``: the exception a reader raises for a bad field."""

_REQUIRED: Any = object()


def _type_name(value: Any) -> str:
    return {dict: "a table", list: "an array", str: "a string", bool: "a boolean",
            int: "an integer", float: "a number"}.get(type(value), type(value).__name__)


def read_xml(
    path: str | os.PathLike[str], error: ErrorFactory = MetadataFieldError
) -> XmlFields:
    """Parse an XML metadata file into :class:`XmlFields`.

    Raises
    ------
    GeoblockIOError
        The file cannot be read.
    GeoblockError
        From ``error(path, "XML", ...)`` when the file is not well-formed XML (truncated?).
    """
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise GeoblockIOError(f"{str(path)!r}: cannot read: {exc.strerror or exc}") from exc
    try:
        root = ET.fromstring(data)
    except ET.ParseError as exc:
        raise error(str(path), "XML", f"not well-formed ({exc}; truncated file?)") from None
    return XmlFields(str(path), root, error)


class XmlFields:
    """Field access to an XML document, with errors naming the source and the element.

    ``where`` arguments are ElementTree paths below ``base`` (default: the root); ``label`` is
    prefixed to ``where`` in error messages when ``base`` is an inner element, so that the
    message names the element's full path.

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

    def find(self, where: str, base: ET.Element | None = None) -> ET.Element | None:
        """The element at ``where``, or None."""
        return (self.root if base is None else base).find(where)

    def node(self, where: str, base: ET.Element | None = None, label: str = "") -> ET.Element:
        """The element at ``where``; missing is an error."""
        found = self.find(where, base)
        if found is None:
            raise self.error(label + where, "missing (truncated metadata?)")
        return found

    def nodes(
        self, where: str, base: ET.Element | None = None, label: str = "", minimum: int = 0
    ) -> list[ET.Element]:
        """All elements at ``where``; fewer than ``minimum`` is an error."""
        found = (self.root if base is None else base).findall(where)
        if len(found) < minimum:
            raise self.error(label + where, f"{len(found)} element(s), at least {minimum} "
                                            "needed (truncated metadata?)")
        return found

    def text(self, where: str, base: ET.Element | None = None, label: str = "") -> str:
        """The stripped text at ``where``; missing or empty is an error."""
        found = self.node(where, base, label)
        if found.text is None or not found.text.strip():
            raise self.error(label + where, "empty (truncated metadata?)")
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
        return _check_number(self.text(where, base, label), self.error, label + where, low, high)

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
        return _check_integer(value, self.error, label + where, minimum, maximum)

    def numbers(
        self, where: str, base: ET.Element | None = None, label: str = "", count: int | None = None
    ) -> np.ndarray:
        """The whitespace-separated finite floats at ``where``, ``(n,)``; ``count`` enforced."""
        text = self.text(where, base, label)
        return _check_numbers(text.split(), self.error, label + where, count, text)


class Fields:
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
    ) -> Any:
        """A finite number (an ``int`` when ``integer``), optionally bounded.

        ``default`` is returned when the key is absent (it may be None); without one the key
        is required. Booleans are not numbers.
        """
        if key not in self.data:
            return self.get(key, default)
        value = self.data[key]
        ok_types = (int,) if integer else (int, float)
        if isinstance(value, bool) or not isinstance(value, ok_types):
            want = "an integer" if integer else "a number"
            raise self.error(key, f"must be {want}, got {_type_name(value)} {value!r}")
        if not math.isfinite(value):
            raise self.error(key, f"must be finite, got {value!r}")
        if low is not None and (value < low or (strict_low and value == low)):
            raise self.error(key, f"must be {'>' if strict_low else '>='} {low}, got {value!r}")
        if high is not None and value > high:
            raise self.error(key, f"must be <= {high}, got {value!r}")
        return int(value) if integer else float(value)

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
        if not isinstance(items, list | tuple) or any(isinstance(v, bool) for v in items):
            raise self.error(key, f"must be an array of numbers, got {_type_name(value)}")
        return _check_numbers(items, self.error, key, count, value)


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
    except (TypeError, ValueError):
        raise error(field, f"not numbers: {shown!r}") from None
    if count is not None and values.size != count:
        raise error(field, f"expected {count} numbers, got {values.size}: {shown!r}")
    if not np.all(np.isfinite(values)):
        raise error(field, f"not finite: {shown!r}")
    return values
