"""The four papers' experiments on simulated blocks: ``geoblock experiment``.

:data:`EXPERIMENTS` names each experiment's module; :func:`run_experiment` runs one and writes
its report (``report.md``, PNG figures, ``results.json``).
"""

from __future__ import annotations

from geoblock_papers.registry import EXPERIMENTS, run_experiment

__all__ = ["EXPERIMENTS", "run_experiment"]
