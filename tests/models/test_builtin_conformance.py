"""Every registered sensor model passes the conformance kit (geoblock.testing.contract).

The models are taken from the registry (built-ins and every installed plugin): each
registered name is checked on the factories of ``EXAMPLES``, else on its class's ``example()``
classmethod; a registered model with neither fails ``test_every_registered_model_has_an_example``,
so a newly registered model cannot skip the kit.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from geoblock.models import ImageCorrection, get_registry
from geoblock.testing.contract import SensorModelContract
from geoblock.testing.synthetic import AffineCamera, ConstantVelocityPushbroom

_N_TERMS = {0: 1, 1: 3, 2: 6}
_A = [0.3, 0.8, -0.5, 0.2, -0.1, 0.05]
_B = [-0.2, 0.4, 0.6, -0.15, 0.1, 0.07]


def _corrections() -> dict[str, Callable[[], object]]:
    bases = {
        "affine": AffineCamera.example,
        "pushbroom": lambda: ConstantVelocityPushbroom.example(roll=0.01),
    }
    out: dict[str, Callable[[], object]] = {}
    for base_id, base in bases.items():
        for order, n in _N_TERMS.items():
            values = np.array(_A[:n] + _B[:n])
            # order 1 also exercises finite a-priori sigmas (numeric steps of 1e-3 sigma)
            sigmas = 2.0 if order == 1 else None

            def build(base=base, order=order, values=values, sigmas=sigmas):
                return ImageCorrection(base(), order, values=values, sigmas=sigmas)

            out[f"order{order}-{base_id}"] = build
    return out


#: registry name -> {case id: factory}. Every registered model needs at least one example.
EXAMPLES: dict[str, dict[str, Callable[[], object]]] = {
    "synthetic-affine": {"example": AffineCamera.example},
    "synthetic-pushbroom": {"roll0.01": lambda: ConstantVelocityPushbroom.example(roll=0.01)},
    "image-correction": _corrections(),
}


def _examples_of(name: str) -> dict[str, Callable[[], object]]:
    """EXAMPLES[name], else the registered class's own ``example()`` classmethod, if any."""
    if EXAMPLES.get(name):
        return EXAMPLES[name]
    factory = getattr(get_registry().get(name), "example", None)
    return {"example": factory} if callable(factory) else {}


def _cases() -> list:
    return [
        pytest.param(factory, id=f"{name}-{case}")
        for name in get_registry().names()
        for case, factory in _examples_of(name).items()
    ]


def test_every_registered_model_has_an_example() -> None:
    missing = [name for name in get_registry().names() if not _examples_of(name)]
    assert not missing, (
        f"registered sensor models without a conformance example: {missing}; add factories to "
        "EXAMPLES in tests/models/test_builtin_conformance.py or give the class an `example()` "
        "classmethod"
    )


def test_examples_are_of_the_registered_class() -> None:
    registry = get_registry()
    for name in registry.names():
        for case, factory in _examples_of(name).items():
            assert type(factory()) is registry.get(name), (name, case)


class TestBuiltinModels(SensorModelContract):
    """The contract over every registered model's examples."""

    parameter_set_options = {"dg": {"accuracy_m": 10.0}, "physical": {"accuracy_m": 10.0},
                             "mba": {"accuracy_m": 50.0}, "jitter": {"accuracy_m": 10.0}}

    @pytest.fixture(params=_cases())
    def model(self, request):
        return request.param()
