"""A generic state-vector pushbroom (line-scanner) model.

A linear array of detectors images one row per exposure time while the satellite moves along
its orbit. The model holds:

* an :class:`Ephemeris`: time-tagged ECEF positions and velocities, interpolated by cubic
  Hermite polynomials;
* an :class:`Attitude`: time-tagged unit quaternions (sensor -> ECEF or sensor -> orbital
  frame), interpolated by slerp;
* :class:`LookDirections`: one unit look vector per detector (column) in the sensor frame;
* :class:`LineTimes`: the exposure time of each row;

and twelve adjustable parameters, bias and drift of the position (in the orbital frame) and of
the attitude (small rotations about the sensor axes), the physical corrections of Teo et al.'s
direct georeferencing and of Chen & Lee's bundle adjustment.

Parameter sets (:meth:`LinescanModel.with_parameter_set`): ``"default"`` (the parameters as
they are), ``"linescan"`` (the twelve, free), ``"physical"`` (:func:`physical_parameters`:
attitude biases and drifts, along/across-track position biases and the focal scale, in the
spirit of Toutin's CCRS model), ``"dg"`` (:func:`dg_parameters`: Teo et al.'s
direct-georeferencing correction, position biases and drifts and attitude biases with a-priori
sigmas from the product's location accuracy, attitude rates fixed) and ``"jitter"`` (one of
these plus roll, pitch and yaw corrections as cubic B-splines in time, with amplitude and
smoothness priors: :mod:`~geoblock.models.linescan.jitter`).

Frames
------
* ECEF: EPSG:4978, metres.
* Sensor (body) frame: +z the boresight (towards the ground), +x along track (the flight
  direction at zero attitude), +y = z x x.
* Orbital frame (LVLH, :func:`orbital_frame`): ``z_o = -P/|P|``, ``y_o = z_o x V / |.|``,
  ``x_o = y_o x z_o``.

Image -> ground intersects each line of sight with the surface of constant ellipsoidal height;
ground -> image is a bracketed, safeguarded secant search on time for the instant the ground
point lies in the detector plane (Chen & Lee eq. 5), vectorised over the points still active.

The building blocks are public, one module each, for readers of pushbroom products (SPOT,
Pleiades, DigitalGlobe ... and third-party sensors) that assemble a :class:`LinescanModel`
from their metadata:

* :mod:`~geoblock.models.linescan.rotations`: quaternions <-> matrices, :func:`rotation_xyz`,
  :func:`orbital_frame`;
* :mod:`~geoblock.models.linescan.ephemeris`: :class:`Ephemeris` (and its plausibility limits
  ``ORBIT_RADIUS_M``, ``MAX_SPEED_M_S``);
* :mod:`~geoblock.models.linescan.attitude`: :class:`Attitude`;
* :mod:`~geoblock.models.linescan.look`: :class:`LookDirections`;
* :mod:`~geoblock.models.linescan.line_times`: :class:`LineTimes`;
* :mod:`~geoblock.models.linescan.light`: the light-path corrections (velocity aberration,
  light time, atmospheric refraction), :data:`CORRECTIONS`;
* :mod:`~geoblock.models.linescan.model`: :class:`LinescanModel`;
* :mod:`~geoblock.models.linescan.presets`: :data:`PARAMETER_NAMES`, :func:`dg_parameters`,
  :func:`physical_parameters`;
* :mod:`~geoblock.models.linescan.jitter`: the ``"jitter"`` set's correction splines in time,
  :class:`JitterSpline`, :func:`attitude_correction`.

Every name is importable from ``geoblock.models.linescan`` itself.
"""


from geoblock.models.linescan.attitude import Attitude
from geoblock.models.linescan.ephemeris import MAX_SPEED_M_S, ORBIT_RADIUS_M, Ephemeris
from geoblock.models.linescan.jitter import JitterSpline, attitude_correction, position_correction
from geoblock.models.linescan.light import CORRECTIONS
from geoblock.models.linescan.line_times import LineTimes
from geoblock.models.linescan.look import LookDirections
from geoblock.models.linescan.model import LinescanModel
from geoblock.models.linescan.presets import (
    DG_ADJUSTABLE,
    OPTIONAL_PARAMETER_NAMES,
    PARAMETER_NAMES,
    PARAMETER_UNITS,
    PHYSICAL_ADJUSTABLE,
    dg_parameters,
    physical_parameters,
)
from geoblock.models.linescan.rotations import (
    matrix_to_quaternion,
    orbital_frame,
    quaternion_to_matrix,
    rotation_xyz,
)

__all__ = [
    "CORRECTIONS",
    "DG_ADJUSTABLE",
    "MAX_SPEED_M_S",
    "OPTIONAL_PARAMETER_NAMES",
    "ORBIT_RADIUS_M",
    "PARAMETER_NAMES",
    "PARAMETER_UNITS",
    "PHYSICAL_ADJUSTABLE",
    "Attitude",
    "Ephemeris",
    "JitterSpline",
    "LineTimes",
    "LinescanModel",
    "LookDirections",
    "attitude_correction",
    "dg_parameters",
    "matrix_to_quaternion",
    "physical_parameters",
    "position_correction",
    "orbital_frame",
    "quaternion_to_matrix",
    "rotation_xyz",
]
