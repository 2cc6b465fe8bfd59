"""Fuzzing sensor-metadata readers: the outcome rule every reader must keep.

A plugin's test mutates real metadata files (delete a line, empty a value, put garbage or
another number in, truncate) and reads each mutant through its read hook; the reader must
answer with a model, with ``None`` (not its format), or with a
:class:`~geoblock.errors.GeoblockError` whose message names the file, and never with another
exception. :func:`read_mutant` applies that rule and counts the outcomes; the plugin then
checks the plausibility of the models it got (its own physics).
"""

from __future__ import annotations

import os
import warnings
from collections import Counter
from collections.abc import Callable
from typing import Any

from geoblock.errors import GeoblockError

__all__ = ["read_mutant"]


def read_mutant(read: Callable[[], Any], path: str | os.PathLike[str], what: str,
                counts: Counter[str]) -> Any | None:
    """Read one mutant and classify the outcome.

    Parameters
    ----------
    read : callable
        ``read()`` reads the mutant (e.g. ``lambda: plugin.geoblock_read_sensor_model(path,
        None, {})``); warnings are ignored.
    path : path-like
        The mutant's path, which an error message must contain.
    what : str
        The source file and mutations, named in assertion messages.
    counts : collections.Counter
        Incremented: ``tried`` and one of ``clean errors``, ``not recognised (None)``,
        ``models``.

    Returns
    -------
    The model, or None for a clean error or a file not recognised.

    Raises
    ------
    AssertionError
        Any exception other than a ``GeoblockError``, or a ``GeoblockError`` whose message
        does not name the file.
    """
    counts["tried"] += 1
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            model = read()
    except GeoblockError as exc:
        assert str(path) in str(exc), f"{what}: the message does not name the file: {exc}"
        counts["clean errors"] += 1
        return None
    except Exception as exc:  # noqa: BLE001 - the rule under test
        raise AssertionError(f"{what} raised {type(exc).__name__}: {exc}") from exc
    if model is None:
        counts["not recognised (None)"] += 1
        return None
    counts["models"] += 1
    return model
