"""The built-in commands load when they run: ``geoblock --help`` lists them from
:data:`geoblock.cli.main.BUILTIN_COMMANDS` without importing their modules, and shows exactly
what the loaded commands would show."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap

import click
import pytest

from geoblock.cli.main import BUILTIN_COMMANDS, LazyCommand, build_cli


def _help(cli: click.Group, width: int) -> str:
    with click.Context(cli, info_name="geoblock", terminal_width=width,
                       max_content_width=width) as ctx:
        return cli.get_help(ctx)


@pytest.mark.parametrize("width", [40, 80, 200])
def test_help_of_stand_ins_is_the_help_of_the_loaded_commands(width):
    lazy = build_cli()
    before = _help(lazy, width)
    assert any(isinstance(c, LazyCommand) for c in lazy.commands.values())
    loaded = build_cli()
    with click.Context(loaded) as ctx:
        for name in loaded.list_commands(ctx):
            loaded.get_command(ctx, name)
    assert not any(isinstance(c, LazyCommand) for c in loaded.commands.values())
    assert _help(loaded, width) == before
    for name in BUILTIN_COMMANDS:
        assert name in before


@pytest.mark.parametrize("name", sorted(BUILTIN_COMMANDS))
def test_table_matches_the_command(name):
    module, attribute, short_help = BUILTIN_COMMANDS[name]
    cli = build_cli()
    with click.Context(cli) as ctx:
        command = cli.get_command(ctx, name)
    assert command is not None and not isinstance(command, LazyCommand)
    assert command.name == name
    assert command.callback is not None and command.callback.__module__ == module
    assert command.get_short_help_str(10**6) == short_help
    assert not command.hidden and not command.deprecated  # the stand-in shows neither
    assert cli.commands[name] is command  # resolved once, then kept


def test_help_imports_no_command_module():
    """``geoblock --help`` imports none of the built-in command modules, nor numpy; running
    one command imports its module only."""
    code = textwrap.dedent("""
        import contextlib, io, json, sys
        from geoblock.cli.main import main
        for args in (["--help"], ["plugins", "--help"]):
            with contextlib.redirect_stdout(io.StringIO()):
                try:
                    main(args)
                except SystemExit:
                    pass
            print(json.dumps(sorted(m for m in sys.modules
                                    if m == "numpy" or m.startswith("geoblock.cli."))))
    """)
    env = {k: v for k, v in os.environ.items() if k != "GEOBLOCK_PLUGIN_MODULES"}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, env=env).stdout.strip().splitlines()
    after_help, after_plugins = json.loads(out[-2]), json.loads(out[-1])
    builtin = {m for m, _, _ in BUILTIN_COMMANDS.values()}
    assert not builtin & set(after_help)
    assert "numpy" not in after_help
    assert builtin & set(after_plugins) == {"geoblock.cli.plugins"}


def test_unknown_command_is_still_a_usage_error(runner):
    result = runner.invoke(build_cli(), ["no-such-command"])
    assert result.exit_code == 2
    assert "No such command" in result.output
