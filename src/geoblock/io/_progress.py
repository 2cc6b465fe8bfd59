"""The progress bar of long writes (``geoblock ortho``, ``geoblock mosaic``): tqdm on a terminal.

:class:`Progress` counts chunks. On a terminal it draws a :mod:`tqdm` bar on standard error;
anywhere else (a pipe, a log file, a batch scheduler, click's test runner) it draws nothing
while running, so no carriage-return frames end up in logs, and writes one summary line when
it is closed (``wrote 12/12 chunks in 3.4 s``).
"""

from __future__ import annotations

import sys
import time
from typing import Any, TextIO

__all__ = ["Progress", "is_terminal"]


def is_terminal(stream: Any) -> bool:
    """Whether ``stream`` is an interactive terminal (False for anything without ``isatty``)."""
    try:
        return bool(stream.isatty())
    except (AttributeError, OSError, ValueError):  # closed or a file-like object
        return False


class Progress:
    """A progress bar over ``total`` units of work, on standard error.

    Parameters
    ----------
    total : int
        Number of units (chunks).
    enabled : bool
        False: nothing is written at all.
    desc : str
        What is being done, shown before the bar and in the summary line.
    unit : str
        Name of one unit.
    file : text stream, optional
        Where to write; default :data:`sys.stderr` at the time of the call.
    """

    def __init__(self, total: int, enabled: bool, *, desc: str = "writing",
                 unit: str = "chunk", file: TextIO | None = None) -> None:
        self.total = max(int(total), 1)
        self.done = 0
        self.enabled = bool(enabled)
        self.desc = desc
        self.unit = unit
        self.file = sys.stderr if file is None else file
        self.start = time.perf_counter()
        self.closed = False
        self._bar: Any = None
        if self.enabled and is_terminal(self.file):
            from tqdm import tqdm

            self._bar = tqdm(total=self.total, desc=desc, unit=unit, file=self.file,
                             leave=True, dynamic_ncols=True, mininterval=0.2)

    @property
    def interactive(self) -> bool:
        """Whether a live bar is drawn (enabled and on a terminal)."""
        return self._bar is not None

    def update(self, n: int = 1) -> None:
        """``n`` more units done."""
        self.done += n
        if self._bar is not None:
            self._bar.update(n)

    def close(self) -> None:
        """End the bar (terminal) or write the summary line (elsewhere); idempotent."""
        if self.closed:
            return
        self.closed = True
        if self._bar is not None:
            self._bar.close()
        elif self.enabled:
            elapsed = time.perf_counter() - self.start
            plural = "" if self.total == 1 else "s"
            self.file.write(f"{self.desc}: {self.done}/{self.total} {self.unit}{plural} in "
                            f"{elapsed:.1f} s\n")
            self.file.flush()

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
