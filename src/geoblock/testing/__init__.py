"""The conformance kit for sensor-model authors (like ``xarray.testing``).

* :func:`check_sensor_model` runs every contract check on a model and raises an
  ``AssertionError`` that says what is wrong, where, and the likely cause; each check is also
  its own function (``check_round_trip``, ``check_partials``, ...);
* :class:`SensorModelContract` is a pytest class to subclass with a ``model`` fixture, one test
  per check;
* :mod:`geoblock.testing.synthetic` holds analytic models, :mod:`geoblock.testing.strategies`
  hypothesis strategies;
* the synthetic models are test models, not registered for users: :func:`enable_synthetic_models`
  registers them in this process (their JSON then opens with :func:`geoblock.open_model`), and
  ``GEOBLOCK_PLUGIN_MODULES=geoblock.testing.plugin`` in a subprocess's environment
  (:mod:`geoblock.testing.plugin`).

``SensorModelContract`` and the strategies need the ``testing`` extra (pytest, hypothesis).
"""

from typing import Any

from geoblock.testing.checks import (
    CHECKS,
    check_dask_token,
    check_footprint,
    check_ground_partials,
    check_metadata,
    check_nan_isolation,
    check_no_mutation,
    check_parameter_partials,
    check_parameter_perturbation,
    check_partials,
    check_pickle,
    check_round_trip,
    check_sensor_model,
    check_serialization,
    check_shapes,
    check_with_parameters,
)
from geoblock.testing.plugin import disable_synthetic_models, enable_synthetic_models

__all__ = [
    "CHECKS",
    "SensorModelContract",
    "check_dask_token",
    "check_footprint",
    "check_ground_partials",
    "check_metadata",
    "check_nan_isolation",
    "check_no_mutation",
    "check_parameter_partials",
    "check_parameter_perturbation",
    "check_partials",
    "check_pickle",
    "check_round_trip",
    "check_sensor_model",
    "check_serialization",
    "check_shapes",
    "check_with_parameters",
    "disable_synthetic_models",
    "enable_synthetic_models",
]


def __getattr__(name: str) -> Any:
    if name == "SensorModelContract":
        from geoblock.testing.contract import SensorModelContract

        return SensorModelContract
    raise AttributeError(f"module 'geoblock.testing' has no attribute {name!r}")
