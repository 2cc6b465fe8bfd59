"""geoblock plugins, and plugin commands: added, isolated when broken, never replacing others."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import click
import pytest

import geoblock
from geoblock.cli.main import BrokenCommand, build_cli
from geoblock.plugins import create_plugin_manager


def test_plugins_table(runner, cli):
    result = runner.invoke(cli, ["plugins"])
    assert result.exit_code == 0, result.output
    assert "geoblock._default_plugin" in result.stdout
    assert "geoblock.testing.plugin" in result.stdout  # enabled for geoblock's tests
    assert "synthetic-affine" in result.stdout
    assert "image-correction" in result.stdout
    assert "register_sensor_models" in result.stdout


def test_plugins_json(runner, cli):
    result = runner.invoke(cli, ["plugins", "--json"])
    assert result.exit_code == 0, result.output
    report = json.loads(result.stdout)
    by_name = {p["name"]: p for p in report["plugins"]}
    default = by_name["geoblock._default_plugin"]
    assert default["distribution"] == "geoblock"
    assert default["version"] == geoblock.__version__
    assert "geoblock_register_sensor_models" in default["hooks"]
    assert {"image-correction", "linescan"} <= set(default["models"])
    assert not {"synthetic-affine", "synthetic-pushbroom"} & set(default["models"])
    assert default["error"] is None
    testing = by_name["geoblock.testing.plugin"]  # the opt-in test models, enabled in tests
    assert (testing["distribution"], testing["version"]) == ("geoblock", geoblock.__version__)
    assert testing["models"] == ["synthetic-affine", "synthetic-pushbroom"]
    models = {m["name"]: m["plugin"] for m in report["models"]}
    assert models["synthetic-affine"] == "geoblock.testing.plugin"
    assert models["image-correction"] == "geoblock._default_plugin"


def _plugins_json_in_a_new_process(**environ: str) -> dict:
    env = {k: v for k, v in os.environ.items() if k != "GEOBLOCK_PLUGIN_MODULES"}
    out = subprocess.run(
        [sys.executable, "-m", "geoblock.cli", "plugins", "--json"],
        capture_output=True, text=True, check=True, env={**env, **environ},
    )
    return json.loads(out.stdout)


def test_a_users_geoblock_plugins_lists_no_test_models():
    report = _plugins_json_in_a_new_process()
    models = {m["name"] for m in report["models"]}
    assert {"image-correction", "linescan"} <= models
    assert not {"synthetic-affine", "synthetic-pushbroom"} & models
    assert "geoblock.testing.plugin" not in {p["name"] for p in report["plugins"]}


def test_geoblock_plugin_modules_loads_the_test_models_in_a_new_process():
    report = _plugins_json_in_a_new_process(GEOBLOCK_PLUGIN_MODULES="geoblock.testing.plugin")
    models = {m["name"]: m["plugin"] for m in report["models"]}
    assert models["synthetic-affine"] == models["synthetic-pushbroom"] == "geoblock.testing.plugin"
    plugin = {p["name"]: p for p in report["plugins"]}["geoblock.testing.plugin"]
    assert plugin["distribution"] == "geoblock"
    assert plugin["hooks"] == ["geoblock_register_sensor_models"]


class _Hello:
    __name__ = "fake-hello"

    @geoblock.hookimpl
    def geoblock_register_commands(self, cli):
        @cli.command()
        @click.argument("who", default="world")
        def hello(who):
            """Say hello (a plugin command). Example: geoblock hello you"""
            click.echo(f"hello {who}")


class _Broken:
    __name__ = "fake-broken"

    @geoblock.hookimpl
    def geoblock_register_commands(self, cli):
        @cli.command()
        def half():
            """Added before the failure: rolled back."""

        raise RuntimeError("boom")


class _Hijacker:
    __name__ = "fake-hijacker"

    @geoblock.hookimpl
    def geoblock_register_commands(self, cli):
        @cli.command(name="info")
        def fake_info():
            """Pretend to be info."""
            click.echo("hijacked")


def _cli(*plugins):
    return build_cli(create_plugin_manager(entry_points=False, plugins=plugins))


def test_plugin_command_appears_and_runs(runner):
    cli = _cli(_Hello())
    result = runner.invoke(cli, ["--help"])
    assert result.exit_code == 0
    assert "hello" in result.stdout
    result = runner.invoke(cli, ["hello", "geoblock"])
    assert result.exit_code == 0, result.output
    assert result.stdout == "hello geoblock\n"
    report = json.loads(runner.invoke(cli, ["plugins", "--json"]).stdout)
    plugin = {p["name"]: p for p in report["plugins"]}["fake-hello"]
    assert plugin["commands"] == ["hello"]
    assert plugin["hooks"] == ["geoblock_register_commands"]
    assert "hello" in runner.invoke(cli, ["plugins"]).stdout


def test_broken_plugin_does_not_break_the_cli(runner, model_path):
    cli = _cli(_Broken(), _Hello())
    result = runner.invoke(cli, ["--help"])
    assert result.exit_code == 0, result.output
    assert "hello" in result.stdout  # the other plugin still works
    assert "half" not in result.stdout  # the broken plugin's partial work is rolled back
    assert "fake-broken" in result.stdout  # a stub says what is missing
    warning_lines = [ln for ln in result.stderr.splitlines() if ln.startswith("Warning:")]
    assert len(warning_lines) == 1
    assert "fake-broken" in warning_lines[0] and "RuntimeError: boom" in warning_lines[0]
    assert isinstance(cli.commands["fake-broken"], BrokenCommand)

    result = runner.invoke(cli, ["info", model_path])
    assert result.exit_code == 0, result.output
    assert "synthetic-affine" in result.stdout

    result = runner.invoke(cli, ["fake-broken", "--anything"])
    assert result.exit_code == 1
    assert result.stderr.splitlines()[-1] == (
        "Error: geoblock plugin 'fake-broken' failed to add its commands: RuntimeError: boom"
    )
    assert "raise RuntimeError" in runner.invoke(cli, ["-v", "fake-broken"]).stderr

    report = json.loads(runner.invoke(cli, ["plugins", "--json"]).stdout)
    broken = {p["name"]: p for p in report["plugins"]}["fake-broken"]
    assert broken["error"] == "RuntimeError: boom"
    assert "broken: RuntimeError: boom" in runner.invoke(cli, ["plugins"]).stdout


def test_quiet_hides_the_broken_plugin_warning(runner):
    result = runner.invoke(_cli(_Broken()), ["-q", "--help"])
    assert result.exit_code == 0
    assert result.stderr == ""


def test_plugin_cannot_replace_a_command(runner, model_path):
    cli = _cli(_Hijacker())
    result = runner.invoke(cli, ["info", model_path])
    assert result.exit_code == 0, result.output
    assert "hijacked" not in result.stdout
    assert "synthetic-affine" in result.stdout
    assert "fake-hijacker" in result.stderr and "'info'" in result.stderr


def test_default_cli_uses_the_patched_plugin_manager(runner, monkeypatch):
    pm = create_plugin_manager(entry_points=False, plugins=[_Hello()])
    monkeypatch.setattr("geoblock.plugins.get_plugin_manager", lambda: pm)
    result = runner.invoke(build_cli(), ["hello"])
    assert result.exit_code == 0, result.output
    assert result.stdout == "hello world\n"


@pytest.mark.parametrize("args", [["plugins"], ["plugins", "--json"]])
def test_plugins_without_models(runner, args, monkeypatch):
    monkeypatch.setattr("geoblock.plugins.DEFAULT_PLUGINS", ())
    cli = build_cli(create_plugin_manager(entry_points=False, plugins=[_Hello()], modules=()))
    result = runner.invoke(cli, args)
    assert result.exit_code == 0, result.output
    if "--json" in args:
        assert json.loads(result.stdout)["models"] == []
    else:
        assert "No sensor models are registered" in result.stdout
