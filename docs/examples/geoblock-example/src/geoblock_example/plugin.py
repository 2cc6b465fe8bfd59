"""The hook implementations geoblock calls (entry point ``example``).

Keep this module cheap to import: geoblock imports it whenever it builds its plugin list
(``geoblock --help`` included), so the model and the reader (numpy, PROJ...) are imported
inside the hooks, when geoblock first calls them.
"""

from __future__ import annotations

import geoblock


@geoblock.hookimpl
def geoblock_register_sensor_models(register):
    """Add ``example-frame`` to the model registry (so ``geoblock.from_dict`` knows it)."""
    from geoblock_example.camera import FrameCamera

    register(FrameCamera)


@geoblock.hookimpl
def geoblock_read_sensor_model(path, model_name):
    """Read ``*.frame`` files; ``None`` for anything else, so other readers get their turn."""
    from geoblock_example.camera import FrameCamera
    from geoblock_example.reader import looks_like_frame_file, read_frame_file

    if model_name is not None and model_name != FrameCamera.name:
        return None
    if not looks_like_frame_file(path):
        return None
    return read_frame_file(path)
