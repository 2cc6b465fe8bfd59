"""The orthorectifier: output grids, the (E, N, h) lattice, resampling kernels, dask graphs.

* :class:`OutputGrid` - the output CRS, geotransform and shape (gdalwarp's ``-te/-tr`` grid);
* :func:`source_coordinates` - image coordinates of output pixels (Chen & Lee's indirect
  method on a refined lattice, chunk-independent);
* :func:`resample` / :func:`cast` - nearest, bilinear, bicubic and windowed-sinc kernels;
* :func:`orthorectify` - the lazy ``(band, y, x)`` orthoimage (``geoblock.io.write_ortho``
  writes it); :func:`ortho_job` - the same chunks without dask (``write_ortho`` runs them on
  local threads);
* :func:`accuracy_layer` - the predicted horizontal error of every ortho pixel, metres
  (:mod:`geoblock.ortho.accuracy`); :func:`accuracy_job` - its chunks without dask.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from geoblock._lazy import lazy_names

if TYPE_CHECKING:
    from geoblock.ortho.accuracy import AccuracyJob, accuracy_job, accuracy_layer
    from geoblock.ortho.graph import OrthoJob, ortho_job, orthorectify
    from geoblock.ortho.grid import OutputGrid
    from geoblock.ortho.kernels import KERNEL_RADIUS, KERNELS, cast, resample
    from geoblock.ortho.lattice import LatticeInfo, source_coordinates

# ``mosaic`` is both a submodule and its function: imported here, or a later import of the
# submodule would leave the module under the function's name
from geoblock.ortho.mosaic import mosaic

# the rest is imported on first use (PEP 562): the orthorectifier's numba kernels, dask and
# PROJ are not loaded by a command that only needs ``geoblock.ortho.limits``
_LAZY = {
    "AccuracyJob": "geoblock.ortho.accuracy",
    "accuracy_job": "geoblock.ortho.accuracy",
    "accuracy_layer": "geoblock.ortho.accuracy",
    "orthorectify": "geoblock.ortho.graph",
    "OrthoJob": "geoblock.ortho.graph",
    "ortho_job": "geoblock.ortho.graph",
    "OutputGrid": "geoblock.ortho.grid",
    "KERNEL_RADIUS": "geoblock.ortho.kernels",
    "KERNELS": "geoblock.ortho.kernels",
    "cast": "geoblock.ortho.kernels",
    "resample": "geoblock.ortho.kernels",
    "LatticeInfo": "geoblock.ortho.lattice",
    "source_coordinates": "geoblock.ortho.lattice",
}


__getattr__, __dir__ = lazy_names(__name__, _LAZY)


__all__ = [
    "AccuracyJob",
    "KERNELS",
    "KERNEL_RADIUS",
    "LatticeInfo",
    "OrthoJob",
    "OutputGrid",
    "accuracy_job",
    "accuracy_layer",
    "cast",
    "mosaic",
    "ortho_job",
    "orthorectify",
    "resample",
    "source_coordinates",
]
