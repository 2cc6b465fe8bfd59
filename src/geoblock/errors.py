"""Every exception and warning geoblock raises.

Every exception derives from :class:`GeoblockError`; where a builtin category fits it is mixed
in, so ``except GeoblockError`` and ``except ValueError`` both work. Per-point numerical
failure is never an exception: it is NaN in the result, a status code and one warning with
the count (:class:`ConvergenceWarning`, :class:`OutOfBoundsWarning`, ...).
"""

from __future__ import annotations

__all__ = [
    "AdjustmentError",
    "ConvergenceWarning",
    "CropError",
    "DemCoverageError",
    "DemError",
    "DuplicateModelError",
    "EmptyOutputError",
    "EmptyOutputWarning",
    "GeoblockDeprecationWarning",
    "GeoblockError",
    "GeoblockIOError",
    "GeoblockWarning",
    "GridError",
    "MetadataFieldError",
    "ModelFormatError",
    "NoIntersectionWarning",
    "ObservationError",
    "OutOfBoundsWarning",
    "ParameterSetError",
    "PluginError",
    "PluginWarning",
    "SerializationError",
    "ShapeMismatchError",
    "SingularSystemError",
    "TooFewPointsError",
    "UnknownModelError",
    "UnsupportedFormatError",
]


class GeoblockError(Exception):
    """Root of every exception geoblock raises."""


class PluginError(GeoblockError):
    """A plugin is broken or conflicts with another one.

    Attributes
    ----------
    plugin_name : str or None
        The plugin (entry-point name or module) at fault.
    """

    def __init__(self, message: str, plugin_name: str | None = None):
        super().__init__(message)
        self.plugin_name = plugin_name


class DuplicateModelError(PluginError, ValueError):
    """Two plugins register the same sensor-model name."""


class ShapeMismatchError(GeoblockError, ValueError):
    """Coordinate arrays do not broadcast together (the message names them and their shapes)."""


class CropError(GeoblockError, ValueError):
    """An image and a model do not fit: shapes differ with no crop offset, or the crop does not
    lie inside the model's scene (the message gives both shapes and what to pass)."""


class UnknownModelError(GeoblockError, KeyError):
    """A sensor-model name is not registered; the message lists the registered names."""

    def __str__(self) -> str:  # KeyError would repr() the message
        return str(self.args[0]) if self.args else ""


class UnsupportedFormatError(GeoblockError, ValueError):
    """No reader or writer recognised a file; the message names the file and the plugins asked."""


class ModelFormatError(GeoblockError, ValueError):
    """A reader recognised a file but its content is invalid (names the file and field)."""


class MetadataFieldError(ModelFormatError):
    """A metadata field is missing, empty, not a number, out of range or unknown.

    Raised by :mod:`geoblock.io.metadata`'s readers (plugins pass their own subclass).

    Attributes
    ----------
    source : str
        The file (or label) read.
    field : str
        The field at fault (an XML element path or a table key such as ``images[2].seed``).
    problem : str
        What is wrong with it.
    """

    def __init__(self, source: str, field: str, problem: str):
        super().__init__(f"{source}: {field}: {problem}")
        self.source = str(source)
        self.field = field
        self.problem = problem


class SerializationError(GeoblockError, ValueError):
    """A model dictionary cannot be turned into a model (missing field, bad schema_version)."""


class DemError(GeoblockError):
    """A DEM cannot be opened or used."""


class DemCoverageError(DemError, ValueError):
    """Points fall outside the DEM (strict mode only; the default is NaN and a status)."""


class GridError(GeoblockError, ValueError):
    """An output grid is impossible: a non-positive or non-finite resolution, empty or inverted
    bounds, a CRS that cannot be read, a grid larger than allowed or smaller than 2 x 2 pixels,
    or a resolution in degrees above 1 degree. The message names the argument (or command-line
    option) and the size the grid would have had.

    Attributes
    ----------
    parameter : str or None
        The argument at fault (``"resolution"``, ``"bounds"``, ``"crs"``, ``"max_pixels"``).
    """

    def __init__(self, message: str, parameter: str | None = None):
        super().__init__(message)
        self.parameter = parameter


class EmptyOutputError(GeoblockError, RuntimeError):
    """Nothing valid was computed for an output (every pixel is nodata: the DEM does not cover
    the scene, the bounds miss the footprint, ...); the output is not written."""


class AdjustmentError(GeoblockError, RuntimeError):
    """An adjustment cannot be set up or solved."""


class ObservationError(AdjustmentError, ValueError):
    """Observations are invalid (non-finite values, bad sigmas, duplicate ids); names the points."""


class ParameterSetError(AdjustmentError, ValueError):
    """A model cannot give the parameter set asked for (``with_parameter_set``).

    The set's name is not one of the model's ``parameter_sets``, an option is unknown to the
    set, or the set needs an option that was not given (``accuracy_m``); the message names
    the model, the set requested and the sets or options it knows.
    """


class TooFewPointsError(AdjustmentError, ValueError):
    """Fewer observations than the adjustable parameters need; the message states the minimum."""


class SingularSystemError(AdjustmentError):
    """The normal equations are rank deficient.

    Attributes
    ----------
    undetermined : tuple of str
        Names of the parameters that the observations cannot determine.
    """

    def __init__(self, message: str, undetermined: tuple[str, ...] = ()):
        super().__init__(message)
        self.undetermined = tuple(undetermined)


class GeoblockIOError(GeoblockError, OSError):
    """A file cannot be read or written."""


class GeoblockWarning(UserWarning):
    """Root of geoblock's warnings."""


class ConvergenceWarning(GeoblockWarning):
    """Some points did not converge; they are NaN in the result."""


class OutOfBoundsWarning(GeoblockWarning):
    """Some points lie outside the model's validity domain; they are NaN in the result."""


class NoIntersectionWarning(GeoblockWarning):
    """Some lines of sight missed the DEM; they are NaN in the result."""


class EmptyOutputWarning(GeoblockWarning):
    """An output was written although every pixel is nodata (asked for, e.g. ``--allow-empty``)."""


class PluginWarning(GeoblockWarning):
    """A plugin failed to load or to register and was skipped."""


class GeoblockDeprecationWarning(FutureWarning):
    """A deprecated feature was used (visible by default)."""
