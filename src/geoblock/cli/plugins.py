"""``geoblock plugins``: the loaded plugins, their hooks, models and commands."""

from __future__ import annotations

import json
from typing import Any, Protocol, runtime_checkable

import click

from geoblock.cli.options import json_opt

__all__ = ["plugins", "plugins_report"]


@runtime_checkable
class _PluginCommands(Protocol):
    """What ``geoblock plugins`` asks of the root group (a
    :class:`~geoblock.cli.main.GeoblockGroup`, which imports this module: no import back)."""

    plugin_commands: dict[str, list[str]]
    broken_plugins: dict[str, str]

    @property
    def explicit_plugin_manager(self) -> Any: ...

    def load_plugin_commands(self) -> None: ...


def plugins_report(group: click.Command | None) -> dict[str, Any]:
    """What ``geoblock plugins --json`` prints.

    ``{"plugins": [{name, distribution, version, hooks, models, commands, error}],
    "models": [{name, plugin}]}``, plugins and models sorted by name. ``error`` is ``null``
    unless the plugin's ``geoblock_register_commands`` failed. ``group`` is the root
    ``geoblock`` group, whose plugin commands and plugin manager are listed (another command
    or None: the process-wide plugin manager, no commands).
    """
    from geoblock.plugins import list_plugins

    pm = None
    commands: dict[str, list[str]] = {}
    broken: dict[str, str] = {}
    if isinstance(group, _PluginCommands):
        group.load_plugin_commands()
        pm = group.explicit_plugin_manager
        commands, broken = group.plugin_commands, group.broken_plugins
    infos = list_plugins(pm)
    return {
        "plugins": [
            {
                "name": info.name,
                "distribution": info.distribution,
                "version": info.version,
                "hooks": list(info.hooks),
                "models": list(info.models),
                "commands": list(commands.get(info.name, ())),
                "error": broken.get(info.name),
            }
            for info in infos
        ],
        "models": sorted(
            ({"name": m, "plugin": info.name} for info in infos for m in info.models),
            key=lambda item: item["name"],
        ),
    }


def _table(header: list[str], rows: list[list[str]]) -> list[str]:
    widths = [max(len(r[i]) for r in [header, *rows]) for i in range(len(header))]
    return [
        "  ".join(cell.ljust(w) for cell, w in zip(row, widths, strict=True)).rstrip()
        for row in [header, *rows]
    ]


def format_report(report: dict[str, Any]) -> str:
    """The human-readable tables of ``geoblock plugins``."""
    lines: list[str] = []
    plugin_rows = [
        [
            p["name"],
            p["distribution"] or "-",
            p["version"] or "-",
            ", ".join(h.removeprefix("geoblock_") for h in p["hooks"]) or "-",
        ]
        for p in report["plugins"]
    ]
    lines += _table(["PLUGIN", "DISTRIBUTION", "VERSION", "HOOKS (geoblock_*)"], plugin_rows)
    lines.append("")
    model_rows = [[m["name"], m["plugin"]] for m in report["models"]]
    if model_rows:
        lines += _table(["MODEL", "PLUGIN"], model_rows)
    else:
        lines.append("No sensor models are registered: install a plugin (geoblock-rpc, ...).")
    command_rows = [[c, p["name"], ""] for p in report["plugins"] for c in p["commands"]]
    command_rows += [
        [p["name"], p["name"], f"broken: {p['error']}"] for p in report["plugins"] if p["error"]
    ]
    if command_rows:
        lines.append("")
        lines += _table(["COMMAND", "PLUGIN", "NOTE"], command_rows)
    return "\n".join(lines)


@click.command(short_help="List plugins, their hooks, models and commands.")
@json_opt
@click.pass_context
def plugins(ctx: click.Context, as_json: bool) -> None:
    """List the loaded plugins and the sensor models they register.

    For each plugin: its name, distribution, version and the geoblock hooks it implements;
    then every registered model name (what 'geoblock info --model-type NAME' and
    'geoblock.open_model(path, model=NAME)' accept) with the plugin providing it, and the
    commands plugins add to this command line. GEOBLOCK_PLUGINS=a,b restricts which
    entry points load; GEOBLOCK_PLUGIN_MODULES=pkg.mod,... loads extra plugin modules by
    import name (e.g. geoblock.testing.plugin, the test kit's synthetic models).

    \b
    Examples:
      geoblock plugins
      geoblock plugins --json | jq -r '.models[].name'
    """
    report = plugins_report(ctx.find_root().command)
    if as_json:
        click.echo(json.dumps(report, indent=2))
    else:
        click.echo(format_report(report))
