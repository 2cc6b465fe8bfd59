"""Writing report outputs (tables, figures) atomically: a temporary file, then a rename."""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import IO

from geoblock.io._atomic import atomic_path


def write_atomic(path: str | os.PathLike, write: Callable[[IO[bytes]], None]) -> Path:
    """Call ``write(file)`` on a temporary file beside ``path``, then rename it to ``path``.

    A reader never sees a half-written file, and a failure leaves any previous file intact.

    Raises
    ------
    GeoblockIOError
        The folder does not exist or the file cannot be written (names the path).
    """
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as f:
            write(f)
        os.chmod(tmp, 0o644)
    return Path(path)
