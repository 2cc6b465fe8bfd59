"""The one place geoblock opens files: sensor models (and, in later modules, DEMs and images)."""

from geoblock.io.dem import open_dem
from geoblock.io.images import ImageSource, open_image, write_ortho
from geoblock.io.models import open_model, write_model
from geoblock.io.points import read_points, write_points

__all__ = [
    "ImageSource",
    "open_dem",
    "open_image",
    "open_model",
    "read_points",
    "write_model",
    "write_ortho",
    "write_points",
]
