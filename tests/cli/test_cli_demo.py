"""``geoblock demo``: simulate, orthorectify with the on-board models, mosaic, report."""

from __future__ import annotations

import numpy as np
import rasterio


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
    # a second run into the same directory needs --force
    again = runner.invoke(cli, ["demo", "--size", "tiny"])
    assert again.exit_code == 2 and "--force" in again.output


def test_demo_help(runner, cli):
    result = runner.invoke(cli, ["demo", "--help"])
    assert result.exit_code == 0
    assert "[OUTDIR]" in result.output and "geoblock-demo" in result.output
