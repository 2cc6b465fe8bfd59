"""The SensorModel protocol: what every engine relies on, and nothing more."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar, Protocol, Self, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from geoblock.models.parameters import ParameterSet
from geoblock.typing import ArrayLike, Float64Array, GroundCoords, ImageCoords

__all__ = ["SensorModel"]


@runtime_checkable
class SensorModel(Protocol):
    """A sensor model: the geometry linking image pixels and ground points.

    Conventions: image ``(row, col)`` pixels with integers at pixel centres; ground
    ``(lon, lat)`` degrees and ``h`` metres above the WGS84 ellipsoid; partials against ECEF
    metres. Coordinates broadcast; failed points are NaN. Models are immutable.
    :class:`geoblock.models.SensorModelBase` implements most of this from a few members.
    """

    name: ClassVar[str]
    """Registry key and the ``"model"`` field of :meth:`to_dict` (lowercase-kebab)."""
    schema_version: ClassVar[int]
    """Version of the :meth:`to_dict` layout."""

    @property
    def shape(self) -> tuple[int, int]:
        """``(rows, cols)``, pixels."""
        ...

    @property
    def height_range(self) -> tuple[float, float]:
        """Valid heights, metres above the ellipsoid."""
        ...

    @property
    def parameters(self) -> ParameterSet:
        """Adjustable parameters (names, units, values, a-priori sigmas, mask, covariance)."""
        ...

    def project(self, lon: ArrayLike, lat: ArrayLike, h: ArrayLike) -> ImageCoords:
        """Ground -> image, (*S,) each."""
        ...

    def backproject(self, row: ArrayLike, col: ArrayLike, h: ArrayLike) -> GroundCoords:
        """Image -> ground at ellipsoidal height ``h``, (*S,) each."""
        ...

    def project_with_status(
        self, lon: ArrayLike, lat: ArrayLike, h: ArrayLike
    ) -> tuple[ImageCoords, NDArray[np.uint8]]:
        """:meth:`project` without warnings, plus the (*S,) :class:`~geoblock.typing.Status`."""
        ...

    def backproject_with_status(
        self, row: ArrayLike, col: ArrayLike, h: ArrayLike
    ) -> tuple[GroundCoords, NDArray[np.uint8]]:
        """:meth:`backproject` without warnings, plus the (*S,) status array."""
        ...

    def partials_ground(self, lon: ArrayLike, lat: ArrayLike, h: ArrayLike) -> Float64Array:
        """(*S, 2, 3) d(row, col)/d(x, y, z) ECEF, pixels per metre."""
        ...

    def partials_parameters(self, lon: ArrayLike, lat: ArrayLike, h: ArrayLike) -> Float64Array:
        """(*S, 2, P) d(row, col)/d(parameter k), pixels per unit of parameter k."""
        ...

    def with_parameters(self, values: ArrayLike) -> Self:
        """A new model with parameter values (P,)."""
        ...

    @property
    def parameter_sets(self) -> tuple[str, ...]:
        """Names of the parameter presets :meth:`with_parameter_set` accepts, ``"default"``
        among them; cheap and free of side effects (a class attribute will do)."""
        ...

    def with_parameter_set(self, name: str, **options: Any) -> Self:
        """A copy whose ``parameters`` are the preset ``name`` (names, values, units, a-priori
        sigmas, adjustable mask): how a block adjustment asks any model for ``"dg"``.

        ``"default"`` is accepted by every model and means the parameters as they are.
        Raises :class:`~geoblock.errors.ParameterSetError` for a name not in
        :attr:`parameter_sets`, an option the set does not know, or a missing option the set
        needs (the message names the model, the set and the known sets or options).
        """
        ...

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe state naming its model."""
        ...

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Self:
        """Inverse of :meth:`to_dict`."""
        ...
