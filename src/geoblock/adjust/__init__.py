"""Adjustment: single-image resection now; the DEM-aided block adjustment builds on it."""

from geoblock.adjust.observations import ControlPoints
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
    "POINT_KINDS",
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
