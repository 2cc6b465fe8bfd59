"""mkdocs hook: the command reference (mkdocs-click) shows every command, plugins' included.

Two things stand between ``geoblock --help`` and what mkdocs-click renders from the
``geoblock.cli.main.cli`` group, and this hook (``hooks:`` in mkdocs.yml) removes both before
any page is rendered:

* The group loads plugin commands lazily, when it first lists or resolves a command, and
  mkdocs-click reads the group's ``commands`` dict directly: without
  ``cli.load_plugin_commands()`` the plugin commands (``fit-rfm``, ``export-rpc``,
  ``experiment``, ...) would be missing from the generated reference.
* mkdocs-click renders a command's help text as Markdown, while click help is plain text: a
  bracketed optional item followed by another (``row, col[, sigma][, kind]``) reads as a
  Markdown reference link, which mkdocs-autorefs then reports as an unknown cross-reference
  in the strict build. Escaping the second bracket (``]\\[``) renders the same characters.
"""

from __future__ import annotations

from typing import Any


def _escape_reference_links(text: str | None) -> str | None:
    return None if text is None else text.replace("][", "]\\[")


def on_config(config: Any) -> Any:
    """Load the plugin commands into the group mkdocs-click documents; escape ``][``."""
    import click

    from geoblock.cli.main import cli

    cli.load_plugin_commands()
    with click.Context(cli) as ctx:
        for name in cli.list_commands(ctx):
            command = cli.get_command(ctx, name)
            if command is not None:
                command.help = _escape_reference_links(command.help)
    return config
