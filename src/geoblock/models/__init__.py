"""Sensor models: the protocol, the implementers' base class, parameters, registry, corrections."""

from geoblock.models.base import SensorModelBase
from geoblock.models.corrections import ImageCorrection
from geoblock.models.parameters import ParameterSet
from geoblock.models.protocol import SensorModel
from geoblock.models.registry import ModelRegistry, from_dict, get_registry

__all__ = [
    "ImageCorrection",
    "ModelRegistry",
    "ParameterSet",
    "SensorModel",
    "SensorModelBase",
    "from_dict",
    "get_registry",
]
