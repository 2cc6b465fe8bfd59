"""End-to-end runs composed from the engines, :mod:`geoblock.io`, :mod:`geoblock.simulate` and
:mod:`geoblock.report`: what the ``geoblock simulate`` and ``geoblock demo`` commands do.

* :func:`run_scenario` simulates a :class:`~geoblock.simulate.scenario.Scenario` into a
  directory: terrain, DEMs, models, points, raw images, a block file and a report of the
  on-board models' accuracy (:mod:`geoblock.workflows.scenario`);
* :func:`run_demo` simulates a three-strip block, adjusts it in single and block mode (DEM
  control), orthorectifies and mosaics the strips with their on-board and their adjusted
  models, measures the seams (:mod:`geoblock.match.seams`) and reports before against after
  (:mod:`geoblock.workflows.demo`).

Every file is read and written through :mod:`geoblock.io`; the computations are those of the
libraries (a workflow only sequences them, reports progress and names the files).
"""

from __future__ import annotations

from geoblock.workflows.demo import (
    DEMO_MARKER,
    DEMO_OUTPUTS,
    DemoResult,
    is_demo_outdir,
    prepare_demo_outdir,
    run_demo,
)
from geoblock.workflows.scenario import ScenarioResult, footprint_rows, run_scenario

__all__ = [
    "DEMO_MARKER",
    "DEMO_OUTPUTS",
    "DemoResult",
    "ScenarioResult",
    "footprint_rows",
    "is_demo_outdir",
    "prepare_demo_outdir",
    "run_demo",
    "run_scenario",
]
