"""The linescan model's parameter names and its parameter presets ``"dg"`` and
``"physical"`` (:meth:`LinescanModel.with_parameter_set`); the ``"jitter"`` set is in
:mod:`geoblock.models.linescan.jitter`."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from geoblock import coords
from geoblock.errors import ParameterSetError
from geoblock.models.parameters import ParameterSet, location_accuracy

if TYPE_CHECKING:
    from geoblock.models.linescan._protocol import Linescan as LinescanModel

__all__ = [
    "DG_ADJUSTABLE",
    "OPTIONAL_PARAMETER_NAMES",
    "PARAMETER_NAMES",
    "PARAMETER_UNITS",
    "PHYSICAL_ADJUSTABLE",
    "dg_parameters",
    "physical_parameters",
]

#: Names of the model's parameters, in order (see :class:`LinescanModel`).
PARAMETER_NAMES: tuple[str, ...] = (
    "dp_along", "dp_across", "dp_radial",
    "dp_along_rate", "dp_across_rate", "dp_radial_rate",
    "roll_bias", "pitch_bias", "yaw_bias",
    "roll_rate", "pitch_rate", "yaw_rate",
)
#: Units of :data:`PARAMETER_NAMES`.
PARAMETER_UNITS: tuple[str, ...] = ("m",) * 3 + ("m/s",) * 3 + ("rad",) * 3 + ("rad/s",) * 3
#: Parameters a model holds only when its set names them: ``focal_scale``, the relative
#: change of the principal distance (look tangents divided by ``1 + focal_scale``; unit 1).
OPTIONAL_PARAMETER_NAMES: tuple[str, ...] = ("focal_scale",)
ALL_NAMES = PARAMETER_NAMES + OPTIONAL_PARAMETER_NAMES
ALL_UNITS = PARAMETER_UNITS + ("1",)
#: The parameters the ``"dg"`` set lets an adjustment change (:func:`dg_parameters`): position
#: biases and drifts, attitude biases; the attitude rates stay fixed.
DG_ADJUSTABLE: tuple[str, ...] = (
    "dp_along", "dp_across", "dp_radial",
    "dp_along_rate", "dp_across_rate", "dp_radial_rate",
    "roll_bias", "pitch_bias", "yaw_bias",
)
#: The parameters the ``"physical"`` set lets an adjustment change
#: (:func:`physical_parameters`, in the spirit of Toutin's CCRS model): attitude biases and
#: drifts, along- and across-track position biases and the focal scale.
PHYSICAL_ADJUSTABLE: tuple[str, ...] = (
    "dp_along", "dp_across",
    "roll_bias", "pitch_bias", "yaw_bias",
    "roll_rate", "pitch_rate", "yaw_rate",
    "focal_scale",
)


# ================================================================================= parameter sets
def dg_parameters(model: LinescanModel, accuracy_m: float) -> ParameterSet:
    """Teo et al.'s DG parameter set for a linescan model, sigmas from a location accuracy.

    The direct-georeferencing correction: a first-degree polynomial orbital correction
    ``dP(t)`` (``dp_along/across/radial`` and their ``_rate``) plus the three attitude biases
    (``roll/pitch/yaw_bias``); the attitude rates stay in the set, fixed at 0.
    :meth:`LinescanModel.with_parameter_set` ``("dg")`` gives the model with this set (and its
    current parameter values).

    Parameters
    ----------
    model : LinescanModel
        The model whose geometry scales the sigmas (its parameter values are not used).
    accuracy_m : float
        The product's location accuracy, metres (1 sigma), > 0.

    Returns
    -------
    ParameterSet
        The twelve linescan names, values 0; adjustable: :data:`DG_ADJUSTABLE` (the attitude
        rates are fixed). Sigmas, with ``s = accuracy_m``: position ``s`` (m); position rates
        ``s / (T/2)`` (m/s, ``T`` the image duration: a drift that moves the image ends by
        ``s``); roll/pitch bias ``s / D`` (rad, ``D`` slant range at the image centre); yaw
        bias ``s / L`` (rad, ``L`` the ground distance from the nadir point to the farther end
        of the centre row: a yaw about the satellite's vertical moves ground points by their
        distance from nadir times the angle, up to 400 km for SPOT's off-nadir views);
        attitude rates ``(roll/pitch sigma) / (T/2)`` (informational, not adjustable).

    Raises
    ------
    ParameterSetError
        ``accuracy_m`` is not a number > 0 (a ``ValueError``).
    """
    sigma = location_accuracy(accuracy_m, "dg_parameters: accuracy_m", ParameterSetError)
    half_t, slant, lever, _ = _geometry_scales(model)
    angle = sigma / slant
    sigmas = np.array([sigma] * 3 + [sigma / half_t] * 3
                      + [angle, angle, sigma / lever] + [angle / half_t] * 3)
    adjustable = np.array([n in DG_ADJUSTABLE for n in PARAMETER_NAMES])
    return ParameterSet(PARAMETER_NAMES, np.zeros(12), PARAMETER_UNITS, sigmas, adjustable)


def physical_parameters(model: LinescanModel, accuracy_m: float) -> ParameterSet:
    """A physical parameter set in the spirit of Toutin's CCRS model, sigmas from a location
    accuracy.

    Attitude biases and drifts (roll, pitch, yaw), along- and across-track position biases
    and the focal scale are adjustable (:data:`PHYSICAL_ADJUSTABLE`); the radial position bias
    and the position drifts stay in the set, fixed at 0 (the attitude drifts absorb them over
    a scene's few seconds). :meth:`LinescanModel.with_parameter_set` ``("physical")`` gives
    the model with this set (and its current parameter values).

    Parameters
    ----------
    model : LinescanModel
        The model whose geometry scales the sigmas (its parameter values are not used).
    accuracy_m : float
        The product's location accuracy, metres (1 sigma), > 0.

    Returns
    -------
    ParameterSet
        The twelve linescan names and ``focal_scale``, values 0. Sigmas, with
        ``s = accuracy_m``, as in :func:`dg_parameters` (position ``s``; roll/pitch bias
        ``s / D``; yaw bias ``s / L``; rates ``(bias sigma) / (T/2)``), and focal scale
        ``s / W`` (``W`` the ground distance from the centre of the centre row to its farther
        end: a focal scale moves the swath edges by ``W`` times it).

    Raises
    ------
    ParameterSetError
        ``accuracy_m`` is not a number > 0 (a ``ValueError``).
    """
    sigma = location_accuracy(accuracy_m, "physical_parameters: accuracy_m", ParameterSetError)
    half_t, slant, lever, half_swath = _geometry_scales(model)
    angle = sigma / slant
    sigmas = np.array([sigma] * 3 + [sigma / half_t] * 3
                      + [angle, angle, sigma / lever]
                      + [angle / half_t, angle / half_t, sigma / lever / half_t]
                      + [sigma / half_swath])
    adjustable = np.array([n in PHYSICAL_ADJUSTABLE for n in ALL_NAMES])
    return ParameterSet(ALL_NAMES, np.zeros(13), ALL_UNITS, sigmas, adjustable)


def _geometry_scales(model: LinescanModel) -> tuple[float, float, float, float]:
    """``(T/2, D, L, W)``: half the image duration (s), the slant range at the image centre,
    the ground distance from the nadir point to the farther end of the centre row (yaw's
    lever arm) and from the centre to the farther end of the centre row (metres)."""
    rows, cols = model.shape
    free = model.replace(parameters=ParameterSet(PARAMETER_NAMES, np.zeros(12), PARAMETER_UNITS))
    half_t = 0.5 * rows * model.line_times.period_magnitude_s  # either scan direction
    centre = (0.5 * (rows - 1), 0.5 * (cols - 1))
    g = free.backproject_ecef([centre[0]] * 3, [centre[1], 0.0, cols - 1.0], 0.0)
    ground = np.stack([np.asarray(c) for c in g], axis=-1)  # (3, 3)
    sat, _, _ = free.sensor_state(centre[0])
    slant = float(np.linalg.norm(ground[0] - sat))
    nadir = np.stack(coords.geodetic_to_ecef(*coords.ecef_to_geodetic(*sat)[:2], 0.0), axis=-1)
    lever = float(np.max(np.linalg.norm(ground[1:] - nadir, axis=-1)))
    half_swath = float(np.max(np.linalg.norm(ground[1:] - ground[0], axis=-1)))
    return half_t, slant, lever, half_swath
