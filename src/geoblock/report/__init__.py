"""Accuracy reports: the papers' tables (Markdown, CSV) and figures (matplotlib, Agg), and
the report of a block adjustment.

Tables and figures take statistics and plain arrays
(:class:`~geoblock.adjust.AccuracyStats`, :class:`~geoblock.adjust.PointErrors`, numpy
arrays), never adjustment or simulator objects, so any workflow can report with them;
:mod:`geoblock.report.adjustment` composes them into what ``geoblock adjust`` writes from a
:class:`~geoblock.adjust.BlockResult`. Files are written through :mod:`geoblock.io.files`.
"""

from geoblock.report.adjustment import (
    correction_curves,
    correction_figure,
    report_markdown,
    result_dict,
    write_result,
)
from geoblock.report.figures import (
    KIND_STYLES,
    correction_curve_plot,
    error_vector_plot,
    residual_vs_distance,
    rmse_vs_gcp_count,
    save_figure,
    to_local_en,
)
from geoblock.report.tables import (
    AGUILAR_COLUMNS,
    DEFAULT_COLUMNS,
    IMAGE_COLUMNS,
    comparison_table,
    stats_table,
    write_table,
)

__all__ = [
    "AGUILAR_COLUMNS",
    "DEFAULT_COLUMNS",
    "IMAGE_COLUMNS",
    "KIND_STYLES",
    "comparison_table",
    "correction_curve_plot",
    "correction_curves",
    "correction_figure",
    "error_vector_plot",
    "residual_vs_distance",
    "report_markdown",
    "result_dict",
    "rmse_vs_gcp_count",
    "save_figure",
    "stats_table",
    "to_local_en",
    "write_result",
    "write_table",
]
