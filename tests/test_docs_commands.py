"""Every command has its documentation page (docs/commands/).

The Commands index (docs/commands/index.md) has one table row per command, ``geoblock NAME``
in its first cell and a link to the command's page: ``docs/commands/NAME.md``, or the user
guide's page when a guide is that command's page (``geoblock demo``: the demo's guide). So a
new command, a plugin's included, fails here until it has a row and a page. The pages under
docs/commands/ end with the reference generated (mkdocs-click) from the very command object
``geoblock NAME`` runs, and every one of them is in the site's navigation.
"""

from __future__ import annotations

import importlib
import re
from pathlib import Path

import click
import pytest
from click.testing import CliRunner

from geoblock.cli.main import BrokenCommand, build_cli

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
COMMANDS = DOCS / "commands"
INDEX = COMMANDS / "index.md"

_ROW = re.compile(r"^\|\s*`geoblock ([\w-]+)`\s*\|.*\[[^\]]*\]\(([^)#]+)(?:#[^)]*)?\)\s*\|\s*$",
                  re.MULTILINE)
_CLICK = re.compile(r"^::: mkdocs-click[ \t]*\n((?:[ \t]+:\w+:.*\n?)*)", re.MULTILINE)


def _help_commands() -> list[str]:
    """The command names ``geoblock --help`` lists (plugin commands included)."""
    result = CliRunner().invoke(build_cli(), ["--help"])
    assert result.exit_code == 0, result.output
    section = result.stdout.split("Commands:", 1)[1]
    return re.findall(r"^  (\S+)", section, flags=re.MULTILINE)


def _index_pages() -> dict[str, Path]:
    """Command name -> the page its row in the Commands index links to."""
    rows = _ROW.findall(INDEX.read_text(encoding="utf-8"))
    pages = {name: (COMMANDS / link).resolve() for name, link in rows}
    assert len(pages) == len(rows), "a command has two rows in docs/commands/index.md"
    return pages


def _commands() -> dict[str, click.Command]:
    cli = build_cli()
    with click.Context(cli, info_name="geoblock") as ctx:
        commands = {name: cli.get_command(ctx, name) for name in cli.list_commands(ctx)}
    return {name: cmd for name, cmd in commands.items()
            if cmd is not None and not isinstance(cmd, BrokenCommand)}


HELP_COMMANDS = _help_commands()


def test_help_lists_the_commands_of_core_and_plugins():
    assert {"ortho", "mosaic", "adjust", "project", "plugins"} <= set(HELP_COMMANDS)
    # the run set's plugin commands (geoblock-rpc, geoblock-papers) are installed in the tests
    assert {"fit-rfm", "export-rpc", "experiment"} <= set(HELP_COMMANDS)


@pytest.mark.parametrize("name", HELP_COMMANDS)
def test_every_command_has_a_page(name):
    pages = _index_pages()
    assert name in pages, (
        f"'geoblock {name}' has no row in docs/commands/index.md: add one linking to its page "
        f"(docs/commands/{name}.md: what it does, usage, examples, errors, the generated "
        f"reference)")
    page = pages[name]
    assert page.is_file(), f"docs/commands/index.md links 'geoblock {name}' to missing {page}"
    text = page.read_text(encoding="utf-8")
    assert f"geoblock {name}" in text, f"{page} never mentions 'geoblock {name}'"


PAGES = sorted(p.name for p in COMMANDS.glob("*.md") if p.name != "index.md")


@pytest.mark.parametrize("page", PAGES)
def test_command_pages_end_with_the_generated_reference_of_their_command(page):
    name = page.removesuffix(".md")
    commands = _commands()
    assert name in commands, f"docs/commands/{page} documents no command 'geoblock {name}'"
    text = (COMMANDS / page).read_text(encoding="utf-8")
    assert text.startswith(f"# `geoblock {name}`\n"), f"{page}: title should be `geoblock {name}`"
    blocks = _CLICK.findall(text)
    assert len(blocks) == 1, f"{page}: one '::: mkdocs-click' directive expected, at the end"
    assert text.rstrip().endswith(blocks[0].rstrip()), f"{page}: the reference comes last"
    options = dict(re.findall(r":(\w+):\s*(.*?)\s*$", blocks[0], re.MULTILINE))
    command = getattr(importlib.import_module(options["module"]), options["command"])
    assert command is commands[name], (
        f"{page}: the directive documents {options['module']}.{options['command']}, not the "
        f"command 'geoblock {name}' runs")
    assert options["prog_name"] == f"geoblock {name}"


def test_command_pages_are_in_the_navigation():
    nav = (ROOT / "mkdocs.yml").read_text(encoding="utf-8")
    missing = [p.name for p in COMMANDS.glob("*.md") if f"commands/{p.name}" not in nav]
    assert not missing, f"docs/commands pages missing from mkdocs.yml's nav: {missing}"


def test_the_index_links_only_to_existing_commands():
    stale = sorted(set(_index_pages()) - set(_commands()))
    assert not stale, f"docs/commands/index.md lists commands that do not exist: {stale}"
