"""One grammar across all commands: every option is spelled one way and means one thing.

Walks every command of ``geoblock`` (the plugins' included) against the glossary
:data:`geoblock.cli.grammar.OPTIONS`: a concept spelled two ways (a retired spelling shown, an
option missing from the glossary) or one name with two meanings (different values between
commands) fails here.
"""

from __future__ import annotations

from pathlib import Path

import click
import pytest
from click.testing import CliRunner

from geoblock.cli.grammar import OPTIONS, RETIRED, grammar_table
from geoblock.cli.main import build_cli

DOCS = Path(__file__).resolve().parents[2] / "docs"

#: names whose values legitimately differ between commands: the meaning is one (see the
#: glossary) but each command has its own range (the order of its own polynomial, ...)
VARIES = {"--order", "--crs", "--output", "--variant", "--seed", "--image-id"}


def _commands() -> dict[str, click.Command]:
    cli = build_cli()
    ctx = click.Context(cli)
    return {name: cli.get_command(ctx, name) for name in cli.list_commands(ctx)}


def _options(command: click.Command) -> list[click.Option]:
    return [p for p in command.params if isinstance(p, click.Option) and not p.hidden]


def _names(option: click.Option) -> list[str]:
    return [n for n in option.opts if n.startswith("--") or n == "-k"]


def _signature(option: click.Option) -> tuple[object, ...]:
    kind = type(option.type).__name__
    choices = tuple(getattr(option.type, "choices", ()) or ())
    return kind, choices, option.nargs, option.is_flag, option.metavar


COMMANDS = _commands()


def test_every_command_is_walked():
    # the built-in commands and the plugins' (an empty walk would pass everything)
    for name in ("ortho", "mosaic", "localize", "match", "adjust", "export-rpc", "fit-rfm",
                 "experiment", "dem-info", "refine"):
        assert name in COMMANDS


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_every_option_is_in_the_glossary(name):
    unknown = [n for o in _options(COMMANDS[name]) for n in _names(o)
               if n not in OPTIONS and n != "--help"]
    assert not unknown, (
        f"geoblock {name}: {unknown} not in geoblock.cli.grammar.OPTIONS: use the spelling "
        "of the concept there, or add the new concept with its one meaning")


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_no_retired_spelling_is_shown(name):
    shown = [n for o in _options(COMMANDS[name]) for n in o.opts + o.secondary_opts
             if n in RETIRED]
    assert not shown, f"geoblock {name} shows retired spellings {shown}: see RETIRED"


def test_one_name_one_meaning():
    seen: dict[str, tuple[str, tuple[object, ...]]] = {}
    clashes = []
    for cmd_name, command in COMMANDS.items():
        for option in _options(command):
            for name in _names(option):
                if name in VARIES:
                    continue
                sig = _signature(option)
                if name in seen and seen[name][1] != sig:
                    clashes.append(f"{name}: {seen[name][0]} {seen[name][1]} vs "
                                   f"{cmd_name} {sig}")
                seen.setdefault(name, (cmd_name, sig))
    assert not clashes, "one option, different values:\n" + "\n".join(clashes)


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_aliases_lead_to_a_shown_option(name):
    command = COMMANDS[name]
    aliases = getattr(command, "deprecated_aliases", {})
    shown = {n for o in _options(command) for n in o.opts + o.secondary_opts}
    for old, new in aliases.items():
        target = new if isinstance(new, str) else new[0]
        assert target in shown, f"geoblock {name}: alias {old} -> {target}, not an option"
        assert old not in shown, f"geoblock {name}: {old} is both shown and an alias"


def test_spellings_changed_by_this_grammar_are_kept_as_aliases():
    # the old spellings users have in their scripts, command by command
    expected = {
        "localize": {"--vertical", "--model", "--nodata", "--interpolation", "--method",
                     "--tolerance"},
        "dem-info": {"--vertical"},
        "info": {"--model"}, "project": {"--model"}, "backproject": {"--model"},
        "refine": {"--model", "--ground", "--image"}, "export-rpc": {"--model"},
        "adjust": {"--out"}, "match": {"--id", "--sigma"},
        "demo": {"--force", "--size"}, "simulate": {"--force"}, "experiment": {"--full"},
    }
    for name, old in expected.items():
        assert old <= set(getattr(COMMANDS[name], "deprecated_aliases", {})), name


def test_a_deprecated_spelling_still_works_and_warns(tmp_path):
    runner = CliRunner()
    cli = build_cli()
    new = runner.invoke(cli, ["dem-info", "const:100", "--dem-vertical", "ellipsoid", "--json"])
    old = runner.invoke(cli, ["dem-info", "const:100", "--vertical=ellipsoid", "--json"])
    assert new.exit_code == 0, new.output
    assert old.exit_code == 0, old.output
    assert "'geoblock dem-info --vertical' is deprecated" in old.stderr
    assert "use --dem-vertical" in old.stderr
    assert old.stdout == new.stdout
    # a retired flag standing for an option and its value
    from geoblock.cli.options import _rewrite

    with pytest.warns(FutureWarning, match="use --variant full"):
        assert _rewrite(["teo2010", "--full", "--", "--full"], {"--full": ("--variant", "full")},
                        "experiment") == ["teo2010", "--variant", "full", "--", "--full"]


def test_the_docs_print_the_glossary():
    page = (DOCS / "user-guide" / "cli.md").read_text(encoding="utf-8")
    assert grammar_table() in page, (
        "docs/user-guide/cli.md must hold geoblock.cli.grammar.grammar_table() verbatim: "
        "paste its output there")
