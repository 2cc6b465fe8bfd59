"""The command-line reference (docs/user-guide/cli.md) is generated from the click commands.

The page holds a ``::: mkdocs-click`` directive over the whole ``geoblock`` group (mkdocs-click
documents every subcommand, recursively), so a new command is documented by construction;
these tests keep the directive there and check that every command ``geoblock --help`` lists
comes out of it. The group loads plugin commands lazily, and mkdocs-click reads its loaded
commands only: the docs build's hook (docs/hooks/click_reference.py, listed in mkdocs.yml)
loads them first, and so do these tests. Each command's own page is checked by
tests/test_docs_commands.py.
"""

from __future__ import annotations

import importlib.util
import re
from pathlib import Path

import click
import pytest
from click.testing import CliRunner

from geoblock.cli.main import BrokenCommand, build_cli

ROOT = Path(__file__).resolve().parents[1]
CLI_MD = ROOT / "docs" / "user-guide" / "cli.md"
HOOK = ROOT / "docs" / "hooks" / "click_reference.py"


def _run_docs_hook() -> None:
    """What the docs build does before rendering: docs/hooks/click_reference.py's on_config."""
    spec = importlib.util.spec_from_file_location("click_reference_hook", HOOK)
    assert spec is not None and spec.loader is not None
    hook = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(hook)
    hook.on_config({})


def _directives(text: str) -> list[dict[str, str]]:
    """The options of each ``::: mkdocs-click`` block of a page."""
    blocks = []
    lines = text.splitlines()
    for k, line in enumerate(lines):
        if line.strip() == "::: mkdocs-click":
            options = {}
            for option in lines[k + 1:]:
                m = re.match(r"^\s+:(\w+):\s*(.*?)\s*$", option)
                if not m:
                    break
                options[m.group(1)] = m.group(2)
            blocks.append(options)
    return blocks


def _command_paths(group: click.Group, prefix: str = "geoblock") -> list[str]:
    """``geoblock CMD [SUB...]`` of every command under ``group`` (plugins' included)."""
    paths = []
    with click.Context(group, info_name=prefix) as ctx:
        for name in group.list_commands(ctx):
            command = group.get_command(ctx, name)
            if command is None or isinstance(command, BrokenCommand) or command.hidden:
                continue
            paths.append(f"{prefix} {name}")
            if isinstance(command, click.Group):
                paths += _command_paths(command, f"{prefix} {name}")
    return paths


def _help_commands() -> list[str]:
    """The command names ``geoblock --help`` lists."""
    result = CliRunner().invoke(build_cli(), ["--help"])
    assert result.exit_code == 0, result.output
    section = result.stdout.split("Commands:", 1)[1]
    return re.findall(r"^  (\S+)", section, flags=re.MULTILINE)


def test_cli_md_generates_the_reference_of_the_whole_group():
    directives = _directives(CLI_MD.read_text(encoding="utf-8"))
    assert len(directives) == 1, directives
    options = directives[0]
    assert options["module"] == "geoblock.cli.main"
    assert options["command"] == "cli"  # the group itself: every subcommand, recursively
    assert options["prog_name"] == "geoblock"
    import geoblock.cli.main

    assert isinstance(geoblock.cli.main.cli, click.Group)


def test_the_docs_build_runs_the_hook_that_loads_plugin_commands():
    config = (ROOT / "mkdocs.yml").read_text(encoding="utf-8")
    assert re.search(r"^hooks:\n(?:\s+- .*\n)*\s+- docs/hooks/click_reference.py$", config,
                     re.MULTILINE), "mkdocs.yml must list docs/hooks/click_reference.py in hooks"


def test_every_command_in_help_is_in_the_generated_reference():
    pytest.importorskip("mkdocs_click")
    import markdown

    _run_docs_hook()
    html = markdown.markdown(CLI_MD.read_text(encoding="utf-8"),
                             extensions=["attr_list", "toc", "mkdocs-click"])
    documented = set(re.findall(r'<h\d id="(geoblock(?:-[\w-]+)?)"', html))
    names = _help_commands()
    assert len(names) >= 12 and {"ortho", "mosaic", "demo", "dem-info"} <= set(names)
    missing = [n for n in names if f"geoblock-{n}" not in documented]
    assert not missing, f"commands of 'geoblock --help' missing from cli.md: {missing}"
    paths = _command_paths(build_cli())
    missing = [p for p in paths if p.replace(" ", "-") not in documented]
    assert not missing, f"commands missing from cli.md: {missing}"
    # each command's options come from click: the demo's --force help is on the page
    assert "previous" in html and "--no-progress" in html
