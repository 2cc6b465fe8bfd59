"""What the linescan model's helper modules (:mod:`~geoblock.models.linescan.presets`,
:mod:`~geoblock.models.linescan.jitter`) use of a
:class:`~geoblock.models.linescan.LinescanModel`: a structural type, so that they need not
import the model module that imports them (the layering test refuses import cycles, type
checking ones included)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, ClassVar, Protocol

from geoblock.typing import ArrayLike, Float64Array

if TYPE_CHECKING:
    from geoblock.models.linescan.attitude import Attitude
    from geoblock.models.linescan.line_times import LineTimes
    from geoblock.models.parameters import ParameterSet


class Linescan(Protocol):
    """The members of :class:`~geoblock.models.linescan.LinescanModel` its helpers use."""

    name: ClassVar[str]

    @property
    def shape(self) -> tuple[int, int]: ...

    @property
    def parameters(self) -> ParameterSet: ...

    @property
    def line_times(self) -> LineTimes: ...

    @property
    def attitude(self) -> Attitude: ...

    @property
    def location_accuracy_m(self) -> float | None: ...

    @property
    def jitter(self) -> Any: ...  # a JitterSpline or None (jitter.py imports this module)

    def replace(self, **changes: Any) -> Linescan: ...

    def with_parameter_set(self, name: str, **options: Any) -> Linescan: ...

    def backproject_ecef(self, row: ArrayLike, col: ArrayLike, h: ArrayLike) -> Any: ...

    def sensor_state(self, row: ArrayLike) -> tuple[Float64Array, Float64Array,
                                                    Float64Array]: ...
