"""Output paths checked before any work: never replace what the user did not ask to replace.

Every ``geoblock`` command that writes calls :func:`check_outputs` with its outputs and its
inputs *before* it reads or computes anything, so that a run which cannot write its result
fails in the first second, naming the user's path, and never after minutes of work:

* an output that is also an input (``geoblock mosaic a.tif b.tif a.tif``: the gdalwarp habit
  of putting the output last) is refused, whatever ``overwrite`` says; so are two outputs
  that are one file;
* an existing output file, or a non-empty output directory, is refused unless ``overwrite``
  (``--overwrite`` on the command line): geoblock cannot tell a file it wrote in an earlier
  run from one the user made, so it replaces neither without being asked;
* the output's directory must exist (files) and be writable: a missing directory, a
  read-only file system and a directory the user cannot write into are named in one line.

The files themselves are written atomically (:mod:`geoblock.io._atomic`): a run that fails
later still leaves any previous file intact.

This module is public so that plugin commands follow the same rules (the RPC plugin's
``export-rpc`` and ``fit-rfm``, the papers' ``experiment``).
"""

from __future__ import annotations

import errno
import os
from collections.abc import Iterable, Mapping
from pathlib import Path

from geoblock.errors import OutputExistsError, OutputIsInputError, OutputPathError

__all__ = ["check_outputs", "is_stream", "is_virtual"]


def is_stream(path: str | os.PathLike[str] | None) -> bool:
    """``'-'``: standard output (or input), not a file."""
    return path is not None and os.fspath(path) == "-"


def is_virtual(path: str | os.PathLike[str]) -> bool:
    """A GDAL virtual path (``/vsizip/...``, ``/vsimem/...``, ``/vsis3/...``)."""
    return os.fspath(path).startswith("/vsi")


def _key(path: str | os.PathLike[str]) -> tuple[str, object]:
    """What identifies the file ``path`` names: its device and inode when it exists (hard and
    symbolic links to one file are one file), else its absolute resolved path."""
    text = os.fspath(path)
    if is_virtual(text):
        return ("vsi", text)
    try:
        st = os.stat(text)
        return ("inode", (st.st_dev, st.st_ino))
    except OSError:
        return ("path", str(Path(text).resolve()))


#: a path, several (a repeatable option) or None (not given)
PathOrPaths = str | os.PathLike[str] | Iterable[str | os.PathLike[str]] | None


def _flatten(paths: Mapping[str, PathOrPaths]) -> list[tuple[str, str]]:
    """``{label: path | [paths] | None}`` -> ``[(label, path), ...]`` without ``None``/``-``."""
    out = []
    for label, value in paths.items():
        if value is None:
            continue
        items = [value] if isinstance(value, str | os.PathLike) else list(value)
        for item in items:
            if item is not None and not is_stream(item):
                out.append((label, os.fspath(item)))
    return out


def _directory_problem(folder: Path) -> str | None:
    """Why nothing can be written in ``folder``, or ``None``."""
    if not folder.exists():
        return f"the directory {folder} does not exist"
    if not folder.is_dir():
        return f"{folder} is not a directory"
    try:
        if os.statvfs(folder).f_flag & os.ST_RDONLY:
            return f"the directory {folder} is on a read-only file system"
    except (OSError, AttributeError):  # no statvfs (Windows): the access test decides
        pass
    if not os.access(folder, os.W_OK | os.X_OK):
        return f"the directory {folder} is not writable ({os.strerror(errno.EACCES).lower()})"
    return None


def check_outputs(
    outputs: Mapping[str, PathOrPaths],
    inputs: Mapping[str, PathOrPaths] | None = None,
    *,
    overwrite: bool = False,
    directories: Iterable[str] = (),
    overwrite_hint: str = "pass --overwrite to replace it",
) -> None:
    """Refuse outputs that would destroy an input or an existing file, or cannot be written.

    Call it before any work. ``'-'`` (standard output) and ``None`` (not requested) are
    skipped; GDAL virtual paths are only compared with the inputs.

    Parameters
    ----------
    outputs : mapping of str to path, paths or None
        What the command writes, by the name the user knows it by (``"OUT"``,
        ``"--output"``, ``"--contribution"``).
    inputs : mapping of str to path, paths or None, optional
        What the command reads, by name (``"ORTHO"``, ``"IMAGE"``, ``"--model"``).
    overwrite : bool
        An existing output file, or a non-empty output directory, may be replaced.
    directories : iterable of str
        The names in ``outputs`` that are directories (created if absent, with their
        parents; refused when not empty, unless ``overwrite``).
    overwrite_hint : str
        How the caller's user allows replacing (the command line's ``--overwrite``; the
        Python API's ``overwrite=True``), for the message.

    Raises
    ------
    OutputIsInputError
        An output is also an input, or two outputs are one file (names both).
    OutputExistsError
        An output exists and ``overwrite`` is false (names it and ``overwrite_hint``).
    OutputPathError
        An output cannot be written: its directory is missing, read-only or not writable,
        or the output is a directory where a file is expected (or the reverse).
    """
    folders = set(directories)
    targets = _flatten(outputs)
    sources = _flatten(inputs or {})
    seen: dict[tuple[str, object], str] = {}
    for label, path in targets:
        key = _key(path)
        for in_label, in_path in sources:
            if _key(in_path) == key:
                raise OutputIsInputError(
                    f"{label} {path!r} is also an input ({in_label} {in_path!r}): geoblock "
                    "never writes over its inputs; name another output (note the order: "
                    "the output comes first where a command takes it first, e.g. "
                    "'geoblock mosaic OUT ORTHO...')")
        if key in seen:
            raise OutputIsInputError(f"{label} {path!r} is also written as {seen[key]}: "
                                     "give each output its own name")
        seen[key] = f"{label} {path!r}"
    for label, path in targets:
        if is_virtual(path):
            continue
        target = Path(path)
        if label in folders:
            _check_directory(label, target, overwrite, overwrite_hint)
        else:
            _check_file(label, target, overwrite, overwrite_hint)


def _check_file(label: str, target: Path, overwrite: bool, hint: str) -> None:
    if target.is_dir():
        raise OutputPathError(f"cannot write {label} {str(target)!r}: it is a directory")
    if target.exists() or target.is_symlink():
        if not overwrite:
            raise OutputExistsError(f"{label} {str(target)!r} exists; {hint} (nothing was "
                                    "written)")
    problem = _directory_problem(target.parent if str(target.parent) else Path("."))
    if problem:
        raise OutputPathError(f"cannot write {label} {str(target)!r}: {problem}")


def _check_directory(label: str, target: Path, overwrite: bool, hint: str) -> None:
    if target.exists() or target.is_symlink():
        if not target.is_dir():
            raise OutputPathError(f"cannot write {label} {str(target)!r}: it exists and is "
                                  "not a directory")
        try:
            empty = not any(target.iterdir())
        except OSError as exc:
            raise OutputPathError(f"cannot write {label} {str(target)!r}: "
                                  f"{(exc.strerror or str(exc)).lower()}") from None
        if not empty and not overwrite:
            raise OutputExistsError(f"{label} {str(target)!r} exists and is not empty; {hint} "
                                    "(nothing was written)")
        problem = _directory_problem(target)
    else:
        parent = target.parent
        while not parent.exists() and parent != parent.parent:  # created with its parents
            parent = parent.parent
        problem = _directory_problem(parent)
    if problem:
        raise OutputPathError(f"cannot write {label} {str(target)!r}: {problem}")
