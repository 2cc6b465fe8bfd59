"""Plain files: text, JSON, CSV, TOML and figures, read with errors naming the file and written
atomically (a temporary beside the target, then a rename: a reader never sees half a file and
a failure leaves any previous file intact).

These are the doors the rest of geoblock uses for files that are not sensor models, DEMs,
images, point files or block files (reports, scenario definitions, demo outputs), and that
plugins use for theirs. :func:`write_error` is the one-line error of a failed write (naming
the user's path, never a temporary; a full disk in plain words) for a writer that stages its
file itself (:func:`staged_files`).
"""

from __future__ import annotations

import csv
import io as _io
import json
import os
import shutil
import tempfile
import tomllib
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any

from geoblock.errors import GeoblockIOError, MetadataFieldError, OutputDirectoryError
from geoblock.io._atomic import atomic_directory as _atomic_directory
from geoblock.io._atomic import atomic_path, write_error

__all__ = [
    "atomic_directory",
    "check_replaceable",
    "make_directory",
    "read_json",
    "read_text",
    "read_toml",
    "remove",
    "save_figure",
    "staged_files",
    "write_bytes",
    "write_csv",
    "write_json",
    "write_error",
    "write_text",
    "write_with",
]


def read_text(path: str | os.PathLike[str], what: str = "") -> str:
    """The UTF-8 text of ``path`` (a BOM is dropped).

    Raises
    ------
    GeoblockIOError
        The file cannot be read or is not UTF-8 (names the file).
    """
    path = Path(path)
    try:
        return path.read_bytes().decode("utf-8-sig")
    except OSError as exc:
        raise GeoblockIOError(f"cannot read {what}{path}: {exc.strerror or exc}") from exc
    except UnicodeDecodeError as exc:
        raise GeoblockIOError(f"cannot read {what}{path}: not UTF-8 text ({exc})") from None


def read_toml(path: str | os.PathLike[str], what: str = "") -> dict[str, Any]:
    """The TOML document at ``path`` as a dict.

    Raises
    ------
    GeoblockIOError
        The file cannot be read.
    MetadataFieldError
        The file is not valid TOML (the message names the file and the parser's line/column).
    """
    text = read_text(path, what)
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise MetadataFieldError(str(path), "TOML", f"not valid TOML: {exc}") from None


def read_json(path: str | os.PathLike[str], what: str = "") -> Any:
    """The JSON document at ``path``.

    Raises
    ------
    GeoblockIOError
        The file cannot be read.
    MetadataFieldError
        The file is not valid JSON (names the file, line and column).
    """
    text = read_text(path, what)
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise MetadataFieldError(str(path), "JSON", f"not valid JSON: {exc}") from None


def write_with(
    path: str | os.PathLike[str], write: Callable[[IO[Any]], object], what: str = "",
    *, encoding: str | None = None,
) -> Path:
    """Call ``write(file)`` on a temporary beside ``path``, then rename it to ``path``.

    ``file`` is binary, or text in ``encoding`` when given (line ends written as they are,
    as ``open(..., newline="")``: what the ``csv`` module needs). The file is made
    world-readable (0644), as a plain ``open`` under the usual umask would.

    Raises
    ------
    GeoblockIOError
        The folder does not exist or the file cannot be written: one line naming ``path``
        (never the temporary); a full disk, a quota, a read-only file system or a missing
        permission in plain words (:func:`geoblock.io._atomic.write_error`). ``path`` is then
        as it was.
    """
    with atomic_path(path, what) as tmp:
        with (open(tmp, "wb") if encoding is None
              else open(tmp, "w", encoding=encoding, newline="")) as f:
            write(f)
        os.chmod(tmp, 0o644)
    return Path(path)


def write_bytes(path: str | os.PathLike[str], data: bytes, what: str = "") -> Path:
    """Write ``data`` to ``path`` atomically."""
    return write_with(path, lambda f: f.write(data), what)


def write_text(path: str | os.PathLike[str], text: str, what: str = "") -> Path:
    """Write ``text`` to ``path`` as UTF-8 (``\\n`` line ends), atomically."""
    return write_bytes(path, text.encode("utf-8"), what)


def write_json(path: str | os.PathLike[str], data: Any, what: str = "", indent: int = 1) -> Path:
    """Write ``data`` as JSON (no NaN or infinity: they are not JSON), with a final newline.

    Raises
    ------
    GeoblockIOError
        ``data`` holds a value JSON cannot represent (names the path), or writing fails.
    """
    try:
        text = json.dumps(data, indent=indent, allow_nan=False)
    except (TypeError, ValueError) as exc:
        raise GeoblockIOError(f"cannot write {what}{path}: not JSON-safe ({exc})") from exc
    return write_text(path, text + "\n", what)


def write_csv(
    path: str | os.PathLike[str],
    rows: Iterable[Mapping[str, Any]] | Sequence[Sequence[Any]],
    header: Sequence[str] | None = None,
    what: str = "",
) -> Path:
    """Write a CSV file (``\\n`` line ends) atomically.

    ``rows`` are mappings (their keys, in order of first appearance, make the header unless
    ``header`` is given) or sequences (then ``header`` is the first line, if given).
    """
    buffer = _io.StringIO()
    items: list[Any] = list(rows)
    if items and isinstance(items[0], Mapping):
        fields = list(header) if header is not None else list(
            dict.fromkeys(k for r in items for k in r)
        )
        writer: Any = csv.DictWriter(buffer, fieldnames=fields, lineterminator="\n")
        writer.writeheader()
        writer.writerows(items)
    else:
        writer = csv.writer(buffer, lineterminator="\n")
        if header is not None:
            writer.writerow(header)
        writer.writerows(items)
    return write_text(path, buffer.getvalue(), what)


def save_figure(figure: Any, path: str | os.PathLike[str], what: str = "", **options: Any) -> Path:
    """Save a matplotlib ``figure`` to ``path`` atomically (``options`` go to ``savefig``;
    the format is taken from the suffix of ``path``)."""
    fmt = options.pop("format", None) or Path(path).suffix.lstrip(".") or "png"
    return write_with(path, lambda f: figure.savefig(f, format=fmt, **options), what)


def make_directory(path: str | os.PathLike[str], what: str = "") -> Path:
    """Create the directory ``path`` and its parents if needed.

    Raises
    ------
    GeoblockIOError
        It exists as a file, or cannot be created (names the path).
    """
    path = Path(path)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise GeoblockIOError(f"cannot create {what}{path}: {exc.strerror or exc}") from exc
    return path


def remove(path: str | os.PathLike[str], what: str = "") -> None:
    """Remove a file, a symbolic link (not its target) or a directory tree; absent is fine.

    Raises
    ------
    GeoblockIOError
        It cannot be removed (names the path).
    """
    path = Path(path)
    try:
        if path.is_symlink() or path.is_file():
            path.unlink()
        elif path.is_dir():
            shutil.rmtree(path)
    except OSError as exc:
        raise GeoblockIOError(f"cannot remove {what}{path}: {exc.strerror or exc}") from exc


@contextmanager
def atomic_directory(
    path: str | os.PathLike[str],
    what: str = "",
    *,
    replaces: Callable[[Path], bool] | None = None,
) -> Iterator[Path]:
    """A temporary directory that takes the place of the directory ``path`` on success.

    On failure ``path`` stays as it was and the temporary is removed. Write into the yielded
    directory with this module's functions.

    An existing ``path`` is replaced as a whole, so it must hold nothing geoblock did not
    write: it is replaced only when it is empty or when ``replaces(entry)`` is true for every
    entry (a :class:`~pathlib.Path`) in it: what a previous output of the same kind holds.
    Anything else is refused before any work, so that a mistyped ``--out .`` never deletes a
    user's files.

    Raises
    ------
    OutputDirectoryError
        ``path`` holds an entry ``replaces`` does not accept (names it), or is not a directory.
    GeoblockIOError
        A rename fails (names the path).
    """
    check_replaceable(path, what, replaces=replaces)
    with _atomic_directory(path, what) as tmp:
        yield tmp


def check_replaceable(
    path: str | os.PathLike[str],
    what: str = "",
    *,
    replaces: Callable[[Path], bool] | None = None,
) -> None:
    """Refuse, before any work, a directory :func:`atomic_directory` would refuse to replace.

    Raises
    ------
    OutputDirectoryError
        ``path`` holds an entry ``replaces`` does not accept (names it), or is not a directory.
    GeoblockIOError
        ``path`` cannot be listed.
    """
    path = Path(path)
    if path.exists() or path.is_symlink():
        if path.is_symlink() or not path.is_dir():
            raise OutputDirectoryError(
                f"cannot write {what}{path}: it exists and is not a directory"
            )
        try:
            entries = sorted(path.iterdir())
        except OSError as exc:
            raise GeoblockIOError(f"cannot write {what}{path}: {exc.strerror or exc}") from exc
        foreign = [e.name for e in entries if replaces is None or not replaces(e)]
        if foreign:
            raise OutputDirectoryError(
                f"cannot write {what}{path}: the directory holds {foreign[0]!r}"
                f"{f' and {len(foreign) - 1} more entries' if len(foreign) > 1 else ''} that "
                f"{'a previous ' + what.strip() if what.strip() else 'geoblock'} does not "
                "write, and writing would replace the directory as a whole; choose another "
                "directory (or empty it yourself)"
            )


@contextmanager
def staged_files(
    paths: Sequence[str | os.PathLike[str]], what: str = ""
) -> Iterator[list[Path]]:
    """Write several files all or nothing.

    Yields one staging path per destination, each in a hidden temporary folder beside its
    destination. When the block succeeds every staged file (and any sidecar a writer put
    beside it, such as a ``.aux.xml``) is moved into place; otherwise none is. The staging
    folders are removed either way. A destination that exists is copied to its staging path
    first, so that writers which update a file in place (GeoTIFF tags) see it.

    Raises
    ------
    GeoblockIOError
        A destination's folder does not exist, or a file cannot be staged or moved (names it).
    """
    finals = [Path(p) for p in paths]
    for final in finals:
        if not final.parent.is_dir():
            raise GeoblockIOError(
                f"cannot write {what}{final}: directory {str(final.parent)!r} does not exist"
            )
    stages: list[Path] = []
    try:
        staged = []
        for k, final in enumerate(finals):
            try:
                stage = Path(tempfile.mkdtemp(prefix=f".geoblock-stage-{k}-", dir=final.parent))
                stages.append(stage)
                if final.exists():
                    shutil.copy2(final, stage / final.name)
            except OSError as exc:
                raise write_error(final, exc, what) from exc
            staged.append(stage / final.name)
        yield staged
        for stage, final in zip(stages, finals, strict=True):
            for item in sorted(stage.iterdir()):  # the file and any sidecar its writer made
                try:
                    os.replace(item, final.parent / item.name)
                except OSError as exc:
                    raise write_error(final.parent / item.name, exc, what) from exc
    finally:
        for stage in stages:
            shutil.rmtree(stage, ignore_errors=True)
