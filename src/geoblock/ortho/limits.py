"""The output-grid limits (:meth:`geoblock.ortho.OutputGrid.check`), in a module of their own
so that the command line can show them without importing numpy and PROJ."""

__all__ = ["MAX_DEGREES", "MAX_PIXELS", "MAX_SIDE", "MIN_SIDE"]

#: default largest number of pixels of a checked grid (:meth:`OutputGrid.check`), ~6.9e10
MAX_PIXELS = 2**36
#: largest number of pixels per side (GDAL's raster sizes are C ints)
MAX_SIDE = 2**31 - 1
#: smallest number of pixels per side of a checked grid
MIN_SIDE = 2
#: largest pixel size, degrees, in a geographic CRS
MAX_DEGREES = 1.0
