"""``geoblock match`` on the real Pleiades pair of Mont Ventoux (shareloc's 500 x 500 px crops of
two 40000 x 40000 px scenes, their vendor RPCs, the SRTM tile with EGM96 heights), then
``geoblock adjust`` with the tie points: the left image held fixed, the right one refined by
an RPCV-0 shift, the SRTM as elevation control. The tie points' residuals after the
adjustment must be a fraction of a pixel."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
from click.testing import CliRunner

from geoblock.cli.main import build_cli
from geoblock.io import read_points

SRTM = "shareloc/dtm/srtm_ventoux/srtm90_non_void_filled/N44E005.hgt"
GEOID = "shareloc/dtm/geoid/egm96_15.gtx"


@pytest.fixture(scope="module")
def ventoux(data_dir):
    pytest.importorskip("geoblock_rpc", reason="the Ventoux RPCs need the geoblock-rpc plugin")
    files = {"srtm": data_dir / SRTM, "geoid": data_dir / GEOID}
    for side in ("left", "right"):
        files[f"{side}_image"] = data_dir / f"shareloc/image/phr_ventoux/{side}_image.tif"
        files[f"{side}_rpc"] = data_dir / f"shareloc/rpc/phr_ventoux/{side}_image.geom"
    for path in files.values():
        if not path.exists():
            pytest.skip(f"real data not found: {path}")
    return files


def test_match_then_adjust_leaves_sub_pixel_residuals(ventoux, tmp_path):
    f = ventoux
    cli = build_cli()
    runner = CliRunner()
    tp = tmp_path / "image.csv"
    result = runner.invoke(cli, [
        "match", str(f["left_image"]), str(f["right_image"]),
        "--model", str(f["left_rpc"]), "--model", str(f["right_rpc"]),
        "--id", "left", "--id", "right", "--dem", str(f["srtm"]), "--dem-vertical", "geoid",
        "--geoid", str(f["geoid"]), "-o", str(tp)])
    assert result.exit_code == 0, result.output
    # the crops' pixel-unit geotransforms place them in their scenes: said, and applied
    assert "crop at row/col 5000, 5000" in result.stderr
    match_stderr = result.stderr
    table = read_points(tp)
    n = np.unique(table["id"]).size
    assert n >= 300, result.stderr
    left = table["image"] == "left"
    # scene pixels: the left crop starts at row/col 5000 (its overlap with the right: the
    # crop's lower part)
    assert (table["row"][left] > 5000).all() and (table["row"][left] < 5500).all()

    (tmp_path / "block.toml").write_text(f"""
version = 1
name = "Ventoux pair, tie points from geoblock match"
method = "default"

[points]
image = "image.csv"

[dem]
path = "{f['srtm']}"
vertical = "geoid"
geoid = "{f['geoid']}"
sigma = 10.0

[[images]]
id = "left"
model = "{f['left_rpc']}"
raster = "{f['left_image']}"

[[images]]
id = "right"
model = "{f['right_rpc']}"
raster = "{f['right_image']}"
correction = 0
""")
    out = tmp_path / "adjusted"
    result = runner.invoke(cli, ["adjust", str(tmp_path / "block.toml"), "-o", str(out),
                                 "--no-figures"])
    assert result.exit_code == 0, result.output
    report = json.loads((out / "report.json").read_text())
    assert report["converged"]
    v = np.array([[m["v_row"], m["v_col"]] for m in report["measurements"]])
    rms = float(np.sqrt(np.mean(np.sum(v**2, axis=1))))
    # measured: 0.068 px (RMS, 2-D) over 1572 measurements, largest 0.19 px
    assert rms < 0.2, rms
    assert np.abs(v).max() < 1.0
    # the RPCs disagree by a few pixels: the shift RPCV-0 finds is what the matching saw
    a0, b0 = (p["value"] for p in report["parameters"]["right"])
    assert 1.0 < np.hypot(a0, b0) < 10.0
    # and the offset geoblock match reports is that disagreement where the crops overlap
    # (measured: -2.92, -4.16 against RPCV-0's -2.92, -4.16), not its bias polynomial
    # extrapolated to the scene's centre 15000 px away (-2.74, -4.22)
    said = re.search(r"kept .*models' offset ([-+][\d.]+), ([-+][\d.]+) px \(row, col\)",
                     match_stderr)
    assert said, match_stderr
    assert abs(float(said[1]) - a0) < 0.1 and abs(float(said[2]) - b0) < 0.1, (said[0], a0, b0)
