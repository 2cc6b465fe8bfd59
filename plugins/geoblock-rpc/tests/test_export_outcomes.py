"""``geoblock export-rpc``: its ``--help`` lists every outcome the command can print.

The outcomes have one source, :class:`geoblock_rpc.export.ExportOutcome`: the line the
command prints after ``OUT (FORMAT):`` starts with one of them (checked here by running each
case), and the help's list of outcomes must hold each, and nothing else (issue 25: the help
listed three while the command also printed "refitted").
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from click.testing import CliRunner
from geoblock_rpc import RpcModel
from geoblock_rpc.export import ExportOutcome

import geoblock
from geoblock.cli.main import build_cli
from geoblock.models.linescan import LinescanModel

#: the sentence of the help that introduces the list of outcomes
INTRO = "One line says which happened"


def _help_outcomes() -> list[str]:
    """The lines of ``geoblock export-rpc --help``'s list of outcomes: the paragraph after
    the one that introduces it."""
    result = CliRunner().invoke(build_cli(), ["export-rpc", "--help"])
    assert result.exit_code == 0, result.output
    paragraphs = [p.splitlines() for p in re.split(r"\n\s*\n", result.stdout)]
    intro = next(k for k, p in enumerate(paragraphs) if INTRO in " ".join(" ".join(p).split()))
    return [line.strip() for line in paragraphs[intro + 1]]


def _outcome(line: str) -> ExportOutcome | None:
    """The outcome a line starts with (its words followed by a space, '(' or ':')."""
    for outcome in ExportOutcome:
        rest = line[len(outcome.value):]
        if line.startswith(outcome.value) and rest[:1] in (" ", "(", ":"):
            return outcome
    return None


def test_the_help_lists_every_outcome_and_only_those():
    listed = _help_outcomes()
    found = [_outcome(line) for line in listed]
    assert None not in found, f"a help line that is no ExportOutcome: {listed}"
    missing = [o.value for o in ExportOutcome if o not in found]
    assert not missing, f"outcomes the command can print, missing from its --help: {missing}"
    assert len(found) == len(set(found)) == len(ExportOutcome), listed


def _printed(tmp_path: Path, model, name: str) -> ExportOutcome | None:
    source = geoblock.write_model(model, tmp_path / f"{name}.json")
    out = tmp_path / f"{name}_RPC.TXT"
    result = CliRunner().invoke(build_cli(), ["export-rpc", str(source), str(out)])
    assert result.exit_code == 0, result.output
    prefix = f"{out} (rpc-txt): "
    assert result.stdout.startswith(prefix), result.stdout
    return _outcome(result.stdout[len(prefix):])


#: a model of each case the write hook reports, and the outcome printed
CASES = {
    "rpc": (lambda: RpcModel.example(), ExportOutcome.WRITTEN),
    "rpcv0": (lambda: geoblock.ImageCorrection(RpcModel.example(), 0, [2.5, -1.25]),
              ExportOutcome.FOLDED),
    "order2": (lambda: geoblock.ImageCorrection(
        RpcModel.example(), 2,
        [1.0, 0.5, -0.3, 0.2, -0.1, 0.05, -1.0, 0.2, 0.4, -0.1, 0.1, 0.02]),
        ExportOutcome.REFITTED),
    "linescan": (lambda: LinescanModel.example(), ExportOutcome.FITTED),
}


@pytest.mark.parametrize("name", sorted(CASES))
def test_the_command_prints_the_outcome_of_each_case(tmp_path, name):
    make, expected = CASES[name]
    assert _printed(tmp_path, make(), name) is expected


def test_another_plugins_writer_is_said(tmp_path, monkeypatch):
    """When another plugin's writer answers the write hook first, there is no export report."""
    import geoblock.io

    def foreign_writer(model, path, format=None, **options):
        Path(path).write_text("written by someone else\n")
        return Path(path)

    monkeypatch.setattr(geoblock.io, "write_model", foreign_writer)
    printed = _printed(tmp_path, LinescanModel.example(), "foreign")
    assert printed is ExportOutcome.OTHER_WRITER
