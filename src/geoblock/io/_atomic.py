"""Atomic writes: every file geoblock writes appears complete under its name or not at all."""

from __future__ import annotations

import contextlib
import os
import uuid
from collections.abc import Iterator
from pathlib import Path

from geoblock.errors import GeoblockIOError

__all__ = ["atomic_path"]


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike[str], what: str = "") -> Iterator[Path]:
    """A temporary path beside ``path``, renamed to ``path`` when the block succeeds.

    A reader never sees a half-written file, and a failure (an exception, an interrupt)
    leaves any previous file intact and no temporary behind.

    Parameters
    ----------
    path : str or path-like
        The final name.
    what : str
        What is written, for the error message (``"block file "``).

    Raises
    ------
    GeoblockIOError
        The folder does not exist, or writing or renaming fails (an ``OSError``, which
        rasterio's I/O errors are); the message names the path.
    """
    path = Path(path)
    folder = path.parent
    if not folder.is_dir():
        raise GeoblockIOError(f"cannot write {what}{path}: the directory {folder} does not exist")
    tmp = folder / f".{path.name}.{uuid.uuid4().hex[:12]}.tmp"
    try:
        yield tmp
        os.replace(tmp, path)
    except OSError as exc:
        raise GeoblockIOError(f"cannot write {what}{path}: {exc}") from exc
    finally:
        tmp.unlink(missing_ok=True)
