"""The report of an experiment: our figures beside the paper's, table by table.

A :class:`Report` collects, in order, sections of text, side-by-side tables, plain tables,
figures and findings; :meth:`Report.write` writes ``report.md`` (the findings' summary
first), and ``results.json`` (every number in the tables, with the per-seed values); the
figures (PNG) are written as they are added.

Side-by-side tables come in two shapes:

* :meth:`Report.compare`: one line per quantity (:class:`Row`): the paper's figure, ours
  and a verdict;
* :meth:`Report.grid`: the paper's table layout (:class:`GridRow`: a label and one cell per
  column), each column split into the paper's figure as printed and ours.

An experiment that runs its set-up under several conditions (``teo2010``: two on-board error
models) shows them side by side: ``series=("realistic", "bias-drift")`` in
:meth:`Report.compare` and :meth:`Report.grid` gives one column of ours per series (the
first from ``Row.ours`` / ``GridRow.ours``, the others from their ``alt``), and a finding
may carry one verdict per series (:attr:`Finding.series`).

Our figures are :class:`Estimate` values: the per-seed values of a statistic, shown as their
mean and 95 % Student-t interval of the mean over the seeds.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from geoblock.adjust import confidence_interval
from geoblock.io.files import make_directory, save_figure, write_json, write_text
from geoblock_papers.registry import ExperimentError

__all__ = ["Estimate", "Finding", "GridRow", "Report", "Row", "estimate"]

#: what the report's figures may be called: a plain PNG file name, no directory
_FIGURE_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]*\.png")


@dataclass(frozen=True)
class Estimate:
    """A statistic over repeated seeds: its mean and 95 % Student-t interval of the mean.

    Attributes
    ----------
    values : tuple of float
        One value per seed (NaN: the run failed or the statistic is undefined for that seed;
        ignored by the statistics).
    unit : str
        E.g. ``"m"``, ``"px"`` or ``""``.
    """

    values: tuple[float, ...]
    unit: str = "m"

    @property
    def finite(self) -> np.ndarray:
        """(K,) the finite values."""
        v = np.asarray(self.values, dtype=float)
        return v[np.isfinite(v)]

    @property
    def mean(self) -> float:
        """Mean of the finite values (NaN if none)."""
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

    def format(self, decimals: int = 2, *, unit: bool = True) -> str:
        """``"5.21 m (4.80 to 5.62)"``: the mean and the 95 % interval of the mean, without
        the unit if not ``unit``. A single seed, or values all equal, show only the value; no
        finite value shows ``"failed"``."""
        if not self.finite.size:
            return "failed"
        text = f"{self.mean:.{decimals}f}" + (f" {self.unit}" if unit and self.unit else "")
        low, high = self.interval
        if math.isfinite(low) and high > low:
            text += f" ({low:.{decimals}f} to {high:.{decimals}f})"
        return text

    def __str__(self) -> str:
        return self.format()

    def to_json(self) -> dict[str, Any]:
        """``{"mean", "ci95": [low, high], "n", "unit", "values"}`` (NaN as null)."""
        low, high = self.interval
        return {"mean": _num(self.mean), "ci95": [_num(low), _num(high)],
                "n": int(self.finite.size), "unit": self.unit,
                "values": [_num(v) for v in self.values]}


def estimate(values: Iterable[float], unit: str = "m") -> Estimate:
    """An :class:`Estimate` of per-seed ``values``."""
    return Estimate(tuple(float(v) for v in values), unit)


def _ours(value: Estimate | str | float, decimals: int, unit: bool = True) -> str:
    if isinstance(value, Estimate):
        return value.format(decimals, unit=unit)
    if isinstance(value, float | int) and not isinstance(value, bool):
        return f"{value:.{decimals}f}" if math.isfinite(value) else "-"
    return str(value)


def _ours_json(value: Estimate | str | float) -> Any:
    if isinstance(value, Estimate):
        return value.to_json()
    if isinstance(value, float | int) and not isinstance(value, bool):
        return _num(value)
    return value


@dataclass(frozen=True)
class Row:
    """One line of a side-by-side table (:meth:`Report.compare`).

    Attributes
    ----------
    quantity : str
        What is compared, e.g. ``"ICTP RMSE strips 2-3, single (m)"``.
    paper : str
        The paper's figure as printed (``"28"``, ``"~0.2 px"``, ``"-"`` when it gives none).
    ours : Estimate or str or float
    verdict : str
        E.g. ``"reproduced"``, ``"not reproduced: ..."``, or empty.
    alt : sequence of Estimate or str or float
        Ours under the report's further series (:meth:`Report.compare` ``series``), in order.
    """

    quantity: str
    paper: str
    ours: Estimate | str | float
    verdict: str = ""
    alt: Sequence[Estimate | str | float] = ()

    def cells(self, decimals: int) -> list[str]:
        """The Markdown cells: quantity, paper, ours (then ``alt``), verdict."""
        return ([self.quantity, self.paper, _ours(self.ours, decimals)]
                + [_ours(v, decimals) for v in self.alt] + [self.verdict])

    def to_json(self, series: Sequence[str] = ()) -> dict[str, Any]:
        out: dict[str, Any] = {"quantity": self.quantity, "paper": self.paper,
                               "geoblock": _ours_json(self.ours), "verdict": self.verdict}
        if series:
            out["series"] = {name: _ours_json(v)
                             for name, v in zip(series, (self.ours, *self.alt), strict=True)}
        return out


@dataclass(frozen=True)
class GridRow:
    """One line of a side-by-side grid (:meth:`Report.grid`): the paper's table layout.

    Attributes
    ----------
    label : str
        The line's label, e.g. ``"MBA block ICTP"``.
    paper : sequence of str
        The paper's figure in each column as printed (``"-"`` where it gives none).
    ours : sequence of Estimate or str or float
        Ours in each column.
    alt : sequence of sequences
        Ours in each column under the report's further series (:meth:`Report.grid`
        ``series``), one sequence per series after the first.
    """

    label: str
    paper: Sequence[str]
    ours: Sequence[Estimate | str | float]
    alt: Sequence[Sequence[Estimate | str | float]] = ()

    def to_json(self, series: Sequence[str] = ()) -> dict[str, Any]:
        out: dict[str, Any] = {"label": self.label, "paper": list(self.paper),
                               "geoblock": [_ours_json(v) for v in self.ours]}
        if series:
            out["series"] = {name: [_ours_json(v) for v in cells] for name, cells
                             in zip(series, (self.ours, *self.alt), strict=True)}
        return out


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
    series : mapping of str to bool or None
        The verdict under each series of the experiment (e.g. on-board error model), when it
        runs several; ``reproduced`` is then the first series' verdict.
    """

    key: str
    statement: str
    reproduced: bool | None
    evidence: str
    series: Mapping[str, bool | None] = field(default_factory=dict)

    @property
    def verdict(self) -> str:
        """``"reproduced"``, ``"NOT reproduced"`` or ``"partly"``."""
        return _VERDICTS[self.reproduced]


_VERDICTS = {True: "reproduced", False: "NOT reproduced", None: "partly"}


def _cell(text: Any) -> str:
    """A Markdown table cell: pipes escaped, line breaks as spaces."""
    return " ".join(str(text).split("\n")).replace("|", "\\|")


@dataclass
class Report:
    """An experiment's report, filled by the experiment and written by :meth:`write`.

    Parameters
    ----------
    name, title, citation : str
    variant : str
        One of ``variants``.
    seeds : sequence of int
        At least one.
    outdir : pathlib.Path
        Where :meth:`figure` and :meth:`write` write.
    variants : sequence of str
        The experiment's variants (default ``("small", "full")``; the registry passes an
        experiment's own, e.g. teo2010's ``case2``).

    Raises
    ------
    ExperimentError
        An unknown variant or no seed.
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
    variants: Sequence[str] = ("small", "full")

    def __post_init__(self) -> None:
        if self.variant not in self.variants:
            raise ExperimentError(f"experiment {self.name}: variant must be one of "
                                  f"{', '.join(repr(v) for v in self.variants)}, got "
                                  f"{self.variant!r}")
        if not len(self.seeds):
            raise ExperimentError(f"experiment {self.name}: no seed to run")
        self.outdir = Path(self.outdir)

    def _key(self, key: str) -> str:
        if not key or key in self.results:
            raise ExperimentError(f"experiment {self.name}: results key {key!r} is empty or "
                                  "used twice")
        return key

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
        """A plain Markdown table (cells may be :class:`Estimate`); ``key`` also records it in
        ``results.json``.

        ``align``: one character per column, ``l`` or ``r`` (default: the first left, the
        rest right).

        Raises
        ------
        ExperimentError
            A row or ``align`` of another length than ``header``, or ``key`` used before.
        """
        align = align or ("l" + "r" * (len(header) - 1))
        if len(align) != len(header) or set(align) - {"l", "r"}:
            raise ExperimentError(f"experiment {self.name}: table {key or header[0]!r}: align "
                                  f"{align!r} must have one 'l' or 'r' per column "
                                  f"({len(header)})")
        for row in rows:
            if len(row) != len(header):
                raise ExperimentError(f"experiment {self.name}: table {key or header[0]!r}: "
                                      f"row {list(map(str, row))} has {len(row)} cells for "
                                      f"{len(header)} columns")
        if key is not None:
            self._key(key)
        lines = ["| " + " | ".join(_cell(h) for h in header) + " |",
                 "|" + "|".join("---" if a == "l" else "---:" for a in align) + "|"]
        lines += ["| " + " | ".join(_cell(c) for c in row) + " |" for row in rows]
        self.blocks.append("\n".join(lines) + "\n")
        if key is not None:
            self.results[key] = {"header": list(header),
                                 "rows": [[_jsonable(c) for c in row] for row in rows]}

    def compare(self, key: str, rows: Sequence[Row], *, title: str | None = None,
                note: str = "", decimals: int = 2, series: Sequence[str] = ()) -> None:
        """A side-by-side table: quantity, the paper's figure, ours (mean and 95 % interval
        over the seeds), verdict; recorded under ``key`` in ``results.json``.

        With ``series`` (two or more names), one column of ours per series: ``Row.ours`` the
        first, ``Row.alt`` the others; ``results.json`` gets each row's ``series`` too.

        Raises
        ------
        ExperimentError
            ``key`` used before, or a row whose ``alt`` does not match ``series``.
        """
        self._key(key)
        self._check_series(key, series, [(r.quantity, len(r.alt)) for r in rows])
        if title:
            self.blocks.append(f"**{title}**\n")
        ours = ([self._ours_header()] if not series else
                [f"geoblock, {name}" for name in series])
        lines = ["| quantity | paper | " + " | ".join(ours) + " | verdict |",
                 "|---|---:|" + "---:|" * len(ours) + "---|"]
        lines += ["| " + " | ".join(_cell(c) for c in r.cells(decimals)) + " |" for r in rows]
        self.blocks.append("\n".join(lines) + "\n")
        if series:
            self.text(f"geoblock: mean and 95 % interval over {len(self.seeds)} "
                      f"seed{'s' if len(self.seeds) > 1 else ''}, per series.")
        if note:
            self.text(note)
        self.results[key] = [r.to_json(series) for r in rows]

    def _check_series(self, key: str, series: Sequence[str],
                      rows: Sequence[tuple[str, int]]) -> None:
        if len(series) == 1:
            raise ExperimentError(f"experiment {self.name}: {key!r}: give two or more series "
                                  f"or none, got {list(series)}")
        want = max(len(series) - 1, 0)
        for label, alt in rows:
            if alt != want:
                raise ExperimentError(f"experiment {self.name}: {key!r}: row {label!r} has "
                                      f"{alt} further series for {want} ({list(series)})")

    def grid(self, key: str, columns: Sequence[str], rows: Sequence[GridRow], *,
             title: str | None = None, note: str = "", decimals: int = 2,
             label: str = "", series: Sequence[str] = ()) -> None:
        """A side-by-side table in the paper's layout: per column, the paper's figure as
        printed beside ours (mean and 95 % interval over the seeds, without units: give them
        in ``title``); recorded under ``key``.

        Parameters
        ----------
        key : str
        columns : sequence of str
            The paper's column headings, e.g. ``["strips 1&2 E", "strips 1&2 N"]``.
        rows : sequence of GridRow
            One cell per column in both ``paper`` and ``ours``.
        title, note : str
            Above and below the table.
        decimals : int
        label : str
            Heading of the label column.
        series : sequence of str
            Two or more names: each column shows the paper's figure then ours per series
            (``GridRow.ours`` the first, ``GridRow.alt`` the others).

        Raises
        ------
        ExperimentError
            A row whose ``paper``, ``ours`` or an ``alt`` has another length than
            ``columns``, ``alt`` not matching ``series``, or ``key`` used before.
        """
        self._key(key)
        self._check_series(key, series, [(r.label, len(r.alt)) for r in rows])
        for r in rows:
            if len(r.paper) != len(columns) or any(
                    len(o) != len(columns) for o in (r.ours, *r.alt)):
                raise ExperimentError(
                    f"experiment {self.name}: grid {key!r}: row {r.label!r} has "
                    f"{len(r.paper)} paper and {len(r.ours)} geoblock cells for "
                    f"{len(columns)} columns")
        if title:
            self.blocks.append(f"**{title}**\n")
        who = ["paper"] + ([f"geoblock {name}" for name in series] or ["geoblock"])
        header = [label] + [f"{c}: {w}" for c in columns for w in who]
        lines = ["| " + " | ".join(_cell(h) for h in header) + " |",
                 "|---|" + "---:|" * (len(who) * len(columns))]
        for r in rows:
            cells = [r.label]
            for k, paper in enumerate(r.paper):
                cells += [paper] + [_ours(o[k], decimals, unit=False) for o in (r.ours, *r.alt)]
            lines.append("| " + " | ".join(_cell(c) for c in cells) + " |")
        self.blocks.append("\n".join(lines) + "\n")
        if note:
            self.text(note)
        self.results[key] = {"columns": list(columns), "series": list(series),
                             "rows": [r.to_json(series) for r in rows]}

    def _ours_header(self) -> str:
        n = len(self.seeds)
        return f"geoblock (mean, 95 % CI over {n} seed{'s' if n > 1 else ''})"

    def finding(self, key: str, statement: str, reproduced: bool | None,
                evidence: str, *, series: Mapping[str, bool | None] | None = None) -> Finding:
        """Record a paper's finding and whether it reproduced (listed first in the report).

        ``series``: the verdict per series (two or more; the first must be ``reproduced``):
        the findings table then has one verdict column per series.

        Raises
        ------
        ExperimentError
            ``key`` used by another finding, or ``series`` inconsistent with the other
            findings' or with ``reproduced``.
        """
        if any(f.key == key for f in self.findings):
            raise ExperimentError(f"experiment {self.name}: finding {key!r} recorded twice")
        series = dict(series or {})
        names = list(series)
        if names and (len(names) < 2 or series[names[0]] is not reproduced):
            raise ExperimentError(f"experiment {self.name}: finding {key!r}: series {series} "
                                  f"must name two or more and start with the verdict "
                                  f"{reproduced}")
        if self.findings and list(self.findings[0].series) != names:
            raise ExperimentError(f"experiment {self.name}: finding {key!r}: series "
                                  f"{names} differ from the other findings' "
                                  f"{list(self.findings[0].series)}")
        found = Finding(key, statement, reproduced, evidence, series)
        self.findings.append(found)
        return found

    def figure(self, fig: Any, filename: str, caption: str, *, dpi: int = 120) -> Path:
        """Save a matplotlib figure as ``outdir/filename`` (PNG, cropped to its content:
        legends outside the axes included) and show it here.

        Raises
        ------
        ExperimentError
            ``filename`` is not a plain ``*.png`` name, or was used before.
        GeoblockIOError
            The file cannot be written.
        """
        if not _FIGURE_NAME.fullmatch(filename):
            raise ExperimentError(f"experiment {self.name}: figure name {filename!r} must be a "
                                  "plain file name ending in .png")
        if any(p.name == filename for p in self.figures):
            raise ExperimentError(f"experiment {self.name}: figure {filename!r} written twice")
        make_directory(self.outdir)
        path = save_figure(fig, self.outdir / filename, dpi=dpi, bbox_inches="tight")
        self.figures.append(path)
        self.blocks.append(f"![{caption}]({filename})\n\n*{caption}*\n")
        return path

    def record(self, key: str, value: Any) -> None:
        """Any JSON-able value (numpy arrays and scalars, :class:`Estimate` included) into
        ``results.json``.

        Raises
        ------
        ExperimentError
            ``key`` used before.
        """
        self.results[self._key(key)] = _jsonable(value)

    def markdown(self, seconds: float | None = None) -> str:
        """The whole ``report.md``."""
        head = [f"# geoblock experiment {self.name}: {self.title}\n",
                f"Paper: {self.citation}.\n",
                f"Variant: **{self.variant}**; {len(self.seeds)} repetition(s) over seeds "
                f"{', '.join(str(s) for s in self.seeds)}. Intervals are 95 % Student-t "
                "intervals of the mean over the seeds."
                + (f" Run time: {seconds:.0f} s." if seconds is not None else "") + "\n"]
        if self.findings:
            names = list(self.findings[0].series)
            if names:
                lines = ["| finding (paper) | " + " | ".join(f"here, {n}" for n in names)
                         + " | evidence |", "|---|" + "---|" * len(names) + "---|"]
                lines += [f"| {_cell(f.statement)} | "
                          + " | ".join(_VERDICTS[f.series[n]] for n in names)
                          + f" | {_cell(f.evidence)} |" for f in self.findings]
            else:
                lines = ["| finding (paper) | here | evidence |", "|---|---|---|"]
                lines += [f"| {_cell(f.statement)} | {f.verdict} | {_cell(f.evidence)} |"
                          for f in self.findings]
            head += ["## Findings\n", "\n".join(lines) + "\n"]
        return "\n".join(head + self.blocks)

    def write(self, seconds: float | None = None) -> dict[str, Path]:
        """Write ``report.md`` and ``results.json`` into ``outdir`` (figures are written by
        :meth:`figure`).

        Returns
        -------
        dict
            ``{"report": path, "results": path}``.

        Raises
        ------
        GeoblockIOError
            A file cannot be written, or a result is not JSON-able (names the file).
        """
        make_directory(self.outdir)
        report = write_text(self.outdir / "report.md", self.markdown(seconds))
        data = {"experiment": self.name, "title": self.title, "citation": self.citation,
                "variant": self.variant, "seeds": list(self.seeds),
                "seconds": _num(seconds) if seconds is not None else None,
                "findings": [{"key": f.key, "statement": f.statement,
                              "reproduced": f.reproduced, "evidence": f.evidence,
                              **({"series": dict(f.series)} if f.series else {})}
                             for f in self.findings],
                "results": self.results,
                "figures": [p.name for p in self.figures]}
        results = write_json(self.outdir / "results.json", data)
        return {"report": report, "results": results}


def _num(x: Any) -> float | None:
    x = float(x)
    return x if math.isfinite(x) else None


def _jsonable(value: Any) -> Any:
    if isinstance(value, Estimate | Row | GridRow):
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
