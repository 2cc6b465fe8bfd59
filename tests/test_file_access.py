"""Principle 7: only ``geoblock.io`` opens, reads, writes or removes files.

Every module of ``src/geoblock`` outside ``geoblock/io/`` is parsed and its calls are checked
against the APIs that touch files: the builtin ``open``, ``rasterio.open`` (through any alias),
``os``/``shutil``/``tempfile`` file operations, ``json``/``tomllib``/``pickle``/numpy file
readers and writers, and the methods that only files have (``Path.read_text``, ``.mkdir``,
``.unlink``, ``fig.savefig``, ``DataFrame.to_csv``, ...). Objects that read lazily (a raster
DEM, the geoid grid, a source image) hold a path and read through ``geoblock.io``.

The check is syntactic: it resolves import aliases (``import rasterio as rio``, ``from os
import remove``) but not the types of variables, so a method is recognised by a name that
only file objects have (``.open(`` on anything; ``.rename(``/``.replace(`` only on
``Path(...)``). A module that must keep a file access goes in :data:`ALLOWED` with the
reason.

The low-level ``geoblock.io`` modules must not import the DEM service, the orthorectifier or
the models at import time: those import them (the layering that keeps ``import geoblock``
free of cycles).
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src" / "geoblock"

#: module (dotted) -> why it may touch files outside geoblock.io; keep it empty or tiny
ALLOWED: dict[str, str] = {}

#: qualified functions that touch files
FORBIDDEN_CALLS = frozenset({
    "open", "io.open", "os.open", "os.fdopen",
    "rasterio.open", "rasterio.shutil.copy", "rasterio.shutil.copyfiles",
    "rasterio.shutil.delete",
    "os.remove", "os.unlink", "os.replace", "os.rename", "os.renames", "os.makedirs",
    "os.mkdir", "os.chmod", "os.rmdir", "os.removedirs", "os.link", "os.symlink",
    "os.truncate", "os.utime",
    "tomllib.load", "json.load", "json.dump", "pickle.load", "pickle.dump",
    "numpy.load", "numpy.save", "numpy.savez", "numpy.savez_compressed", "numpy.savetxt",
    "numpy.loadtxt", "numpy.genfromtxt", "numpy.fromfile", "numpy.memmap",
    "xarray.open_dataset", "xarray.open_dataarray", "xarray.open_mfdataset",
    "xarray.load_dataset", "xarray.load_dataarray", "pandas.read_csv",
})
#: modules every function of which touches files (but these)
FORBIDDEN_MODULES = {"shutil": {"which", "get_terminal_size", "disk_usage"}, "tempfile": set()}
#: method names only file objects (paths, figures, data frames, arrays) have
FILE_METHODS = frozenset({
    "open", "read_text", "read_bytes", "write_text", "write_bytes", "mkdir", "unlink",
    "touch", "rmdir", "symlink_to", "hardlink_to", "savefig", "to_csv", "to_netcdf",
    "to_zarr", "to_raster", "tofile",
})
#: methods that touch files when called on a ``Path(...)``
PATH_METHODS = frozenset({"rename", "replace", "chmod", "open"})

#: low-level io modules (imported by dem/, ortho/, models/) and what they must not import
LOW_LEVEL_IO = ("io/_atomic.py", "io/_progress.py", "io/files.py", "io/metadata.py", "io/vsi.py",
                "io/rasters.py")
UPPER_PACKAGES = ("geoblock.dem", "geoblock.ortho", "geoblock.models", "geoblock.adjust",
                  "geoblock.simulate", "geoblock.workflows", "geoblock.report")


def _modules() -> list[Path]:
    return sorted(p for p in SRC.rglob("*.py") if "io" not in p.relative_to(SRC).parts[:1])


def _dotted(path: Path) -> str:
    parts = ("geoblock",) + path.relative_to(SRC).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _aliases(tree: ast.AST) -> dict[str, str]:
    """Local name -> what it stands for (``rio`` -> ``rasterio``, ``np`` -> ``numpy``,
    ``remove`` -> ``os.remove``), from every import of the module (function-level too)."""
    names: dict[str, str] = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.asname:
                    names[alias.asname] = alias.name
                else:
                    top = alias.name.split(".")[0]
                    names[top] = top
        elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
            for alias in node.names:
                names[alias.asname or alias.name] = f"{node.module}.{alias.name}"
    return names


def _qualified(func: ast.expr, aliases: dict[str, str]) -> str | None:
    """``a.b.c`` of a called expression, its first name resolved through ``aliases``."""
    parts = []
    while isinstance(func, ast.Attribute):
        parts.append(func.attr)
        func = func.value
    if not isinstance(func, ast.Name):
        return None
    parts.append(aliases.get(func.id, func.id))
    return ".".join(reversed(parts))


def _is_path_call(node: ast.expr, aliases: dict[str, str]) -> bool:
    return isinstance(node, ast.Call) and _qualified(node.func, aliases) in (
        "pathlib.Path", "Path", "pathlib.PurePath")


def file_accesses(path: Path) -> list[str]:
    """``"line: call"`` of every file-touching call in the module at ``path``."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    aliases = _aliases(tree)
    found = []
    for node in ast.walk(tree):
        if not isinstance(node, ast.Call):
            continue
        name = _qualified(node.func, aliases)
        if name is not None and name.startswith("geoblock.io."):
            continue  # the door itself (``files.write_text`` of ``from geoblock.io import files``)
        bad = False
        if name is not None:
            module, _, function = name.rpartition(".")
            bad = name in FORBIDDEN_CALLS or (
                module in FORBIDDEN_MODULES and function not in FORBIDDEN_MODULES[module])
        if isinstance(node.func, ast.Attribute):
            method = node.func.attr
            bad |= method in FILE_METHODS
            bad |= method in PATH_METHODS and _is_path_call(node.func.value, aliases)
        if bad:
            found.append(f"{node.lineno}: {ast.unparse(node.func)}(...)")
    return found


@pytest.mark.parametrize("path", _modules(), ids=lambda p: _dotted(p))
def test_only_geoblock_io_touches_files(path):
    module = _dotted(path)
    found = file_accesses(path)
    if module in ALLOWED:
        assert found, f"{module} is allowed a file access it no longer has: remove it"
        return
    assert not found, (
        f"{module} touches files outside geoblock.io (principle 7: only geoblock.io opens, "
        f"reads, writes or removes files; read and write through geoblock.io):\n  "
        + "\n  ".join(found))


def test_the_check_sees_file_accesses(tmp_path):
    """The detector itself: each form is caught, lookalikes are not."""
    sample = tmp_path / "sample.py"
    sample.write_text(
        "import json\nimport os\nimport rasterio as rio\nimport numpy as np\n"
        "from pathlib import Path\nfrom shutil import copyfile\nimport tempfile\n"
        "from rasterio import open as ropen\nfrom geoblock.io import files\n"
        "def f(p, fig, df, text):\n"
        "    open(p)\n    rio.open(p)\n    ropen(p)\n    os.remove(p)\n    copyfile(p, p)\n"
        "    json.dump({}, p)\n    np.save(p, 1)\n    tempfile.mkdtemp()\n"
        "    Path(p).read_text()\n    p.mkdir()\n    fig.savefig(p)\n    df.to_csv(p)\n"
        "    Path(p).replace(p)\n"
        "    text.replace('a', 'b')\n    json.dumps({})\n    os.path.exists(p)\n"
        "    np.asarray(p)\n    files.write_text(p, '')\n",
        encoding="utf-8")
    found = file_accesses(sample)
    assert [line.split(":")[0] for line in found] == [str(n) for n in range(11, 24)], found


@pytest.mark.parametrize("name", LOW_LEVEL_IO)
def test_low_level_io_imports_no_engine_at_import_time(name):
    """``geoblock.dem`` reads its files through these modules: they must not import it (nor
    the other packages above ``geoblock.io``) when they are imported."""
    path = SRC / name
    if not path.exists():
        pytest.skip(f"{name} does not exist")
    tree = ast.parse(path.read_text(encoding="utf-8"))
    top_level = []
    for node in tree.body:
        if isinstance(node, ast.If):  # ``if TYPE_CHECKING:`` blocks do not run
            continue
        if isinstance(node, ast.Import):
            top_level += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module:
            top_level.append(node.module)
    bad = [m for m in top_level if m.startswith(UPPER_PACKAGES)]
    assert not bad, f"{name} imports {bad} at import time"
