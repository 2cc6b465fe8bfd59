"""geoblock: geometric processing of optical satellite images.

Sensor models are plugins (``geoblock plugins`` lists them); the engines (DEM service, block
adjustment, orthorectifier) see only the :class:`~geoblock.models.SensorModel` protocol.
"""

from importlib.metadata import PackageNotFoundError, version

from geoblock.dem import localize
from geoblock.errors import GeoblockError, GeoblockWarning
from geoblock.hookspecs import hookimpl
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
from geoblock.typing import EcefCoords, GroundCoords, ImageCoords, LineOfSight, Status

try:
    __version__ = version("geoblock")
except PackageNotFoundError:  # pragma: no cover - running from a source tree
    __version__ = "0+unknown"

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
    "write_model",
    "write_points",
]
