"""Opening rasters without rasterio's ``NotGeoreferencedWarning``, safely across threads.

``warnings.catch_warnings`` changes process-wide state and is not thread-safe: two threads
that enter and leave it in an interleaved order can leave a thread without its filter, so a
warning that was meant to be silenced reaches (and, under ``-W error``, breaks) a dask
worker. Every quiet open in geoblock goes through :func:`open_quietly`, which serialises them
on one lock (opens are short; the reads after them are not serialised).
"""

from __future__ import annotations

import threading
import warnings
from typing import Any

__all__ = ["open_quietly"]

_LOCK = threading.RLock()


def open_quietly(name: Any, mode: str = "r", **kwargs: Any) -> Any:
    """``rasterio.open(name, mode, **kwargs)`` with ``NotGeoreferencedWarning`` silenced (raw
    images and outputs being created have no geotransform: expected)."""
    import rasterio

    with _LOCK, warnings.catch_warnings():
        warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
        return rasterio.open(name, mode, **kwargs)
