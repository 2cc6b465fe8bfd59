"""The README's quickstart runs as written."""

import re
from pathlib import Path

README = Path(__file__).resolve().parents[1] / "README.md"


def test_quickstart_runs(tmp_path, monkeypatch, capsys):
    """As a user runs it: without the test suite's opt-in synthetic models."""
    import geoblock.testing
    from geoblock.plugins import PLUGIN_MODULES_VARIABLE

    code = re.search(r"```python\n(.*?)```", README.read_text(), re.S).group(1)
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv(PLUGIN_MODULES_VARIABLE, raising=False)
    geoblock.testing.disable_synthetic_models()
    try:
        exec(compile(code, str(README), "exec"), {})
    finally:
        geoblock.testing.enable_synthetic_models()
    out = capsys.readouterr().out
    assert "converged" in out and "a0" in out
    assert (tmp_path / "scene.json").is_file()


def test_setup_commands_match_ci():
    text = README.read_text()
    ci = (README.parent / ".ci" / "run").read_text()
    test_command = next(line for line in text.splitlines()
                        if "requirements-dev.txt" in line and "pytest" in line)
    assert test_command.strip() in ci


def test_first_command_runs_the_demo_and_ci_smoke_runs_it():
    text = README.read_text()
    ci = (README.parent / ".ci" / "run").read_text()
    first = next(line for line in text.splitlines() if "requirements.txt" in line
                 and "pip install" in line)
    assert first.strip().endswith(".venv/bin/geoblock demo")
    assert '.venv/bin/geoblock demo "$(mktemp -d)"' in ci
