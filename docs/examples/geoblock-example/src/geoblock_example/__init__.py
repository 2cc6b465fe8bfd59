"""geoblock-example: a frame camera sensor model plugin for geoblock.

geoblock finds this package through the entry point ``example = "geoblock_example.plugin"``;
nothing here needs importing by users, but the model class and the reader are public so that
they can be used directly too. They are imported on first use (PEP 562): geoblock imports this
package whenever it lists its plugins (``geoblock --help`` included), so it must stay cheap.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from geoblock_example.camera import FrameCamera
    from geoblock_example.reader import read_frame_file, sample_file

__all__ = ["FrameCamera", "read_frame_file", "sample_file"]
__version__ = "0.1.0"

_LAZY = {"FrameCamera": "geoblock_example.camera", "read_frame_file": "geoblock_example.reader",
         "sample_file": "geoblock_example.reader"}


def __getattr__(name: str) -> Any:
    if name not in _LAZY:
        raise AttributeError(f"module 'geoblock_example' has no attribute {name!r}")
    return getattr(importlib.import_module(_LAZY[name]), name)
