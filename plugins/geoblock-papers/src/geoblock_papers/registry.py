"""The experiments by name, and :func:`run_experiment`, which runs one into a directory.

An experiment is a module with:

``TITLE`` : str
    One line, e.g. ``"Teo et al. (2010): DEM-aided block adjustment of three SPOT-5 strips"``.
``CITATION`` : str
    The paper, as cited in ``../shared/papers/README.md``.
``SEEDS`` : dict
    Repetitions per variant, e.g. ``{"small": 3, "full": 10}`` (one entry per variant of
    its :data:`EXPERIMENTS` entry).
``run(report, *, full, seeds, progress)``
    Simulates and adjusts, once per seed of ``seeds``, and fills ``report``
    (:class:`~geoblock_papers.report.Report`): sections, side-by-side tables with the paper's
    figures, findings (reproduced or not, and why), figures and results. An experiment with
    variants beyond ``small`` and ``full`` (teo2010's ``case2``) takes ``variant`` too:
    ``run(report, *, full, seeds, progress, variant)``.

Every experiment has the variants ``small`` and ``full``; an entry may list more, e.g.
teo2010's ``case2`` and ``case2-full`` (Teo et al.'s case II). A variant named ``full`` or
ending in ``-full`` uses the papers' image sizes (``full=True``).
"""

from __future__ import annotations

import importlib
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import ModuleType
from typing import Any

from geoblock.errors import GeoblockError

__all__ = ["EXPERIMENTS", "ExperimentError", "ExperimentResult", "all_variants",
           "experiment_module", "is_full", "run_experiment"]


class ExperimentError(GeoblockError, ValueError):
    """Unknown experiment, or options an experiment cannot run with."""


@dataclass(frozen=True)
class _Entry:
    """An experiment of :data:`EXPERIMENTS`: its module, a one-line summary, its run times
    (``{"small": "~20 s", "full": "~4 min"}``: shown by ``--help``; empty when unmeasured)
    and its variants (``small`` and ``full``, then any more, each with a one-line note)."""

    module: str
    summary: str
    runtime: dict[str, str] = field(default_factory=dict)
    more_variants: dict[str, str] = field(default_factory=dict)

    @property
    def variants(self) -> tuple[str, ...]:
        """``("small", "full", *more_variants)``."""
        return ("small", "full", *self.more_variants)


def is_full(variant: str) -> bool:
    """Whether a variant uses the papers' image sizes: ``full`` or a name ending in
    ``-full``."""
    return variant == "full" or variant.endswith("-full")


def all_variants() -> tuple[str, ...]:
    """Every variant of any experiment, in order (``--variant``'s choices)."""
    return tuple(dict.fromkeys(v for e in EXPERIMENTS.values() for v in e.variants))


#: Experiment name -> its module and a one-line summary (``geoblock experiment --help``).
EXPERIMENTS: dict[str, _Entry] = {
    "teo2010": _Entry("geoblock_papers.teo2010",
                      "Teo et al. 2010: MBA, DG and RFM, single vs block, on three SPOT-5 "
                      "strips; DEM control, collocation; realistic and bias-drift on-board "
                      "errors side by side",
                      {"small": "~75 s CPU, 100 s at load 4 (both error models)",
                       "full": "~6 min (10 seeds, both error models, 1.2 GB)",
                       "case2": "~55 s CPU, 85 s at load 4"},
                      {"case2": "case II: two scenes per strip (Tables IV, VII, VIII), "
                                "small images",
                       "case2-full": "case II at the papers' image sizes"}),
    "chen2008": _Entry("geoblock_papers.chen2008",
                       "Chen, Teo & Lo 2008: the conference version's tables (the teo2010 "
                       "block)", {"small": "~75 s CPU, 100 s at load 4 (both error models)",
                                  "full": "~6 min (10 seeds, both error models, 1.2 GB)"}),
    "chen1993": _Entry("geoblock_papers.chen1993",
                       "Chen & Lee 1993: SPOT resection residuals, check points, orthoimage "
                       "RMSE over rolling and rugged terrain",
                       {"small": "~15 s", "full": "~5 min (10 seeds, 1.5 GB)"}),
    "aguilar2007": _Entry("geoblock_papers.aguilar2007",
                          "Aguilar et al. 2007: RPCV-0, RPCV-1, RFM-1 and the physical model vs "
                          "GCP count and sampling, along-track error, ortho error budget",
                          {"small": "~25 s", "full": "~8 min (10 seeds, 2.4 GB)"}),
    "jitter": _Entry("geoblock_papers.jitter",
                     "Beyond the papers (issue 27): the jitter set recovers a measured attitude "
                     "wander on the three SPOT-5 strips (dg vs jitter, with and without GCPs, "
                     "ICP RMSE against the posterior over 20 seeds)",
                     {"small": "~95 s CPU, 110 s at load 3.6 (20 seeds)"}),
    "reference": _Entry("geoblock_papers.reference",
                        "Beyond the papers (issue 28): no surveyed GCP, control from a "
                        "reference ortho misregistered by a known shift (Teo, Aguilar and a "
                        "4-image RPC block): ICP RMSE against the reference's error, the "
                        "posterior's prediction, the matches, GSD and error sweeps, the "
                        "accuracy layer against the ortho's error",
                        {"small": "~55 s wall, 40 s CPU at load 2-4",
                         "full": "~6.5 min (3 seeds, 20 repetitions of the layer's "
                                 "validation), 9.5 min at load 4"}),
}


@dataclass(frozen=True)
class ExperimentResult:
    """What :func:`run_experiment` wrote.

    Attributes
    ----------
    name : str
    outdir : pathlib.Path
    report : pathlib.Path
        ``report.md``.
    results : pathlib.Path
        ``results.json``.
    figures : tuple of pathlib.Path
    seconds : float
        Wall time.
    """

    name: str
    outdir: Path
    report: Path
    results: Path
    figures: tuple[Path, ...]
    seconds: float


def experiment_module(name: str) -> ModuleType:
    """The module of experiment ``name``.

    Raises
    ------
    ExperimentError
        Unknown name (the message lists the known ones), or a module without ``TITLE``,
        ``CITATION``, ``SEEDS`` or ``run`` (the module docstring).
    """
    if name not in EXPERIMENTS:
        raise ExperimentError(f"unknown experiment {name!r}; known: {', '.join(EXPERIMENTS)}")
    module = importlib.import_module(EXPERIMENTS[name].module)
    missing = [a for a in ("TITLE", "CITATION", "run") if not hasattr(module, a)]
    seeds = getattr(module, "SEEDS", None)
    variants = EXPERIMENTS[name].variants
    if not (isinstance(seeds, dict) and all(
            isinstance(seeds.get(v), int) and seeds[v] >= 1 for v in variants)):
        missing.append("SEEDS = {" + ", ".join(f"'{v}': n" for v in variants)
                       + "} with n >= 1")
    if missing:
        raise ExperimentError(f"experiment {name}: module {module.__name__} lacks "
                              f"{', '.join(missing)}")
    return module


def run_experiment(
    name: str,
    outdir: str | os.PathLike[str],
    *,
    full: bool = False,
    repeats: int | None = None,
    seed: int = 0,
    progress: Callable[[str], None] | None = None,
    variant: str | None = None,
) -> ExperimentResult:
    """Run experiment ``name`` and write its report into ``outdir`` (created if absent; files
    of the same name are replaced).

    Parameters
    ----------
    name : str
        A key of :data:`EXPERIMENTS`.
    outdir : str or os.PathLike
    full : bool
        The papers' image sizes and the full number of repetitions (minutes to hours) instead
        of the small variant (seconds to a minute).
    repeats : int, optional
        Repetitions over seeds (default: the experiment's ``SEEDS`` for the variant).
    seed : int
        The first seed; repetition ``k`` uses ``seed + k``.
    progress : callable, optional
        Called with one-line messages.
    variant : str, optional
        One of the experiment's variants (:data:`EXPERIMENTS`); default ``"full"`` if
        ``full`` else ``"small"``.

    Returns
    -------
    ExperimentResult

    Raises
    ------
    ExperimentError
        Unknown ``name``, a variant the experiment lacks, ``repeats < 1``, ``seed < 0``,
        or ``outdir`` is a file (checked before anything runs).
    GeoblockIOError
        ``outdir`` or a file in it cannot be written.
    GeoblockError
        The experiment failed (the message says where).
    """
    from geoblock_papers.report import Report

    module = experiment_module(name)
    variants = EXPERIMENTS[name].variants
    variant = variant or ("full" if full else "small")
    if variant not in variants:
        raise ExperimentError(f"experiment {name} has no variant {variant!r}; its variants: "
                              f"{', '.join(variants)}")
    full = is_full(variant)
    count = int(repeats) if repeats is not None else int(module.SEEDS[variant])
    if count < 1:
        raise ExperimentError(f"experiment {name}: repeats must be >= 1, got {count}")
    if int(seed) < 0:
        raise ExperimentError(f"experiment {name}: seed must be >= 0, got {seed}")
    if Path(outdir).exists() and not Path(outdir).is_dir():
        raise ExperimentError(f"experiment {name}: OUTDIR {str(outdir)!r} exists and is not a "
                              "directory")
    seeds: Sequence[int] = tuple(int(seed) + k for k in range(count))
    say = progress or (lambda message: None)
    start = time.perf_counter()
    report = Report(name, module.TITLE, module.CITATION, variant=variant, seeds=seeds,
                    outdir=Path(outdir), variants=variants)
    say(f"experiment {name} ({variant}, {count} seed{'s' if count > 1 else ''}): "
        f"{module.TITLE}")
    if len(variants) > 2:
        module.run(report, full=full, seeds=seeds, progress=say, variant=variant)
    else:
        module.run(report, full=full, seeds=seeds, progress=say)
    seconds = time.perf_counter() - start
    paths = report.write(seconds=seconds)
    say(f"done in {seconds:.0f} s: {paths['report']}")
    return ExperimentResult(name, Path(outdir), paths["report"], paths["results"],
                            tuple(report.figures), seconds)


def per_seed(seeds: Sequence[int], run_one: Callable[[int], Any], what: str,
             progress: Callable[[str], None] | None = None) -> list[Any]:
    """``run_one(seed)`` for each seed, in order, with a progress line per repetition.

    ``what`` names what one repetition simulates (``"the SPOT 1A scene"``); ``run_one``'s
    result must have a ``seconds`` attribute (wall time of the repetition).
    """
    say = progress or (lambda message: None)
    found = []
    for k, seed in enumerate(seeds):
        say(f"repetition {k + 1}/{len(seeds)} (seed {seed}): simulating {what}")
        found.append(run_one(int(seed)))
        say(f"  seed {seed}: {found[-1].seconds:.1f} s")
    return found
