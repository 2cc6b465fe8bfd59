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

import numpy as np

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
    sigmas: Mapping[str, float] | None = None,
    accuracy_m: float | None = None,
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
    sigmas : mapping of str to float, optional
        A-priori sigmas of named parameters of the result (``inf``: free; 0: fixed).
    accuracy_m : float, optional
        The product's location accuracy (1 sigma, metres), for presets that derive their
        sigmas from it.
    where : str
        Named in error messages (e.g. ``"block.toml: images[2]"``).

    Raises
    ------
    AdjustmentError
        Unknown parameter set or parameter name, or a set the model cannot build (the
        message names ``where`` and the model's sets).
    """
    if parameters != "default" or accuracy_m is not None:
        options = {} if accuracy_m is None else {"accuracy_m": float(accuracy_m)}
        try:
            model = model.with_parameter_set(parameters, **options)
        except AttributeError:
            raise AdjustmentError(f"{where}: model {model.name!r} offers no parameter sets; "
                                  f"'{parameters}' cannot be used") from None
        except (ValueError, KeyError) as exc:
            raise AdjustmentError(f"{where}: {exc}") from None
    if correction is not None:
        if correction not in (0, 1, 2):
            raise AdjustmentError(f"{where}: correction must be 0, 1 or 2, got {correction!r}")
        model = ImageCorrection(model, order=int(correction))
    if sigmas:
        model = _with_sigmas(model, sigmas, where)
    return model


def _with_sigmas(model: SensorModel, sigmas: Mapping[str, float], where: str) -> SensorModel:
    params = model.parameters
    values = np.array(params.sigmas, dtype=np.float64)
    adjustable = np.array(params.adjustable)
    for name, sigma in sigmas.items():
        if name not in params.names:
            raise AdjustmentError(f"{where}: sigmas: model {model.name!r} has no parameter "
                                  f"{name!r}; its parameters are {list(params.names)}")
        k = params.names.index(name)
        if sigma == 0:
            adjustable[k] = False
        else:
            values[k] = float(sigma)
    if isinstance(model, ImageCorrection):
        return ImageCorrection(model.model, model.order, params.values, values, adjustable)
    replace = getattr(model, "with_parameter_set", None)
    try:
        return replace("default", sigmas=values, adjustable=adjustable)  # type: ignore[misc]
    except Exception as exc:  # the model's set cannot take sigmas
        raise AdjustmentError(f"{where}: model {model.name!r} does not accept a-priori sigmas "
                              f"from the block file ({exc})") from None
