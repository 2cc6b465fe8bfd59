"""``geoblock demo``: simulate, adjust (single and block), orthorectify and mosaic before and
after, measure, report; re-runs into the same OUTDIR."""

from __future__ import annotations

import json

import numpy as np
import pytest
import rasterio

import geoblock
from geoblock.errors import DemoOutdirError
from geoblock.workflows.demo import (
    DEMO_MARKER,
    DEMO_OUTPUTS,
    is_demo_outdir,
    prepare_demo_outdir,
    seam_shift,
)

STRIPS = ("strip1", "strip2", "strip3")
PAIRS = ("strip1 & strip2", "strip2 & strip3")


def _shift_to_truth(ortho_path, true_model, raster, dem):
    """Shift of a written ortho against the same raw image orthorectified with its TRUE
    model onto the ortho's grid (metres east, north): where the ortho puts the ground. One
    raw image on both sides: no content but the geometry differs."""
    import pyproj

    from geoblock.ortho import OutputGrid, orthorectify

    with rasterio.open(ortho_path) as ds:
        band = ds.read(1).astype(float)
        band[band == ds.nodata] = np.nan
        grid = OutputGrid(pyproj.CRS.from_wkt(ds.crs.to_wkt()), ds.transform, band.shape)
    reference = orthorectify(str(raster), true_model, dem, grid).values[0].astype(float)
    reference[reference == 0] = np.nan
    return seam_shift(reference, band, grid.transform)


def test_demo_tiny(runner, cli, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    result = runner.invoke(cli, ["demo", "--variant", "tiny"])
    assert result.exit_code == 0, result.output
    out = tmp_path / "geoblock-demo"  # the default OUTDIR
    # progress: six stages on standard error, each closed by its time
    stages = [line for line in result.stderr.splitlines() if line.startswith("[")]
    assert [s[:5] for s in stages] == [f"[{k}/6]" for k in range(1, 7)]
    assert "block adjustment (DG, GCPs + TPs + DEM elevation control)" in stages[2]
    assert "single strip1: iteration  1" in result.stderr  # the engine's iterations
    assert result.stderr.count(" s)\n") >= 6 and "done in" in result.stderr
    assert "report: geoblock-demo/report.md" in result.stdout

    # every output where the docs say
    assert sorted(p.name for p in out.iterdir()) == sorted([DEMO_MARKER, *DEMO_OUTPUTS])
    for name in ("quicklook.png", "errors.png", "seams.png"):
        assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert (out / "block" / "block.toml").is_file()
    for mode in ("single", "block"):
        folder = out / "adjustment" / mode
        assert (folder / "report.md").is_file() and (folder / "report.json").is_file()
        for strip in STRIPS:  # the adjusted models open as any model (DG + collocation)
            model = geoblock.open_model(folder / "models" / f"{strip}.json")
            assert model.shape == (200, 200)
    assert "## Single versus block adjustment" in (
        out / "adjustment" / "block" / "report.md").read_text()
    for folder in (out / "orthos", out / "onboard" / "orthos"):
        assert sorted(p.name for p in folder.iterdir()) == [f"{s}.tif" for s in STRIPS]
    for path in (out / "mosaic.tif", out / "onboard" / "mosaic.tif"):
        with rasterio.open(path) as ds:
            assert ds.crs.to_epsg() == 32651  # UTM 51N, Taiwan
            assert ds.width > 2 * ds.height  # three strips side by side
    with rasterio.open(out / "mosaic.tif") as ds:
        mosaic = ds.read(1)
    with rasterio.open(out / "contribution.tif") as ds:
        contribution = ds.read(1)
    assert set(np.unique(contribution)) == {0, 1, 2, 3}
    assert (mosaic[contribution > 0] > 0).mean() > 0.99

    # the report: before/after tables, figures, numbers from this run
    text = (out / "report.md").read_text()
    for heading in ("## Accuracy at the control and check points",
                    "## ICTP discrepancies between strips",
                    "## Seamline discrepancies measured on the images", "## The adjustments",
                    "## Footprints", "![quicklook](quicklook.png)",
                    "![error vectors](errors.png)", "![seams](seams.png)",
                    "| image | kind | n | on-board RMSE E (m) |",
                    "| strip1 & strip2 (", "block RMSE 2D (m)", "single RMSE 2D (m)"):
        assert heading in text, heading
    results = json.loads((out / "results.json").read_text())
    assert results["size"] == "tiny" and results["adjustment"]["block"]["converged"]
    ictp = results["ictp"]
    for pair in PAIRS:
        # the block adjustment removes the misregistration between strips
        onboard, block = ictp["onboard"][pair]["rmse_2d"], ictp["block"][pair]["rmse_2d"]
        assert block < 0.3 * onboard and block < 15.0, (pair, onboard, block)
        assert f"| {pair} (" in text
        # the orthos at the seams, matched on their pixels: misregistered by tens of metres
        # with the on-board models, lined up after the block adjustment (the shifts less
        # what the matching finds between the orthos made with the true models: at 300 m
        # pixels the images' content alone makes it find tens of metres)
        for key in ("true", "onboard", "block"):
            seam = results["seams"][key][pair]
            assert seam["status"] == "converged" and seam["pixels"] > 1000
            assert len(seam["segments"]) == 6
        before = results["seam_discrepancies"]["onboard"][pair]
        after = results["seam_discrepancies"]["block"][pair]
        assert before["shift"] > 20.0 and after["shift"] < min(10.0, 0.3 * before["shift"])
    for strip in STRIPS:
        icp = {key: results["accuracy"][key][strip]["icp"]["rmse_2d"]
               for key in ("onboard", "single", "block")}
        assert icp["block"] < 0.5 * icp["onboard"] and icp["single"] < 0.5 * icp["onboard"]
        assert f"| {strip} | ICP | {results['accuracy']['block'][strip]['icp']['n']} |" in text
    assert f"{icp['block']:.2f}" in text  # the table's number is the run's

    # each ortho is where its model puts the ground: displaced by the model's mean error at
    # the ICPs (the true image position located through the model, minus the truth; the
    # on-board error drifts across a strip, which the ICPs and the pixels weigh apart)
    dem = geoblock.open_dem(str(out / "block" / "terrain" / "dem200.tif"))
    for strip in STRIPS:
        true_model = geoblock.open_model(out / "block" / "images" / f"{strip}_true.json")
        raster = out / "block" / "images" / f"{strip}.tif"
        for key, folder in (("onboard", out / "onboard" / "orthos"), ("block", out / "orthos")):
            s = _shift_to_truth(folder / f"{strip}.tif", true_model, raster, dem)
            error = results["accuracy"][key][strip]["icp"]
            tolerance = max(3.0, 0.2 * np.hypot(error["mean_e"], error["mean_n"]))
            assert s.status == "converged"
            assert np.hypot(s.e - error["mean_e"], s.n - error["mean_n"]) < tolerance, (
                strip, key, s.e, s.n, error)
        assert s.shift < 3.0  # block-adjusted: in place

    # the README's first command run again: a marked OUTDIR is a demo output, and preparing
    # it for the next run removes every entry this run wrote (all are in DEMO_OUTPUTS) and
    # keeps the files the user added (a second full run is test_prepare_demo_outdir's rule
    # plus the fresh run above)
    (out / "orthos" / "stale.tif").write_bytes(b"from an older demo")
    (out / "my-notes.txt").write_text("mine")
    assert is_demo_outdir(out) and prepare_demo_outdir(out) is True
    assert sorted(p.name for p in out.iterdir()) == [DEMO_MARKER, "my-notes.txt"]


def test_demo_refuses_a_directory_that_is_not_a_demo_output(runner, cli, tmp_path):
    outdir = tmp_path / "work"
    outdir.mkdir()
    (outdir / "thesis.docx").write_bytes(b"precious")
    (outdir / "report.md").write_text("# my own report\n")
    result = runner.invoke(cli, ["demo", str(outdir), "--variant", "tiny"])
    assert result.exit_code == 1
    message = " ".join(result.output.split())
    assert str(outdir) in message and "--overwrite" in message
    assert sorted(p.name for p in outdir.iterdir()) == ["report.md", "thesis.docx"]
    assert (outdir / "report.md").read_text() == "# my own report\n"
    # a file in place of OUTDIR
    afile = tmp_path / "afile"
    afile.write_text("x")
    result = runner.invoke(cli, ["demo", str(afile), "--variant", "tiny"])
    assert result.exit_code == 1 and "not a directory" in result.output
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
    (marked / "adjustment" / "block").mkdir(parents=True)
    (marked / DEMO_MARKER).write_text("")
    (marked / "mosaic.tif").write_bytes(b"")
    (marked / "seams.png").write_bytes(b"")
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
    assert "block mode" in result.output and "seam" in result.output
