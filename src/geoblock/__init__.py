"""geoblock: geometric processing of optical satellite images.

Sensor models are plugins (``geoblock plugins`` lists them); the engines (DEM service, block
adjustment, orthorectifier) see only the :class:`~geoblock.models.SensorModel` protocol.

The public names below are imported on first use (PEP 562): ``import geoblock`` costs only
the errors and the hook marker, so that ``geoblock --help``, plugins' hook modules and
commands that need neither the DEM service nor the orthorectifier start fast.
"""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError, version
from typing import TYPE_CHECKING

from geoblock._lazy import lazy_names
from geoblock.errors import GeoblockError, GeoblockWarning
from geoblock.hookspecs import hookimpl

if TYPE_CHECKING:  # the lazily imported names, for type checkers and IDEs
    from geoblock.dem import localize
    from geoblock.io import open_dem, open_model, read_points, write_model, write_points
    from geoblock.models import (
        ImageCorrection,
        ParameterSet,
        SensorModel,
        SensorModelBase,
        from_dict,
        get_registry,
    )
    from geoblock.ortho import orthorectify
    from geoblock.triangulation import triangulate
    from geoblock.typing import EcefCoords, GroundCoords, ImageCoords, LineOfSight, Status

try:
    __version__ = version("geoblock")
except PackageNotFoundError:  # pragma: no cover - running from a source tree
    __version__ = "0+unknown"

#: public name -> the module it is imported from on first use
_LAZY = {
    "localize": "geoblock.dem",
    "open_dem": "geoblock.io",
    "open_model": "geoblock.io",
    "read_points": "geoblock.io",
    "write_model": "geoblock.io",
    "write_points": "geoblock.io",
    "ImageCorrection": "geoblock.models",
    "ParameterSet": "geoblock.models",
    "SensorModel": "geoblock.models",
    "SensorModelBase": "geoblock.models",
    "from_dict": "geoblock.models",
    "get_registry": "geoblock.models",
    "orthorectify": "geoblock.ortho",
    "triangulate": "geoblock.triangulation",
    "EcefCoords": "geoblock.typing",
    "GroundCoords": "geoblock.typing",
    "ImageCoords": "geoblock.typing",
    "LineOfSight": "geoblock.typing",
    "Status": "geoblock.typing",
}


__getattr__, __dir__ = lazy_names(__name__, _LAZY)


__all__ = [
    "EcefCoords",
    "GeoblockError",
    "GeoblockWarning",
    "GroundCoords",
    "ImageCoords",
    "ImageCorrection",
    "LineOfSight",
    "ParameterSet",
    "SensorModel",
    "SensorModelBase",
    "Status",
    "__version__",
    "from_dict",
    "get_registry",
    "hookimpl",
    "localize",
    "open_dem",
    "open_model",
    "orthorectify",
    "read_points",
    "triangulate",
    "write_model",
    "write_points",
]
