"""The one place geoblock opens files: sensor models (and, in later modules, DEMs and images)."""

from geoblock.io.dem import open_dem
from geoblock.io.models import open_model, write_model
from geoblock.io.points import read_points, write_points

__all__ = ["open_dem", "open_model", "read_points", "write_model", "write_points"]
