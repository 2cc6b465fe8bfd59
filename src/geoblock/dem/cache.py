"""The process-wide, thread-safe LRU cache of DEM blocks that every raster DEM reads through.

:class:`~geoblock.dem.raster.RasterDem` (and :class:`~geoblock.dem.array.ArrayDem`) read their
heights in square blocks with a halo (see :mod:`geoblock.dem.raster`); the blocks of every DEM
of the same file and options, hence of every call and every dask task in a worker, share
:data:`BLOCK_CACHE`, 256 MB unless ``GEOBLOCK_DEM_CACHE_MB`` says otherwise.
"""

from __future__ import annotations

import os
import threading
from collections import OrderedDict
from collections.abc import Callable
from typing import Any

import numpy as np

__all__ = ["BLOCK_CACHE", "BlockCache"]

class BlockCache:
    """A thread-safe LRU cache of DEM blocks, bounded in bytes.

    Parameters
    ----------
    max_bytes : int
        Budget; least recently used blocks are dropped beyond it.
    """

    def __init__(self, max_bytes: int) -> None:
        self.max_bytes = int(max_bytes)
        self._data: OrderedDict[Any, np.ndarray] = OrderedDict()
        self._bytes = 0
        self._lock = threading.Lock()
        self.hits = 0
        self.misses = 0

    def get(self, key: Any, load: Callable[[], np.ndarray]) -> np.ndarray:
        """The block under ``key``, loaded by ``load()`` (outside the lock) when missing."""
        with self._lock:
            found = self._data.get(key)
            if found is not None:
                self._data.move_to_end(key)
                self.hits += 1
                return found
            self.misses += 1
        block = load()
        block.flags.writeable = False
        with self._lock:
            if key not in self._data:
                self._data[key] = block
                self._bytes += block.nbytes
                while self._bytes > self.max_bytes and len(self._data) > 1:
                    _, old = self._data.popitem(last=False)
                    self._bytes -= old.nbytes
            return self._data[key]

    def clear(self) -> None:
        """Drop every block and reset the counters."""
        with self._lock:
            self._data.clear()
            self._bytes = 0
            self.hits = self.misses = 0

    @property
    def nbytes(self) -> int:
        """Bytes held."""
        return self._bytes

    def __len__(self) -> int:
        return len(self._data)


BLOCK_CACHE = BlockCache(int(float(os.environ.get("GEOBLOCK_DEM_CACHE_MB", "256")) * 2**20))
"""The process-wide DEM block cache shared by every :class:`RasterDem`."""
