"""The built-in plugins and the example plugin use geoblock's public API only (issue 13).

A plugin is a separate distribution: whatever it imports from ``geoblock`` is API that core
must keep. So no plugin may import a private core module (``geoblock._array``,
``geoblock.io._atomic``), import an underscore name (``from geoblock.models.base import
_x``) or reach an underscore attribute of something it imported from geoblock
(``coords._nan_where_invalid``, ``geoblock._array.broadcast_float64``). What a plugin needs
gets a public name in core instead. Dunder names (``__version__``) are public.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
#: the sources of every plugin distribution in the repository (tests may use private names)
SOURCES = sorted(
    [*ROOT.glob("plugins/*/src/**/*.py"), *ROOT.glob("docs/examples/**/src/**/*.py")]
)


def _private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def _private_module(module: str) -> bool:
    parts = module.split(".")
    return parts[0] == "geoblock" and any(_private(p) for p in parts[1:])


def private_uses(source: str, filename: str = "<source>") -> list[str]:
    """Every use of a private geoblock module or name in ``source``, as ``"line: what"``."""
    tree = ast.parse(source, filename)
    found = []
    bound: set[str] = set()  # local names bound to something imported from geoblock
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.split(".")[0] != "geoblock":
                    continue
                if _private_module(alias.name):
                    found.append(f"{node.lineno}: import {alias.name}")
                bound.add(alias.asname or alias.name.split(".")[0])
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            if node.module.split(".")[0] != "geoblock":
                continue
            if _private_module(node.module):
                found.append(f"{node.lineno}: from {node.module} import ...")
            for alias in node.names:
                if _private(alias.name):
                    found.append(f"{node.lineno}: from {node.module} import {alias.name}")
                bound.add(alias.asname or alias.name)
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and _private(node.attr):
            base = node.value
            while isinstance(base, ast.Attribute):  # geoblock.models._x, coords.sub._y
                base = base.value
            if isinstance(base, ast.Name) and base.id in bound:
                found.append(f"{node.lineno}: {ast.unparse(node)}")
    return sorted(set(found), key=lambda s: int(s.split(":")[0]))


def test_the_plugin_sources_are_found():
    names = {p.name for p in SOURCES}
    assert {"model.py", "readers.py", "chenlee.py", "dimap.py", "camera.py"} <= names


@pytest.mark.parametrize("path", SOURCES, ids=[str(p.relative_to(ROOT)) for p in SOURCES])
def test_plugins_use_no_private_geoblock_module_or_name(path):
    uses = private_uses(path.read_text(encoding="utf-8"), str(path))
    assert not uses, (f"{path.relative_to(ROOT)} reaches into geoblock's private API: "
                      f"{uses}; give what it needs a public name in core instead")


@pytest.mark.parametrize(("source", "expected"), [
    ("from geoblock._array import broadcast_float64", ["1: from geoblock._array import ..."]),
    ("import geoblock.io._atomic", ["1: import geoblock.io._atomic"]),
    ("import geoblock._array as a", ["1: import geoblock._array"]),
    ("from geoblock.models.base import _nan", ["1: from geoblock.models.base import _nan"]),
    ("from geoblock import coords\nx = coords._nan_where_invalid",
     ["2: coords._nan_where_invalid"]),
    ("import geoblock\nf = geoblock._array.broadcast_float64", ["2: geoblock._array"]),
    ("from geoblock.models.linescan import LookDirections as L\nL._invert",
     ["2: L._invert"]),
    # public API, dunders, the plugin's own private names and other packages' are fine
    ("from geoblock.models import broadcast_float64, warn_status\nimport geoblock\n"
     "v = geoblock.__version__", []),
    ("from geoblock_rpc import _kernels\nfrom numpy import _globals\nimport os\nos._exit", []),
    ("from .reader import _parse\nself._frame = 1", []),
])
def test_the_scan_catches_private_uses(source, expected):
    assert private_uses(source) == expected
