"""Sensor models: the protocol, the implementers' base class, parameters, registry, corrections,
crops."""

from geoblock._array import broadcast_float64, warn_status
from geoblock.models.base import KernelResult, SensorModelBase, image_shape
from geoblock.models.corrections import ImageCorrection
from geoblock.models.crop import CroppedModel, model_for_image
from geoblock.models.curves import CorrectionCurve, HasCorrectionCurves
from geoblock.models.parameters import ParameterSet
from geoblock.models.protocol import SensorModel
from geoblock.models.registry import ModelRegistry
from geoblock.plugins import from_dict, get_registry

__all__ = [
    "CorrectionCurve",
    "CroppedModel",
    "HasCorrectionCurves",
    "ImageCorrection",
    "KernelResult",
    "ModelRegistry",
    "ParameterSet",
    "SensorModel",
    "SensorModelBase",
    "broadcast_float64",
    "from_dict",
    "get_registry",
    "image_shape",
    "model_for_image",
    "warn_status",
]
