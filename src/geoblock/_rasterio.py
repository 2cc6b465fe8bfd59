"""Opening rasters without rasterio's ``NotGeoreferencedWarning``, safely across threads.

``warnings.catch_warnings`` changes process-wide state and is not thread-safe: two threads
that enter and leave it in an interleaved order can leave a thread without its filter, so a
warning that was meant to be silenced reaches (and, under ``-W error``, breaks) a dask
worker. Every quiet open in geoblock goes through :func:`open_quietly`, which serialises them
on one lock (opens are short; the reads after them are not serialised).

Repeated window reads of one file (DEM blocks, source-image windows of every ortho or mosaic
chunk) go through :func:`cached_dataset`: one open dataset per file and thread, so that they
pay neither for ``rasterio.open`` nor for the lock.
"""

from __future__ import annotations

import os
import threading
import warnings
from collections import OrderedDict
from typing import Any

__all__ = ["cached_dataset", "open_quietly"]

_LOCK = threading.RLock()


def open_quietly(name: Any, mode: str = "r", **kwargs: Any) -> Any:
    """``rasterio.open(name, mode, **kwargs)`` with ``NotGeoreferencedWarning`` silenced (raw
    images and outputs being created have no geotransform: expected)."""
    import rasterio

    with _LOCK, warnings.catch_warnings():
        warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
        return rasterio.open(name, mode, **kwargs)


# ---------------------------------------------------------------------------- dataset handles
_handles = threading.local()  # per thread: path -> (signature, open rasterio dataset)
#: open datasets kept per thread, least recently used closed beyond (a mosaic of hundreds of
#: orthos on every core must not run out of file descriptors)
MAX_HANDLES_PER_THREAD = 16


def _signature(path: str) -> tuple[int, int, int] | None:
    """What identifies the file's current contents (None for non-local paths)."""
    try:
        st = os.stat(path)
    except OSError:
        return None
    return (st.st_ino, st.st_size, st.st_mtime_ns)


def cached_dataset(path: str) -> Any:
    """An open (read-only) rasterio dataset of ``path``, kept per thread and reopened when the
    file changes, so that repeated window reads do not pay for ``rasterio.open``.

    Opened with :func:`open_quietly`. The handle belongs to the calling thread (GDAL datasets
    are not thread-safe) and to the calling process (a forked child opens its own: shared file
    offsets); the caller must not close it nor keep it beyond its reads (at most
    :data:`MAX_HANDLES_PER_THREAD` are kept: the least recently used is closed).
    """
    cache = getattr(_handles, "datasets", None)
    if cache is None or getattr(_handles, "pid", None) != os.getpid():
        # (a forked child never reads through its parent's handles: shared file offsets)
        cache = _handles.datasets = OrderedDict()
        _handles.pid = os.getpid()
    sig = _signature(path)
    found = cache.get(path)
    if found is not None:
        if found[0] == sig and not found[1].closed:
            cache.move_to_end(path)
            return found[1]
        found[1].close()
        del cache[path]
    ds = open_quietly(path)
    cache[path] = (sig, ds)
    while len(cache) > MAX_HANDLES_PER_THREAD:
        _, (_, old) = cache.popitem(last=False)
        old.close()
    return ds
