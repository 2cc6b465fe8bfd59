"""Every exception and warning geoblock raises.

Every exception derives from :class:`GeoblockError`; where a builtin category fits it is mixed
in, so ``except GeoblockError`` and ``except ValueError`` both work. Per-point numerical
failure is never an exception: it is NaN in the result, a status code and one warning with
the count (:class:`ConvergenceWarning`, :class:`OutOfBoundsWarning`, ...).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from pathlib import Path

__all__ = [
    "AdjustmentError",
    "BlockFileError",
    "ConvergenceWarning",
    "CoordinateError",
    "CropError",
    "ModelImageMismatchError",
    "DemCoverageError",
    "DemDatumError",
    "DemSettingError",
    "GeoidNotFoundError",
    "DemError",
    "DemoOutdirError",
    "DuplicateModelError",
    "EmptyOutputError",
    "EmptyOutputWarning",
    "GeoblockDeprecationWarning",
    "GeoblockError",
    "GeoblockIOError",
    "OutputDirectoryError",
    "GeoblockWarning",
    "GridError",
    "InputFileError",
    "InputTypeError",
    "MatchError",
    "MetadataFieldError",
    "ModelFormatError",
    "MosaicError",
    "NoIntersectionWarning",
    "ObservationError",
    "OutOfBoundsWarning",
    "ParameterSetError",
    "PluginError",
    "PluginWarning",
    "PointFileError",
    "ResolutionWarning",
    "ScenarioError",
    "SerializationError",
    "ShapeMismatchError",
    "OutputExistsError",
    "OutputIsInputError",
    "OutputPathError",
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


class CoordinateError(GeoblockError, ValueError):
    """A coordinate frame or a set of points is unusable: a non-finite origin, a latitude
    beyond +-90 degrees, no finite point to centre a frame on, a latitude outside UTM's range
    (the message names the argument and its value)."""


class CropError(GeoblockError, ValueError):
    """An image and a model do not fit: shapes differ with no crop offset, or the crop does not
    lie inside the model's scene (the message gives both shapes and what to pass)."""


class ModelImageMismatchError(GeoblockError, ValueError):
    """The model describes another image than the raster it is used with: both carry an id of
    the same kind and the ids differ (the message names both ids, both files and how to
    override)."""


class UnknownModelError(GeoblockError, KeyError):
    """A sensor-model name is not registered; the message lists the registered names."""

    def __str__(self) -> str:  # KeyError would repr() the message
        return str(self.args[0]) if self.args else ""


class UnsupportedFormatError(GeoblockError, ValueError):
    """No reader or writer recognised a file; the message names the file and the plugins asked."""


class InputFileError(GeoblockError, ValueError):
    """A file given as input is readable but its content is invalid.

    The message names the file and the field (or line and column). The subclasses say which
    kind of file: :class:`ModelFormatError` (sensor-model metadata), :class:`PointFileError`,
    :class:`BlockFileError`. A file that cannot be read at all is a :class:`GeoblockIOError`.
    """


class ModelFormatError(InputFileError):
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


class PointFileError(InputFileError):
    """A point file (CSV) is malformed (names the file, line and column).

    Raised by :func:`geoblock.io.read_points` and :func:`geoblock.io.points.read_observations`.
    """


class BlockFileError(InputFileError):
    """A block file (TOML) is malformed or names something unusable (names the file and the
    field); raised by :func:`geoblock.io.read_block` and :func:`geoblock.io.open_block`."""


class SerializationError(GeoblockError, ValueError):
    """A model dictionary cannot be turned into a model (missing field, bad schema_version)."""


class DemError(GeoblockError):
    """A DEM cannot be opened or used."""


class DemSettingError(DemError, ValueError):
    """A DEM needs a setting the caller did not give; the message ends with how to give it, in
    the spelling of the caller's front end (:meth:`with_hint`: the command line's options, a
    block file's ``[dem]`` keys, the Python API's arguments).

    Attributes
    ----------
    path : str
        The DEM file ('' when the error is not about one file).
    reason : str
        What is wrong, without the hint.
    hint : str
        How to put it right.
    """

    def __init__(self, path: str, reason: str, hint: str) -> None:
        super().__init__(f"{f'DEM {path}: ' if path else ''}{reason}; {hint}")
        self.path = path
        self.reason = reason
        self.hint = hint

    def with_hint(self, hint: str) -> DemSettingError:
        """The same error with another front end's hint."""
        return type(self)(self.path, self.reason, hint)


class DemDatumError(DemSettingError):
    """A DEM's vertical datum is not stated (or is one geoblock does not convert) and the
    caller did not state it (``--dem-vertical``, ``[dem] vertical``, ``vertical=``)."""


class GeoidNotFoundError(DemSettingError):
    """The geoid grid that geoid heights need is not found (``--geoid``, ``[dem] geoid``,
    ``geoid=``, ``GEOBLOCK_GEOID``, or ``apt-get install proj-data``)."""


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


class InputTypeError(GeoblockError, TypeError):
    """An engine or ``open_*`` function was given an object it cannot use.

    The message says what was received (its type) and what is accepted, e.g. for a DEM: a
    path, a ``DemSource``, an open rasterio dataset, a georeferenced ``xarray.DataArray``, or
    a numpy array with its ``transform`` and ``crs``.
    """


class MatchError(GeoblockError, ValueError):
    """Images cannot be matched (``geoblock match``): they do not overlap on the DEM, an image
    has no keypoints where the others see it, no consistent match survives the tests, or an
    option is invalid; the message names the image file(s)."""


class MosaicError(GeoblockError, ValueError):
    """Sources that cannot be mosaicked without resampling (CRS, resolution, pixel phase,
    bands) or invalid mosaic arguments."""


class ScenarioError(GeoblockError, ValueError):
    """A simulation scenario (a TOML file, a preset name or variant, or a scenario mapping) is
    invalid; the message names the file (or preset) and the key, e.g.
    ``my.toml: points.gcp: must be an integer, got a number 2.5``."""


class DemoOutdirError(GeoblockError):
    """The output directory of ``geoblock demo`` exists and is not a previous demo output (or
    is not a directory); raised before anything is written.

    Attributes
    ----------
    path : pathlib.Path
        The directory refused.
    """

    def __init__(self, message: str, path: Path) -> None:
        super().__init__(message)
        self.path = path


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


class OutputDirectoryError(GeoblockIOError):
    """An output directory holds files geoblock did not write there: it is not replaced (the
    message names the directory and one foreign entry). Choose another directory, or empty
    it yourself."""


class OutputPathError(GeoblockIOError, ValueError):
    """An output cannot be written where it was asked for: its directory is missing, read-only
    or not writable, or it is a directory where a file is expected. Raised before any work
    (:func:`geoblock.io.outputs.check_outputs`); the message names the user's path."""


class OutputExistsError(OutputPathError):
    """An output exists and replacing it was not asked for (``--overwrite``): nothing is
    written, and the existing file is left as it was."""


class OutputIsInputError(OutputPathError):
    """An output is also an input of the same command, or two outputs are one file: refused
    whatever ``--overwrite`` says (the message names both)."""


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


class ResolutionWarning(GeoblockWarning):
    """An output resolution far finer than the image's ground sample distance (likely a typo:
    ``--res 0.02`` for ``0.2``); the message names both."""


class PluginWarning(GeoblockWarning):
    """A plugin failed to load or to register and was skipped."""


class GeoblockDeprecationWarning(FutureWarning):
    """A deprecated feature was used (visible by default)."""
