"""Adjustment: single-image resection and the DEM-aided block adjustment (MBA, DG, RFM),
least-squares collocation, robust estimation and accuracy statistics."""

from geoblock.adjust.block import (
    DEM_CONTROLS,
    MODES,
    ROBUST,
    Block,
    BlockResult,
    MeasurementResults,
    ParameterEstimates,
    PointResults,
    adjust,
    check_errors,
)
from geoblock.adjust.collocation import Collocation, CollocationCorrection, fit_collocation
from geoblock.adjust.methods import METHODS, prepare_model
from geoblock.adjust.observations import KINDS, ControlPoints, GroundPoints, ImagePoints
from geoblock.adjust.resect import PointResiduals, ResectionResult, resect
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
