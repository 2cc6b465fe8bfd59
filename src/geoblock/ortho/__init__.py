"""The orthorectifier: output grids, the (E, N, h) lattice, resampling kernels, dask graphs.

* :class:`OutputGrid` - the output CRS, geotransform and shape (gdalwarp's ``-te/-tr`` grid);
* :func:`source_coordinates` - image coordinates of output pixels (Chen & Lee's indirect
  method on a refined lattice, chunk-independent);
* :func:`resample` / :func:`cast` - nearest, bilinear, bicubic and windowed-sinc kernels;
* :func:`orthorectify` - the lazy ``(band, y, x)`` orthoimage (``geoblock.io.write_ortho``
  writes it).
"""

from geoblock.ortho.graph import orthorectify
from geoblock.ortho.grid import OutputGrid
from geoblock.ortho.kernels import KERNEL_RADIUS, KERNELS, cast, resample
from geoblock.ortho.lattice import LatticeInfo, source_coordinates
from geoblock.ortho.mosaic import mosaic

__all__ = [
    "KERNELS",
    "KERNEL_RADIUS",
    "LatticeInfo",
    "OutputGrid",
    "cast",
    "mosaic",
    "orthorectify",
    "resample",
    "source_coordinates",
]
