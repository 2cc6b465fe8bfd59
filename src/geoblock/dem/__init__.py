"""The DEM service: terrain heights above the WGS84 ellipsoid, whatever the file's datum."""

from geoblock.dem.base import DemBase
from geoblock.dem.constant import ConstantDem
from geoblock.dem.grid import GridDem
from geoblock.dem.protocol import DemSource
from geoblock.dem.sampling import INTERPOLATIONS

__all__ = ["INTERPOLATIONS", "ConstantDem", "DemBase", "DemSource", "GridDem"]
