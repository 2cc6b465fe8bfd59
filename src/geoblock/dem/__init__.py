"""The DEM service: terrain heights above the WGS84 ellipsoid, whatever the file's datum."""

from geoblock.dem.array import ArrayDem
from geoblock.dem.base import DemBase
from geoblock.dem.cache import BLOCK_CACHE
from geoblock.dem.constant import ConstantDem
from geoblock.dem.filled import FilledDem
from geoblock.dem.geoid import ConstantGeoidDem, Geoid, find_geoid
from geoblock.dem.grid import GridDem
from geoblock.dem.intersect import as_dem_source, coverage_gap, localize
from geoblock.dem.mosaic import MosaicDem
from geoblock.dem.protocol import DemSource
from geoblock.dem.raster import RasterDem
from geoblock.dem.sampling import INTERPOLATIONS

__all__ = [
    "BLOCK_CACHE",
    "INTERPOLATIONS",
    "ArrayDem",
    "ConstantDem",
    "ConstantGeoidDem",
    "DemBase",
    "DemSource",
    "FilledDem",
    "Geoid",
    "GridDem",
    "MosaicDem",
    "RasterDem",
    "as_dem_source",
    "coverage_gap",
    "find_geoid",
    "localize",
]
