"""run_demo from Python: what it returns, --force's rule, refusal before any write."""

from __future__ import annotations

import pytest

from geoblock.errors import DemoOutdirError, ScenarioError
from geoblock.workflows import DEMO_MARKER, DemoResult, is_demo_outdir, run_demo


def test_run_demo_forced_into_a_foreign_directory(tmp_path):
    out = tmp_path / "work"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    messages: list[str] = []
    result = run_demo(out, size="tiny", force=True, progress=messages.append)
    assert isinstance(result, DemoResult) and result.outdir == out
    assert messages[0].startswith("[1/6]") and messages[-1].startswith("done in")
    assert result.report.read_text().startswith("# geoblock demo\n")
    assert result.quicklook.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert result.mosaic == out / "mosaic.tif" and (out / "contribution.tif").is_file()
    assert sorted(result.orthos) == ["strip1", "strip2", "strip3"]
    assert all(p.parent == out / "orthos" and p.is_file() for p in result.orthos.values())
    assert result.scenario.outdir == out / "block"
    assert result.scenario.files["block"] == out / "block" / "block.toml"
    # forced: written into, not marked, the user's file kept
    assert not (out / DEMO_MARKER).exists() and not is_demo_outdir(out)
    assert (out / "notes.txt").read_text() == "mine"


def test_run_demo_refuses_before_writing(tmp_path):
    afile = tmp_path / "afile"
    afile.write_text("x")
    with pytest.raises(DemoOutdirError, match="not a directory") as info:
        run_demo(afile, size="tiny")
    assert info.value.path == afile and afile.read_text() == "x"
    with pytest.raises(ScenarioError, match="unknown size 'huge'"):
        run_demo(tmp_path / "new", size="huge")
    assert not (tmp_path / "new").exists()
