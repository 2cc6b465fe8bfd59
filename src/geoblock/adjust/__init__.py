"""Adjustment: single-image resection now; the DEM-aided block adjustment builds on it."""

from geoblock.adjust.observations import ControlPoints
from geoblock.adjust.resect import PointResiduals, ResectionResult, resect
from geoblock.adjust.statistics import AccuracyStats

__all__ = ["AccuracyStats", "ControlPoints", "PointResiduals", "ResectionResult", "resect"]
