"""Adjustment: single-image resection and the DEM-aided block adjustment (MBA, DG, RFM),
least-squares collocation, robust estimation and accuracy statistics."""

from __future__ import annotations

from typing import TYPE_CHECKING

from geoblock._lazy import lazy_names

if TYPE_CHECKING:
    from geoblock.adjust.block import adjust, check_errors
    from geoblock.adjust.collocation import Collocation, CollocationCorrection, fit_collocation
    from geoblock.adjust.methods import METHODS, prepare_model
    from geoblock.adjust.observations import KINDS, ControlPoints, GroundPoints, ImagePoints
    from geoblock.adjust.problem import DEM_CONTROLS, MODES, ROBUST, Block
    from geoblock.adjust.resect import PointResiduals, ResectionResult, resect
    from geoblock.adjust.results import (
        BlockResult,
        MeasurementResults,
        ParameterEstimates,
        PointResults,
    )
    from geoblock.adjust.statistics import (
        POINT_KINDS,
        AccuracyStats,
        ConfidenceInterval,
        IctpDiscrepancies,
        ImageResidualStats,
        PointErrors,
        confidence_interval,
        distance_from_image_centre,
        ground_errors,
        ictp_accuracy,
    )

__all__ = [
    "DEM_CONTROLS",
    "KINDS",
    "METHODS",
    "MODES",
    "POINT_KINDS",
    "ROBUST",
    "Block",
    "BlockResult",
    "Collocation",
    "CollocationCorrection",
    "GroundPoints",
    "ImagePoints",
    "MeasurementResults",
    "ParameterEstimates",
    "PointResults",
    "adjust",
    "check_errors",
    "fit_collocation",
    "prepare_model",
    "AccuracyStats",
    "ConfidenceInterval",
    "ControlPoints",
    "IctpDiscrepancies",
    "ImageResidualStats",
    "PointErrors",
    "PointResiduals",
    "ResectionResult",
    "confidence_interval",
    "distance_from_image_centre",
    "ground_errors",
    "ictp_accuracy",
    "resect",
]

# ``resect`` is both a submodule and its function: imported here, or a later import of the
# submodule would leave the module under the function's name
from geoblock.adjust.resect import resect

# the rest is imported on first use (PEP 562): the registry imports CollocationCorrection (a
# model) from here, and a command that only projects must not pay for SciPy's statistics
_LAZY = {
    "DEM_CONTROLS": "geoblock.adjust.problem",
    "MODES": "geoblock.adjust.problem",
    "ROBUST": "geoblock.adjust.problem",
    "Block": "geoblock.adjust.problem",
    "BlockResult": "geoblock.adjust.results",
    "MeasurementResults": "geoblock.adjust.results",
    "ParameterEstimates": "geoblock.adjust.results",
    "PointResults": "geoblock.adjust.results",
    "adjust": "geoblock.adjust.block",
    "check_errors": "geoblock.adjust.block",
    "Collocation": "geoblock.adjust.collocation",
    "CollocationCorrection": "geoblock.adjust.collocation",
    "fit_collocation": "geoblock.adjust.collocation",
    "METHODS": "geoblock.adjust.methods",
    "prepare_model": "geoblock.adjust.methods",
    "KINDS": "geoblock.adjust.observations",
    "ControlPoints": "geoblock.adjust.observations",
    "GroundPoints": "geoblock.adjust.observations",
    "ImagePoints": "geoblock.adjust.observations",
    "PointResiduals": "geoblock.adjust.resect",
    "ResectionResult": "geoblock.adjust.resect",
    "POINT_KINDS": "geoblock.adjust.statistics",
    "AccuracyStats": "geoblock.adjust.statistics",
    "ConfidenceInterval": "geoblock.adjust.statistics",
    "IctpDiscrepancies": "geoblock.adjust.statistics",
    "ImageResidualStats": "geoblock.adjust.statistics",
    "PointErrors": "geoblock.adjust.statistics",
    "confidence_interval": "geoblock.adjust.statistics",
    "distance_from_image_centre": "geoblock.adjust.statistics",
    "ground_errors": "geoblock.adjust.statistics",
    "ictp_accuracy": "geoblock.adjust.statistics",
}


__getattr__, __dir__ = lazy_names(__name__, _LAZY)
