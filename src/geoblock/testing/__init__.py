"""The conformance kit for sensor-model authors (like ``xarray.testing``).

* :func:`check_sensor_model` runs every contract check on a model and raises an
  ``AssertionError`` that says what is wrong;
* :class:`SensorModelContract` is a pytest class to subclass with a ``model`` fixture, one test
  per check;
* :mod:`geoblock.testing.synthetic` holds analytic models, :mod:`geoblock.testing.strategies`
  hypothesis strategies.

``SensorModelContract`` and the strategies need the ``testing`` extra (pytest, hypothesis).
"""

from geoblock.testing.checks import check_sensor_model

__all__ = ["SensorModelContract", "check_sensor_model"]


def __getattr__(name: str):
    if name == "SensorModelContract":
        from geoblock.testing.contract import SensorModelContract

        return SensorModelContract
    raise AttributeError(f"module 'geoblock.testing' has no attribute {name!r}")
