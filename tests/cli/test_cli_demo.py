"""``geoblock demo``: simulate, orthorectify with the on-board models, mosaic, report."""

from __future__ import annotations

import numpy as np
import pytest
import rasterio

from geoblock.errors import DemoOutdirError
from geoblock.workflows.demo import DEMO_MARKER, is_demo_outdir, prepare_demo_outdir


def test_demo_tiny(runner, cli, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    result = runner.invoke(cli, ["demo", "--size", "tiny"])
    assert result.exit_code == 0, result.output
    out = tmp_path / "geoblock-demo"  # the default OUTDIR
    for step in ("[1/4]", "[2/4]", "[3/4]", "[4/4]", "done in"):
        assert step in result.stderr
    assert "report: geoblock-demo/report.md" in result.stdout
    text = (out / "report.md").read_text()
    for heading in ("## Footprints", "## Accuracy of the on-board models at the check points",
                    "## ICTP discrepancies between strips", "quicklook.png"):
        assert heading in text
    assert (out / "quicklook.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with rasterio.open(out / "mosaic.tif") as ds:
        mosaic = ds.read(1)
        assert ds.crs.to_epsg() == 32651  # UTM 51N, Taiwan
        assert ds.width > 2 * ds.height  # three strips side by side
    with rasterio.open(out / "contribution.tif") as ds:
        contribution = ds.read(1)
    assert set(np.unique(contribution)) == {0, 1, 2, 3}
    assert (mosaic[contribution > 0] > 0).mean() > 0.99
    for strip in ("strip1", "strip2", "strip3"):
        assert (out / "orthos" / f"{strip}.tif").is_file()
    assert (out / "block" / "block.toml").is_file()
    assert (out / DEMO_MARKER).is_file()
    # the README's first command run again: the previous demo's outputs are replaced, the
    # files the user added are kept
    (out / "orthos" / "stale.tif").write_bytes(b"from an older demo")
    (out / "my-notes.txt").write_text("mine")
    first_report = (out / "report.md").stat().st_mtime_ns
    again = runner.invoke(cli, ["demo", "--size", "tiny"])
    assert again.exit_code == 0, again.output
    assert "report: geoblock-demo/report.md" in again.stdout
    assert not (out / "orthos" / "stale.tif").exists()
    assert (out / "my-notes.txt").read_text() == "mine"
    assert (out / "report.md").stat().st_mtime_ns != first_report
    assert (out / DEMO_MARKER).is_file() and (out / "mosaic.tif").is_file()
    for strip in ("strip1", "strip2", "strip3"):
        assert (out / "orthos" / f"{strip}.tif").is_file()


def test_demo_refuses_a_directory_that_is_not_a_demo_output(runner, cli, tmp_path):
    outdir = tmp_path / "work"
    outdir.mkdir()
    (outdir / "thesis.docx").write_bytes(b"precious")
    (outdir / "report.md").write_text("# my own report\n")
    result = runner.invoke(cli, ["demo", str(outdir), "--size", "tiny"])
    assert result.exit_code == 2
    message = " ".join(result.output.split())
    assert str(outdir) in message and DEMO_MARKER in message and "--force" in message
    assert sorted(p.name for p in outdir.iterdir()) == ["report.md", "thesis.docx"]
    assert (outdir / "report.md").read_text() == "# my own report\n"
    # a file in place of OUTDIR
    afile = tmp_path / "afile"
    afile.write_text("x")
    result = runner.invoke(cli, ["demo", str(afile), "--size", "tiny"])
    assert result.exit_code == 2 and "not a directory" in result.output
    assert afile.read_text() == "x"


def test_prepare_demo_outdir(tmp_path):
    assert prepare_demo_outdir(tmp_path / "absent") is True
    assert prepare_demo_outdir(tmp_path) is True  # empty
    # a demo made before the marker existed is recognised by its entries and report
    legacy = tmp_path / "legacy"
    (legacy / "orthos").mkdir(parents=True)
    (legacy / "orthos" / "strip1.tif").write_bytes(b"")
    (legacy / "report.md").write_text("# geoblock demo\n\nold\n")
    (legacy / "quicklook.png").write_bytes(b"")
    assert is_demo_outdir(legacy)
    assert prepare_demo_outdir(legacy) is True
    assert list(legacy.iterdir()) == []
    # marked: only the demo's own entries go
    marked = tmp_path / "marked"
    (marked / "block").mkdir(parents=True)
    (marked / DEMO_MARKER).write_text("")
    (marked / "mosaic.tif").write_bytes(b"")
    (marked / "keep.txt").write_text("k")
    assert prepare_demo_outdir(marked) is True
    assert sorted(p.name for p in marked.iterdir()) == [DEMO_MARKER, "keep.txt"]
    # anything else: refused by name, or written into (not marked) with force
    other = tmp_path / "other"
    other.mkdir()
    (other / "mosaic.tif").write_bytes(b"mine")
    assert not is_demo_outdir(other)  # no report.md of a demo
    with pytest.raises(DemoOutdirError, match="other"):
        prepare_demo_outdir(other)
    assert prepare_demo_outdir(other, force=True) is False
    assert (other / "mosaic.tif").read_bytes() == b"mine"


def test_demo_help(runner, cli):
    result = runner.invoke(cli, ["demo", "--help"])
    assert result.exit_code == 0
    assert "[OUTDIR]" in result.output and "geoblock-demo" in result.output
    assert ".geoblock-demo" in result.output  # the re-run rule is documented
