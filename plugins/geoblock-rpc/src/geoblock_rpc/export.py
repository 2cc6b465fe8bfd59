"""RPC export of any sensor model: the RPC00B to write, and how well it reproduces the model.

:func:`export_rpc` returns an :class:`~geoblock_rpc.RpcModel` as it is, an RFM fitted in
lon/lat as its exact RPC00B, an image correction of an RPC folded into its coefficients
(exactly where the algebra allows, else refitted), and any other model fitted as a
sensor-oriented RPC (:func:`geoblock_rpc.fit.fit_rpc`). The write hook
(:mod:`geoblock_rpc.plugin`) and ``geoblock export-rpc`` use it; what was done is reported by
an :class:`RpcExportWarning`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum
from typing import Any

from geoblock.errors import AdjustmentError, GeoblockWarning, ModelFormatError
from geoblock.models.corrections import ImageCorrection
from geoblock.models.protocol import SensorModel
from geoblock_rpc.model import RpcModel

__all__ = ["EXPORT_OPTIONS", "MAX_FIT_ERROR_PX", "MAX_REFIT_ERROR_PX", "ExportOutcome",
           "ExportReport", "RpcExportWarning", "export_rpc"]


#: a corrected RPC whose correction does not fold exactly is refitted, and written only when
#: the refit reproduces the corrected model to this many pixels on the check grid (option
#: ``max_error_px``, formerly ``max_refit_error_px``): such a refit is normally near exact
MAX_REFIT_ERROR_PX = 1e-3

#: any other model is fitted, and written only when the fit's maximum error on the check grid
#: is at most this many pixels (option ``max_error_px``): a cubic RPC follows a smooth
#: pushbroom to 1e-6 px but not the attitude jitter of DigitalGlobe models, whose best fits
#: are 0.05-0.12 px RMS and about 0.3 px at worst
MAX_FIT_ERROR_PX = 0.5

#: the options :func:`export_rpc` takes out of the writer options
EXPORT_OPTIONS = ("grid", "regularization", "max_error_px", "max_refit_error_px")


class ExportOutcome(str, Enum):
    """What ``geoblock export-rpc`` says happened: the words its line starts with, after
    ``OUT (FORMAT):``. The one list of them: :meth:`ExportReport.summary` and the command
    print these, and the command's ``--help`` lists each (a test checks it)."""

    #: an RpcModel, or an RFM fitted in lon/lat (its RPC00B): the coefficients as they are
    WRITTEN = "written exactly"
    #: an image correction of an RPC folded into its coefficients, algebraically equal
    FOLDED = "folded exactly"
    #: an image correction of an RPC that does not fold exactly: an RPC refitted to it
    REFITTED = "refitted"
    #: any other model: a sensor-oriented RPC fitted to it
    FITTED = "fitted"
    #: the command only: another plugin's writer answered the write hook first (no report)
    OTHER_WRITER = "written by another plugin's writer"


@dataclass(frozen=True)
class ExportReport:
    """How a model became the RPC00B written, and how well that RPC reproduces it.

    Attributes
    ----------
    method : str
        ``"identity"`` (an :class:`~geoblock_rpc.RpcModel`, written as it is), ``"as-rpc"`` (an
        RFM in lon/lat, whose RPC00B is exact), ``"fold"`` (an
        image correction of an RPC, folded into its coefficients, or refitted when it does not
        fold exactly) or ``"fit"`` (any other model, fitted by
        :func:`~geoblock_rpc.fit.fit_rpc`).
    exact : bool
        The RPC equals the model algebraically (errors are float64 rounding only).
    detail : str
        The fold's method (``"offset"``, ``"scale-offset"``, ``"affine-same-denominator"``,
        ``"refit"``, joined with ``"+"`` for nested corrections), ``"fit_rpc"`` or
        ``"RpcModel"``.
    rms_px, max_px : float
        2D image error of the RPC against the model on the independent check grid, pixels.
    n_check : int
        Check points.
    regularization : float, str or None
        The fit's Tikhonov weight (fitted and refitted RPCs), else None.
    model : str
        The exported model's registry name.
    message : str
        The full one-line report (the fold's, or what the fit did), as the write hook warns it.
    """

    method: str
    exact: bool
    detail: str
    rms_px: float
    max_px: float
    n_check: int
    regularization: float | str | None
    model: str
    message: str = ""

    def summary(self) -> str:
        """One line saying which happened, as ``geoblock export-rpc`` prints it; it starts
        with :attr:`outcome`.

        ``"written exactly (RpcModel)"``, ``"folded exactly (offset): max error 2e-09 px over
        25600 check points"``, ``"refitted (refit: the correction does not fold exactly):
        check-grid RMS ..."`` or ``"fitted: check-grid RMS 0.116 px, max 0.28 px over 25600
        points (regularization 1e-09)"``.
        """
        outcome = self.outcome.value
        if self.outcome is ExportOutcome.WRITTEN:
            return f"{outcome} ({self.detail})"
        if self.outcome is ExportOutcome.FOLDED:
            return (f"{outcome} ({self.detail}): max error {self.max_px:.3g} px over "
                    f"{self.n_check} check points")
        if self.outcome is ExportOutcome.REFITTED:
            outcome = f"{outcome} ({self.detail}: the correction does not fold exactly)"
        return (f"{outcome}: check-grid RMS {self.rms_px:.3g} px, max {self.max_px:.3g} px "
                f"over {self.n_check} points (regularization {_number(self.regularization)})")

    @property
    def outcome(self) -> ExportOutcome:
        """Which happened (:class:`ExportOutcome`; never ``OTHER_WRITER``)."""
        if self.method in ("identity", "as-rpc"):
            return ExportOutcome.WRITTEN
        if self.exact:
            return ExportOutcome.FOLDED
        return ExportOutcome.FITTED if self.method == "fit" else ExportOutcome.REFITTED


class RpcExportWarning(GeoblockWarning):
    """The RPC written is not the model's own: folded, refitted or fitted (see ``report``).

    Issued by the ``geoblock_write_sensor_model`` hook after writing, so that callers (the
    ``geoblock refine`` and ``geoblock export-rpc`` commands) show how the model was exported.

    Attributes
    ----------
    report : ExportReport
    """

    def __init__(self, message: str, report: ExportReport) -> None:
        super().__init__(message)
        self.report = report


def _number(value: object) -> str:
    return f"{value:g}" if isinstance(value, float) else str(value)


def _regularization(stats: object, options: dict[str, Any]) -> float | str | None:
    """The Tikhonov weight a fit used (``FitStats.regularization``), else the one asked for."""
    value = getattr(stats, "regularization", None)
    if value is None:
        value = options.get("regularization")
    return float(value) if isinstance(value, int | float) else value


def _limit(options: dict[str, Any], label: str) -> float | None:
    """``max_error_px`` (or its former name ``max_refit_error_px``), or None for the default."""
    given = [k for k in ("max_error_px", "max_refit_error_px") if options.get(k) is not None]
    if len(given) > 1:
        raise ModelFormatError(f"{label}: give max_error_px or its former name "
                               "max_refit_error_px, not both")
    return float(options[given[0]]) if given else None


def export_rpc(
    model: SensorModel,
    *,
    grid: tuple[int, int, int] | None = None,
    regularization: float | str | None = None,
    max_error_px: float | None = None,
    max_refit_error_px: float | None = None,
    label: str = "RPC export",
) -> tuple[RpcModel, ExportReport]:
    """The RPC00B model to write for any ``model``, and how it was obtained.

    * an :class:`~geoblock_rpc.RpcModel` is returned as it is (exact), and so is a
      terrain-dependent RFM fitted in lon/lat (:meth:`~geoblock_rpc.rfm.RfmModel.as_rpc`);
    * an ``ImageCorrection`` of one (RPCV-0, RPCV-1, ...: ``geoblock refine``'s models) is
      folded into the coefficients (:func:`geoblock_rpc.fold.rpc_for`): exactly where the
      algebra allows, else refitted, and refused when the refit misses the corrected model by
      more than ``max_error_px`` (default :data:`MAX_REFIT_ERROR_PX`, 1e-3 px);
    * any other model (physical, adjusted, corrected physical) is fitted as a
      sensor-oriented RPC by :func:`geoblock_rpc.fit.fit_rpc` over the image and the model's
      height range, and refused when the fit misses the model by more than ``max_error_px``
      (default :data:`MAX_FIT_ERROR_PX`, 0.5 px) on the independent check grid.

    Parameters
    ----------
    model : SensorModel
    grid : (int, int, int), optional
        Fit grid (rows, columns, heights) for a fit or refit; default fit_rpc's (21, 21, 9).
    regularization : float or str, optional
        Tikhonov weight of a fit or refit; default the fitting function's.
    max_error_px : float, optional
        Largest check-grid error (pixels) of an approximate RPC that may be written; default
        per case, as above.
    max_refit_error_px : float, optional
        The former name of ``max_error_px`` (give one or the other).
    label : str
        What the error messages name (the writer gives the destination path).

    Returns
    -------
    rpc_model : RpcModel
        Of ``model.shape`` (a corrected RPC keeps its base's domain limits).
    report : ExportReport

    Raises
    ------
    ModelFormatError
        The approximate RPC misses the model by more than the limit, or no RPC can be fitted
        (the message names ``label``, the model and the error).
    """
    from geoblock_rpc.fit import fit_rpc
    from geoblock_rpc.fold import is_rpc_based, rpc_for

    options: dict[str, Any] = {k: v for k, v in (("grid", grid),
                                                 ("regularization", regularization))
                               if v is not None}
    limit = _limit({"max_error_px": max_error_px, "max_refit_error_px": max_refit_error_px},
                   label)
    if isinstance(model, RpcModel):
        return model, ExportReport("identity", True, "RpcModel", 0.0, 0.0, 0, None, model.name,
                                   "written exactly (RpcModel)")
    from geoblock_rpc.rfm import RfmModel

    exact = model.as_rpc() if isinstance(model, RfmModel) else None
    if exact is not None:  # an RFM in lon/lat is an RPC00B with zero higher-order terms
        rpc_model = RpcModel(exact, model.shape, domain_limit=model.domain_limit)
        return rpc_model, ExportReport(
            "as-rpc", True, f"RFM-{model.order} in lon/lat is an RPC00B", 0.0, 0.0, 0, None,
            model.name, f"written exactly (RFM-{model.order} in lon/lat is an RPC00B)")

    if is_rpc_based(model):
        limit = MAX_REFIT_ERROR_PX if limit is None else limit
        rpc, fold = rpc_for(model, **options)
        report = ExportReport(
            "fold", fold.exact, fold.method, fold.rms_error_px, fold.max_error_px,
            fold.n_check, None if fold.fit is None else _regularization(fold.fit, options),
            model.name, str(fold),
        )
        if not fold.exact and not fold.max_error_px <= limit:
            raise ModelFormatError(
                f"{label}: the order-{getattr(model, 'order', '?')} correction does not fold "
                "into RPC00B exactly and the refitted RPC misses the corrected model by "
                f"{fold.max_error_px:.3g} px (> max_error_px={limit:g}); write the model as "
                f"JSON instead ({fold})"
            )
        base = model
        while isinstance(base, ImageCorrection):
            base = base.model
        assert isinstance(base, RpcModel)  # is_rpc_based
        folded = RpcModel(rpc, model.shape, domain_limit=base.domain_limit,
                          height_limit=base.height_limit, height_margin_m=base.height_margin_m)
        return folded, report

    limit = MAX_FIT_ERROR_PX if limit is None else limit
    try:
        rpc, stats = fit_rpc(model, **options)
    except AdjustmentError as exc:
        raise ModelFormatError(
            f"{label}: cannot fit an RPC00B to model {model.name!r}: {exc} (options "
            "regularization and grid; --regularization and --grid of geoblock export-rpc)"
        ) from exc
    lam = _regularization(stats, options)
    report = ExportReport(
        "fit", False, "fit_rpc", stats.rms_px, stats.max_px, stats.n_check, lam, model.name,
        f"model {model.name!r} is not an RPC: an RPC00B was FITTED to it (approximate): "
        f"check-grid error RMS {stats.rms_px:.3g} px, max {stats.max_px:.3g} px over "
        f"{stats.n_check} points (regularization {_number(lam)})",
    )
    if not (math.isfinite(stats.max_px) and stats.max_px <= limit):
        raise ModelFormatError(
            f"{label}: the RPC00B fitted to model {model.name!r} misses it by "
            f"{stats.max_px:.3g} px on the check grid (> max_error_px={limit:g}); raise "
            f"max_error_px (--max-error-px), or keep the model as JSON ({stats})"
        )
    return RpcModel(rpc, model.shape), report
