"""The report of an experiment: our figures beside the paper's, table by table.

A :class:`Report` collects, in order, sections of text, side-by-side tables (:meth:`compare`:
quantity, the paper's figure, ours as the mean and 95 % confidence interval over the seeds,
and a verdict), plain tables, figures and findings; :meth:`Report.write` writes
``report.md`` (the findings' summary first), the figures (PNG) and ``results.json`` (every
number in the tables, with the per-seed values).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from geoblock.adjust import confidence_interval
from geoblock.io.files import make_directory, save_figure, write_json, write_text

__all__ = ["Estimate", "Finding", "Report", "Row", "estimate"]


@dataclass(frozen=True)
class Estimate:
    """A statistic over repeated seeds: its mean and 95 % Student-t interval of the mean.

    Attributes
    ----------
    values : tuple of float
        One value per seed (NaN: the run failed; ignored by the statistics).
    unit : str
        E.g. ``"m"``, ``"px"`` or ``""``.
    """

    values: tuple[float, ...]
    unit: str = "m"

    @property
    def finite(self) -> np.ndarray:
        v = np.asarray(self.values, dtype=float)
        return v[np.isfinite(v)]

    @property
    def mean(self) -> float:
        v = self.finite
        return float(v.mean()) if v.size else math.nan

    @property
    def interval(self) -> tuple[float, float]:
        """95 % interval of the mean (NaN bounds for fewer than two finite values)."""
        v = self.finite
        if v.size < 2:
            return (math.nan, math.nan)
        ci = confidence_interval(v)
        return (float(ci.low), float(ci.high))

    def format(self, decimals: int = 2) -> str:
        """``"5.21 m (4.80-5.62)"``; a single seed shows only the value."""
        if not self.finite.size:
            return "failed"
        unit = f" {self.unit}" if self.unit else ""
        low, high = self.interval
        text = f"{self.mean:.{decimals}f}{unit}"
        if math.isfinite(low):
            text += f" ({low:.{decimals}f}-{high:.{decimals}f})"
        return text

    def to_json(self) -> dict[str, Any]:
        low, high = self.interval
        return {"mean": _num(self.mean), "ci95": [_num(low), _num(high)],
                "n": int(self.finite.size), "unit": self.unit,
                "values": [_num(v) for v in self.values]}


def estimate(values: Iterable[float], unit: str = "m") -> Estimate:
    """An :class:`Estimate` of per-seed ``values``."""
    return Estimate(tuple(float(v) for v in values), unit)


@dataclass(frozen=True)
class Row:
    """One line of a side-by-side table.

    Attributes
    ----------
    quantity : str
        What is compared, e.g. ``"ICTP RMSE strips 2-3, single (m)"``.
    paper : str
        The paper's figure as printed (``"28"``, ``"~0.2 px"``, ``"-"`` when it gives none).
    ours : Estimate or str or float
    verdict : str
        E.g. ``"reproduced"``, ``"not reproduced: ..."``, or empty.
    """

    quantity: str
    paper: str
    ours: Estimate | str | float
    verdict: str = ""

    def cells(self, decimals: int) -> list[str]:
        if isinstance(self.ours, Estimate):
            ours = self.ours.format(decimals)
        elif isinstance(self.ours, float):
            ours = f"{self.ours:.{decimals}f}"
        else:
            ours = str(self.ours)
        return [self.quantity, self.paper, ours, self.verdict]

    def to_json(self) -> dict[str, Any]:
        ours = self.ours.to_json() if isinstance(self.ours, Estimate) else (
            _num(self.ours) if isinstance(self.ours, float) else self.ours)
        return {"quantity": self.quantity, "paper": self.paper, "geoblock": ours,
                "verdict": self.verdict}


@dataclass(frozen=True)
class Finding:
    """A finding of the paper and whether it reproduced here.

    Attributes
    ----------
    key : str
    statement : str
        The paper's finding, e.g. ``"block adjustment improves ICTP consistency ~5x"``.
    reproduced : bool or None
        None: partly, or not testable in this variant (say why in ``evidence``).
    evidence : str
        Our figures, and why when it did not reproduce.
    """

    key: str
    statement: str
    reproduced: bool | None
    evidence: str

    @property
    def verdict(self) -> str:
        return {True: "reproduced", False: "NOT reproduced", None: "partly"}[self.reproduced]


@dataclass
class Report:
    """An experiment's report, filled by the experiment and written by :meth:`write`.

    Parameters
    ----------
    name, title, citation : str
    variant : {"small", "full"}
    seeds : sequence of int
    outdir : pathlib.Path
    """

    name: str
    title: str
    citation: str
    variant: str
    seeds: Sequence[int]
    outdir: Path
    blocks: list[str] = field(default_factory=list)
    findings: list[Finding] = field(default_factory=list)
    results: dict[str, Any] = field(default_factory=dict)
    figures: list[Path] = field(default_factory=list)

    def section(self, title: str, text: str = "", level: int = 2) -> None:
        """A heading, and optionally a paragraph under it."""
        self.blocks.append(f"{'#' * level} {title}\n")
        if text:
            self.text(text)

    def text(self, text: str) -> None:
        """A paragraph (Markdown)."""
        self.blocks.append(text.strip() + "\n")

    def table(self, header: Sequence[str], rows: Sequence[Sequence[Any]], *,
              key: str | None = None, align: str | None = None) -> None:
        """A plain Markdown table; ``key`` also records it in ``results.json``.

        ``align``: one character per column, ``l`` or ``r`` (default: the first left, the
        rest right).
        """
        align = align or ("l" + "r" * (len(header) - 1))
        lines = ["| " + " | ".join(header) + " |",
                 "|" + "|".join("---" if a == "l" else "---:" for a in align) + "|"]
        lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
        self.blocks.append("\n".join(lines) + "\n")
        if key is not None:
            self.results[key] = {"header": list(header),
                                 "rows": [[_jsonable(c) for c in row] for row in rows]}

    def compare(self, key: str, rows: Sequence[Row], *, title: str | None = None,
                note: str = "", decimals: int = 2) -> None:
        """A side-by-side table: quantity, the paper's figure, ours (mean and 95 % interval
        over the seeds), verdict; recorded under ``key`` in ``results.json``."""
        if title:
            self.blocks.append(f"**{title}**\n")
        n = len(self.seeds)
        ours = f"geoblock (mean, 95 % CI over {n} seed{'s' if n > 1 else ''})"
        lines = ["| quantity | paper | " + ours + " | verdict |", "|---|---:|---:|---|"]
        lines += ["| " + " | ".join(r.cells(decimals)) + " |" for r in rows]
        self.blocks.append("\n".join(lines) + "\n")
        if note:
            self.text(note)
        self.results[key] = [r.to_json() for r in rows]

    def finding(self, key: str, statement: str, reproduced: bool | None,
                evidence: str) -> Finding:
        """Record a paper's finding and whether it reproduced (listed first in the report)."""
        found = Finding(key, statement, reproduced, evidence)
        self.findings.append(found)
        return found

    def figure(self, fig: Any, filename: str, caption: str, *, dpi: int = 120) -> Path:
        """Save a matplotlib figure as ``outdir/filename`` (PNG) and show it here."""
        make_directory(self.outdir)
        path = save_figure(fig, self.outdir / filename, dpi=dpi)
        self.figures.append(path)
        self.blocks.append(f"![{caption}]({filename})\n\n*{caption}*\n")
        return path

    def record(self, key: str, value: Any) -> None:
        """Any JSON-able value (numpy arrays and scalars included) into ``results.json``."""
        self.results[key] = _jsonable(value)

    def markdown(self, seconds: float | None = None) -> str:
        """The whole ``report.md``."""
        head = [f"# geoblock experiment {self.name}: {self.title}\n",
                f"Paper: {self.citation}.\n",
                f"Variant: **{self.variant}**; {len(self.seeds)} repetition(s) over seeds "
                f"{', '.join(str(s) for s in self.seeds)}. Intervals are 95 % Student-t "
                "intervals of the mean over the seeds."
                + (f" Run time: {seconds:.0f} s." if seconds is not None else "") + "\n"]
        if self.findings:
            lines = ["| finding (paper) | here | evidence |", "|---|---|---|"]
            lines += [f"| {f.statement} | {f.verdict} | {f.evidence} |" for f in self.findings]
            head += ["## Findings\n", "\n".join(lines) + "\n"]
        return "\n".join(head + self.blocks)

    def write(self, seconds: float | None = None) -> dict[str, Path]:
        """Write ``report.md`` and ``results.json`` into ``outdir`` (figures are written by
        :meth:`figure`)."""
        make_directory(self.outdir)
        report = write_text(self.outdir / "report.md", self.markdown(seconds))
        data = {"experiment": self.name, "title": self.title, "citation": self.citation,
                "variant": self.variant, "seeds": list(self.seeds),
                "seconds": _num(seconds) if seconds is not None else None,
                "findings": [{"key": f.key, "statement": f.statement,
                              "reproduced": f.reproduced, "evidence": f.evidence}
                             for f in self.findings],
                "results": self.results,
                "figures": [p.name for p in self.figures]}
        results = write_json(self.outdir / "results.json", data)
        return {"report": report, "results": results}


def _num(x: Any) -> float | None:
    x = float(x)
    return x if math.isfinite(x) else None


def _jsonable(value: Any) -> Any:
    if isinstance(value, Estimate | Row):
        return value.to_json()
    if isinstance(value, np.ndarray):
        return [_jsonable(v) for v in value.tolist()]
    if isinstance(value, np.generic):
        return _jsonable(value.item())
    if isinstance(value, float):
        return _num(value)
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_jsonable(v) for v in value]
    return value
