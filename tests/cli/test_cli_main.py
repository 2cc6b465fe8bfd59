"""The geoblock group: --help everywhere, --version, errors, warnings and the entry point."""

from __future__ import annotations

import warnings

import click
import pytest

from geoblock.cli.main import build_cli, main
from geoblock.errors import ConvergenceWarning
from geoblock.plugins import create_plugin_manager


def _commands(cli):
    with click.Context(cli) as ctx:
        return cli.list_commands(ctx)


def test_group_help_lists_builtin_commands(runner, cli):
    result = runner.invoke(cli, ["--help"])
    assert result.exit_code == 0, result.output
    for name in ("plugins", "info", "project", "backproject"):
        assert name in result.stdout
    assert "--verbose" in result.stdout and "--quiet" in result.stdout


def test_every_command_has_help_with_example(runner, cli):
    names = _commands(cli)
    assert {"plugins", "info", "project", "backproject"} <= set(names)
    for name in names:
        result = runner.invoke(cli, [name, "--help"])
        assert result.exit_code == 0, (name, result.output)
        assert f"Usage: geoblock {name}" in result.stdout, name
        if name in {"plugins", "info", "project", "backproject"}:
            assert "Example" in result.stdout, name
            assert cli.commands[name].get_short_help_str(), name


def test_version(runner, cli):
    import geoblock

    result = runner.invoke(cli, ["--version"])
    assert result.exit_code == 0
    assert result.stdout.strip() == f"geoblock {geoblock.__version__}"


def test_usage_error_keeps_click_behaviour(runner, cli):
    result = runner.invoke(cli, ["info"])
    assert result.exit_code == 2
    assert "Missing argument 'MODEL'" in result.stderr
    result = runner.invoke(cli, ["no-such-command"])
    assert result.exit_code == 2


def test_missing_model_file_is_one_line_error(runner, cli, tmp_path):
    missing = tmp_path / "missing.json"
    result = runner.invoke(cli, ["info", str(missing)])
    assert result.exit_code == 1
    lines = result.stderr.splitlines()
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("Error: ")
    assert "missing.json" in lines[0] and "does not exist" in lines[0]
    assert "Traceback" not in result.output


def test_verbose_shows_traceback(runner, cli, tmp_path):
    missing = str(tmp_path / "missing.json")
    result = runner.invoke(cli, ["--verbose", "info", missing])
    assert result.exit_code == 1
    assert "Traceback (most recent call last)" in result.stderr
    assert "GeoblockIOError" in result.stderr
    assert result.stderr.splitlines()[-1].startswith("Error: ")
    # the short flag, and the flag not leaking into the next invocation of the same group
    assert "Traceback" in runner.invoke(cli, ["-v", "info", missing]).stderr
    assert "Traceback" not in runner.invoke(cli, ["info", missing]).stderr


class _Commands:
    """A plugin adding commands that fail or warn."""

    __name__ = "fake-commands"

    def __init__(self):
        import geoblock

        @geoblock.hookimpl
        def geoblock_register_commands(cli):
            @cli.command()
            def crash():
                """Fail unexpectedly."""
                return 1 / 0

            @cli.command()
            def warn():
                """Warn twice, then succeed."""
                warnings.warn("3 of 10 points diverged", ConvergenceWarning, stacklevel=1)
                warnings.warn("something\nmulti-line", ConvergenceWarning, stacklevel=1)
                click.echo("done")

        self.geoblock_register_commands = geoblock_register_commands


@pytest.fixture
def fake_cli():
    return build_cli(create_plugin_manager(entry_points=False, plugins=[_Commands()]))


def test_unexpected_exception_is_one_line(runner, fake_cli):
    result = runner.invoke(fake_cli, ["crash"])
    assert result.exit_code == 1
    lines = result.stderr.splitlines()
    assert len(lines) == 1
    assert lines[0].startswith("Error: ZeroDivisionError: division by zero")
    assert "--verbose" in lines[0]
    result = runner.invoke(fake_cli, ["-v", "crash"])
    assert result.exit_code == 1
    assert "Traceback" in result.stderr and "1 / 0" in result.stderr


def test_warnings_are_one_line_each_and_quiet_drops_them(runner, fake_cli):
    result = runner.invoke(fake_cli, ["warn"])
    assert result.exit_code == 0, result.output
    assert result.stdout == "done\n"
    assert result.stderr.splitlines() == [
        "Warning: 3 of 10 points diverged",
        "Warning: something multi-line",
    ]
    result = runner.invoke(fake_cli, ["-q", "warn"])
    assert result.exit_code == 0
    assert result.stderr == ""
    assert result.stdout == "done\n"


def test_main_entry_point(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    assert capsys.readouterr().out.startswith("geoblock ")


def test_module_level_group_and_python_m(runner):
    import subprocess
    import sys

    from geoblock.cli.main import GeoblockGroup, cli

    assert isinstance(cli, GeoblockGroup)
    assert runner.invoke(cli, ["--version"]).exit_code == 0
    out = subprocess.run(
        [sys.executable, "-m", "geoblock.cli", "--version"],
        capture_output=True, text=True, check=True,
    )
    assert out.stdout.startswith("geoblock ")
