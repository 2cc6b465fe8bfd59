"""The set-ups of the Teo et al. (2010) block: its cases, variants and on-board error models.

:data:`CASES` holds Teo et al.'s case I (one scene per strip) and case II (two), with the
paper's point counts and on-board accuracies; :data:`VARIANTS` maps the experiment's
variants to them; :func:`scenario_dict` turns a seed, a variant and an error model into the
``teo2010-spot5`` scenario :mod:`geoblock_papers._teo_block` simulates.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

from geoblock.simulate.presets import SENSOR_PRESETS
from geoblock.simulate.scenario import preset_dict
from geoblock.simulate.sensors import OrbitSensorSpec
from geoblock_papers.registry import ExperimentError, is_full

__all__ = ["CASES", "ERROR_MODELS", "SENSITIVITY_MODELS", "VARIANTS", "Case",
           "available_error_models", "case_of", "scenario_dict"]

#: The simulator's on-board error models, the default first
#: (:attr:`geoblock.simulate.sensors.OrbitSensorSpec.onboard_errors`)
ERROR_MODELS = ("realistic", "bias-drift")


#: Error models for sensitivity studies from Python (:func:`geoblock_papers._teo_block.study`
#: ``models=``; never run by the command): ``"realistic-spot1-4"`` is ``"realistic"`` with the
#: attitude wander measured on the SPOT 1-4 records
#: (:data:`geoblock.simulate.onboard.WANDER_SPOT1_4`, 7.8 times SPOT-5's in pitch) instead of
#: SPOT-5's: local systematic errors of metres, where collocation has something to remove.
SENSITIVITY_MODELS = ("realistic-spot1-4",)


def available_error_models(sensitivity: bool = False) -> tuple[str, ...]:
    """:data:`ERROR_MODELS` (and with ``sensitivity`` :data:`SENSITIVITY_MODELS`), or only
    ``("bias-drift",)`` with a simulator that has no ``onboard_errors`` (its only model:
    biases and drifts)."""
    if "onboard_errors" in {f.name for f in dataclasses.fields(OrbitSensorSpec)}:
        return ERROR_MODELS + (SENSITIVITY_MODELS if sensitivity else ())
    return ("bias-drift",)


@dataclass(frozen=True)
class Case:
    """One of Teo et al.'s two cases: scenes per strip and point counts.

    Attributes
    ----------
    name : {"I", "II"}
    scenes : int
        Standard scenes per strip, adjacent along track: the strip is simulated as one image
        of ``scenes`` times the preset's rows (the paper's Table I gives case II's strips as
        24000 x 48000 px images, and reports per strip).
    gcps : tuple of int
        GCPs kept per strip (Teo et al. Table I / VII).
    gcp_candidates : int
        GCPs drawn per strip, of which the ``gcps`` nearest the centre column are kept.
    icp : int
        ICPs drawn per strip.
    tp, ictp : (int, int)
        Ranges of the TP and ICTP counts per overlap.
    onboard_rmse_m : tuple of float
        2-D RMSE of the on-board data per strip (Teo et al. Table II).
    """

    name: str
    scenes: int
    gcps: tuple[int, int, int]
    gcp_candidates: int
    icp: int
    tp: tuple[int, int]
    ictp: tuple[int, int]
    onboard_rmse_m: tuple[float, float, float]


#: Teo et al.'s cases. I: the presets' counts (Table I, Table III); II: two scenes per
#: strip, 20/22/22 GCPs (Table VII), 48/31/28 ICPs (a mean of 36 drawn per strip), 32 and 26
#: TPs, 31 and 26 ICTPs (Table IV), on-board RMSE from Table II case II (hypot(E, N)).
CASES: dict[str, Case] = {
    "I": Case("I", 1, (9, 9, 9), 27, 20, (13, 19), (13, 18), (33.6, 12.0, 42.3)),
    "II": Case("II", 2, (20, 22, 22), 66, 36, (26, 32), (26, 31), (33.6, 12.3, 42.4)),
}
#: The variants of the block: variant -> case (``*full`` at the papers' image sizes,
#: :func:`geoblock_papers.registry.is_full`)
VARIANTS: dict[str, str] = {"small": "I", "full": "I", "case2": "II", "case2-full": "II"}


def case_of(variant: str) -> Case:
    """The :class:`Case` of a variant of :data:`VARIANTS`.

    Raises
    ------
    ExperimentError
        An unknown variant.
    """
    if variant not in VARIANTS:
        raise ExperimentError(f"teo block: unknown variant {variant!r}; known: "
                              f"{', '.join(VARIANTS)}")
    return CASES[VARIANTS[variant]]


def scenario_dict(seed: int, variant: str = "small",
                  errors: str | None = None) -> dict[str, Any]:
    """The ``teo2010-spot5`` preset (``full`` or ``small`` images) for a variant of
    :data:`VARIANTS` with ``seed``, its case's strips and point counts (:data:`CASES`) and,
    unless None, the on-board error model ``errors`` of every strip."""
    case = case_of(variant)
    known = available_error_models(sensitivity=True)
    if errors is not None and errors not in known:
        raise ExperimentError(f"teo block: on-board error model {errors!r} is not one of "
                              f"{', '.join(known)}")
    if len(known) == 1:
        errors = None  # a simulator without the key: its only model
    wander: dict[str, Any] = {}
    if errors == "realistic-spot1-4":
        from geoblock.simulate.onboard import WANDER_SPOT1_4

        errors = "realistic"
        wander = {"wander_rms_rad": list(WANDER_SPOT1_4.rms_rad),
                  "wander_slope": WANDER_SPOT1_4.slope,
                  "wander_band_hz": list(WANDER_SPOT1_4.band_hz)}
    data = preset_dict("teo2010-spot5", "full" if is_full(variant) else "small")
    data["seed"] = int(seed)
    data["points"].update(gcp=case.gcp_candidates, icp=case.icp, tp=list(case.tp),
                          ictp=list(case.ictp))
    for image, rmse in zip(data["images"], case.onboard_rmse_m, strict=True):
        if case.scenes != 1:  # the strip's scenes as one image: its rows times the scenes
            rows, cols = SENSOR_PRESETS[image["preset"]].shape
            image["shape"] = [rows * case.scenes, cols]
        image["onboard_rmse_m"] = rmse
        if errors is not None:
            image["onboard_errors"] = errors
        image.update(wander)
    data["description"] += (f"; case {case.name}; {case.gcp_candidates} GCP candidates per "
                            f"strip of which the {'/'.join(map(str, case.gcps))} nearest the "
                            "centre column are kept")
    return data
