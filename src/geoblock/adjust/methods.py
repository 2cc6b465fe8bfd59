"""The papers' adjustment methods as presets of the one block engine.

A method says, for the images that do not say it themselves, which parameters are adjusted
and which options the engine gets:

======== ====================================================================================
method   per image, and engine options
======== ====================================================================================
mba      the model's ``mba`` parameter set (Chen & Lee's orbit and attitude polynomials and
         scale, a-priori sigmas from the product's accuracy: Teo et al.'s modified bundle
         adjustment)
dg       the model's ``dg`` parameter set (direct georeferencing: position biases and drifts,
         attitude biases), then least-squares collocation of the residual vectors
rfm      an affine image-space correction around the model (an RPC: Teo et al.'s RFM method)
rpcv0    an image-space shift (Grodecki & Dial's RPCV-0)
rpcv1    an affine image-space correction (RPCV-1)
default  the models' parameters as they are
======== ====================================================================================

Every name resolves through the sensor-model protocol (``with_parameter_set``) or the
:class:`~geoblock.models.ImageCorrection` wrapper, so a method works for any model that offers
the set, a third party's included.
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType
from typing import Any

from geoblock.errors import AdjustmentError
from geoblock.models.corrections import ImageCorrection
from geoblock.models.protocol import SensorModel

__all__ = ["METHODS", "prepare_model"]

METHODS: Mapping[str, Mapping[str, Any]] = MappingProxyType({
    "mba": MappingProxyType({"parameters": "mba", "correction": None, "collocation": False}),
    "dg": MappingProxyType({"parameters": "dg", "correction": None, "collocation": True}),
    "rfm": MappingProxyType({"parameters": "default", "correction": 1, "collocation": False}),
    "rpcv0": MappingProxyType({"parameters": "default", "correction": 0, "collocation": False}),
    "rpcv1": MappingProxyType({"parameters": "default", "correction": 1, "collocation": False}),
    "default": MappingProxyType({"parameters": "default", "correction": None,
                                 "collocation": False}),
})
"""Method name -> per-image ``parameters`` set, ``correction`` order and engine options."""


def prepare_model(
    model: SensorModel,
    *,
    parameters: str = "default",
    correction: int | None = None,
    accuracy_m: float | None = None,
    options: Mapping[str, Any] | None = None,
    where: str = "model",
) -> SensorModel:
    """A model ready for the block engine: a parameter set chosen, optionally wrapped.

    Parameters
    ----------
    model : SensorModel
    parameters : str
        A name of ``model.parameter_sets`` (``"default"``: as the model is).
    correction : {0, 1, 2}, optional
        Wrap the (preset) model in an :class:`~geoblock.models.ImageCorrection` of that order;
        the wrapped model's own parameters are then fixed.
    accuracy_m : float, optional
        The product's location accuracy (1 sigma, metres), for presets that derive their
        sigmas from it.
    options : mapping of str to value, optional
        Further options of the parameter set (``model.with_parameter_set(parameters,
        **options)``), such as ``knot_lines`` of a linescan model's ``jitter`` set.
    where : str
        Named in error messages (e.g. ``"block.toml: images[2]"``).

    Raises
    ------
    AdjustmentError
        Unknown parameter set or parameter name, or a set the model cannot build (the
        message names ``where`` and the model's sets).
    """
    if parameters != "default" or accuracy_m is not None or options:
        kwargs = dict(options or {})
        if accuracy_m is not None:
            kwargs["accuracy_m"] = float(accuracy_m)
        try:
            model = model.with_parameter_set(parameters, **kwargs)
        except AttributeError:
            raise AdjustmentError(f"{where}: model {model.name!r} offers no parameter sets; "
                                  f"'{parameters}' cannot be used") from None
        except (ValueError, KeyError) as exc:
            raise AdjustmentError(f"{where}: {exc}") from None
    if correction is not None:
        if correction not in (0, 1, 2):
            raise AdjustmentError(f"{where}: correction must be 0, 1 or 2, got {correction!r}")
        model = ImageCorrection(model, order=int(correction))
    return model
