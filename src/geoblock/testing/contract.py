"""``SensorModelContract``: the conformance kit as a pytest class to subclass.

Needs the ``testing`` extra (pytest).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar

import pytest

from geoblock.testing import checks

__all__ = ["SensorModelContract"]


class SensorModelContract:
    """Contract tests every sensor model must pass, one pytest test per check.

    Subclass it in your plugin's tests with a name starting with ``Test`` and give it a
    ``model`` fixture returning the model to check (parametrise the fixture to check several
    configurations). Each ``test_*`` method calls one function of
    :mod:`geoblock.testing.checks`, whose ``AssertionError`` says what is wrong, where, and
    the likely cause.

    Attributes
    ----------
    check_options : mapping
        Keyword arguments of :func:`~geoblock.testing.checks.check_sensor_model` passed on to
        the checks that accept them: ``n`` (grid points per image side), ``seed``,
        ``tolerance_px``, ``partials_rtol``, ``perturbation_rtol``. Loosen them only with a
        reason (a model known to round-trip to 1e-5 px only, say).
    parameter_set_options : mapping
        Options of the model's parameter sets that need some, by set name, for
        ``test_parameter_sets`` (e.g. ``{"dg": {"accuracy_m": 10.0}}``). A set that needs
        options not given here is left out, and the test is skipped saying which sets were
        checked and which were not.

    Examples
    --------
    In ``tests/test_contract.py`` of a plugin::

        import pytest
        from geoblock.testing import SensorModelContract
        from geoblock_mysat import MySatModel

        class TestMySatModel(SensorModelContract):
            check_options = {"n": 4}

            @pytest.fixture(params=["scene_a.xml", "scene_b.xml"])
            def model(self, request, data_dir):
                return MySatModel.read(data_dir / request.param)

    ``pytest`` then runs ``test_round_trip``, ``test_ground_partials``, ... for each scene. A
    test can be switched off with a reason by overriding it::

            @pytest.mark.skip(reason="no dask on this platform")
            def test_dask_token(self, model): ...
    """

    check_options: ClassVar[Mapping[str, Any]] = {}
    parameter_set_options: ClassVar[Mapping[str, Mapping[str, Any]]] = {}

    @pytest.fixture
    def model(self) -> Any:
        """The model under test: override this fixture in the subclass."""
        raise NotImplementedError(
            f"{type(self).__qualname__} must define a `model` fixture returning the sensor "
            "model to check (see the SensorModelContract docstring)"
        )

    def _run(self, check: Any, model: Any) -> None:
        check(model, **checks._options_for(check, self.check_options))

    def test_metadata(self, model: Any) -> None:
        """name, schema_version, shape, height_range and parameters are sane."""
        self._run(checks.check_metadata, model)

    def test_shapes(self, model: Any) -> None:
        """0-d, empty and broadcast inputs; float64 outputs; partials shapes."""
        self._run(checks.check_shapes, model)

    def test_round_trip(self, model: Any) -> None:
        """project and backproject invert each other over the image and height range."""
        self._run(checks.check_round_trip, model)

    def test_footprint(self, model: Any) -> None:
        """Pixel edges, footprint and the pixel-centre convention."""
        self._run(checks.check_footprint, model)

    def test_nan_isolation(self, model: Any) -> None:
        """Non-finite inputs give NaN and INVALID_INPUT at their point only."""
        self._run(checks.check_nan_isolation, model)

    def test_ground_partials(self, model: Any) -> None:
        """partials_ground matches central differences."""
        self._run(checks.check_ground_partials, model)

    def test_parameter_partials(self, model: Any) -> None:
        """partials_parameters matches central differences."""
        self._run(checks.check_parameter_partials, model)

    def test_partials_together(self, model: Any) -> None:
        """partials(), when the model has it, equals the two partials called apart."""
        self._run(checks.check_partials_together, model)

    def test_parameter_perturbation(self, model: Any) -> None:
        """A parameter change moves projections as the partials predict."""
        self._run(checks.check_parameter_perturbation, model)

    def test_with_parameters(self, model: Any) -> None:
        """with_parameters keeps state, sets values and never mutates."""
        self._run(checks.check_with_parameters, model)

    def test_parameter_sets(self, model: Any) -> None:
        """Every named parameter preset builds a working model; unknown names are refused."""
        options = {**self.check_options, "parameter_set_options": self.parameter_set_options}
        skipped = checks.check_parameter_sets(
            model, **checks._options_for(checks.check_parameter_sets, options))
        if skipped:
            checked = [n for n in model.parameter_sets if n not in skipped]
            reasons = "; ".join(f"{n!r}: {why}" for n, why in skipped.items())
            pytest.skip(f"parameter sets checked: {checked}; not checked, as they need options "
                        f"(give them in {type(self).__name__}.parameter_set_options): {reasons}")

    def test_no_mutation(self, model: Any) -> None:
        """No method changes the model or its inputs."""
        self._run(checks.check_no_mutation, model)

    def test_serialization(self, model: Any) -> None:
        """to_dict/from_dict round trips (direct, JSON text, registry)."""
        self._run(checks.check_serialization, model)

    def test_pickle(self, model: Any) -> None:
        """pickle round trip."""
        self._run(checks.check_pickle, model)

    def test_dask_token(self, model: Any) -> None:
        """dask.base.tokenize is deterministic and follows the value."""
        self._run(checks.check_dask_token, model)
