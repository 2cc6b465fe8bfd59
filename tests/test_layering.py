"""The import graph of ``src/geoblock``: no cycle, the agreed layering, no plugin imported.

Every ``import`` and ``from ... import`` of every module is read from its source (top level,
inside functions and under ``TYPE_CHECKING`` alike: a deferred import is still a dependency)
and resolved to the module it names:

* ``from geoblock.x import y`` is an edge to ``geoblock.x.y`` when that is a module, else to
  the module that *defines* ``y``: a name a package ``__init__`` re-exports (``from
  geoblock.io import open_model``) resolves to where it comes from (``geoblock.io.models``).
* Package ``__init__`` modules only re-export; they are discounted: they take part in neither
  the cycle check nor the layering check as importers. Importing a package itself
  (``import geoblock.io``) is an edge to its ``__init__``, whose layer is the highest of what
  it re-exports (importing it runs all of them).
* A module-level ``__getattr__`` forwarding names that moved elsewhere (a deprecation alias:
  ``geoblock.adjust.output`` -> ``geoblock.report.adjustment``) is discounted too: its imports
  run only when old code asks for an old name. A package ``__init__`` that imports its names
  on first use (PEP 562: ``geoblock``, ``geoblock.io``, ``geoblock.adjust``...) lists them under
  ``if TYPE_CHECKING:``; they are re-exports like eager ones.

The layers (docs/explanation/design.md, "Layers"): a module may import from its own layer and
below, never above.
"""

from __future__ import annotations

import ast
from functools import cache
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src"
PACKAGE = SRC / "geoblock"

#: Module (or package prefix) -> layer; the longest matching prefix wins.
LAYERS: dict[str, int] = {
    # 0 base: errors, coordinate containers and conventions, array helpers
    "geoblock.errors": 0,
    "geoblock.typing": 0,
    "geoblock.pixels": 0,
    "geoblock._array": 0,
    "geoblock._affine": 0,
    "geoblock._lazy": 0,  # PEP 562 lazy names of the packages
    "geoblock._jit": 0,  # numba kernels compiled on their first call
    "geoblock.coords": 0,
    # 1 file primitives: the lowest part of io, which the lazily-read values use
    "geoblock.io.files": 1,
    "geoblock.io.metadata": 1,
    "geoblock.io._atomic": 1,
    "geoblock.io._progress": 1,
    "geoblock.io.rasters": 1,  # the raster handle cache
    "geoblock.io.vsi": 1,  # GDAL virtual paths (/vsizip/, /vsicurl/...) for metadata files
    "geoblock.io.geotiff": 1,  # the GeoTIFF write options (no imports: shown by --help)
    # 2 values and registry: sensor models, DEM sources, observations, the plugin machinery
    "geoblock.hookspecs": 2,
    "geoblock.plugins": 2,
    "geoblock.models": 2,
    "geoblock.dem": 2,
    "geoblock.adjust.observations": 2,  # GroundPoints/ImagePoints: values io.points builds
    # 3 openers: files -> values
    "geoblock.io.models": 3,
    "geoblock.io.dem": 3,
    "geoblock.io.images": 3,
    "geoblock.io.points": 3,
    "geoblock.models.crop": 3,  # model_for_image opens the image it is given (io.images)
    # 4 engines
    "geoblock.dem.intersect": 4,  # localize
    "geoblock.triangulation": 4,  # triangulate (any models, no DEM)
    "geoblock.ortho.limits": 0,  # the output-grid limits (no imports: shown by --help)
    "geoblock.ortho": 4,
    "geoblock.adjust": 4,
    # 5 compositions of engines and values
    "geoblock.io.blocks": 5,  # a block file -> adjust.Block
    "geoblock.report": 5,
    "geoblock.simulate": 5,
    "geoblock.match": 5,  # tie points: images, models, DEM, localize and the ortho's kernels
    "geoblock.testing": 5,
    "geoblock._default_plugin": 5,  # registers core's models, the collocation one among them
    # 6 end-to-end runs
    "geoblock.workflows": 6,
    # 7 the command line and the curated top-level API
    "geoblock.cli": 7,
    "geoblock": 7,
}

#: Edges allowed against the layering, each with its reason (keep this empty).
EXCEPTIONS: dict[tuple[str, str], str] = {}

#: Cycles known and scheduled for removal, each with its reason (keep this empty).
KNOWN_CYCLES: dict[frozenset[str], str] = {
    frozenset({"geoblock.match.pairs", "geoblock.match.pipeline", "geoblock.match.tasks",
               "geoblock.match.tracks"}):
        "issue 29: the tasks and tracks name MatchImage/MatchOptions (pipeline) for typing "
        "and the pipeline runs them lazily; to be broken by moving those types to a module "
        "of their own",
}


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(SRC).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


MODULES: dict[str, Path] = {_module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}
PACKAGES = {_module_name(p) for p in PACKAGE.rglob("__init__.py")}


@cache
def _tree(module: str) -> ast.Module:
    return ast.parse(MODULES[module].read_text(encoding="utf-8"), str(MODULES[module]))


def _top_level(tree: ast.Module) -> list[ast.stmt]:
    """A module's top-level statements, those of its ``if TYPE_CHECKING:`` blocks included: a
    package whose names are imported on first use (PEP 562 ``__getattr__``) lists them there
    for type checkers."""
    out: list[ast.stmt] = []
    for node in tree.body:
        if isinstance(node, ast.If) and isinstance(node.test, ast.Name) \
                and node.test.id == "TYPE_CHECKING":
            out += node.body
        else:
            out.append(node)
    return out


@cache
def _reexports(package: str) -> dict[str, tuple[str, str]]:
    """``name -> (module, name)`` for the ``from ... import`` lines of a package ``__init__``
    (eager, or lazy: listed under ``if TYPE_CHECKING:`` and imported by ``__getattr__``)."""
    out = {}
    for node in _top_level(_tree(package)):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            for alias in node.names:
                out[alias.asname or alias.name] = (node.module, alias.name)
    return out


def _resolve(module: str, name: str, seen: frozenset[tuple[str, str]] = frozenset()) -> str:
    """The module an import of ``name`` from ``module`` depends on."""
    candidate = f"{module}.{name}"
    if candidate in MODULES:
        return candidate
    if module in PACKAGES and (module, name) not in seen:
        source = _reexports(module).get(name)
        if source is not None and source[0].split(".")[0] == "geoblock":
            return _resolve(*source, seen | {(module, name)})
    return module


def _absolute(module: str, node: ast.ImportFrom) -> str:
    if not node.level:
        return node.module or ""
    base = module.split(".") if module in PACKAGES else module.split(".")[:-1]
    base = base[: len(base) - node.level + 1]
    return ".".join(base + ([node.module] if node.module else []))


def _forwarding(tree: ast.Module) -> set[int]:
    """``id`` of the nodes inside a module-level ``__getattr__`` (deprecation aliases)."""
    return {id(inner) for node in tree.body
            if isinstance(node, ast.FunctionDef) and node.name == "__getattr__"
            for inner in ast.walk(node)}


@cache
def imports(module: str) -> tuple[tuple[str, int], ...]:
    """``(imported name, line)`` of every import in ``module``, plugins included, resolved
    (deprecation aliases discounted)."""
    out = []
    tree = _tree(module)
    skip = _forwarding(tree)
    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        if isinstance(node, ast.Import):
            out += [(alias.name, node.lineno) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            target = _absolute(module, node)
            if target.split(".")[0] == "geoblock":
                out += [(_resolve(target, a.name), node.lineno) for a in node.names]
            else:
                out.append((target, node.lineno))
        elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
              and node.func.attr == "import_module" and node.args
              and isinstance(node.args[0], ast.Constant) and isinstance(node.args[0].value, str)):
            out.append((node.args[0].value, node.lineno))  # importlib.import_module("...")
    return tuple(out)


def _internal(name: str) -> str | None:
    """The geoblock module ``name`` is, or is inside (``geoblock.x.y.attr`` -> ``geoblock.x.y``)."""
    while name and name not in MODULES:
        name = name.rpartition(".")[0]
    return name or None


GRAPH: dict[str, set[str]] = {
    m: {t for t in (_internal(n) for n, _ in imports(m)) if t is not None and t != m}
    for m in MODULES
}


@cache
def layer(module: str) -> int:
    if module in PACKAGES and module != "geoblock" and module not in LAYERS:
        # a package __init__: importing it runs what it re-exports
        inner = [layer(t) for t in GRAPH[module] if t.startswith(module + ".")]
        own = _declared(module)
        return max([own, *inner])
    return _declared(module)


def _declared(module: str) -> int:
    name = module
    while name:
        if name in LAYERS:
            return LAYERS[name]
        name = name.rpartition(".")[0]
    raise AssertionError(f"{module} is in no layer: add it to LAYERS in {__file__}")


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out: list[list[str]] = []
    counter = 0
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = counter
                    counter += 1
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph[child]))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1:
                    out.append(sorted(component))
    return out


# ------------------------------------------------------------------------------------ tests
def test_every_module_has_a_layer():
    for module in MODULES:
        layer(module)


def test_no_import_cycle_between_modules():
    modules = {m for m in MODULES if m not in PACKAGES}
    graph = {m: GRAPH[m] & modules for m in modules}
    cycles = [c for c in _cycles(graph) if frozenset(c) not in KNOWN_CYCLES]
    details = []
    for cycle in cycles:
        members = set(cycle)
        edges = [f"{m} -> {t} (line {line})" for m in cycle for n, line in imports(m)
                 if (t := _internal(n)) in members and t != m]
        details.append("; ".join(dict.fromkeys(edges)))
    assert not cycles, "import cycles:\n" + "\n".join(details)


def test_known_cycles_are_still_cycles():
    """An entry of KNOWN_CYCLES that no longer is a cycle must be removed."""
    modules = {m for m in MODULES if m not in PACKAGES}
    found = {frozenset(c) for c in _cycles({m: GRAPH[m] & modules for m in modules})}
    stale = [sorted(c) for c in KNOWN_CYCLES if c not in found]
    assert not stale, f"remove from KNOWN_CYCLES: {stale}"


def test_modules_import_only_their_layer_and_below():
    wrong = []
    for module in MODULES:
        if module in PACKAGES and module != "geoblock":
            continue  # re-exports only (module docstring)
        for name, line in imports(module):
            target = _internal(name)
            if target is None or target == module or (module, target) in EXCEPTIONS:
                continue
            if layer(target) > layer(module):
                wrong.append(f"{module} (layer {layer(module)}) imports {target} "
                             f"(layer {layer(target)}) at line {line}")
    assert not wrong, "imports against the layering:\n" + "\n".join(wrong)


def test_exceptions_are_still_needed():
    unused = [edge for edge in EXCEPTIONS
              if edge[0] not in MODULES or edge[1] not in GRAPH.get(edge[0], set())]
    assert not unused, f"remove from EXCEPTIONS: {unused}"


def test_core_never_imports_a_plugin():
    """Principle 2: plugins reach core through entry points and hooks, never an import."""
    found = [f"{module}: {name} (line {line})" for module in MODULES
             for name, line in imports(module)
             if name.split(".")[0].startswith("geoblock_")]
    assert not found, "core imports plugins:\n" + "\n".join(found)


@pytest.mark.parametrize(
    ("module", "name", "expected"),
    [
        ("geoblock.io", "open_model", "geoblock.io.models"),  # through the re-export
        ("geoblock", "coords", "geoblock.coords"),  # a submodule
        ("geoblock.adjust", "Block", "geoblock.adjust.problem"),  # a lazy re-export
        ("geoblock.io", "write_ortho", "geoblock.io.images"),
    ],
)
def test_imports_resolve_to_the_defining_module(module, name, expected):
    assert _resolve(module, name) == expected


def test_the_checks_catch_a_cycle_and_an_upward_import():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert _cycles({"a": {"b"}, "b": set()}) == []
    assert layer("geoblock.report.tables") > layer("geoblock.adjust.statistics")
    assert layer("geoblock.io") >= layer("geoblock.io.blocks")  # the package runs io.blocks
    # a deprecation alias forwards without depending
    assert "geoblock.report.adjustment" not in GRAPH["geoblock.adjust.output"]
    assert "geoblock.report.adjustment" in GRAPH["geoblock.cli.adjust"]  # a deferred import
