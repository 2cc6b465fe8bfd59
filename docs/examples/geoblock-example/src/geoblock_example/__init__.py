"""geoblock-example: a frame camera sensor model plugin for geoblock.

geoblock finds this package through the entry point ``example = "geoblock_example.plugin"``;
nothing here needs importing by users, but the model class and the reader are public so that
they can be used directly too.
"""

from geoblock_example.camera import FrameCamera
from geoblock_example.reader import read_frame_file, sample_file

__all__ = ["FrameCamera", "read_frame_file", "sample_file"]
__version__ = "0.1.0"
