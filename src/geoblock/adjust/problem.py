"""The problem a block adjustment solves: :class:`Block` (models, measurements, ground points,
DEM) and the engine's options and tuning constants (:mod:`geoblock.adjust.block` runs it)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from geoblock.adjust.observations import GroundPoints, ImagePoints
from geoblock.errors import (
    ObservationError,
)
from geoblock.models.protocol import SensorModel

if TYPE_CHECKING:
    from geoblock.dem.protocol import DemSource

__all__ = ["CONTROL_SHIFTS", "DEM_CONTROLS", "MODES", "ROBUST", "TP_PRIORS", "Block"]

MODES = ("block", "single")
"""``block``: all images together with GCPs, TPs and DEM control; ``single``: each image
alone with its own GCPs (no TPs, no DEM), as the papers' single adjustment."""
DEM_CONTROLS = ("observation", "iterate", "none")
"""How the DEM controls TP heights (module docstring)."""
ROBUST = ("none", "huber", "cauchy", "snooping")
"""Robust estimators of the image measurements."""
TP_PRIORS = ("floating", "fixed")
#: How a control source's common error (the ground points' ``sigma_shift_*``) enters:
#: ``consider`` (propagated into the posterior, the sources held fixed) or ``estimate``
#: (three unknowns per source with that prior): :mod:`geoblock.adjust._consider`.
CONTROL_SHIFTS = ("consider", "estimate")
"""Centring of the TPs' weak ground pseudo-observations (:func:`adjust`)."""

#: GCP sigmas below this (metres) are raised to it: a sigma of 0 means "error-free" and
#: would give an infinite weight
MIN_GROUND_SIGMA_M = 1e-3
#: converged also when the cost changes by less than this fraction in an iteration
COST_TOLERANCE = 1e-10
#: converged also when an iteration changes the cost by less than this fraction AND its step,
#: measured in the undamped normal matrix's metric, is below ``tolerance`` (so no unknown
#: moved by more than ``tolerance`` of its posterior sigma): ends the creep of damped steps
#: along a nearly undetermined combination of unknowns
CREEP_COST_TOLERANCE = 1e-8
#: sigma (metres) of the floating TP pseudo-observations after the first iteration: they only
#: keep a point regular where nothing else determines it (parallel rays without a DEM)
FLOATING_TP_SIGMA_M = 1e4
#: sigma (metres) holding a TP's height on the DEM surface in ``dem_control="iterate"``
ITERATE_HOLD_SIGMA_M = 1e-3



# ================================================================================ problem
@dataclass(frozen=True, eq=False)
class Block:
    """A block of images to adjust together.

    Parameters
    ----------
    models : mapping of str to SensorModel
        Image id -> model. Each model's ``parameters`` (values, a-priori sigmas, adjustable
        mask) say what is adjusted: choose them with ``model.with_parameter_set(name)`` or
        wrap the model in :class:`~geoblock.models.ImageCorrection`.
    measurements : ImagePoints
        Image measurements of every kind.
    ground : GroundPoints, optional
        Surveyed GCPs and ICPs.
    dem : DemSource, optional
        Terrain heights above the ellipsoid (:func:`geoblock.open_dem`): elevation control
        of the TPs and the initial TP positions.
    dem_sigma_m : float
        Standard deviation of the DEM's heights, metres (default 5 m).
    sigmas : mapping of str to mapping of str to float, optional
        Per image, a-priori sigmas overriding the model's for named parameters (``inf``: free;
        0: held fixed), in each parameter's unit.

    Raises
    ------
    ObservationError
        A measurement names an image that is not in ``models``, a GCP/ICP measurement has no
        ground point (or the other way round), or the block has no image.
    """

    models: Mapping[str, SensorModel]
    measurements: ImagePoints
    ground: GroundPoints | None = None
    dem: DemSource | None = None
    dem_sigma_m: float = 5.0
    sigmas: Mapping[str, Mapping[str, float]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        models = dict(self.models)
        if not models:
            raise ObservationError("block: no image")
        for image, table in self.sigmas.items():
            if image not in models:
                raise ObservationError(f"block: sigmas given for image {image!r}, which is not "
                                       f"in the block (images: {list(models)})")
            names = models[image].parameters.names
            for name, value in table.items():
                if name not in names:
                    raise ObservationError(
                        f"block: sigmas of image {image!r}: model {models[image].name!r} has no "
                        f"parameter {name!r}; its parameters are {list(names)}")
                if not (isinstance(value, int | float) and value >= 0):
                    raise ObservationError(f"block: sigmas of image {image!r}: {name} must be a "
                                           f"number >= 0 (inf: free), got {value!r}")
        unknown = ~np.isin(self.measurements.image, list(models))
        if unknown.any():
            pairs = sorted({f"{p} in {i!r}" for p, i in zip(
                self.measurements.id[unknown][:5].tolist(),
                self.measurements.image[unknown][:5].tolist(), strict=True)})
            raise ObservationError(
                f"block: measurement(s) of point(s) {', '.join(pairs)} name an image that is "
                f"not in the block (images: {list(models)})")
        if not (isinstance(self.dem_sigma_m, int | float) and self.dem_sigma_m > 0
                and math.isfinite(self.dem_sigma_m)):
            raise ObservationError(f"block: dem_sigma_m must be a finite number > 0, got "
                                   f"{self.dem_sigma_m!r}")
        object.__setattr__(self, "models", models)
        object.__setattr__(self, "measurements", self.measurements.resolve_kinds(self.ground))

    @property
    def image_ids(self) -> tuple[str, ...]:
        return tuple(self.models)
