"""Named parameter sets: ``parameter_sets`` / ``with_parameter_set`` on the protocol, the base
class, the linescan model (``"linescan"``, ``"dg"``), the simulator's on-board models and the
conformance kit's ``check_parameter_sets``."""

from __future__ import annotations

import json
from typing import ClassVar

import numpy as np
import pytest

from geoblock.errors import AdjustmentError, ModelFormatError, ParameterSetError
from geoblock.models import SensorModel
from geoblock.models.linescan import (
    DG_ADJUSTABLE,
    PARAMETER_NAMES,
    LinescanModel,
    dg_parameters,
)
from geoblock.models.parameters import ParameterSet
from geoblock.simulate.sensors import QUICKBIRD_SMALL, simulate_sensor
from geoblock.testing.checks import check_parameter_sets
from geoblock.testing.synthetic import AffineCamera

ORBITAL = LinescanModel.example()
#: every parameter non-zero (as tests/models/test_linescan.py's CORRECTED)
VALUES = np.linspace(1.0, 2.0, 12) * np.repeat([1.0, 0.1, 1e-5, 1e-6], 3)
CORRECTED = ORBITAL.with_parameters(VALUES)
SUBSET = ORBITAL.replace(parameters=ParameterSet(
    ("dp_along", "roll_rate"), [3.0, 2e-6], ("m", "rad/s"), sigmas=[10.0, 1e-5]))
DG_MASK = np.array([n in DG_ADJUSTABLE for n in PARAMETER_NAMES])


def _grid(model):
    rows, cols = model.shape
    r, c = np.meshgrid([0.0, rows / 2, rows - 1.0], [0.0, cols / 2, cols - 1.0])
    return ORBITAL.backproject(r.ravel(), c.ravel(), 300.0)


# ============================================================================ errors, base
def test_parameter_set_error_is_an_adjustment_and_value_error():
    assert issubclass(ParameterSetError, AdjustmentError)
    assert issubclass(ParameterSetError, ValueError)


def test_base_class_offers_default_only():
    model = AffineCamera.example()
    assert model.parameter_sets == ("default",)
    assert model.with_parameter_set("default") is model
    with pytest.raises(ParameterSetError) as info:
        model.with_parameter_set("dg")
    text = str(info.value)
    assert "AffineCamera" in text and "'dg'" in text and "['default']" in text
    with pytest.raises(ParameterSetError, match=r"\['accuracy_m'\]"):
        model.with_parameter_set("default", accuracy_m=10.0)


def test_protocol_lists_the_parameter_set_members():
    assert "parameter_sets" in dir(SensorModel) and "with_parameter_set" in dir(SensorModel)
    assert isinstance(ORBITAL, SensorModel)


# ============================================================================ linescan
def test_linescan_lists_its_sets():
    assert LinescanModel.parameter_sets == ("default", "linescan", "dg", "physical", "jitter")
    assert ORBITAL.with_parameter_set("default") is ORBITAL


def test_dg_set_has_the_dg_mask_and_finite_sigmas():
    dg = ORBITAL.with_parameter_set("dg", accuracy_m=10.0)
    p = dg.parameters
    assert type(dg) is LinescanModel and dg.shape == ORBITAL.shape
    assert p.names == PARAMETER_NAMES
    np.testing.assert_array_equal(p.adjustable, DG_MASK)
    assert np.all(np.isfinite(p.sigmas)) and np.all(p.values == 0)
    assert p.sigmas[0] == 10.0
    assert p == dg_parameters(ORBITAL, 10.0)
    # scales with the accuracy
    np.testing.assert_allclose(ORBITAL.with_parameter_set("dg", accuracy_m=20.0).parameters.sigmas,
                               2 * p.sigmas, rtol=1e-12)


def test_linescan_set_is_the_twelve_free():
    p = SUBSET.with_parameter_set("linescan").parameters
    assert p.names == PARAMETER_NAMES and np.all(p.adjustable) and np.all(np.isinf(p.sigmas))


@pytest.mark.parametrize("name", ["linescan", "dg"])
@pytest.mark.parametrize("model", [ORBITAL, CORRECTED, SUBSET], ids=["zero", "corrected", "subset"])
def test_presets_keep_the_values_and_the_geometry(model, name):
    """A preset changes which parameters are estimated, never the projection: the current
    values of the twelve parameters are kept (none is dropped)."""
    preset = model.with_parameter_set(name, **({"accuracy_m": 10.0} if name == "dg" else {}))
    full = dict.fromkeys(PARAMETER_NAMES, 0.0) | model.parameters.as_dict()
    assert preset.parameters.as_dict() == full
    g = _grid(model)
    np.testing.assert_array_equal(np.stack(preset.project(g.lon, g.lat, g.h)),
                                  np.stack(model.project(g.lon, g.lat, g.h)))


def test_dg_needs_an_accuracy():
    with pytest.raises(ParameterSetError, match="accuracy_m"):
        ORBITAL.with_parameter_set("dg")
    with pytest.raises(ParameterSetError, match="accuracy_m"):
        ORBITAL.with_parameter_set("dg", accuracy_m=0.0)
    with pytest.raises(ParameterSetError, match="accuracy_m"):
        ORBITAL.with_parameter_set("dg", accuracy_m=None)


def test_dg_uses_the_stored_accuracy_unless_given_one():
    stored = ORBITAL.replace(location_accuracy_m=12.0)
    assert stored.location_accuracy_m == 12.0 and ORBITAL.location_accuracy_m is None
    assert stored.with_parameter_set("dg").parameters == dg_parameters(ORBITAL, 12.0)
    assert stored.with_parameter_set("dg", accuracy_m=5.0).parameters.sigmas[0] == 5.0
    # kept through with_parameters and presets
    assert stored.with_parameters(VALUES).location_accuracy_m == 12.0
    assert stored.with_parameter_set("dg").location_accuracy_m == 12.0


def test_unknown_set_or_option_is_refused_naming_what_is_known():
    with pytest.raises(ParameterSetError) as info:
        ORBITAL.with_parameter_set("mba")
    text = str(info.value)
    assert "LinescanModel" in text and "'mba'" in text
    assert "['default', 'linescan', 'dg', 'physical', 'jitter']" in text
    with pytest.raises(ParameterSetError, match=r"\['sigma'\].*\['accuracy_m'\]"):
        ORBITAL.with_parameter_set("dg", sigma=3.0)
    with pytest.raises(ParameterSetError, match="accuracy_m"):
        ORBITAL.with_parameter_set("linescan", accuracy_m=3.0)


def test_location_accuracy_is_serialised_only_when_known():
    assert "location_accuracy_m" not in ORBITAL.to_dict()
    stored = CORRECTED.replace(location_accuracy_m=7.5).with_parameter_set("dg")
    data = json.loads(json.dumps(stored.to_dict()))
    assert data["location_accuracy_m"] == 7.5
    again = LinescanModel.from_dict(data)
    assert again == stored and again.location_accuracy_m == 7.5
    assert again.parameters == stored.parameters
    # JSON written before the field existed still reads
    del data["location_accuracy_m"]
    assert LinescanModel.from_dict(data).location_accuracy_m is None


def test_location_accuracy_must_be_positive():
    for bad in (0.0, -1.0, float("nan"), "ten"):
        with pytest.raises(ModelFormatError, match="location_accuracy_m"):
            ORBITAL.replace(location_accuracy_m=bad)


# ============================================================================ simulator
def test_simulated_onboard_model_takes_dg_without_options():
    sim = simulate_sensor(QUICKBIRD_SMALL)
    onboard = sim.onboard_model
    assert onboard.location_accuracy_m == QUICKBIRD_SMALL.onboard_rmse_m
    dg = onboard.with_parameter_set("dg")
    np.testing.assert_array_equal(dg.parameters.adjustable, DG_MASK)
    assert np.all(np.isfinite(dg.parameters.sigmas))
    assert dg.parameters.sigmas[0] == QUICKBIRD_SMALL.onboard_rmse_m
    assert check_parameter_sets(onboard) == {}
    # the true model has no stated accuracy
    assert sim.true_model.location_accuracy_m is None
    with pytest.raises(ParameterSetError, match="accuracy_m"):
        sim.true_model.with_parameter_set("dg")


# ============================================================================ conformance kit
@pytest.mark.parametrize("model", [ORBITAL, CORRECTED, SUBSET], ids=["zero", "corrected", "subset"])
def test_kit_checks_every_linescan_set(model):
    options = {"dg": {"accuracy_m": 10.0}, "physical": {"accuracy_m": 10.0},
               "jitter": {"accuracy_m": 10.0}}
    assert check_parameter_sets(model, parameter_set_options=options) == {}
    skipped = check_parameter_sets(model)
    assert list(skipped) == ["dg", "physical", "jitter"]
    assert all("accuracy_m" in reason for reason in skipped.values())


class _Lenient(AffineCamera):
    """Accepts any set name and option (returns itself)."""

    name: ClassVar[str] = "broken-lenient-sets"

    def with_parameter_set(self, name, **options):
        return self


class _Unbuildable(AffineCamera):
    """Lists a set it cannot build."""

    name: ClassVar[str] = "broken-unbuildable-set"
    parameter_sets: ClassVar[tuple[str, ...]] = ("default", "fancy")

    def with_parameter_set(self, name, **options):
        if name == "fancy":
            raise KeyError("fancy")
        return super().with_parameter_set(name, **options)


class _NoDefault(AffineCamera):
    name: ClassVar[str] = "broken-no-default-set"
    parameter_sets: ClassVar[tuple[str, ...]] = ("fancy",)


class _LossyPreset(AffineCamera):
    """A preset whose sigmas to_dict() does not record."""

    name: ClassVar[str] = "broken-lossy-preset"
    parameter_sets: ClassVar[tuple[str, ...]] = ("default", "tight")

    def __init__(self, *args, tight=False, **kwargs):
        super().__init__(*args, **kwargs)
        self._tight = tight

    @property
    def parameters(self):
        p = super().parameters
        return p.with_sigmas(np.ones(len(p))) if self._tight else p

    def with_parameter_set(self, name, **options):
        if name == "tight":
            self._parameter_set_request(name, options)
            base = AffineCamera.example()
            return type(self)(base.shape, base._origin, base.coefficients, base.height_range,
                              tight=True)
        return super().with_parameter_set(name, **options)


def _broken(cls):
    base = AffineCamera.example()
    return cls(base.shape, base._origin, base.coefficients, base.height_range)


@pytest.mark.parametrize("cls, message", [
    (_Lenient, "does not raise"),
    (_Unbuildable, "raised KeyError"),
    (_NoDefault, "'default' among them"),
    (_LossyPreset, "does not give the preset back"),
])
def test_kit_catches_broken_parameter_sets(cls, message):
    with pytest.raises(AssertionError, match=message):
        check_parameter_sets(_broken(cls))
